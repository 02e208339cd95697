//! Mesh-space detail: the fine surface's folds predicted from the coarse mesh itself, before any map is drawn.
//!
//! A capture loses folds because it low-passes the surface; what is left of a fold in the coarse mesh is an
//! attenuated copy of it at the same place. So the fine shape is predicted as the coarse one plus a learned
//! linear filter of it: d = Σ_j w_j T_j(A) Δc, where c are the coarse positions, Δ the uniform graph Laplacian
//! (the average of the one-ring minus the vertex; boundary vertices average only their boundary neighbours, so a
//! rim is treated along itself), A = −Δ − I (its spectrum lies in [−1, 1]) and T_j the Chebyshev polynomials.
//! The weights w are fitted by ridge least squares on (coarse, fine) training pairs, one set for interior and
//! one for boundary vertices, shared by every vertex and axis: the filter depends only on the local shape of
//! the mesh, never on vertex identity, so it applies to any mesh of the same kind of capture.
//!
//! Why this basis: Δc removes the coarse shape itself (a filter that keeps long waves has d ≈ 0 there), which
//! keeps the least-squares problem well conditioned; Chebyshev polynomials of A are bounded on its spectrum, so
//! high degrees stay numerically tame where powers of Δ would not. Why a polynomial of the Laplacian: any
//! low-pass made of neighbourhood averages (Taubin's λ|μ filter that made the sleeve data's `captured/`, a
//! scanner's smoothing) is one, and so is the best linear estimate of what it removed; the fit learns that
//! estimate, with the ridge setting how far it trusts the weakest surviving frequencies.
//!
//! The predicted fine shape is used only for its normals (the map `apply --coarse` writes); the output mesh stays
//! the coarse one, so the shape is not moved.

use crate::register::boundary_vertices;
use crease_core::mesh::Topology;
use crease_core::shape::TaubinFilter;
use crease_core::vec3::{self, V3};
use crease_core::{Error, Result};
use faer::{Mat, Side};
use serde::{Deserialize, Serialize};

/// Polynomial degree of the default filter: over the sleeve-train leave-one-sequence-out splits the held-out
/// normal error fell from 3.60° (degree 10) to 3.04° (20), 2.81° (40) and 2.78° (60): 40 is where more terms
/// stop paying (docs/deepwrinkles.md).
pub const DEFAULT_DEGREE: usize = 40;
/// Ridge weight relative to the mean diagonal of the normal equations; the held-out error is flat from 1e-10
/// to 1e-15 and rises above 1e-8 (docs/deepwrinkles.md).
pub const DEFAULT_RIDGE: f64 = 1e-10;

/// The uniform Laplacian of a topology: per vertex, the neighbours it averages over.
///
/// The neighbour lists are the capture filter's own ([`TaubinFilter::neighbors`]): the filter learns to undo
/// that low-pass, so its Laplacian must be the very operator the capture applied, and keeping one builder
/// means the two cannot drift apart.
#[derive(Debug, Clone)]
pub struct Umbrella {
    rings: TaubinFilter,
    boundary: Vec<bool>,
}

impl Umbrella {
    pub fn new(topo: &Topology) -> Self {
        let mut boundary = vec![false; topo.n_vertices()];
        for v in boundary_vertices(topo) {
            boundary[v as usize] = true;
        }
        Umbrella {
            rings: TaubinFilter::new(topo, 0.5, -0.53, 80),
            boundary,
        }
    }

    pub fn n_vertices(&self) -> usize {
        self.boundary.len()
    }

    /// Whether vertex `v` lies on an open boundary (its Laplacian runs along the boundary).
    pub fn is_boundary(&self, v: usize) -> bool {
        self.boundary[v]
    }

    /// Δx: the mean of each vertex's neighbours minus the vertex (0 for a vertex without neighbours).
    pub fn laplacian(&self, x: &[V3]) -> Vec<V3> {
        (0..x.len()).map(|v| self.laplacian_at(x, v)).collect()
    }

    /// (Δx)_v, the one definition [`Umbrella::laplacian`] and [`DetailFilter::apply_into`] share.
    #[inline]
    pub fn laplacian_at(&self, x: &[V3], v: usize) -> V3 {
        let nb = self.rings.neighbors(v);
        if nb.is_empty() {
            return [0.0; 3];
        }
        let mut avg = [0.0; 3];
        for &w in nb {
            avg = vec3::add(avg, x[w as usize]);
        }
        vec3::sub(vec3::scale(avg, 1.0 / nb.len() as f64), x[v])
    }

