//! Plain OBJ frames for an output whose topology differs from the input's (a subdivided sequence): the input
//! layout's own sink rewrites the input's files and cannot hold the new faces.

use super::obj::write_obj;
use crate::error::{Error, Result};
use crate::mesh::{FrameSink, Topology};
use crate::vec3::V3;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Writes each frame as a complete OBJ file (vertices and faces) named after the input frame files
/// (`<stem>.obj`), or `frame_NNNN.obj` when the input is not one file per frame (a point cache).
pub struct ObjFramesSink {
    dir: PathBuf,
    names: Vec<String>,
    topology: Arc<Topology>,
    written: Vec<PathBuf>,
}

impl ObjFramesSink {
    /// The output file names for an input made of `input_files` with `n_frames` frames. Also what a job
    /// planner lists as the output files before anything is written, so both come from here.
    pub fn frame_names(input_files: &[PathBuf], n_frames: usize) -> Vec<String> {
        let width = n_frames.to_string().len().max(4);
        if input_files.len() == n_frames {
            input_files
                .iter()
                .map(|p| {
                    let stem = p.file_stem().map(|s| s.to_string_lossy().into_owned());
                    format!("{}.obj", stem.unwrap_or_default())
                })
                .collect()
        } else {
            (0..n_frames)
                .map(|t| format!("frame_{:0width$}.obj", t + 1))
                .collect()
        }
    }

    pub fn new(
        dir: &Path,
        input_files: &[PathBuf],
        n_frames: usize,
        topology: Arc<Topology>,
    ) -> Result<Self> {
        crate::fsutil::create_dir_all(dir)?;
        Ok(ObjFramesSink {
            dir: dir.to_path_buf(),
            names: Self::frame_names(input_files, n_frames),
            topology,
            written: Vec::new(),
        })
    }
}

impl FrameSink for ObjFramesSink {
    fn write_frame(&mut self, t: usize, positions: &[V3]) -> Result<()> {
        let name = self
            .names
            .get(t)
            .ok_or_else(|| Error::param("frame", format!("output frame {t} is out of range")))?;
        let path = self.dir.join(name);
        write_obj(&path, &self.topology, positions)?;
        self.written.push(path);
        Ok(())
    }
    fn finish(&mut self) -> Result<Vec<PathBuf>> {
        self.written.sort();
        Ok(self.written.clone())
    }
}
