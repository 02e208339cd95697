//! Tasks and their attempts: readiness, claims, results, and the retry policy applied to a failed attempt.

use super::events::event;
use super::rows::{fail_job_tx, insert_tasks, job_row};
use super::{now, Claim, Failure, NewTask, Outcome, Result, Store, TaskRow, TaskState};
use crease_jobs::FailureKind;
use rusqlite::{params, OptionalExtension, Transaction};

impl Store {
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
        close_attempt(&tx, job_id, key, attempt, "done", None)?;
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
            close_attempt(&tx, job_id, key, attempt, "cancelled", Some(failure))?;
            tx.commit()?;
            return Ok(Outcome::Cancelled);
        }
        let outcome_name = match failure.kind {
            FailureKind::CoordinatorRestart => "coordinator-restart",
            _ if !failure.counts() => "handed-back",
            _ => "failed",
        };
        close_attempt(&tx, job_id, key, attempt, outcome_name, Some(failure))?;
        tx.execute(
            "UPDATE tasks SET last_error = ?3 WHERE job_id = ?1 AND key = ?2",
            params![job_id, key, failure.reason],
        )?;
        let mut failures = job.failures;
        if failure.counts() {
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
        let counts = failure.counts();
        let fatal = counts && !failure.retryable();
        let out_of_attempts = counts && counted >= job.max_task_attempts;
        let over_job_limit = counts && failures >= job.max_failures;
        let outcome = if fatal || out_of_attempts || over_job_limit {
            let why = if fatal {
                format!(
                    "task `{key}` failed ({}, not retryable) on attempt {attempt}: {}",
                    failure.kind, failure.reason
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

    /// Makes a running attempt `worker`'s (a worker that registered again after a coordinator restart and still
    /// runs it, or holds its result). False when the attempt is no longer the task's current one.
    pub fn adopt(&mut self, job_id: &str, key: &str, attempt: u32, worker: &str) -> Result<bool> {
        let tx = self.conn.transaction()?;
        if !is_current(&tx, job_id, key, attempt)? {
            return Ok(false);
        }
        tx.execute(
            "UPDATE tasks SET worker = ?3 WHERE job_id = ?1 AND key = ?2",
            params![job_id, key, worker],
        )?;
        tx.execute(
            "UPDATE attempts SET worker = ?4 WHERE job_id = ?1 AND task_key = ?2 AND attempt = ?3",
            params![job_id, key, attempt, worker],
        )?;
        event(
            &tx,
            job_id,
            "task_adopted",
            key,
            &format!("attempt {attempt} adopted by {worker} after a coordinator restart"),
        )?;
        tx.commit()?;
        Ok(true)
    }

    /// The claim of a task's current running attempt `attempt` (for a result reported outside its stream),
    /// with the worker it runs on and when it started; `None` when that attempt is not current any more.
    pub fn current_claim(
        &self,
        job_id: &str,
        key: &str,
        attempt: u32,
    ) -> Result<Option<(Claim, String, f64)>> {
        let row: Option<(String, String, bool, u32, String, String, f64)> = self
            .conn
            .query_row(
                "SELECT t.kind, t.payload, t.expands, t.attempts, t.state, t.worker,
                        COALESCE((SELECT a.started FROM attempts a WHERE a.job_id = t.job_id
                                  AND a.task_key = t.key AND a.attempt = t.attempts), 0)
                 FROM tasks t WHERE t.job_id = ?1 AND t.key = ?2",
                params![job_id, key],
                |r| {
                    Ok((
                        r.get(0)?,
                        r.get(1)?,
                        r.get(2)?,
                        r.get(3)?,
                        r.get(4)?,
                        r.get(5)?,
                        r.get(6)?,
                    ))
                },
            )
            .optional()?;
        Ok(match row {
            Some((kind, payload, expands, current, state, worker, started))
                if state == "running" && current == attempt =>
            {
                let claim = Claim {
                    job_id: job_id.to_string(),
                    key: key.to_string(),
                    kind,
                    payload,
                    attempt,
                    expands,
                };
                Some((claim, worker, started))
            }
            _ => None,
        })
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
}

pub(super) fn task_row(r: &rusqlite::Row<'_>) -> rusqlite::Result<TaskRow> {
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

/// Records that a report of an attempt the queue has moved past (a worker already given up on) was dropped.
pub(super) fn ignore_stale(
    tx: Transaction<'_>,
    job_id: &str,
    key: &str,
    attempt: u32,
) -> Result<Outcome> {
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

pub(super) fn is_current(
    tx: &Transaction<'_>,
    job_id: &str,
    key: &str,
    attempt: u32,
) -> Result<bool> {
    let row: Option<(String, u32)> = tx
        .query_row(
            "SELECT state, attempts FROM tasks WHERE job_id = ?1 AND key = ?2",
            params![job_id, key],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
        .optional()?;
    Ok(matches!(row, Some((s, a)) if s == "running" && a == attempt))
}

pub(super) fn close_attempt(
    tx: &Transaction<'_>,
    job_id: &str,
    key: &str,
    attempt: u32,
    outcome: &str,
    failure: Option<&Failure>,
) -> Result<()> {
    let (kind, error) = failure.map_or(("", ""), |f| (f.kind.as_str(), f.reason.as_str()));
    tx.execute(
        "UPDATE attempts SET outcome = ?4, error = ?5, finished = ?6, kind = ?7
         WHERE job_id = ?1 AND task_key = ?2 AND attempt = ?3",
        params![job_id, key, attempt, outcome, error, now(), kind],
    )?;
    Ok(())
}
