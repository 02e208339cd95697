//! Following a job from a client (`crease watch`, `crease submit --watch`): a progress bar fed by the
//! coordinator's event stream that rides out a coordinator restart, and an exit status that says how the job
//! ended.
//!
//! The coordinator keeps its queue in SQLite, so a restart loses no job: the client only has to find it again.
//! When the stream breaks before the job has ended, the client reconnects with exponential backoff and
//! resumes from a fresh snapshot (GetJob, then WatchJob, whose first event is a snapshot too), saying so on
//! stderr. It gives up after `--reconnect-secs` and exits with its own code, so a script can tell "the job
//! failed" from "I lost sight of it".

use crate::client::{runtime, ClientArgs};
use crate::progress::CliProgress;
use anyhow::Result;
use clap::Args;
use crease_coordinator::{ClientError, EventStream, JobClient};
use crease_core::progress::Progress;
use crease_proto as pb;
use futures::StreamExt;
use std::time::{Duration, Instant};

/// Exit status of a command that follows a job (also in `crease watch --help` and docs/cluster.md).
pub const EXIT_CODES: &str = "\
Exit status:
  0  the job is done
  1  the command itself failed (unknown job, refused token, bad flags, ...); the message says why
  2  usage error (clap)
  3  the job failed (the message names the task and its reason)
  4  the job was cancelled
  5  lost the coordinator: it could not be reached for --reconnect-secs";

pub const EXIT_FAILED: i32 = 3;
pub const EXIT_CANCELLED: i32 = 4;
pub const EXIT_LOST: i32 = 5;

/// A follow that ended without the job being done; `main` exits with `code` after printing the message.
#[derive(Debug)]
pub struct Ended {
    pub code: i32,
    pub message: String,
}

impl std::fmt::Display for Ended {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Ended {}

/// How long a client keeps trying to reach a coordinator that went away.
#[derive(Args, Debug, Clone)]
pub struct ReconnectArgs {
    /// Seconds to keep reconnecting to a coordinator that went away (a restart) before giving up (exit 5).
    #[arg(long, default_value_t = 120.0)]
    pub reconnect_secs: f64,
}

impl ReconnectArgs {
    fn budget(&self) -> Result<Duration> {
        if !(self.reconnect_secs.is_finite() && self.reconnect_secs >= 0.0) {
            anyhow::bail!(
                "--reconnect-secs must be a non-negative number, got {}",
                self.reconnect_secs
            );
        }
        Ok(Duration::from_secs_f64(self.reconnect_secs))
    }
}

#[derive(Args, Debug)]
pub struct WatchArgs {
    /// Job id, as `crease submit` printed it (`crease jobs` lists them).
    pub job: String,
    #[command(flatten)]
    pub client: ClientArgs,
    #[command(flatten)]
    pub reconnect: ReconnectArgs,
}

pub fn watch(a: WatchArgs) -> Result<()> {
    runtime()?.block_on(async move {
        let progress = CliProgress::new(false);
        let status = follow_remote(&a.client, &a.reconnect, &a.job, &progress).await?;
        finish(&status)
    })
}

pub fn is_terminal(state: &str) -> bool {
    matches!(state, "done" | "failed" | "cancelled")
}

/// Ok for a done job; an [`Ended`] with the job's exit code and reason otherwise.
pub fn finish(s: &pb::JobStatus) -> Result<()> {
    let code = match s.state.as_str() {
        "done" => {
            eprintln!(
                "{} done: {} tasks, {:.2}s of work",
                s.job_id, s.tasks_total, s.work_seconds
            );
            return Ok(());
        }
        "cancelled" => EXIT_CANCELLED,
        _ => EXIT_FAILED,
    };
    Err(Ended {
        code,
        message: format!("job {} {}: {}", s.job_id, s.state, s.message),
    }
    .into())
}

/// The progress display of one follow, kept across reconnections so the bar resumes where it was.
pub struct Follower<'a> {
    job_id: String,
    progress: Option<&'a CliProgress>,
    total: u64,
    shown: u64,
    /// Long tasks with a bar of their own (fold detection), with the units shown so far.
    task_bars: std::collections::BTreeMap<String, u64>,
    pub last: Option<pb::JobStatus>,
}

impl<'a> Follower<'a> {
    pub fn new(job_id: &str, progress: Option<&'a CliProgress>) -> Self {
        Follower {
            job_id: job_id.to_string(),
            progress,
            total: 0,
            shown: 0,
            task_bars: Default::default(),
            last: None,
        }
    }

    /// The job's state as last seen, if it has ended.
    pub fn ended(&self) -> Option<&pb::JobStatus> {
        self.last.as_ref().filter(|s| is_terminal(&s.state))
    }

    /// Moves the bar to `done` of `total` tasks (a snapshot), or on by one (a task_done).
    fn tasks(&mut self, done: u64, total: u64) {
        let Some(p) = self.progress else { return };
        if total != self.total && total > 0 {
            if self.total > 0 {
                p.abandon("tasks", "replanned");
            }
            self.total = total;
            self.shown = 0;
            p.begin("tasks", total);
        }
        if done > self.shown && self.total > 0 {
            p.advance("tasks", done - self.shown);
            self.shown = done;
        }
    }

