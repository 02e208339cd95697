//! crease's own low-pass: the heat kernel of the surface, e^{−t Δ}, with the cotangent Laplacian and lumped
//! masses of one frame, evaluated as a Chebyshev series (matrix-free neighbour sweeps).
//!
//! Folds are short-wavelength and the garment's pose and outline long-wavelength, so several steps need to
//! split a field on the surface by wavelength: the fold restoration (what a capture damped), the shape
//! projection (what a deformation must not move) and the shape figures of `report.json`. They all use this one
//! filter. It is not a model of any capture: it is the smoothest isotropic low-pass there is (the diffusion of
//! the field for a time t), it depends on the surface's geometry and not on how its mesh was cut (cotangent
//! weights), and its one parameter is a length: the wavelength whose amplitude it halves. A plane wave of
//! wavenumber k on a flat part of the surface is an eigenfunction of the Laplacian with eigenvalue k², so the
//! kernel keeps e^{−t k²} of it; half at the wavelength ℓ means t = ln 2 · (ℓ / 2π)².
//!
//! Any function f of the operator (the kernel itself, a deconvolution built on it) is applied the same way:
//! f(A) x with A = M⁻¹ L, whose eigenvalues are real and lie in [0, λ_max] (L is positive semi-definite for
//! every triangle mesh; λ_max is bounded by Gershgorin's discs), is the Chebyshev series of f on that interval,
//! truncated where its coefficients fall below rounding level, evaluated by the three-term recurrence. Each
//! term costs one sweep over the vertices' one-rings, in parallel, with the same arithmetic in the same order
//! whatever the number of threads.

use crate::mesh::Topology;
use crate::vec3::{self, V3};
use rayon::prelude::*;
use std::f64::consts::PI;

/// A triangle's cotangent weights are scaled down together until none exceeds this magnitude (an angle of about
/// 1.1° or 178.9°): a needle triangle would otherwise give a weight, and so a λ_max, large enough to need
/// thousands of series terms, for a triangle whose shape carries no information about the surface.
///
/// Together, not each on its own: a triangle's stiffness ½ Σ cot_k (x_i − x_j)² is positive semi-definite
/// because its cotangents satisfy cot α cot β + cot β cot γ + cot γ cot α = 1. Clipping them one by one breaks
/// that identity (a sliver's −200, 100, 100 clipped to −50, 50, 50 gives −2500): the Laplacian gets a negative
/// eigenvalue, where every Chebyshev series on [0, λ_max] grows like a power of its term count, and one nearly
/// collapsed triangle in a captured frame sent the shape projection's low-pass to 10⁴⁰. Scaled together, the
/// three keep their identity up to a positive factor: the sliver is a weaker but still positive spring.
const MAX_COT: f64 = 50.0;

/// Coefficients below this fraction of the largest end the series.
const TAIL_FRACTION: f64 = 1e-10;

/// Terms kept beyond the last coefficient above [`TAIL_FRACTION`].
const TAIL_MARGIN: usize = 4;

/// Most terms a series may have (a function that needs more is not smooth on the mesh's scale).
const MAX_TERMS: usize = 400;

/// Vertices per parallel chunk of one sweep.
const CHUNK: usize = 2048;

/// The operator A = M⁻¹ L of one frame: cotangent weights of every vertex's one-ring and its lumped mass.
#[derive(Debug, Clone)]
pub struct SurfaceOperator {
    offsets: Vec<u32>,
    neighbors: Vec<u32>,
    /// w_ij / m_i for each neighbour slot.
    weights: Vec<f64>,
    /// Σ_j w_ij / m_i of each vertex (the diagonal of A).
    diagonal: Vec<f64>,
    /// An upper bound of A's eigenvalues (Gershgorin).
    lambda_max: f64,
    /// Lumped (barycentric) vertex masses.
    mass: Vec<f64>,
}

impl SurfaceOperator {
    /// The operator of the surface `p` with connectivity `topo`, every vertex diffusing over its one-ring. A
    /// vertex whose triangles have no area gets a zero row (it keeps its value under any filter), so the
    /// operator is defined on every frame that passed validation.
    pub fn new(topo: &Topology, p: &[V3]) -> Self {
        Self::build(topo, p, false)
    }

    /// [`SurfaceOperator::new`], except that a vertex on an open rim diffuses along the rim only (the 1-D
    /// Laplacian of the rim curve, weights 1 / edge length, mass half its two rim edges). A rim is a curve
    /// whose shape the surface next to it does not hold: smoothed over its one-ring, a rim that flaps looks
    /// like a short fold of the surface, while along itself it is the long, smooth motion it is. Low-passes
    /// that split shape from folds in a displacement (the shape projection, the shape figures) use this one.
    pub fn with_rims_along_themselves(topo: &Topology, p: &[V3]) -> Self {
        Self::build(topo, p, true)
    }

