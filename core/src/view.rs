//! Where a picture of a garment is taken from: its principal axes, not the world axes.
//!
//! A garment can lie in any orientation in its capture's coordinates; a bounding-box rule ("up along the longest
//! axis") turns a wide hanging sheet on its side and looks at it edge-on. The covariance of the vertex positions
//! says how the garment itself is spread: the camera looks along the axis of least spread (a sheet's normal, a
//! sleeve's cross-section), so the garment faces it. The picture's up is the other principal axis (largest or
//! middle) nearer to the world's +z, the vertical of the data sets (Blender's convention), pointing upwards, so
//! a hanging sheet hangs and a horizontal sleeve lies.

use crate::vec3::{self, M3, V3};

/// Eigenvalues (descending) and unit eigenvectors of a symmetric 3x3 matrix, by cyclic Jacobi rotations.
pub fn symmetric_eigen(m: M3) -> ([f64; 3], [V3; 3]) {
    let mut a = m;
    let mut v = vec3::IDENTITY; // columns are the eigenvectors
    for _ in 0..50 {
        let off = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
        let scale = a[0][0].powi(2) + a[1][1].powi(2) + a[2][2].powi(2);
        if off <= 1e-30 * scale.max(f64::MIN_POSITIVE) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            // Rotation angle that zeroes a[p][q] (Golub & Van Loan, symmetric Schur decomposition).
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = c * row_p[k] - s * row_q[k];
                a[q][k] = s * row_p[k] + c * row_q[k];
            }
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| a[j][j].total_cmp(&a[i][i]));
    let values = order.map(|i| a[i][i]);
    let vectors = order.map(|i| vec3::normalize([v[0][i], v[1][i], v[2][i]]));
    (values, vectors)
}

/// Principal axes of a point set: spreads (variances, descending) and unit axes.
pub fn principal_axes(points: &[V3]) -> ([f64; 3], [V3; 3]) {
    let n = points.len().max(1) as f64;
    let mut mean = [0.0; 3];
    for p in points {
        mean = vec3::add(mean, *p);
    }
    let mean = vec3::scale(mean, 1.0 / n);
    let mut c = [[0.0; 3]; 3];
    for p in points {
        let d = vec3::sub(*p, mean);
        for i in 0..3 {
            for j in 0..3 {
                c[i][j] += d[i] * d[j] / n;
            }
        }
    }
    symmetric_eigen(c)
}

/// A viewing direction (from the camera into the scene) and an up vector for pictures of `points`: along the
/// axis of least spread, from the side `focus` faces when given (the folds' mean normal: look at them, not at
/// their back), slightly from above.
pub fn view_for(points: &[V3], focus: Option<V3>) -> (V3, V3) {
    let (_, axes) = principal_axes(points);
    let [a0, a1, normal] = axes;
    // Up: the in-plane axis nearer the vertical, pointing up (for a vertical tie, the larger spread wins).
    let mut up = if a1[2].abs() > a0[2].abs() + 1e-9 {
        a1
    } else {
        a0
    };
    if up[2] < 0.0 || (up[2] == 0.0 && up.iter().sum::<f64>() < 0.0) {
        up = vec3::scale(up, -1.0);
    }
    // Look against the folds' normal; without folds, from the side of the normal facing −y (the data sets'
    // front), else whichever.
    let side = match focus {
        Some(f) if vec3::dot(f, normal).abs() > 1e-6 => vec3::dot(f, normal).signum(),
        _ => {
            if normal[1] > 0.0 {
                1.0
            } else {
                -1.0
            }
        }
    };
    let dir = vec3::scale(normal, -side);
    let dir = vec3::normalize(vec3::sub(dir, vec3::scale(up, 0.3)));
    (dir, up)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigen_of_a_rotated_diagonal_matrix() {
        let r = crate::spacetime::blend::so3::exp([0.3, -0.8, 0.5]);
        let d = [[5.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 0.5]];
        let m = vec3::mat_mul(&vec3::mat_mul(&r, &d), &vec3::transpose(&r));
        let (vals, vecs) = symmetric_eigen(m);
        for (got, want) in vals.iter().zip([5.0, 2.0, 0.5]) {
            assert!((got - want).abs() < 1e-12, "{vals:?}");
        }
        for (k, v) in vecs.iter().enumerate() {
            let col = [r[0][k], r[1][k], r[2][k]];
            assert!((vec3::dot(*v, col).abs() - 1.0).abs() < 1e-12);
        }
    }

    /// A flat sheet is seen face-on whatever plane it lies in, with its vertical in-plane axis up.
    #[test]
    fn flat_sheets_face_the_camera() {
        let (_, p) = crate::synth::sheet(41, 33, 0.025).unwrap(); // 1.0 x 0.8 in the x–y plane
                                                                  // Lying on the floor (normal z): looked at from above.
        let (dir, up) = view_for(&p, None);
        assert!(dir[2].abs() > 0.9, "floor sheet seen along {dir:?}");
        assert!(
            up[2].abs() < 1e-9 && (up[0].abs() - 1.0).abs() < 1e-9,
            "{up:?}"
        );
        // Hanging like the drape (x–z plane, wider than tall): seen along y, up is +z, the wide side across.
        let hanging: Vec<V3> = p.iter().map(|q| [q[0], 0.0, -q[1]]).collect();
        let (dir, up) = view_for(&hanging, None);
        assert!(dir[1].abs() > 0.9, "hanging sheet seen along {dir:?}");
        assert!(up[2] > 0.999, "{up:?}");
        // Tilted and yawed: still face-on (the camera axis is within 20° of the sheet's normal).
        let r = crate::spacetime::blend::so3::exp([0.2, 0.1, 0.6]);
        let turned: Vec<V3> = hanging.iter().map(|q| vec3::mat_vec(&r, *q)).collect();
        let normal = vec3::mat_vec(&r, [0.0, 1.0, 0.0]);
        let (dir, _) = view_for(&turned, None);
        assert!(
            vec3::dot(dir, normal).abs() > 20f64.to_radians().cos(),
            "{dir:?}"
        );
        // The folds' side decides which face is shown.
        let (d1, _) = view_for(&hanging, Some([0.0, -1.0, 0.0]));
        let (d2, _) = view_for(&hanging, Some([0.0, 1.0, 0.0]));
        assert!(d1[1] > 0.9 && d2[1] < -0.9, "{d1:?} {d2:?}");
    }
}
