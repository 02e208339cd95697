//! The tasks of a deep job (see [`crate::deep`]): they call crease-deep on a local staging directory under the
//! worker's cache and upload what it wrote, so the bytes in storage are the bytes `crease deep train|apply`
//! writes, whatever the storage.

use super::env::{storage_err, TaskEnv};
use crate::deep::inspect::{fetch_training_dirs, model_files};
use crate::deep::keys as dk;
use crate::deep::library::train_params;
use crate::deep::spec::{ApplyFrom, DeepSpec};
use crate::error::TaskError;
use crate::storage::keys;
use crate::storage::store::fetch_input_to_cache;
use crease_deep::apply::{apply as deep_apply, ApplyInput, ApplyParams};
use crease_deep::model::{Manifest, Model};
use crease_deep::train::{load_training_dir, train as deep_train};
use serde_json::{json, Value};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// A directory under the worker's cache, private to one task attempt, removed when dropped.
struct Staging(PathBuf);

impl Staging {
    fn new(cache: &Path, what: &str) -> Result<Self, TaskError> {
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let dir = cache.join(format!(
            "deep-{what}-{}-{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        if dir.exists() {
            let _ = std::fs::remove_dir_all(&dir);
        }
        crease_core::fsutil::create_dir_all(&dir)
            .map_err(|e| TaskError::from_core("staging", e))?;
        Ok(Staging(dir))
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn spec_of<'a>(env: &'a TaskEnv) -> Result<&'a DeepSpec, TaskError> {
    env.job
        .deep
        .as_ref()
        .ok_or_else(|| TaskError::fatal("a deep task of a job without a [deep] section"))
}

fn put_file(env: &TaskEnv, key: &str, file: &Path) -> Result<(), TaskError> {
    env.block_on(env.out.put_file(key, file))
        .map_err(storage_err)
}

fn fetch(env: &TaskEnv, uri: &str) -> Result<PathBuf, TaskError> {
    env.block_on(fetch_input_to_cache(uri, &env.ctx.cache_dir))
        .map_err(storage_err)
}

/// `deep/train`: trains on the job's training directories and publishes the model under `model/`, the manifest
/// last (a stale one is deleted first, so it never vouches for files being replaced), then `report.json`.
pub fn train(env: &TaskEnv) -> Result<(Value, Vec<String>), TaskError> {
    let deep = spec_of(env)?;
    let DeepSpec::Train { params, .. } = deep else {
        return Err(TaskError::fatal("deep-train task of an apply job"));
    };
    env.delete(keys::REPORT)?;
    env.delete(dk::MODEL_MANIFEST)?;
    let dirs = env
        .block_on(fetch_training_dirs(env.job, deep, &env.ctx.cache_dir))
        .map_err(storage_err)?;
    let uv = match &params.uv {
        Some(u) => Some(fetch(env, u)?),
        None => None,
    };
    let clock = Instant::now();
    let mut seqs = Vec::with_capacity(dirs.len());
    for d in &dirs {
        seqs.push(
            load_training_dir(d)
                .map_err(|e| TaskError::from_core("deep-train: training data", e))?,
        );
    }
    let staging = Staging::new(&env.ctx.cache_dir, "train")?;
    let local = staging.0.join("model");
    deep_train(&seqs, &train_params(params, uv), &local, env.progress())
        .map_err(|e| TaskError::from_core("deep-train", e))?;
    let seconds = clock.elapsed().as_secs_f64();
    env.check_cancelled()?;
    let mpath = local.join("manifest.json");
    let text = std::fs::read(&mpath)
        .map_err(|e| TaskError::from_core("deep-train", crease_core::Error::io(&mpath, e)))?;
    let manifest: Manifest = serde_json::from_slice(&text)
        .map_err(|e| TaskError::fatal(format!("deep-train: {}: {e}", mpath.display())))?;
    let mut written = Vec::new();
    for name in manifest.files.keys() {
        let key = dk::model_file(name);
        put_file(env, &key, &local.join(name))?;
        written.push(key);
    }
    // The planner named the files the job must end with; a model with others would never be marked done.
    for key in model_files(deep) {
        if key != dk::MODEL_MANIFEST && !written.contains(&key) {
            return Err(TaskError::fatal(format!(
                "deep-train: the trained model has no `{key}`, which this job's parameters promise"
            )));
        }
    }
    env.put(dk::MODEL_MANIFEST, text)?;
    written.push(dk::MODEL_MANIFEST.to_string());
    let summary = json!({
        "kind": "deep-train",
        "model": dk::MODEL_DIR,
        "frames": seqs.iter().map(|s| s.fine.len()).sum::<usize>(),
        "k": manifest.k,
        "resolution": manifest.resolution,
        "training": manifest.training,
        "seconds": seconds,
    });
    let report = json!({ "complete": true, "report": summary, "manifest": written });
    env.put(keys::REPORT, report.to_string())?;
    written.push(keys::REPORT.to_string());
    Ok((summary, written))
}

/// The model and the input of an apply job, from the worker's cache.
fn open_apply(env: &TaskEnv) -> Result<(Model, ApplyInput, ApplyParams), TaskError> {
    let DeepSpec::Apply {
        model,
        from,
        space,
        regressor,
        no_cgan,
        coarse_detail,
    } = spec_of(env)?
    else {
        return Err(TaskError::fatal("deep-apply task of a training job"));
    };
    let model_dir = fetch(env, model)?;
    let input = fetch(env, &env.job.input)?;
    let model = Model::load(&model_dir).map_err(|e| TaskError::from_core("deep.model", e))?;
    let input = match from {
        ApplyFrom::Pose => ApplyInput::Pose(input),
        ApplyFrom::Coarse => ApplyInput::Coarse(input),
    };
    let params = ApplyParams {
        space: (*space).into(),
        regressor: regressor.map(Into::into),
        frames: None,
        no_cgan: *no_cgan,
        coarse_detail: coarse_detail.map(Into::into),
    };
    Ok((model, input, params))
}

/// `deep/apply/fNNNNNN`: frames `frames` of apply's output layout, `mesh/` and `normals/`.
pub fn apply(env: &TaskEnv, frames: Range<usize>) -> Result<(Value, Vec<String>), TaskError> {
    let (model, input, mut params) = open_apply(env)?;
    params.frames = Some(frames.clone());
    let staging = Staging::new(&env.ctx.cache_dir, "apply")?;
    let clock = Instant::now();
    let applied = deep_apply(&model, &input, &params, &staging.0, env.progress())
        .map_err(|e| TaskError::from_core("deep-apply", e))?;
    let seconds = clock.elapsed().as_secs_f64();
    let mut written = Vec::new();
    for t in frames.clone() {
        for key in [dk::mesh(t), dk::normals(t)] {
            put_file(env, &key, &staging.0.join(&key))?;
            written.push(key);
        }
    }
    let summary = json!({
        "frames": [frames.start, frames.end],
        "ms_per_frame": 1e3 * seconds / frames.len().max(1) as f64,
        // Frames the detail model's guard gave the input's own normals (their OBJ says why too).
        "fallback_frames": applied.fallback.iter().map(|(t, _)| t + 1).collect::<Vec<_>>(),
        // Pose frames outside what the kernel regressor learned (near the mean shape).
        "outside_frames": applied.outside.iter().map(|(t, _)| t + 1).collect::<Vec<_>>(),
    });
    Ok((summary, written))
}

/// `deep/finish`: `done.json` (the bytes `crease deep apply` writes) once every frame is in storage, then
/// `report.json`.
pub fn finish(env: &TaskEnv, n_frames: usize) -> Result<(Value, Vec<String>), TaskError> {
    env.delete(keys::REPORT)?;
    let (model, _, params) = open_apply(env)?;
    for t in 0..n_frames {
        for key in [dk::mesh(t), dk::normals(t)] {
            if !env.block_on(env.out.exists(&key)).map_err(storage_err)? {
                return Err(TaskError::fatal(format!(
                    "deep-finish: {} is missing (frame {})",
                    env.out.describe(&key),
                    t + 1
                )));
            }
        }
    }
    let staging = Staging::new(&env.ctx.cache_dir, "finish")?;
    crease_deep::contract::finish(
        &staging.0,
        n_frames,
        params.space,
        model.manifest.resolution,
        "crease deep apply",
    )
    .map_err(|e| TaskError::from_core("deep-finish", e))?;
    put_file(env, dk::DONE, &staging.0.join(dk::DONE))?;
    let summary = json!({
        "kind": "deep-apply",
        "frames": n_frames,
        "space": params.space,
        "resolution": model.manifest.resolution,
        "cgan": model.manifest.cgan.is_some() && !params.no_cgan,
    });
    let mut written: Vec<String> = (0..n_frames)
        .flat_map(|t| [dk::mesh(t), dk::normals(t)])
        .collect();
    written.push(dk::DONE.to_string());
    let report = json!({ "complete": true, "report": summary, "manifest": written });
    env.put(keys::REPORT, report.to_string())?;
    Ok((
        summary,
        vec![dk::DONE.to_string(), keys::REPORT.to_string()],
    ))
}
