//! The job event log (`watch` replays it) and the per-attempt log lines (`crease logs`).

use super::{now, AttemptLog, EventRow, Result, Store};
use rusqlite::{params, Connection};

impl Store {
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
            "SELECT a.task_key, a.attempt, a.worker, a.outcome, a.error, a.started, a.finished, a.kind
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
                    kind: r.get(7)?,
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

    /// Appends an event outside of a state transition.
    pub fn note(&mut self, job_id: &str, kind: &str, key: &str, message: &str) -> Result<()> {
        let tx = self.conn.transaction()?;
        event(&tx, job_id, kind, key, message)?;
        tx.commit()?;
        Ok(())
    }
}

pub(super) fn event(
    tx: &Connection,
    job_id: &str,
    kind: &str,
    key: &str,
    message: &str,
) -> Result<()> {
    tx.execute(
        "INSERT INTO events (job_id, time, kind, task_key, message) VALUES (?1, ?2, ?3, ?4, ?5)",
        params![job_id, now(), kind, key, message],
    )?;
    Ok(())
}
