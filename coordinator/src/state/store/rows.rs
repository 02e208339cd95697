//! The row-level steps that job and task operations both take inside their transactions: reading a job's
//! row, failing a job (its queued tasks cancelled, the event logged), inserting tasks with their dependencies.

use super::events::event;
use super::{now, JobRow, JobState, NewTask, Result, StoreError};
use rusqlite::{params, Connection, OptionalExtension, Transaction};

pub(super) const JOB_COLS: &str =
    "id, name, spec, info, output, priority, state, message, max_task_attempts, \
                        max_failures, failures, submitted, finished";

pub(super) fn job_from_row(r: &rusqlite::Row<'_>) -> rusqlite::Result<JobRow> {
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

pub(super) fn job_row(conn: &Connection, job_id: &str) -> Result<JobRow> {
    conn.query_row(
        &format!("SELECT {JOB_COLS} FROM jobs WHERE id = ?1"),
        params![job_id],
        job_from_row,
    )
    .optional()?
    .ok_or_else(|| StoreError::NoSuchJob(job_id.to_string()))
}

pub(super) fn fail_job_tx(tx: &Transaction<'_>, job_id: &str, message: &str) -> Result<bool> {
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

pub(super) fn insert_tasks(tx: &Transaction<'_>, job_id: &str, tasks: &[NewTask]) -> Result<()> {
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
