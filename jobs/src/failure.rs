//! Why a task attempt failed, as a type. The worker names the kind where the failure happens, it travels in
//! the protocol (`crease.v1.FailureKind`) and into the queue file, and the coordinator's retry policy reads
//! [`FailureKind::policy`], never the message text (Ballista's `FailedTask { retryable, count_to_failures }`).

use serde::{Deserialize, Serialize};

/// The kinds of failure. "Local" storage is the worker's own disk (its cache and staging), which another
/// worker may not share; "remote" storage is the job's input and output location (a volume, a quota, an
/// object store), the same for every worker.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FailureKind {
    /// Bad data or parameters, a malformed task: the same on any worker.
    InvalidInput,
    /// The numerics failed (no convergence, a degenerate system): the same on any worker.
    Solver,
    /// Larger than a limit (a coordinator limit, the gRPC message size).
    TooLarge,
    /// The job's storage is full: an operator has to make room; retrying within the backoff will not.
    StorageFullRemote,
    /// This worker's own disk is full: another worker may have room.
    StorageFullLocal,
    /// The storage could not be reached (refused, timed out, DNS): an outage may pass.
    StorageUnreachable,
    /// Another failure that another attempt may not meet (I/O, a flaky mount, an unreadable input).
    #[default]
    Transient,
    /// The task stopped because it was told to (job cancelled, worker draining): the work was fine.
    Cancelled,
    /// The worker did not take the task (at capacity, unreachable, shutting down).
    HandedBack,
    /// The worker died or went silent while the task ran.
    WorkerLost,
    /// The coordinator restarted while the task ran and no worker reported the attempt afterwards.
    CoordinatorRestart,
    /// The worker's answer could not be used (a malformed task output).
    Internal,
}

/// What the retry policy does with a kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Policy {
    /// Another attempt may succeed.
    pub retryable: bool,
    /// Counts towards the task's attempt limit, the job's failure limit and the worker's blocklist count.
    pub counts: bool,
}

impl FailureKind {
    pub const ALL: [FailureKind; 12] = [
        FailureKind::InvalidInput,
        FailureKind::Solver,
        FailureKind::TooLarge,
        FailureKind::StorageFullRemote,
        FailureKind::StorageFullLocal,
        FailureKind::StorageUnreachable,
        FailureKind::Transient,
        FailureKind::Cancelled,
        FailureKind::HandedBack,
        FailureKind::WorkerLost,
        FailureKind::CoordinatorRestart,
        FailureKind::Internal,
    ];

    /// The retry policy of this kind.
    pub fn policy(self) -> Policy {
        use FailureKind as K;
        let (retryable, counts) = match self {
            K::InvalidInput | K::Solver | K::TooLarge | K::StorageFullRemote | K::Internal => {
                (false, true)
            }
            K::StorageFullLocal | K::StorageUnreachable | K::Transient | K::WorkerLost => {
                (true, true)
            }
            K::Cancelled | K::HandedBack | K::CoordinatorRestart => (true, false),
        };
        Policy { retryable, counts }
    }

    /// The name stored in the queue file and shown by `status` and `logs`.
    pub fn as_str(self) -> &'static str {
        use FailureKind as K;
        match self {
            K::InvalidInput => "invalid-input",
            K::Solver => "solver-failure",
            K::TooLarge => "too-large",
            K::StorageFullRemote => "storage-full-remote",
            K::StorageFullLocal => "storage-full-local",
            K::StorageUnreachable => "storage-unreachable",
            K::Transient => "transient",
            K::Cancelled => "cancelled",
            K::HandedBack => "handed-back",
            K::WorkerLost => "worker-lost",
            K::CoordinatorRestart => "coordinator-restart",
            K::Internal => "internal",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.as_str() == s)
    }
}

impl std::fmt::Display for FailureKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_the_policy_table_holds() {
        for k in FailureKind::ALL {
            assert_eq!(FailureKind::parse(k.as_str()), Some(k));
        }
        assert_eq!(FailureKind::parse("boom"), None);
        let p = |k: FailureKind| (k.policy().retryable, k.policy().counts);
        assert_eq!(p(FailureKind::InvalidInput), (false, true));
        assert_eq!(p(FailureKind::StorageFullRemote), (false, true));
        assert_eq!(p(FailureKind::StorageFullLocal), (true, true));
        assert_eq!(p(FailureKind::WorkerLost), (true, true));
        assert_eq!(p(FailureKind::HandedBack), (true, false));
        assert_eq!(p(FailureKind::CoordinatorRestart), (true, false));
    }
}
