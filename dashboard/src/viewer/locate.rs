//! How an id in a viewer URL becomes the folders to show: a coordinator looks the job up in its queue, `crease
//! view` has the one folder it was started on. Everything after that is the same code.

use std::path::PathBuf;

/// The folders behind one id. At least one of `input` and `output` is set.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Located {
    /// What the page calls it (the job's name, the folder's name).
    pub name: String,
    /// The captured sequence, when it is on this machine's filesystem.
    pub input: Option<PathBuf>,
    /// The output folder, only once it is complete (its `report.json` is written last).
    pub output: Option<PathBuf>,
    /// Where `report.json` and `eval.json` are read (a path or a storage URI: remote outputs still have a report
    /// even though their frames are not read here).
    pub output_uri: Option<String>,
    /// The anchors file the job was given, for outputs that hold no `anchors.json` of their own.
    pub anchors: Option<PathBuf>,
    /// Why a part is missing (a remote location, an output still being written), for the page to say.
    pub notes: Vec<String>,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LocateError {
    /// No such id (404).
    NotFound(String),
    /// The id exists but nothing of it can be shown here (409, with the reason).
    Unavailable(String),
    /// The lookup itself failed (500).
    Internal(String),
}

impl std::fmt::Display for LocateError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LocateError::NotFound(m) | LocateError::Unavailable(m) | LocateError::Internal(m) => {
                f.write_str(m)
            }
        }
    }
}

/// Turns an id into folders. Implementations must not join the id into a path: it comes from a URL.
pub trait Locate: Send + Sync {
    fn locate(&self, id: &str) -> Result<Located, LocateError>;
}
