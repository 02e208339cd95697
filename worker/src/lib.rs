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

/// `eprintln!` when `$on` (logging is off in local single-node mode, where the CLI owns stderr).
macro_rules! log {
    ($on:expr, $($t:tt)*) => {
        if $on {
            eprintln!($($t)*)
        }
    };
}

pub mod report;
pub mod running;
pub mod servant;

use crease_proto::worker_server::WorkerServer;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use tokio_stream::wrappers::TcpListenerStream;

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
    /// Log registration, drain and shutdown to stderr.
    pub log: bool,
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
    let advertise = config.advertise.clone().unwrap_or_else(|| {
        let scheme = if net.server.tls.is_some() {
            "https"
        } else {
            "http"
        };
        format!("{scheme}://{addr}")
    });
    let state = Arc::new(running::Tasks::new(config.cache_dir.clone()));
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
    log!(
        config.log,
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
        return Err(e);
    }
    // Drain: no new tasks; let running ones finish, then hand the rest back.
    state.set_draining();
    log!(
        config.log,
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
            log!(
                config.log,
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
    log!(config.log, "worker `{}`: stopped", config.name);
    Ok(())
}
