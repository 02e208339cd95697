//! Submit-time inspection of a deep job: the training data loads and agrees with itself (frame counts,
//! topology, poses without NaNs), or the model is complete and of this version and the input fits it, so a bad
//! input is refused at submit with the file, frame or field named, not by a task later.

use super::keys;
use super::spec::{ApplyFrom, DeepSpec};
use crate::error::JobError;
use crate::inspect::InputInfo;
use crate::spec::JobSpec;
use crate::storage::fetch_input_to_cache;
use crease_deep::apply::open_coarse;
use crease_deep::model::{Model, RegressorKind};
use crease_deep::regression::pose::read_pose_file;
use crease_deep::train::{common_topology, load_training_dir};
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
    if params.regressor == RegressorKind::Lstm {
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

fn inspect_training(
    deep: &DeepSpec,
    dirs: &[PathBuf],
    uris: &[String],
) -> Result<InputInfo, JobError> {
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

fn inspect_apply(
    job: &JobSpec,
    model_uri: &str,
    model_dir: &Path,
    from: ApplyFrom,
    regressor: Option<RegressorKind>,
    input: &Path,
) -> Result<InputInfo, JobError> {
    let model = Model::load(model_dir).map_err(|e| JobError::input(model_uri, e))?;
    let n = match from {
        ApplyFrom::Pose => {
            model
                .check_regressor(regressor.unwrap_or(model.manifest.regressor))
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
    let mut output_files: Vec<String> = (0..n)
        .flat_map(|t| [keys::mesh(t), keys::normals(t)])
        .collect();
    output_files.push(keys::DONE.to_string());
    Ok(InputInfo {
        layout: "deep-apply".to_string(),
        n_frames: n,
        n_vertices: model.topology.n_vertices(),
        n_triangles: model.topology.n_triangles(),
        output_files,
        anchors_per_frame: None,
    })
}
