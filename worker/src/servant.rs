//! The Worker gRPC service: `Execute` streams one task's events, `Cancel` stops one. `Execute` beyond the
//! worker's capacity is refused with `RESOURCE_EXHAUSTED` (the coordinator hands the task back without
//! charging it), so a worker is never overcommitted even if a coordinator miscounts.

use crate::running::Tasks;
use crease_proto as pb;
use crease_proto::worker_server::Worker;
use std::pin::Pin;
use std::sync::Arc;
use tokio::sync::{OwnedSemaphorePermit, Semaphore};
use tokio_stream::wrappers::UnboundedReceiverStream;
use tokio_stream::Stream;
use tonic::{Request, Response, Status};

pub struct WorkerService {
    tasks: Arc<Tasks>,
    capacity: u32,
    /// One permit per task slot. A permit is released just before its task's last event (result or failure)
    /// is sent, before the coordinator can react to it, so the next Execute never races with the previous
    /// task's bookkeeping.
    slots: Arc<Semaphore>,
}

impl WorkerService {
    pub fn new(tasks: Arc<Tasks>, capacity: u32) -> Self {
        WorkerService {
            tasks,
            capacity,
            slots: Arc::new(Semaphore::new(capacity.max(1) as usize)),
        }
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
        let permit: OwnedSemaphorePermit =
            Arc::clone(&self.slots).try_acquire_owned().map_err(|_| {
                Status::resource_exhausted(format!(
                    "this worker already runs {} task(s), its capacity",
                    self.capacity
                ))
            })?;
        let (tx, rx) = tokio::sync::mpsc::unbounded_channel();
        // The task holds its slot, not the stream: a task that outlives its stream (the coordinator
        // restarted) still counts against the capacity until it ends.
        self.tasks.start(req.into_inner(), tx, permit);
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
