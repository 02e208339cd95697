//! Normals of an unstructured point cloud (a scan), from the principal axes of each point's neighbourhood.
//!
//! Registration needs them twice: the point-to-plane data term slides the template along the scan's surface
//! instead of pinning each vertex to one noisy point, and pairs whose normals disagree (a vertex matched to the
//! other wall of a fold) are rejected. The sign is unknown and not needed: both uses square or take |n·m|.

use crate::registration::kdtree::KdTree;
use crease_core::vec3::{self, V3};

/// Unit normal per point: the eigenvector of the smallest eigenvalue of the covariance of its `k` nearest
/// neighbours (itself included). Degenerate neighbourhoods get the zero vector, which no pair accepts.
pub fn estimate_normals(points: &[V3], tree: &KdTree, k: usize) -> Vec<V3> {
    use rayon::prelude::*;
    points
        .par_iter()
        .map(|&p| {
            let nb = tree.k_nearest(p, k);
            if nb.len() < 3 {
                return [0.0; 3];
            }
            let mut c = [0.0; 3];
            for &(i, _) in &nb {
                c = vec3::add(c, points[i]);
            }
            c = vec3::scale(c, 1.0 / nb.len() as f64);
            let mut cov = [[0.0; 3]; 3];
            for &(i, _) in &nb {
                let d = vec3::sub(points[i], c);
                for (a, row) in cov.iter_mut().enumerate() {
                    for (b, v) in row.iter_mut().enumerate() {
                        *v += d[a] * d[b];
                    }
                }
            }
            smallest_eigenvector(&cov)
        })
        .collect()
}

/// Noise variance of a scan along its surface normal (squared input units): the median over every `stride`-th
/// point of the variance of its `k` nearest neighbours along their smallest principal axis, times k / (k − 3)
/// (a plane fitted to k noisy points absorbs three of their degrees of freedom). Curvature within a
/// neighbourhood adds to it, so it is an upper bound on a curved scan. Registration weighs its
/// regularisation by it (`RegisterParams::noise_floor`): a MAP fit divides the data term by σ².
pub fn noise_variance(points: &[V3], tree: &KdTree, k: usize, stride: usize) -> f64 {
    use rayon::prelude::*;
    let k = k.max(4);
    let mut v: Vec<f64> = (0..points.len())
        .step_by(stride.max(1))
        .collect::<Vec<_>>()
        .par_iter()
        .filter_map(|&i| {
            let nb = tree.k_nearest(points[i], k);
            if nb.len() < 4 {
                return None;
            }
            let mut c = [0.0; 3];
            for &(j, _) in &nb {
                c = vec3::add(c, points[j]);
            }
            c = vec3::scale(c, 1.0 / nb.len() as f64);
            let mut cov = [[0.0; 3]; 3];
            for &(j, _) in &nb {
                let d = vec3::sub(points[j], c);
                for (a, row) in cov.iter_mut().enumerate() {
                    for (b, x) in row.iter_mut().enumerate() {
                        *x += d[a] * d[b];
                    }
                }
            }
            let n = smallest_eigenvector(&cov);
            if n == [0.0; 3] {
                return None;
            }
            let along = vec3::dot(n, vec3::mat_vec(&cov, n));
            Some(along / (nb.len() - 3) as f64)
        })
        .collect();
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    v.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    v[mid]
}

/// Smallest-eigenvalue eigenvector of a symmetric positive semi-definite 3 × 3 matrix: inverse power iteration
/// on a shifted copy would need a solve; instead the largest eigenvector of (tr·I − C), whose top eigenvalue is
/// C's smallest, by power iteration from the axis least covered by the data.
fn smallest_eigenvector(cov: &[[f64; 3]; 3]) -> V3 {
    let tr = cov[0][0] + cov[1][1] + cov[2][2];
    if !(tr.is_finite() && tr > 0.0) {
        return [0.0; 3];
    }
    let m = [
        [tr - cov[0][0], -cov[0][1], -cov[0][2]],
        [-cov[1][0], tr - cov[1][1], -cov[1][2]],
        [-cov[2][0], -cov[2][1], tr - cov[2][2]],
    ];
    let axis = (0..3)
        .min_by(|&a, &b| cov[a][a].total_cmp(&cov[b][b]))
        .unwrap_or(0);
    let mut v = [0.0; 3];
    v[axis] = 1.0;
    // Start slightly off-axis so an eigenvector orthogonal to the start is still found.
    v = vec3::normalize(vec3::add(v, [0.01, 0.02, 0.03]));
    for _ in 0..50 {
        let w = vec3::mat_vec(&m, v);
        let n = vec3::norm(w);
        if n <= 0.0 {
            return [0.0; 3];
        }
        v = vec3::scale(w, 1.0 / n);
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normals_of_a_noisy_plane_point_along_its_axis() {
        let mut rng = crate::nn::seed::Rng::new(4);
        let pts: Vec<V3> = (0..400)
            .map(|_| [rng.uniform(), rng.uniform(), 0.002 * (rng.uniform() - 0.5)])
            .collect();
        let tree = KdTree::new(&pts);
        let n = estimate_normals(&pts, &tree, 10);
        let worst = n.iter().map(|m| m[2].abs()).fold(1.0f64, f64::min);
        assert!(worst > 0.95, "normal off the plane's axis: |n_z| = {worst}");
    }

    #[test]
    fn k_nearest_agrees_with_brute_force() {
        let mut rng = crate::nn::seed::Rng::new(9);
        let pts: Vec<V3> = (0..300)
            .map(|_| [rng.uniform(), rng.uniform(), rng.uniform()])
            .collect();
        let tree = KdTree::new(&pts);
        let q = [0.4, 0.5, 0.6];
        let got: Vec<usize> = tree.k_nearest(q, 7).iter().map(|e| e.0).collect();
        let mut all: Vec<(f64, usize)> = pts
            .iter()
            .enumerate()
            .map(|(i, p)| (vec3::norm(vec3::sub(*p, q)), i))
            .collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0));
        let want: Vec<usize> = all[..7].iter().map(|e| e.1).collect();
        assert_eq!(got, want);
    }
}
