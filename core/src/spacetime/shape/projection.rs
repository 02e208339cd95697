//! Shape projection: the deformation's displacement loses the part the capture would have seen.
//!
//! The capture low-passed the cloth (the filter C that made the public data's `captured/`,
//! [`TaubinFilter::capture`]): whatever it kept, the captured surface already has, and whatever a fold adds
//! must lie in the band C removed. The shape screen of the positioning ([`crate::spacetime::position`]) holds long
//! wavelengths back, but its roll-off 1 / (1 + (ℓ/ℓ_c)²) is gentle (a displacement twice the cutoff long keeps
//! a fifth of itself), and an open rim is held only by its own side of the surface: on the public sleeve the
//! cuffs flap by up to 0.7 edge lengths of low-frequency displacement, mostly along the surface normal, while
//! the real cloth's rims move by 0.05 (bench/results/2026-12-02-shape-projection.md). The capture filter's own
//! transfer is far sharper (it keeps 84% of an 8-edge wave and all of a 10-edge one, 2% of a 4-edge one).
//!
//! So, after the stretch passes and before the fold restoration, the positioned displacement d = x − c is
//! replaced by d − s · C(d):
//!
//! ```text
//!   x ← x − s · C(x − c)
//! ```
//!
//! With s = 1 the displacement keeps exactly the band the capture removed: its drift C(d − C d) = C(I − C) d is
//! what the same band-pass gives the real folds (the ground truth's drift is C(I − C) applied to the true
//! surface), at most a quarter of d's mid-band content and none of its long-wavelength part. Folds a few edges
//! wide, which the capture erased (T ≈ 0), are untouched; the garment's shape, the rims included (C smooths a
//! rim along itself, as the capture did), is the captured one. The restoration that follows adds back in place
//! only what the capture filter damped ([`super::restore`]), so it does not undo this.
//!
//! It is linear, the same arithmetic wherever a frame is positioned (cluster and single machine stay
//! byte-identical), invariant to rigid motions of the input (C acts on each coordinate with weights that
//! depend on connectivity only), and a frame the positioning left in place is not touched.

use crate::shape::TaubinFilter;
use crate::vec3::{self, V3};
use serde::{Deserialize, Serialize};

/// Most of the capture band a projection may remove: all of it.
pub const MAX_SHAPE_PROJECTION: f64 = 1.0;

/// Default fraction removed (docs/fidelity.md).
pub const DEFAULT_SHAPE_PROJECTION: f64 = 1.0;

/// Where the projection sits relative to the last stretch pass (bench/results/2026-12-03-rest-length-stretch.md). The projection re-stretches triangles the passes had relaxed (it is linear in the
/// displacement and knows nothing of triangle shapes), so the order trades stretch against drift.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ProjectionOrder {
    /// After the last pass only (default): the drift is what the projection leaves, the stretch what it makes.
    #[default]
    Last,
    /// Before and after the last pass (project, pass, project): the pass relaxes the projected shape, the
    /// second projection removes the drift the pass brought back.
    Around,
    /// The last pass's shape screen pulls toward the projected shape instead of the captured one, then the
    /// projection: the pass may not move the band the projection guards.
    ScreenToProjected,
}

impl std::str::FromStr for ProjectionOrder {
    type Err = crate::Error;
    fn from_str(s: &str) -> crate::Result<Self> {
        match s {
            "last" => Ok(ProjectionOrder::Last),
            "around" => Ok(ProjectionOrder::Around),
            "screen-to-projected" => Ok(ProjectionOrder::ScreenToProjected),
            _ => Err(crate::Error::param(
                "projection_order",
                format!("`{s}` is not one of: last, around, screen-to-projected"),
            )),
        }
    }
}