    fn build(topo: &Topology, p: &[V3], rims: bool) -> Self {
        let nv = topo.n_vertices();
        let mut mass = vec![0.0; nv];
        // Cotangent weight of each directed vertex pair, accumulated per triangle: w_ij = (cot α + cot β) / 2.
        let mut pairs: Vec<(u32, u32, f64)> = Vec::with_capacity(topo.n_triangles() * 6);
        for tri in topo.triangles() {
            let q = tri.map(|v| p[v as usize]);
            let area = 0.5 * vec3::norm(vec3::cross(vec3::sub(q[1], q[0]), vec3::sub(q[2], q[0])));
            for &v in tri {
                mass[v as usize] += area / 3.0;
            }
            let cots = triangle_cotangents(q);
            for (k, cot) in cots.into_iter().enumerate() {
                let (i, j) = (tri[k], tri[(k + 1) % 3]);
                pairs.push((i, j, 0.5 * cot));
                pairs.push((j, i, 0.5 * cot));
            }
        }
        if rims {
            // Rim vertices: their rows become the rim curve's 1-D Laplacian.
            let mut rim_mass = vec![0.0; nv];
            let mut rim_pairs = Vec::new();
            for (t, tri) in topo.triangles().iter().enumerate() {
                for k in 0..3 {
                    if topo.tri_adj()[t][k] == crate::mesh::NONE {
                        let (a, b) = (tri[k], tri[(k + 1) % 3]);
                        let len = vec3::norm(vec3::sub(p[a as usize], p[b as usize]));
                        if len > 0.0 {
                            rim_mass[a as usize] += 0.5 * len;
                            rim_mass[b as usize] += 0.5 * len;
                            rim_pairs.push((a, b, 1.0 / len));
                            rim_pairs.push((b, a, 1.0 / len));
                        }
                    }
                }
            }
            pairs.retain(|&(i, _, _)| rim_mass[i as usize] == 0.0);
            pairs.extend(rim_pairs);
            for (m, r) in mass.iter_mut().zip(&rim_mass) {
                if *r > 0.0 {
                    *m = *r;
                }
            }
        }
        pairs.sort_unstable_by_key(|a| (a.0, a.1));
        let mut offsets = Vec::with_capacity(nv + 1);
        let mut neighbors = Vec::with_capacity(pairs.len() / 2);
        let mut weights = Vec::with_capacity(pairs.len() / 2);
        let mut diagonal = vec![0.0; nv];
        let mut lambda_max: f64 = 0.0;
        offsets.push(0u32);
        let mut k = 0;
        for v in 0..nv {
            let start = neighbors.len();
            while k < pairs.len() && pairs[k].0 as usize == v {
                let j = pairs[k].1;
                let mut w = 0.0;
                while k < pairs.len() && pairs[k].0 as usize == v && pairs[k].1 == j {
                    w += pairs[k].2;
                    k += 1;
                }
                neighbors.push(j);
                weights.push(w);
            }
            let m = mass[v];
            if m > 0.0 {
                let mut sum = 0.0;
                let mut abs = 0.0;
                for w in &mut weights[start..] {
                    sum += *w;
                    abs += w.abs();
                    *w /= m;
                }
                diagonal[v] = sum / m;
                lambda_max = lambda_max.max((sum.abs() + abs) / m);
            } else {
                neighbors.truncate(start);
                weights.truncate(start);
            }
            offsets.push(neighbors.len() as u32);
        }
        SurfaceOperator {
            offsets,
            neighbors,
            weights,
            diagonal,
            lambda_max: lambda_max.max(f64::MIN_POSITIVE),
            mass,
        }
    }

    pub fn n_vertices(&self) -> usize {
        self.diagonal.len()
    }

    /// Lumped vertex masses (a third of the area of each incident triangle).
    pub fn mass(&self) -> &[f64] {
        &self.mass
    }

    /// The Gershgorin bound of the operator's eigenvalues.
    pub fn lambda_max(&self) -> f64 {
        self.lambda_max
    }

