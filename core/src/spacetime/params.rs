//! Parameters of the space-time deformation, with their paper defaults and validation.

use super::position::stretch::StretchRotation;
use super::position::Pinning;
use super::shape::relief::ReliefParams;
use super::shape::ShapeEnding;
use super::weights::operator::Coefficients;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// How the weight solve is organised: `fused` (three right-hand sides) or `per-anchor` (one CG column per
/// anchor, spread over tasks).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WeightMode {
    /// Three right-hand sides X = W Φ per window.
    #[default]
    Fused,
    /// One CG column per anchor, grouped into blocks of partial blends (the paper's formulation).
    PerAnchor,
}

impl std::str::FromStr for WeightMode {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "fused" => Ok(WeightMode::Fused),
            "per-anchor" => Ok(WeightMode::PerAnchor),
            _ => Err(Error::param(
                "mode",
                format!("`{s}` is not one of: fused, per-anchor"),
            )),
        }
    }
}

impl std::fmt::Display for WeightMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            WeightMode::Fused => "fused",
            WeightMode::PerAnchor => "per-anchor",
        })
    }
}

/// Default cutoff wavelength of the shape screen, in detail scales (docs/fidelity.md). Shorter than the
/// projection's shape scale ([`super::shape::SHAPE_SCALES`]): the projection only removes what passes its
/// low-pass, so displacements between a fold's width and twice the detail scale (7–10 mean edge lengths at the
/// default) were left to the solve, which moved the garment there; the screen holds them from the start and the
/// folds, narrower, stay free.
pub const DEFAULT_SHAPE_CUTOFF: f64 = 1.5;

/// The lengths a sequence's deformation works at ([`DeformParams::scales`]), in the input's units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scales {
    /// The detail scale ([`super::shape::relief`]).
    pub detail: f64,
    /// The shape screen's cutoff wavelength (None: no screen).
    pub screen: Option<f64>,
    pub ending: ShapeEnding,
}

/// Everything the deformation needs besides the sequence and the anchors.
///
/// Read from a job spec's `[deform]` table through [`DeformFields`], which takes the coefficients flat (`c_s`,
/// as their tuning keys `deform.c_s` name them) or nested, and the older names `cg_tol` and `cg_max_iter`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "DeformFields")]
pub struct DeformParams {
    pub coefficients: Coefficients,
    /// Frames per time window.
    pub window: usize,
    /// Frames between window starts; `window - shift` frames are cross-faded.
    pub shift: usize,
    /// Relative residual at which each CG column stops.
    pub cg_tolerance: f64,
    pub cg_max_iterations: usize,
    pub mode: WeightMode,
    /// Anchor columns per block in per-anchor mode.
    pub anchor_block: usize,
    /// Stretch-reduction passes after the first positioning.
    pub stretch_passes: usize,
    /// Which rotation each stretch pass gives a triangle (see [`super::position::stretch`]).
    pub stretch_rotation: StretchRotation,
    /// Cutoff wavelength ℓ_c of the positioning's shape screen, in detail scales (see [`super::position`] and
    /// [`super::shape`]): displacements much longer than this are held to the captured shape, shorter ones
    /// (folds) are free. 0 turns the screen off (the paper's unscreened system, with `pinning`).
    pub shape_cutoff: f64,
    /// How the unscreened system (`shape_cutoff` 0) removes its translational null space; the screened one
    /// has none and keeps each component's area-weighted mean displacement at zero by itself.
    pub pinning: Pinning,
    /// The fold relief ([`super::shape::relief`]): the detail scale, the deconvolution's steps and the temporal
    /// average.
    pub relief: ReliefParams,
    /// Shape projection (see [`super::shape::projection`]): the fraction of the low-pass (at the shape scale) of
    /// the positioned displacement removed after the stretch passes, so the folds do not move the garment. 0
    /// turns it off; it acts only with the shape screen on (`shape_cutoff` > 0: `off` is the paper's
    /// unconstrained system).
    pub shape_projection: f64,
    /// Bound what the deformation adds by the surface the capture lost ([`super::shape::lost_area`]): a
    /// neighbourhood whose captured area is as large as it ever is in the sequence gets no folds added. Off, the
    /// relief and the anchors act wherever they reach (a capture whose folds never open in any frame, anchors
    /// an artist placed on purpose).
    pub lost_area_bound: bool,
    /// Let the shape screen and the projection go where the capture kept no trace of the surface it lost
    /// ([`super::shape::lost_area::Trace::hold`]): at a vertex whose captured neighbourhood the relief
    /// gives back less than this share of the surface lost there, they hold only in proportion. A capture that
    /// erased a fold outright leaves the relief nothing to sharpen, and the screen, which cannot tell a
    /// fold's rise from a drift of the garment, keeps most of the fold the anchors make. 0 (default): the
    /// screen holds everywhere. Acts only with the lost-area bound, which still caps what is added.
    pub release_share: f64,

