//! Registry of live workers: capacity, running count, liveness and drain state. Kept in memory (workers
//! re-register after a coordinator restart); the `workers` table only keeps history.

use crease_net::AuthChannel as Channel;
use crease_proto::worker_client::WorkerClient;
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// One registered worker.
#[derive(Debug, Clone)]
pub struct WorkerEntry {
    pub id: String,
    pub name: String,
    pub address: String,
    pub capacity: u32,
    pub running: u32,
    pub last_seen: Instant,
    /// A draining worker (SIGTERM) finishes what it runs and gets nothing new.
    pub draining: bool,
    pub client: WorkerClient<Channel>,
}

impl WorkerEntry {
    pub fn free(&self) -> u32 {
        if self.draining {
            0
        } else {
            self.capacity.saturating_sub(self.running)
        }
    }
}

/// Live workers by id.
#[derive(Default)]
pub struct Workers {
    by_id: BTreeMap<String, WorkerEntry>,
}

impl Workers {
    pub fn insert(&mut self, w: WorkerEntry) {
        self.by_id.insert(w.id.clone(), w);
    }

    pub fn get_mut(&mut self, id: &str) -> Option<&mut WorkerEntry> {
        self.by_id.get_mut(id)
    }

    pub fn get(&self, id: &str) -> Option<&WorkerEntry> {
        self.by_id.get(id)
    }

    pub fn remove(&mut self, id: &str) -> Option<WorkerEntry> {
        self.by_id.remove(id)
    }

    /// Workers that can take work now or later (not draining).
    pub fn live(&self) -> usize {
        self.by_id.values().filter(|w| !w.draining).count()
    }

    pub fn total_free(&self) -> u32 {
        self.by_id.values().map(WorkerEntry::free).sum()
    }

    /// Ids of workers whose last heartbeat is older than `timeout`.
    pub fn expired(&self, timeout: Duration) -> Vec<String> {
        self.by_id
            .values()
            .filter(|w| w.last_seen.elapsed() > timeout)
            .map(|w| w.id.clone())
            .collect()
    }

    /// The worker with the most free slots among those `allowed` accepts (ties: lowest id), so work spreads
    /// over the farm instead of filling one machine first.
    pub fn pick(&self, allowed: impl Fn(&WorkerEntry) -> bool) -> Option<String> {
        self.by_id
            .values()
            .filter(|w| w.free() > 0 && allowed(w))
            .max_by(|a, b| a.free().cmp(&b.free()).then_with(|| b.id.cmp(&a.id)))
            .map(|w| w.id.clone())
    }

    pub fn ids(&self) -> Vec<String> {
        self.by_id.keys().cloned().collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(id: &str, capacity: u32, running: u32, draining: bool) -> WorkerEntry {
        let channel = crease_net::ClientSecurity::default()
            .connect_lazy("http://127.0.0.1:9")
            .unwrap();
        WorkerEntry {
            id: id.into(),
            name: id.into(),
            address: "http://127.0.0.1:9".into(),
            capacity,
            running,
            last_seen: Instant::now(),
            draining,
            client: WorkerClient::new(channel),
        }
    }

    #[tokio::test]
    async fn picks_the_worker_with_most_free_slots_and_skips_draining_and_refused_ones() {
        let mut w = Workers::default();
        w.insert(entry("w1", 2, 1, false));
        w.insert(entry("w2", 4, 1, false));
        w.insert(entry("w3", 8, 0, true));
        assert_eq!(w.total_free(), 4);
        assert_eq!(w.live(), 2);
        assert_eq!(w.pick(|_| true).as_deref(), Some("w2"));
        // A blacklisted worker is passed over while another can take the task.
        assert_eq!(w.pick(|e| e.id != "w2").as_deref(), Some("w1"));
        assert_eq!(w.pick(|e| e.id == "w3"), None);
        w.get_mut("w1").unwrap().running = 2;
        assert_eq!(w.pick(|e| e.id != "w2"), None);
    }
}
