//! One client interface with two implementations (the Quickwit shape): [`RemoteClient`] talks gRPC to a
//! coordinator elsewhere, [`LocalClient`] calls an in-process [`Scheduler`]. The CLI's `submit`, `status`,
//! `watch`, `cancel` and `jobs` and the single-node `crease run` are written once against [`JobClient`].

use crate::scheduler::{ApiError, Scheduler};
use crease_net::{AuthChannel, ClientSecurity};
use crease_proto as pb;
use crease_proto::coordinator_client::CoordinatorClient;
use futures::stream::BoxStream;
use futures::StreamExt;
use std::future::Future;
use std::sync::Arc;
use tokio_stream::wrappers::ReceiverStream;

/// A client-side error: the message is what the user sees.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ClientError(pub String);

impl From<tonic::Status> for ClientError {
    fn from(s: tonic::Status) -> Self {
        ClientError(crease_net::client::explain(&s))
    }
}

impl From<ApiError> for ClientError {
    fn from(e: ApiError) -> Self {
        ClientError(e.to_string())
    }
}

pub type EventStream = BoxStream<'static, Result<pb::JobEvent, ClientError>>;

/// What a user can ask of a coordinator.
pub trait JobClient: Send + Sync {
    /// Submits a job spec (`format` = "toml" or "json"); returns (job id, created).
    fn submit(
        &self,
        spec: String,
        format: &str,
    ) -> impl Future<Output = Result<(String, bool), ClientError>> + Send;
    fn status(
        &self,
        job_id: &str,
        with_tasks: bool,
    ) -> impl Future<Output = Result<pb::JobStatus, ClientError>> + Send;
    fn list(&self) -> impl Future<Output = Result<Vec<pb::JobStatus>, ClientError>> + Send;
    /// Returns the job's state after the request.
    fn cancel(&self, job_id: &str) -> impl Future<Output = Result<String, ClientError>> + Send;
    fn watch(&self, job_id: &str) -> impl Future<Output = Result<EventStream, ClientError>> + Send;
    /// Log tails of a job's task attempts (`task_key`: one task, or all).
    fn logs(
        &self,
        job_id: &str,
        task_key: Option<&str>,
    ) -> impl Future<Output = Result<Vec<pb::TaskAttemptLog>, ClientError>> + Send;
    /// Clears a job's worker blocklist (`worker`: one, or all); returns the workers cleared.
    fn unblock(
        &self,
        job_id: &str,
        worker: Option<&str>,
    ) -> impl Future<Output = Result<Vec<String>, ClientError>> + Send;
}

/// gRPC client of a coordinator.
#[derive(Clone)]
pub struct RemoteClient {
    inner: CoordinatorClient<AuthChannel>,
    plaintext: bool,
}

impl RemoteClient {
    /// Connects to `url` (e.g. `http://127.0.0.1:7070`).
    pub async fn connect(url: &str) -> Result<Self, ClientError> {
        Self::connect_with(url, &ClientSecurity::default()).await
    }

    /// Connects with TLS and a token (`--tls-ca`, `--token-file`).
    pub async fn connect_with(url: &str, net: &ClientSecurity) -> Result<Self, ClientError> {
        let endpoint = net
            .endpoint(url)
            .map_err(|e| ClientError(format!("coordinator address {e}")))?
            .connect_timeout(std::time::Duration::from_secs(5));
        let channel = endpoint.connect().await.map_err(|e| {
            let msg = crease_net::client::error_chain(&e);
            let hint = if msg.contains("invalid peer certificate") {
                " (the coordinator's certificate is not signed by the CA given with --tls-ca)"
            } else if url.starts_with("http://") {
                " (if the coordinator serves TLS, use an https:// URL and --tls-ca)"
            } else {
                ""
            };
            ClientError(format!(
                "cannot reach the coordinator at {url}: {msg}{hint}"
            ))
        })?;
        let inner = CoordinatorClient::new(tonic::service::interceptor::InterceptedService::new(
            channel,
            net.bearer(),
        ))
        .max_decoding_message_size(net.max_message_bytes)
        .max_encoding_message_size(net.max_message_bytes);
        Ok(RemoteClient {
            inner,
            plaintext: url.starts_with("http://"),
        })
    }

    /// A failed call, with a hint for the usual causes of a refused connection or token.
    fn err(&self, s: tonic::Status) -> ClientError {
        let msg = crease_net::client::explain(&s);
        let hint = if s.code() == tonic::Code::Unauthenticated {
            " (give a token with --token-file or CREASE_TOKEN)"
        } else if msg.contains("invalid peer certificate") {
            " (the coordinator's certificate is not signed by the CA given with --tls-ca)"
        } else if self.plaintext && msg.contains("transport error") {
            " (the coordinator closed the connection: if it serves TLS, use an https:// URL and --tls-ca)"
        } else {
            ""
        };
        ClientError(format!("{msg}{hint}"))
    }
}