    /// The filter's features of a coarse frame: T_j(A) Δc for j = 0..=degree, A = −Δ − I.
    pub fn features(&self, coarse: &[V3], degree: usize) -> Vec<Vec<V3>> {
        let a = |x: &[V3]| -> Vec<V3> {
            self.laplacian(x)
                .iter()
                .zip(x)
                .map(|(l, p)| vec3::scale(vec3::add(*l, *p), -1.0))
                .collect()
        };
        let mut out = Vec::with_capacity(degree + 1);
        out.push(self.laplacian(coarse));
        if degree >= 1 {
            out.push(a(&out[0]));
        }
        for j in 2..=degree {
            let at = a(&out[j - 1]);
            let next: Vec<V3> = at
                .iter()
                .zip(&out[j - 2])
                .map(|(p, q)| vec3::sub(vec3::scale(*p, 2.0), *q))
                .collect();
            out.push(next);
        }
        out
    }
}

/// Normal equations of the filter over some training pairs, interior and boundary vertices apart.
#[derive(Debug, Clone, PartialEq)]
pub struct DetailSystem {
    pub degree: usize,
    /// [interior, boundary] Gram matrices ((degree+1)², row-major) and right-hand sides.
    pub gram: [Vec<f64>; 2],
    pub rhs: [Vec<f64>; 2],
    /// Σ |fine − coarse|² per class, for held-out residuals of other fits ([`DetailSystem::residual`]).
    pub target_sq: [f64; 2],
    pub frames: usize,
}

impl DetailSystem {
    pub fn new(degree: usize) -> Self {
        let m = degree + 1;
        DetailSystem {
            degree,
            gram: [vec![0.0; m * m], vec![0.0; m * m]],
            rhs: [vec![0.0; m], vec![0.0; m]],
            target_sq: [0.0; 2],
            frames: 0,
        }
    }

    /// The normal equations of one (coarse, fine) frame pair.
    pub fn of_frame(op: &Umbrella, coarse: &[V3], fine: &[V3], degree: usize) -> Self {
        let m = degree + 1;
        let mut s = DetailSystem::new(degree);
        let f = op.features(coarse, degree);
        for v in 0..coarse.len() {
            let c = usize::from(op.is_boundary(v));
            let d = vec3::sub(fine[v], coarse[v]);
            s.target_sq[c] += vec3::dot(d, d);
            let (g, b) = (&mut s.gram[c], &mut s.rhs[c]);
            for i in 0..m {
                let fi = f[i][v];
                b[i] += vec3::dot(fi, d);
                for j in i..m {
                    g[i * m + j] += vec3::dot(fi, f[j][v]);
                }
            }
        }
        for g in &mut s.gram {
            for i in 0..m {
                for j in 0..i {
                    g[i * m + j] = g[j * m + i];
                }
            }
        }
        s.frames = 1;
        s
    }

    /// Adds another system (same degree) into this one.
    pub fn add(&mut self, o: &DetailSystem) {
        for c in 0..2 {
            for (a, b) in self.gram[c].iter_mut().zip(&o.gram[c]) {
                *a += b;
            }
            for (a, b) in self.rhs[c].iter_mut().zip(&o.rhs[c]) {
                *a += b;
            }
            self.target_sq[c] += o.target_sq[c];
        }
        self.frames += o.frames;
    }

    /// Sum of squared residuals |fine − (coarse + filter)|² of `filter` on the pairs of this system.
    pub fn residual(&self, filter: &DetailFilter) -> f64 {
        let m = self.degree + 1;
        (0..2)
            .map(|c| {
                let w = filter.weights(c == 1);
                let mut r = self.target_sq[c];
                for i in 0..m {
                    r -= 2.0 * self.rhs[c][i] * w[i];
                    for j in 0..m {
                        r += w[i] * self.gram[c][i * m + j] * w[j];
                    }
                }
                r
            })
            .sum()
    }

