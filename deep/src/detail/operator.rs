//! The averaging operator the detail model and the training captures work with: a random walk over each
//! vertex's one-ring whose weights follow the surface's own geometry (cotangent weights).
//!
//! Why cotangent weights: they approximate the Laplace–Beltrami operator of the surface, so the operator means
//! the same thing on a regular grid, a stretched one or another garment's mesh; a uniform average would treat
//! a long edge like a short one. Negative cotangents (obtuse angles) are clamped to a small positive floor so
//! that every row is a proper average: its eigenvalues then lie in [−1, 1] and Chebyshev polynomials of it
//! stay bounded. Open boundaries need no special case: a boundary vertex averages the neighbours it has.

use crease_core::mesh::Topology;
use crease_core::vec3::{self, V3};

/// Floor of a clamped cotangent weight, relative to the mean weight of its row.
const WEIGHT_FLOOR: f64 = 0.05;

/// P: x ↦ per vertex, the weighted mean of its one-ring (rows of a sparse matrix, weights summing to 1).
#[derive(Debug, Clone)]
pub struct Walk {
    offsets: Vec<u32>,
    cols: Vec<u32>,
    weights: Vec<f64>,
    /// Row sums before normalisation (the "mass" D of D⁻¹W), for operators that need the symmetric form.
    degree: Vec<f64>,
    boundary: Vec<bool>,
}

impl Walk {
    /// The one-ring pattern of `topo` with unit weights (the plain umbrella average).
    pub fn uniform(topo: &Topology) -> Walk {
        Walk::build(topo, |_, _, _| 1.0)
    }

    /// Cotangent weights of the surface `p`: w_ij = ½ (cot α_ij + cot β_ij), clamped from below.
    pub fn cotangent(topo: &Topology, p: &[V3]) -> Walk {
        let n = topo.n_vertices();
        // Half cotangent of every triangle corner, added to the opposite edge in both rows.
        let mut acc: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
        for t in topo.triangles() {
            for k in 0..3 {
                let (a, b, c) = (
                    t[k] as usize,
                    t[(k + 1) % 3] as usize,
                    t[(k + 2) % 3] as usize,
                );
                let u = vec3::sub(p[b], p[a]);
                let v = vec3::sub(p[c], p[a]);
                let cross = vec3::norm(vec3::cross(u, v));
                let cot = if cross > 0.0 {
                    vec3::dot(u, v) / cross
                } else {
                    0.0
                };
                acc[b].push((c as u32, 0.5 * cot));
                acc[c].push((b as u32, 0.5 * cot));
            }
        }
        Walk::build(topo, |v, w, _| {
            acc[v]
                .iter()
                .filter(|(u, _)| *u == w)
                .map(|(_, c)| c)
                .sum::<f64>()
        })
    }

    /// Rows from a raw weight per (vertex, neighbour); weights below [`WEIGHT_FLOOR`] of the row mean are raised
    /// to it, then each row is normalised.
    fn build(topo: &Topology, weight: impl Fn(usize, u32, usize) -> f64) -> Walk {
        let n = topo.n_vertices();
        let mut offsets = Vec::with_capacity(n + 1);
        let mut cols = Vec::new();
        let mut weights = Vec::new();
        let mut degree = Vec::with_capacity(n);
        let mut boundary = vec![false; n];
        offsets.push(0u32);
        for (v, on_boundary) in boundary.iter_mut().enumerate() {
            let nb = topo.vertex_neighbors(v);
            // A vertex is on an open boundary when some edge from it has only one triangle: then it has as many
            // neighbours as triangles (a closed fan has as many of each).
            *on_boundary = nb.len() != topo.vertex_triangles(v).len();
            let raw: Vec<f64> = nb
                .iter()
                .enumerate()
                .map(|(i, &w)| weight(v, w, i))
                .collect();
            let mean = raw.iter().map(|w| w.abs()).sum::<f64>() / raw.len().max(1) as f64;
            let floor = (WEIGHT_FLOOR * mean).max(f64::MIN_POSITIVE);
            let clamped: Vec<f64> = raw.iter().map(|w| w.max(floor)).collect();
            let sum: f64 = clamped.iter().sum();
            degree.push(sum);
            for (&w, c) in nb.iter().zip(&clamped) {
                cols.push(w);
                weights.push(if sum > 0.0 { c / sum } else { 0.0 });
            }
            offsets.push(cols.len() as u32);
        }
        Walk {
            offsets,
            cols,
            weights,
            degree,
            boundary,
        }
    }

    pub fn n_vertices(&self) -> usize {
        self.degree.len()
    }

    /// Whether vertex `v` lies on an open boundary.
    pub fn is_boundary(&self, v: usize) -> bool {
        self.boundary[v]
    }

