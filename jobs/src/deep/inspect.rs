//! Submit-time inspection of a deep job: the training data loads and agrees with itself (frame counts,
//! topology, poses without NaNs), or the model is complete and of this version and the input fits it, so a bad
//! input is refused at submit with the file, frame or field named, not by a task later.
//!
//! That takes the learning library (the `deep` feature). A coordinator built without it still plans deep
//! jobs: it reads only what the planner needs (frame counts, the model's mesh size from its manifest) with
//! crease-core, and the worker that runs the job's first task, which has the library, checks the rest.

use super::keys;
use super::spec::Regressor;
use super::spec::{ApplyFrom, DeepSpec};
use crate::error::JobError;
use crate::plan::input::InputInfo;
use crate::spec::JobSpec;
use crate::storage::store::fetch_input_to_cache;
use std::path::{Path, PathBuf};

/// The model files a training job with these parameters publishes, manifest last.
pub fn model_files(deep: &DeepSpec) -> Vec<String> {
    let DeepSpec::Train { params, .. } = deep else {
        return Vec::new();
    };
    let mut names = vec![
        "triangles.npy",
        "uv.npy",
        "uv_corners.npy",
        "mean.npy",
        "basis.npy",
        "singular_values.npy",
        "linear.npy",
        "template.obj",
        "autoregressive.npy",
        "ar_scale.npy",
        "ar_start.npy",
        "detail.npy",
    ];
    if params.regressor == Regressor::Lstm {
        names.push("lstm.safetensors");
    }
    if params.cgan_steps > 0 {
        names.push("cgan.safetensors");
    }
    names.push("manifest.json");
    names.into_iter().map(keys::model_file).collect()
}

/// The input's URIs fetched into `cache` (local paths are used in place): `input` first, then `deep.data`.
pub async fn fetch_training_dirs(
    job: &JobSpec,
    deep: &DeepSpec,
    cache: &Path,
) -> Result<Vec<PathBuf>, JobError> {
    let mut dirs = vec![fetch_input_to_cache(&job.input, cache).await?];
    if let DeepSpec::Train { data, .. } = deep {
        for d in data {
            dirs.push(fetch_input_to_cache(d, cache).await?);
        }
    }
    Ok(dirs)
}

pub async fn inspect(job: &JobSpec, deep: &DeepSpec, cache: &Path) -> Result<InputInfo, JobError> {
    match deep {
        DeepSpec::Train { data, .. } => {
            let dirs = fetch_training_dirs(job, deep, cache).await?;
            let uris: Vec<String> = std::iter::once(job.input.clone())
                .chain(data.iter().cloned())
                .collect();
            let deep2 = deep.clone();
            tokio::task::spawn_blocking(move || inspect_training(&deep2, &dirs, &uris))
                .await
                .map_err(|e| JobError::input(&job.input, format!("inspection panicked: {e}")))?
        }
        DeepSpec::Apply {
            model,
            from,
            regressor,
            ..
        } => {
            let model_dir = fetch_input_to_cache(model, cache).await?;
            let input = fetch_input_to_cache(&job.input, cache).await?;
            let (job2, model_uri, from, regressor) =
                (job.clone(), model.clone(), *from, *regressor);
            tokio::task::spawn_blocking(move || {
                inspect_apply(&job2, &model_uri, &model_dir, from, regressor, &input)
            })
            .await
            .map_err(|e| JobError::input(&job.input, format!("inspection panicked: {e}")))?
        }
    }
}

#[cfg(feature = "deep")]
fn inspect_training(
    deep: &DeepSpec,
    dirs: &[PathBuf],
    uris: &[String],
) -> Result<InputInfo, JobError> {
    use crease_deep::train::{common_topology, load_training_dir};
    let mut seqs = Vec::with_capacity(dirs.len());
    for (d, uri) in dirs.iter().zip(uris) {
        seqs.push(load_training_dir(d).map_err(|e| JobError::input(uri, e))?);
    }
    let topo = common_topology(&seqs).map_err(|e| JobError::input(&uris[0], e))?;
    Ok(InputInfo {
        layout: deep.kind().to_string(),
        n_frames: seqs.iter().map(|s| s.fine.len()).sum(),
        n_vertices: topo.n_vertices(),
        n_triangles: topo.n_triangles(),
        output_files: model_files(deep),
        anchors_per_frame: None,
    })
}

