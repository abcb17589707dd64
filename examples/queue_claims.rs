//! Queue throughput: jobs claimed and finished per second by several workers, each with its
//! own connections to one database, as separate worker processes have.
//!
//! `cargo run --release --example queue_claims -- [jobs] [workers] [--database URL]`
//! (defaults 2000, 4, a new SQLite file; a `postgres://` URL must name an empty database):
//! queues `jobs` empty jobs, then `workers` workers claim and finish them as fast as the
//! queue lets them (no fit: the queue's own cost). Prints claims per second, each job's
//! claim count (every job must be claimed exactly once), and the time to queue the jobs.

use std::collections::HashMap;
use std::time::Instant;

use cohortforge::store::jobs::{JobStatus, NewJob};
use cohortforge::store::{Location, Store};

#[tokio::main(flavor = "multi_thread")]
async fn main() {
    let raw: Vec<String> = std::env::args().skip(1).collect();
    let database = raw
        .iter()
        .position(|a| a == "--database")
        .and_then(|i| raw.get(i + 1))
        .map(|url| Location::parse(url).expect("a database URL"));
    let args: Vec<usize> = raw.iter().filter_map(|a| a.parse().ok()).collect();
    let (jobs, workers) = (
        args.first().copied().unwrap_or(2000),
        args.get(1).copied().unwrap_or(4),
    );
    let dir = tempfile::tempdir().expect("temporary directory");
    let location = database.unwrap_or_else(|| Location::Sqlite(dir.path().join("queue.db")));
    let store = Store::connect(&location).await.expect("database");
    let started = Instant::now();
    for k in 0..jobs {
        let new = NewJob {
            dataset_id: "none".into(),
            model_type: "rsmp".into(),
            params: serde_json::json!({}),
            seed: k as u64,
            holdout_fraction: 0.0,
            max_attempts: 3,
            idempotency_key: None,
            request_hash: format!("{k}"),
        };
        store.submit_job(new).await.expect("queued");
    }
    let queued = started.elapsed().as_secs_f64();

    let started = Instant::now();
    let mut tasks = tokio::task::JoinSet::new();
    for w in 0..workers {
        // Each worker opens the database itself, as a process of its own would.
        let store = Store::connect(&location).await.expect("database");
        tasks.spawn(async move {
            let name = format!("worker-{w}");
            let mut claimed = Vec::new();
            while let Some(job) = store.claim_job(&name, 30_000).await.expect("claim") {
                let done = store
                    .finish_job(&job.id, &name, JobStatus::Succeeded, None)
                    .await
                    .expect("finish");
                assert!(done, "a held lease finishes its job");
                claimed.push(job.id);
            }
            claimed
        });
    }
    let mut counts: HashMap<String, usize> = HashMap::new();
    let mut per_worker = Vec::new();
    for ids in tasks.join_all().await {
        per_worker.push(ids.len());
        for id in ids {
            *counts.entry(id).or_default() += 1;
        }
    }
    let seconds = started.elapsed().as_secs_f64();
    let once = counts.values().all(|&c| c == 1) && counts.len() == jobs;
    println!(
        "{location}: {jobs} jobs queued in {queued:.2} s ({:.0}/s); claimed and finished by {workers} \
         workers in {seconds:.2} s: {:.0} claims/s; per worker {per_worker:?}; every job \
         claimed exactly once: {once}",
        jobs as f64 / queued,
        jobs as f64 / seconds
    );
    assert!(once, "a job was claimed twice or never");
}
