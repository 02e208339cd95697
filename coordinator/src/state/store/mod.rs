//! The persistent queue: jobs, tasks, attempts, workers, per-worker failure counts and events in one SQLite
//! file (or in memory for local mode).
//!
//! Everything here is synchronous and transport-free, so the state machine of a task
//! (`blocked`/`queued` → `running` → `done` | `queued` again (retry) | `failed` | `cancelled`) is unit-tested
//! without gRPC. Every transition that must survive a crash happens in one transaction.

mod blocklist;
mod events;
mod jobs;
mod rows;
mod schema;
mod tasks;
#[cfg(test)]
mod tests;
mod worker_rows;

pub use blocklist::Blocked;
pub use schema::SCHEMA_VERSION;

use crease_jobs::FailureKind;
use rusqlite::Connection;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A task's state. A task is *ready* when it is `Queued`, its `not_before` has passed and all its
/// dependencies are `Done`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum TaskState {
    Queued,
    Running,
    Done,
    Failed,
    Cancelled,
}

impl TaskState {
    pub fn as_str(self) -> &'static str {
        match self {
            TaskState::Queued => "queued",
            TaskState::Running => "running",
            TaskState::Done => "done",
            TaskState::Failed => "failed",
            TaskState::Cancelled => "cancelled",
        }
    }
}

/// A job's state. `Waiting` = runnable work but no live worker (the grace period runs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum JobState {
    Queued,
    Running,
    Waiting,
    Done,
    Failed,
    Cancelled,
}

impl JobState {
    pub fn as_str(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Waiting => "waiting",
            JobState::Done => "done",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
        }
    }
    pub fn parse(s: &str) -> JobState {
        match s {
            "running" => JobState::Running,
            "waiting" => JobState::Waiting,
            "done" => JobState::Done,
            "failed" => JobState::Failed,
            "cancelled" => JobState::Cancelled,
            _ => JobState::Queued,
        }
    }
    /// Done, failed and cancelled jobs never change again.
    pub fn is_terminal(self) -> bool {
        matches!(
            self,
            JobState::Done | JobState::Failed | JobState::Cancelled
        )
    }
}

/// A new task as the planner describes it (kind + JSON payload + dependency keys).
#[derive(Debug, Clone)]
pub struct NewTask {
    pub key: String,
    pub kind: String,
    pub payload: String,
    pub deps: Vec<String>,
    pub expands: bool,
}

/// A new job.
#[derive(Debug, Clone)]
pub struct NewJob {
    pub name: String,
    /// The job spec (JSON) and the submit-time input inspection (JSON), kept for expand/final checks.
    pub spec_json: String,
    pub info_json: String,
    pub output: String,
    pub priority: i32,
    pub client_token: Option<String>,
    pub max_task_attempts: u32,
    pub max_failures: u32,
    pub tasks: Vec<NewTask>,
}

/// One row of the `jobs` table.
#[derive(Debug, Clone, PartialEq)]
pub struct JobRow {
    pub id: String,
    pub name: String,
    pub spec_json: String,
    pub info_json: String,
    pub output: String,
    pub priority: i32,
    pub state: JobState,
    pub message: String,
    pub max_task_attempts: u32,
    pub max_failures: u32,
    pub failures: u32,
    pub submitted: f64,
    pub finished: f64,
}

/// Task counts of a job.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Counts {
    pub total: u32,
    pub done: u32,
    pub running: u32,
    pub failed: u32,
    pub queued: u32,
    pub work_seconds: f64,
}

/// One row of the `tasks` table.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskRow {
    pub job_id: String,
    pub key: String,
    pub kind: String,
    pub payload: String,
    pub expands: bool,
    pub state: TaskState,
    pub attempts: u32,
    pub last_error: String,
    pub worker: String,
    pub work_seconds: f64,
    /// Wall time of the successful attempt, dispatch to report (0 until done).
    pub wall_seconds: f64,
}

/// A task handed to a worker: the attempt number identifies this try.
#[derive(Debug, Clone, PartialEq)]
pub struct Claim {
    pub job_id: String,
    pub key: String,
    pub kind: String,
    pub payload: String,
    pub attempt: u32,
    pub expands: bool,
}

impl Claim {
    /// An attempt known only by its identity (a lost worker's or an orphaned one): enough to fail it.
    pub fn of_attempt(job_id: &str, key: &str, attempt: u32) -> Self {
        Claim {
            job_id: job_id.to_string(),
            key: key.to_string(),
            kind: String::new(),
            payload: String::new(),
            attempt,
            expands: false,
        }
    }
}

