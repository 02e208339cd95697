//! Rotations as rotation vectors: the exponential and logarithm maps of SO(3) (Rodrigues), and the rotation
//! taking one direction to another.
//!
//! Alexa's linear combination of transformations (Alexa 2002) blends rotations as exp(Σ w_a log R_a); with the
//! identity's logarithm being zero, the blended rotation of a triangle is exp of the weighted sum of the anchors'
//! rotation vectors, which is what [`crate::spacetime::blend`] evaluates.

use crate::vec3::{self, M3, V3};

/// exp: rotation vector (axis · angle) → rotation matrix (Rodrigues' formula, with a Taylor expansion near
/// zero so that tiny blended rotations stay accurate).
pub fn exp(phi: V3) -> M3 {
    let th2 = vec3::dot(phi, phi);
    let th = th2.sqrt();
    let (a, b) = if th < 1e-4 {
        // sin θ/θ and (1-cos θ)/θ² to fourth order.
        (
            1.0 - th2 / 6.0 + th2 * th2 / 120.0,
            0.5 - th2 / 24.0 + th2 * th2 / 720.0,
        )
    } else {
        (th.sin() / th, (1.0 - th.cos()) / th2)
    };
    let [x, y, z] = phi;
    // R = I + a K + b K², K the cross-product matrix of phi.
    [
        [
            1.0 - b * (y * y + z * z),
            -a * z + b * x * y,
            a * y + b * x * z,
        ],
        [
            a * z + b * x * y,
            1.0 - b * (x * x + z * z),
            -a * x + b * y * z,
        ],
        [
            -a * y + b * x * z,
            a * x + b * y * z,
            1.0 - b * (x * x + y * y),
        ],
    ]
}

/// log: rotation matrix → principal rotation vector (angle in [0, π]).
pub fn log(r: &M3) -> V3 {
    let tr = r[0][0] + r[1][1] + r[2][2];
    let cos = ((tr - 1.0) * 0.5).clamp(-1.0, 1.0);
    let w = [r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]]; // 2 sin θ · axis
    let sin2 = vec3::norm(w); // 2 sin θ
    let th = (0.5 * sin2).atan2(cos);
    if th < 1e-6 {
        return vec3::scale(w, 0.5 * (1.0 + th * th / 6.0));
    }
    if th < std::f64::consts::PI - 1e-4 {
        return vec3::scale(w, th / sin2);
    }
    // Near π the antisymmetric part vanishes; read the axis from the symmetric part R + I = 2 a aᵀ (θ = π).
    let mut best = 0;
    for k in 1..3 {
        if r[k][k] > r[best][best] {
            best = k;
        }
    }
    let mut axis = [0.0; 3];
    for (k, a) in axis.iter_mut().enumerate() {
        *a = if k == best {
            ((r[best][best] + 1.0) * 0.5).max(0.0).sqrt()
        } else {
            (r[k][best] + r[best][k]) * 0.25 / ((r[best][best] + 1.0) * 0.5).max(1e-300).sqrt()
        };
    }
    let axis = vec3::normalize(axis);
    // Pick the sign consistent with the (small) antisymmetric part.
    let axis = if vec3::dot(axis, w) < 0.0 {
        vec3::scale(axis, -1.0)
    } else {
        axis
    };
    vec3::scale(axis, th)
}

