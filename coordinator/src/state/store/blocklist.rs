//! The per-job worker blocklist (`--blacklist-after`): which workers a job no longer gives its tasks to while
//! another worker can take them, the failures that put them there, and an operator's way to clear it.

use super::{Result, Store};
use rusqlite::params;

/// A worker a job excludes, with why.
#[derive(Debug, Clone, PartialEq)]
pub struct Blocked {
    pub worker: String,
    /// Failed attempts of the job's tasks on this worker (each counted failure; hand-backs are not).
    pub failures: u32,
    /// The latest of those failures, newest first: "task `k` attempt n (kind): error".
    pub reasons: Vec<String>,
}

/// How many of a worker's failures [`Store::blocklist`] quotes.
const REASONS: usize = 3;

impl Store {
    /// The workers `job_id` excludes: those with at least `threshold` counted failures on it.
    pub fn blocklist(&self, job_id: &str, threshold: u32) -> Result<Vec<Blocked>> {
        let mut stmt = self.conn.prepare_cached(
            "SELECT worker, count FROM worker_failures WHERE job_id = ?1 AND count >= ?2 ORDER BY worker",
        )?;
        let rows = stmt
            .query_map(params![job_id, threshold], |r| {
                Ok((r.get::<_, String>(0)?, r.get::<_, u32>(1)?))
            })?
            .collect::<rusqlite::Result<Vec<_>>>()?;
        let mut why = self.conn.prepare_cached(
            "SELECT task_key, attempt, kind, error FROM attempts
             WHERE job_id = ?1 AND worker = ?2 AND outcome = 'failed'
             ORDER BY finished DESC LIMIT ?3",
        )?;
        let mut out = Vec::new();
        for (worker, failures) in rows {
            let reasons = why
                .query_map(params![job_id, worker, REASONS as i64], |r| {
                    let (key, attempt, kind, error): (String, u32, String, String) =
                        (r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?);
                    let kind = if kind.is_empty() {
                        "failed".into()
                    } else {
                        kind
                    };
                    Ok(format!("task `{key}` attempt {attempt} ({kind}): {error}"))
                })?
                .collect::<rusqlite::Result<Vec<_>>>()?;
            out.push(Blocked {
                worker,
                failures,
                reasons,
            });
        }
        Ok(out)
    }

    /// Per active job, how many workers it excludes (the metrics endpoint).
    pub fn blocklist_sizes(&self, threshold: u32) -> Result<Vec<(String, i64)>> {
        let mut stmt = self.conn.prepare_cached(
            "SELECT j.id, (SELECT COUNT(*) FROM worker_failures f WHERE f.job_id = j.id AND f.count >= ?1)
             FROM jobs j WHERE j.state IN ('queued', 'running', 'waiting') ORDER BY j.seq",
        )?;
        let rows = stmt
            .query_map(params![threshold], |r| Ok((r.get(0)?, r.get(1)?)))?
            .collect::<rusqlite::Result<Vec<_>>>()?;
        Ok(rows)
    }

    /// Forgets the failures that blocklist `worker` (or every worker) for `job_id`, so the job's tasks go to
    /// it again; returns the workers whose counts were cleared. The attempts' history stays (`crease logs`).
    pub fn unblock(&mut self, job_id: &str, worker: Option<&str>) -> Result<Vec<String>> {
        let tx = self.conn.transaction()?;
        let cleared = {
            let mut stmt = tx.prepare(
                "DELETE FROM worker_failures WHERE job_id = ?1 AND (?2 IS NULL OR worker = ?2)
                 RETURNING worker",
            )?;
            let mut v = stmt
                .query_map(params![job_id, worker], |r| r.get::<_, String>(0))?
                .collect::<rusqlite::Result<Vec<_>>>()?;
            v.sort();
            v
        };
        if !cleared.is_empty() {
            super::events::event(
                &tx,
                job_id,
                "blocklist_cleared",
                "",
                &format!("failure counts cleared for {}", cleared.join(", ")),
            )?;
        }
        tx.commit()?;
        Ok(cleared)
    }
}
