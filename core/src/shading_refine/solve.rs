//! The refinement's linear system, applied without forming it: the data term as per-triangle 3 × 3 blocks, the
//! smoothness as the umbrella Laplacian and its transpose, solved by conjugate gradients with a diagonal
//! preconditioner (symmetric positive definite once the prior is added; a few thousand unknowns).

use super::ShadingRefineParams;
use crate::mesh::Topology;

const MAX_ITERATIONS: usize = 1000;
const TOLERANCE: f64 = 1e-8;

struct System<'a> {
    tris: &'a [[u32; 3]],
    neighbours: &'a [Vec<u32>],
    h: &'a [[[f64; 3]; 3]],
    smooth: f64,
    /// Per vertex.
    stay: Vec<f64>,
}

impl System<'_> {
    fn laplacian(&self, x: &[f64]) -> Vec<f64> {
        self.neighbours
            .iter()
            .enumerate()
            .map(|(i, nb)| {
                if nb.is_empty() {
                    return 0.0;
                }
                let mean = nb.iter().map(|&j| x[j as usize]).sum::<f64>() / nb.len() as f64;
                x[i] - mean
            })
            .collect()
    }

    fn laplacian_t(&self, y: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; y.len()];
        for (i, nb) in self.neighbours.iter().enumerate() {
            if nb.is_empty() {
                continue;
            }
            out[i] += y[i];
            let share = y[i] / nb.len() as f64;
            for &j in nb {
                out[j as usize] -= share;
            }
        }
        out
    }

    /// The regularisers alone: `smooth · LᵀL x + stay · x`.
    fn regular(&self, x: &[f64]) -> Vec<f64> {
        let llx = self.laplacian_t(&self.laplacian(x));
        llx.iter()
            .zip(x)
            .zip(&self.stay)
            .map(|((l, v), s)| self.smooth * l + s * v)
            .collect()
    }

    fn apply(&self, x: &[f64]) -> Vec<f64> {
        let mut y = self.regular(x);
        for (t, h) in self.tris.iter().zip(self.h) {
            for i in 0..3 {
                let mut s = 0.0;
                for j in 0..3 {
                    s += h[i][j] * x[t[j] as usize];
                }
                y[t[i] as usize] += s;
            }
        }
        y
    }

    fn diagonal(&self) -> Vec<f64> {
        let mut d = self.stay.clone();
        for (i, nb) in self.neighbours.iter().enumerate() {
            if nb.is_empty() {
                continue;
            }
            d[i] += self.smooth;
            let k = 1.0 / nb.len() as f64;
            for &j in nb {
                d[j as usize] += self.smooth * k * k;
            }
        }
        for (t, h) in self.tris.iter().zip(self.h) {
            for i in 0..3 {
                d[t[i] as usize] += h[i][i];
            }
        }
        d
    }
}

/// The step of one Gauss–Newton round: argmin over δ of the data term's quadratic model plus the regularisers
/// at `offsets + δ`, with each vertex's own stay weight (`stay`). `None` when no pixel carries a data weight
/// (nothing to refine from).
#[allow(clippy::too_many_arguments)]
pub(super) fn solve_offsets(
    topo: &Topology,
    neighbours: &[Vec<u32>],
    h: &[[[f64; 3]; 3]],
    g: &[[f64; 3]],
    offsets: &[f64],
    params: &ShadingRefineParams,
    stay: &[f64],
    edge: f64,
) -> Option<Vec<f64>> {
    let n = offsets.len();
    let tris = topo.triangles();
    let mut data_diag = vec![0.0; n];
    let mut b = vec![0.0; n];
    for ((t, hb), gb) in tris.iter().zip(h).zip(g) {
        for i in 0..3 {
            data_diag[t[i] as usize] += hb[i][i];
            b[t[i] as usize] += gb[i];
        }
    }
    if !data_diag.iter().any(|&d| d > 0.0)
        || edge.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
    {
        return None;
    }
    // Offsets measured in edge lengths: the priors do not depend on the mesh's units or resolution.
    let per_edge = 1.0 / (edge * edge);
    let sys = System {
        tris,
        neighbours,
        h,
        smooth: params.smoothness * per_edge,
        stay: stay.iter().map(|w| w * per_edge).collect(),
    };
    for (bi, r) in b.iter_mut().zip(sys.regular(offsets)) {
        *bi -= r;
    }
    let precond: Vec<f64> = sys.diagonal().iter().map(|&d| 1.0 / d).collect();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut x = vec![0.0; n];
    let mut r = b.clone();
    let mut z: Vec<f64> = r.iter().zip(&precond).map(|(a, p)| a * p).collect();
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let stop = TOLERANCE * dot(&b, &b).sqrt();
    for _ in 0..MAX_ITERATIONS {
        if dot(&r, &r).sqrt() <= stop {
            break;
        }
        let ap = sys.apply(&p);
        let pap = dot(&p, &ap);
        if pap.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            break;
        }
        let alpha = rz / pap;
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        z = r.iter().zip(&precond).map(|(a, p)| a * p).collect();
        let rz_next = dot(&r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}
