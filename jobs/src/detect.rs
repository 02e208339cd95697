//! The one place that maps a job's [`FoldSpec`] to a fold detector. Adding a detector (video, stretch) is one
//! match arm here: the planner and the fold-detection tasks only see `dyn FoldDetector` and its
//! [`Granularity`](crease_core::folds::Granularity).

use crate::error::JobError;
use crate::spec::FoldSpec;
use crease_core::folds::FoldDetector;

/// The detector of `spec`, or `None` when the anchors are known without detection (anchors file, no folds).
pub fn detector(spec: &FoldSpec) -> Result<Option<Box<dyn FoldDetector>>, JobError> {
    match spec {
        FoldSpec::None | FoldSpec::Anchors { .. } => Ok(None),
        #[cfg(test)]
        FoldSpec::TestDetector { whole_sequence } => {
            Ok(Some(Box::new(test_detector::GeometryDetector {
                whole_sequence: *whole_sequence,
            })))
        }
    }
}

#[cfg(test)]
pub(crate) mod test_detector {
    //! A deterministic stand-in detector for the planner tests: anchors on every 7th triangle whose centroid is
    //! above the frame's mean height, angle growing with the height, so the anchors depend on each frame's
    //! geometry as a real detector's would.
    use crease_core::folds::{Anchor, FoldDetector, FrameAnchors, Granularity};
    use crease_core::mesh::FrameSource;
    use crease_core::progress::Progress;
    use std::ops::Range;

    pub struct GeometryDetector {
        pub whole_sequence: bool,
    }

    impl FoldDetector for GeometryDetector {
        fn name(&self) -> &'static str {
            "test-detector"
        }
        fn granularity(&self) -> Granularity {
            if self.whole_sequence {
                Granularity::WholeSequence
            } else {
                Granularity::PerFrame
            }
        }
        fn detect(
            &self,
            source: &dyn FrameSource,
            frames: Range<usize>,
            _progress: &dyn Progress,
        ) -> crease_core::Result<Vec<FrameAnchors>> {
            let topo = source.topology().clone();
            frames
                .map(|t| {
                    let f = source.read_frame(t)?;
                    let mean_y = f.iter().map(|p| p[1]).sum::<f64>() / f.len() as f64;
                    let anchors = topo
                        .triangles()
                        .iter()
                        .enumerate()
                        .filter_map(|(i, tri)| {
                            let y = tri.iter().map(|&v| f[v as usize][1]).sum::<f64>() / 3.0;
                            (i % 7 == t % 7 && y > mean_y).then_some(Anchor {
                                triangle: i as u32,
                                axis: [1.0, 0.0, 0.0],
                                angle: 0.3 + 0.1 * (y - mean_y).min(1.0),
                            })
                        })
                        .collect();
                    Ok(FrameAnchors {
                        frame: t,
                        anchors,
                        control_lines: vec![],
                    })
                })
                .collect()
        }
    }
}
