//! The JSON shapes of the API, built from the scheduler's own records so the page and scripts see the same
//! figures as `crease status` and `crease logs`.

use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use crease_coordinator::scheduler::WorkerView;
use crease_proto as pb;
use serde_json::{json, Value};

/// A JSON response that is never cached (it is live state).
pub fn reply(status: StatusCode, body: &Value) -> Response {
    (
        status,
        [
            (header::CONTENT_TYPE, "application/json"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        body.to_string(),
    )
        .into_response()
}

/// An error as `{"error": message}`.
pub fn error(status: StatusCode, message: impl Into<String>) -> Response {
    reply(status, &json!({ "error": message.into() }))
}

fn now_unix() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

/// Seconds from submission to the end (or to now while the job runs).
fn duration(s: &pb::JobStatus) -> f64 {
    let end = if s.finished_unix > 0.0 {
        s.finished_unix
    } else {
        now_unix()
    };
    (end - s.submitted_unix).max(0.0)
}

/// One row of the jobs list: counts for the stacked progress bar (CueWeb's done / running / dead / waiting).
pub fn job_summary(s: &pb::JobStatus) -> Value {
    let queued = s
        .tasks_total
        .saturating_sub(s.tasks_done + s.tasks_running + s.tasks_failed);
    json!({
        "id": s.job_id,
        "name": s.name,
        "state": s.state,
        "priority": s.priority,
        "tasks": {
            "total": s.tasks_total,
            "done": s.tasks_done,
            "running": s.tasks_running,
            "failed": s.tasks_failed,
            "queued": queued,
        },
        "message": s.message,
        "output": s.output,
        "submitted_unix": s.submitted_unix,
        "finished_unix": s.finished_unix,
        "duration_secs": duration(s),
        "work_secs": s.work_seconds,
    })
}

/// Stages of the task graph in the order they run; a kind not listed here sorts after them.
const STAGES: [(&str, &str); 13] = [
    ("relief", "fold relief (from the input alone)"),
    ("fold-steps", "fold steps (stretch)"),
    ("fold-phases", "fold phases (stretch)"),
    ("fold-detect", "fold detection"),
    ("fold-settle", "fold temporal coherence"),
    ("fold-merge", "fold merge"),
    ("fold-files", "fold files"),
    ("fold-plot", "fold plot (folds.png)"),
    ("weight-block", "weights (anchor blocks)"),
    ("weight-window", "weights (windows)"),
    ("reduce", "reduce"),
    ("position", "positioning"),
    ("finalize", "finalize"),
];

fn attempt_log(a: &pb::TaskAttemptLog) -> Value {
    json!({
        "attempt": a.attempt,
        "worker": a.worker,
        "outcome": a.outcome,
        "error": a.error,
        "started_unix": a.started_unix,
        "finished_unix": a.finished_unix,
        "lines": a.lines,
    })
}

/// The tasks of a job grouped by stage, each with its attempts' log tails.
pub fn stages(tasks: &[pb::TaskRow], logs: &[pb::TaskAttemptLog]) -> Value {
    let rank = |kind: &str| {
        STAGES
            .iter()
            .position(|(k, _)| *k == kind)
            .unwrap_or(STAGES.len())
    };
    let mut kinds: Vec<&str> = Vec::new();
    for t in tasks {
        if !kinds.contains(&t.kind.as_str()) {
            kinds.push(&t.kind);
        }
    }
    kinds.sort_by_key(|k| (rank(k), k.to_string()));
    let out: Vec<Value> = kinds
        .iter()
        .map(|kind| {
            let rows: Vec<&pb::TaskRow> = tasks.iter().filter(|t| t.kind == *kind).collect();
            let count = |state: &str| rows.iter().filter(|t| t.state == state).count();
            let label = STAGES
                .iter()
                .find(|(k, _)| k == kind)
                .map_or(*kind, |(_, l)| *l);
            json!({
                "kind": kind,
                "label": label,
                "counts": {
                    "total": rows.len(),
                    "done": count("done"),
                    "running": count("running"),
                    "failed": count("failed"),
                    "queued": rows.len() - count("done") - count("running") - count("failed"),
                },
                "tasks": rows.iter().map(|t| json!({
                    "key": t.key,
                    "state": t.state,
                    "attempts": t.attempts,
                    "worker": t.worker,
                    "work_secs": t.work_seconds,
                    "wall_secs": t.wall_seconds,
                    "last_error": t.last_error,
                    "logs": logs.iter().filter(|a| a.task_key == t.key).map(attempt_log).collect::<Vec<_>>(),
                })).collect::<Vec<_>>(),
            })
        })
        .collect();
    Value::Array(out)
}

pub fn worker(w: &WorkerView) -> Value {
    json!({
        "id": w.id,
        "name": w.name,
        "address": w.address,
        "capacity": w.capacity,
        "running": w.running,
        "free": if w.draining { 0 } else { w.capacity.saturating_sub(w.running) },
        "last_heartbeat_secs": w.last_seen_secs,
        "draining": w.draining,
        "tasks": w.tasks.iter().map(|(job, key, attempt)| json!({
            "job_id": job, "key": key, "attempt": attempt,
        })).collect::<Vec<_>>(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn task(key: &str, kind: &str, state: &str) -> pb::TaskRow {
        pb::TaskRow {
            key: key.into(),
            kind: kind.into(),
            state: state.into(),
            ..Default::default()
        }
    }

    #[test]
    fn tasks_are_grouped_by_stage_in_graph_order_with_their_own_logs() {
        let tasks = [
            task("finalize", "finalize", "queued"),
            task("position/f000000", "position", "done"),
            task("weights/w0000", "weight-window", "running"),
            task("position/f000010", "position", "failed"),
            task("odd", "something-new", "queued"),
        ];
        let logs = [pb::TaskAttemptLog {
            task_key: "position/f000010".into(),
            attempt: 2,
            lines: vec!["boom".into()],
            ..Default::default()
        }];
        let v = stages(&tasks, &logs);
        let kinds: Vec<&str> = v
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s["kind"].as_str().unwrap())
            .collect();
        assert_eq!(
            kinds,
            ["weight-window", "position", "finalize", "something-new"]
        );
        let pos = &v[1];
        assert_eq!(pos["label"], "positioning");
        assert_eq!(pos["counts"]["total"], 2);
        assert_eq!(pos["counts"]["done"], 1);
        assert_eq!(pos["counts"]["failed"], 1);
        assert_eq!(pos["tasks"][0]["logs"].as_array().unwrap().len(), 0);
        assert_eq!(pos["tasks"][1]["logs"][0]["attempt"], 2);
        assert_eq!(pos["tasks"][1]["logs"][0]["lines"][0], "boom");
    }

    #[test]
    fn queued_tasks_are_what_is_neither_done_running_nor_failed() {
        let s = pb::JobStatus {
            tasks_total: 10,
            tasks_done: 4,
            tasks_running: 2,
            tasks_failed: 1,
            submitted_unix: 100.0,
            finished_unix: 130.5,
            ..Default::default()
        };
        let v = job_summary(&s);
        assert_eq!(v["tasks"]["queued"], 3);
        assert_eq!(v["duration_secs"], 30.5);
    }
}
