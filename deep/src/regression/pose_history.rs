//! Exponentially decayed pose history as regression features.
//!
//! The sleeve's folds depend on how the cuff got to its pose, not only on the pose (sleeve-train README: equal
//! poses, meshes 18 mm apart). Feeding back the model's own shapes carries that history but drifts when rolled
//! out; fixed pose lags carry it but made the linear map worse over the leave-one-sequence-out splits
//! (docs/deepwrinkles.md). A leaky average of the pose, h_t = d·h_{t−1} + (1 − d)·p_t with d = exp(−1/τ), is a
//! linear, stable-by-construction summary of the last ~τ frames computed from the pose file alone, so it cannot
//! drift; several time constants let the regression pick how far back the cloth remembers. The feature is
//! p_t − h_t (what the pose did recently, zero at rest), standardised on the training data so the ridge treats
//! every time constant alike.

use crease_core::{Error, Result};
use serde::{Deserialize, Serialize};

/// Time constants (frames) and the standardisation of p − h per time constant and pose dimension.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DecayedHistory {
    pub time_constants: Vec<f64>,
    /// 1 / training standard deviation of p − h, row-major (time constant, pose dimension); 0 for a feature
    /// that never moves.
    pub scale: Vec<f64>,
}

impl DecayedHistory {
    /// Standardisation from the (already normalised) poses of every training sequence.
    pub fn fit(sequences: &[Vec<Vec<f64>>], time_constants: &[f64]) -> Result<Self> {
        if let Some(t) = time_constants
            .iter()
            .find(|t| !(t.is_finite() && **t > 0.0))
        {
            return Err(Error::param(
                "pose_history",
                format!("time constant {t} is not a positive number of frames"),
            ));
        }
        let dim = sequences
            .iter()
            .find_map(|s| s.first().map(|p| p.len()))
            .ok_or_else(|| Error::param("pose_history", "no training poses"))?;
        let mut unscaled = DecayedHistory {
            time_constants: time_constants.to_vec(),
            scale: vec![1.0; time_constants.len() * dim],
        };
        let mut sum_sq = vec![0.0; unscaled.scale.len()];
        let mut n = 0usize;
        for s in sequences {
            for f in unscaled.features(s) {
                for (acc, x) in sum_sq.iter_mut().zip(&f) {
                    *acc += x * x;
                }
                n += 1;
            }
        }
        unscaled.scale = sum_sq
            .iter()
            .map(|s| {
                let var = s / n.max(1) as f64;
                if var > 1e-18 {
                    1.0 / var.sqrt()
                } else {
                    0.0
                }
            })
            .collect();
        Ok(unscaled)
    }

    /// Number of features per frame for poses of `pose_dim` numbers.
    pub fn len(&self, pose_dim: usize) -> usize {
        self.time_constants.len() * pose_dim
    }

    /// Features of every frame of one sequence of normalised poses. The average starts at the first pose (every
    /// sequence starts at rest), so frame t depends on frames 1..=t only.
    pub fn features(&self, poses: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let dim = poses.first().map_or(0, |p| p.len());
        let decays: Vec<f64> = self
            .time_constants
            .iter()
            .map(|t| (-1.0 / t).exp())
            .collect();
        let mut h: Vec<Vec<f64>> = decays
            .iter()
            .map(|_| poses.first().cloned().unwrap_or_default())
            .collect();
        poses
            .iter()
            .map(|p| {
                let mut out = Vec::with_capacity(self.len(dim));
                for (i, d) in decays.iter().enumerate() {
                    for j in 0..dim {
                        h[i][j] = d * h[i][j] + (1.0 - d) * p[j];
                        out.push((p[j] - h[i][j]) * self.scale[i * dim + j]);
                    }
                }
                out
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp_and_hold(n: usize) -> Vec<Vec<f64>> {
        (0..n)
            .map(|t| vec![(t.min(20) as f64) / 20.0, 0.5])
            .collect()
    }

    #[test]
    fn features_are_standardised_zero_at_rest_and_causal() {
        let seq = ramp_and_hold(120);
        let h = DecayedHistory::fit(std::slice::from_ref(&seq), &[3.0, 30.0]).unwrap();
        let f = h.features(&seq);
        assert_eq!(f.len(), 120);
        assert_eq!(f[0].len(), h.len(2));
        // At rest (first frame) nothing has happened yet.
        assert!(f[0].iter().all(|x| x.abs() < 1e-12), "{:?}", f[0]);
        // The constant pose dimension gives no feature.
        assert!(f.iter().all(|r| r[1] == 0.0 && r[3] == 0.0));
        // Unit variance over the training frames for the moving dimension, both time constants.
        for col in [0, 2] {
            let var = f.iter().map(|r| r[col] * r[col]).sum::<f64>() / f.len() as f64;
            assert!((var - 1.0).abs() < 1e-9, "column {col}: variance {var}");
        }
        // The short memory forgets the ramp sooner than the long one after the pose stops moving.
        let ratio = |c: usize, t: usize| f[t][c].abs() / f[20][c].abs();
        assert!(ratio(0, 40) < 0.01 && ratio(2, 40) > 0.4);
        // Causal: changing later poses leaves earlier features alone.
        let mut later = seq.clone();
        later[60][0] = 5.0;
        let g = h.features(&later);
        assert_eq!(&f[..60], &g[..60]);
        assert_ne!(f[60], g[60]);
    }

    #[test]
    fn bad_time_constants_are_refused() {
        let seq = ramp_and_hold(10);
        for bad in [0.0, -2.0, f64::NAN] {
            let e = DecayedHistory::fit(std::slice::from_ref(&seq), &[bad]).unwrap_err();
            assert!(e.to_string().contains("time constant"), "{e}");
        }
    }
}
