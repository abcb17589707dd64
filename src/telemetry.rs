//! Prometheus metrics of one process (an API server or a worker): what handlers and workers
//! record, and the exposition text a scrape of `/metrics` returns.
//!
//! Counters and histograms are kept by the `metrics` facade's global recorder, installed
//! once per process. Gauges of the queue (jobs by status, age of the oldest queued job) are
//! read from the database at scrape time instead, so every replica reports the same state.

use std::fmt::Write as _;
use std::sync::OnceLock;
use std::time::Duration;

use metrics_exporter_prometheus::{Matcher, PrometheusBuilder, PrometheusHandle};

/// Histogram of HTTP request durations, seconds, by `method`, `route` (the matched path
/// pattern, never the raw URI) and `status`.
pub const HTTP_REQUEST_DURATION: &str = "http_server_request_duration_seconds";
/// Gauge of HTTP requests being served.
pub const HTTP_ACTIVE_REQUESTS: &str = "http_server_active_requests";
/// Histogram of job run times, seconds, by `kind`, `model_type` and `outcome`.
pub const JOB_RUN_SECONDS: &str = "cohortforge_job_run_seconds";
/// Histogram of the time of each fit stage, seconds, by `model_type` and `stage`.
pub const FIT_STAGE_SECONDS: &str = "cohortforge_fit_stage_seconds";
/// Counter of cohort members drawn and kept, by `mode` (`sync` in the request, `job`).
pub const COHORT_MEMBERS_DRAWN: &str = "cohortforge_cohort_members_drawn_total";

/// Upper bounds of the request-duration buckets, seconds.
const HTTP_BUCKETS: [f64; 14] = [
    0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0,
];
/// Upper bounds of the job and stage buckets, seconds (a second to four hours).
const JOB_BUCKETS: [f64; 13] = [
    0.1, 1.0, 5.0, 15.0, 30.0, 60.0, 120.0, 300.0, 600.0, 1800.0, 3600.0, 7200.0, 14400.0,
];
/// Interval of the recorder's upkeep (draining histogram samples).
const UPKEEP: Duration = Duration::from_secs(5);

static HANDLE: OnceLock<Option<PrometheusHandle>> = OnceLock::new();

/// The process's recorder, installed on first use; `None` when another recorder was
/// installed first (metrics are then not exported).
pub fn handle() -> Option<&'static PrometheusHandle> {
    HANDLE
        .get_or_init(|| {
            let handle = install().map_err(|e| {
                tracing::warn!(error = %e, "metrics recorder not installed");
            });
            let handle = handle.ok()?;
            let upkeep = handle.clone();
            let _ = std::thread::Builder::new()
                .name("metrics-upkeep".into())
                .spawn(move || {
                    loop {
                        std::thread::sleep(UPKEEP);
                        upkeep.run_upkeep();
                    }
                });
            Some(handle)
        })
        .as_ref()
}

fn install() -> Result<PrometheusHandle, metrics_exporter_prometheus::BuildError> {
    PrometheusBuilder::new()
        .set_buckets_for_metric(Matcher::Full(HTTP_REQUEST_DURATION.into()), &HTTP_BUCKETS)?
        .set_buckets_for_metric(Matcher::Full(JOB_RUN_SECONDS.into()), &JOB_BUCKETS)?
        .set_buckets_for_metric(Matcher::Full(FIT_STAGE_SECONDS.into()), &JOB_BUCKETS)?
        .install_recorder()
}

/// Installs the recorder (idempotent): call at start so that the first requests count.
pub fn init() {
    let _ = handle();
    describe();
}

fn describe() {
    metrics::describe_histogram!(
        HTTP_REQUEST_DURATION,
        metrics::Unit::Seconds,
        "Time to answer an HTTP request, by method, matched route and status."
    );
    metrics::describe_gauge!(HTTP_ACTIVE_REQUESTS, "HTTP requests being answered.");
    metrics::describe_histogram!(
        JOB_RUN_SECONDS,
        metrics::Unit::Seconds,
        "Run time of jobs on this process's workers, by kind, model type and outcome."
    );
    metrics::describe_histogram!(
        FIT_STAGE_SECONDS,
        metrics::Unit::Seconds,
        "Time of each stage of the fits run on this process, by model type and stage."
    );
    metrics::describe_counter!(
        COHORT_MEMBERS_DRAWN,
        "Cohort members drawn and kept by this process, in requests (sync) or jobs (job)."
    );
}

