//! The gRPC face of the coordinator (Ballista's `scheduler_server`): translates requests to
//! [`Scheduler`] calls and [`ApiError`]s to status codes. No scheduling logic lives here.

use crate::scheduler::{ApiError, Scheduler};
use crease_proto as pb;
use crease_proto::coordinator_server::{Coordinator, CoordinatorServer};
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::Arc;
use tokio_stream::wrappers::{ReceiverStream, TcpListenerStream};
use tokio_stream::{Stream, StreamExt};
use tonic::{Request, Response, Status};

impl From<ApiError> for Status {
    fn from(e: ApiError) -> Self {
        match e {
            ApiError::Invalid(m) => Status::invalid_argument(m),
            ApiError::NotFound(m) => Status::not_found(m),
            ApiError::Internal(m) => Status::internal(m),
        }
    }
}

/// The Coordinator service over a shared scheduler.
pub struct CoordinatorService {
    scheduler: Arc<Scheduler>,
}

impl CoordinatorService {
    pub fn new(scheduler: Arc<Scheduler>) -> Self {
        CoordinatorService { scheduler }
    }
}

type EventStream = Pin<Box<dyn Stream<Item = Result<pb::JobEvent, Status>> + Send>>;

#[tonic::async_trait]
impl Coordinator for CoordinatorService {
    async fn submit_job(
        &self,
        req: Request<pb::SubmitJobRequest>,
    ) -> Result<Response<pb::SubmitJobResponse>, Status> {
        let r = req.into_inner();
        let (job_id, created) = self.scheduler.submit(&r.spec, &r.format).await?;
        Ok(Response::new(pb::SubmitJobResponse { job_id, created }))
    }

    async fn get_job(
        &self,
        req: Request<pb::GetJobRequest>,
    ) -> Result<Response<pb::JobStatus>, Status> {
        let r = req.into_inner();
        Ok(Response::new(
            self.scheduler.status(&r.job_id, r.with_tasks)?,
        ))
    }

    async fn list_jobs(
        &self,
        _req: Request<pb::ListJobsRequest>,
    ) -> Result<Response<pb::ListJobsResponse>, Status> {
        Ok(Response::new(pb::ListJobsResponse {
            jobs: self.scheduler.list()?,
        }))
    }

    async fn cancel_job(
        &self,
        req: Request<pb::CancelJobRequest>,
    ) -> Result<Response<pb::CancelJobResponse>, Status> {
        let state = self.scheduler.cancel(&req.into_inner().job_id)?;
        Ok(Response::new(pb::CancelJobResponse {
            state: state.as_str().to_string(),
        }))
    }

    type WatchJobStream = EventStream;

    async fn watch_job(
        &self,
        req: Request<pb::WatchJobRequest>,
    ) -> Result<Response<Self::WatchJobStream>, Status> {
        let rx = self.scheduler.watch(&req.into_inner().job_id)?;
        let stream = ReceiverStream::new(rx).map(Ok);
        Ok(Response::new(Box::pin(stream)))
    }

    async fn get_task_logs(
        &self,
        req: Request<pb::GetTaskLogsRequest>,
    ) -> Result<Response<pb::GetTaskLogsResponse>, Status> {
        let r = req.into_inner();
        let key = (!r.task_key.is_empty()).then_some(r.task_key.as_str());
        Ok(Response::new(self.scheduler.task_logs(&r.job_id, key)?))
    }

    async fn unblock_workers(
        &self,
        req: Request<pb::UnblockWorkersRequest>,
    ) -> Result<Response<pb::UnblockWorkersResponse>, Status> {
        let r = req.into_inner();
        let worker = (!r.worker.is_empty()).then_some(r.worker.as_str());
        let cleared = self.scheduler.unblock(&r.job_id, worker)?;
        Ok(Response::new(pb::UnblockWorkersResponse { cleared }))
    }

    async fn register_worker(
        &self,
        req: Request<pb::RegisterWorkerRequest>,
    ) -> Result<Response<pb::RegisterWorkerResponse>, Status> {
        Ok(Response::new(self.scheduler.register(&req.into_inner())?))
    }

    async fn heartbeat(
        &self,
        req: Request<pb::HeartbeatRequest>,
    ) -> Result<Response<pb::HeartbeatResponse>, Status> {
        Ok(Response::new(self.scheduler.heartbeat(&req.into_inner())))
    }

    async fn report_task(
        &self,
        req: Request<pb::TaskReport>,
    ) -> Result<Response<pb::ReportTaskResponse>, Status> {
        Ok(Response::new(
            self.scheduler.report_task(req.into_inner()).await?,
        ))
    }
}

/// Workers register and heartbeat with the cluster secret; every other method is a user's.
fn method_role(method: &str) -> crease_net::Role {
    match method {
        "RegisterWorker" | "Heartbeat" | "ReportTask" => crease_net::Role::Worker,
        _ => crease_net::Role::Client,
    }
}

/// Binds `listen`, returns the bound address and a future that serves the coordinator (and runs its
/// dispatch loop) until `shutdown` resolves.
pub async fn serve(
    scheduler: Arc<Scheduler>,
    listen: SocketAddr,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> std::io::Result<(
    SocketAddr,
    impl std::future::Future<Output = Result<(), tonic::transport::Error>>,
)> {
    let net = scheduler.config().server_security.clone();
    for w in net.warnings("coordinator") {
        tracing::warn!("{w}");
    }
    let builder = net.builder().map_err(std::io::Error::other)?;
    let listener = tokio::net::TcpListener::bind(listen).await?;
    let addr = listener.local_addr()?;
    let dispatch = tokio::spawn(Arc::clone(&scheduler).run());
    let service = CoordinatorServer::new(CoordinatorService::new(scheduler))
        .max_decoding_message_size(net.max_message_bytes)
        .max_encoding_message_size(net.max_message_bytes);
    let server = builder
        .layer(net.auth_layer(method_role))
        .add_service(service)
        .serve_with_incoming_shutdown(TcpListenerStream::new(listener), shutdown);
    Ok((addr, async move {
        let r = server.await;
        dispatch.abort();
        r
    }))
}
