//! The coordinator: persistent queue, scheduler, gRPC services.
