//! The persistent queue: jobs, tasks, attempts, workers, per-worker failure counts and events in one SQLite
//! file (or in memory for local mode).
//!
//! Everything here is synchronous and transport-free, so the state machine of a task
//! (`blocked`/`queued` → `running` → `done` | `queued` again (retry) | `failed` | `cancelled`) is unit-tested
//! without gRPC. Every transition that must survive a crash happens in one transaction.

use rusqlite::{params, Connection, OptionalExtension, Transaction};
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

/// A task failure as the store sees it (typed: the retry policy reads fields, not strings).
#[derive(Debug, Clone, PartialEq)]
pub struct Failure {
    pub retryable: bool,
    /// Counts towards the task's attempt limit and the job's failure limit. A coordinator restart does not.
    pub counts: bool,
    /// A cancellation (job cancelled or worker draining).
    pub cancelled: bool,
    pub reason: String,
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
}

pub type Result<T, E = StoreError> = std::result::Result<T, E>;

const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS jobs (
    seq INTEGER PRIMARY KEY AUTOINCREMENT,
    id TEXT NOT NULL UNIQUE,
    name TEXT NOT NULL,
    spec TEXT NOT NULL,
    info TEXT NOT NULL,
    output TEXT NOT NULL,
    priority INTEGER NOT NULL,
    client_token TEXT UNIQUE,
    state TEXT NOT NULL,
    message TEXT NOT NULL DEFAULT '',
    max_task_attempts INTEGER NOT NULL,
    max_failures INTEGER NOT NULL,
    failures INTEGER NOT NULL DEFAULT 0,
    submitted REAL NOT NULL,
    finished REAL NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS tasks (
    seq INTEGER PRIMARY KEY AUTOINCREMENT,
    job_id TEXT NOT NULL,
    key TEXT NOT NULL,
    kind TEXT NOT NULL,
    payload TEXT NOT NULL,
    expands INTEGER NOT NULL,
    state TEXT NOT NULL,
    attempts INTEGER NOT NULL DEFAULT 0,
    last_error TEXT NOT NULL DEFAULT '',
    worker TEXT NOT NULL DEFAULT '',
    output TEXT NOT NULL DEFAULT '',
    work_seconds REAL NOT NULL DEFAULT 0,
    not_before REAL NOT NULL DEFAULT 0,
    UNIQUE (job_id, key)
);
CREATE TABLE IF NOT EXISTS deps (
    job_id TEXT NOT NULL,
    key TEXT NOT NULL,
    dep TEXT NOT NULL,
    PRIMARY KEY (job_id, key, dep)
);
CREATE TABLE IF NOT EXISTS attempts (
    job_id TEXT NOT NULL,
    task_key TEXT NOT NULL,
    attempt INTEGER NOT NULL,
    worker TEXT NOT NULL,
    started REAL NOT NULL,
    finished REAL NOT NULL DEFAULT 0,
    outcome TEXT NOT NULL DEFAULT 'running',
    error TEXT NOT NULL DEFAULT '',
    PRIMARY KEY (job_id, task_key, attempt)
);
CREATE TABLE IF NOT EXISTS workers (
    id TEXT PRIMARY KEY,
    name TEXT NOT NULL,
    address TEXT NOT NULL,
    capacity INTEGER NOT NULL,
    registered REAL NOT NULL,
    state TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS worker_failures (
    job_id TEXT NOT NULL,
    worker TEXT NOT NULL,
    count INTEGER NOT NULL,
    PRIMARY KEY (job_id, worker)
);
CREATE TABLE IF NOT EXISTS events (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    job_id TEXT NOT NULL,
    time REAL NOT NULL,
    kind TEXT NOT NULL,
    task_key TEXT NOT NULL,
    message TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS tasks_state ON tasks (state, job_id);
CREATE TABLE IF NOT EXISTS task_logs (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    job_id TEXT NOT NULL,
    task_key TEXT NOT NULL,
    attempt INTEGER NOT NULL,
    line TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS task_logs_attempt ON task_logs (job_id, task_key, attempt);
CREATE INDEX IF NOT EXISTS jobs_state ON jobs (state);
";

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
        Self::init(conn)
    }

    /// A queue that lives as long as the process (local single-node mode, tests).
    pub fn in_memory() -> Result<Self> {
        Self::init(Connection::open_in_memory()?)
    }

    fn init(conn: Connection) -> Result<Self> {
        conn.execute_batch(SCHEMA)?;
        Ok(Store { conn })
    }

    /// Restart recovery: tasks that were running when the coordinator stopped go back to the queue (their
    /// attempt is closed as `coordinator-restart` and does not count as a failure), and every worker must
    /// register again. Returns the number of re-queued tasks.
    pub fn recover(&mut self) -> Result<usize> {
        let tx = self.conn.transaction()?;
        let t = now();
        tx.execute(
            "UPDATE attempts SET outcome = 'coordinator-restart', finished = ?1 WHERE outcome = 'running'",
            params![t],
        )?;
        let n = tx.execute(
            "UPDATE tasks SET state = 'queued', worker = '' WHERE state = 'running'",
            [],
        )?;
        tx.execute(
            "UPDATE workers SET state = 'lost' WHERE state != 'lost'",
            [],
        )?;
        tx.commit()?;
        Ok(n)
    }

    /// The job submitted earlier with `token`, if any (idempotent submit).
    pub fn job_by_token(&self, token: &str) -> Result<Option<String>> {
        Ok(self
            .conn
            .query_row(
                "SELECT id FROM jobs WHERE client_token = ?1",
                params![token],
                |r| r.get(0),
            )
            .optional()?)
    }

    /// Inserts a job and its initial tasks in one transaction; returns (job id, created). With a client token
    /// that already names a job, nothing is inserted and that job's id is returned.
    pub fn insert_job(&mut self, job: &NewJob) -> Result<(String, bool)> {
        if let Some(token) = &job.client_token {
            if let Some(id) = self.job_by_token(token)? {
                return Ok((id, false));
            }
        }
        let tx = self.conn.transaction()?;
        let seq: i64 = tx.query_row("SELECT COALESCE(MAX(seq), 0) + 1 FROM jobs", [], |r| {
            r.get(0)
        })?;
        let id = format!("job-{seq:05}");
        let t = now();
        tx.execute(
            "INSERT INTO jobs (seq, id, name, spec, info, output, priority, client_token, state,
                               max_task_attempts, max_failures, submitted)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, 'queued', ?9, ?10, ?11)",
            params![
                seq,
                id,
                job.name,
                job.spec_json,
                job.info_json,
                job.output,
                job.priority,
                job.client_token,
                job.max_task_attempts.max(1),
                job.max_failures.max(1),
                t
            ],
        )?;
        insert_tasks(&tx, &id, &job.tasks)?;
        event(
            &tx,
            &id,
            "job_submitted",
            "",
            &format!("{} tasks", job.tasks.len()),
        )?;
        tx.commit()?;
        Ok((id, true))
    }

    /// Ready tasks in dispatch order: higher job priority first, FIFO by submission within a priority, then
    /// task order within the job. At most `limit`.
    pub fn ready_tasks(&self, limit: usize) -> Result<Vec<TaskRow>> {
        let mut stmt = self.conn.prepare_cached(
            "SELECT t.job_id, t.key, t.kind, t.payload, t.expands, t.state, t.attempts, t.last_error,
                    t.worker, t.work_seconds, 0.0
             FROM tasks t JOIN jobs j ON j.id = t.job_id
             WHERE t.state = 'queued' AND j.state IN ('queued', 'running', 'waiting')
               AND t.not_before <= ?1
               AND NOT EXISTS (SELECT 1 FROM deps d JOIN tasks u ON u.job_id = d.job_id AND u.key = d.dep
                               WHERE d.job_id = t.job_id AND d.key = t.key AND u.state != 'done')
             ORDER BY j.priority DESC, j.seq ASC, t.seq ASC
             LIMIT ?2",
        )?;
        let rows = stmt
            .query_map(params![now(), limit as i64], task_row)?
            .collect::<rusqlite::Result<Vec<_>>>()?;
        Ok(rows)
    }

    /// How many failed attempts `worker` has had on `job` (the blacklist counter).
    pub fn worker_failures(&self, job_id: &str, worker: &str) -> Result<u32> {
        Ok(self
            .conn
            .query_row(
                "SELECT count FROM worker_failures WHERE job_id = ?1 AND worker = ?2",
                params![job_id, worker],
                |r| r.get(0),
            )
            .optional()?
            .unwrap_or(0))
    }

    /// Marks a queued task running on `worker` under a new attempt number.
    pub fn claim(&mut self, job_id: &str, key: &str, worker: &str) -> Result<Option<Claim>> {
        let tx = self.conn.transaction()?;
        let row: Option<(String, String, bool, u32)> = tx
            .query_row(
                "SELECT kind, payload, expands, attempts FROM tasks
                 WHERE job_id = ?1 AND key = ?2 AND state = 'queued'",
                params![job_id, key],
                |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)),
            )
            .optional()?;
        let Some((kind, payload, expands, attempts)) = row else {
            return Ok(None);
        };
        let attempt = attempts + 1;
        let t = now();
        tx.execute(
            "UPDATE tasks SET state = 'running', attempts = ?3, worker = ?4 WHERE job_id = ?1 AND key = ?2",
            params![job_id, key, attempt, worker],
        )?;
        tx.execute(
            "INSERT OR REPLACE INTO attempts (job_id, task_key, attempt, worker, started) VALUES (?1, ?2, ?3, ?4, ?5)",
            params![job_id, key, attempt, worker, t],
        )?;
        tx.execute(
            "UPDATE jobs SET state = 'running', message = '' WHERE id = ?1 AND state IN ('queued', 'waiting')",
            params![job_id],
        )?;
        event(
            &tx,
            job_id,
            "task_started",
            key,
            &format!("attempt {attempt} on {worker}"),
        )?;
        tx.commit()?;
        Ok(Some(Claim {
            job_id: job_id.to_string(),
            key: key.to_string(),
            kind,
            payload,
            attempt,
            expands,
        }))
    }

    /// Records a successful attempt. `more` are the tasks its success adds to the graph (planner expansion);
    /// they are inserted in the same transaction. A report for another attempt than the current one, or for a
    /// task that is no longer running, is stale and ignored.
    pub fn complete(
        &mut self,
        job_id: &str,
        key: &str,
        attempt: u32,
        output_json: &str,
        work_seconds: f64,
        more: &[NewTask],
    ) -> Result<Outcome> {
        let tx = self.conn.transaction()?;
        if !is_current(&tx, job_id, key, attempt)? {
            return ignore_stale(tx, job_id, key, attempt);
        }
        let t = now();
        tx.execute(
            "UPDATE tasks SET state = 'done', output = ?3, work_seconds = ?4, last_error = ''
             WHERE job_id = ?1 AND key = ?2",
            params![job_id, key, output_json, work_seconds],
        )?;
        close_attempt(&tx, job_id, key, attempt, "done", "")?;
        insert_tasks(&tx, job_id, more)?;
        event(
            &tx,
            job_id,
            "task_done",
            key,
            &format!("attempt {attempt}, {work_seconds:.3}s"),
        )?;
        let left: u32 = tx.query_row(
            "SELECT COUNT(*) FROM tasks WHERE job_id = ?1 AND state != 'done'",
            params![job_id],
            |r| r.get(0),
        )?;
        let _ = t;
        tx.commit()?;
        Ok(Outcome::Done {
            job_done: left == 0,
        })
    }

    /// Marks a job done (called once every task is done and every final output exists).
    pub fn finish_job(&mut self, job_id: &str) -> Result<bool> {
        let tx = self.conn.transaction()?;
        let n = tx.execute(
            "UPDATE jobs SET state = 'done', message = '', finished = ?2
             WHERE id = ?1 AND state IN ('queued', 'running', 'waiting')",
            params![job_id, now()],
        )?;
        if n > 0 {
            event(&tx, job_id, "job_done", "", "")?;
        }
        tx.commit()?;
        Ok(n > 0)
    }

    /// Records a failed attempt and applies the retry policy: a cancellation of a cancelled job closes the
    /// task; a non-retryable error, or the task's last allowed attempt, or the job's failure limit fails the
    /// job with a message naming the task and the error; otherwise the task is re-queued after `backoff`
    /// seconds. Failures that count are charged to `worker` for the per-job blacklist.
    pub fn fail(
        &mut self,
        job_id: &str,
        key: &str,
        attempt: u32,
        worker: &str,
        failure: &Failure,
        backoff: f64,
    ) -> Result<Outcome> {
        let tx = self.conn.transaction()?;
        if !is_current(&tx, job_id, key, attempt)? {
            return ignore_stale(tx, job_id, key, attempt);
        }
        let job = job_row(&tx, job_id)?;
        if job.state.is_terminal() {
            tx.execute(
                "UPDATE tasks SET state = 'cancelled' WHERE job_id = ?1 AND key = ?2",
                params![job_id, key],
            )?;
            close_attempt(&tx, job_id, key, attempt, "cancelled", &failure.reason)?;
            tx.commit()?;
            return Ok(Outcome::Cancelled);
        }
        let outcome_name = if failure.cancelled {
            "handed-back"
        } else {
            "failed"
        };
        close_attempt(&tx, job_id, key, attempt, outcome_name, &failure.reason)?;
        tx.execute(
            "UPDATE tasks SET last_error = ?3 WHERE job_id = ?1 AND key = ?2",
            params![job_id, key, failure.reason],
        )?;
        let mut failures = job.failures;
        if failure.counts {
            failures += 1;
            tx.execute(
                "UPDATE jobs SET failures = ?2 WHERE id = ?1",
                params![job_id, failures],
            )?;
            tx.execute(
                "INSERT INTO worker_failures (job_id, worker, count) VALUES (?1, ?2, 1)
                 ON CONFLICT (job_id, worker) DO UPDATE SET count = count + 1",
                params![job_id, worker],
            )?;
        }
        // Attempts that do not count (hand-backs, restarts) do not use up the task's attempt budget.
        let counted: u32 = tx.query_row(
            "SELECT COUNT(*) FROM attempts WHERE job_id = ?1 AND task_key = ?2 AND outcome = 'failed'",
            params![job_id, key],
            |r| r.get(0),
        )?;
        let fatal = failure.counts && !failure.retryable;
        let out_of_attempts = failure.counts && counted >= job.max_task_attempts;
        let over_job_limit = failure.counts && failures >= job.max_failures;
        let outcome = if fatal || out_of_attempts || over_job_limit {
            let why = if fatal {
                format!(
                    "task `{key}` failed (not retryable) on attempt {attempt}: {}",
                    failure.reason
                )
            } else if out_of_attempts {
                format!(
                    "task `{key}` failed {counted} time(s), the limit is {}: {}",
                    job.max_task_attempts, failure.reason
                )
            } else {
                format!(
                    "{failures} failed task attempts in this job reached the limit of {}; last: task `{key}`: {}",
                    job.max_failures, failure.reason
                )
            };
            tx.execute(
                "UPDATE tasks SET state = 'failed' WHERE job_id = ?1 AND key = ?2",
                params![job_id, key],
            )?;
            fail_job_tx(&tx, job_id, &why)?;
            Outcome::JobFailed { message: why }
        } else {
            tx.execute(
                "UPDATE tasks SET state = 'queued', worker = '', not_before = ?3 WHERE job_id = ?1 AND key = ?2",
                params![job_id, key, now() + backoff.max(0.0)],
            )?;
            event(
                &tx,
                job_id,
                "task_retry",
                key,
                &format!("attempt {attempt} on {worker}: {}", failure.reason),
            )?;
            Outcome::Retry { attempt }
        };
        tx.commit()?;
        Ok(outcome)
    }

    /// Fails a job that is not finished yet with `message`; its queued and running tasks are cancelled (running
    /// ones are told to stop by the scheduler). Returns false when the job had already ended.
    pub fn fail_job(&mut self, job_id: &str, message: &str) -> Result<bool> {
        let tx = self.conn.transaction()?;
        let n = fail_job_tx(&tx, job_id, message)?;
        tx.commit()?;
        Ok(n)
    }

    /// Cancels a job. Queued tasks are cancelled at once; running ones stay `running` until their worker
    /// reports (the scheduler asks the workers to stop them). Returns the job's state afterwards.
    pub fn cancel_job(&mut self, job_id: &str) -> Result<JobState> {
        let tx = self.conn.transaction()?;
        let job = job_row(&tx, job_id)?;
        if job.state.is_terminal() {
            tx.commit()?;
            return Ok(job.state);
        }
        tx.execute(
            "UPDATE jobs SET state = 'cancelled', message = 'cancelled by the user', finished = ?2 WHERE id = ?1",
            params![job_id, now()],
        )?;
        tx.execute(
            "UPDATE tasks SET state = 'cancelled' WHERE job_id = ?1 AND state = 'queued'",
            params![job_id],
        )?;
        event(&tx, job_id, "job_cancelled", "", "cancelled by the user")?;
        tx.commit()?;
        Ok(JobState::Cancelled)
    }

    /// Sets a non-terminal job's state to waiting (no worker) or back to running, with a message.
    pub fn set_waiting(&mut self, job_id: &str, waiting: bool, message: &str) -> Result<()> {
        let (from, to) = if waiting {
            ("('queued', 'running')", "waiting")
        } else {
            ("('waiting')", "running")
        };
        let n = self.conn.execute(
            &format!("UPDATE jobs SET state = ?2, message = ?3 WHERE id = ?1 AND state IN {from}"),
            params![job_id, to, message],
        )?;
        if n > 0 {
            let tx = self.conn.transaction()?;
            event(
                &tx,
                job_id,
                if waiting {
                    "job_waiting"
                } else {
                    "job_resumed"
                },
                "",
                message,
            )?;
            tx.commit()?;
        }
        Ok(())
    }

    /// Running tasks (job, key, attempt, worker), for cancel and lost-worker handling.
    pub fn running_tasks(
        &self,
        job_id: Option<&str>,
    ) -> Result<Vec<(String, String, u32, String)>> {
        let mut stmt = self.conn.prepare_cached(
            "SELECT job_id, key, attempts, worker FROM tasks
             WHERE state = 'running' AND (?1 IS NULL OR job_id = ?1)",
        )?;
        let rows = stmt
            .query_map(params![job_id], |r| {
                Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?))
            })?
            .collect::<rusqlite::Result<Vec<_>>>()?;
        Ok(rows)
    }

    /// Jobs that are not finished, oldest first.
    pub fn active_jobs(&self) -> Result<Vec<JobRow>> {
        self.jobs_where("state IN ('queued', 'running', 'waiting')")
    }

    /// All jobs, newest first.
    pub fn list_jobs(&self) -> Result<Vec<JobRow>> {
        let mut v = self.jobs_where("1")?;
        v.reverse();
        Ok(v)
    }

    fn jobs_where(&self, cond: &str) -> Result<Vec<JobRow>> {
        let mut stmt = self.conn.prepare(&format!(
            "SELECT {JOB_COLS} FROM jobs WHERE {cond} ORDER BY seq"
        ))?;
        let rows = stmt
            .query_map([], job_from_row)?
            .collect::<rusqlite::Result<Vec<_>>>()?;
        Ok(rows)
    }

    pub fn job(&self, job_id: &str) -> Result<JobRow> {
        job_row(&self.conn, job_id)
    }

    pub fn counts(&self, job_id: &str) -> Result<Counts> {
        let mut c = Counts::default();
        let mut stmt = self.conn.prepare_cached(
            "SELECT state, COUNT(*), COALESCE(SUM(work_seconds), 0) FROM tasks WHERE job_id = ?1 GROUP BY state",
        )?;
        let rows = stmt.query_map(params![job_id], |r| {
            Ok((
                r.get::<_, String>(0)?,
                r.get::<_, u32>(1)?,
                r.get::<_, f64>(2)?,
            ))
        })?;
        for row in rows {
            let (state, n, secs) = row?;
            c.total += n;
            c.work_seconds += secs;
            match state.as_str() {
                "done" => c.done += n,
                "running" => c.running += n,
                "failed" => c.failed += n,
                "queued" => c.queued += n,
                _ => {}
            }
        }
        Ok(c)
    }

    pub fn tasks(&self, job_id: &str) -> Result<Vec<TaskRow>> {
        let mut stmt = self.conn.prepare_cached(
            "SELECT job_id, key, kind, payload, expands, state, attempts, last_error, worker, work_seconds,
                    (SELECT COALESCE(SUM(a.finished - a.started), 0) FROM attempts a
                     WHERE a.job_id = t.job_id AND a.task_key = t.key AND a.outcome = 'done')
             FROM tasks t WHERE job_id = ?1 ORDER BY seq",
        )?;
        let rows = stmt
            .query_map(params![job_id], task_row)?
            .collect::<rusqlite::Result<Vec<_>>>()?;
        Ok(rows)
    }

    /// A task's output JSON (after it is done).
    pub fn task_output(&self, job_id: &str, key: &str) -> Result<Option<String>> {
        Ok(self
            .conn
            .query_row(
                "SELECT output FROM tasks WHERE job_id = ?1 AND key = ?2 AND state = 'done'",
                params![job_id, key],
                |r| r.get(0),
            )
            .optional()?)
    }

    /// Persisted events of a job after event id `after`.
    pub fn events(&self, job_id: &str, after: i64) -> Result<Vec<EventRow>> {
        let mut stmt = self.conn.prepare_cached(
            "SELECT id, job_id, time, kind, task_key, message FROM events WHERE job_id = ?1 AND id > ?2 ORDER BY id",
        )?;
        let rows = stmt
            .query_map(params![job_id, after], |r| {
                Ok(EventRow {
                    id: r.get(0)?,
                    job_id: r.get(1)?,
                    time: r.get(2)?,
                    kind: r.get(3)?,
                    task_key: r.get(4)?,
                    message: r.get(5)?,
                })
            })?
            .collect::<rusqlite::Result<Vec<_>>>()?;
        Ok(rows)
    }

    /// Records a worker registration.
    pub fn register_worker(
        &mut self,
        id: &str,
        name: &str,
        address: &str,
        capacity: u32,
    ) -> Result<()> {
        self.conn.execute(
            "INSERT OR REPLACE INTO workers (id, name, address, capacity, registered, state)
             VALUES (?1, ?2, ?3, ?4, ?5, 'live')",
            params![id, name, address, capacity, now()],
        )?;
        Ok(())
    }

    /// Marks a worker lost (missed heartbeats, broken stream) or gone (drained).
    pub fn set_worker_state(&mut self, id: &str, state: &str) -> Result<()> {
        self.conn.execute(
            "UPDATE workers SET state = ?2 WHERE id = ?1",
            params![id, state],
        )?;
        Ok(())
    }

    /// Number of worker rows ever registered (worker ids are `w<n>`).
    pub fn worker_count(&self) -> Result<u32> {
        Ok(self
            .conn
            .query_row("SELECT COUNT(*) FROM workers", [], |r| r.get(0))?)
    }

    /// Appends lines to the log of one attempt (`crease logs`).
    pub fn append_task_log(
        &mut self,
        job_id: &str,
        key: &str,
        attempt: u32,
        lines: &[String],
    ) -> Result<()> {
        let tx = self.conn.transaction()?;
        {
            let mut stmt = tx.prepare_cached(
                "INSERT INTO task_logs (job_id, task_key, attempt, line) VALUES (?1, ?2, ?3, ?4)",
            )?;
            for line in lines {
                stmt.execute(params![job_id, key, attempt, line])?;
            }
        }
        tx.commit()?;
        Ok(())
    }

    /// Every attempt of a job's tasks (or of one task), in task then attempt order, with its log lines.
    pub fn task_logs(&self, job_id: &str, key: Option<&str>) -> Result<Vec<AttemptLog>> {
        let mut stmt = self.conn.prepare_cached(
            "SELECT a.task_key, a.attempt, a.worker, a.outcome, a.error, a.started, a.finished
             FROM attempts a JOIN tasks t ON t.job_id = a.job_id AND t.key = a.task_key
             WHERE a.job_id = ?1 AND (?2 IS NULL OR a.task_key = ?2)
             ORDER BY t.seq, a.attempt",
        )?;
        let mut attempts = stmt
            .query_map(params![job_id, key], |r| {
                Ok(AttemptLog {
                    task_key: r.get(0)?,
                    attempt: r.get(1)?,
                    worker: r.get(2)?,
                    outcome: r.get(3)?,
                    error: r.get(4)?,
                    started: r.get(5)?,
                    finished: r.get(6)?,
                    lines: Vec::new(),
                })
            })?
            .collect::<rusqlite::Result<Vec<_>>>()?;
        let mut lines = self.conn.prepare_cached(
            "SELECT line FROM task_logs WHERE job_id = ?1 AND task_key = ?2 AND attempt = ?3 ORDER BY id",
        )?;
        for a in &mut attempts {
            a.lines = lines
                .query_map(params![job_id, a.task_key, a.attempt], |r| r.get(0))?
                .collect::<rusqlite::Result<Vec<String>>>()?;
        }
        Ok(attempts)
    }

    /// Whether a job has a task with this key.
    pub fn has_task(&self, job_id: &str, key: &str) -> Result<bool> {
        Ok(self
            .conn
            .query_row(
                "SELECT 1 FROM tasks WHERE job_id = ?1 AND key = ?2",
                params![job_id, key],
                |_| Ok(()),
            )
            .optional()?
            .is_some())
    }

    /// Figures the metrics endpoint reads at scrape time; each is one count over an index.
    pub fn gauges(&self) -> Result<QueueGauges> {
        let mut g = QueueGauges {
            queue_depth: self.conn.query_row(
                "SELECT COUNT(*) FROM tasks t JOIN jobs j ON j.id = t.job_id
                 WHERE t.state = 'queued' AND j.state IN ('queued', 'running', 'waiting')
                   AND t.not_before <= ?1
                   AND NOT EXISTS (SELECT 1 FROM deps d JOIN tasks u ON u.job_id = d.job_id AND u.key = d.dep
                                   WHERE d.job_id = t.job_id AND d.key = t.key AND u.state != 'done')",
                params![now()],
                |r| r.get(0),
            )?,
            tasks_running: self.conn.query_row(
                "SELECT COUNT(*) FROM tasks WHERE state = 'running'",
                [],
                |r| r.get(0),
            )?,
            jobs: Vec::new(),
        };
        let mut stmt = self
            .conn
            .prepare_cached("SELECT state, COUNT(*) FROM jobs GROUP BY state")?;
        g.jobs = stmt
            .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))?
            .collect::<rusqlite::Result<Vec<_>>>()?;
        Ok(g)
    }

    /// Appends an event outside of a state transition.
    pub fn note(&mut self, job_id: &str, kind: &str, key: &str, message: &str) -> Result<()> {
        let tx = self.conn.transaction()?;
        event(&tx, job_id, kind, key, message)?;
        tx.commit()?;
        Ok(())
    }
}

