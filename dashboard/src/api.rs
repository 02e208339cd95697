//! The JSON API the page uses: `GET /api/jobs[?state=S]`, `GET /api/jobs/{id}`, `GET /api/workers`,
//! `POST /api/jobs/{id}/cancel`, `POST /api/jobs/{id}/resubmit`. Scheduler errors keep their meaning: an
//! unknown job is 404, a refused spec 400, anything else 500 with the scheduler's message.

use crate::errors::{api_error, plausible_id};
use crate::json::{self, error, reply};
use crate::AppState;
use axum::extract::{Path, RawQuery, State};
use axum::http::StatusCode;
use axum::response::Response;
use serde_json::{json, Value};

/// The states a job can be in, for the `state` filter (anything else is a 400 naming these).
const JOB_STATES: [&str; 6] = [
    "queued",
    "running",
    "waiting",
    "done",
    "failed",
    "cancelled",
];

fn no_such_job(id: &str) -> Response {
    error(StatusCode::NOT_FOUND, format!("job {id} not found"))
}

/// The value of `name` in a query string (no percent-decoding: the values asked for are plain words).
fn query_value<'a>(query: &'a str, name: &str) -> Option<&'a str> {
    query
        .split('&')
        .filter_map(|kv| kv.split_once('='))
        .find(|(k, _)| *k == name)
        .map(|(_, v)| v)
}

pub async fn jobs(State(s): State<AppState>, RawQuery(query): RawQuery) -> Response {
    let filter = query.as_deref().and_then(|q| query_value(q, "state"));
    let wanted: Option<Vec<&str>> = match filter {
        None | Some("") | Some("all") => None,
        Some(f) => {
            let states: Vec<&str> = f.split(',').collect();
            if let Some(bad) = states.iter().find(|st| !JOB_STATES.contains(st)) {
                return error(
                    StatusCode::BAD_REQUEST,
                    format!(
                        "state filter `{bad}` is not a job state (one of {} or all)",
                        JOB_STATES.join(", ")
                    ),
                );
            }
            Some(states)
        }
    };
    match s.scheduler.list() {
        Ok(list) => {
            let jobs: Vec<Value> = list
                .iter()
                .filter(|j| {
                    wanted
                        .as_ref()
                        .is_none_or(|w| w.contains(&j.state.as_str()))
                })
                .map(json::job_summary)
                .collect();
            reply(StatusCode::OK, &json!({ "jobs": jobs }))
        }
        Err(e) => api_error(e),
    }
}

pub async fn job(State(s): State<AppState>, Path(id): Path<String>) -> Response {
    if !plausible_id(&id) {
        return no_such_job(&id);
    }
    let status = match s.scheduler.status(&id, true) {
        Ok(st) => st,
        Err(e) => return api_error(e),
    };
    let logs = match s.scheduler.task_logs(&id, None) {
        Ok(l) => l.attempts,
        Err(e) => return api_error(e),
    };
    let mut v = json::job_summary(&status);
    v["stages"] = json::stages(&status.tasks, &logs);
    let (files, report) = crate::files::outputs(&id, &status.output).await;
    v["files"] = files;
    v["report"] = report;
    reply(StatusCode::OK, &v)
}

pub async fn workers(State(s): State<AppState>) -> Response {
    match s.scheduler.workers_view() {
        Ok(ws) => reply(
            StatusCode::OK,
            &json!({ "workers": ws.iter().map(json::worker).collect::<Vec<_>>() }),
        ),
        Err(e) => api_error(e),
    }
}

pub async fn cancel(State(s): State<AppState>, Path(id): Path<String>) -> Response {
    if !plausible_id(&id) {
        return no_such_job(&id);
    }
    match s.scheduler.cancel(&id) {
        Ok(state) => {
            tracing::info!(job_id = %id, "dashboard: job {id} cancel requested, now {}", state.as_str());
            reply(
                StatusCode::OK,
                &json!({ "id": id, "state": state.as_str() }),
            )
        }
        Err(e) => api_error(e),
    }
}

/// Submits the job's stored spec again as a new job (its idempotency token is dropped, or the old job would
/// be returned).
pub async fn resubmit(State(s): State<AppState>, Path(id): Path<String>) -> Response {
    if !plausible_id(&id) {
        return no_such_job(&id);
    }
    let spec = match s.scheduler.job_spec_json(&id) {
        Ok(t) => t,
        Err(e) => return api_error(e),
    };
    let mut spec: Value = match serde_json::from_str(&spec) {
        Ok(v) => v,
        Err(e) => {
            return error(
                StatusCode::INTERNAL_SERVER_ERROR,
                format!("job {id}: the stored spec is unreadable: {e}"),
            )
        }
    };
    if let Some(obj) = spec.as_object_mut() {
        obj.remove("client_token");
    }
    match s.scheduler.submit(&spec.to_string(), "json").await {
        Ok((new_id, _)) => {
            tracing::info!(job_id = %new_id, "dashboard: job {id} resubmitted as {new_id}");
            reply(
                StatusCode::CREATED,
                &json!({ "id": new_id, "resubmitted_from": id }),
            )
        }
        Err(e) => api_error(e),
    }
}

pub async fn not_found() -> Response {
    error(StatusCode::NOT_FOUND, "no such page")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn query_values_are_found_by_name() {
        assert_eq!(query_value("a=1&state=done", "state"), Some("done"));
        assert_eq!(query_value("states=done", "state"), None);
    }
}