impl JobClient for RemoteClient {
    async fn submit(&self, spec: String, format: &str) -> Result<(String, bool), ClientError> {
        let r = self
            .inner
            .clone()
            .submit_job(pb::SubmitJobRequest {
                spec,
                format: format.to_string(),
            })
            .await
            .map_err(|e| self.err(e))?
            .into_inner();
        Ok((r.job_id, r.created))
    }

    async fn status(&self, job_id: &str, with_tasks: bool) -> Result<pb::JobStatus, ClientError> {
        Ok(self
            .inner
            .clone()
            .get_job(pb::GetJobRequest {
                job_id: job_id.to_string(),
                with_tasks,
            })
            .await
            .map_err(|e| self.err(e))?
            .into_inner())
    }

    async fn list(&self) -> Result<Vec<pb::JobStatus>, ClientError> {
        Ok(self
            .inner
            .clone()
            .list_jobs(pb::ListJobsRequest {})
            .await
            .map_err(|e| self.err(e))?
            .into_inner()
            .jobs)
    }

    async fn cancel(&self, job_id: &str) -> Result<String, ClientError> {
        Ok(self
            .inner
            .clone()
            .cancel_job(pb::CancelJobRequest {
                job_id: job_id.to_string(),
            })
            .await
            .map_err(|e| self.err(e))?
            .into_inner()
            .state)
    }

    async fn unblock(
        &self,
        job_id: &str,
        worker: Option<&str>,
    ) -> Result<Vec<String>, ClientError> {
        Ok(self
            .inner
            .clone()
            .unblock_workers(pb::UnblockWorkersRequest {
                job_id: job_id.to_string(),
                worker: worker.unwrap_or_default().to_string(),
            })
            .await
            .map_err(|e| self.err(e))?
            .into_inner()
            .cleared)
    }

    async fn watch(&self, job_id: &str) -> Result<EventStream, ClientError> {
        let stream = self
            .inner
            .clone()
            .watch_job(pb::WatchJobRequest {
                job_id: job_id.to_string(),
            })
            .await
            .map_err(|e| self.err(e))?
            .into_inner();
        Ok(stream.map(|r| r.map_err(ClientError::from)).boxed())
    }

    async fn logs(
        &self,
        job_id: &str,
        task_key: Option<&str>,
    ) -> Result<Vec<pb::TaskAttemptLog>, ClientError> {
        Ok(self
            .inner
            .clone()
            .get_task_logs(pb::GetTaskLogsRequest {
                job_id: job_id.to_string(),
                task_key: task_key.unwrap_or_default().to_string(),
            })
            .await?
            .into_inner()
            .attempts)
    }
}

/// In-process client of a scheduler (single-node mode).
#[derive(Clone)]
pub struct LocalClient {
    scheduler: Arc<Scheduler>,
}

impl LocalClient {
    pub fn new(scheduler: Arc<Scheduler>) -> Self {
        LocalClient { scheduler }
    }
}

impl JobClient for LocalClient {
    async fn submit(&self, spec: String, format: &str) -> Result<(String, bool), ClientError> {
        Ok(self.scheduler.submit(&spec, format).await?)
    }

    async fn status(&self, job_id: &str, with_tasks: bool) -> Result<pb::JobStatus, ClientError> {
        Ok(self.scheduler.status(job_id, with_tasks)?)
    }

    async fn list(&self) -> Result<Vec<pb::JobStatus>, ClientError> {
        Ok(self.scheduler.list()?)
    }

    async fn cancel(&self, job_id: &str) -> Result<String, ClientError> {
        Ok(self.scheduler.cancel(job_id)?.as_str().to_string())
    }

    async fn unblock(
        &self,
        job_id: &str,
        worker: Option<&str>,
    ) -> Result<Vec<String>, ClientError> {
        Ok(self.scheduler.unblock(job_id, worker)?)
    }

    async fn watch(&self, job_id: &str) -> Result<EventStream, ClientError> {
        let rx = self.scheduler.watch(job_id)?;
        Ok(ReceiverStream::new(rx).map(Ok).boxed())
    }

    async fn logs(
        &self,
        job_id: &str,
        task_key: Option<&str>,
    ) -> Result<Vec<pb::TaskAttemptLog>, ClientError> {
        Ok(self.scheduler.task_logs(job_id, task_key)?.attempts)
    }
}
