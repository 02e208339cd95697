//! Local single-node mode: an in-process coordinator (queue in memory) with its gRPC service on 127.0.0.1
//! and workers on 127.0.0.1 that register with it, exactly as on a farm. `crease run` submits through
//! [`LocalClient`], the same [`crease_coordinator::JobClient`] interface the remote commands use.

use anyhow::{Context, Result};
use crease_coordinator::{CoordinatorConfig, LocalClient, Scheduler};
use std::time::Duration;
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

/// A running single-node cluster; [`LocalCluster::stop`] shuts it down.
pub struct LocalCluster {
    pub client: LocalClient,
    stops: Vec<oneshot::Sender<()>>,
    handles: Vec<JoinHandle<()>>,
}

impl LocalCluster {
    /// Starts the coordinator and `workers` workers of `capacity` tasks each.
    pub async fn start(
        workers: usize,
        capacity: u32,
        cache_dir: std::path::PathBuf,
    ) -> Result<Self> {
        let config = CoordinatorConfig {
            db: None,
            heartbeat_interval: Duration::from_millis(500),
            worker_timeout: Duration::from_secs(10),
            log: false,
            ..CoordinatorConfig::default()
        };
        let scheduler = Scheduler::open(config).context("starting the in-process coordinator")?;
        let (stop_tx, stop_rx) = oneshot::channel::<()>();
        let (addr, serve) = crease_coordinator::server::serve(
            scheduler.clone(),
            "127.0.0.1:0".parse().expect("loopback address"),
            async {
                let _ = stop_rx.await;
            },
        )
        .await
        .context("starting the local coordinator on 127.0.0.1")?;
        let mut stops = vec![stop_tx];
        let mut handles = vec![tokio::spawn(async move {
            if let Err(e) = serve.await {
                eprintln!("local coordinator: {e}");
            }
        })];
        for i in 0..workers.max(1) {
            let (tx, rx) = oneshot::channel::<()>();
            let config = crease_worker::WorkerConfig {
                coordinator: format!("http://{addr}"),
                listen: "127.0.0.1:0".parse().expect("loopback address"),
                advertise: None,
                name: format!("local-{i}"),
                capacity,
                cache_dir: cache_dir.clone(),
                drain_timeout: Duration::from_secs(5),
                protocol_version: crease_proto::PROTOCOL_VERSION,
                log: false,
                metrics_listen: None,
            };
            stops.insert(0, tx);
            handles.insert(
                0,
                tokio::spawn(async move {
                    if let Err(e) = crease_worker::run(config, async {
                        let _ = rx.await;
                    })
                    .await
                    {
                        eprintln!("local worker: {e}");
                    }
                }),
            );
        }
        Ok(LocalCluster {
            client: LocalClient::new(scheduler),
            stops,
            handles,
        })
    }

    /// Stops the workers, then the coordinator.
    pub async fn stop(self) {
        for (stop, handle) in self.stops.into_iter().zip(self.handles) {
            let _ = stop.send(());
            let _ = tokio::time::timeout(Duration::from_secs(15), handle).await;
        }
    }
}
