//! The worker: a stateless gRPC server that registers with a coordinator, runs the tasks it is sent by calling
//! `crease_jobs::execute`, streams their progress back, and drains on shutdown (finishes its tasks within the
//! drain timeout, then hands the rest back).
//!
//! Split the way OpenCue splits its daemon: [`running`] runs work, [`servant`] is the RPC face, [`report`]
//! talks back to the coordinator (registration and heartbeats).
//!
//! Test hook (documented because chaos tests rely on it): `CREASE_TEST_TASK_DELAY=<kind>=<ms>[,<kind>=<ms>]`
//! makes the worker wait (cancellably) before running tasks of those kinds, so a test can kill a worker or
//! cancel a job while a task is known to be in flight on tiny inputs.

//!
//! Logs are `tracing` events (every one about a task carries `job_id`, `task` and `attempt`); each attempt's
//! events and stage messages are also kept in a bounded tail sent back with its result (`crease logs`).
//! [`metrics`] holds the Prometheus metrics and readiness served on `metrics_listen`.

pub mod metrics;
pub mod report;
pub mod running;
pub mod servant;

use crease_proto::worker_server::WorkerServer;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use tokio_stream::wrappers::TcpListenerStream;
use tracing::{info, warn};

/// Worker settings.
#[derive(Debug, Clone)]
pub struct WorkerConfig {
    /// Coordinator URL, e.g. `http://127.0.0.1:7070`.
    pub coordinator: String,
    /// Where the worker's own gRPC server listens (port 0 = any free port).
    pub listen: SocketAddr,
    /// URL the coordinator uses to reach this worker (default: `http://<bound address>`).
    pub advertise: Option<String>,
    pub name: String,
    /// Tasks run at the same time.
    pub capacity: u32,
    /// Local cache for remote inputs.
    pub cache_dir: PathBuf,
    /// On shutdown, how long running tasks may take to finish before they are handed back.
    pub drain_timeout: Duration,
    /// Protocol version announced at registration (tests announce a wrong one).
    pub protocol_version: u32,
    /// Kept for callers that set it: logs are `tracing` events now, printed only where the process installed a
    /// subscriber (the `crease worker` command does, local single-node mode does not).
    pub log: bool,
    /// Where to serve `/metrics`, `/healthz` and `/readyz` over HTTP (none: no HTTP server).
    pub metrics_listen: Option<SocketAddr>,
}

/// TLS, tokens and message limits of a worker (crease-net): its own server (requires the worker token on
/// Execute/Cancel when configured) and its channel to the coordinator (presents the worker token).
#[derive(Debug, Clone, Default)]
pub struct WorkerSecurity {
    pub server: crease_net::ServerSecurity,
    pub coordinator: crease_net::ClientSecurity,
}

/// Errors that stop a worker.
#[derive(Debug, thiserror::Error)]
pub enum WorkerError {
    #[error("worker: cannot listen on {addr}: {source}")]
    Listen {
        addr: SocketAddr,
        source: std::io::Error,
    },
    #[error("worker: the coordinator refused the registration: {0}")]
    Refused(String),
    #[error("worker: gRPC server: {0}")]
    Serve(String),
    #[error("worker: cannot serve metrics on {addr}: {source}")]
    Metrics {
        addr: SocketAddr,
        source: std::io::Error,
    },
    #[error("worker: {0}")]
    Config(String),
}

/// Runs a worker until `shutdown` resolves, then drains. Returns an error when the coordinator refuses it.
pub async fn run(
    config: WorkerConfig,
    shutdown: impl std::future::Future<Output = ()> + Send,
) -> Result<(), WorkerError> {
    run_with(config, WorkerSecurity::default(), shutdown).await
}