/// `out` minus `fraction` times the capture filter's low-pass of its displacement from `rest`. Returns `out`
/// unchanged (bit for bit) when `fraction` is 0 or `out` equals `rest`.
pub fn project(filter: &TaubinFilter, rest: &[V3], out: &[V3], fraction: f64) -> Vec<V3> {
    if fraction <= 0.0 || out == rest {
        return out.to_vec();
    }
    let d: Vec<V3> = out
        .iter()
        .zip(rest)
        .map(|(o, c)| vec3::sub(*o, *c))
        .collect();
    let low = filter.apply(&d);
    out.iter()
        .zip(&low)
        .map(|(o, l)| vec3::sub(*o, vec3::scale(*l, fraction)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape::{mean_edge_length, ShapeAccumulator};
    use crate::synth;

    /// A displacement made of a wide bulge (what the capture would have seen) and a narrow ripple (a fold the
    /// capture erased): the projection removes the bulge and keeps the ripple, so the drift falls to a
    /// fraction of the ripple's own.
    #[test]
    fn removes_the_captured_band_and_keeps_narrow_folds() {
        let (topo, p) = synth::sheet(61, 61, 0.01).unwrap();
        let filter = TaubinFilter::capture(&topo);
        let h = mean_edge_length(&topo, &p);
        let two_pi = 2.0 * std::f64::consts::PI;
        // Bulge: half a wave over the whole sheet (60 edges), 2 edges high. Ripple: 4 edges, 0.5 edge high.
        let bulge = |q: &V3| 2.0 * h * (std::f64::consts::PI * q[0] / 0.6).sin();
        let ripple = |q: &V3| 0.5 * h * (two_pi * q[0] / 0.04).sin();
        let out: Vec<V3> = p
            .iter()
            .map(|q| [q[0], q[1], q[2] + bulge(q) + ripple(q)])
            .collect();
        let got = project(&filter, &p, &out, 1.0);
        let drift = |o: &[V3]| {
            let mut acc = ShapeAccumulator::default();
            acc.add_frame(&topo, &TaubinFilter::captured(&topo), &p, o);
            acc.stats()
        };
        let (before, after) = (drift(&out), drift(&got));
        assert!(before.drift_max > 1.5, "{before:?}");
        assert!(after.drift_max < 0.1, "{after:?}");
        // Away from the rim the ripple is kept (the capture keeps about 2% of a 4-edge wave: so does C(d)).
        let mut checked = 0;
        for (v, q) in p.iter().enumerate() {
            let interior = (0.15..0.45).contains(&q[0]) && (0.15..0.45).contains(&q[1]);
            if interior && ripple(q).abs() > 0.4 * h {
                let kept = (got[v][2] - p[v][2]) / ripple(q);
                assert!((0.9..1.1).contains(&kept), "vertex {v}: kept {kept}");
                checked += 1;
            }
        }
        assert!(checked > 50, "{checked}");
        // A partial projection removes that fraction of the band, linearly.
        let half = project(&filter, &p, &out, 0.5);
        for v in 0..p.len() {
            let mid = vec3::scale(vec3::add(out[v], got[v]), 0.5);
            assert!(vec3::norm(vec3::sub(half[v], mid)) < 1e-12);
        }
    }

    #[test]
    fn nothing_moved_or_nothing_asked_gives_the_input_back() {
        let (topo, p) = synth::sheet(9, 9, 0.1).unwrap();
        let filter = TaubinFilter::capture(&topo);
        assert_eq!(project(&filter, &p, &p, 1.0), p);
        let out: Vec<V3> = p.iter().map(|q| [q[0], q[1], q[2] + q[0]]).collect();
        assert_eq!(project(&filter, &p, &out, 0.0), out);
    }

    /// The fraction is validated (naming the field) and read from a job spec's `[deform]` table; it is off
    /// with the shape screen off (the paper's unconstrained system).
    #[test]
    fn the_fraction_is_validated_read_and_tied_to_the_screen() {
        use crate::spacetime::DeformParams;
        for bad in [-0.1, 1.5, f64::NAN, f64::INFINITY] {
            let params = DeformParams {
                shape_projection: bad,
                ..DeformParams::default()
            };
            let err = params.validate().unwrap_err().to_string();
            assert!(err.contains("shape_projection"), "{bad}: {err}");
        }
        let d = DeformParams::default();
        assert_eq!(d.restoration().projection, DEFAULT_SHAPE_PROJECTION);
        let p: DeformParams = serde_json::from_str(r#"{"shape_projection": 0.25}"#).unwrap();
        assert_eq!(p.shape_projection, 0.25);
        assert_eq!(p.restoration().projection, 0.25);
        assert_eq!(d.projection_order, ProjectionOrder::Last);
        let p: DeformParams =
            serde_json::from_str(r#"{"projection_order": "screen-to-projected"}"#).unwrap();
        assert_eq!(p.restoration().order, ProjectionOrder::ScreenToProjected);
        let err = "sideways"
            .parse::<ProjectionOrder>()
            .unwrap_err()
            .to_string();
        assert!(err.contains("projection_order"), "{err}");
        assert_eq!(
            "around".parse::<ProjectionOrder>().unwrap(),
            ProjectionOrder::Around
        );
        let unscreened = DeformParams {
            shape_cutoff: 0.0,
            ..DeformParams::default()
        };
        assert_eq!(unscreened.restoration().projection, 0.0);
    }
}