    /// The ridge solution: (G + ridge · mean diag(G) · I) w = b per class; a class without vertices gets w = 0.
    pub fn solve(&self, ridge: f64) -> Result<DetailFilter> {
        let m = self.degree + 1;
        let mut w = [vec![0.0; m], vec![0.0; m]];
        for (c, wc) in w.iter_mut().enumerate() {
            let mean_diag = (0..m).map(|i| self.gram[c][i * m + i]).sum::<f64>() / m as f64;
            if mean_diag <= 0.0 || !mean_diag.is_finite() {
                continue;
            }
            let g = Mat::<f64>::from_fn(m, m, |i, j| {
                self.gram[c][i * m + j] + if i == j { ridge * mean_diag } else { 0.0 }
            });
            let eig = g
                .self_adjoint_eigen(Side::Lower)
                .map_err(|e| Error::Numeric {
                    stage: "detail filter".into(),
                    msg: format!("eigendecomposition of the normal equations: {e:?}"),
                })?;
            let s = eig.S().column_vector();
            let u = eig.U();
            let smax = (0..m).map(|i| s[i]).fold(0.0f64, f64::max);
            for k in 0..m {
                if s[k] <= smax * 1e-14 {
                    continue;
                }
                let proj: f64 = (0..m).map(|i| u[(i, k)] * self.rhs[c][i]).sum::<f64>() / s[k];
                for i in 0..m {
                    wc[i] += u[(i, k)] * proj;
                }
            }
        }
        let [interior, boundary] = w;
        Ok(DetailFilter {
            degree: self.degree,
            interior,
            boundary,
        })
    }
}

/// The fitted filter: Chebyshev weights for interior and for boundary vertices.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetailFilter {
    pub degree: usize,
    pub interior: Vec<f64>,
    pub boundary: Vec<f64>,
}

impl DetailFilter {
    pub fn weights(&self, boundary: bool) -> &[f64] {
        if boundary {
            &self.boundary
        } else {
            &self.interior
        }
    }

    /// Fits the filter on (coarse, fine) frame pairs of one topology. Frames are reduced in their given order
    /// (each frame's system is computed in parallel, then summed one after another), so the weights are the
    /// same bytes whatever the number of threads.
    pub fn fit(
        topo: &Topology,
        pairs: &[FramePair],
        degree: usize,
        ridge: f64,
    ) -> Result<DetailFilter> {
        fit_system(topo, pairs, degree)?.solve(ridge)
    }

    /// The fine shape the filter predicts for a coarse frame.
    pub fn apply(&self, op: &Umbrella, coarse: &[V3]) -> Vec<V3> {
        let mut out = Vec::new();
        self.apply_into(op, coarse, &mut out, &mut FilterScratch::default());
        out
    }

    /// [`DetailFilter::apply`] into `out`, with `scratch`'s buffers reused from frame to frame: the Chebyshev
    /// recurrence keeps only its last two terms, and each term is added into the result as soon as it is made
    /// (41 passes over three flat arrays instead of 41 stored feature arrays). Every vertex sees the same
    /// operations in the same order as [`Umbrella::features`] followed by the weighted sum, so the result is
    /// bit for bit the same.
    pub fn apply_into(
        &self,
        op: &Umbrella,
        coarse: &[V3],
        out: &mut Vec<V3>,
        scratch: &mut FilterScratch,
    ) {
        let n = coarse.len();
        out.clear();
        out.extend_from_slice(coarse);
        let FilterScratch { prev, cur, next } = scratch;
        for buf in [&mut *prev, &mut *cur, &mut *next] {
            buf.clear();
            buf.resize(n, [0.0; 3]);
        }
        let add_term = |out: &mut [V3], f: &[V3], j: usize| {
            for (v, (p, fv)) in out.iter_mut().zip(f).enumerate() {
                let w = self.weights(op.is_boundary(v))[j];
                *p = vec3::add(*p, vec3::scale(*fv, w));
            }
        };
        // T_0(A) Δc = Δc.
        for (v, l) in cur.iter_mut().enumerate() {
            *l = op.laplacian_at(coarse, v);
        }
        add_term(out, cur, 0);
        if self.degree == 0 {
            return;
        }
        // T_1(A) Δc = A Δc, A x = −(Δx + x).
        std::mem::swap(prev, cur);
        for (v, t) in cur.iter_mut().enumerate() {
            *t = vec3::scale(vec3::add(op.laplacian_at(prev, v), prev[v]), -1.0);
        }
        add_term(out, cur, 1);
        // T_j = 2 A T_(j−1) − T_(j−2).
        for j in 2..=self.degree {
            for (v, t) in next.iter_mut().enumerate() {
                let at = vec3::scale(vec3::add(op.laplacian_at(cur, v), cur[v]), -1.0);
                *t = vec3::sub(vec3::scale(at, 2.0), prev[v]);
            }
            add_term(out, next, j);
            // (prev, cur, next) ← (cur, next, prev): the oldest term's buffer is the next one written.
            std::mem::swap(prev, cur);
            std::mem::swap(cur, next);
        }
    }

