//! `GET /v1/jobs/{id}/events`: a job's progress as server-sent events, for dashboards that
//! would rather listen than poll.

use std::convert::Infallible;
use std::time::Duration;

use axum::extract::State;
use axum::response::sse::{Event, KeepAlive, Sse};
use futures_util::Stream;

use super::AppState;
use super::error::{ApiError, Problem};
use super::extract::Path;
use crate::store::Store;

/// How often the job record is read for changes.
const POLL_INTERVAL: Duration = Duration::from_millis(250);

/// Where the stream is: the last job record sent (as JSON) and whether it has ended.
struct Cursor {
    store: Store,
    id: String,
    last_sent: Option<String>,
    ended: bool,
}

/// Follow a job: a `progress` event with the job record (as `GET /v1/jobs/{id}` returns it)
/// whenever its status or progress changes, then one `end` event with the final record when
/// it succeeds, fails or is cancelled, after which the stream closes.
#[utoipa::path(
    get, path = "/v1/jobs/{id}/events", tag = "jobs",
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 200, description = "Server-sent events `progress` and `end`, each with the job record as JSON data", content_type = "text/event-stream", body = String),
        (status = 404, description = "No such job", body = Problem, content_type = "application/problem+json"),
    )
)]
pub(super) async fn job_events(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Sse<impl Stream<Item = Result<Event, Infallible>>>, ApiError> {
    state.store.job(&id).await?;
    let cursor = Cursor {
        store: state.store.clone(),
        id,
        last_sent: None,
        ended: false,
    };
    let stream = futures_util::stream::unfold(cursor, |mut cursor| async move {
        next_event(&mut cursor)
            .await
            .map(|event| (Ok(event), cursor))
    });
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}

/// Waits for the next change of the job; `None` once the `end` event has gone out.
async fn next_event(cursor: &mut Cursor) -> Option<Event> {
    if cursor.ended {
        return None;
    }
    loop {
        let job = match cursor.store.job(&cursor.id).await {
            Ok(job) => job,
            Err(e) => {
                // The job was deleted or the database failed: say so and close.
                cursor.ended = true;
                return Some(Event::default().event("error").data(e.to_string()));
            }
        };
        let data = serde_json::to_string(&job).unwrap_or_default();
        if job.status.is_final() {
            cursor.ended = true;
            return Some(Event::default().event("end").data(data));
        }
        if cursor.last_sent.as_deref() != Some(data.as_str()) {
            cursor.last_sent = Some(data.clone());
            return Some(Event::default().event("progress").data(data));
        }
        tokio::time::sleep(POLL_INTERVAL).await;
    }
}
