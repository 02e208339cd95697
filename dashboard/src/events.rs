//! `GET /api/events`: server-sent events that keep the page current without polling. On connect the stream
//! sends `jobs` (the whole list) and `workers`; then one `job` event per scheduler event (the event and the
//! job's row after it), and `workers` again every few seconds while heartbeats move. A reader that falls
//! behind gets a fresh `jobs` list instead of the events it missed.

use crate::json;
use crate::AppState;
use axum::extract::State;
use axum::response::sse::{Event, KeepAlive, Sse};
use futures::Stream;
use serde_json::{json, Value};
use std::convert::Infallible;
use std::time::Duration;
use tokio::sync::{broadcast, mpsc};
use tokio_stream::wrappers::ReceiverStream;
use tokio_stream::StreamExt;

/// How often the workers list is pushed (heartbeat ages change without scheduler events).
const WORKERS_EVERY: Duration = Duration::from_secs(2);

fn event(name: &str, data: &Value) -> Event {
    Event::default().event(name).data(data.to_string())
}

fn jobs_event(s: &AppState) -> Event {
    match s.scheduler.list() {
        Ok(list) => event(
            "jobs",
            &json!({ "jobs": list.iter().map(json::job_summary).collect::<Vec<_>>() }),
        ),
        Err(e) => event("problem", &json!({ "error": e.to_string() })),
    }
}

fn workers_event(s: &AppState) -> Event {
    match s.scheduler.workers_view() {
        Ok(ws) => event(
            "workers",
            &json!({ "workers": ws.iter().map(json::worker).collect::<Vec<_>>() }),
        ),
        Err(e) => event("problem", &json!({ "error": e.to_string() })),
    }
}

pub async fn stream(
    State(s): State<AppState>,
) -> Sse<impl Stream<Item = Result<Event, Infallible>>> {
    let mut rx = s.scheduler.subscribe();
    let (tx, out) = mpsc::channel::<Event>(64);
    tokio::spawn(async move {
        if tx.send(jobs_event(&s)).await.is_err() || tx.send(workers_event(&s)).await.is_err() {
            return;
        }
        let mut tick = tokio::time::interval(WORKERS_EVERY);
        tick.tick().await;
        loop {
            let next = tokio::select! {
                ev = rx.recv() => match ev {
                    Ok(ev) => match s.scheduler.status(&ev.job_id, false) {
                        Ok(st) => event("job", &json!({
                            "kind": ev.kind,
                            "task_key": ev.task_key,
                            "message": ev.message,
                            "job": json::job_summary(&st),
                        })),
                        Err(_) => continue,
                    },
                    Err(broadcast::error::RecvError::Lagged(_)) => jobs_event(&s),
                    Err(broadcast::error::RecvError::Closed) => return,
                },
                _ = tick.tick() => workers_event(&s),
                _ = tx.closed() => return,
            };
            if tx.send(next).await.is_err() {
                return;
            }
        }
    });
    Sse::new(ReceiverStream::new(out).map(Ok)).keep_alive(KeepAlive::default())
}