    /// y = (a A + b I) x, one parallel sweep.
    fn sweep(&self, x: &[V3], y: &mut [V3], a: f64, b: f64) {
        y.par_chunks_mut(CHUNK).enumerate().for_each(|(c, out)| {
            let base = c * CHUNK;
            for (i, yv) in out.iter_mut().enumerate() {
                let v = base + i;
                let mut acc = vec3::scale(x[v], self.diagonal[v]);
                let (s, e) = (self.offsets[v] as usize, self.offsets[v + 1] as usize);
                for (&j, &w) in self.neighbors[s..e].iter().zip(&self.weights[s..e]) {
                    acc = vec3::sub(acc, vec3::scale(x[j as usize], w));
                }
                *yv = vec3::add(vec3::scale(acc, a), vec3::scale(x[v], b));
            }
        });
    }

    /// f(A) x for the series `f` (made for an operator with this one's λ_max or a larger one).
    pub fn apply(&self, f: &Series, x: &[V3]) -> Vec<V3> {
        assert_eq!(x.len(), self.n_vertices(), "field size");
        let c = &f.coefficients;
        // B = (2 / λ) A − I maps [0, λ] onto [−1, 1]; T_0 x = x, T_1 x = B x, T_{k+1} = 2 B T_k − T_{k−1}.
        let scale = 2.0 / f.lambda_max;
        let mut out: Vec<V3> = x.iter().map(|v| vec3::scale(*v, c[0])).collect();
        if c.len() == 1 {
            return out;
        }
        let mut prev = x.to_vec();
        let mut cur = vec![[0.0; 3]; x.len()];
        self.sweep(x, &mut cur, scale, -1.0);
        let mut next = vec![[0.0; 3]; x.len()];
        for (k, &ck) in c.iter().enumerate().skip(1) {
            for (o, t) in out.iter_mut().zip(&cur) {
                *o = vec3::add(*o, vec3::scale(*t, ck));
            }
            if k + 1 == c.len() {
                break;
            }
            // next = 2 B cur − prev = (2 s A − 2 I) cur − prev
            self.sweep(&cur, &mut next, 2.0 * scale, -2.0);
            next.par_iter_mut()
                .zip(prev.par_iter())
                .for_each(|(n, p)| *n = vec3::sub(*n, *p));
            std::mem::swap(&mut prev, &mut cur);
            std::mem::swap(&mut cur, &mut next);
        }
        out
    }
}

/// The cotangent of the angle opposite each edge (k, k + 1) of triangle `q`, scaled together so that none
/// exceeds [`MAX_COT`]; zero for a triangle without area.
fn triangle_cotangents(q: [V3; 3]) -> [f64; 3] {
    let cots: [f64; 3] = std::array::from_fn(|k| {
        let o = q[(k + 2) % 3];
        let (u, w) = (vec3::sub(q[k], o), vec3::sub(q[(k + 1) % 3], o));
        let cross = vec3::norm(vec3::cross(u, w));
        if cross > 0.0 {
            vec3::dot(u, w) / cross
        } else {
            0.0
        }
    });
    let largest = cots.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    if largest > MAX_COT {
        cots.map(|c| c * (MAX_COT / largest))
    } else {
        cots
    }
}

/// A function of the operator's eigenvalue as a truncated Chebyshev series on [0, λ_max].
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    coefficients: Vec<f64>,
    lambda_max: f64,
}

impl Series {
    /// The Chebyshev series of `f` on [0, `lambda_max`], truncated where its coefficients reach rounding level.
    pub fn new(lambda_max: f64, f: impl Fn(f64) -> f64) -> Self {
        // Coefficients by the discrete cosine transform of f at the Chebyshev nodes, doubling the node count
        // until the tail is below the cut (or the cap is reached).
        let mut n = 32;
        loop {
            let values: Vec<f64> = (0..n)
                .map(|j| {
                    let x = ((j as f64 + 0.5) * PI / n as f64).cos();
                    f(0.5 * lambda_max * (x + 1.0))
                })
                .collect();
            let mut c: Vec<f64> = (0..n)
                .map(|k| {
                    let s: f64 = values
                        .iter()
                        .enumerate()
                        .map(|(j, v)| v * (k as f64 * (j as f64 + 0.5) * PI / n as f64).cos())
                        .sum();
                    2.0 * s / n as f64
                })
                .collect();
            c[0] *= 0.5;
            let largest = c.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let last = c
                .iter()
                .rposition(|v| v.abs() > TAIL_FRACTION * largest)
                .unwrap_or(0);
            if last + TAIL_MARGIN < n / 2 || n >= MAX_TERMS {
                c.truncate((last + 1 + TAIL_MARGIN).min(n));
                return Series {
                    coefficients: c,
                    lambda_max,
                };
            }
            n *= 2;
        }
    }

