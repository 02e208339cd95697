//! Errors of job handling, split the way the two callers need them:
//! [`JobError`] is what submit-time checks and planning report to a user (naming the field, URI or file), and
//! [`TaskError`] is the typed failure of one task attempt that the coordinator's retry policy reads as data
//! (Ballista style: bad data is not retryable, I/O is).

use crate::failure::FailureKind;
use crate::storage::errors::{self, Kind};
use serde::{Deserialize, Serialize};

/// A job that cannot be accepted or planned. The message always names the field, URI or file at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JobError {
    /// A field of the job spec is malformed or out of range.
    #[error("job spec: `{field}`: {msg}")]
    Spec { field: String, msg: String },
    /// An input (sequence or anchors file) is unreachable or unreadable.
    #[error("input {uri}: {msg}")]
    Input { uri: String, msg: String },
    /// Storage (the output location, an intermediate) could not be used.
    #[error("storage {uri}: {msg}")]
    Storage { uri: String, msg: String },
    /// The storage at `uri` has no room left (ENOSPC, a quota, an S3 `507 Insufficient Storage`). Named apart
    /// from other storage errors because the fix is an operator's (free space), not a retry.
    #[error("storage full at {uri}: {msg}")]
    Full { uri: String, msg: String },
    /// The storage at `uri` could not be reached within the configured retries and timeout (connection
    /// refused, timed out, DNS); `uri` names the location and, for object stores, the endpoint.
    #[error("storage unreachable at {uri}: {msg}")]
    Unreachable { uri: String, msg: String },
    /// The job is larger than a limit the coordinator enforces (`--max-job-frames`, ...).
    #[error("limit {limit}: {msg}")]
    Limit { limit: String, msg: String },
    /// The task graph could not be built or extended.
    #[error("planning: {0}")]
    Plan(String),
}

