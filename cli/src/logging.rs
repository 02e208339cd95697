//! Logs of the long-running commands (`crease coordinator`, `crease worker`): `tracing` events on stderr as
//! text or JSON lines, filtered by `CREASE_LOG`, plus the layer that feeds each task attempt's log tail. The
//! other commands (and local single-node mode) install nothing, so their stderr stays as before.

use anyhow::{anyhow, Result};
use clap::{Args, ValueEnum};
use crease_telemetry::tail::{TailLayer, TASK_SPAN};
use std::net::SocketAddr;
use tracing_subscriber::filter::{filter_fn, EnvFilter, FilterExt, LevelFilter};
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::Layer;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LogFormat {
    /// Human-readable lines.
    Text,
    /// One JSON object per line (for log collectors); fields such as job_id and task are top-level keys.
    Json,
}

/// Observability flags shared by the coordinator and the worker.
#[derive(Args, Debug, Clone)]
pub struct ObsArgs {
    /// Log format on stderr. The level comes from CREASE_LOG (EnvFilter syntax, e.g. `info` or
    /// `crease_coordinator=debug,info`; default info).
    #[arg(long, env = "CREASE_LOG_FORMAT", value_enum, default_value_t = LogFormat::Text)]
    pub log_format: LogFormat,
    /// Serve Prometheus /metrics and the /healthz and /readyz probes over HTTP on this address (port 0 =
    /// any free port; the bound address is logged). Off when not given.
    #[arg(long, env = "CREASE_METRICS_LISTEN")]
    pub metrics_listen: Option<SocketAddr>,
}

/// Installs the process-wide subscriber. Call once, before the runtime starts.
pub fn init(args: &ObsArgs) -> Result<()> {
    let filter = match std::env::var("CREASE_LOG") {
        Ok(s) if !s.trim().is_empty() => EnvFilter::try_new(s.trim())
            .map_err(|e| anyhow!("CREASE_LOG=`{s}` is not a valid log filter: {e}"))?,
        _ => EnvFilter::new("info"),
    };
    // Every event about a task carries its ids as fields; printing the task span too would repeat them.
    let no_task_span = filter_fn(|m| !(m.is_span() && m.name() == TASK_SPAN));
    let fmt = tracing_subscriber::fmt::layer().with_writer(std::io::stderr);
    let fmt = match args.log_format {
        LogFormat::Text => fmt.boxed(),
        LogFormat::Json => fmt
            .json()
            .flatten_event(true)
            .with_current_span(false)
            .with_span_list(false)
            .boxed(),
    };
    tracing_subscriber::registry()
        .with(fmt.with_filter(filter.and(no_task_span)))
        .with(TailLayer.with_filter(LevelFilter::INFO))
        .try_init()
        .map_err(|e| anyhow!("setting up logging: {e}"))
}
