//! Parameters of the geometric fold estimation (Chen 2011 ch. 4), with the thesis' choices as defaults where it
//! gives them and values tuned on the sleeve sample elsewhere (see the README table).
//!
//! Lengths are in units of the mesh's mean edge length, so one set of defaults works for garments of any scale
//! and resolution.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// Everything the stretch fold detector can be told. [`StretchParams::validate`] names the offending field.
/// Serde: every field defaults (a job spec names only what it changes); unknown fields are errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StretchParams {
    /// θ0 of eq. 4.2, degrees: the largest change of the dominant direction between consecutive steps that
    /// still counts as the same phase. Must lie in (0, 90).
    #[serde(alias = "theta0")]
    pub theta0_deg: f64,
    /// A step whose absolute change |v| (eq. 4.1) is below `1 + isometry` is isometric: it neither starts nor
    /// breaks a phase (folds holding their shape for a frame or two, §4.3).
    pub isometry: f64,
    /// Consecutive isometric steps a phase may hold through before it ends.
    pub max_hold: usize,
    /// A stretch phase of at most this many steps that turns straight into shrinkage along the same direction
    /// is a transient (an outlier vertex, a frame of tracking jitter): the shrinkage is measured from before
    /// the stretch instead of from its peak. 0 measures every shrinkage from the phase boundary (the thesis).
    pub transient_steps: usize,
    /// Jacobi smoothing iterations of Γ, γ and the direction angle over edge-adjacent triangles (§4.2).
    pub smooth_iterations: usize,
    /// Valid magnitude range: absolute changes above this are outliers (registration errors), §4.2.
    pub max_change: f64,
    /// Histogram tails: extreme histogram bins holding less than this fraction of the triangles are dropped,
    /// walking in from the highest stretch and the lowest shrinkage (§4.2). 0 disables.
    pub tail_fraction: f64,
    /// Seeds need an integrated shrinkage of at least `1 + min_shrink` (absolute change).
    pub min_shrink: f64,
    /// Tracing stops where the shrinkage falls below this fraction of the seed's (`|v| − 1` scale).
    pub fade: f64,
    /// Tracing stops where the fold direction turns by more than this many degrees between triangles.
    #[serde(alias = "max_turn")]
    pub max_turn_deg: f64,
    /// Fold width at |v| = 1, in mean edge lengths; the width is `fold_width / |v|` (inversely proportional
    /// to the absolute change, §4.4).
    pub fold_width: f64,
    /// α of eq. 4.3 in mean edge lengths: the region of influence reaches `α·|v|` from the fold axis.
    pub alpha: f64,
    /// Radius of the parameterised patch around a seed, in mean edge lengths; bounds a fold's half length.
    pub patch_radius: f64,
    /// Positive (default 4): the linear law, angle = gain · (|v| − 1) radians. 0: anchor angles from the
    /// material — the angle at which the fold gives back the length its region of influence lost to the
    /// measured shrinkage ([`super::trace::fold_angle`]). Measured with the shape screen and anchored stretch
    /// passes it raises κ but lowers the correlation and puts the normal error above the captured input's
    /// (the extra amplitude lands on folds only partly in the right place), so it is not the default
    /// (bench/results/2026-12-02-anchored-stretch-passes.md). Either way capped by `max_angle_deg`.
    pub angle_gain: f64,
    /// Cap of the anchor rotation, degrees (Popa et al. use 30°–60°).
    #[serde(alias = "max_angle")]
    pub max_angle_deg: f64,
    /// Frames on each side over which anchors are matched and their angles averaged (`crate::folds::temporal`);
    /// 0 leaves each frame's anchors as traced.
    pub temporal_radius: usize,
    /// The thesis' seed memory (§4.4): the seeds that gave folds in the previous frame are tried first. It
    /// makes every frame's folds depend on all frames before it, so tracing cannot be split across workers
    /// without tracing again in order (`split::reconcile`), and measured on the public cases it does not buy
    /// coherence that the anchor matching of `temporal_radius` does not already give: without it, fold-signal
    /// correlation, κ and normal error all improve on the sleeve and the drape, popping stays below 1.2
    /// (docs/folds.md). Off by default, which makes tracing independent per frame.
    pub seed_memory: bool,
    /// Folds whose traced axis is shorter than this (mean edge lengths) are dropped as noise.
    pub min_length: f64,
}

impl Default for StretchParams {
    fn default() -> Self {
        StretchParams {
            theta0_deg: 30.0,
            isometry: 0.002,
            max_hold: 2,
            transient_steps: 1,
            smooth_iterations: 6,
            max_change: 2.0,
            tail_fraction: 0.0005,
            min_shrink: 0.02,
            fade: 0.3,
            max_turn_deg: 45.0,
            fold_width: 2.0,
            alpha: 2.0,
            patch_radius: 8.0,
            angle_gain: 4.0,
            max_angle_deg: 60.0,
            min_length: 2.0,
            temporal_radius: 2,
            seed_memory: false,
        }
    }
}

