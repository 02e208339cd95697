//! The queue file's schema and its migrations. A queue file records the schema version it has reached in
//! SQLite's `PRAGMA user_version`; opening it applies the migrations it lacks, each in one transaction with
//! the version bump, so a column added by a later release reaches queue files written by an earlier one, and
//! a crash mid-upgrade leaves the file at the last whole version.
//!
//! Queue files from before versioning (user_version 0) hold the baseline, or a prefix of it (files older than
//! the `task_logs` table): the baseline is written with `IF NOT EXISTS` so it completes either.

use super::{Result, StoreError};
use rusqlite::Connection;

/// Version 1: the tables as they were when versioning began.
pub(super) const BASELINE: &str = "
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

/// Every migration in order; a queue file at version `n` has applied the first `n`. Append only: a released
/// migration never changes.
const MIGRATIONS: &[&str] = &[
    BASELINE,
    // 2: the canonical spec hash beside the client token, so a reused token with another spec is refused.
    "ALTER TABLE jobs ADD COLUMN spec_hash TEXT NOT NULL DEFAULT '';",
    // 3: the typed failure kind of each closed attempt (crease_jobs::FailureKind), which the retry policy read.
    "ALTER TABLE attempts ADD COLUMN kind TEXT NOT NULL DEFAULT '';",
];

/// The schema version this build writes.
pub const SCHEMA_VERSION: u32 = MIGRATIONS.len() as u32;

/// Brings the queue file at `conn` up to [`SCHEMA_VERSION`]; `what` names it in errors. A file written by a
/// newer crease (a higher version) is refused rather than guessed at.
pub(super) fn migrate(conn: &mut Connection, what: &str) -> Result<()> {
    let found: u32 = conn.pragma_query_value(None, "user_version", |r| r.get(0))?;
    if found > SCHEMA_VERSION {
        return Err(StoreError::TooNew {
            what: what.to_string(),
            found,
            known: SCHEMA_VERSION,
        });
    }
    for (i, sql) in MIGRATIONS.iter().enumerate().skip(found as usize) {
        let version = i as u32 + 1;
        let tx = conn.transaction()?;
        tx.execute_batch(sql).map_err(|e| StoreError::Migration {
            what: what.to_string(),
            version,
            source: e,
        })?;
        tx.pragma_update(None, "user_version", version)?;
        tx.commit()?;
    }
    Ok(())
}
