//! Service benchmark: upload throughput, an RSMP fit through the job queue with the latency
//! of `GET /v1/jobs/{id}` sampled while it runs, and the time to sample a cohort.
//!
//! `cargo run --release --example bench_service -- [train] [test] [seed]`
//! (defaults: 100 training and 25 held-out LV phantoms, seed 1).

use std::time::{Duration, Instant};

use cohortforge::config::Config;
use cohortforge::mesh::phantom::{self, Family};
use cohortforge::mesh::{Format, io};
use cohortforge::store::Store;
use serde_json::{Value, json};
use tokio_util::sync::CancellationToken;

async fn start(dir: &std::path::Path) -> (String, CancellationToken) {
    let config = Config {
        workers: 1,
        ..Config::local(dir.join("bench.db"))
    };
    let store = Store::connect(&config.database).await.expect("database");
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .expect("bind");
    let base = format!("http://{}", listener.local_addr().expect("address"));
    let shutdown = CancellationToken::new();
    let token = shutdown.clone();
    tokio::spawn(async move { cohortforge::api::run(listener, &config, store, token).await });
    (base, shutdown)
}

async fn json_of(response: reqwest::Response) -> Value {
    let status = response.status();
    let text = response.text().await.expect("body");
    assert!(status.is_success(), "{status}: {text}");
    serde_json::from_str(&text).expect("json")
}

async fn dataset(client: &reqwest::Client, base: &str, name: &str) -> String {
    let body = json_of(
        client
            .post(format!("{base}/v1/datasets"))
            .json(&json!({"name": name, "organ": "lv"}))
            .send()
            .await
            .unwrap(),
    )
    .await;
    body["id"].as_str().unwrap().to_owned()
}

/// Uploads each file as a raw body, one request at a time; returns (meshes/s, MB/s).
async fn upload_all(
    client: &reqwest::Client,
    base: &str,
    dataset: &str,
    format: Format,
    files: &[Vec<u8>],
) -> (f64, f64) {
    let started = Instant::now();
    let bytes: usize = files.iter().map(Vec::len).sum();
    for f in files {
        let url = format!(
            "{base}/v1/datasets/{dataset}/meshes?format={}",
            format.extension()
        );
        json_of(client.post(url).body(f.clone()).send().await.unwrap()).await;
    }
    let s = started.elapsed().as_secs_f64();
    (files.len() as f64 / s, bytes as f64 / 1e6 / s)
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((p * (sorted.len() - 1) as f64).round() as usize).min(sorted.len() - 1)]
}

async fn upload_throughput(client: &reqwest::Client, base: &str) {
    // Liver phantoms resampled near 2,000 vertices: pick those between 1,800 and 2,200.
    let meshes: Vec<_> = phantom::generate(Family::Liver, 400, 99)
        .into_iter()
        .filter(|p| (1800..=2200).contains(&p.mesh.vertex_count()))
        .take(60)
        .map(|p| p.mesh)
        .collect();
    let mean_vertices = meshes.iter().map(|m| m.vertex_count()).sum::<usize>() / meshes.len();
    println!(
        "\n## Upload throughput ({} meshes, mean {mean_vertices} vertices, one request at a time)\n",
        meshes.len()
    );
    println!("| format | meshes/s | MB/s | file size (kB) |\n|---|---|---|---|");
    for format in [Format::Obj, Format::Stl] {
        let files: Vec<Vec<u8>> = meshes.iter().map(|m| io::write(m, format)).collect();
        let d = dataset(client, base, &format!("upload-{}", format.extension())).await;
        let (per_s, mb_s) = upload_all(client, base, &d, format, &files).await;
        let kb = files.iter().map(Vec::len).sum::<usize>() as f64 / files.len() as f64 / 1e3;
        println!(
            "| {} | {per_s:.1} | {mb_s:.2} | {kb:.0} |",
            format.extension()
        );
    }
}

