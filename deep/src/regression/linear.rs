//! Linear pose-to-shape regression (Lähner et al. §3.3): F = Λ Θ†.
//!
//! The pseudo-inverse is taken through the eigendecomposition of the small Gram matrix ΘᵀΘ (control length ×
//! control length), with a ridge term: with 240 training frames and strongly correlated lagged poses, the plain
//! pseudo-inverse fits noise; the ridge keeps the map smooth where the data is thin.

use crease_core::{Error, Result};
use faer::{Mat, Side};
use serde::{Deserialize, Serialize};

/// Λ ≈ W Θ: `weights` is k × m, row-major.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinearRegression {
    pub k: usize,
    pub m: usize,
    pub weights: Vec<f64>,
}

impl LinearRegression {
    /// Fits `targets[i] ≈ W controls[i]` in the least-squares sense with ridge `alpha` (relative to the mean
    /// diagonal of ΘᵀΘ).
    pub fn fit(controls: &[Vec<f64>], targets: &[Vec<f64>], alpha: f64) -> Result<Self> {
        let n = controls.len();
        if n == 0 || n != targets.len() {
            return Err(Error::param(
                "regression",
                format!("{} control vectors for {} targets", n, targets.len()),
            ));
        }
        let m = controls[0].len();
        let k = targets[0].len();
        let theta = Mat::<f64>::from_fn(n, m, |i, j| controls[i][j]);
        let lam = Mat::<f64>::from_fn(n, k, |i, j| targets[i][j]);
        let mut g = theta.transpose() * &theta;
        let mean_diag = (0..m).map(|i| g[(i, i)]).sum::<f64>() / m as f64;
        for i in 0..m {
            g[(i, i)] += alpha * mean_diag;
        }
        let eig = g
            .self_adjoint_eigen(Side::Lower)
            .map_err(|e| Error::Numeric {
                stage: "linear regression".into(),
                msg: format!("eigendecomposition of ΘᵀΘ: {e:?}"),
            })?;
        let s = eig.S().column_vector();
        let u = eig.U();
        let smax = (0..m).map(|i| s[i]).fold(0.0f64, f64::max);
        // (ΘᵀΘ)⁺ = U diag(1/s) Uᵀ over the non-negligible eigenvalues.
        let mut uinv = u.to_owned();
        for j in 0..m {
            let inv = if s[j] > smax * 1e-12 { 1.0 / s[j] } else { 0.0 };
            for i in 0..m {
                uinv[(i, j)] *= inv;
            }
        }
        let pinv = &uinv * u.transpose();
        let tl = theta.transpose() * &lam; // m × k
        let w = &pinv * &tl; // m × k
        let mut weights = vec![0.0; k * m];
        for r in 0..k {
            for c in 0..m {
                weights[r * m + c] = w[(c, r)];
            }
        }
        Ok(LinearRegression { k, m, weights })
    }

    pub fn predict(&self, control: &[f64]) -> Vec<f64> {
        (0..self.k)
            .map(|r| {
                self.weights[r * self.m..(r + 1) * self.m]
                    .iter()
                    .zip(control)
                    .map(|(a, b)| a * b)
                    .sum()
            })
            .collect()
    }
}
