//! `crease logs JOB [TASK]`: the log tail of a job's task attempts as the coordinator keeps it (its own lines
//! about dispatch, outcome and retries, and the tail each worker sent back), per task and attempt.

use crate::client::{runtime, ClientArgs};
use anyhow::Result;
use clap::Args;
use crease_coordinator::JobClient;
use crease_proto as pb;

#[derive(Args, Debug)]
pub struct LogsArgs {
    /// Job id.
    pub job: String,
    /// Task key (every task of the job when omitted).
    pub task: Option<String>,
    #[command(flatten)]
    pub client: ClientArgs,
}

pub fn logs(a: LogsArgs) -> Result<()> {
    runtime()?.block_on(async move {
        let client = a.client.connect().await?;
        let attempts = client.logs(&a.job, a.task.as_deref()).await?;
        print!("{}", render(&a.job, a.task.as_deref(), &attempts));
        Ok(())
    })
}

/// One block per attempt: a header naming task, attempt, worker and outcome, then the lines.
fn render(job: &str, task: Option<&str>, attempts: &[pb::TaskAttemptLog]) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    if attempts.is_empty() {
        let _ = match task {
            Some(t) => writeln!(out, "task `{t}` of {job} has not run yet"),
            None => writeln!(out, "no task of {job} has run yet"),
        };
        return out;
    }
    for a in attempts {
        let worker = if a.worker.is_empty() { "-" } else { &a.worker };
        let secs = if a.finished_unix > a.started_unix {
            format!(", {:.2}s", a.finished_unix - a.started_unix)
        } else {
            String::new()
        };
        let _ = writeln!(
            out,
            "== task `{}` attempt {} on {worker}: {}{secs} ==",
            a.task_key, a.attempt, a.outcome
        );
        for l in &a.lines {
            let _ = writeln!(out, "  {l}");
        }
        if a.lines.is_empty() {
            let _ = writeln!(out, "  (no log lines)");
        }
        if !a.error.is_empty() && !a.lines.iter().any(|l| l.contains(&a.error)) {
            let _ = writeln!(out, "  error: {}", a.error);
        }
    }
    out
}