async fn fit_and_sample(
    client: &reqwest::Client,
    base: &str,
    train: usize,
    test: usize,
    seed: u64,
) {
    let d = dataset(client, base, "lv-bench").await;
    let files: Vec<Vec<u8>> = phantom::generate(Family::Lv, train + test, seed)
        .iter()
        .map(|p| io::write(&p.mesh, Format::Stl))
        .collect();
    upload_all(client, base, &d, Format::Stl, &files).await;
    let holdout = test as f64 / (train + test) as f64;
    let job = json_of(client.post(format!("{base}/v1/jobs")).json(&json!({"dataset_id": d, "model_type": "rsmp", "seed": seed, "holdout_fraction": holdout})).send().await.unwrap()).await;
    let id = job["id"].as_str().unwrap().to_owned();
    let started = Instant::now();
    let mut latencies = Vec::new();
    let done = loop {
        let t = Instant::now();
        let body = json_of(
            client
                .get(format!("{base}/v1/jobs/{id}"))
                .send()
                .await
                .unwrap(),
        )
        .await;
        latencies.push(t.elapsed().as_secs_f64() * 1e3);
        if matches!(
            body["status"].as_str(),
            Some("succeeded" | "failed" | "cancelled")
        ) {
            break body;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    let fit_s = started.elapsed().as_secs_f64();
    assert_eq!(done["status"], "succeeded", "{done}");
    latencies.sort_by(f64::total_cmp);
    println!("\n## RSMP fit, {train} training / {test} held-out LV phantoms (seed {seed})\n");
    println!(
        "job wall time {fit_s:.1} s; GET /v1/jobs/{{id}} during the fit: {} requests, p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms",
        latencies.len(),
        percentile(&latencies, 0.5),
        percentile(&latencies, 0.99),
        latencies.last().unwrap()
    );
    let model_id = done["model_id"].as_str().unwrap();
    let model = json_of(
        client
            .get(format!("{base}/v1/models/{model_id}"))
            .send()
            .await
            .unwrap(),
    )
    .await;
    println!("\n| stage | seconds |\n|---|---|");
    for t in model["timings"].as_array().unwrap() {
        println!(
            "| {} | {:.1} |",
            t["stage"].as_str().unwrap(),
            t["seconds"].as_f64().unwrap()
        );
    }
    println!(
        "\nmodes kept: {}, atlas vertices: {}",
        model["n_modes"], model["atlas"]["vertex_count"]
    );
    println!("\n| metric (mm) | HD | ED | ED* | CD |\n|---|---|---|---|---|");
    for metric in ["generalisation", "specificity", "matching"] {
        let m = &model["evaluation"][metric];
        let cell = |k: &str| {
            format!(
                "{:.2} ± {:.2}",
                m[k]["mean"].as_f64().unwrap_or(f64::NAN),
                m[k]["std"].as_f64().unwrap_or(f64::NAN)
            )
        };
        println!(
            "| {metric} | {} | {} | {} | {} |",
            cell("hd"),
            cell("ed"),
            cell("ed_star"),
            cell("cd")
        );
    }
    let t = Instant::now();
    let cohort = json_of(
        client
            .post(format!("{base}/v1/models/{model_id}/cohorts"))
            .json(&json!({"size": 1000, "seed": seed}))
            .send()
            .await
            .unwrap(),
    )
    .await;
    let cohort_s = t.elapsed().as_secs_f64();
    println!(
        "\n## Cohort of 1,000 members: {cohort_s:.2} s including biomarkers, acceptance and storage ({:.0} members/s)\n",
        1000.0 / cohort_s
    );
    println!(
        "| biomarker | reference mean ± sd | cohort mean ± sd | A^r | A^M | A^μ |\n|---|---|---|---|---|---|"
    );
    for (name, b) in cohort["report"]["biomarkers"].as_object().unwrap() {
        let f = |v: &Value| v.as_f64().unwrap_or(f64::NAN);
        println!(
            "| {name} | {:.2} ± {:.2} | {:.2} ± {:.2} | {:.3} | {:.3} | {:.3} |",
            f(&b["reference"]["mean"]),
            f(&b["reference"]["sd"]),
            f(&b["synthetic"]["mean"]),
            f(&b["synthetic"]["sd"]),
            f(&b["acceptance"]["range"]),
            f(&b["acceptance"]["mode"]),
            f(&b["acceptance"]["mean"])
        );
    }
    let a = &cohort["report"]["acceptance"];
    println!(
        "| **joint** | | | {:.3} | {:.3} | {:.3} |",
        a["range"].as_f64().unwrap(),
        a["mode"].as_f64().unwrap(),
        a["mean"].as_f64().unwrap()
    );
}

#[tokio::main]
async fn main() {
    let args: Vec<u64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let (train, test, seed) = (
        args.first().copied().unwrap_or(100) as usize,
        args.get(1).copied().unwrap_or(25) as usize,
        args.get(2).copied().unwrap_or(1),
    );
    let dir = tempfile::tempdir().expect("temporary directory");
    let (base, shutdown) = start(dir.path()).await;
    let client = reqwest::Client::new();
    upload_throughput(&client, &base).await;
    fit_and_sample(&client, &base, train, test, seed).await;
    shutdown.cancel();
}
