//! Jobs: submission (with its tasks, in one transaction), the job state machine (done, failed, cancelled,
//! waiting) and the queries `status`, `jobs` and the metrics read.

use super::events::event;
use super::rows::{fail_job_tx, insert_tasks, job_from_row, job_row, JOB_COLS};
use super::{now, Counts, JobRow, JobState, NewJob, QueueGauges, Result, Store, StoreError};
use rusqlite::{params, OptionalExtension};

impl Store {
    /// The job submitted earlier with `token`, if any (idempotent submit).
    /// Same token and same spec: that job. Same token, another spec: an error naming that job (a token
    /// identifies one submission; reusing it for another job is a client bug, not a resubmit).
    pub fn job_by_token(&self, token: &str, spec_json: &str) -> Result<Option<String>> {
        let row: Option<(String, String, String)> = self
            .conn
            .query_row(
                "SELECT id, spec_hash, spec FROM jobs WHERE client_token = ?1",
                params![token],
                |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
            )
            .optional()?;
        let Some((id, hash, spec)) = row else {
            return Ok(None);
        };
        // Jobs queued before the hash existed (an upgraded queue file) are compared by their stored spec.
        let hash = if hash.is_empty() {
            spec_hash(&spec)
        } else {
            hash
        };
        if hash != spec_hash(spec_json) {
            return Err(StoreError::TokenReused {
                token: token.to_string(),
                job: id,
            });
        }
        Ok(Some(id))
    }

    /// A job not yet ended that writes to `output` (trailing slashes aside), if any.
    pub fn live_job_writing(&self, output: &str) -> Result<Option<(String, JobState)>> {
        let row: Option<(String, String)> = self
            .conn
            .query_row(
                "SELECT id, state FROM jobs
                 WHERE rtrim(output, '/') = ?1 AND state IN ('queued', 'running', 'waiting')
                 ORDER BY seq LIMIT 1",
                params![output.trim_end_matches('/')],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .optional()?;
        Ok(row.map(|(id, state)| (id, JobState::parse(&state))))
    }

    /// Inserts a job and its initial tasks in one transaction; returns (job id, created). With a client token
    /// that already names a job, nothing is inserted and that job's id is returned.
    pub fn insert_job(&mut self, job: &NewJob) -> Result<(String, bool)> {
        if let Some(token) = &job.client_token {
            if let Some(id) = self.job_by_token(token, &job.spec_json)? {
                return Ok((id, false));
            }
        }
        if let Some((other, state)) = self.live_job_writing(&job.output)? {
            return Err(StoreError::OutputBusy {
                output: job.output.clone(),
                job: other,
                state: state.as_str().to_string(),
            });
        }
        let tx = self.conn.transaction()?;
        let seq: i64 = tx.query_row("SELECT COALESCE(MAX(seq), 0) + 1 FROM jobs", [], |r| {
            r.get(0)
        })?;
        let id = format!("job-{seq:05}");
        let t = now();
        tx.execute(
            "INSERT INTO jobs (seq, id, name, spec, info, output, priority, client_token, state,
                               max_task_attempts, max_failures, submitted, spec_hash)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, 'queued', ?9, ?10, ?11, ?12)",
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
                t,
                spec_hash(&job.spec_json)
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
}

/// A stable hash of a job's canonical spec (its JSON as the coordinator stores it): FNV-1a, 64 bits, as hex.
/// Not a security measure: it tells a resubmission of the same job from another job under the same client
/// token, and stays the same across releases (unlike `std`'s hasher).
pub fn spec_hash(spec_json: &str) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in spec_json.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}
