//! Talking back to the coordinator: registration (with the protocol version) and heartbeats. A coordinator
//! that is down is retried with backoff; one that restarted (answers `known: false`) gets a new registration
//! naming the attempts this worker still runs or holds, and then the held results (`ReportTask`).

use crate::running::Tasks;
use crate::{WorkerConfig, WorkerError};
use crease_net::{AuthChannel, ClientSecurity};
use crease_proto as pb;
use crease_proto::coordinator_client::CoordinatorClient;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Mutex;
use tracing::{info, warn};

pub struct Reporter {
    coordinator: String,
    name: String,
    address: String,
    capacity: u32,
    protocol_version: u32,
    tasks: Arc<Tasks>,
    /// The current registration: (client, worker id).
    current: Mutex<Option<(CoordinatorClient<AuthChannel>, String)>>,
    /// TLS trust, the worker token and the message limit for the coordinator.
    net: ClientSecurity,
}

impl Reporter {
    pub fn new(
        config: &WorkerConfig,
        address: String,
        tasks: Arc<Tasks>,
        net: ClientSecurity,
    ) -> Self {
        Reporter {
            coordinator: config.coordinator.clone(),
            name: config.name.clone(),
            address,
            capacity: config.capacity,
            protocol_version: config.protocol_version,
            tasks,
            current: Mutex::new(None),
            net,
        }
    }

    /// Registers, then heartbeats forever; re-registers when the coordinator forgot us. Returns only when the
    /// coordinator refuses the worker.
    pub async fn run(&self) -> Result<(), WorkerError> {
        let mut backoff = Duration::from_millis(100);
        loop {
            let interval = match self.register().await {
                Ok(interval) => {
                    backoff = Duration::from_millis(100);
                    interval
                }
                Err(RegisterError::Refused(msg)) => return Err(WorkerError::Refused(msg)),
                Err(RegisterError::Unreachable(msg)) => {
                    warn!(
                        coordinator = %self.coordinator,
                        "worker `{}`: coordinator {} unreachable ({msg}); retrying in {:.1}s",
                        self.name,
                        self.coordinator,
                        backoff.as_secs_f64()
                    );
                    tokio::time::sleep(backoff).await;
                    backoff = (backoff * 2).min(Duration::from_secs(2));
                    continue;
                }
            };
            // Heartbeats until the coordinator does not know us any more; held results go with them.
            loop {
                self.report_held().await;
                tokio::time::sleep(interval).await;
                match self.beat().await {
                    Some(true) | None => {}
                    Some(false) => {
                        self.tasks.metrics.set_registered(false);
                        warn!(
                            "worker `{}`: the coordinator does not know this worker (restarted?); registering again",
                            self.name
                        );
                        break;
                    }
                }
            }
        }
    }

    /// Heartbeats (announcing the drain) until dropped.
    pub async fn keep_beating(&self) {
        loop {
            tokio::time::sleep(Duration::from_millis(500)).await;
            let _ = self.beat().await;
        }
    }

    /// Tells the coordinator at once that no new task should come (SIGTERM).
    pub async fn announce_draining(&self) {
        let _ = self.beat().await;
    }

    /// Hands the held final events to the coordinator; what it cannot take now (unreachable) is held again.
    async fn report_held(&self) {
        let held = self.tasks.take_held();
        if held.is_empty() {
            return;
        }
        let Some((mut client, worker_id)) = self.current.lock().await.clone() else {
            for (id, ev) in held {
                self.tasks.hold(id, ev);
            }
            return;
        };
        for ((job_id, task_key, attempt), event) in held {
            let report = pb::TaskReport {
                worker_id: worker_id.clone(),
                attempt: Some(pb::AttemptRef {
                    job_id: job_id.clone(),
                    task_key: task_key.clone(),
                    attempt,
                }),
                event: Some(event.clone()),
            };
            match client.report_task(report).await {
                Ok(r) => info!(
                    job_id = %job_id,
                    task = %task_key,
                    attempt,
                    accepted = r.get_ref().accepted,
                    "reported a held attempt to the coordinator ({})",
                    if r.get_ref().accepted { "accepted" } else { "it had moved on" }
                ),
                // A coordinator without ReportTask (older) will never take it.
                Err(s) if s.code() == tonic::Code::Unimplemented => warn!(
                    job_id = %job_id,
                    task = %task_key,
                    attempt,
                    "the coordinator cannot take held results (older version); dropping it"
                ),
                Err(_) => self.tasks.hold((job_id, task_key, attempt), event),
            }
        }
    }

    /// One heartbeat: Some(known) when the coordinator answered.
    async fn beat(&self) -> Option<bool> {
        let current = self.current.lock().await.clone();
        let (mut client, id) = current?;
        let r = client
            .heartbeat(pb::HeartbeatRequest {
                worker_id: id,
                draining: self.tasks.draining(),
                running: self.tasks.running() as u32,
            })
            .await;
        match r {
            Ok(r) => Some(r.into_inner().known),
            Err(s) => {
                // A rotated cluster secret shows up here; without a log line the worker would just be lost.
                if matches!(
                    s.code(),
                    tonic::Code::Unauthenticated | tonic::Code::PermissionDenied
                ) {
                    tracing::warn!(
                        worker = %self.name,
                        "the coordinator refused a heartbeat: {}",
                        s.message()
                    );
                }
                None
            }
        }
    }

    async fn register(&self) -> Result<Duration, RegisterError> {
        let endpoint = self
            .net
            .endpoint(&self.coordinator)
            .map_err(|e| RegisterError::Refused(format!("--coordinator {e}")))?
            .connect_timeout(Duration::from_secs(2));
        let channel = endpoint
            .connect()
            .await
            .map_err(|e| RegisterError::Unreachable(crease_net::client::error_chain(&e)))?;
        let limit = self.net.max_message_bytes;
        let mut client = CoordinatorClient::new(
            tonic::service::interceptor::InterceptedService::new(channel, self.net.bearer()),
        )
        .max_decoding_message_size(limit)
        .max_encoding_message_size(limit);
        let resp = client
            .register_worker(pb::RegisterWorkerRequest {
                protocol_version: self.protocol_version,
                capacity: self.capacity,
                address: self.address.clone(),
                name: self.name.clone(),
                attempts: self
                    .tasks
                    .attempts()
                    .into_iter()
                    .map(|(job_id, task_key, attempt)| pb::AttemptRef {
                        job_id,
                        task_key,
                        attempt,
                    })
                    .collect(),
            })
            .await;
        match resp {
            Ok(r) => {
                let r = r.into_inner();
                self.tasks.metrics.set_registered(true);
                info!(
                    worker = %r.worker_id,
                    coordinator = %self.coordinator,
                    "worker `{}`: registered as {} with {}",
                    self.name,
                    r.worker_id,
                    self.coordinator
                );
                *self.current.lock().await = Some((client, r.worker_id));
                Ok(Duration::from_millis(u64::from(
                    r.heartbeat_interval_ms.max(50),
                )))
            }
            // A wrong protocol version or a refused token will not fix itself by retrying.
            Err(s)
                if matches!(
                    s.code(),
                    tonic::Code::InvalidArgument
                        | tonic::Code::Unauthenticated
                        | tonic::Code::PermissionDenied
                ) =>
            {
                Err(RegisterError::Refused(s.message().to_string()))
            }
            Err(s) => Err(RegisterError::Unreachable(crease_net::client::explain(&s))),
        }
    }
}

enum RegisterError {
    Refused(String),
    Unreachable(String),
}
