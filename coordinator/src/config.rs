//! Coordinator settings.

use std::path::PathBuf;
use std::time::Duration;

#[derive(Debug, Clone)]
pub struct CoordinatorConfig {
    /// Queue file; `None` keeps the queue in memory (local single-node mode).
    pub db: Option<PathBuf>,
    /// How often workers send heartbeats (told to them at registration).
    pub heartbeat_interval: Duration,
    /// A worker silent for this long is lost; its tasks run elsewhere.
    pub worker_timeout: Duration,
    /// How long a job with runnable work waits for a worker before it fails.
    pub no_worker_grace: Duration,
    /// Failed attempts of one job on one worker after which that worker gets no more of the job's tasks (as
    /// long as another worker can take them).
    pub blacklist_after: u32,
    /// First retry delay; doubles per attempt up to `retry_backoff_max`.
    pub retry_backoff: Duration,
    pub retry_backoff_max: Duration,
    /// Kept for callers that set it: logs are `tracing` events now, printed only where the process installed a
    /// subscriber (the `crease coordinator` command does, local single-node mode does not).
    pub log: bool,
    /// TLS, accepted tokens and message limit of the gRPC server (crease-net; default: none, 64 MiB).
    pub server_security: crease_net::ServerSecurity,
    /// How the coordinator calls workers: CA and expected name, the worker token, message limit.
    pub worker_channel: crease_net::ClientSecurity,
    /// Locations jobs may read and write (`--storage-root`); empty: any.
    pub storage_roots: crease_jobs::StorageRoots,
    /// Largest job accepted at submit (`--max-job-frames`, ...).
    pub limits: crease_jobs::JobLimits,
}

impl Default for CoordinatorConfig {
    fn default() -> Self {
        CoordinatorConfig {
            db: None,
            heartbeat_interval: Duration::from_millis(1000),
            worker_timeout: Duration::from_millis(5000),
            no_worker_grace: Duration::from_secs(120),
            blacklist_after: 2,
            retry_backoff: Duration::from_millis(200),
            retry_backoff_max: Duration::from_secs(10),
            log: true,
            server_security: crease_net::ServerSecurity::default(),
            worker_channel: crease_net::ClientSecurity::default(),
            storage_roots: Default::default(),
            limits: Default::default(),
        }
    }
}

impl CoordinatorConfig {
    /// After a restart, how long the tasks that were running wait for their workers to register again and
    /// adopt them before they are queued again: two worker timeouts (a live worker re-registers within one).
    pub fn adopt_window(&self) -> Duration {
        self.worker_timeout * 2
    }

    /// Delay before attempt `attempt + 1` after attempt `attempt` failed.
    pub fn backoff(&self, attempt: u32) -> Duration {
        let factor = 1u32 << attempt.saturating_sub(1).min(16);
        (self.retry_backoff * factor).min(self.retry_backoff_max)
    }
}
