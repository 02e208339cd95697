//! Fold estimates and their hand-off to the deformation: anchors (triangle, axis, angle) per frame.
//!
//! Every way of finding folds (an anchors file, the capture video of Popa et al. 2009 §4, the geometry alone
//! after Chen 2011 ch. 4) ends in the same [`AnchorSet`]; the [`FoldDetector`] trait is the seam that lets the
//! single-machine driver and the cluster planner run any of them without knowing which one it is.

pub mod anchors;
pub mod fuse;
pub mod stretch;
pub mod temporal;
pub mod video;

pub use anchors::{Anchor, AnchorSet, FrameAnchors, FrameDetection};

use crate::mesh::FrameSource;
use crate::progress::Progress;
use crate::Result;
use std::ops::Range;

/// How a detector's work may be split across tasks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Granularity {
    /// Each frame is detected on its own (video edges): any frame range is a valid task.
    PerFrame,
    /// Detection carries state through time (phases, seed memory): the whole sequence is one task.
    WholeSequence,
}

/// Turns a captured sequence into anchors for the space-time deformation.
pub trait FoldDetector: Sync {
    /// Short name used in logs and reports (`video`, `stretch`).
    fn name(&self) -> &'static str;

    /// Whether frame ranges may be detected independently.
    fn granularity(&self) -> Granularity;

    /// Detects the anchors (and control lines) of `frames` of `source`. Returns one entry per frame of the range,
    /// in order, with `FrameAnchors::frame` set to the absolute frame index. For
    /// [`Granularity::WholeSequence`] the range is always the whole sequence.
    fn detect(
        &self,
        source: &dyn FrameSource,
        frames: Range<usize>,
        progress: &dyn Progress,
    ) -> Result<Vec<FrameAnchors>>;

    /// [`FoldDetector::detect`], plus the inspection files the detector draws for frames of the range
    /// (overlays). The detector has the per-frame data they need only while detecting, so they are made here
    /// rather than recomputed afterwards. Default: no files.
    fn detect_with_artifacts(
        &self,
        source: &dyn FrameSource,
        frames: Range<usize>,
        progress: &dyn Progress,
    ) -> Result<(Vec<FrameAnchors>, Vec<Artifact>)> {
        Ok((self.detect(source, frames, progress)?, Vec::new()))
    }

    /// Whole-sequence finishing of the anchors of all frames (`frames`: one entry per frame, in order), run
    /// once after every detection chunk is in: temporal coherence for detectors that find each frame on its
    /// own ([`temporal::settle`]). Default: unchanged.
    fn settle(
        &self,
        source: &dyn FrameSource,
        frames: Vec<FrameAnchors>,
    ) -> Result<Vec<FrameAnchors>> {
        let _ = source;
        Ok(frames)
    }

    /// What the report says about this detection beyond the anchors (parameters, choices made automatically).
    fn summary(&self, source: &dyn FrameSource) -> Result<serde_json::Value> {
        let _ = source;
        Ok(serde_json::Value::Null)
    }
}

/// A file a detector produces for inspection, named by a `/`-separated key relative to the output directory
/// (`folds.png`, `overlays/frame_0001.png`). Bytes rather than a path, so that a job task can put it into any
/// output storage; keys are deterministic, so a task run twice writes the same object.
#[derive(Debug, Clone, PartialEq)]
pub struct Artifact {
    pub key: String,
    pub bytes: Vec<u8>,
}