const JOB_COLS: &str =
    "id, name, spec, info, output, priority, state, message, max_task_attempts, \
                        max_failures, failures, submitted, finished";

fn job_from_row(r: &rusqlite::Row<'_>) -> rusqlite::Result<JobRow> {
    Ok(JobRow {
        id: r.get(0)?,
        name: r.get(1)?,
        spec_json: r.get(2)?,
        info_json: r.get(3)?,
        output: r.get(4)?,
        priority: r.get(5)?,
        state: JobState::parse(&r.get::<_, String>(6)?),
        message: r.get(7)?,
        max_task_attempts: r.get(8)?,
        max_failures: r.get(9)?,
        failures: r.get(10)?,
        submitted: r.get(11)?,
        finished: r.get(12)?,
    })
}

fn job_row(conn: &Connection, job_id: &str) -> Result<JobRow> {
    conn.query_row(
        &format!("SELECT {JOB_COLS} FROM jobs WHERE id = ?1"),
        params![job_id],
        job_from_row,
    )
    .optional()?
    .ok_or_else(|| StoreError::NoSuchJob(job_id.to_string()))
}

fn task_row(r: &rusqlite::Row<'_>) -> rusqlite::Result<TaskRow> {
    let state: String = r.get(5)?;
    Ok(TaskRow {
        job_id: r.get(0)?,
        key: r.get(1)?,
        kind: r.get(2)?,
        payload: r.get(3)?,
        expands: r.get(4)?,
        state: match state.as_str() {
            "running" => TaskState::Running,
            "done" => TaskState::Done,
            "failed" => TaskState::Failed,
            "cancelled" => TaskState::Cancelled,
            _ => TaskState::Queued,
        },
        attempts: r.get(6)?,
        last_error: r.get(7)?,
        worker: r.get(8)?,
        work_seconds: r.get(9)?,
        wall_seconds: r.get(10)?,
    })
}

