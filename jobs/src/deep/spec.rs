//! The `[deep]` section of a job spec. Its fields are the flags of `crease deep train` and `crease deep apply`
//! with the same defaults, so a job and the command with the same values write the same model or frames.
//!
//! The types are this crate's own, not the learning library's, so that a coordinator built without the
//! `deep` feature parses, checks and plans deep jobs; with the feature, `super::library` turns them into
//! the library's parameters, and its tests hold the defaults here to the library's.

use crate::error::JobError;
use crate::storage::location::parse_location;
use serde::{Deserialize, Serialize};

/// What a deep job does. `input` is the first training directory (`train`), or the pose file or coarse
/// sequence the model runs on (`apply`); `output` receives the model or the applied frames (meshes and normal maps).
// A spec is parsed once per job and moved rarely: the training parameters' size does not matter here.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "task", rename_all = "kebab-case", deny_unknown_fields)]
pub enum DeepSpec {
    /// Train a model on `input` and `data` (each with `gt/` and `pose.json`): one task.
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
        space: MapSpace,
        /// Overrides the model's regressor (`from = "pose"` only).
        #[serde(default)]
        regressor: Option<Regressor>,
        /// Write the coarse maps without the cGAN.
        #[serde(default)]
        no_cgan: bool,
        /// Where a coarse input's detail comes from (`from = "coarse"` only): `relief`, `model` or `blend`; default:
        /// whichever won on the model's held-out training sequence.
        #[serde(default)]
        coarse_detail: Option<CoarseDetail>,
    },
}

/// Where `apply --coarse` takes a capture's detail from (`--coarse-detail`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CoarseDetail {
    /// crease's fold relief over the whole coarse sequence.
    Relief,
    /// The model's learned detail filter, frame by frame.
    Model,
    /// The midpoint of the two.
    Blend,
}

fn world() -> MapSpace {
    MapSpace::World
}

/// The pose-to-shape regressor (`--regressor`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Regressor {
    /// Pose (+ velocity, acceleration, lags) only.
    Linear,
    /// Pose and the model's own previous shape coefficients, rolled out from the first frame.
    Autoregressive,
    Lstm,
    /// Weighted mean of the linear map and the autoregressive rollout.
    Blend,
    /// Gaussian kernel ridge regression over a short window of poses.
    Kernel,
}

/// What the pose numbers become before the regression (`--pose-features`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PoseFeatures {
    /// Rigid when the pose file names its numbers as location/rotation_euler blocks, raw otherwise.
    Auto,
    Raw,
    /// Rigid, and an error when the pose file's names do not have that layout.
    Rigid,
}

/// Which reflection augments the training data (`--mirror`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mirror {
    /// The coordinate plane in which the first training frame is most symmetric, if any; otherwise none.
    Auto,
    None,
    X,
    Y,
    Z,
}

/// The frame the stored normals are expressed in (`--space`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MapSpace {
    World,
    Tangent,
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
    pub regressor: Regressor,
    pub kernel_window: Vec<usize>,
    pub kernel_uniform: bool,
    pub ar_state: usize,
    pub ar_rollout_iters: usize,
    pub blend_weight: f64,
    pub blend_fit: bool,
    pub lags: Vec<usize>,
    pub pose_history: Vec<f64>,
    pub ridge: f64,
    pub pose_features: PoseFeatures,
    pub mirror: Mirror,
    pub lstm_layers: usize,
    pub lstm_hidden: usize,
    pub lstm_seq: usize,
    pub lstm_epochs: usize,
    pub lstm_lr: f64,
    pub pose_components: usize,
    pub pose_lowpass: f64,
    pub detail_degree: usize,
    pub detail_captures: usize,
    pub seed: u64,
    pub resolution: usize,
    /// URI of an OBJ whose `vt` gives the UV layout (it must have `vt`); default: computed.
    pub uv: Option<String>,
    /// 0: no cGAN.
    pub cgan_steps: usize,
    pub cgan_filters: usize,
    pub cgan_disc_filters: usize,
    pub cgan_w_temporal: f64,
    pub cgan_depth: usize,
    pub cgan_crop: usize,
}

impl Default for DeepTrainParams {
    /// `crease deep train`'s defaults (the library's `TrainParams`, `LstmConfig` and `CganConfig` defaults,
    /// which the `deep` feature's tests compare them with), seed 1.
    fn default() -> Self {
        DeepTrainParams {
            k: 200,
            regressor: Regressor::Kernel,
            kernel_window: vec![0, 2, 4, 6],
            kernel_uniform: false,
            ar_state: 10,
            ar_rollout_iters: 20,
            blend_weight: 0.5,
            blend_fit: false,
            lags: vec![],
            pose_history: vec![],
            ridge: 1e-3,
            pose_features: PoseFeatures::Auto,
            mirror: Mirror::Auto,
            lstm_layers: 4,
            lstm_hidden: 256,
            lstm_seq: 3,
            lstm_epochs: 300,
            lstm_lr: 1e-3,
            pose_components: 0,
            pose_lowpass: 6.0,
            detail_degree: 16,
            detail_captures: 1,
            seed: 1,
            // crease_deep::normal_maps::DEFAULT_RESOLUTION (the library may not be built in; a test checks).
            resolution: 512,
            uv: None,
            cgan_steps: 1500,
            cgan_filters: 8,
            cgan_disc_filters: 8,
            cgan_w_temporal: 50.0,
            cgan_depth: 5,
            cgan_crop: 64,
        }
    }
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

    /// Checks what can be checked without storage and without the learning library, naming the field at
    /// fault (with the `deep` feature, the training parameters are checked against the library too).
    pub fn validate(&self) -> Result<(), JobError> {
        for (field, uri) in self.uris() {
            parse_location(uri, field)?;
        }
        match self {
            DeepSpec::Train { .. } => {}
            DeepSpec::Apply {
                from,
                regressor,
                coarse_detail,
                ..
            } => {
                if regressor.is_some() && *from != ApplyFrom::Pose {
                    return Err(JobError::spec(
                        "deep.regressor",
                        "applies to `from = \"pose\"` only (coarse meshes need no regression)",
                    ));
                }
                if coarse_detail.is_some() && *from != ApplyFrom::Coarse {
                    return Err(JobError::spec(
                        "deep.coarse_detail",
                        "applies to `from = \"coarse\"` only (a pose's shape has no capture detail)",
                    ));
                }
            }
        }
        Ok(())
    }
}
