//! Stretch reduction (Popa et al. 2009 §5.5).
//!
//! Blended rotations are not the gradient of any surface, so the positioned triangles are a least-squares
//! compromise and some of them stretch. A pass replaces each triangle's rotation by one read off the surface it
//! got, and positions again with the frame's factor:
//!
//! - [`StretchRotation::Normal`] (the paper): the rotation taking the original normal to the new one. It keeps
//!   the orientation the folds took but drops any in-plane turn, so a triangle that turned within its plane is
//!   sheared by the next solve.
//! - [`StretchRotation::Polar`]: the rotation closest to the triangle's whole deformation gradient (its polar
//!   factor: the new normal and the in-plane turn). This is the local step of as-rigid-as-possible modelling
//!   (Sorkine & Alexa 2007) on the positioning's energy, so every pass lowers Σ A ‖F − R‖² (plus the shape
//!   screen), which is the area-weighted stretch itself.
//! - [`StretchRotation::Anchored`] (default): the geodesic midpoint between the polar rotation and the blended
//!   rotation the folds asked for. Plain polar passes forget the anchors: the captured surface (d = 0) is a
//!   fixed point of zero stretch, so every pass trades fold amplitude for stretch and the folds fade. This is
//!   the alternating minimisation of Σ A (‖F − R‖² + ‖R − B‖²) with B the blend: the passes still lower the
//!   stretch, but the folds stay pinned to what the anchors asked for (docs/fidelity.md).

use crate::spacetime::position::FramePositioner;
use crate::spacetime::blend::so3;
use crate::mesh::{geometry, Frame};
use crate::vec3::{self, M3, V3};
use serde::{Deserialize, Serialize};

/// Which rotation a stretch-reduction pass gives each triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StretchRotation {
    /// Original normal to current normal (Popa et al. 2009 §5.5).
    Normal,
    /// Closest rotation to the current deformation gradient (as-rigid-as-possible local step).
    Polar,
    /// Halfway (on SO(3)) between the polar rotation and the blended rotation: stretch reduction that keeps
    /// the folds.
    #[default]
    Anchored,
}

impl std::str::FromStr for StretchRotation {
    type Err = crate::Error;
    fn from_str(s: &str) -> crate::Result<Self> {
        match s {
            "normal" => Ok(StretchRotation::Normal),
            "polar" => Ok(StretchRotation::Polar),
            "anchored" => Ok(StretchRotation::Anchored),
            _ => Err(crate::Error::param(
                "stretch_rotation",
                format!("`{s}` is not one of: normal, polar, anchored"),
            )),
        }
    }
}

/// For each triangle, the rotation taking its original normal to its normal in `current` (identity for a
/// triangle that collapsed to zero area, which has no normal to follow).
pub fn normal_rotations(fp: &FramePositioner, current: &[V3]) -> Vec<M3> {
    let n_new = geometry::triangle_normals(fp.topology(), current);
    fp.rest_normals()
        .iter()
        .zip(&n_new)
        .map(|(n0, n1)| {
            if vec3::norm(*n1) == 0.0 {
                vec3::IDENTITY
            } else {
                so3::exp(so3::rotation_between(*n0, *n1))
            }
        })
        .collect()
}

/// For each triangle, the rotation closest to its deformation gradient from the original frame to `current`
/// (identity for a collapsed triangle).
pub fn polar_rotations(fp: &FramePositioner, current: &[V3]) -> Vec<M3> {
    let rest = fp.rest();
    fp.topology()
        .triangles()
        .iter()
        .zip(fp.rest_normals())
        .map(|(tri, &n0)| {
            let [r0, r1, r2] = tri.map(|i| rest[i as usize]);
            let [o0, o1, o2] = tri.map(|i| current[i as usize]);
            closest_rotation([r0, r1, r2], n0, [o0, o1, o2]).unwrap_or(vec3::IDENTITY)
        })
        .collect()
}

