//! `crease run --folds stretch`: fold estimation from the geometry alone (Chen 2011 ch. 4).
//!
//! Flags are prefixed `--stretch-` (they only apply to this detector); `--subdivide` runs detection and
//! deformation on a midpoint-subdivided sequence. They map onto the job's `folds = { kind = "stretch" }`; the
//! job writes `anchors.json` (anchors plus control lines), `folds/control_lines.obj` and `folds.png` into the
//! output (see crease-jobs).

use anyhow::{anyhow, Result};
use clap::Args;
use crease_core::folds::stretch::StretchParams;
use crease_core::Error;

/// Parameters of `--folds stretch` (defaults: see docs/folds.md, "Folds from the geometry alone").
#[derive(Args, Clone, Debug)]
pub struct StretchArgs {
    /// θ0 (degrees, in (0, 90)): largest direction change within one phase (eq. 4.2).
    #[arg(long = "stretch-theta0", default_value_t = StretchParams::default().theta0_deg, allow_hyphen_values = true)]
    pub theta0: f64,
    /// Steps with absolute change below 1 + this are isometric (a fold holding its shape).
    #[arg(long = "stretch-isometry", default_value_t = StretchParams::default().isometry, allow_hyphen_values = true)]
    pub isometry: f64,
    /// Consecutive isometric steps a phase survives.
    #[arg(long = "stretch-max-hold", default_value_t = StretchParams::default().max_hold)]
    pub max_hold: usize,
    /// Smoothing iterations of Γ, γ and the direction angle.
    #[arg(long = "stretch-smooth-iterations", default_value_t = StretchParams::default().smooth_iterations)]
    pub smooth_iterations: usize,
    /// Valid range: absolute changes above this are outliers.
    #[arg(long = "stretch-max-change", default_value_t = StretchParams::default().max_change, allow_hyphen_values = true)]
    pub max_change: f64,
    /// Histogram tails: sparse extreme bins below this fraction of triangles are dropped (0 = off).
    #[arg(long = "stretch-tail-fraction", default_value_t = StretchParams::default().tail_fraction, allow_hyphen_values = true)]
    pub tail_fraction: f64,
    /// Seeds need integrated shrinkage of at least 1 + this (absolute change).
    #[arg(long = "stretch-min-shrink", default_value_t = StretchParams::default().min_shrink, allow_hyphen_values = true)]
    pub min_shrink: f64,
    /// Tracing stops where shrinkage falls below this fraction of the seed's.
    #[arg(long = "stretch-fade", default_value_t = StretchParams::default().fade, allow_hyphen_values = true)]
    pub fade: f64,
    /// Tracing stops at a direction turn above this many degrees.
    #[arg(long = "stretch-max-turn", default_value_t = StretchParams::default().max_turn_deg, allow_hyphen_values = true)]
    pub max_turn: f64,
    /// Fold width at |v| = 1 in mean edge lengths (width = this / |v|).
    #[arg(long = "stretch-fold-width", default_value_t = StretchParams::default().fold_width, allow_hyphen_values = true)]
    pub fold_width: f64,
    /// α of eq. 4.3 in mean edge lengths: region of influence radius α·|v|.
    #[arg(long = "stretch-alpha", default_value_t = StretchParams::default().alpha, allow_hyphen_values = true)]
    pub alpha: f64,
    /// Radius of the flattened patch around a seed, in mean edge lengths.
    #[arg(long = "stretch-patch-radius", default_value_t = StretchParams::default().patch_radius, allow_hyphen_values = true)]
    pub patch_radius: f64,
    /// Anchor angle (radians) per unit of shrinkage |v| − 1; 0 = the angle that gives back the length the
    /// capture lost.
    #[arg(long = "stretch-angle-gain", default_value_t = StretchParams::default().angle_gain, allow_hyphen_values = true)]
    pub angle_gain: f64,
    /// Cap of the anchor angle, degrees.
    #[arg(long = "stretch-max-angle", default_value_t = StretchParams::default().max_angle_deg, allow_hyphen_values = true)]
    pub max_angle: f64,
    /// Shortest fold axis kept, in mean edge lengths.
    #[arg(long = "stretch-min-length", default_value_t = StretchParams::default().min_length, allow_hyphen_values = true)]
    pub min_length: f64,
    /// Frames on each side over which anchors are matched and their angles averaged (0 = off).
    #[arg(long = "stretch-temporal-radius", default_value_t = StretchParams::default().temporal_radius)]
    pub temporal_radius: usize,
    /// Try the previous frame's fold seeds first (Chen's seed memory); makes tracing sequential over time.
    #[arg(long = "stretch-seed-memory", default_value_t = StretchParams::default().seed_memory)]
    pub seed_memory: bool,
    /// Patch flattening of fold tracing: `unfold` (default: unfolding from the seed, no solve; LSCM for a patch
    /// that folds over) or `lscm` (least-squares conformal map, one sparse solve per seed).
    #[arg(long = "stretch-flattening", default_value = StretchParams::default().flattening.name(),
          value_parser = ["unfold", "lscm"])]
    pub flattening: String,
    /// Levels of midpoint subdivision before detection (0 = none); output is then on the subdivided mesh,
    /// original vertices first.
    #[arg(long, default_value_t = 0)]
    pub subdivide: usize,
}

impl StretchArgs {
    pub fn params(&self) -> StretchParams {
        StretchParams {
            theta0_deg: self.theta0,
            isometry: self.isometry,
            max_hold: self.max_hold,
            smooth_iterations: self.smooth_iterations,
            max_change: self.max_change,
            tail_fraction: self.tail_fraction,
            min_shrink: self.min_shrink,
            fade: self.fade,
            max_turn_deg: self.max_turn,
            fold_width: self.fold_width,
            alpha: self.alpha,
            patch_radius: self.patch_radius,
            angle_gain: self.angle_gain,
            max_angle_deg: self.max_angle,
            min_length: self.min_length,
            temporal_radius: self.temporal_radius,
            seed_memory: self.seed_memory,
            flattening: self.flattening.parse().unwrap_or_default(),
        }
    }

    /// Validates the parameters; errors name the flag.
    pub fn validated(&self) -> Result<StretchParams> {
        let p = self.params();
        p.validate().map_err(|e| match e {
            Error::Param { name, msg } => anyhow!("--stretch-{name}: {msg}"),
            e => e.into(),
        })?;
        if self.subdivide > 4 {
            return Err(anyhow!(
                "--subdivide: at most 4 levels (256× the triangles), got {}",
                self.subdivide
            ));
        }
        Ok(p)
    }
}