    /// Strain limit (see [`super::position::strain_limit`]): the last step of the positioning shortens every edge
    /// longer than (1 + this) times its reference length back to it; a fraction, 0 turns it off.
    pub strain_limit: f64,
    /// Gauss–Seidel sweeps of the strain limit (it stops early once a sweep moves nothing).
    pub strain_limit_sweeps: usize,
    /// The strain limit's reference lengths: the sequence's longest captured edge lengths (default) or each
    /// frame's own ([`super::position::strain_limit::StrainReference`]).
    pub strain_reference: super::position::strain_limit::StrainReference,
}

impl Default for DeformParams {
    fn default() -> Self {
        DeformParams {
            coefficients: Coefficients::default(),
            window: 10,
            shift: 7,
            cg_tolerance: 1e-3,
            cg_max_iterations: 2000,
            mode: WeightMode::Fused,
            anchor_block: 256,
            stretch_passes: 2,
            stretch_rotation: StretchRotation::Anchored,
            shape_cutoff: DEFAULT_SHAPE_CUTOFF,
            pinning: Pinning::Centroid,
            relief: ReliefParams::default(),
            shape_projection: super::shape::projection::DEFAULT_SHAPE_PROJECTION,
            lost_area_bound: true,
            release_share: 0.0,

            strain_limit: super::position::strain_limit::DEFAULT_STRAIN_LIMIT,
            strain_limit_sweeps: super::position::strain_limit::DEFAULT_STRAIN_LIMIT_SWEEPS,
            strain_reference: Default::default(),
        }
    }
}

/// The `[deform]` table as written: every field optional (paper defaults), each under the name of its tuning
/// key (`c_s`, `cg_max_iterations`), its place in the struct (`coefficients.c_s`) or its older name
/// (`cg_max_iter`).
#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct DeformFields {
    coefficients: Option<CoefficientFields>,
    c_s: Option<f64>,
    c_t: Option<f64>,
    c_i: Option<f64>,
    c_a: Option<f64>,
    window: Option<usize>,
    shift: Option<usize>,
    #[serde(alias = "cg_tol")]
    cg_tolerance: Option<f64>,
    #[serde(alias = "cg_max_iter")]
    cg_max_iterations: Option<usize>,
    mode: Option<WeightMode>,
    anchor_block: Option<usize>,
    stretch_passes: Option<usize>,
    stretch_rotation: Option<StretchRotation>,
    shape_cutoff: Option<f64>,
    pinning: Option<Pinning>,
    relief: Option<ReliefParams>,
    shape_projection: Option<f64>,
    lost_area_bound: Option<bool>,
    release_share: Option<f64>,

    strain_limit: Option<f64>,
    strain_limit_sweeps: Option<usize>,
    strain_reference: Option<super::position::strain_limit::StrainReference>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct CoefficientFields {
    c_s: Option<f64>,
    c_t: Option<f64>,
    c_i: Option<f64>,
    c_a: Option<f64>,
}

impl TryFrom<DeformFields> for DeformParams {
    type Error = String;
    fn try_from(f: DeformFields) -> std::result::Result<Self, String> {
        let d = DeformParams::default();
        let nested = f.coefficients.unwrap_or_default();
        let both =
            |name: &str, flat: Option<f64>, inner: Option<f64>, default: f64| match (flat, inner) {
                (Some(_), Some(_)) => Err(format!(
                    "`{name}` is given twice (as `{name}` and `coefficients.{name}`): keep one"
                )),
                (v, w) => Ok(v.or(w).unwrap_or(default)),
            };
        let c = &d.coefficients;
        Ok(DeformParams {
            coefficients: Coefficients {
                c_s: both("c_s", f.c_s, nested.c_s, c.c_s)?,
                c_t: both("c_t", f.c_t, nested.c_t, c.c_t)?,
                c_i: both("c_i", f.c_i, nested.c_i, c.c_i)?,
                c_a: both("c_a", f.c_a, nested.c_a, c.c_a)?,
            },
            window: f.window.unwrap_or(d.window),
            shift: f.shift.unwrap_or(d.shift),
            cg_tolerance: f.cg_tolerance.unwrap_or(d.cg_tolerance),
            cg_max_iterations: f.cg_max_iterations.unwrap_or(d.cg_max_iterations),
            mode: f.mode.unwrap_or(d.mode),
            anchor_block: f.anchor_block.unwrap_or(d.anchor_block),
            stretch_passes: f.stretch_passes.unwrap_or(d.stretch_passes),
            stretch_rotation: f.stretch_rotation.unwrap_or(d.stretch_rotation),
            shape_cutoff: f.shape_cutoff.unwrap_or(d.shape_cutoff),
            pinning: f.pinning.unwrap_or(d.pinning),
            relief: f.relief.unwrap_or(d.relief),
            shape_projection: f.shape_projection.unwrap_or(d.shape_projection),
            lost_area_bound: f.lost_area_bound.unwrap_or(d.lost_area_bound),
            release_share: f.release_share.unwrap_or(d.release_share),

            strain_limit: f.strain_limit.unwrap_or(d.strain_limit),
            strain_limit_sweeps: f.strain_limit_sweeps.unwrap_or(d.strain_limit_sweeps),
            strain_reference: f.strain_reference.unwrap_or(d.strain_reference),
        })
    }
}

