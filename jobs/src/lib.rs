//! Job specs, planning (job -> task graph), storage and task execution on top of crease-core.
