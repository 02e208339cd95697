//! Which regressor maps a pose to subspace coefficients: named in the CLI, the job spec and the model's
//! manifest.

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RegressorKind {
    /// Pose (+ velocity, acceleration, lags) only.
    Linear,
    /// Pose and the model's own previous shape coefficients, rolled out from the first frame.
    Autoregressive,
    Lstm,
    /// Weighted mean of the linear map and the autoregressive rollout ([`crate::regression::blend`]).
    Blend,
    /// Gaussian kernel ridge regression over a short window of poses ([`crate::regression::kernel`]).
    Kernel,
}

impl RegressorKind {
    pub fn name(self) -> &'static str {
        match self {
            RegressorKind::Linear => "linear",
            RegressorKind::Autoregressive => "autoregressive",
            RegressorKind::Lstm => "lstm",
            RegressorKind::Blend => "blend",
            RegressorKind::Kernel => "kernel",
        }
    }
}

impl std::str::FromStr for RegressorKind {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "linear" => Ok(RegressorKind::Linear),
            "autoregressive" => Ok(RegressorKind::Autoregressive),
            "lstm" => Ok(RegressorKind::Lstm),
            "blend" => Ok(RegressorKind::Blend),
            "kernel" => Ok(RegressorKind::Kernel),
            _ => Err(format!(
                "unknown regressor `{s}` (kernel, linear, autoregressive, blend or lstm)"
            )),
        }
    }
}