/// What became of a reported attempt.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// The report is for an attempt the coordinator already gave up on (or a finished job): ignored.
    Stale,
    /// The task is done (and the job too when `job_done`).
    Done { job_done: bool },
    /// The task goes back to the queue for another attempt.
    Retry { attempt: u32 },
    /// The job failed; the message names the task and the error.
    JobFailed { message: String },
    /// The task stopped because its job was cancelled.
    Cancelled,
}

/// A task failure as the store sees it: its kind decides the retry policy (see
/// [`crease_jobs::FailureKind::policy`]); the reason is for people.
#[derive(Debug, Clone, PartialEq)]
pub struct Failure {
    pub kind: FailureKind,
    pub reason: String,
}

impl Failure {
    pub fn new(kind: FailureKind, reason: impl Into<String>) -> Self {
        Failure {
            kind,
            reason: reason.into(),
        }
    }
    /// Another attempt may succeed.
    pub fn retryable(&self) -> bool {
        self.kind.policy().retryable
    }
    /// Counts towards the task's attempt limit, the job's failure limit and the worker's blocklist.
    pub fn counts(&self) -> bool {
        self.kind.policy().counts
    }
}

/// A persisted event.
#[derive(Debug, Clone, PartialEq)]
pub struct EventRow {
    pub id: i64,
    pub job_id: String,
    pub time: f64,
    pub kind: String,
    pub task_key: String,
    pub message: String,
}

/// One attempt of a task with its log lines (`crease logs`).
#[derive(Debug, Clone, PartialEq)]
pub struct AttemptLog {
    pub task_key: String,
    pub attempt: u32,
    pub worker: String,
    pub outcome: String,
    /// The failure kind of a failed or handed-back attempt (a [`FailureKind`] name), else empty.
    pub kind: String,
    pub error: String,
    pub started: f64,
    pub finished: f64,
    pub lines: Vec<String>,
}

/// Queue figures for the metrics endpoint.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct QueueGauges {
    /// Tasks queued and runnable now (dependencies done, backoff over, job active).
    pub queue_depth: i64,
    pub tasks_running: i64,
    /// Jobs per state.
    pub jobs: Vec<(String, i64)>,
}

/// Store errors (SQLite or corrupt rows); they name the job or task when they concern one.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("queue database: {0}")]
    Sql(#[from] rusqlite::Error),
    #[error("job {0} not found")]
    NoSuchJob(String),
    #[error(
        "client_token `{token}` already names job {job}, submitted with another spec; a token stands for one \
         submission: give this job a new token (or resubmit {job}'s spec unchanged to get {job} back)"
    )]
    TokenReused { token: String, job: String },
    #[error(
        "output {output} is being written by job {job} ({state}); wait for it to end, cancel it \
         (`crease cancel {job}`), or choose another output"
    )]
    OutputBusy {
        output: String,
        job: String,
        state: String,
    },
    #[error(
        "queue file {what} has schema version {found}, newer than this crease knows ({known}); run the crease \
         that wrote it, or start with another --db"
    )]
    TooNew {
        what: String,
        found: u32,
        known: u32,
    },
    #[error("queue file {what}: upgrading its schema to version {version} failed: {source}")]
    Migration {
        what: String,
        version: u32,
        source: rusqlite::Error,
    },
}

pub type Result<T, E = StoreError> = std::result::Result<T, E>;

/// Seconds since the Unix epoch (the store's clock).
pub fn now() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

/// The queue database.
pub struct Store {
    conn: Connection,
}

impl Store {
    /// Opens (or creates) the queue file.
    pub fn open(path: &Path) -> Result<Self> {
        let conn = Connection::open(path)?;
        conn.pragma_update(None, "journal_mode", "WAL")?;
        conn.pragma_update(None, "synchronous", "NORMAL")?;
        Self::init(conn, &path.display().to_string())
    }

    /// A queue that lives as long as the process (local single-node mode, tests).
    pub fn in_memory() -> Result<Self> {
        Self::init(Connection::open_in_memory()?, "(in memory)")
    }

    fn init(mut conn: Connection, what: &str) -> Result<Self> {
        schema::migrate(&mut conn, what)?;
        Ok(Store { conn })
    }

    /// Restart recovery: every worker must register again. Tasks that were running when the coordinator
    /// stopped stay running under their attempt number: their workers keep running them and, registering
    /// again, adopt them ([`Store::adopt`]); the scheduler queues again those nobody adopts in time (a failure
    /// of kind `coordinator-restart`, which does not count). Returns those attempts (job, key, attempt, worker).
    pub fn recover(&mut self) -> Result<Vec<(String, String, u32, String)>> {
        self.conn.execute(
            "UPDATE workers SET state = 'lost' WHERE state != 'lost'",
            [],
        )?;
        self.running_tasks(None)
    }
}