/// For each triangle, the midpoint on SO(3) of its polar rotation `P` in `current` and its blended rotation
/// `B`: `P · exp(½ log(Pᵀ B))`. For rotations this is the minimiser of ‖P − R‖² + ‖R − B‖² (the geodesic
/// mean), so a pass pulls each triangle halfway back to what the folds asked for instead of letting the
/// surface it got erase them.
pub fn anchored_rotations(fp: &FramePositioner, current: &[V3], blended: &[M3]) -> Vec<M3> {
    polar_rotations(fp, current)
        .iter()
        .zip(blended)
        .map(|(p, b)| midpoint(p, b))
        .collect()
}

/// The geodesic midpoint of two rotations, P · exp(½ log(Pᵀ B)), evaluated with unit quaternions: for
/// q_P · q_B ≥ 0 (the shorter arc, which is the principal logarithm's) the half-way rotation is
/// (q_P + q_B) / |q_P + q_B|, the same rotation up to rounding without the log/exp pair's trigonometry.
fn midpoint(p: &M3, b: &M3) -> M3 {
    let qp = so3::to_quaternion(p);
    let mut qb = so3::to_quaternion(b);
    if qp.iter().zip(&qb).map(|(a, c)| a * c).sum::<f64>() < 0.0 {
        qb = qb.map(|v| -v);
    }
    // |q_P + q_B|² = 2 + 2 |q_P · q_B| ≥ 2: never small.
    let sum: [f64; 4] = std::array::from_fn(|k| qp[k] + qb[k]);
    let inv = 1.0 / sum.iter().map(|v| v * v).sum::<f64>().sqrt();
    so3::from_quaternion(sum.map(|v| v * inv))
}

/// The rotation nearest (Frobenius) to the map taking triangle `r` (unit normal `n0`) to triangle `o`, with the
/// normal taken to the new normal; None when `o` is degenerate.
fn closest_rotation(r: [V3; 3], n0: V3, o: [V3; 3]) -> Option<M3> {
    let e1 = vec3::sub(r[1], r[0]);
    let e2 = vec3::sub(r[2], r[0]);
    let l1 = vec3::norm(e1);
    let u = vec3::scale(e1, 1.0 / l1);
    let v = vec3::cross(n0, u);
    let (a, b) = (vec3::dot(e2, u), vec3::dot(e2, v));
    // Images of the rest frame's in-plane axes u, v under the triangle's affine map.
    let j1 = vec3::scale(vec3::sub(o[1], o[0]), 1.0 / l1);
    let j2 = vec3::scale(
        vec3::sub(vec3::sub(o[2], o[0]), vec3::scale(j1, a)),
        1.0 / b,
    );
    let n1 = vec3::cross(j1, j2);
    let (ln, lj) = (vec3::norm(n1), vec3::norm(j1));
    if !(ln > 0.0 && lj > 0.0 && ln.is_finite()) {
        return None;
    }
    let n1 = vec3::scale(n1, 1.0 / ln);
    let p = vec3::scale(j1, 1.0 / lj);
    let q = vec3::cross(n1, p);
    // The 2x2 in-plane part in the new plane's frame (p, q) and its closest rotation angle.
    let (g00, g01) = (vec3::dot(p, j1), vec3::dot(p, j2));
    let (g10, g11) = (vec3::dot(q, j1), vec3::dot(q, j2));
    // The angle φ = atan2(g10 − g01, g00 + g11), needed only as its cosine and sine.
    let (x, y) = (g00 + g11, g10 - g01);
    let h = (x * x + y * y).sqrt();
    let (c, s) = if h > 0.0 { (x / h, y / h) } else { (1.0, 0.0) };
    let u1 = vec3::add(vec3::scale(p, c), vec3::scale(q, s));
    let v1 = vec3::sub(vec3::scale(q, c), vec3::scale(p, s));
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = u1[i] * u[j] + v1[i] * v[j] + n1[i] * n0[j];
        }
    }
    Some(m)
}