fn insert_tasks(tx: &Transaction<'_>, job_id: &str, tasks: &[NewTask]) -> Result<()> {
    for t in tasks {
        tx.execute(
            "INSERT OR IGNORE INTO tasks (job_id, key, kind, payload, expands, state) VALUES (?1, ?2, ?3, ?4, ?5, 'queued')",
            params![job_id, t.key, t.kind, t.payload, t.expands],
        )?;
        for d in &t.deps {
            tx.execute(
                "INSERT OR IGNORE INTO deps (job_id, key, dep) VALUES (?1, ?2, ?3)",
                params![job_id, t.key, d],
            )?;
        }
    }
    Ok(())
}

/// Records that a report of an attempt the queue has moved past (a worker already given up on) was dropped.
fn ignore_stale(tx: Transaction<'_>, job_id: &str, key: &str, attempt: u32) -> Result<Outcome> {
    event(
        &tx,
        job_id,
        "stale_report",
        key,
        &format!("attempt {attempt} ignored"),
    )?;
    tx.commit()?;
    Ok(Outcome::Stale)
}

fn is_current(tx: &Transaction<'_>, job_id: &str, key: &str, attempt: u32) -> Result<bool> {
    let row: Option<(String, u32)> = tx
        .query_row(
            "SELECT state, attempts FROM tasks WHERE job_id = ?1 AND key = ?2",
            params![job_id, key],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
        .optional()?;
    Ok(matches!(row, Some((s, a)) if s == "running" && a == attempt))
}

fn close_attempt(
    tx: &Transaction<'_>,
    job_id: &str,
    key: &str,
    attempt: u32,
    outcome: &str,
    error: &str,
) -> Result<()> {
    tx.execute(
        "UPDATE attempts SET outcome = ?4, error = ?5, finished = ?6
         WHERE job_id = ?1 AND task_key = ?2 AND attempt = ?3",
        params![job_id, key, attempt, outcome, error, now()],
    )?;
    Ok(())
}

fn fail_job_tx(tx: &Transaction<'_>, job_id: &str, message: &str) -> Result<bool> {
    let n = tx.execute(
        "UPDATE jobs SET state = 'failed', message = ?2, finished = ?3
         WHERE id = ?1 AND state IN ('queued', 'running', 'waiting')",
        params![job_id, message, now()],
    )?;
    if n > 0 {
        tx.execute(
            "UPDATE tasks SET state = 'cancelled' WHERE job_id = ?1 AND state = 'queued'",
            params![job_id],
        )?;
        event(tx, job_id, "job_failed", "", message)?;
    }
    Ok(n > 0)
}

fn event(tx: &Connection, job_id: &str, kind: &str, key: &str, message: &str) -> Result<()> {
    tx.execute(
        "INSERT INTO events (job_id, time, kind, task_key, message) VALUES (?1, ?2, ?3, ?4, ?5)",
        params![job_id, now(), kind, key, message],
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn task(key: &str, deps: &[&str]) -> NewTask {
        NewTask {
            key: key.into(),
            kind: "test".into(),
            payload: "{}".into(),
            deps: deps.iter().map(|d| d.to_string()).collect(),
            expands: false,
        }
    }

    fn job(priority: i32, tasks: Vec<NewTask>) -> NewJob {
        NewJob {
            name: "j".into(),
            spec_json: "{}".into(),
            info_json: "{}".into(),
            output: "/tmp/x".into(),
            priority,
            client_token: None,
            max_task_attempts: 3,
            max_failures: 10,
            tasks,
        }
    }

    fn err(retryable: bool) -> Failure {
        Failure {
            retryable,
            counts: true,
            cancelled: false,
            reason: "boom".into(),
        }
    }

    fn keys(store: &Store) -> Vec<String> {
        store
            .ready_tasks(100)
            .unwrap()
            .into_iter()
            .map(|t| format!("{}:{}", t.job_id, t.key))
            .collect()
    }

    #[test]
    fn priority_first_then_fifo_then_dependencies() {
        let mut s = Store::in_memory().unwrap();
        let (a, _) = s
            .insert_job(&job(0, vec![task("x", &[]), task("y", &["x"])]))
            .unwrap();
        let (b, _) = s.insert_job(&job(5, vec![task("x", &[])])).unwrap();
        let (c, _) = s.insert_job(&job(0, vec![task("x", &[])])).unwrap();
        assert_eq!(
            keys(&s),
            vec![format!("{b}:x"), format!("{a}:x"), format!("{c}:x")]
        );
        let cl = s.claim(&a, "x", "w1").unwrap().unwrap();
        assert_eq!(cl.attempt, 1);
        assert!(!keys(&s).contains(&format!("{a}:y")), "y waits for x");
        let out = s.complete(&a, "x", 1, "{}", 0.5, &[]).unwrap();
        assert_eq!(out, Outcome::Done { job_done: false });
        assert!(keys(&s).contains(&format!("{a}:y")));
    }

    #[test]
    fn stale_reports_are_ignored() {
        let mut s = Store::in_memory().unwrap();
        let (a, _) = s.insert_job(&job(0, vec![task("x", &[])])).unwrap();
        s.claim(&a, "x", "w1").unwrap().unwrap();
        // The coordinator gave up on attempt 1 (worker lost) and re-queued it.
        assert_eq!(
            s.fail(&a, "x", 1, "w1", &err(true), 0.0).unwrap(),
            Outcome::Retry { attempt: 1 }
        );
        let cl = s.claim(&a, "x", "w2").unwrap().unwrap();
        assert_eq!(cl.attempt, 2);
        // The late report of attempt 1 changes nothing.
        assert_eq!(
            s.complete(&a, "x", 1, "{}", 1.0, &[]).unwrap(),
            Outcome::Stale
        );
        assert_eq!(s.tasks(&a).unwrap()[0].state, TaskState::Running);
        assert_eq!(
            s.complete(&a, "x", 2, "{}", 1.0, &[]).unwrap(),
            Outcome::Done { job_done: true }
        );
        assert!(s.finish_job(&a).unwrap());
        assert_eq!(s.job(&a).unwrap().state, JobState::Done);
    }

    #[test]
    fn retries_up_to_the_limit_then_the_job_fails_naming_the_task() {
        let mut s = Store::in_memory().unwrap();
        let (a, _) = s.insert_job(&job(0, vec![task("pos/f0003", &[])])).unwrap();
        for attempt in 1..=2 {
            s.claim(&a, "pos/f0003", "w1").unwrap().unwrap();
            assert_eq!(
                s.fail(&a, "pos/f0003", attempt, "w1", &err(true), 0.0)
                    .unwrap(),
                Outcome::Retry { attempt }
            );
        }
        s.claim(&a, "pos/f0003", "w1").unwrap().unwrap();
        match s.fail(&a, "pos/f0003", 3, "w1", &err(true), 0.0).unwrap() {
            Outcome::JobFailed { message } => {
                assert!(
                    message.contains("pos/f0003") && message.contains("boom"),
                    "{message}"
                )
            }
            o => panic!("{o:?}"),
        }
        assert_eq!(s.job(&a).unwrap().state, JobState::Failed);
        assert_eq!(s.worker_failures(&a, "w1").unwrap(), 3);
    }

    #[test]
    fn non_retryable_failures_fail_at_once_and_hand_backs_do_not_count() {
        let mut s = Store::in_memory().unwrap();
        let (a, _) = s.insert_job(&job(0, vec![task("x", &[])])).unwrap();
        // Hand-backs (drain) and restarts do not use up attempts.
        for attempt in 1..=5 {
            s.claim(&a, "x", "w1").unwrap().unwrap();
            let handed_back = Failure {
                retryable: true,
                counts: false,
                cancelled: true,
                reason: "cancelled".into(),
            };
            assert_eq!(
                s.fail(&a, "x", attempt, "w1", &handed_back, 0.0).unwrap(),
                Outcome::Retry { attempt }
            );
        }
        s.claim(&a, "x", "w1").unwrap().unwrap();
        assert!(matches!(
            s.fail(&a, "x", 6, "w1", &err(false), 0.0).unwrap(),
            Outcome::JobFailed { .. }
        ));
    }

    #[test]
    fn job_failure_limit_counts_over_all_tasks() {
        let mut s = Store::in_memory().unwrap();
        let mut j = job(0, vec![task("a", &[]), task("b", &[])]);
        j.max_failures = 2;
        let (id, _) = s.insert_job(&j).unwrap();
        s.claim(&id, "a", "w1").unwrap().unwrap();
        s.claim(&id, "b", "w1").unwrap().unwrap();
        assert!(matches!(
            s.fail(&id, "a", 1, "w1", &err(true), 0.0).unwrap(),
            Outcome::Retry { .. }
        ));
        match s.fail(&id, "b", 1, "w1", &err(true), 0.0).unwrap() {
            Outcome::JobFailed { message } => assert!(message.contains("limit of 2"), "{message}"),
            o => panic!("{o:?}"),
        }
    }

    #[test]
    fn cancel_drops_queued_tasks_and_closes_running_ones_on_report() {
        let mut s = Store::in_memory().unwrap();
        let (a, _) = s
            .insert_job(&job(0, vec![task("x", &[]), task("y", &[])]))
            .unwrap();
        s.claim(&a, "x", "w1").unwrap().unwrap();
        assert_eq!(s.cancel_job(&a).unwrap(), JobState::Cancelled);
        assert!(s.ready_tasks(10).unwrap().is_empty());
        assert_eq!(s.running_tasks(Some(&a)).unwrap().len(), 1);
        let stopped = Failure {
            retryable: true,
            counts: false,
            cancelled: true,
            reason: "cancelled".into(),
        };
        assert_eq!(
            s.fail(&a, "x", 1, "w1", &stopped, 0.0).unwrap(),
            Outcome::Cancelled
        );
        assert!(s.running_tasks(Some(&a)).unwrap().is_empty());
        assert_eq!(s.cancel_job(&a).unwrap(), JobState::Cancelled);
    }

    #[test]
    fn restart_recovery_requeues_running_tasks_and_keeps_done_ones() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("q.sqlite");
        let a = {
            let mut s = Store::open(&path).unwrap();
            let (a, _) = s
                .insert_job(&job(0, vec![task("x", &[]), task("y", &[])]))
                .unwrap();
            s.claim(&a, "x", "w1").unwrap().unwrap();
            s.complete(&a, "x", 1, "{}", 0.1, &[]).unwrap();
            s.claim(&a, "y", "w1").unwrap().unwrap();
            a
        };
        let mut s = Store::open(&path).unwrap();
        assert_eq!(s.recover().unwrap(), 1);
        let tasks = s.tasks(&a).unwrap();
        assert_eq!(tasks[0].state, TaskState::Done);
        assert_eq!(tasks[0].attempts, 1);
        assert_eq!(tasks[1].state, TaskState::Queued);
        // The interrupted attempt does not count against the task.
        let cl = s.claim(&a, "y", "w2").unwrap().unwrap();
        assert_eq!(cl.attempt, 2);
        assert_eq!(s.job(&a).unwrap().failures, 0);
    }

    #[test]
    fn task_logs_are_kept_per_attempt_and_old_queue_files_gain_the_table() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.sqlite");
        {
            // A queue file from before the task_logs table existed.
            let conn = Connection::open(&path).unwrap();
            conn.execute_batch(
                SCHEMA
                    .split("CREATE TABLE IF NOT EXISTS task_logs")
                    .next()
                    .unwrap(),
            )
            .unwrap();
        }
        let mut s = Store::open(&path).unwrap();
        let (a, _) = s
            .insert_job(&job(0, vec![task("x", &[]), task("y", &["x"])]))
            .unwrap();
        s.claim(&a, "x", "w1").unwrap().unwrap();
        s.append_task_log(&a, "x", 1, &["one".into(), "two".into()])
            .unwrap();
        s.fail(&a, "x", 1, "w1", &err(true), 0.0).unwrap();
        s.claim(&a, "x", "w2").unwrap().unwrap();
        s.append_task_log(&a, "x", 2, &["three".into()]).unwrap();
        let logs = s.task_logs(&a, None).unwrap();
        assert_eq!(logs.len(), 2);
        assert_eq!((logs[0].attempt, logs[0].worker.as_str()), (1, "w1"));
        assert_eq!(logs[0].outcome, "failed");
        assert_eq!(logs[0].error, "boom");
        assert_eq!(logs[0].lines, vec!["one", "two"]);
        assert_eq!((logs[1].attempt, logs[1].outcome.as_str()), (2, "running"));
        assert_eq!(logs[1].lines, vec!["three"]);
        assert!(s.task_logs(&a, Some("y")).unwrap().is_empty());
        assert!(s.has_task(&a, "y").unwrap() && !s.has_task(&a, "z").unwrap());
        let g = s.gauges().unwrap();
        assert_eq!((g.queue_depth, g.tasks_running), (0, 1));
        assert_eq!(g.jobs, vec![("running".to_string(), 1)]);
    }

    #[test]
    fn client_token_makes_submit_idempotent_and_expansion_is_atomic() {
        let mut s = Store::in_memory().unwrap();
        let mut j = job(0, vec![task("merge", &[])]);
        j.client_token = Some("tok".into());
        let (a, created) = s.insert_job(&j).unwrap();
        assert!(created);
        let (b, created) = s.insert_job(&j).unwrap();
        assert_eq!((a.clone(), false), (b, created));
        s.claim(&a, "merge", "w1").unwrap().unwrap();
        let more = vec![task("w/0", &["merge"]), task("fin", &["w/0"])];
        assert_eq!(
            s.complete(&a, "merge", 1, "{}", 0.0, &more).unwrap(),
            Outcome::Done { job_done: false }
        );
        assert_eq!(keys(&s), vec![format!("{a}:w/0")]);
    }
}