    /// Terms of the series (sweeps per application, less one).
    pub fn len(&self) -> usize {
        self.coefficients.len()
    }

    pub fn is_empty(&self) -> bool {
        self.coefficients.is_empty()
    }
}

/// Diffusion time t of the heat kernel that halves a wave of `wavelength`: e^{−t (2π/ℓ)²} = 1/2.
pub fn diffusion_time(wavelength: f64) -> f64 {
    std::f64::consts::LN_2 * (wavelength / (2.0 * PI)).powi(2)
}

/// The heat kernel e^{−tλ} halving `wavelength`, as a series for `op`.
pub fn low_pass(op: &SurfaceOperator, wavelength: f64) -> Series {
    let t = diffusion_time(wavelength);
    Series::new(op.lambda_max(), move |l| (-t * l).exp())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A flat grid of `nx` × `ny` vertices, spacing 1 (equilateral rows), with a wave of wavelength `wl` and
    /// height `amp` along x.
    pub fn waved_grid(nx: usize, ny: usize, wl: f64, amp: f64) -> (Topology, Vec<V3>) {
        let mut p = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let x = i as f64 + 0.5 * (j % 2) as f64;
                let y = j as f64 * 0.75f64.sqrt();
                p.push([x, y, amp * (2.0 * PI * x / wl).sin()]);
            }
        }
        let mut tris = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let a = (j * nx + i) as u32;
                let (b, c, d) = (a + 1, a + nx as u32, a + nx as u32 + 1);
                if j % 2 == 0 {
                    tris.push([a, b, c]);
                    tris.push([b, d, c]);
                } else {
                    tris.push([a, b, d]);
                    tris.push([a, d, c]);
                }
            }
        }
        (Topology::new(nx * ny, tris).unwrap(), p)
    }

    fn interior(p: &[V3], nx: f64, ny: f64) -> Vec<usize> {
        (0..p.len())
            .filter(|&v| {
                let (x, y) = (p[v][0], p[v][1]);
                x > 0.3 * nx && x < 0.7 * nx && y > 0.3 * ny * 0.866 && y < 0.7 * ny * 0.866
            })
            .collect()
    }

    /// On a flat grid the kernel keeps half of a wave at the wavelength it is made for, more of longer waves
    /// and less of shorter ones, as e^{−t k²} says.
    #[test]
    fn the_kernel_halves_its_wavelength() {
        let (topo, flat) = waved_grid(80, 60, 8.0, 0.0);
        let op = SurfaceOperator::new(&topo, &flat);
        let lp = low_pass(&op, 8.0);
        for wl in [6.0, 8.0, 12.0, 20.0] {
            let wave: Vec<V3> = flat
                .iter()
                .map(|q| [0.0, 0.0, (2.0 * PI * q[0] / wl).sin()])
                .collect();
            let out = op.apply(&lp, &wave);
            let want = (-diffusion_time(8.0) * (2.0 * PI / wl).powi(2)).exp();
            let crest: Vec<usize> = interior(&flat, 80.0, 60.0)
                .into_iter()
                .filter(|&v| wave[v][2] > 0.99)
                .collect();
            assert!(crest.len() > 10);
            for v in crest {
                let got = out[v][2] / wave[v][2];
                // The discrete cotangent Laplacian of a wave with a few edges per wavelength has a slightly
                // smaller eigenvalue than k²: the kernel keeps a little more than the continuous formula.
                assert!(
                    got > want - 0.01 && got < want + 0.06,
                    "wavelength {wl}: kept {got}, continuous formula {want}"
                );
            }
        }
    }

    /// A constant field and a linear one (a plane) are fixed points: the Laplacian of both is zero inside.
    #[test]
    fn constants_and_planes_pass_unchanged() {
        let (topo, p) = waved_grid(30, 20, 5.0, 0.3);
        let op = SurfaceOperator::new(&topo, &p);
        let lp = low_pass(&op, 10.0);
        let constant = vec![[1.5, -2.0, 0.25]; p.len()];
        for (a, b) in op.apply(&lp, &constant).iter().zip(&constant) {
            assert!(vec3::norm(vec3::sub(*a, *b)) < 1e-9);
        }
    }

    /// S = M^{1/2} A M^{-1/2}, symmetric (L is), with A's eigenvalues.
    fn symmetric(op: &SurfaceOperator) -> faer::Mat<f64> {
        let n = op.n_vertices();
        let m = op.mass();
        let mut sym = faer::Mat::<f64>::zeros(n, n);
        for v in 0..n {
            sym[(v, v)] = op.diagonal[v];
            for s in op.offsets[v] as usize..op.offsets[v + 1] as usize {
                let j = op.neighbors[s] as usize;
                sym[(v, j)] -= op.weights[s] * (m[v] / m[j]).sqrt();
            }
        }
        sym
    }

    /// A nearly collapsed triangle (a capture's vertex that slid almost onto its neighbours' edge) keeps the
    /// operator positive semi-definite, so the low-pass stays a low-pass: clipping its three large cotangents
    /// one by one gave a negative eigenvalue, which the series amplifies without bound.
    #[test]
    fn a_sliver_keeps_the_operator_positive() {
        let (topo, mut p) = waved_grid(12, 9, 6.0, 0.0);
        // Vertex 5 of row 4 moved to 0.002 above the edge between vertices 4 and 5 of row 3, the other two
        // corners of its triangle below: the triangle becomes a needle with an angle of about 179.5°.
        let (a, b, v) = (3 * 12 + 4, 3 * 12 + 5, 4 * 12 + 5);
        let mid = vec3::scale(vec3::add(p[a], p[b]), 0.5);
        p[v] = vec3::add(mid, [0.0, 0.002, 0.0]);
        let tri = topo
            .triangles()
            .iter()
            .find(|t| t.contains(&(a as u32)) && t.contains(&(b as u32)) && t.contains(&(v as u32)))
            .copied()
            .expect("the needle triangle");
        let cots = triangle_cotangents(tri.map(|i| p[i as usize]));
        assert!(
            cots.iter().any(|c| c.abs() >= MAX_COT * (1.0 - 1e-12)),
            "{cots:?}"
        );
        let identity = cots[0] * cots[1] + cots[1] * cots[2] + cots[2] * cots[0];
        assert!(identity > 0.0, "{cots:?}");
        let op = SurfaceOperator::new(&topo, &p);
        let eig = symmetric(&op)
            .self_adjoint_eigen(faer::Side::Lower)
            .unwrap();
        let smallest = eig.S().column_vector()[0];
        assert!(smallest > -1e-9 * op.lambda_max(), "eigenvalue {smallest}");
        // And the low-pass of a bounded field stays bounded.
        let x: Vec<V3> = (0..p.len())
            .map(|v| [(v as f64 * 0.7).sin(), 0.0, 0.0])
            .collect();
        let out = op.apply(&low_pass(&op, 8.0), &x);
        let largest = out.iter().fold(0.0f64, |m, q| m.max(q[0].abs()));
        assert!(largest < 1.5, "low-pass reached {largest}");
    }

    /// The series evaluates f(A) x: on a small mesh, against f applied to A's eigendecomposition computed
    /// densely.
    #[test]
    fn the_series_is_the_function_of_the_operator() {
        let (topo, p) = waved_grid(9, 7, 4.0, 0.4);
        let op = SurfaceOperator::new(&topo, &p);
        let n = op.n_vertices();
        // f(A) = M^{-1/2} f(S) M^{1/2} with S = M^{1/2} A M^{-1/2} symmetric (L is): dense eigendecomposition.
        let m = op.mass();
        let sym = symmetric(&op);
        let f = |l: f64| 1.0 / (1.0 + 0.3 * l) + 0.1 * (-0.5 * l).exp();
        let series = Series::new(op.lambda_max(), f);
        let x: Vec<V3> = (0..n)
            .map(|v| {
                [
                    (v as f64 * 0.37).sin(),
                    (v as f64 * 0.11).cos(),
                    v as f64 * 0.01,
                ]
            })
            .collect();
        let got = op.apply(&series, &x);
        let eig = sym.self_adjoint_eigen(faer::Side::Lower).unwrap();
        let vals = eig.S().column_vector();
        let vecs = eig.U();
        let mut fa = faer::Mat::<f64>::zeros(n, n);
        for i in 0..n {
            for j in 0..n {
                let mut s = 0.0;
                for k in 0..n {
                    let l = vals[k];
                    assert!(
                        l > -1e-9 && l <= op.lambda_max() * (1.0 + 1e-9),
                        "eigenvalue {l}"
                    );
                    s += vecs[(i, k)] * f(l) * vecs[(j, k)];
                }
                fa[(i, j)] = s * (m[j] / m[i]).sqrt();
            }
        }
        for d in 0..3 {
            for i in 0..n {
                let want: f64 = (0..n).map(|j| fa[(i, j)] * x[j][d]).sum();
                assert!(
                    (got[i][d] - want).abs() < 1e-8,
                    "{i},{d}: {} vs {want}",
                    got[i][d]
                );
            }
        }
    }
}
