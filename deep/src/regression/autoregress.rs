//! Autoregressive pose-to-shape regression (Lähner et al. §3.3: the control vector holds the previous shape
//! coefficients as well as the pose).
//!
//! The sleeve's shape depends on its history, which the pose alone does not carry (sleeve-train README: equal
//! poses, meshes 18 mm apart). Feeding α_{t−1} and α_{t−2} back in gives the regression that state; at test time
//! the model is rolled out from the first frame on its own predictions, so errors can accumulate. Two measures
//! keep the rollout stable: only the leading `k_state` coefficients (normalised by their training standard
//! deviation) are fed back, so 240 training frames are not asked to fit a 400-dimensional state; and the fit is
//! repeated on the states the model itself produces when rolled out over the training sequences (DAgger, Ross
//! et al. 2011), so it learns to recover from its own drift instead of only from perfect histories.

use crate::regression::linear::LinearRegression;
use crease_core::{Error, Result};
use serde::{Deserialize, Serialize};

/// Default bound of a fed-back coefficient, in training standard deviations.
pub const CLIP: f64 = 4.0;

/// Which earlier coefficients join the control vector, and how they are normalised.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShapeHistory {
    /// How many leading coefficients are fed back.
    pub k_state: usize,
    /// How many earlier frames (α_{t−1} … α_{t−order}).
    pub order: usize,
    /// 1 / training standard deviation of each fed-back coefficient (0 for a constant one).
    pub scale: Vec<f64>,
    /// Coefficients assumed before the first frame: the mean of the training sequences' first frames (every
    /// sequence starts at rest), so a rollout needs no ground truth of the sequence it predicts.
    pub start: Vec<f64>,
    /// Bound of a fed-back coefficient, in training standard deviations.
    pub clip: f64,
}

impl ShapeHistory {
    /// Statistics from the training coefficients, one slice of frames per sequence.
    pub fn fit(sequences: &[&[Vec<f64>]], k_state: usize, order: usize) -> Result<Self> {
        let all: Vec<&Vec<f64>> = sequences.iter().flat_map(|s| s.iter()).collect();
        let Some(first) = all.first() else {
            return Err(Error::param("autoregression", "no training coefficients"));
        };
        if k_state == 0 || k_state > first.len() {
            return Err(Error::param(
                "autoregression.k_state",
                format!(
                    "must be 1..={} (the subspace size), not {k_state}",
                    first.len()
                ),
            ));
        }
        if order == 0 {
            return Err(Error::param("autoregression.order", "must be at least 1"));
        }
        let n = all.len() as f64;
        let scale = (0..k_state)
            .map(|j| {
                let var = all.iter().map(|a| a[j] * a[j]).sum::<f64>() / n;
                if var > 1e-24 {
                    1.0 / var.sqrt()
                } else {
                    0.0
                }
            })
            .collect();
        let firsts: Vec<&Vec<f64>> = sequences.iter().filter_map(|s| s.first()).collect();
        let start = (0..first.len())
            .map(|j| firsts.iter().map(|a| a[j]).sum::<f64>() / firsts.len() as f64)
            .collect();
        Ok(ShapeHistory {
            k_state,
            order,
            scale,
            start,
            clip: CLIP,
        })
    }

    /// Extra control entries for frame t given the coefficients of the frames before it (`history[t−1]`, …;
    /// frames before the first are [`ShapeHistory::start`]).
    pub fn features(&self, history: &[Vec<f64>], t: usize) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.k_state * self.order);
        for lag in 1..=self.order {
            let a = if t >= lag {
                &history[t - lag]
            } else {
                &self.start
            };
            // Clipped at ±clip standard deviations: a drifting rollout then saturates instead of feeding
            // ever larger states back (and, in DAgger rounds, swamping the ridge's scale with them).
            out.extend(
                (0..self.k_state).map(|j| (a[j] * self.scale[j]).clamp(-self.clip, self.clip)),
            );
        }
        out
    }

    fn augment(&self, control: &[f64], history: &[Vec<f64>], t: usize) -> Vec<f64> {
        let mut c = control.to_vec();
        c.extend(self.features(history, t));
        c
    }
}

/// One training sequence: its control vectors and its true subspace coefficients, frame by frame.
pub type ControlsAndCoefficients<'a> = (&'a [Vec<f64>], &'a [Vec<f64>]);

/// Ridge regression on [pose controls, earlier coefficients], rolled out frame by frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AutoregressiveLinear {
    pub history: ShapeHistory,
    pub regression: LinearRegression,
}

impl AutoregressiveLinear {
    /// Fits on sequences of (control vectors, true coefficients). Round 0 uses the true histories (teacher
    /// forcing); each of the `dagger_rounds` further rounds adds the histories of a rollout over every training
    /// sequence, paired with the true coefficients, and refits.
    pub fn fit(
        sequences: &[ControlsAndCoefficients<'_>],
        history: ShapeHistory,
        alpha: f64,
        dagger_rounds: usize,
    ) -> Result<Self> {
        for (i, (c, a)) in sequences.iter().enumerate() {
            if c.len() != a.len() {
                return Err(Error::param(
                    "autoregression",
                    format!(
                        "sequence {}: {} control vectors for {} coefficient vectors",
                        i + 1,
                        c.len(),
                        a.len()
                    ),
                ));
            }
        }
        let mut controls = Vec::new();
        let mut targets = Vec::new();
        for (c, a) in sequences {
            for t in 0..c.len() {
                controls.push(history.augment(&c[t], a, t));
                targets.push(a[t].clone());
            }
        }
        let mut model = AutoregressiveLinear {
            regression: LinearRegression::fit(&controls, &targets, alpha)?,
            history,
        };
        for _ in 0..dagger_rounds {
            for (c, a) in sequences {
                let rolled = model.rollout(c);
                for t in 0..c.len() {
                    controls.push(model.history.augment(&c[t], &rolled, t));
                    targets.push(a[t].clone());
                }
            }
            model.regression = LinearRegression::fit(&controls, &targets, alpha)?;
        }
        Ok(model)
    }

    /// Coefficients of every frame from the pose controls alone, each frame fed the model's own predictions
    /// for the frames before it.
    pub fn rollout(&self, controls: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let mut out: Vec<Vec<f64>> = Vec::with_capacity(controls.len());
        for (t, c) in controls.iter().enumerate() {
            let x = self.history.augment(c, &out, t);
            out.push(self.regression.predict(&x));
        }
        out
    }

    /// One step with the true history (teacher forcing), for comparison with the rollout.
    pub fn one_step(&self, controls: &[Vec<f64>], truth: &[Vec<f64>]) -> Vec<Vec<f64>> {
        (0..controls.len())
            .map(|t| {
                self.regression
                    .predict(&self.history.augment(&controls[t], truth, t))
            })
            .collect()
    }
}
