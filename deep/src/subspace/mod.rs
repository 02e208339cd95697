//! Linear shape subspace (Lähner et al. 2018 §3.2): mean shape + principal components of registered frames.
//!
//! With n frames of 3v coordinates and n ≪ 3v, the SVD of the centred data O (3v × n) comes from the n × n Gram
//! matrix G = OᵀO = W Λ Wᵀ: the components are V_l = O w_l / √λ_l. That is one small dense eigendecomposition
//! (faer) and two tall products, instead of an SVD of a 22,080 × 360 matrix.
//! Pose normalisation (the paper's inverse skinning) is the identity here: the sleeve data has no skeleton,
//! the arm is static and the pose only drives the cuff, so the registered shapes are already in one frame.

pub mod mirror;

use crease_core::vec3::V3;
use crease_core::{Error, Result};
use faer::{Mat, Side};

#[derive(Debug, Clone)]
pub struct Subspace {
    /// Mean shape, 3v (x, y, z per vertex).
    pub mean: Vec<f64>,
    /// Orthonormal components as columns, 3v × k.
    pub basis: Mat<f64>,
    /// Singular values of the centred data, largest first (all n of them, for the energy table).
    pub singular_values: Vec<f64>,
}

pub fn flatten(frame: &[V3]) -> Vec<f64> {
    frame.iter().flat_map(|p| p.iter().copied()).collect()
}

pub fn unflatten(x: &[f64]) -> Vec<V3> {
    x.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

impl Subspace {
    /// Fits mean and the first `k` components of `frames` (all with the same vertex count). `k` is capped at
    /// the number of non-negligible components (at most n − 1).
    pub fn fit(frames: &[&[V3]], k: usize) -> Result<Self> {
        let n = frames.len();
        if n < 2 {
            return Err(Error::param(
                "k",
                format!("a subspace needs at least 2 frames, got {n}"),
            ));
        }
        if k == 0 {
            return Err(Error::param("k", "must be at least 1"));
        }
        let d = 3 * frames[0].len();
        if let Some(i) = frames.iter().position(|f| 3 * f.len() != d) {
            return Err(Error::mesh(format!(
                "training frame {i} has {} vertices, frame 0 has {}",
                frames[i].len(),
                d / 3
            )));
        }
        let mut mean = vec![0.0; d];
        for f in frames {
            for (m, x) in mean.iter_mut().zip(f.iter().flat_map(|p| p.iter())) {
                *m += x / n as f64;
            }
        }
        let o = Mat::<f64>::from_fn(d, n, |r, c| frames[c][r / 3][r % 3] - mean[r]);
        let gram = o.transpose() * &o;
        let eig = gram
            .self_adjoint_eigen(Side::Lower)
            .map_err(|e| Error::Numeric {
                stage: "subspace".into(),
                msg: format!("Gram eigendecomposition: {e:?}"),
            })?;
        let s = eig.S().column_vector();
        let u = eig.U();
        // Eigenvalues come in increasing order; components in decreasing.
        let lam: Vec<f64> = (0..n).rev().map(|i| s[i].max(0.0)).collect();
        let top = lam[0].max(1e-300);
        let usable = lam.iter().take_while(|&&l| l > top * 1e-12).count();
        let k = k.min(usable).max(1);
        let mut w = Mat::<f64>::zeros(n, k);
        for j in 0..k {
            let src = n - 1 - j;
            let inv = 1.0 / lam[j].sqrt().max(1e-300);
            for i in 0..n {
                w[(i, j)] = u[(i, src)] * inv;
            }
        }
        let basis = &o * &w;
        Ok(Subspace {
            mean,
            basis,
            singular_values: lam.iter().map(|l| l.sqrt()).collect(),
        })
    }

    pub fn k(&self) -> usize {
        self.basis.ncols()
    }

    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// Coefficients λ = Vᵀ(x − mean) of a frame, using the first `k` components.
    pub fn project(&self, frame: &[V3], k: usize) -> Vec<f64> {
        let k = k.min(self.k());
        let x: Vec<f64> = flatten(frame)
            .iter()
            .zip(&self.mean)
            .map(|(a, m)| a - m)
            .collect();
        (0..k)
            .map(|j| {
                let col = self.basis.col(j);
                (0..x.len()).map(|r| col[r] * x[r]).sum()
            })
            .collect()
    }

    /// mean + Σ λ_l V_l for the given coefficients (fewer than k uses the leading components).
    pub fn reconstruct(&self, coeffs: &[f64]) -> Vec<V3> {
        let mut x = self.mean.clone();
        for (j, &c) in coeffs.iter().enumerate().take(self.k()) {
            let col = self.basis.col(j);
            for (r, xr) in x.iter_mut().enumerate() {
                *xr += c * col[r];
            }
        }
        unflatten(&x)
    }

    /// Keeps only the leading `k` components.
    pub fn truncated(&self, k: usize) -> Subspace {
        let k = k.min(self.k()).max(1);
        Subspace {
            mean: self.mean.clone(),
            basis: self.basis.subcols(0, k).to_owned(),
            singular_values: self.singular_values.clone(),
        }
    }
}

/// Mean and 95th-percentile vertex distance between two frames.
pub fn vertex_error(a: &[V3], b: &[V3]) -> (f64, f64) {
    let mut d: Vec<f64> = a
        .iter()
        .zip(b)
        .map(|(p, q)| crease_core::vec3::norm(crease_core::vec3::sub(*p, *q)))
        .collect();
    let mean = d.iter().sum::<f64>() / d.len().max(1) as f64;
    d.sort_by(f64::total_cmp);
    let p95 = d
        .get(((d.len() as f64 * 0.95) as usize).min(d.len().saturating_sub(1)))
        .copied()
        .unwrap_or(0.0);
    (mean, p95)
}
