//! Stretch/shrinkage tensor of one triangle between two frames (Chen 2011 §2.1 and §4.2).
//!
//! The reference triangle is laid out in its own 2D frame, (0,0), (l1,0), (a,b); the affine map to the other
//! frame's triangle has the 3x2 Jacobian J = [S_s, S_t]. Its SVD J = U Σ Vᵀ gives the largest and smallest
//! length ratios Γ ≥ γ; the left singular vectors (columns of U) are the principal directions *on the current
//! triangle*, which is where the fold will be traced. The dominant direction is the one whose absolute change
//! |v| (eq. 4.1: v if v ≥ 1, else 1/v) is larger.
//!
//! Directions are axial (d and −d are the same), and they are compared in a common local frame of the
//! triangle: the angle from its first edge (v0 → v1) in its own plane. Under the small strains between
//! adjacent frames this edge is (nearly) the same material line, so the angle is comparable across frames.

use crate::vec3::{self, V3};

/// The 2D layout (l1, a, b) of a triangle in its own frame: vertices (0,0), (l1,0), (a,b).
pub type Shape = [f64; 3];

/// Lays a triangle out in 2D. Degenerate triangles give `b = 0`, which [`jacobian`] treats as no data.
pub fn shape(p: [V3; 3]) -> Shape {
    let e1 = vec3::sub(p[1], p[0]);
    let e2 = vec3::sub(p[2], p[0]);
    let l1 = vec3::norm(e1);
    if l1 <= 0.0 {
        return [0.0; 3];
    }
    let u = vec3::scale(e1, 1.0 / l1);
    let a = vec3::dot(e2, u);
    let b = vec3::norm(vec3::cross(u, e2));
    [l1, a, b]
}

/// Unit normal and first-edge direction of a triangle: the axes of its local frame.
pub fn local_frame(p: [V3; 3]) -> (V3, V3, V3) {
    let e1 = vec3::normalize(vec3::sub(p[1], p[0]));
    let n = vec3::normalize(vec3::cross(vec3::sub(p[1], p[0]), vec3::sub(p[2], p[0])));
    let e2 = vec3::cross(n, e1);
    (e1, e2, n)
}

/// Angle (radians, in (−π/2, π/2]) of the axial direction `d` in the local frame (e1, e2).
pub fn axial_angle(d: V3, e1: V3, e2: V3) -> f64 {
    let mut a = vec3::dot(d, e2).atan2(vec3::dot(d, e1));
    if a <= -std::f64::consts::FRAC_PI_2 {
        a += std::f64::consts::PI;
    } else if a > std::f64::consts::FRAC_PI_2 {
        a -= std::f64::consts::PI;
    }
    a
}

/// Unoriented angle between two axial directions given as angles, in [0, π/2].
pub fn axial_difference(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::PI);
    d.min(std::f64::consts::PI - d)
}

/// Absolute change of eq. 4.1: v if v ≥ 1, else 1/v (≥ 1; 1 means no change).
#[inline]
pub fn absolute_change(v: f64) -> f64 {
    if v >= 1.0 {
        v
    } else if v > 0.0 {
        1.0 / v
    } else {
        f64::INFINITY
    }
}

/// Principal stretches and directions of one triangle's map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tensor {
    /// Largest singular value Γ.
    pub big: f64,
    /// Smallest singular value γ.
    pub small: f64,
    /// Unit direction of Γ on the current triangle (γ's is `normal × dir_big`).
    pub dir_big: V3,
}

impl Tensor {
    pub const IDENTITY: Tensor = Tensor {
        big: 1.0,
        small: 1.0,
        dir_big: [0.0; 3],
    };

    /// The dominant principal value and its direction (on the current triangle with unit `normal`): the one
    /// with the larger absolute change (§4.2).
    pub fn dominant(&self, normal: V3) -> (f64, V3) {
        if absolute_change(self.big) >= absolute_change(self.small) {
            (self.big, self.dir_big)
        } else {
            (self.small, vec3::cross(normal, self.dir_big))
        }
    }
}