    /// Reads events until the stream ends (Ok) or breaks (Err).
    pub async fn consume(&mut self, mut stream: EventStream) -> Result<(), ClientError> {
        while let Some(ev) = stream.next().await {
            let ev = ev?;
            match ev.kind.as_str() {
                "snapshot" => self.tasks(ev.done, ev.total),
                "task_done" => {
                    self.task_ended(&ev.task_key, "done");
                    let done = if ev.total == self.total {
                        ev.done.max(self.shown + 1)
                    } else {
                        ev.done
                    };
                    self.tasks(done, ev.total)
                }
                "task_progress" => self.task_progress(&ev),
                "task_retry" => {
                    self.task_ended(&ev.task_key, "attempt failed");
                    self.say(&format!(
                        "{}: task `{}` attempt failed: {}",
                        self.job_id, ev.task_key, ev.message
                    ))
                }
                "job_waiting" | "job_failed" | "job_cancelled" | "job_resumed" => {
                    self.say(&format!("{}: {}", self.job_id, ev.message))
                }
                _ => {}
            }
            if let Some(s) = ev.status {
                self.last = Some(s);
            }
        }
        Ok(())
    }

    /// A fold-detection task runs over many frames as one task, so the task bar alone would sit still while
    /// it works: it gets a bar of its own, fed by the units (frames) its worker reports.
    fn task_progress(&mut self, ev: &pb::JobEvent) {
        let Some(p) = self.progress else { return };
        if !ev.task_key.starts_with("folds/") || ev.total == 0 {
            return;
        }
        if !self.task_bars.contains_key(&ev.task_key) {
            p.begin(&ev.task_key, ev.total);
        }
        let shown = self.task_bars.entry(ev.task_key.clone()).or_insert(0);
        if ev.done > *shown {
            p.advance(&ev.task_key, ev.done - *shown);
            *shown = ev.done;
        }
    }

    fn task_ended(&mut self, key: &str, how: &str) {
        if let (Some(p), Some(_)) = (self.progress, self.task_bars.remove(key)) {
            if how == "done" {
                p.end(key);
            } else {
                p.abandon(key, how);
            }
        }
    }

    fn say(&self, msg: &str) {
        if let Some(p) = self.progress {
            p.println(msg);
        }
    }

    /// Closes the bars: "done" only for a done job.
    pub fn close(&mut self) {
        let Some(p) = self.progress else { return };
        for key in std::mem::take(&mut self.task_bars).into_keys() {
            p.abandon(&key, "stopped");
        }
        if self.total == 0 {
            return;
        }
        match self.last.as_ref().map(|s| s.state.as_str()) {
            Some("done") => p.end("tasks"),
            Some(state) => p.abandon("tasks", state),
            None => p.abandon("tasks", "unknown"),
        }
        self.total = 0;
    }
}

/// Follows a job to its end through a client that cannot go away (single-node mode, benchmarks).
pub async fn follow(
    client: &impl JobClient,
    job_id: &str,
    progress: Option<&CliProgress>,
) -> Result<pb::JobStatus> {
    let mut f = Follower::new(job_id, progress);
    let outcome = f.consume(client.watch(job_id).await?).await;
    f.close();
    outcome?;
    match f.ended() {
        Some(s) => Ok(s.clone()),
        None => Ok(client.status(job_id, false).await?),
    }
}

/// Follows a job on a remote coordinator to its end, reconnecting when the coordinator restarts.
pub async fn follow_remote(
    args: &ClientArgs,
    reconnect: &ReconnectArgs,
    job_id: &str,
    progress: &CliProgress,
) -> Result<pb::JobStatus> {
    let budget = reconnect.budget()?;
    let url = &args.coordinator;
    let client = args.connect().await.map_err(|e| Ended {
        code: EXIT_LOST,
        message: format!("{e:#}"),
    })?;
    let mut f = Follower::new(job_id, Some(progress));
    // The first WatchJob answers for the job id: an unknown job is an ordinary error, not a lost coordinator.
    let mut stream = Some(client.watch(job_id).await?);
    loop {
        let broke = match stream.take() {
            Some(s) => f.consume(s).await.err(),
            None => None,
        };
        if let Some(s) = f.ended() {
            let s = s.clone();
            f.close();
            return Ok(s);
        }
        // The stream ended or broke with the job still going: usually the coordinator stopping.
        let why = broke.map_or_else(|| "the event stream ended".to_string(), |e| e.0);
        progress.println(&format!(
            "{job_id}: lost the coordinator at {url} ({why}); reconnecting for up to {:.0}s",
            budget.as_secs_f64()
        ));
        let started = Instant::now();
        let mut delay = Duration::from_millis(250);
        let mut attempts = 0u32;
        let s = loop {
            attempts += 1;
            let tried = async {
                let c = args.connect().await?;
                let s = c.status(job_id, false).await?;
                let stream = c.watch(job_id).await?;
                anyhow::Ok((s, stream))
            }
            .await;
            match tried {
                Ok((s, st)) => {
                    stream = Some(st);
                    break s;
                }
                Err(e) if started.elapsed() + delay > budget => {
                    f.close();
                    return Err(Ended {
                        code: EXIT_LOST,
                        message: format!(
                            "{job_id}: gave up reconnecting to the coordinator at {url} after {:.1}s \
                             ({attempts} attempts): {e:#}; the job may still be running (crease status {job_id})",
                            started.elapsed().as_secs_f64()
                        ),
                    }
                    .into());
                }
                Err(_) => {
                    tokio::time::sleep(delay).await;
                    delay = (delay * 2).min(Duration::from_secs(5));
                }
            }
        };
        progress.println(&format!(
            "{job_id}: reconnected to the coordinator after {:.1}s; resuming from its snapshot: {} {}/{} tasks done",
            started.elapsed().as_secs_f64(),
            s.state,
            s.tasks_done,
            s.tasks_total
        ));
        f.tasks(s.tasks_done as u64, s.tasks_total as u64);
        f.last = Some(s);
    }
}
