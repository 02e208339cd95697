//! The `[deep]` section of a job spec. Its fields are the flags of `crease deep train` and `crease deep apply`
//! with the same defaults, so a job and the command with the same values write the same model or frames.

use crate::error::JobError;
use crate::spec::{FoldSpec, JobSpec};
use crate::storage::parse_location;
use crease_deep::cgan::CganConfig;
use crease_deep::lstm::LstmConfig;
use crease_deep::model::RegressorKind;
use crease_deep::normal_map::Space;
use crease_deep::train::TrainParams;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// What a deep job does. `input` is the first training directory (`train`), or the pose file or coarse
/// sequence the model runs on (`apply`); `output` receives the model or the applied frames (meshes and normal maps).
// A spec is parsed once per job and moved rarely: the training parameters' size does not matter here.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "task", rename_all = "kebab-case", deny_unknown_fields)]
pub enum DeepSpec {
    /// Train a model on `input` and `data` (each with `gt/`, `captured/`, `pose.json`): one task.
    Train {
        /// Further training directories (URIs), after `input`.
        #[serde(default)]
        data: Vec<String>,
        #[serde(default)]
        params: DeepTrainParams,
    },
    /// Run the model at `model` on `input`: frame-chunk tasks and a last one writing `done.json`.
    Apply {
        /// The model directory (URI): a training job's `<output>/model`, or `crease deep train --out`.
        model: String,
        /// Whether `input` is a pose file (`pose`, shapes from the regression) or a coarse sequence (`coarse`).
        from: ApplyFrom,
        /// Normal map space: `world` (default) or `tangent`.
        #[serde(default = "world")]
        space: Space,
        /// Overrides the model's regressor (`from = "pose"` only).
        #[serde(default)]
        regressor: Option<RegressorKind>,
        /// Write the coarse maps without the cGAN.
        #[serde(default)]
        no_cgan: bool,
    },
}

fn world() -> Space {
    Space::World
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ApplyFrom {
    Pose,
    Coarse,
}

/// `crease deep train`'s options, same names (underscores) and defaults.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DeepTrainParams {
    pub k: usize,
    pub regressor: RegressorKind,
    pub ar_state: usize,
    pub ar_rollout_iters: usize,
    pub blend_weight: f64,
    pub blend_fit: bool,
    pub lags: Vec<usize>,
    pub pose_history: Vec<f64>,
    pub ridge: f64,
    pub pose_features: crease_deep::pose_features::PoseFeatureMode,
    pub mirror: crease_deep::mirror::MirrorMode,
    pub lstm_layers: usize,
    pub lstm_hidden: usize,
    pub lstm_seq: usize,
    pub lstm_epochs: usize,
    pub lstm_lr: f64,
    pub pose_components: usize,
    pub pose_smoothing: usize,
    pub seed: u64,
    pub resolution: usize,
    /// URI of an OBJ whose `vt` gives the UV layout (it must have `vt`); default: computed.
    pub uv: Option<String>,
    /// 0: no cGAN.
    pub cgan_epochs: usize,
    pub cgan_filters: usize,
    pub cgan_disc_filters: usize,
    pub cgan_w_temporal: f64,
}

impl Default for DeepTrainParams {
    fn default() -> Self {
        let t = TrainParams::default();
        let c = CganConfig::default();
        DeepTrainParams {
            k: t.k,
            regressor: t.regressor,
            ar_state: t.ar_state,
            ar_rollout_iters: t.ar_rollout_iters,
            blend_weight: t.blend_weight,
            blend_fit: t.blend_fit,
            lags: t.lags,
            pose_history: t.pose_history,
            ridge: t.ridge,
            pose_features: t.pose_features,
            mirror: t.mirror,
            lstm_layers: t.lstm.layers,
            lstm_hidden: t.lstm.hidden,
            lstm_seq: t.lstm.seq_len,
            lstm_epochs: t.lstm.epochs,
            lstm_lr: t.lstm.lr,
            pose_components: t.pose_components,
            pose_smoothing: t.pose_smoothing,
            seed: 1,
            resolution: t.resolution,
            uv: None,
            cgan_epochs: 0,
            cgan_filters: c.filters,
            cgan_disc_filters: c.disc_filters,
            cgan_w_temporal: c.w_temporal,
        }
    }
}