/// Jacobian of the map from the reference layout `s` to the current triangle `q`, its SVD, and the left
/// singular direction of Γ. Returns `None` for degenerate reference or current triangles.
pub fn jacobian(s: Shape, q: [V3; 3]) -> Option<Tensor> {
    let [l1, a, b] = s;
    if l1 <= 0.0 || b <= 1e-12 * l1 {
        return None;
    }
    let f1 = vec3::sub(q[1], q[0]);
    let f2 = vec3::sub(q[2], q[0]);
    // J [l1 a; 0 b] = [f1 f2]  ⇒  j1 = f1 / l1, j2 = (f2 − a j1) / b (the columns S_s, S_t of §2.1).
    let j1 = vec3::scale(f1, 1.0 / l1);
    let j2 = vec3::scale(vec3::sub(f2, vec3::scale(j1, a)), 1.0 / b);
    // JᵀJ = [p q; q r]; its eigenvalues are Γ², γ², its eigenvectors the right singular vectors.
    let (p, qq, r) = (vec3::dot(j1, j1), vec3::dot(j1, j2), vec3::dot(j2, j2));
    let mean = 0.5 * (p + r);
    let disc = (0.25 * (p - r) * (p - r) + qq * qq).sqrt();
    let l_big = mean + disc;
    let l_small = (mean - disc).max(0.0);
    let big = l_big.sqrt();
    if big.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) || !big.is_finite() {
        return None;
    }
    // Right singular vector of Γ: eigenvector of JᵀJ for l_big.
    let v = if p >= r {
        [l_big - r, qq]
    } else {
        [qq, l_big - p]
    };
    let vn = (v[0] * v[0] + v[1] * v[1]).sqrt();
    let v = if vn > 1e-300 {
        [v[0] / vn, v[1] / vn]
    } else {
        [1.0, 0.0]
    };
    // Left singular vector u = J v / Γ.
    let u = vec3::normalize(vec3::add(vec3::scale(j1, v[0]), vec3::scale(j2, v[1])));
    let n = vec3::cross(f1, f2);
    if vec3::norm(n) <= 0.0 {
        return None;
    }
    Some(Tensor {
        big,
        small: l_small.sqrt(),
        dir_big: u,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> [V3; 3] {
        [[0.0, 0.0, 0.0], [1.0, 0.2, 0.0], [0.3, 0.9, 0.0]]
    }

    #[test]
    fn rigid_motion_is_identity() {
        let p = tri();
        // Rotate about z by 40° and translate.
        let (s, c) = 40f64.to_radians().sin_cos();
        let q = p.map(|x| [c * x[0] - s * x[1] + 3.0, s * x[0] + c * x[1] - 1.0, 2.0]);
        let t = jacobian(shape(p), q).unwrap();
        assert!((t.big - 1.0).abs() < 1e-12 && (t.small - 1.0).abs() < 1e-12);
    }

    #[test]
    fn compression_along_x_is_found() {
        let p = tri();
        let q = p.map(|x| [0.8 * x[0], x[1], x[2]]);
        let t = jacobian(shape(p), q).unwrap();
        assert!((t.big - 1.0).abs() < 1e-9, "{t:?}");
        assert!((t.small - 0.8).abs() < 1e-9, "{t:?}");
        let (v, d) = t.dominant([0.0, 0.0, 1.0]);
        assert!((v - 0.8).abs() < 1e-9);
        assert!(d[0].abs() > 0.999, "shrink direction {d:?}");
        // Stretch along y by 1.1 dominates a 0.95 shrink along x (1.1 > 1/0.95).
        let q = p.map(|x| [0.95 * x[0], 1.1 * x[1], x[2]]);
        let t = jacobian(shape(p), q).unwrap();
        let (v, d) = t.dominant([0.0, 0.0, 1.0]);
        assert!((v - 1.1).abs() < 1e-9 && d[1].abs() > 0.999);
    }

    #[test]
    fn axial_angles() {
        let (e1, e2) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert!((axial_angle([-1.0, 0.0, 0.0], e1, e2) - 0.0).abs() < 1e-12);
        let a = axial_angle([0.0, -1.0, 0.0], e1, e2);
        assert!((a - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((axial_difference(0.1, std::f64::consts::PI - 0.1) - 0.2).abs() < 1e-12);
        assert_eq!(absolute_change(0.5), 2.0);
        assert_eq!(absolute_change(1.25), 1.25);
    }
}
