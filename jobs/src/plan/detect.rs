//! The one place that maps a job's [`FoldSpec`] to a fold detector. Adding a detector is one match arm in
//! [`detector`] (and one in [`granularity`]): the planner and the fold-detection tasks only see
//! `dyn FoldDetector` and its [`Granularity`].

use crate::error::JobError;
use crate::plan::chunks::chunk_ranges;
use crate::spec::{FoldSpec, JobSpec};
use crate::storage::store::fetch_input_to_cache;
use crease_core::folds::stretch::StretchDetector;
use crease_core::folds::video::{CameraRig, VideoFolds};
use crease_core::folds::{FoldDetector, Granularity};
use crease_core::mesh::io::SequenceLayout;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Local copies of the files a detector reads besides the input sequence (remote URIs fetched to the cache).
#[derive(Debug, Clone, Default)]
pub struct FoldInputs {
    /// The video detector's cameras file.
    pub cameras: Option<PathBuf>,
    /// The video detector's image directory, when the spec names one.
    pub images: Option<PathBuf>,
}

/// Fetches the detector's own input files of `spec` (see [`FoldInputs`]).
pub async fn fetch_fold_inputs(spec: &FoldSpec, cache: &Path) -> Result<FoldInputs, JobError> {
    match spec {
        FoldSpec::Video {
            cameras, images, ..
        } => Ok(FoldInputs {
            cameras: Some(fetch_input_to_cache(cameras, cache).await?),
            images: match images {
                Some(uri) => Some(fetch_input_to_cache(uri, cache).await?),
                None => None,
            },
        }),
        _ => Ok(FoldInputs::default()),
    }
}

/// How the folds of `spec` are detected, or `None` when the anchors are known without detection. The planner
/// needs only this, so it reads no camera files; it matches what [`detector`] builds.
pub fn granularity(spec: &FoldSpec) -> Option<Granularity> {
    match spec {
        FoldSpec::None | FoldSpec::Anchors { .. } => None,
        FoldSpec::Stretch { .. } => Some(Granularity::WholeSequence),
        FoldSpec::Video { .. } => Some(Granularity::PerFrame),
        #[cfg(test)]
        FoldSpec::TestDetector { whole_sequence } => Some(if *whole_sequence {
            Granularity::WholeSequence
        } else {
            Granularity::PerFrame
        }),
    }
}

/// The detector of `job` for an input laid out as `layout` with `n_frames` frames, or `None` when the anchors
/// are known without detection (anchors file, no folds). Errors name the spec field or file at fault.
pub fn detector(
    job: &JobSpec,
    layout: &SequenceLayout,
    n_frames: usize,
    inputs: &FoldInputs,
) -> Result<Option<Box<dyn FoldDetector>>, JobError> {
    let d: Box<dyn FoldDetector> = match &job.folds {
        FoldSpec::None | FoldSpec::Anchors { .. } => return Ok(None),
        FoldSpec::Stretch { .. } => Box::new(stretch_detector(job, n_frames).expect("stretch")),
        FoldSpec::Video {
            cameras,
            params,
            front_vertex,
            back_vertex,
            first_image_number,
            overlay_frames,
            ..
        } => {
            let path = inputs.cameras.as_deref().ok_or_else(|| {
                JobError::input(cameras, "the cameras file was not fetched before detection")
            })?;
            let rig = CameraRig::read(path, inputs.images.as_deref())
                .map_err(|e| JobError::input(cameras, e))?;
            let numbers = image_numbers(layout, n_frames, *first_image_number);
            let mut det = VideoFolds::new(rig, params.clone(), numbers).map_err(|e| match e {
                crease_core::Error::Param { name, msg } => {
                    JobError::spec(format!("folds.params.{name}"), msg)
                }
                e => JobError::spec("folds.params", e.to_string()),
            })?;
            det.vertices = match (front_vertex, back_vertex) {
                (Some(f), Some(b)) => Some((*f as usize, *b as usize)),
                _ => None,
            };
            det.overlay_frames = overlay_frames.clone();
            Box::new(det)
        }
        #[cfg(test)]
        FoldSpec::TestDetector { whole_sequence } => Box::new(test_detector::GeometryDetector {
            whole_sequence: *whole_sequence,
        }),
    };
    debug_assert_eq!(Some(d.granularity()), granularity(&job.folds));
    Ok(Some(d))
}

/// The stretch detector of `job` (`None` for other fold kinds).
pub fn stretch_detector(job: &JobSpec, n_frames: usize) -> Option<StretchDetector> {
    match &job.folds {
        FoldSpec::Stretch { params, .. } => Some(StretchDetector {
            params: params.clone(),
            // folds.png shows the frames preview.png shows, as `crease run` always drew them.
            overlay_frames: preview_frames(job, n_frames),
            overlay_size: job.preview.size,
        }),
        _ => None,
    }
}

/// The frames `preview.png` shows: the job's, or four spread over the sequence.
pub fn preview_frames(job: &JobSpec, n: usize) -> Vec<usize> {
    if job.preview.frames.is_empty() {
        let mut k: Vec<usize> = (1..=4)
            .map(|i| (i * n / 5).min(n.saturating_sub(1)))
            .collect();
        k.dedup();
        k
    } else {
        job.preview.frames.clone()
    }
}

/// Image number of every sequence frame: `first` onwards when given, else each frame file's own number (1
/// onwards for a point cache).
pub fn image_numbers(layout: &SequenceLayout, n: usize, first: Option<u64>) -> Vec<u64> {
    match (first, layout) {
        (Some(f), _) => (0..n as u64).map(|t| f + t).collect(),
        (
            None,
            SequenceLayout::ObjFrames { frames, .. } | SequenceLayout::PlyFrames { frames, .. },
        ) => frames.iter().map(|f| f.number).collect(),
        (None, _) => (1..=n as u64).collect(),
    }
}

/// The frame ranges of a detector's tasks over `n` frames, in order: chunks of `per_chunk` frames for per-frame
/// detectors, the whole sequence for detectors that carry state through time.
pub fn detection_chunks(g: Granularity, n: usize, per_chunk: usize) -> Vec<Range<usize>> {
    match g {
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
                        ..Default::default()
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
    use crate::plan::graph::{expand, plan};
    use crate::plan::inspect::inspect_input;
    use crate::plan::task::TaskSpec;
    use crate::spec::JobSpec;
    use crate::storage::keys;
    use crate::{execute, ExecContext};
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
        let relief_tasks = tasks
            .iter()
            .filter(|t| matches!(t.spec, TaskSpec::Relief { .. }))
            .count();
        assert_eq!(
            relief_tasks, 4,
            "the relief of every frame chunk, from the input alone"
        );
        assert_eq!(
            tasks.len(),
            detect_tasks + relief_tasks + 1,
            "detection, relief and merge only"
        );
        let merge = tasks
            .iter()
            .find(|t| t.key == keys::FOLD_MERGE_TASK)
            .unwrap();
        assert!(merge.expands);
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
        for key in crate::plan::graph::final_outputs(&spec, &info) {
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
