//! What the planner knows of a job's input, as submit-time inspection found it.

use serde::{Deserialize, Serialize};

/// What submit-time inspection learned about a job's input; stored with the job and passed to the planner.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputInfo {
    /// `obj-frames`, `ply-frames` or `obj+pc2`.
    pub layout: String,
    pub n_frames: usize,
    pub n_vertices: usize,
    pub n_triangles: usize,
    /// Keys (relative to the output) of the output sequence's files, in the input's layout and names.
    pub output_files: Vec<String>,
    /// Anchors per frame when known at submit (anchors file, or none); `None` when folds are detected.
    pub anchors_per_frame: Option<Vec<usize>>,
}