impl DeformParams {
    /// The lengths of a sequence whose first frame has mean edge length `edge`: the detail scale, the shape
    /// screen's cutoff (None when off) and the positioning's ending.
    pub fn scales(&self, edge: f64) -> Scales {
        let detail = self.relief.scale_for(edge);
        let screen = (self.shape_cutoff > 0.0).then_some(self.shape_cutoff * detail);
        Scales {
            detail,
            screen,
            ending: ShapeEnding {
                projection: if screen.is_some() {
                    self.shape_projection
                } else {
                    0.0
                },
                shape_scale: super::shape::SHAPE_SCALES * detail,
                release_share: if screen.is_some() && self.lost_area_bound {
                    self.release_share
                } else {
                    0.0
                },
            },
        }
    }

    /// The strain limiter of these settings for `source` (its rest lengths read from every frame for the
    /// sequence reference), or `None` when `strain_limit` is 0.
    pub fn strain_limiter(
        &self,
        source: &dyn crate::mesh::FrameSource,
    ) -> Result<Option<super::position::strain_limit::StrainLimiter>> {
        super::position::strain_limit::StrainLimiter::for_source(
            source,
            self.strain_limit,
            self.strain_limit_sweeps,
            self.strain_reference,
        )
    }

    /// Rejects values the solver cannot honour, naming the parameter.
    pub fn validate(&self) -> Result<()> {
        let c = &self.coefficients;
        let finite_nonneg = |name: &str, v: f64| {
            if !v.is_finite() || v < 0.0 {
                Err(Error::param(
                    name,
                    format!("must be a finite number ≥ 0, got {v}"),
                ))
            } else {
                Ok(())
            }
        };
        finite_nonneg("c_s", c.c_s)?;
        finite_nonneg("c_t", c.c_t)?;
        for (name, v) in [("c_i", c.c_i), ("c_a", c.c_a)] {
            if !v.is_finite() || v <= 0.0 {
                return Err(Error::param(
                    name,
                    format!("must be a finite number > 0, got {v}"),
                ));
            }
        }
        if self.window == 0 {
            return Err(Error::param("window", "must be at least 1 frame"));
        }
        if self.shift == 0 || self.shift > self.window {
            return Err(Error::param(
                "shift",
                format!(
                    "must be between 1 and the window ({}), got {}",
                    self.window, self.shift
                ),
            ));
        }
        if !(self.cg_tolerance > 0.0 && self.cg_tolerance < 1.0) {
            return Err(Error::param(
                "cg_tolerance",
                format!("must be in (0, 1), got {}", self.cg_tolerance),
            ));
        }
        if self.cg_max_iterations == 0 {
            return Err(Error::param("cg_max_iterations", "must be at least 1"));
        }
        if self.anchor_block == 0 {
            return Err(Error::param("anchor_block", "must be at least 1"));
        }
        if !(self.shape_cutoff.is_finite() && self.shape_cutoff >= 0.0) {
            return Err(Error::param(
                "shape_cutoff",
                format!(
                    "must be a wavelength ≥ 0 detail scales (0: no screen), got {}",
                    self.shape_cutoff
                ),
            ));
        }
        if self.shape_cutoff > 0.0 && self.pinning == Pinning::Vertex {
            return Err(Error::param(
                "pinning",
                "`vertex` needs the unscreened system: set shape_cutoff to 0 (off) to fix a vertex",
            ));
        }
        self.relief.validate()?;
        let max_projection = super::shape::projection::MAX_SHAPE_PROJECTION;
        if !(self.shape_projection.is_finite()
            && (0.0..=max_projection).contains(&self.shape_projection))
        {
            return Err(Error::param(
                "shape_projection",
                format!(
                    "must be a fraction in [0, {max_projection}] (0: off), got {}",
                    self.shape_projection
                ),
            ));
        }
        if !(self.release_share.is_finite() && (0.0..=1.0).contains(&self.release_share)) {
            return Err(Error::param(
                "release_share",
                format!(
                    "must be a share in [0, 1] (0: the screen holds everywhere), got {}",
                    self.release_share
                ),
            ));
        }
        super::position::strain_limit::validate(self.strain_limit, self.strain_limit_sweeps)?;
        if self.stretch_passes > 20 {
            return Err(Error::param(
                "stretch_passes",
                format!("{} is more than the 20 allowed", self.stretch_passes),
            ));
        }
        Ok(())
    }
}
