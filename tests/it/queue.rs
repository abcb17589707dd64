//! The job queue with several processes' connections on one database: every job claimed
//! once, and, on PostgreSQL, wake-ups across processes. These run against the suite's
//! database (SQLite, or PostgreSQL with `COHORTFORGE_TEST_POSTGRES`).

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

use cohortforge::store::jobs::{JobStatus, NewJob};
use cohortforge::store::{Location, Store};
use tokio::sync::Notify;
use tokio_util::sync::CancellationToken;

use crate::support::{fresh_database, test_postgres};

fn empty_job(k: usize) -> NewJob {
    NewJob {
        dataset_id: "none".into(),
        model_type: "rsmp".into(),
        params: serde_json::json!({}),
        seed: k as u64,
        holdout_fraction: 0.0,
        max_attempts: 3,
        idempotency_key: None,
        request_hash: format!("{k}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn workers_with_their_own_connections_claim_every_job_exactly_once() {
    let dir = tempfile::tempdir().unwrap();
    let location = fresh_database(dir.path()).await;
    let store = Store::connect(&location).await.unwrap();
    const JOBS: usize = 120;
    for k in 0..JOBS {
        store.submit_job(empty_job(k)).await.unwrap();
    }
    let mut workers = tokio::task::JoinSet::new();
    for w in 0..4 {
        let store = Store::connect(&location).await.unwrap();
        workers.spawn(async move {
            let name = format!("worker-{w}");
            let mut claimed = Vec::new();
            while let Some(job) = store.claim_job(&name, 30_000).await.unwrap() {
                assert_eq!(job.status, JobStatus::Running);
                assert!(
                    store
                        .finish_job(&job.id, &name, JobStatus::Succeeded, None)
                        .await
                        .unwrap()
                );
                claimed.push(job.id);
            }
            claimed
        });
    }
    let mut counts: HashMap<String, usize> = HashMap::new();
    for ids in workers.join_all().await {
        for id in ids {
            *counts.entry(id).or_default() += 1;
        }
    }
    assert_eq!(counts.len(), JOBS, "every job was claimed");
    assert!(counts.values().all(|&n| n == 1), "no job was claimed twice");
    let (_, total) = store
        .jobs(
            Some(JobStatus::Succeeded),
            None,
            cohortforge::store::Page {
                limit: 1,
                offset: 0,
            },
        )
        .await
        .unwrap();
    assert_eq!(total, JOBS as i64);
}

#[tokio::test]
async fn a_worker_whose_lease_was_taken_over_cannot_write() {
    let dir = tempfile::tempdir().unwrap();
    let store = Store::connect(&fresh_database(dir.path()).await)
        .await
        .unwrap();
    let (job, _) = store.submit_job(empty_job(0)).await.unwrap();
    let first = store.claim_job("first", 30_000).await.unwrap().unwrap();
    assert_eq!(first.id, job.id);
    store.expire_lease(&job.id).await.unwrap();
    assert_eq!(store.recover_expired_leases().await.unwrap(), (1, 0));
    let second = store.claim_job("second", 30_000).await.unwrap().unwrap();
    assert_eq!((second.id.as_str(), second.attempts), (job.id.as_str(), 2));
    let progress = cohortforge::store::jobs::JobProgress::default();
    use cohortforge::store::jobs::Lease;
    assert_eq!(
        store
            .heartbeat(&job.id, "first", &progress, 30_000)
            .await
            .unwrap(),
        Lease::Lost
    );
    assert!(
        !store
            .finish_job(&job.id, "first", JobStatus::Failed, Some("late"))
            .await
            .unwrap()
    );
    assert!(
        store
            .finish_job(&job.id, "second", JobStatus::Succeeded, None)
            .await
            .unwrap()
    );
    assert_eq!(
        store.job(&job.id).await.unwrap().status,
        JobStatus::Succeeded
    );
}

/// Needs PostgreSQL: `.ci/run` starts a throwaway cluster and runs it with
/// `--include-ignored`; without `COHORTFORGE_TEST_POSTGRES` it fails and says so.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "needs PostgreSQL: set COHORTFORGE_TEST_POSTGRES=postgres://USER@HOST:PORT (scripts/postgres_throwaway.sh starts one)"]
async fn postgres_a_job_queued_by_one_process_wakes_an_idle_worker_of_another() {
    assert!(
        test_postgres().is_some(),
        "this test needs PostgreSQL: set COHORTFORGE_TEST_POSTGRES=postgres://USER@HOST:PORT"
    );
    let dir = tempfile::tempdir().unwrap();
    let location = fresh_database(dir.path()).await;
    assert!(matches!(location, Location::Postgres(_)));
    let (api, worker) = (
        Store::connect(&location).await.unwrap(),
        Store::connect(&location).await.unwrap(),
    );
    let (wake, stop) = (Arc::new(Notify::new()), CancellationToken::new());
    let listening = tokio::spawn({
        let (wake, stop) = (wake.clone(), stop.clone());
        async move { worker.forward_job_notifications(wake, stop).await }
    });
    // The listener needs a moment to LISTEN; a notification sent before that is lost, so
    // queue until one arrives, each within a short wait.
    let mut woken = false;
    for k in 0..20 {
        let notified = wake.notified();
        api.submit_job(empty_job(k)).await.unwrap();
        if tokio::time::timeout(Duration::from_millis(500), notified)
            .await
            .is_ok()
        {
            woken = true;
            break;
        }
    }
    assert!(woken, "no notification reached the other process's workers");
    stop.cancel();
    tokio::time::timeout(Duration::from_secs(5), listening)
        .await
        .expect("the listener stops on shutdown")
        .unwrap();
}

#[tokio::test]
async fn sqlite_has_no_notification_channel_and_workers_poll() {
    let dir = tempfile::tempdir().unwrap();
    let store = Store::open(&dir.path().join("q.db")).await.unwrap();
    // Returns at once instead of waiting for notifications that never come.
    tokio::time::timeout(
        Duration::from_secs(5),
        store.forward_job_notifications(Arc::new(Notify::new()), CancellationToken::new()),
    )
    .await
    .expect("returns at once on SQLite");
}
