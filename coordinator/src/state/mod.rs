//! Task and worker bookkeeping, apart from the gRPC face (Ballista's `state/` split): the persistent queue
//! ([`store`]) and the in-memory registry of live workers ([`workers`]).

pub mod store;
pub mod workers;
