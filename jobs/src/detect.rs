//! The one place that maps a job's [`FoldSpec`] to a fold detector. Adding a detector (video, stretch) is one
//! match arm here: the planner and the fold-detection tasks only see `dyn FoldDetector` and its
//! [`Granularity`].

use crate::error::JobError;
use crate::plan::chunk_ranges;
use crate::spec::FoldSpec;
use crease_core::folds::{FoldDetector, Granularity};
use std::ops::Range;

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

/// The frame ranges of a detector's tasks over `n` frames, in order: chunks of `per_chunk` frames for per-frame
/// detectors, the whole sequence for detectors that carry state through time.
pub fn detection_chunks(d: &dyn FoldDetector, n: usize, per_chunk: usize) -> Vec<Range<usize>> {
    match d.granularity() {
        Granularity::WholeSequence => std::iter::once(0..n).collect(),
        Granularity::PerFrame => chunk_ranges(n, per_chunk),
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

#[cfg(test)]
mod tests {
    //! The generic fold-detection path: detection tasks (per frame chunk or whole sequence), the merge that
    //! expands the graph, then the deformation on the detected anchors, all run in process.
    use super::test_detector::GeometryDetector;
    use crate::spec::JobSpec;
    use crate::task::TaskSpec;
    use crate::{execute, expand, inspect_input, keys, plan, ExecContext};
    use crease_core::folds::{AnchorSet, FoldDetector};
    use crease_core::mesh::io::{create_sink, open_sequence, write_obj_sequence};
    use crease_core::progress::NoProgress;
    use crease_core::spacetime::deform;
    use crease_core::synth::{demo, DemoSpec};
    use std::collections::HashSet;
    use std::path::Path;
    use std::sync::Arc;

    async fn detect_and_deform(root: &Path, whole_sequence: bool) {
        let (seq, _) = demo(&DemoSpec {
            triangles: 700,
            frames: 10,
            ..Default::default()
        })
        .unwrap();
        let input = root.join("input");
        std::fs::create_dir_all(&input).unwrap();
        write_obj_sequence(
            &input,
            &seq.topology,
            seq.frames
                .iter()
                .enumerate()
                .map(|(t, f)| (format!("f{t:03}.obj"), f.as_slice())),
        )
        .unwrap();
        let out = root.join("out");
        let spec = JobSpec::from_toml_str(&format!(
            "input = {:?}\noutput = {:?}\n[folds]\nkind = \"test-detector\"\nwhole_sequence = {whole_sequence}\n\
             [deform]\nmode = \"per-anchor\"\nwindow = 5\nshift = 3\n[partition]\nanchor_block = 20\n\
             fold_frames_per_chunk = 3\nframes_per_chunk = 3\n",
            input.display().to_string(),
            out.display().to_string()
        ))
        .unwrap();
        let info = inspect_input(&spec).await.unwrap();
        assert_eq!(info.anchors_per_frame, None, "anchors unknown at submit");
        let mut tasks = plan(&spec, &info).unwrap();
        let detect_tasks = tasks
            .iter()
            .filter(|t| matches!(t.spec, TaskSpec::FoldDetect { .. }))
            .count();
        assert_eq!(detect_tasks, if whole_sequence { 1 } else { 4 });
        assert_eq!(tasks.len(), detect_tasks + 1, "detection and merge only");
        assert!(tasks.last().unwrap().expands);
        let ctx = ExecContext {
            progress: Arc::new(NoProgress),
            cache_dir: root.join("cache"),
        };
        let mut done = HashSet::new();
        while let Some(i) = (0..tasks.len()).find(|&i| {
            !done.contains(&tasks[i].key) && tasks[i].deps.iter().all(|d| done.contains(d))
        }) {
            let t = tasks[i].clone();
            let output = execute(&t.spec, &ctx)
                .await
                .unwrap_or_else(|e| panic!("{}: {e}", t.key));
            done.insert(t.key.clone());
            if t.expands {
                tasks.extend(expand(&spec, &info, &t.key, &output).unwrap());
            }
        }
        assert_eq!(done.len(), tasks.len());
        assert!(tasks
            .iter()
            .any(|t| matches!(t.spec, TaskSpec::WeightBlock { .. })));
        // The merged anchors are what the detector finds on the whole sequence at once.
        let opened = open_sequence(&input).unwrap();
        let direct = GeometryDetector { whole_sequence }
            .detect(opened.source.as_ref(), 0..10, &NoProgress)
            .unwrap();
        let direct =
            AnchorSet::from_frame_anchors(direct, seq.topology.n_triangles(), None).unwrap();
        assert!(direct.total() > 20);
        let written = std::fs::read_to_string(out.join(keys::ANCHORS)).unwrap();
        assert_eq!(written, direct.to_json());
        // And the output is deform() on those anchors.
        let anchors =
            AnchorSet::read(&out.join(keys::ANCHORS), 10, seq.topology.n_triangles()).unwrap();
        let reference = root.join("reference");
        let mut sink = create_sink(&opened.layout, &reference).unwrap();
        deform(
            opened.source.as_ref(),
            &anchors,
            &spec.params(),
            sink.as_mut(),
            &NoProgress,
            &[],
        )
        .unwrap();
        sink.finish().unwrap();
        for t in 0..10 {
            let name = format!("f{t:03}.obj");
            assert!(
                std::fs::read(out.join(&name)).unwrap()
                    == std::fs::read(reference.join(&name)).unwrap(),
                "{name} differs"
            );
        }
        for key in crate::final_outputs(&spec, &info) {
            assert!(out.join(&key).is_file(), "{key}");
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn per_frame_detection_in_chunks_then_deformation() {
        detect_and_deform(tempfile::tempdir().unwrap().path(), false).await;
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn whole_sequence_detection_then_deformation() {
        detect_and_deform(tempfile::tempdir().unwrap().path(), true).await;
    }
}
