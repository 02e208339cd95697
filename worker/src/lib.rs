//! The worker: a stateless gRPC server that runs tasks by calling crease-jobs/crease-core.
