//! Submit-time inspection: is the input reachable and sane, do the anchors fit it, can the output be written?
//! The coordinator calls [`inspect_input`] before accepting a job, so a bad spec or an unreachable input is
//! rejected at submit with a message naming the field, URI or file, rather than failing tasks later.

use super::input::InputInfo;
use crate::error::JobError;
use crate::spec::{FoldSpec, JobSpec};
use crate::storage::keys;
use crate::storage::location::{parse_location, Location};
use crate::storage::store::{fetch_input_to_cache, Storage};
use crease_core::folds::AnchorSet;
use crease_core::mesh::io::{create_sink, open_sequence, ObjFramesSink, SequenceLayout};
use crease_core::mesh::subdivide::Subdivision;
use crease_core::mesh::{FrameSink, Topology};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Checks the job spec, opens the input and validates frame 0, parses the anchors file against the input, and
/// checks that the output location is writable and is not the input directory.
pub async fn inspect_input(spec: &JobSpec) -> Result<InputInfo, JobError> {
    spec.validate()?;
    let cache = std::env::temp_dir().join("crease-cache");
    let info = match &spec.deep {
        Some(deep) => crate::deep::inspect::inspect(spec, deep, &cache).await?,
        None => inspect_deformation(spec, &cache).await?,
    };
    // Output: usable, and not the input directory (the output files have the input's names).
    let storage =
        Storage::open(&spec.output).map_err(|e| JobError::spec("output", e.to_string()))?;
    if let (Some(out), Location::Local(inp)) =
        (storage.local_path(), parse_location(&spec.input, "input")?)
    {
        let in_dir = if inp.is_dir() {
            inp.clone()
        } else {
            inp.parent().map(Path::to_path_buf).unwrap_or_default()
        };
        if same_dir(out, &in_dir) {
            return Err(JobError::spec(
                "output",
                format!("{} holds the input sequence; writing there would overwrite the input files, choose another location", spec.output),
            ));
        }
    }
    let probe = format!("{}/probe", keys::WORK_DIR);
    storage
        .put(&probe, bytes::Bytes::from_static(b"crease"))
        .await
        .map_err(|e| JobError::spec("output", format!("not writable: {e}")))?;
    storage.delete(&probe).await?;
    Ok(info)
}

/// The input of a deformation job: the sequence, the anchors file, the detector's inputs.
async fn inspect_deformation(spec: &JobSpec, cache: &Path) -> Result<InputInfo, JobError> {
    let input = fetch_input_to_cache(&spec.input, cache).await?;
    let anchors = match &spec.folds {
        FoldSpec::Anchors { uri } => Some((uri.clone(), fetch_input_to_cache(uri, cache).await?)),
        _ => None,
    };
    let fold_inputs = crate::plan::detect::fetch_fold_inputs(&spec.folds, cache).await?;
    let spec2 = spec.clone();
    tokio::task::spawn_blocking(move || inspect_local(&spec2, &input, anchors, &fold_inputs))
        .await
        .map_err(|e| JobError::input(&spec.input, format!("inspection panicked: {e}")))?
}