/// [`run`] with TLS, tokens and message limits.
pub async fn run_with(
    config: WorkerConfig,
    net: WorkerSecurity,
    shutdown: impl std::future::Future<Output = ()> + Send,
) -> Result<(), WorkerError> {
    for w in net.server.warnings("worker") {
        tracing::warn!("{w}");
    }
    let builder = net
        .server
        .builder()
        .map_err(|e| WorkerError::Config(e.to_string()))?;
    let listener = tokio::net::TcpListener::bind(config.listen)
        .await
        .map_err(|source| WorkerError::Listen {
            addr: config.listen,
            source,
        })?;
    let addr = listener
        .local_addr()
        .map_err(|source| WorkerError::Listen {
            addr: config.listen,
            source,
        })?;
    let metrics = Arc::new(metrics::WorkerMetrics::new(config.capacity));
    let state = Arc::new(running::Tasks::new(
        config.cache_dir.clone(),
        Arc::clone(&metrics),
    ));
    let metrics_server = match config.metrics_listen {
        Some(at) => {
            let (render_state, ready_state) = (Arc::clone(&state), Arc::clone(&state));
            let (bound, handle) = crease_telemetry::http::serve(
                at,
                Arc::new(move || render_state.metrics.render(render_state.running())),
                Arc::new(move || ready_state.metrics.registered() && !ready_state.draining()),
            )
            .await
            .map_err(|source| WorkerError::Metrics { addr: at, source })?;
            info!(address = %bound, "metrics listening on {bound}");
            Some(handle)
        }
        None => None,
    };
    let advertise = config.advertise.clone().unwrap_or_else(|| {
        let scheme = if net.server.tls.is_some() {
            "https"
        } else {
            "http"
        };
        format!("{scheme}://{addr}")
    });
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let limit = net.server.max_message_bytes;
    let service = WorkerServer::new(servant::WorkerService::new(
        Arc::clone(&state),
        config.capacity,
    ))
    .max_decoding_message_size(limit)
    .max_encoding_message_size(limit);
    let server = tokio::spawn(
        builder
            // Only the coordinator (holding the cluster secret) may run or cancel tasks here.
            .layer(net.server.auth_layer(|_| crease_net::Role::Worker))
            .add_service(service)
            .serve_with_incoming_shutdown(TcpListenerStream::new(listener), async {
                let _ = stop_rx.await;
            }),
    );
    info!(
        name = %config.name,
        coordinator = %config.coordinator,
        capacity = config.capacity,
        "worker `{}`: listening on {addr}, coordinator {}, capacity {}",
        config.name,
        config.coordinator,
        config.capacity
    );
    let reporter = report::Reporter::new(&config, advertise, Arc::clone(&state), net.coordinator);
    let outcome = tokio::select! {
        r = reporter.run() => r,
        _ = shutdown => Ok(()),
    };
    if let Err(e) = outcome {
        let _ = stop_tx.send(());
        if let Some(h) = &metrics_server {
            h.abort();
        }
        return Err(e);
    }
    // Drain: no new tasks; let running ones finish, then hand the rest back.
    state.set_draining();
    info!(
        name = %config.name,
        running = state.running(),
        "worker `{}`: draining ({} task(s) running, up to {:.0}s)",
        config.name,
        state.running(),
        config.drain_timeout.as_secs_f64()
    );
    reporter.announce_draining().await;
    // Keep heartbeating while draining, or the coordinator would declare the worker lost mid-task.
    let drain = async {
        if !state.wait_idle(config.drain_timeout).await {
            let n = state.cancel_all();
            warn!(
                name = %config.name,
                "worker `{}`: handing back {n} unfinished task(s)",
                config.name
            );
            state.wait_idle(Duration::from_secs(10)).await;
        }
    };
    tokio::select! {
        _ = drain => {}
        _ = reporter.keep_beating() => {}
    }
    let _ = stop_tx.send(());
    match server.await {
        Ok(Ok(())) => {}
        Ok(Err(e)) => return Err(WorkerError::Serve(e.to_string())),
        Err(e) => return Err(WorkerError::Serve(e.to_string())),
    }
    if let Some(h) = metrics_server {
        h.abort();
    }
    info!(name = %config.name, "worker `{}`: stopped", config.name);
    Ok(())
}
