//! Triangle-mesh sequences with shared connectivity: topology, per-frame geometry, sources and sinks.

pub mod geometry;
pub mod io;
pub mod seams;
pub mod subdivide;
mod topology;
pub mod uv;

pub use topology::{Topology, NONE};
pub use uv::UvSet;

use crate::error::Result;
use crate::vec3::V3;
use std::path::PathBuf;
use std::sync::Arc;

/// Positions of one frame, indexed like the topology's vertices.
pub type Frame = Vec<V3>;

/// A sequence whose frames are read on demand, so that memory is bounded by the working window and not by the
/// sequence length. Implementations validate every frame they return (vertex count, finite values, degenerate
/// triangles) and name the file and frame in their errors.
pub trait FrameSource: Send + Sync {
    fn topology(&self) -> &Arc<Topology>;
    fn n_frames(&self) -> usize;
    /// Reads and validates frame `t` (0-based position in the sequence).
    fn read_frame(&self, t: usize) -> Result<Frame>;
    /// Human-readable origin of frame `t` (a file path, or `file.pc2 sample 12`), for messages and reports.
    fn describe_frame(&self, t: usize) -> String;
    /// The coarser source this one subdivides and how, for work that belongs on the input mesh (fold tracing,
    /// Chen 2011 §4.4) while its result is realised on the subdivided one. `None` for an unsubdivided source.
    fn subdivided_from(&self) -> Option<(&dyn FrameSource, &subdivide::Subdivision)> {
        None
    }
}

/// Receives output frames. Frames may arrive in any order; nothing is presented as complete before
/// [`FrameSink::finish`] succeeds.
pub trait FrameSink: Send {
    fn write_frame(&mut self, t: usize, positions: &[V3]) -> Result<()>;
    /// Completes the output (e.g. closes a point cache) and returns the files written.
    fn finish(&mut self) -> Result<Vec<PathBuf>>;
}

/// A fully loaded sequence: shared topology plus all frames. Used for synthetic data, tests and small inputs.
#[derive(Debug, Clone)]
pub struct Sequence {
    pub topology: Arc<Topology>,
    pub frames: Vec<Frame>,
}

impl Sequence {
    /// Builds a sequence and validates every frame against the topology.
    pub fn new(topology: Arc<Topology>, frames: Vec<Frame>) -> Result<Self> {
        for (t, f) in frames.iter().enumerate() {
            geometry::validate_frame(&topology, f).map_err(|e| e.at(None, Some(t)))?;
        }
        Ok(Sequence { topology, frames })
    }

    /// Reads every frame of a source into memory.
    pub fn load(source: &dyn FrameSource) -> Result<Self> {
        let frames = (0..source.n_frames())
            .map(|t| source.read_frame(t))
            .collect::<Result<Vec<_>>>()?;
        Ok(Sequence {
            topology: source.topology().clone(),
            frames,
        })
    }
}

impl FrameSource for Sequence {
    fn topology(&self) -> &Arc<Topology> {
        &self.topology
    }
    fn n_frames(&self) -> usize {
        self.frames.len()
    }
    fn read_frame(&self, t: usize) -> Result<Frame> {
        Ok(self.frames[t].clone())
    }
    fn describe_frame(&self, t: usize) -> String {
        format!("in-memory frame {t}")
    }
}

/// Collects output frames in memory (tests, benchmarks).
#[derive(Debug, Default)]
pub struct MemorySink {
    pub frames: std::collections::BTreeMap<usize, Frame>,
}

impl FrameSink for MemorySink {
    fn write_frame(&mut self, t: usize, positions: &[V3]) -> Result<()> {
        self.frames.insert(t, positions.to_vec());
        Ok(())
    }
    fn finish(&mut self) -> Result<Vec<PathBuf>> {
        Ok(Vec::new())
    }
}