fn same_dir(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

fn inspect_local(
    spec: &JobSpec,
    input: &Path,
    anchors: Option<(String, PathBuf)>,
    fold_inputs: &crate::plan::detect::FoldInputs,
) -> Result<InputInfo, JobError> {
    let opened = open_sequence(input).map_err(|e| JobError::input(&spec.input, e))?;
    let source = opened.source.as_ref();
    let n = source.n_frames();
    if n == 0 {
        return Err(JobError::input(&spec.input, "the sequence has no frames"));
    }
    source
        .read_frame(0)
        .map_err(|e| JobError::input(&spec.input, e))?;
    // Sizes as the tasks see the input: subdivided when the job subdivides it.
    let topo = match spec.folds.subdivide() {
        0 => source.topology().clone(),
        levels => Subdivision::new(source.topology(), levels)
            .map_err(|e| JobError::spec("folds.subdivide", e.to_string()))?
            .topology()
            .clone(),
    };
    check_detector_inputs(spec, &opened, fold_inputs)?;
    let anchors_per_frame = match (&spec.folds, anchors) {
        (FoldSpec::None, _) => Some(vec![0; n]),
        (FoldSpec::Anchors { .. }, Some((uri, path))) => {
            let set = AnchorSet::read(&path, n, topo.n_triangles())
                .map_err(|e| JobError::input(&uri, e))?;
            Some((0..n).map(|t| set.frame(t).len()).collect())
        }
        _ => None,
    };
    if let Some(frames) = &spec.preview.frames.iter().find(|&&f| f >= n) {
        return Err(JobError::spec(
            "preview.frames",
            format!("frame {frames} is out of range (the sequence has {n} frames, 0-based)"),
        ));
    }
    Ok(InputInfo {
        layout: opened.layout.kind().to_string(),
        n_frames: n,
        n_vertices: topo.n_vertices(),
        n_triangles: topo.n_triangles(),
        output_files: output_files(spec, &opened.layout, n),
        anchors_per_frame,
    })
}

/// The detector's own inputs: for video, the cameras file parses and validates, every camera has a readable
/// image of the stated size for every frame (PNG headers only), and given tracked vertices exist. Errors name
/// the field, URI, camera, frame and file.
fn check_detector_inputs(
    spec: &JobSpec,
    opened: &crease_core::mesh::io::OpenedSequence,
    fold_inputs: &crate::plan::detect::FoldInputs,
) -> Result<(), JobError> {
    let FoldSpec::Video {
        cameras,
        images,
        front_vertex,
        back_vertex,
        overlay_frames,
        ..
    } = &spec.folds
    else {
        return Ok(());
    };
    let n = opened.source.n_frames();
    if let Some(images) = images {
        match &fold_inputs.images {
            Some(dir) if dir.is_dir() => {}
            _ => {
                return Err(JobError::input(
                    images,
                    "folds.images: not a readable directory",
                ))
            }
        }
    }
    let nv = opened.source.topology().n_vertices();
    for (field, v) in [
        ("folds.front_vertex", front_vertex),
        ("folds.back_vertex", back_vertex),
    ] {
        if let Some(v) = v {
            if *v as usize >= nv {
                return Err(JobError::spec(
                    field,
                    format!("vertex {v} is out of range (the mesh has {nv} vertices)"),
                ));
            }
        }
    }
    if let Some(f) = overlay_frames.iter().find(|&&f| f >= n) {
        return Err(JobError::spec(
            "folds.overlay_frames",
            format!("frame {f} is out of range (the sequence has {n} frames, 0-based)"),
        ));
    }
    // The images of every frame, checked here so a missing one fails the submit, not a task hours later.
    let path = fold_inputs.cameras.as_deref().unwrap_or(Path::new(cameras));
    let rig = crease_core::folds::video::CameraRig::read(path, fold_inputs.images.as_deref())
        .map_err(|e| JobError::input(cameras, e))?;
    let numbers = crate::plan::detect::image_numbers(&opened.layout, n, first_image_number(spec));
    let frames: Vec<(usize, u64)> = numbers.into_iter().enumerate().collect();
    rig.check_images(&frames)
        .map_err(|e| JobError::input(images.as_deref().unwrap_or(cameras), e))
}

fn first_image_number(spec: &JobSpec) -> Option<u64> {
    match &spec.folds {
        FoldSpec::Video {
            first_image_number, ..
        } => *first_image_number,
        _ => None,
    }
}

/// Names of the output sequence's files: the input's frame files, or its OBJ + PC2; plain OBJ frames (see
/// [`output_sink`]) when the job subdivides the input.
pub(crate) fn output_files(job: &JobSpec, layout: &SequenceLayout, n_frames: usize) -> Vec<String> {
    if job.folds.subdivide() > 0 {
        return ObjFramesSink::frame_names(&layout.input_files(), n_frames);
    }
    layout
        .input_files()
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect()
}

/// Whether the output is one file per frame, written by the positioning tasks as they go; otherwise (a point
/// cache, one file for all frames) finalize writes it from the stored positions.
pub(crate) fn writes_frames(job: &JobSpec, layout: &SequenceLayout) -> bool {
    job.folds.subdivide() > 0
        || matches!(
            layout,
            SequenceLayout::ObjFrames { .. } | SequenceLayout::PlyFrames { .. }
        )
}

/// The sink of the output sequence in `dir`: the input layout's own writer (same names and format as the
/// input), or plain OBJ frames when the job subdivides the input, since the input's files cannot hold the new
/// faces. The one place tasks get an output sink from.
pub(crate) fn output_sink(
    job: &JobSpec,
    layout: &SequenceLayout,
    topology: &Arc<Topology>,
    n_frames: usize,
    dir: &Path,
) -> crease_core::Result<Box<dyn FrameSink>> {
    if job.folds.subdivide() > 0 {
        Ok(Box::new(ObjFramesSink::new(
            dir,
            &layout.input_files(),
            n_frames,
            topology.clone(),
        )?))
    } else {
        create_sink(layout, dir)
    }
}
