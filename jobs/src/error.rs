//! Errors of job handling, split the way the two callers need them:
//! [`JobError`] is what submit-time checks and planning report to a user (naming the field, URI or file), and
//! [`TaskError`] is the typed failure of one task attempt that the coordinator's retry policy reads as data
//! (Ballista style: bad data is not retryable, I/O is).

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
    /// The task graph could not be built or extended.
    #[error("planning: {0}")]
    Plan(String),
}

impl JobError {
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

/// Why one task attempt failed, and whether running it again may help.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("{reason}{}", if *retryable { " (retryable)" } else { "" })]
pub struct TaskError {
    /// True for transient failures (I/O, storage, a worker told to stop); false when the same input would fail
    /// the same way again (bad data, non-convergence, a malformed task).
    pub retryable: bool,
    /// What went wrong, naming the file, frame, window or block.
    pub reason: String,
}

/// Reason given by [`TaskError::cancelled`].
pub const CANCELLED_REASON: &str = "cancelled";

impl TaskError {
    /// A failure that will repeat on any worker.
    pub fn fatal(reason: impl Into<String>) -> Self {
        TaskError {
            retryable: false,
            reason: reason.into(),
        }
    }
    /// A failure that another attempt may not meet.
    pub fn transient(reason: impl Into<String>) -> Self {
        TaskError {
            retryable: true,
            reason: reason.into(),
        }
    }
    /// The task stopped because its progress sink reported cancellation (job cancelled, or the worker is shutting
    /// down and hands the task back). Retryable: the work itself is fine.
    pub fn cancelled() -> Self {
        TaskError::transient(CANCELLED_REASON)
    }
    pub fn is_cancelled(&self) -> bool {
        self.reason == CANCELLED_REASON
    }

    /// Classifies a crease-core error: I/O may be transient; malformed data, bad parameters and numerical
    /// failures repeat wherever the task runs. `context` (task key or stage) is prefixed to the message.
    pub fn from_core(context: &str, e: crease_core::Error) -> Self {
        use crease_core::Error as E;
        match e {
            E::Cancelled => TaskError::cancelled(),
            E::Io { .. } => TaskError::transient(format!("{context}: {e}")),
            _ => TaskError::fatal(format!("{context}: {e}")),
        }
    }
}