impl JobError {
    /// A failure of the storage at `uri`, classified by its source chain ([`errors::kind`]): `Full`,
    /// `Unreachable` (naming the endpoint of a network store), or `Storage`.
    pub fn storage_failure(uri: impl Into<String>, e: &(dyn std::error::Error + 'static)) -> Self {
        let uri = uri.into();
        match errors::kind(e) {
            Kind::Full => JobError::Full {
                msg: e.to_string(),
                uri,
            },
            Kind::Unreachable => JobError::Unreachable {
                uri: match errors::endpoint_of(&uri) {
                    Some(ep) => format!("{uri} (endpoint {ep})"),
                    None => uri,
                },
                msg: e.to_string(),
            },
            Kind::Other => JobError::storage(uri, e),
        }
    }
    /// Like [`JobError::storage_failure`], but an unclassified failure is an input error (reading an input,
    /// an anchors file).
    pub fn input_failure(uri: &str, e: &(dyn std::error::Error + 'static)) -> Self {
        match errors::kind(e) {
            Kind::Other => JobError::input(uri, e),
            _ => JobError::storage_failure(uri, e),
        }
    }
    pub fn spec(field: impl Into<String>, msg: impl Into<String>) -> Self {
        JobError::Spec {
            field: field.into(),
            msg: msg.into(),
        }
    }
    pub fn input(uri: impl Into<String>, msg: impl std::fmt::Display) -> Self {
        JobError::Input {
            uri: uri.into(),
            msg: msg.to_string(),
        }
    }
    pub fn storage(uri: impl Into<String>, msg: impl std::fmt::Display) -> Self {
        JobError::Storage {
            uri: uri.into(),
            msg: msg.to_string(),
        }
    }
}

/// Why one task attempt failed: a [`FailureKind`] (the retry policy reads it, see
/// [`FailureKind::policy`]) and a message naming the file, frame, window or block.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("{reason}{}", if self.retryable() { " (retryable)" } else { "" })]
pub struct TaskError {
    #[serde(default)]
    pub kind: FailureKind,
    /// What went wrong, naming the file, frame, window or block.
    pub reason: String,
    /// For storage kinds: the path or URI at fault (a full worker cache is told from a full output by it).
    #[serde(default)]
    pub location: Option<String>,
}

/// Reason given by [`TaskError::cancelled`].
pub const CANCELLED_REASON: &str = "cancelled";

impl TaskError {
    pub fn new(kind: FailureKind, reason: impl Into<String>) -> Self {
        TaskError {
            kind,
            reason: reason.into(),
            location: None,
        }
    }
    /// A failure that will repeat on any worker (bad data, a malformed task).
    pub fn fatal(reason: impl Into<String>) -> Self {
        TaskError::new(FailureKind::InvalidInput, reason)
    }
    /// A failure that another attempt may not meet.
    pub fn transient(reason: impl Into<String>) -> Self {
        TaskError::new(FailureKind::Transient, reason)
    }
    /// The task stopped because its progress sink reported cancellation (job cancelled, or the worker is shutting
    /// down and hands the task back). Retryable: the work itself is fine.
    pub fn cancelled() -> Self {
        TaskError::new(FailureKind::Cancelled, CANCELLED_REASON)
    }
    pub fn is_cancelled(&self) -> bool {
        self.kind == FailureKind::Cancelled
    }
    /// Whether another attempt may help (the kind's policy).
    pub fn retryable(&self) -> bool {
        self.kind.policy().retryable
    }

    /// Classifies a crease-core error: I/O may be transient; malformed data, bad parameters and numerical
    /// failures repeat wherever the task runs. `context` (task key or stage) is prefixed to the message.
    pub fn from_core(context: &str, e: crease_core::Error) -> Self {
        use crease_core::Error as E;
        match e {
            E::Cancelled => TaskError::cancelled(),
            E::Io { path, source } if errors::is_full_io(&source) => {
                TaskError::from_job(&JobError::Full {
                    uri: path.display().to_string(),
                    msg: format!("{context}: {source}"),
                })
            }
            E::Io { .. } => TaskError::transient(format!("{context}: {e}")),
            E::Numeric { .. } => TaskError::new(FailureKind::Solver, format!("{context}: {e}")),
            _ => TaskError::fatal(format!("{context}: {e}")),
        }
    }

    /// A storage or input failure met by a task. Unreachable storage and plain I/O may pass (an outage, a flaky
    /// mount): retryable. Full storage is not: it will not free itself within the retry backoff, so the job
    /// fails at once with "storage full at …" (the worker turns a full local cache back into a retryable
    /// failure, see `execute::run`, since another worker may have room).
    pub fn from_job(e: &JobError) -> Self {
        let kind = match e {
            JobError::Full { .. } => FailureKind::StorageFullRemote,
            JobError::Limit { .. } => FailureKind::TooLarge,
            JobError::Unreachable { .. } => FailureKind::StorageUnreachable,
            _ => FailureKind::Transient,
        };
        let location = match e {
            JobError::Full { uri, .. } | JobError::Unreachable { uri, .. } => Some(uri.clone()),
            _ => None,
        };
        TaskError {
            location,
            ..TaskError::new(kind, e.to_string())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::ErrorKind;

    #[test]
    fn a_full_volume_is_named_storage_full() {
        let e = std::io::Error::from_raw_os_error(28);
        let msg = JobError::storage_failure("/data/out", &e).to_string();
        assert!(msg.starts_with("storage full at /data/out: "), "{msg}");
    }

    #[test]
    fn a_request_that_was_never_answered_is_unreachable() {
        let e = std::io::Error::other(
            "Error performing PUT http://127.0.0.1:9/b/k after 2 retries - HTTP error: error sending request",
        );
        let msg = JobError::storage_failure("s3://b/out", &e).to_string();
        assert!(
            msg.starts_with("storage unreachable at s3://b/out"),
            "{msg}"
        );
    }

    #[test]
    fn unreachable_names_the_uri() {
        let refused = std::io::Error::new(ErrorKind::ConnectionRefused, "refused");
        let msg = JobError::storage_failure("memory://x/out", &refused).to_string();
        assert!(
            msg.starts_with("storage unreachable at memory://x/out: "),
            "{msg}"
        );
    }
}
