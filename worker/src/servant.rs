//! The Worker gRPC service: `Execute` streams one task's events, `Cancel` stops one.

use crate::running::Tasks;
use crease_proto as pb;
use crease_proto::worker_server::Worker;
use std::pin::Pin;
use std::sync::Arc;
use tokio_stream::wrappers::UnboundedReceiverStream;
use tokio_stream::Stream;
use tonic::{Request, Response, Status};

pub struct WorkerService {
    tasks: Arc<Tasks>,
}

impl WorkerService {
    pub fn new(tasks: Arc<Tasks>) -> Self {
        WorkerService { tasks }
    }
}

type TaskStream = Pin<Box<dyn Stream<Item = Result<pb::TaskEvent, Status>> + Send>>;

#[tonic::async_trait]
impl Worker for WorkerService {
    type ExecuteStream = TaskStream;

    async fn execute(&self, req: Request<pb::Task>) -> Result<Response<TaskStream>, Status> {
        if self.tasks.draining() {
            return Err(Status::unavailable(
                "this worker is shutting down and takes no new tasks",
            ));
        }
        let (tx, rx) = tokio::sync::mpsc::unbounded_channel();
        self.tasks.start(req.into_inner(), tx);
        Ok(Response::new(Box::pin(UnboundedReceiverStream::new(rx))))
    }

    async fn cancel(
        &self,
        req: Request<pb::CancelTaskRequest>,
    ) -> Result<Response<pb::CancelTaskResponse>, Status> {
        let r = req.into_inner();
        let found = self.tasks.cancel(&(r.job_id, r.task_key, r.attempt));
        Ok(Response::new(pb::CancelTaskResponse { found }))
    }
}