#[cfg(feature = "deep")]
fn inspect_apply(
    job: &JobSpec,
    model_uri: &str,
    model_dir: &Path,
    from: ApplyFrom,
    regressor: Option<Regressor>,
    input: &Path,
) -> Result<InputInfo, JobError> {
    use crease_deep::apply::open_coarse;
    use crease_deep::model::Model;
    use crease_deep::regression::pose::read_pose_file;
    let model = Model::load(model_dir).map_err(|e| JobError::input(model_uri, e))?;
    let n = match from {
        ApplyFrom::Pose => {
            model
                .check_regressor(regressor.map_or(model.manifest.regressor, Into::into))
                .map_err(|e| JobError::input(model_uri, e))?;
            let poses = read_pose_file(input, None).map_err(|e| JobError::input(&job.input, e))?;
            let dim = model.manifest.control.pose_dim();
            if poses[0].len() != dim {
                return Err(JobError::input(
                    &job.input,
                    format!(
                        "pose vectors have {} numbers; the model was trained on {dim}",
                        poses[0].len()
                    ),
                ));
            }
            poses.len()
        }
        ApplyFrom::Coarse => open_coarse(&model, input)
            .map_err(|e| JobError::input(&job.input, e))?
            .n_frames(),
    };
    if n == 0 {
        return Err(JobError::input(&job.input, "the input has no frames"));
    }
    Ok(apply_info(
        n,
        model.topology.n_vertices(),
        model.topology.n_triangles(),
    ))
}

/// What the planner knows of an apply job over `n` frames of a model of that mesh size.
fn apply_info(n: usize, n_vertices: usize, n_triangles: usize) -> InputInfo {
    let mut output_files: Vec<String> = (0..n)
        .flat_map(|t| [keys::mesh(t), keys::normals(t)])
        .collect();
    output_files.push(keys::DONE.to_string());
    InputInfo {
        layout: "deep-apply".to_string(),
        n_frames: n,
        n_vertices,
        n_triangles,
        output_files,
        anchors_per_frame: None,
    }
}

/// Without the learning library: the frames and mesh size of the training data (every directory's `gt/`
/// sequence), as the library would count them.
#[cfg(not(feature = "deep"))]
fn inspect_training(
    deep: &DeepSpec,
    dirs: &[PathBuf],
    uris: &[String],
) -> Result<InputInfo, JobError> {
    let mut n_frames = 0;
    let mut mesh = None;
    for (d, uri) in dirs.iter().zip(uris) {
        let opened = crease_core::mesh::io::open_sequence(&d.join("gt"))
            .map_err(|e| JobError::input(uri, e))?;
        n_frames += opened.source.n_frames();
        let topo = opened.source.topology();
        mesh.get_or_insert((topo.n_vertices(), topo.n_triangles()));
    }
    let (n_vertices, n_triangles) = mesh.unwrap_or_default();
    Ok(InputInfo {
        layout: deep.kind().to_string(),
        n_frames,
        n_vertices,
        n_triangles,
        output_files: model_files(deep),
        anchors_per_frame: None,
    })
}

/// Without the learning library: the input's frame count (pose vectors, or coarse frames) and the model's
/// mesh size from its manifest.
#[cfg(not(feature = "deep"))]
fn inspect_apply(
    job: &JobSpec,
    model_uri: &str,
    model_dir: &Path,
    from: ApplyFrom,
    _regressor: Option<Regressor>,
    input: &Path,
) -> Result<InputInfo, JobError> {
    let manifest = read_json(&model_dir.join("manifest.json"), model_uri)?;
    let count = |field: &str| {
        manifest
            .get(field)
            .and_then(|v| v.as_u64())
            .ok_or_else(|| JobError::input(model_uri, format!("manifest.json: no `{field}` count")))
    };
    let (n_vertices, n_triangles) = (count("vertices")? as usize, count("triangles")? as usize);
    let n = match from {
        ApplyFrom::Pose => read_json(input, &job.input)?
            .get("pose_vectors")
            .and_then(|v| v.as_array())
            .map(Vec::len)
            .ok_or_else(|| JobError::input(&job.input, "no `pose_vectors` array"))?,
        ApplyFrom::Coarse => crease_core::mesh::io::open_sequence(input)
            .map_err(|e| JobError::input(&job.input, e))?
            .source
            .n_frames(),
    };
    if n == 0 {
        return Err(JobError::input(&job.input, "the input has no frames"));
    }
    Ok(apply_info(n, n_vertices, n_triangles))
}

#[cfg(not(feature = "deep"))]
fn read_json(path: &Path, uri: &str) -> Result<serde_json::Value, JobError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| JobError::input(uri, format!("{}: {e}", path.display())))?;
    serde_json::from_str(&text)
        .map_err(|e| JobError::input(uri, format!("{}: invalid JSON: {e}", path.display())))
}