    /// Checks the weights against the stored degree (a damaged or foreign `detail.npy`).
    pub fn check(&self) -> std::result::Result<(), String> {
        let m = self.degree + 1;
        if self.interior.len() != m || self.boundary.len() != m {
            return Err(format!(
                "{} interior and {} boundary weights for degree {}",
                self.interior.len(),
                self.boundary.len(),
                self.degree
            ));
        }
        if self
            .interior
            .iter()
            .chain(&self.boundary)
            .any(|w| !w.is_finite())
        {
            return Err("a weight is not finite".into());
        }
        Ok(())
    }
}

/// The three recurrence buffers of [`DetailFilter::apply_into`], kept between frames.
#[derive(Debug, Clone, Default)]
pub struct FilterScratch {
    prev: Vec<V3>,
    cur: Vec<V3>,
    next: Vec<V3>,
}

/// A (coarse, fine) frame pair of one topology.
pub type FramePair<'a> = (&'a [V3], &'a [V3]);

/// The normal equations of all `pairs` (checked against `topo`), reduced in frame order.
pub fn fit_system(topo: &Topology, pairs: &[FramePair], degree: usize) -> Result<DetailSystem> {
    use rayon::prelude::*;
    let nv = topo.n_vertices();
    if let Some(i) = pairs
        .iter()
        .position(|(c, f)| c.len() != nv || f.len() != nv)
    {
        return Err(Error::param(
            "detail",
            format!(
                "training pair {} does not have the topology's {nv} vertices",
                i + 1
            ),
        ));
    }
    let op = Umbrella::new(topo);
    let systems: Vec<DetailSystem> = pairs
        .par_iter()
        .map(|(c, f)| DetailSystem::of_frame(&op, c, f, degree))
        .collect();
    let mut total = DetailSystem::new(degree);
    for s in &systems {
        total.add(s);
    }
    Ok(total)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat grid, its boundary rows open.
    fn grid(nx: usize, ny: usize) -> (Topology, Vec<V3>) {
        let mut p = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                p.push([i as f64, j as f64, 0.0]);
            }
        }
        let mut tris = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let a = (j * nx + i) as u32;
                let (b, c, d) = (a + 1, a + 1 + nx as u32, a + nx as u32);
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            }
        }
        (Topology::new(p.len(), tris).unwrap(), p)
    }

    /// Folds of a few wavelengths on the grid, and their low-pass (a few λ|μ steps of the same Laplacian).
    fn pair(topo: &Topology, flat: &[V3], phase: f64) -> (Vec<V3>, Vec<V3>) {
        let fine: Vec<V3> = flat
            .iter()
            .map(|p| {
                let z = 0.3 * (p[0] * 1.3 + phase).sin() + 0.2 * (p[1] * 0.9 - 2.0 * phase).cos();
                [p[0], p[1], z]
            })
            .collect();
        let op = Umbrella::new(topo);
        let mut c = fine.clone();
        for it in 0..8 {
            let f = if it % 2 == 0 { 0.5 } else { -0.53 };
            let l = op.laplacian(&c);
            for (x, d) in c.iter_mut().zip(&l) {
                *x = vec3::add(*x, vec3::scale(*d, f));
            }
        }
        (c, fine)
    }

    #[test]
    fn learns_to_undo_a_low_pass_on_unseen_folds() {
        let (topo, flat) = grid(24, 20);
        let train: Vec<(Vec<V3>, Vec<V3>)> = (0..6).map(|k| pair(&topo, &flat, k as f64)).collect();
        let refs: Vec<(&[V3], &[V3])> = train
            .iter()
            .map(|(c, f)| (c.as_slice(), f.as_slice()))
            .collect();
        let filter = DetailFilter::fit(&topo, &refs, 12, 1e-10).unwrap();
        filter.check().unwrap();
        let (c, f) = pair(&topo, &flat, 0.37);
        let op = Umbrella::new(&topo);
        let got = filter.apply(&op, &c);
        let err = |a: &[V3]| {
            a.iter()
                .zip(&f)
                .map(|(p, q)| vec3::norm(vec3::sub(*p, *q)))
                .sum::<f64>()
        };
        // The smoothed surface is far from the folds; the filter brings an unseen phase most of the way back.
        assert!(err(&got) < 0.2 * err(&c), "{} vs {}", err(&got), err(&c));
    }

    /// The filter as it was first written: every feature array stored, then the weighted sum per vertex.
    fn apply_from_features(filter: &DetailFilter, op: &Umbrella, coarse: &[V3]) -> Vec<V3> {
        let f = op.features(coarse, filter.degree);
        (0..coarse.len())
            .map(|v| {
                let w = filter.weights(op.is_boundary(v));
                let mut p = coarse[v];
                for (j, fj) in f.iter().enumerate() {
                    p = vec3::add(p, vec3::scale(fj[v], w[j]));
                }
                p
            })
            .collect()
    }

    #[test]
    fn the_fused_filter_gives_the_bits_of_the_stored_features() {
        let (topo, flat) = grid(15, 11);
        let op = Umbrella::new(&topo);
        let mut scratch = FilterScratch::default();
        let mut out = Vec::new();
        for (degree, phase) in [(0usize, 0.1), (1, 0.4), (2, 0.9), (7, 1.3), (40, 2.2)] {
            let (c, _) = pair(&topo, &flat, phase);
            // Distinct interior and boundary weights of both signs, so a mixed-up class or order shows.
            let filter = DetailFilter {
                degree,
                interior: (0..=degree)
                    .map(|j| 0.3 / (1.0 + j as f64) * if j % 3 == 1 { -1.0 } else { 1.0 })
                    .collect(),
                boundary: (0..=degree)
                    .map(|j| -0.07 * (j as f64 + 0.5).sqrt())
                    .collect(),
            };
            let want = apply_from_features(&filter, &op, &c);
            // The scratch comes in dirty from the previous degree: it must not matter.
            filter.apply_into(&op, &c, &mut out, &mut scratch);
            assert_eq!(out.len(), want.len());
            for (v, (a, b)) in out.iter().zip(&want).enumerate() {
                for k in 0..3 {
                    assert_eq!(
                        a[k].to_bits(),
                        b[k].to_bits(),
                        "degree {degree} vertex {v} axis {k}"
                    );
                }
            }
            assert_ne!(out, c, "the filter moved the surface (degree {degree})");
            assert_eq!(filter.apply(&op, &c), want);
        }
    }

    #[test]
    fn residual_of_the_normal_equations_matches_the_direct_one() {
        let (topo, flat) = grid(10, 9);
        let (c, f) = pair(&topo, &flat, 0.5);
        let op = Umbrella::new(&topo);
        let sys = DetailSystem::of_frame(&op, &c, &f, 4);
        let filter = sys.solve(1e-3).unwrap();
        let direct: f64 = filter
            .apply(&op, &c)
            .iter()
            .zip(&f)
            .map(|(p, q)| {
                let d = vec3::sub(*p, *q);
                vec3::dot(d, d)
            })
            .sum();
        assert!((sys.residual(&filter) - direct).abs() < 1e-9 * (1.0 + direct));
        // The boundary ring of an open grid is its own class.
        assert!(op.is_boundary(0) && !op.is_boundary(10 + 1));
    }

    #[test]
    fn the_same_pairs_give_the_same_bytes_and_no_boundary_means_zero_weights() {
        let (topo, flat) = grid(12, 10);
        let pairs: Vec<(Vec<V3>, Vec<V3>)> = (0..4).map(|k| pair(&topo, &flat, k as f64)).collect();
        let refs: Vec<(&[V3], &[V3])> = pairs
            .iter()
            .map(|(c, f)| (c.as_slice(), f.as_slice()))
            .collect();
        let a = DetailFilter::fit(&topo, &refs, 6, 1e-8).unwrap();
        let b = DetailFilter::fit(&topo, &refs, 6, 1e-8).unwrap();
        assert_eq!(a, b);
        let mut empty = DetailSystem::new(3);
        empty.gram[0][0] = 1.0;
        empty.rhs[0][0] = 2.0;
        let s = empty.solve(0.0).unwrap();
        assert!(s.boundary.iter().all(|&w| w == 0.0));
        assert!((s.interior[0] - 2.0).abs() < 1e-12);
    }

    /// The neighbour lists Umbrella built by hand before it read the capture filter's: boundary vertices take
    /// their neighbours along open edges (sorted, deduplicated), the others their one-ring.
    fn hand_built_rings(topo: &Topology) -> (Vec<Vec<u32>>, Vec<bool>) {
        use crease_core::mesh::NONE;
        let nv = topo.n_vertices();
        let mut boundary_nb: Vec<Vec<u32>> = vec![Vec::new(); nv];
        for (t, tri) in topo.triangles().iter().enumerate() {
            for k in 0..3 {
                if topo.tri_adj()[t][k] == NONE {
                    let (a, b) = (tri[k], tri[(k + 1) % 3]);
                    boundary_nb[a as usize].push(b);
                    boundary_nb[b as usize].push(a);
                }
            }
        }
        let mut boundary = vec![false; nv];
        let rings = boundary_nb
            .into_iter()
            .enumerate()
            .map(|(v, mut bn)| {
                if bn.is_empty() {
                    topo.vertex_neighbors(v)
                } else {
                    boundary[v] = true;
                    bn.sort_unstable();
                    bn.dedup();
                    bn
                }
            })
            .collect();
        (rings, boundary)
    }

    #[test]
    fn the_shared_rings_give_the_laplacian_the_hand_built_ones_gave() {
        // A grid with a hole, a vertex pinched between two cut cells (four boundary neighbours), a detached
        // triangle and a vertex no triangle uses: every kind of ring the builder distinguishes.
        let (nx, ny) = (9usize, 8usize);
        let (_, mut p) = grid(nx, ny);
        let cut = |i: usize, j: usize| (i, j) == (3, 3) || (i, j) == (4, 3) || (i, j) == (5, 4);
        let mut tris = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                if cut(i, j) {
                    continue;
                }
                let a = (j * nx + i) as u32;
                let (b, c, d) = (a + 1, a + 1 + nx as u32, a + nx as u32);
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            }
        }
        let base = p.len() as u32;
        p.extend([
            [20.0, 0.0, 0.5],
            [21.0, 0.0, -0.2],
            [20.0, 1.0, 0.1],
            [30.0, 0.0, 0.0],
        ]);
        tris.push([base, base + 1, base + 2]);
        let topo = Topology::new(p.len(), tris).unwrap();
        for (v, q) in p.iter_mut().enumerate() {
            q[2] += 0.3 * (v as f64 * 0.7).sin();
        }

        let op = Umbrella::new(&topo);
        let (rings, boundary) = hand_built_rings(&topo);
        assert_eq!(op.n_vertices(), rings.len());
        for v in 0..rings.len() {
            assert_eq!(op.rings.neighbors(v), rings[v].as_slice(), "vertex {v}");
            assert_eq!(op.is_boundary(v), boundary[v], "vertex {v}");
        }
        // The cases the mesh was built for are really there.
        let pinch = 4 * nx + 5;
        assert_eq!(rings[pinch].len(), 4, "pinched vertex");
        assert!(boundary[base as usize] && rings[base as usize].len() == 2);
        assert!(rings[base as usize + 3].is_empty() && !boundary[base as usize + 3]);
        assert!(!boundary[nx + 1] && rings[nx + 1].len() == 6);

        // The Laplacian (and so every feature and fitted weight) is bit for bit the hand-built rings' one.
        let expected: Vec<V3> = (0..p.len())
            .map(|v| {
                let nb = &rings[v];
                if nb.is_empty() {
                    return [0.0; 3];
                }
                let mut avg = [0.0; 3];
                for &w in nb {
                    avg = vec3::add(avg, p[w as usize]);
                }
                vec3::sub(vec3::scale(avg, 1.0 / nb.len() as f64), p[v])
            })
            .collect();
        let got = op.laplacian(&p);
        for (v, (a, b)) in got.iter().zip(&expected).enumerate() {
            for k in 0..3 {
                assert_eq!(a[k].to_bits(), b[k].to_bits(), "vertex {v} axis {k}");
            }
        }
    }
}