/// Records the end of a job run on this process.
pub fn record_job_run(kind: &str, model_type: &str, outcome: &str, seconds: f64) {
    metrics::histogram!(JOB_RUN_SECONDS, "kind" => kind.to_owned(),
        "model_type" => model_type.to_owned(), "outcome" => outcome.to_owned())
    .record(seconds);
}

/// Records the stage times of a finished fit.
pub fn record_fit_stages<'a>(model_type: &str, stages: impl IntoIterator<Item = (&'a str, f64)>) {
    for (stage, seconds) in stages {
        metrics::histogram!(FIT_STAGE_SECONDS, "model_type" => model_type.to_owned(),
            "stage" => stage.to_owned())
        .record(seconds);
    }
}

/// Records members drawn and kept, `mode` `sync` (in a request) or `job`.
pub fn record_members_drawn(mode: &'static str, members: usize) {
    metrics::counter!(COHORT_MEMBERS_DRAWN, "mode" => mode).increment(members as u64);
}

/// Queue gauges read from the database at scrape time.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct QueueGauges {
    /// `(status, kind, model_type, count)` of every group of jobs.
    pub jobs: Vec<(String, String, String, i64)>,
    /// Age of the oldest queued job, seconds (0 when none waits).
    pub oldest_queued_seconds: f64,
}

/// The exposition text: the recorder's metrics, then the queue gauges.
pub fn render(queue: Option<&QueueGauges>) -> String {
    let mut text = handle().map(|h| h.render()).unwrap_or_default();
    if let Some(q) = queue {
        text.push_str(&render_queue(q));
    }
    text
}

fn render_queue(q: &QueueGauges) -> String {
    let mut out = String::new();
    out.push_str("# HELP cohortforge_jobs Jobs in the database, by status, kind and model type.\n");
    out.push_str("# TYPE cohortforge_jobs gauge\n");
    for (status, kind, model_type, count) in &q.jobs {
        let _ = writeln!(
            out,
            "cohortforge_jobs{{status=\"{}\",kind=\"{}\",model_type=\"{}\"}} {count}",
            escape(status),
            escape(kind),
            escape(model_type)
        );
    }
    out.push_str(
        "# HELP cohortforge_oldest_queued_job_age_seconds Time the oldest queued job has \
         waited for a worker (0 when none waits).\n",
    );
    out.push_str("# TYPE cohortforge_oldest_queued_job_age_seconds gauge\n");
    let _ = writeln!(
        out,
        "cohortforge_oldest_queued_job_age_seconds {}",
        q.oldest_queued_seconds
    );
    out
}

/// A label value with `\`, `"` and line breaks escaped as the exposition format wants.
fn escape(value: &str) -> String {
    value
        .replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', "\\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn queue_gauges_are_exposition_lines_with_escaped_labels() {
        let q = QueueGauges {
            jobs: vec![
                ("queued".into(), "fit".into(), "rsmp".into(), 2),
                ("failed".into(), "fit".into(), "a\"b\\c".into(), 1),
            ],
            oldest_queued_seconds: 12.5,
        };
        let text = render_queue(&q);
        assert!(
            text.contains(
                "cohortforge_jobs{status=\"queued\",kind=\"fit\",model_type=\"rsmp\"} 2\n"
            )
        );
        assert!(text.contains("model_type=\"a\\\"b\\\\c\"} 1\n"));
        assert!(text.contains("# TYPE cohortforge_oldest_queued_job_age_seconds gauge\n"));
        assert!(text.ends_with("cohortforge_oldest_queued_job_age_seconds 12.5\n"));
    }
}