impl DeepTrainParams {
    /// The library's parameters, with the UV template at `uv` (already fetched) when the spec names one.
    pub fn train_params(&self, uv: Option<PathBuf>) -> TrainParams {
        TrainParams {
            k: self.k,
            lags: self.lags.clone(),
            pose_history: self.pose_history.clone(),
            ridge: self.ridge,
            pose_features: self.pose_features,
            mirror: self.mirror,
            regressor: self.regressor,
            ar_state: self.ar_state,
            ar_rollout_iters: self.ar_rollout_iters,
            blend_weight: self.blend_weight,
            blend_fit: self.blend_fit,
            lstm: LstmConfig {
                layers: self.lstm_layers,
                hidden: self.lstm_hidden,
                seq_len: self.lstm_seq,
                epochs: self.lstm_epochs,
                batch: 32,
                lr: self.lstm_lr,
                seed: self.seed,
                // Residual of the blend, cross-fitted, early stopping: as `crease deep train`.
                ..LstmConfig::default()
            },
            pose_components: self.pose_components,
            pose_smoothing: self.pose_smoothing,
            resolution: self.resolution,
            uv,
            cgan: (self.cgan_epochs > 0).then(|| CganConfig {
                resolution: self.resolution,
                filters: self.cgan_filters,
                disc_filters: self.cgan_disc_filters,
                w_temporal: self.cgan_w_temporal,
                epochs: self.cgan_epochs,
                seed: self.seed,
                ..Default::default()
            }),
            checkpoint: None,
        }
    }
}

/// The spec field a library parameter error is about (`lstm.layers` → `deep.params.lstm_layers`).
fn param_field(name: &str) -> String {
    let field = match name {
        "cgan.resolution" => "resolution".to_string(),
        "cgan" => "cgan_filters".to_string(),
        n => n.replace('.', "_"),
    };
    format!("deep.params.{field}")
}

impl DeepSpec {
    /// Short name for logs and the report (`deep-train`, `deep-apply`).
    pub fn kind(&self) -> &'static str {
        match self {
            DeepSpec::Train { .. } => "deep-train",
            DeepSpec::Apply { .. } => "deep-apply",
        }
    }

    /// The URIs the job reads besides `input` and `output`, with their field names (for confinement checks).
    pub fn uris(&self) -> Vec<(&'static str, &str)> {
        match self {
            DeepSpec::Train { data, params } => {
                let mut v: Vec<(&'static str, &str)> =
                    data.iter().map(|d| ("deep.data", d.as_str())).collect();
                if let Some(uv) = &params.uv {
                    v.push(("deep.params.uv", uv));
                }
                v
            }
            DeepSpec::Apply { model, .. } => vec![("deep.model", model.as_str())],
        }
    }

    /// Checks what can be checked without storage; the parts of a job spec that only deformations use must be
    /// left at their defaults, so that nothing set there is silently ignored.
    pub fn validate(&self, job: &JobSpec) -> Result<(), JobError> {
        if job.folds != FoldSpec::None {
            return Err(JobError::spec(
                "folds",
                "a [deep] job has no folds (it trains or applies a DeepWrinkles model); remove [folds]",
            ));
        }
        if !job.export.formats.is_empty() {
            return Err(JobError::spec(
                "export",
                "a [deep] job writes meshes and normal maps, not an exported sequence; remove [export]",
            ));
        }
        if job.deform != crease_core::spacetime::DeformParams::default() {
            return Err(JobError::spec(
                "deform",
                "a [deep] job does not deform its input; remove [deform]",
            ));
        }
        for (field, uri) in self.uris() {
            parse_location(uri, field)?;
        }
        match self {
            DeepSpec::Train { params, .. } => {
                let p = params.train_params(None);
                let lib = |e: crease_core::Error| match e {
                    crease_core::Error::Param { name, msg } => {
                        JobError::spec(param_field(&name), msg)
                    }
                    e => JobError::spec("deep.params", e.to_string()),
                };
                p.validate().map_err(lib)?;
                if let Some(c) = &p.cgan {
                    c.validate().map_err(lib)?;
                }
            }
            DeepSpec::Apply {
                from, regressor, ..
            } => {
                if regressor.is_some() && *from != ApplyFrom::Pose {
                    return Err(JobError::spec(
                        "deep.regressor",
                        "applies to `from = \"pose\"` only (coarse meshes need no regression)",
                    ));
                }
            }
        }
        Ok(())
    }
}
