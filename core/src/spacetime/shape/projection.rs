//! Shape projection: the deformation's displacement loses its long wavelengths.
//!
//! The rotation field is known only as far as the anchors say where folds are; integrated over the surface,
//! its errors move the garment (a rim that flaps, a side that swells), and the positioning's shape screen
//! ([`crate::spacetime::position`]) holds long wavelengths back only gently: its roll-off 1 / (1 + (ℓ/ℓ_c)²)
//! keeps a fifth of a displacement twice the cutoff long, and an open rim is held only by its own side of the
//! surface. So, after the stretch passes, the positioned displacement d = x − c gives up its low-pass:
//!
//! ```text
//!   x ← x − s · H(x − c)
//! ```
//!
//! with H crease's own low-pass ([`crate::heat`]) at the shape scale (a multiple of the detail scale, see
//! [`super::relief`]), and s the fraction removed. Folds, a detail scale or so wide, pass H's complement almost
//! whole; the garment's pose and outline are the captured ones.
//!
//! Linear, the same arithmetic wherever a frame is positioned (cluster and single machine stay byte-identical),
//! invariant to rigid motions (H acts on each coordinate with weights that depend on the captured frame's
//! shape only), and a frame the positioning left in place is not touched.

use crate::heat::{Series, SurfaceOperator};
use crate::vec3::{self, V3};

/// Most of the low-pass a projection may remove: all of it.
pub const MAX_SHAPE_PROJECTION: f64 = 1.0;

/// Default fraction removed.
pub const DEFAULT_SHAPE_PROJECTION: f64 = 1.0;

/// `out` with `fraction` of the low-pass `low` (of `op`, the captured frame's operator) of its displacement
/// from `rest` removed. Returns `out` unchanged when `fraction` is 0 or nothing moved.
pub fn project(
    op: &SurfaceOperator,
    low: &Series,
    rest: &[V3],
    out: &[V3],
    fraction: f64,
) -> Vec<V3> {
    if fraction <= 0.0 || out == rest {
        return out.to_vec();
    }
    let d: Vec<V3> = out
        .iter()
        .zip(rest)
        .map(|(o, c)| vec3::sub(*o, *c))
        .collect();
    let smooth = op.apply(low, &d);
    out.iter()
        .zip(&smooth)
        .map(|(o, l)| vec3::sub(*o, vec3::scale(*l, fraction)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::heat::{low_pass, tests::waved_grid};

    /// A uniform swell of the whole sheet (a displacement of the garment, not a fold) is taken back; a ripple
    /// a few edges wide on top of it stays.
    #[test]
    fn drift_goes_and_folds_stay() {
        let (topo, rest) = waved_grid(60, 40, 6.0, 0.0);
        let ripple = |x: f64| 0.2 * (2.0 * std::f64::consts::PI * x / 4.0).sin();
        let out: Vec<V3> = rest
            .iter()
            .map(|q| [q[0], q[1], 0.5 + ripple(q[0])])
            .collect();
        let op = SurfaceOperator::new(&topo, &rest);
        let got = project(&op, &low_pass(&op, 10.0), &rest, &out, 1.0);
        for v in 0..rest.len() {
            let (x, y) = (rest[v][0], rest[v][1]);
            if (15.0..45.0).contains(&x) && (8.0..25.0).contains(&y) {
                // The swell (0.5) is gone to a few percent; the ripple keeps most of itself.
                let base = got[v][2] - ripple(x);
                assert!(base.abs() < 0.03, "vertex {v}: swell left {base}");
                if ripple(x).abs() > 0.19 {
                    let kept = got[v][2] / ripple(x);
                    assert!(kept > 0.8 && kept < 1.1, "vertex {v}: ripple kept {kept}");
                }
            }
        }
        assert_eq!(project(&op, &low_pass(&op, 10.0), &rest, &rest, 1.0), rest);
    }
}
