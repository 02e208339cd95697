//! One error type for all of crease-core.
//!
//! Every variant carries *where* the problem is (file, frame, line, element index) because the people reading
//! these messages are pipeline engineers looking at a farm log, not at a debugger.

use std::path::PathBuf;

/// Result alias used throughout crease-core.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Errors raised by crease-core. Messages always name the offending file, frame, line or index.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system refused a read or write.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file could be read but its contents are malformed (syntax, truncation, wrong header).
    #[error("{}{}: {msg}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Format {
        path: PathBuf,
        line: Option<usize>,
        msg: String,
    },
    /// The geometry or topology violates what the algorithms need (NaN, degenerate or non-manifold elements,
    /// frames that disagree).
    #[error("invalid mesh{}{}: {msg}", path.as_ref().map(|p| format!(" {}", p.display())).unwrap_or_default(), frame.map(|f| format!(" (frame {f})")).unwrap_or_default())]
    Mesh {
        path: Option<PathBuf>,
        frame: Option<usize>,
        msg: String,
    },
    /// The anchors file is malformed or does not match the sequence.
    #[error("anchors{}: {msg}", path.as_ref().map(|p| format!(" {}", p.display())).unwrap_or_default())]
    Anchors { path: Option<PathBuf>, msg: String },
    /// A user-supplied parameter is outside its valid range.
    #[error("invalid parameter `{name}`: {msg}")]
    Param { name: String, msg: String },
    /// A numerical routine failed (factorization breakdown, non-convergence).
    #[error("{stage}: {msg}")]
    Numeric { stage: String, msg: String },
    /// The caller asked the computation to stop.
    #[error("cancelled")]
    Cancelled,
}

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    pub fn format(path: impl Into<PathBuf>, line: Option<usize>, msg: impl Into<String>) -> Self {
        Error::Format {
            path: path.into(),
            line,
            msg: msg.into(),
        }
    }

    pub fn mesh(msg: impl Into<String>) -> Self {
        Error::Mesh {
            path: None,
            frame: None,
            msg: msg.into(),
        }
    }

    pub fn param(name: impl Into<String>, msg: impl Into<String>) -> Self {
        Error::Param {
            name: name.into(),
            msg: msg.into(),
        }
    }

    pub fn numeric(stage: impl Into<String>, msg: impl Into<String>) -> Self {
        Error::Numeric {
            stage: stage.into(),
            msg: msg.into(),
        }
    }

    /// Attach a file and frame to a mesh error that was raised without them (validation runs on plain arrays
    /// and does not know where they came from).
    pub fn at(self, path: Option<PathBuf>, frame: Option<usize>) -> Self {
        match self {
            Error::Mesh {
                path: p,
                frame: f,
                msg,
            } => Error::Mesh {
                path: p.or(path),
                frame: f.or(frame),
                msg,
            },
            other => other,
        }
    }
}