/// Rotation vector of the smallest rotation taking unit direction `from` to unit direction `to`: axis
/// `from × to`, angle `acos(from · to)` (computed with atan2 for accuracy at small and large angles). This is the
/// per-triangle update of the stretch-reduction step (Popa et al. 2009 §5.5).
pub fn rotation_between(from: V3, to: V3) -> V3 {
    let c = vec3::cross(from, to);
    let s = vec3::norm(c);
    let d = vec3::dot(from, to);
    let th = s.atan2(d);
    if s > 1e-12 {
        return vec3::scale(c, th / s);
    }
    if d > 0.0 {
        return [0.0; 3];
    }
    // Opposite directions: any axis perpendicular to `from` gives a rotation by π.
    let helper = if from[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    vec3::scale(
        vec3::normalize(vec3::cross(from, helper)),
        std::f64::consts::PI,
    )
}

/// Unit quaternion [w, x, y, z] (w ≥ 0 not guaranteed) of a rotation matrix, by Shepperd's method: the
/// square root is taken of the largest of 1 + trace and 1 + 2 R_kk − trace, so no division is by a small
/// number and the result is accurate to rounding for every rotation, including half turns.
pub fn to_quaternion(r: &M3) -> [f64; 4] {
    let (m00, m11, m22) = (r[0][0], r[1][1], r[2][2]);
    let tr = m00 + m11 + m22;
    if tr >= m00 && tr >= m11 && tr >= m22 {
        let w = 0.5 * (1.0 + tr).sqrt();
        let s = 0.25 / w;
        [
            w,
            (r[2][1] - r[1][2]) * s,
            (r[0][2] - r[2][0]) * s,
            (r[1][0] - r[0][1]) * s,
        ]
    } else if m00 >= m11 && m00 >= m22 {
        let x = 0.5 * (1.0 + m00 - m11 - m22).sqrt();
        let s = 0.25 / x;
        [
            (r[2][1] - r[1][2]) * s,
            x,
            (r[0][1] + r[1][0]) * s,
            (r[0][2] + r[2][0]) * s,
        ]
    } else if m11 >= m22 {
        let y = 0.5 * (1.0 - m00 + m11 - m22).sqrt();
        let s = 0.25 / y;
        [
            (r[0][2] - r[2][0]) * s,
            (r[0][1] + r[1][0]) * s,
            y,
            (r[1][2] + r[2][1]) * s,
        ]
    } else {
        let z = 0.5 * (1.0 - m00 - m11 + m22).sqrt();
        let s = 0.25 / z;
        [
            (r[1][0] - r[0][1]) * s,
            (r[0][2] + r[2][0]) * s,
            (r[1][2] + r[2][1]) * s,
            z,
        ]
    }
}

/// Rotation matrix of a unit quaternion [w, x, y, z].
pub fn from_quaternion(q: [f64; 4]) -> M3 {
    let [w, x, y, z] = q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// Geodesic angle between two rotations, |log(Aᵀ B)|.
pub fn angle_between(a: &M3, b: &M3) -> f64 {
    vec3::norm(log(&vec3::mat_mul(&vec3::transpose(a), b)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: V3, b: V3, tol: f64) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() < tol)
    }

    #[test]
    fn exp_log_roundtrip() {
        let cases = [
            [0.0, 0.0, 0.0],
            [1e-9, -2e-9, 3e-9],
            [1e-5, 0.0, 0.0],
            [0.3, -0.2, 0.9],
            [0.0, 2.0, 0.0],
            [0.0, 0.0, std::f64::consts::PI - 1e-7],
            [1.0, 1.0, 1.0],
        ];
        for phi in cases {
            let r = exp(phi);
            // orthonormal with det 1
            let rtr = vec3::mat_mul(&vec3::transpose(&r), &r);
            for (i, row) in rtr.iter().enumerate() {
                for (j, v) in row.iter().enumerate() {
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((v - want).abs() < 1e-12);
                }
            }
            let back = log(&r);
            assert!(close(back, phi, 1e-6), "{phi:?} -> {back:?}");
        }
    }

    #[test]
    fn quaternions_round_trip_every_branch() {
        // Small angles (trace branch) and half turns about each axis (the three diagonal branches).
        let pi = std::f64::consts::PI;
        for phi in [
            [0.0, 0.0, 0.0],
            [0.3, -0.2, 0.9],
            [pi - 1e-9, 0.0, 0.0],
            [0.0, pi, 0.0],
            [0.1, 0.2, pi - 0.05],
            [-2.0, 1.0, 0.5],
        ] {
            let r = exp(phi);
            let q = to_quaternion(&r);
            let len = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!((len - 1.0).abs() < 1e-14, "{phi:?}: |q| = {len}");
            let back = from_quaternion(q);
            for i in 0..3 {
                for j in 0..3 {
                    assert!((back[i][j] - r[i][j]).abs() < 1e-14, "{phi:?}");
                }
            }
        }
    }

    #[test]
    fn exp_rotates_about_axis() {
        let r = exp([0.0, 0.0, std::f64::consts::FRAC_PI_2]);
        let v = vec3::mat_vec(&r, [1.0, 0.0, 0.0]);
        assert!(close(v, [0.0, 1.0, 0.0], 1e-12));
    }

    #[test]
    fn rotation_between_maps_directions() {
        let pairs = [
            ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
            ([0.0, 0.0, 1.0], vec3::normalize([0.2, -0.3, 0.9])),
            ([1.0, 0.0, 0.0], [1.0, 0.0, 0.0]),
            ([1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]),
        ];
        for (a, b) in pairs {
            let r = exp(rotation_between(a, b));
            assert!(close(vec3::mat_vec(&r, a), b, 1e-12), "{a:?} {b:?}");
        }
    }
}