/// One stretch-reduction pass on `current`, reusing the frame's factorisation; `blended` are the rotations
/// the first positioning was given (read by [`StretchRotation::Anchored`] only).
pub fn pass(fp: &FramePositioner, current: &[V3], kind: StretchRotation, blended: &[M3]) -> Frame {
    fp.solve(&pass_rotations(fp, current, kind, blended))
}

fn pass_rotations(
    fp: &FramePositioner,
    current: &[V3],
    kind: StretchRotation,
    blended: &[M3],
) -> Vec<M3> {
    match kind {
        StretchRotation::Normal => normal_rotations(fp, current),
        StretchRotation::Polar => polar_rotations(fp, current),
        StretchRotation::Anchored => anchored_rotations(fp, current, blended),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_rotation_recovers_a_rigid_motion_and_ignores_stretch() {
        let r = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.3, 0.8, 0.0]];
        let n0 = [0.0, 0.0, 1.0];
        let q = so3::exp([0.4, -0.9, 1.7]);
        let moved = r.map(|p| vec3::add(vec3::mat_vec(&q, p), [5.0, 1.0, -2.0]));
        let got = closest_rotation(r, n0, moved).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                assert!((got[i][j] - q[i][j]).abs() < 1e-12, "{got:?} vs {q:?}");
            }
        }
        // Stretching along the rest x axis before the rotation changes nothing: the polar factor is q.
        let stretched = r.map(|p| vec3::mat_vec(&q, [1.3 * p[0], p[1], p[2]]));
        let got = closest_rotation(r, n0, stretched).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                assert!((got[i][j] - q[i][j]).abs() < 1e-12);
            }
        }
        // A collapsed triangle has no rotation.
        assert!(closest_rotation(r, n0, [[0.0; 3]; 3]).is_none());
    }

    /// The quaternion midpoint is the log/exp formula's rotation to rounding, also close to a half turn.
    #[test]
    fn midpoint_matches_the_log_exp_formula() {
        let reference = |p: &M3, b: &M3| {
            let rel = so3::log(&vec3::mat_mul(&vec3::transpose(p), b));
            vec3::mat_mul(p, &so3::exp(vec3::scale(rel, 0.5)))
        };
        let pi = std::f64::consts::PI;
        let cases = [
            ([0.1, 0.7, -0.2], [-0.4, 0.2, 0.9]),
            ([0.0, 0.0, 0.0], [1e-9, 0.0, 0.0]),
            ([2.5, -1.0, 0.3], [-2.0, 1.5, 0.1]),
            ([0.0, 0.0, 0.0], [0.0, pi - 1e-3, 0.0]),
            ([pi - 0.1, 0.0, 0.0], [0.0, 0.0, 3.0]),
        ];
        for (a, c) in cases {
            let (p, b) = (so3::exp(a), so3::exp(c));
            let (got, want) = (midpoint(&p, &b), reference(&p, &b));
            for i in 0..3 {
                for j in 0..3 {
                    assert!((got[i][j] - want[i][j]).abs() < 1e-9, "{a:?} {c:?}");
                }
            }
        }
    }

    /// The midpoint lies on the geodesic, at the same angle from both ends, and fixes equal rotations.
    #[test]
    fn midpoint_is_halfway_on_the_geodesic() {
        let p = so3::exp([0.1, 0.7, -0.2]);
        let b = so3::exp([-0.4, 0.2, 0.9]);
        let m = midpoint(&p, &b);
        let (dp, db) = (so3::angle_between(&m, &p), so3::angle_between(&m, &b));
        assert!((dp - db).abs() < 1e-12, "{dp} vs {db}");
        assert!((dp + db - so3::angle_between(&p, &b)).abs() < 1e-12);
        let same = midpoint(&p, &p);
        for i in 0..3 {
            for j in 0..3 {
                assert!((same[i][j] - p[i][j]).abs() < 1e-12);
            }
        }
    }
}
