//! The workers ever registered, as rows: ids survive a coordinator restart so new ones do not collide.

use super::{now, Result, Store};
use rusqlite::params;

impl Store {
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
}
