//! `GET /api/events`: server-sent events that keep the page current without polling. On connect the stream
//! sends `jobs` (the whole list) and `workers`; then one `job` event per scheduler event (the event and the
//! job's row after it), and `workers` again every few seconds while heartbeats move. Some changes publish no
//! event (a cancelled job's last running task being handed back), so on the same tick the jobs' rows are
//! compared with what this stream last sent and the changed ones are sent as `job` events of kind `refresh`.
//! A reader that falls behind gets a fresh `jobs` list instead of the events it missed.

use crate::json;
use crate::AppState;
use axum::extract::State;
use axum::response::sse::{Event, KeepAlive, Sse};
use futures::Stream;
use serde_json::{json, Value};
use std::collections::HashMap;
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

/// What a client was last told of each job (state and task counts), to send only what changed.
type Sent = HashMap<String, Value>;

fn seen(summary: &Value) -> Value {
    json!([summary["state"], summary["tasks"], summary["message"]])
}

fn jobs_event(s: &AppState, sent: &mut Sent) -> Event {
    match s.scheduler.list() {
        Ok(list) => {
            let jobs: Vec<Value> = list.iter().map(json::job_summary).collect();
            sent.clear();
            for j in &jobs {
                sent.insert(j["id"].as_str().unwrap_or_default().to_string(), seen(j));
            }
            event("jobs", &json!({ "jobs": jobs }))
        }
        Err(e) => event("problem", &json!({ "error": e.to_string() })),
    }
}

/// `job` events of kind `refresh` for the jobs whose row changed since it was last sent.
fn changed_jobs(s: &AppState, sent: &mut Sent) -> Vec<Event> {
    let Ok(list) = s.scheduler.list() else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for st in &list {
        let j = json::job_summary(st);
        let now = seen(&j);
        if sent.get(&st.job_id) != Some(&now) {
            sent.insert(st.job_id.clone(), now);
            out.push(event(
                "job",
                &json!({ "kind": "refresh", "task_key": "", "message": "", "job": j }),
            ));
        }
    }
    out
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
        let mut sent = Sent::new();
        let first = jobs_event(&s, &mut sent);
        if tx.send(first).await.is_err() || tx.send(workers_event(&s)).await.is_err() {
            return;
        }
        let mut tick = tokio::time::interval(WORKERS_EVERY);
        tick.tick().await;
        loop {
            let next: Vec<Event> = tokio::select! {
                ev = rx.recv() => match ev {
                    Ok(ev) => match s.scheduler.status(&ev.job_id, false) {
                        Ok(st) => {
                            let j = json::job_summary(&st);
                            sent.insert(st.job_id.clone(), seen(&j));
                            vec![event("job", &json!({
                                "kind": ev.kind,
                                "task_key": ev.task_key,
                                "message": ev.message,
                                "job": j,
                            }))]
                        }
                        Err(_) => continue,
                    },
                    Err(broadcast::error::RecvError::Lagged(_)) => vec![jobs_event(&s, &mut sent)],
                    Err(broadcast::error::RecvError::Closed) => return,
                },
                _ = tick.tick() => {
                    let mut v = changed_jobs(&s, &mut sent);
                    v.push(workers_event(&s));
                    v
                }
                _ = tx.closed() => return,
            };
            for e in next {
                if tx.send(e).await.is_err() {
                    return;
                }
            }
        }
    });
    Sse::new(ReceiverStream::new(out).map(Ok)).keep_alive(KeepAlive::default())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crease_coordinator::{CoordinatorConfig, Scheduler};

    #[tokio::test]
    async fn only_rows_that_changed_since_last_sent_are_pushed_again() {
        let dir = tempfile::tempdir().unwrap();
        let fixture =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/sleeve");
        let spec = format!(
            "input = {:?}\noutput = {:?}\n",
            fixture.display().to_string(),
            dir.path().join("out").display().to_string()
        );
        let scheduler = Scheduler::open(CoordinatorConfig::default()).unwrap();
        let (id, _) = scheduler.submit(&spec, "toml").await.unwrap();
        let s = AppState::new(std::sync::Arc::clone(&scheduler), Default::default(), false);
        let mut sent = Sent::new();
        // Nothing sent yet: the job is new to this stream.
        assert_eq!(changed_jobs(&s, &mut sent).len(), 1);
        assert_eq!(sent[&id][0], "queued");
        // Nothing changed: nothing is pushed.
        assert!(changed_jobs(&s, &mut sent).is_empty());
        // A change the stream did not see as an event is pushed on the next tick, once.
        scheduler.cancel(&id).unwrap();
        assert_eq!(changed_jobs(&s, &mut sent).len(), 1);
        assert_eq!(sent[&id][0], "cancelled");
        assert!(changed_jobs(&s, &mut sent).is_empty());
        // A full snapshot resets what was sent to exactly the listed jobs.
        sent.insert("job-gone".into(), Value::Null);
        let _ = jobs_event(&s, &mut sent);
        assert_eq!(sent.len(), 1);
        assert!(changed_jobs(&s, &mut sent).is_empty());
    }
}
