//! Separate processes on one database: an API that runs no jobs (`serve --workers 0`, here
//! in the test process) and `cohortforge worker` processes that run them, one of which is
//! killed with SIGKILL in the middle of a fit. Also `/metrics` on both.

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use reqwest::StatusCode;
use serde_json::{Value, json};

use super::jobs::{upload_phantoms, wait_for};
use super::support::{TestServer, expect_json};
use cohortforge::mesh::Format;
use cohortforge::mesh::phantom::Family;

/// Lease of the worker processes: a killed worker's job is taken over this long after its
/// last heartbeat.
const LEASE_SECONDS: u64 = 2;

/// A `cohortforge worker` process, killed when dropped.
struct WorkerProcess {
    child: Child,
    base: String,
}

impl WorkerProcess {
    fn start(database: &str) -> Self {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free port")
            .port();
        let child = Command::new(env!("CARGO_BIN_EXE_cohortforge"))
            .args(["worker", "--workers", "1"])
            .arg("--database")
            .arg(database)
            .args(["--bind", &format!("127.0.0.1:{port}")])
            .args(["--lease-seconds", &LEASE_SECONDS.to_string()])
            .env("COHORTFORGE_LOG", "warn")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("the worker process starts");
        Self {
            child,
            base: format!("http://127.0.0.1:{port}"),
        }
    }

    async fn get(&self, client: &reqwest::Client, path: &str) -> Option<reqwest::Response> {
        client.get(format!("{}{path}", self.base)).send().await.ok()
    }

