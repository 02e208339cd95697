//! The coordinator: persistent queue ([`state::store`]), scheduler ([`scheduler`]), gRPC face ([`server`])
//! and the client interface shared by remote and single-node use ([`client`]).
//!
//! Semantics in brief: tasks run at least once; outputs are written under deterministic keys so a re-run
//! overwrites identically; each attempt has a number and a report for an attempt already given up on is
//! ignored; a task is retried with exponential backoff up to the job's `max_task_attempts`; a job fails after
//! `max_task_failures_per_job` failed attempts; a worker that failed a job `blacklist_after` times gets no more
//! of its tasks while another worker can take them (`status` shows it, `crease unblock` clears it); after a
//! restart the attempts that were running are adopted by their workers when these register again (they kept
//! running and hold their results), and only those nobody reports within two worker timeouts are queued again;
//! with no live worker a job reports `waiting` and fails after the grace period. One coordinator per queue
//! file ([`queue_lock`]).

//!
//! Logs are `tracing` events with `job_id`, `task`, `attempt` and `worker` fields; the process that embeds the
//! coordinator decides whether and how they are printed (local single-node mode installs no subscriber, so it
//! prints nothing). Metrics for Prometheus are in [`metrics`].

pub mod client;
pub mod config;
pub mod live;
pub mod metrics;
pub mod queue_lock;
pub mod scheduler;
pub mod server;
pub mod state;

pub use client::{ClientError, EventStream, JobClient, LocalClient, RemoteClient};
pub use config::CoordinatorConfig;
pub use scheduler::{ApiError, Scheduler};
