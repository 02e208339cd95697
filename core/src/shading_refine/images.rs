//! The refinement as a step of the positioning: each finished frame refined from its own images, read when the
//! frame is (so a task holds one frame's images at a time, and any machine that positions a frame refines it
//! the same way).

use super::{refine_frame_traced, RefineView, ShadingRefineParams};
use crate::error::{Error, Result};
use crate::folds::video::cameras::CameraRig;
use crate::mesh::Topology;
use crate::spacetime::shape::lost_area::Trace;
use crate::spacetime::stages::FrameRefiner;
use crate::vec3::V3;

/// Refines frame `t` from the images of `rig` numbered `numbers[t]`.
pub struct ImageRefiner {
    pub rig: CameraRig,
    pub numbers: Vec<u64>,
    pub params: ShadingRefineParams,
}

impl FrameRefiner for ImageRefiner {
    fn refine(
        &self,
        topo: &Topology,
        t: usize,
        positions: &[V3],
        trace: Option<&Trace>,
    ) -> Result<Vec<V3>> {
        let number = *self.numbers.get(t).ok_or_else(|| {
            Error::param(
                "image_numbers",
                format!(
                    "no image number for frame {t} (the rig has {})",
                    self.numbers.len()
                ),
            )
        })?;
        let photos = (0..self.rig.cameras.len())
            .map(|c| self.rig.load(c, t, number))
            .collect::<Result<Vec<_>>>()?;
        let views = self
            .rig
            .cameras
            .iter()
            .zip(&photos)
            .map(|(c, photo)| RefineView {
                camera: &c.camera,
                photo,
            })
            .collect();
        Ok(refine_frame_traced(topo, positions, views, &self.params, trace)?.positions)
    }
}
