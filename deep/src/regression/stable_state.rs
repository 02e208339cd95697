//! Spectral radius of the autoregressive regressor's state recurrence, and its projection below a bound.
//!
//! Rolled out, the regressor is a linear recurrence on its fed-back state s_t (the leading coefficients of
//! α_t, scaled): s_t = D·(A₁ s_{t−1} + A₂ s_{t−2}) + (pose terms), with D the state scale and A₁, A₂ the
//! weight columns of the two fed-back frames. Its companion matrix [[D A₁, D A₂], [I, 0]] decides whether an
//! error made at one frame dies out or grows: with a spectral radius ≥ 1 it never dies out and the rollout
//! drifts (the clip of the fed-back state is then all that bounds it). Scaling A₁ by c and A₂ by c² scales
//! every eigenvalue of the companion matrix by c exactly, so the projection can put the radius where it is
//! asked while keeping the recurrence's modes (their frequencies and relative weights) as fitted.

use crate::regression::autoregress::AutoregressiveLinear;
use crease_core::{Error, Result};
use faer::Mat;

/// Columns of the regression's input where the fed-back state starts (after the pose controls).
fn state_start(ar: &AutoregressiveLinear) -> usize {
    ar.regression.m - ar.history.k_state * ar.history.order
}

/// The companion matrix of the state recurrence (k_state · order square).
pub fn companion(ar: &AutoregressiveLinear) -> Mat<f64> {
    let h = &ar.history;
    let (ks, order, m) = (h.k_state, h.order, ar.regression.m);
    let c0 = state_start(ar);
    let n = ks * order;
    let w = &ar.regression.weights;
    Mat::from_fn(n, n, |i, j| {
        if i < ks {
            // Row i of D·A_lag, lag = j / ks + 1.
            h.scale[i] * w[i * m + c0 + j]
        } else if i - ks == j {
            1.0
        } else {
            0.0
        }
    })
}

/// Largest eigenvalue modulus of [`companion`].
pub fn spectral_radius(ar: &AutoregressiveLinear) -> Result<f64> {
    let eig = companion(ar).eigenvalues().map_err(|e| Error::Numeric {
        stage: "autoregressive state".into(),
        msg: format!("eigenvalues of the state recurrence: {e:?}"),
    })?;
    Ok(eig
        .iter()
        .map(|z| (z.re * z.re + z.im * z.im).sqrt())
        .fold(0.0, f64::max))
}

/// Scales the fed-back weight columns so the spectral radius is at most `max_radius` (lag l's columns by
/// c^l). Returns the radius before and after; a recurrence already inside the bound is left unchanged.
pub fn project(ar: &mut AutoregressiveLinear, max_radius: f64) -> Result<(f64, f64)> {
    if !(max_radius.is_finite() && max_radius > 0.0) {
        return Err(Error::param(
            "ar_max_radius",
            format!("{max_radius} is not a positive number"),
        ));
    }
    let before = spectral_radius(ar)?;
    if before <= max_radius {
        return Ok((before, before));
    }
    let c = max_radius / before;
    let (ks, m, c0) = (ar.history.k_state, ar.regression.m, state_start(ar));
    for r in 0..ar.regression.k {
        for lag in 1..=ar.history.order {
            let f = c.powi(lag as i32);
            for j in 0..ks {
                ar.regression.weights[r * m + c0 + (lag - 1) * ks + j] *= f;
            }
        }
    }
    Ok((before, spectral_radius(ar)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::regression::autoregress::ShapeHistory;
    use crate::regression::linear::LinearRegression;

    /// One pose control plus a bias; k = 2 coefficients, both fed back, order 2, unit scale.
    fn model(a1: [[f64; 2]; 2], a2: [[f64; 2]; 2]) -> AutoregressiveLinear {
        let mut weights = Vec::new();
        for r in 0..2 {
            weights.extend([0.3, 0.0, a1[r][0], a1[r][1], a2[r][0], a2[r][1]]);
        }
        AutoregressiveLinear {
            history: ShapeHistory {
                k_state: 2,
                order: 2,
                scale: vec![1.0, 1.0],
                start: vec![0.0, 0.0],
                clip: 1e9,
            },
            regression: LinearRegression {
                k: 2,
                m: 6,
                weights,
            },
        }
    }

    #[test]
    fn radius_of_a_known_recurrence_and_its_projection() {
        // s_t = 1.5 s_{t−1} − 0.56 s_{t−2} per coefficient: roots 0.8 and 0.7; the second coefficient
        // s_t = 1.1 s_{t−1}: roots 1.1 and 0.
        let mut ar = model([[1.5, 0.0], [0.0, 1.1]], [[-0.56, 0.0], [0.0, 0.0]]);
        let rho = spectral_radius(&ar).unwrap();
        assert!((rho - 1.1).abs() < 1e-9, "{rho}");
        let (before, after) = project(&mut ar, 0.9).unwrap();
        assert!(
            (before - 1.1).abs() < 1e-9 && (after - 0.9).abs() < 1e-9,
            "{before} {after}"
        );
        // The pose columns are untouched; the lag-2 column is scaled by c².
        let c = 0.9 / 1.1;
        assert_eq!(ar.regression.weights[0], 0.3);
        assert!((ar.regression.weights[4] + 0.56 * c * c).abs() < 1e-12);
        // A rolled-out impulse now dies out instead of growing.
        let mut controls = vec![vec![0.0, 0.0]; 200];
        controls[0] = vec![1.0, 0.0];
        let out = ar.rollout(&controls);
        assert!(
            out[199][1].abs() < 1e-6 * out[5][1].abs(),
            "{:?} {:?}",
            out[5],
            out[199]
        );
        // Inside the bound: unchanged.
        let before_w = ar.regression.weights.clone();
        project(&mut ar, 0.95).unwrap();
        assert_eq!(ar.regression.weights, before_w);
        assert!(project(&mut ar, 0.0).is_err());
    }
}
