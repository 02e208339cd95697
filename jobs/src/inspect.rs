//! Submit-time inspection: is the input reachable and sane, do the anchors fit it, can the output be written?
//! The coordinator calls [`inspect_input`] before accepting a job, so a bad spec or an unreachable input is
//! rejected at submit with a message naming the field, URI or file, rather than failing tasks later.

use crate::error::JobError;
use crate::keys;
use crate::spec::{FoldSpec, JobSpec};
use crate::storage::{fetch_input_to_cache, parse_location, Location, Storage};
use crease_core::folds::AnchorSet;
use crease_core::mesh::io::{open_sequence, SequenceLayout};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

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

/// Checks the job spec, opens the input and validates frame 0, parses the anchors file against the input, and
/// checks that the output location is writable and is not the input directory.
pub async fn inspect_input(spec: &JobSpec) -> Result<InputInfo, JobError> {
    spec.validate()?;
    let cache = std::env::temp_dir().join("crease-cache");
    let input = fetch_input_to_cache(&spec.input, &cache).await?;
    let anchors = match &spec.folds {
        FoldSpec::Anchors { uri } => Some((uri.clone(), fetch_input_to_cache(uri, &cache).await?)),
        _ => None,
    };
    let spec2 = spec.clone();
    let info = tokio::task::spawn_blocking(move || inspect_local(&spec2, &input, anchors))
        .await
        .map_err(|e| JobError::input(&spec.input, format!("inspection panicked: {e}")))??;
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
    let topo = source.topology();
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
        output_files: output_files(&opened.layout),
        anchors_per_frame,
    })
}

/// Names of the output sequence's files: the input's frame files, or its OBJ + PC2.
pub(crate) fn output_files(layout: &SequenceLayout) -> Vec<String> {
    layout
        .input_files()
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect()
}