    /// Row sums of the unnormalised weights.
    pub fn degree(&self) -> &[f64] {
        &self.degree
    }

    /// (Px)_v.
    #[inline]
    pub fn average_at(&self, x: &[V3], v: usize) -> V3 {
        let (a, b) = (self.offsets[v] as usize, self.offsets[v + 1] as usize);
        let mut s = [0.0; 3];
        for k in a..b {
            let w = self.weights[k];
            let p = x[self.cols[k] as usize];
            s[0] += w * p[0];
            s[1] += w * p[1];
            s[2] += w * p[2];
        }
        if a == b {
            x[v]
        } else {
            s
        }
    }

    /// out = P x.
    pub fn average_into(&self, x: &[V3], out: &mut [V3]) {
        for (v, o) in out.iter_mut().enumerate() {
            *o = self.average_at(x, v);
        }
    }

    /// Δx = Px − x (zero where x is locally flat in the walk's sense).
    pub fn laplacian(&self, x: &[V3]) -> Vec<V3> {
        (0..x.len())
            .map(|v| vec3::sub(self.average_at(x, v), x[v]))
            .collect()
    }

    /// Implicit diffusion: solves ((1 + t) I − t P) y = x. A frequency k of I − P keeps 1 / (1 + t k) of its
    /// amplitude, half at k = 1/t. The matrix is strictly diagonally dominant, so Jacobi sweeps converge; they
    /// stop when no vertex moves by more than 1e-9 of the input's extent.
    pub fn diffuse(&self, x: &[V3], t: f64) -> Vec<V3> {
        if t <= 0.0 {
            return x.to_vec();
        }
        let mut y = x.to_vec();
        let mut next = y.clone();
        let (lo, hi) = crease_core::mesh::geometry::bounding_box(x);
        let scale = vec3::norm(vec3::sub(hi, lo)).max(1e-12);
        for _ in 0..10_000 {
            let mut change = 0.0f64;
            for v in 0..x.len() {
                let avg = self.average_at(&y, v);
                let n = vec3::scale(vec3::add(x[v], vec3::scale(avg, t)), 1.0 / (1.0 + t));
                change = change.max(vec3::norm(vec3::sub(n, y[v])));
                next[v] = n;
            }
            std::mem::swap(&mut y, &mut next);
            if change < 1e-9 * scale {
                break;
            }
        }
        y
    }

    /// Neighbours of `v` and their normalised weights.
    pub fn row(&self, v: usize) -> (&[u32], &[f64]) {
        let (a, b) = (self.offsets[v] as usize, self.offsets[v + 1] as usize);
        (&self.cols[a..b], &self.weights[a..b])
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A flat grid of `nx` × `ny` unit squares split along one diagonal.
    pub fn grid(nx: usize, ny: usize) -> (Topology, Vec<V3>) {
        let mut p = Vec::new();
        for j in 0..=ny {
            for i in 0..=nx {
                p.push([i as f64, j as f64, 0.0]);
            }
        }
        let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
        let mut tris = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        (Topology::new(p.len(), tris).unwrap(), p)
    }

    #[test]
    fn rows_are_averages_and_planes_are_fixed_points() {
        let (topo, p) = grid(6, 5);
        for walk in [Walk::uniform(&topo), Walk::cotangent(&topo, &p)] {
            for v in 0..topo.n_vertices() {
                let (_, w) = walk.row(v);
                assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
                assert!(w.iter().all(|&x| x > 0.0));
            }
            // An interior vertex of a plane is the mean of its ring under cotangent weights (exactly) and under
            // uniform ones on this symmetric grid.
            let lap = walk.laplacian(&p);
            let interior = (2 * 7 + 3) as usize;
            assert!(!walk.is_boundary(interior));
            assert!(vec3::norm(lap[interior]) < 1e-12, "{:?}", lap[interior]);
            assert!(walk.is_boundary(0) && walk.is_boundary(6));
        }
    }

    #[test]
    fn cotangent_weights_ignore_the_right_angled_diagonal() {
        let (topo, p) = grid(4, 4);
        let walk = Walk::cotangent(&topo, &p);
        // Vertex (2, 2): its diagonal neighbours (1, 1) and (3, 3) face right angles (cot 90° = 0), so they get
        // the floor only; the four axis neighbours share the rest.
        let v = 2 * 5 + 2;
        let (cols, w) = walk.row(v);
        for (&c, &x) in cols.iter().zip(w) {
            let (i, j) = (c as usize % 5, c as usize / 5);
            let diagonal = i != 2 && j != 2;
            assert_eq!(x < 0.05, diagonal, "neighbour ({i}, {j}) weight {x}");
        }
    }
}