    /// Waits until its probe answers.
    async fn ready(&self, client: &reqwest::Client) {
        let started = Instant::now();
        while started.elapsed() < Duration::from_secs(60) {
            if let Some(r) = self.get(client, "/readyz").await
                && r.status() == StatusCode::OK
            {
                return;
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        panic!("worker at {} never became ready", self.base);
    }
}

impl Drop for WorkerProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

async fn jobs_with_status(s: &TestServer, status: &str) -> Vec<Value> {
    let page = expect_json(
        s.client
            .get(s.url(&format!("/v1/jobs?status={status}&limit=100")))
            .send()
            .await
            .unwrap(),
        StatusCode::OK,
    )
    .await;
    page["items"].as_array().unwrap().clone()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn worker_processes_share_the_queue_and_take_over_a_killed_workers_job() {
    let s = TestServer::start_with(|c| c.workers = 0).await;
    let dataset = upload_phantoms(&s, Family::Lv, 12, 5).await;
    // Fits with the rotation search and non-rigid correspondences: seconds each, so the
    // kill lands in the middle of one.
    let mut jobs = Vec::new();
    for seed in 0..6 {
        let body = json!({"dataset_id": dataset, "model_type": "rsmp", "seed": seed,
            "holdout_fraction": 0.2, "params": {"cpd_max_iterations": 60}});
        let job = expect_json(
            s.client
                .post(s.url("/v1/jobs"))
                .json(&body)
                .send()
                .await
                .unwrap(),
            StatusCode::ACCEPTED,
        )
        .await;
        jobs.push(job["id"].as_str().unwrap().to_owned());
    }
    assert_eq!(jobs_with_status(&s, "queued").await.len(), 6);

    // The first worker process claims a job; the second starts, then the first is killed.
    let mut first = WorkerProcess::start(&s.database_url());
    let started = Instant::now();
    let running = loop {
        if let Some(job) = jobs_with_status(&s, "running").await.pop() {
            break job;
        }
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "no worker took a job"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    let second = WorkerProcess::start(&s.database_url());
    second.ready(&s.client).await;
    first.child.kill().expect("SIGKILL");
    first.child.wait().expect("the killed worker is reaped");
    let killed_at = Instant::now();
    let killed_job = running["id"].as_str().unwrap().to_owned();
    assert_eq!(
        jobs_with_status(&s, "succeeded").await.len(),
        0,
        "the kill landed in the middle of the first fit"
    );

    // Back in the queue once its lease expired, although the other worker is busy; started
    // again (attempt 2) when that worker is free.
    let mut requeued = None;
    loop {
        let job = expect_json(
            s.client
                .get(s.url(&format!("/v1/jobs/{killed_job}")))
                .send()
                .await
                .unwrap(),
            StatusCode::OK,
        )
        .await;
        if requeued.is_none() && (job["status"] == "queued" || job["attempts"] == 2) {
            requeued = Some(killed_at.elapsed());
        }
        if job["attempts"] == 2 {
            break;
        }
        assert!(killed_at.elapsed() < Duration::from_secs(120), "{job}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    eprintln!(
        "the killed worker's job was requeued {:.2} s and started again {:.2} s after the kill \
         (lease {LEASE_SECONDS} s)",
        requeued.unwrap_or_default().as_secs_f64(),
        killed_at.elapsed().as_secs_f64()
    );
    let taken_over = wait_for(&s, &killed_job, Duration::from_secs(600)).await;
    assert_eq!(taken_over["status"], "succeeded", "{taken_over}");
    assert_eq!(
        taken_over["attempts"], 2,
        "started by the killed worker, then by the other"
    );
    let mut models = Vec::new();
    for id in &jobs {
        let done = wait_for(&s, id, Duration::from_secs(600)).await;
        assert_eq!(done["status"], "succeeded", "{done}");
        models.push(done["model_id"].as_str().unwrap().to_owned());
    }
    models.sort();
    models.dedup();
    assert_eq!(models.len(), 6, "one model per job");
    let listed = expect_json(
        s.client.get(s.url("/v1/models")).send().await.unwrap(),
        StatusCode::OK,
    )
    .await;
    assert_eq!(listed["total"], 6, "no model stored twice: {listed}");

    // The surviving worker ran all six jobs and says so on its own /metrics; the API's
    // /metrics counts them from the database and times requests by route.
    let metrics = second
        .get(&s.client, "/metrics")
        .await
        .expect("worker metrics")
        .text()
        .await
        .unwrap();
    assert!(
        metrics.contains(
            "cohortforge_job_run_seconds_count{kind=\"fit\",model_type=\"rsmp\",outcome=\"succeeded\"} 6"
        ),
        "{metrics}"
    );
    assert!(
        metrics.contains(
            "cohortforge_fit_stage_seconds_count{model_type=\"rsmp\",stage=\"alignment\"} 6"
        ),
        "{metrics}"
    );
    let api = s
        .client
        .get(s.url("/metrics"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(
        api.contains("cohortforge_jobs{status=\"succeeded\",kind=\"fit\",model_type=\"rsmp\"} 6"),
        "{api}"
    );
    assert!(api.contains("cohortforge_oldest_queued_job_age_seconds 0\n"));
    assert!(
        api.contains("http_server_request_duration_seconds_count{method=\"GET\",route=\"/v1/jobs/{id}\",status=\"200\"}"),
        "{api}"
    );
    assert!(
        !api.lines()
            .any(|l| l.starts_with("http_server") && jobs.iter().any(|id| l.contains(id))),
        "routes are patterns, never raw paths"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_api_replicas_on_one_database_answer_races_with_one_record_and_no_500() {
    let a = TestServer::start_with(|c| c.workers = 0).await;
    let b = TestServer::sharing(&a).await;
    let dataset = a.dataset("lv", "lv").await;
    let phantoms = cohortforge::mesh::phantom::generate(Family::Lv, 3, 12);
    let stl = |k: usize| cohortforge::mesh::io::write(&phantoms[k].mesh, Format::Stl);
    for k in 1..3 {
        expect_json(a.upload(&dataset, "stl", stl(k)).await, StatusCode::CREATED).await;
    }
    let bytes = stl(0);

    // The same geometry uploaded through both replicas at once: stored once.
    let mut uploads = tokio::task::JoinSet::new();
    for k in 0..8 {
        let s = if k % 2 == 0 { &a } else { &b };
        let request = s
            .client
            .post(s.url(&format!("/v1/datasets/{dataset}/meshes?format=stl")))
            .body(bytes.clone());
        uploads.spawn(async move { request.send().await.unwrap().status() });
    }
    let statuses = uploads.join_all().await;
    let created = statuses
        .iter()
        .filter(|s| **s == StatusCode::CREATED)
        .count();
    let conflicts = statuses
        .iter()
        .filter(|s| **s == StatusCode::CONFLICT)
        .count();
    assert_eq!((created, conflicts), (1, 7), "{statuses:?}");

    // One Idempotency-Key sent through both replicas at once: one job.
    let body = json!({"dataset_id": dataset, "model_type": "rsmp", "holdout_fraction": 0.0});
    let mut submissions = tokio::task::JoinSet::new();
    for k in 0..8 {
        let s = if k % 2 == 0 { &a } else { &b };
        let request = s
            .client
            .post(s.url("/v1/jobs"))
            .header("idempotency-key", "replica-race")
            .json(&body);
        submissions.spawn(async move {
            let response = request.send().await.unwrap();
            (response.status(), response.json::<Value>().await.unwrap())
        });
    }
    let answers = submissions.join_all().await;
    for (status, job) in &answers {
        assert_eq!(*status, StatusCode::ACCEPTED, "{job}");
        assert_eq!(job["id"], answers[0].1["id"], "one job for one key");
    }
    let jobs = expect_json(
        b.client.get(b.url("/v1/jobs")).send().await.unwrap(),
        StatusCode::OK,
    )
    .await;
    assert_eq!(jobs["total"], 1, "{jobs}");
}