impl StretchParams {
    /// Checks every field; errors name the field.
    pub fn validate(&self) -> Result<()> {
        let finite_pos = |name: &str, v: f64| -> Result<()> {
            if !v.is_finite() || v <= 0.0 {
                return Err(Error::param(
                    name,
                    format!("must be a positive number, got {v}"),
                ));
            }
            Ok(())
        };
        let finite_nonneg = |name: &str, v: f64| -> Result<()> {
            if !v.is_finite() || v < 0.0 {
                return Err(Error::param(
                    name,
                    format!("must be zero or positive, got {v}"),
                ));
            }
            Ok(())
        };
        if !(self.theta0_deg > 0.0 && self.theta0_deg < 90.0) {
            return Err(Error::param(
                "theta0_deg",
                format!(
                    "must lie in (0°, 90°) (directions are axial), got {}°",
                    self.theta0_deg
                ),
            ));
        }
        finite_nonneg("isometry", self.isometry)?;
        if self.smooth_iterations > 1000 {
            return Err(Error::param(
                "smooth_iterations",
                format!("at most 1000, got {}", self.smooth_iterations),
            ));
        }
        if !(self.max_change.is_finite() && self.max_change > 1.0) {
            return Err(Error::param(
                "max_change",
                format!(
                    "is an absolute change (≥ 1) and must exceed 1, got {}",
                    self.max_change
                ),
            ));
        }
        if !(self.tail_fraction.is_finite() && (0.0..0.5).contains(&self.tail_fraction)) {
            return Err(Error::param(
                "tail_fraction",
                format!("must lie in [0, 0.5), got {}", self.tail_fraction),
            ));
        }
        finite_pos("min_shrink", self.min_shrink)?;
        if self.min_shrink + 1.0 >= self.max_change {
            return Err(Error::param(
                "min_shrink",
                format!(
                    "1 + min_shrink ({}) must be below max_change ({})",
                    1.0 + self.min_shrink,
                    self.max_change
                ),
            ));
        }
        if !(self.fade.is_finite() && (0.0..1.0).contains(&self.fade)) {
            return Err(Error::param(
                "fade",
                format!("must lie in [0, 1), got {}", self.fade),
            ));
        }
        if !(self.max_turn_deg > 0.0 && self.max_turn_deg <= 90.0) {
            return Err(Error::param(
                "max_turn_deg",
                format!("must lie in (0°, 90°], got {}°", self.max_turn_deg),
            ));
        }
        finite_pos("fold_width", self.fold_width)?;
        finite_pos("alpha", self.alpha)?;
        finite_pos("patch_radius", self.patch_radius)?;
        if self.patch_radius > 1000.0 {
            return Err(Error::param(
                "patch_radius",
                format!("at most 1000 edge lengths, got {}", self.patch_radius),
            ));
        }
        finite_nonneg("angle_gain", self.angle_gain)?;
        if !(self.max_angle_deg > 0.0 && self.max_angle_deg <= 180.0) {
            return Err(Error::param(
                "max_angle_deg",
                format!("must lie in (0°, 180°], got {}°", self.max_angle_deg),
            ));
        }
        finite_nonneg("min_length", self.min_length)?;
        if self.transient_steps > 50 {
            return Err(Error::param(
                "transient_steps",
                format!("at most 50 steps, got {}", self.transient_steps),
            ));
        }
        if self.temporal_radius > 50 {
            return Err(Error::param(
                "temporal_radius",
                format!("at most 50 frames, got {}", self.temporal_radius),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_values_name_their_field() {
        assert!(StretchParams::default().validate().is_ok());
        let cases: Vec<(StretchParams, &str)> = vec![
            (
                StretchParams {
                    theta0_deg: 0.0,
                    ..Default::default()
                },
                "theta0_deg",
            ),
            (
                StretchParams {
                    theta0_deg: 95.0,
                    ..Default::default()
                },
                "theta0_deg",
            ),
            (
                StretchParams {
                    fold_width: -1.0,
                    ..Default::default()
                },
                "fold_width",
            ),
            (
                StretchParams {
                    alpha: f64::NAN,
                    ..Default::default()
                },
                "alpha",
            ),
            (
                StretchParams {
                    max_change: 0.5,
                    ..Default::default()
                },
                "max_change",
            ),
            (
                StretchParams {
                    tail_fraction: 0.7,
                    ..Default::default()
                },
                "tail_fraction",
            ),
            (
                StretchParams {
                    fade: 1.0,
                    ..Default::default()
                },
                "fade",
            ),
            (
                StretchParams {
                    max_angle_deg: 0.0,
                    ..Default::default()
                },
                "max_angle_deg",
            ),
            (
                StretchParams {
                    min_shrink: 3.0,
                    ..Default::default()
                },
                "min_shrink",
            ),
        ];
        for (p, name) in cases {
            let e = p.validate().unwrap_err().to_string();
            assert!(e.contains(&format!("`{name}`")), "{name}: {e}");
        }
    }
}
