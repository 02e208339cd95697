//! The blend regressor: a weighted mean of the pose-only linear map and the autoregressive rollout.
//!
//! The two regressors fail differently on an unseen motion: the linear map has no memory, so it misses the
//! shape the cloth keeps from earlier poses; the rollout has that memory but drifts, since it feeds its own
//! errors back. Their errors partly cancel (on sleeve-train an even blend measured 6.85 mm against 7.20 mm
//! for the rollout and 7.57 mm for the linear map, leave one sequence out), so the blend is worth storing.
//!
//! The weight is fitted without touching the held-out motion: an inner leave-one-out over the training
//! sequences ([`crate::train::inner_blend_weight`]) gives each training sequence the two regressors' predictions
//! from models that never saw it, and the weight is the least-squares one over those predictions. The
//! subspace basis is orthonormal, so the least-squares weight on coefficients is also the one on vertex
//! positions.

use crease_core::{Error, Result};
use serde::{Deserialize, Serialize};

/// How a model's blend weight was chosen (stored in its manifest).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BlendSpec {
    /// Weight of the autoregressive rollout; the linear map gets 1 − weight.
    pub weight: f64,
    /// `inner-leave-one-out` (fitted) or `fixed` (given, or fewer than two training sequences).
    pub method: String,
    /// Least-squares weight of each inner fold alone (its held-out training sequence), before clamping, for
    /// people judging how stable the fitted weight is (none where a fold's two predictions coincide); empty
    /// when fixed.
    #[serde(default)]
    pub fold_weights: Vec<Option<f64>>,
}

impl BlendSpec {
    pub fn fixed(weight: f64) -> Result<Self> {
        check_weight(weight)?;
        Ok(BlendSpec {
            weight,
            method: "fixed".into(),
            fold_weights: Vec::new(),
        })
    }
}

/// Refuses a weight outside [0, 1] (an extrapolation, not a blend) or one that is not a number.
pub fn check_weight(weight: f64) -> Result<()> {
    if weight.is_finite() && (0.0..=1.0).contains(&weight) {
        Ok(())
    } else {
        Err(Error::param(
            "blend_weight",
            format!("{weight} is not a weight in 0..=1"),
        ))
    }
}

/// (1 − w) · linear + w · autoregressive, frame by frame. w = 0 and w = 1 return the parts
/// exactly (up to the sign of a zero).
pub fn mix(linear: &[Vec<f64>], autoregressive: &[Vec<f64>], w: f64) -> Vec<Vec<f64>> {
    linear
        .iter()
        .zip(autoregressive)
        .map(|(l, a)| {
            l.iter()
                .zip(a)
                .map(|(&x, &y)| (1.0 - w) * x + w * y)
                .collect()
        })
        .collect()
}

/// Sufficient statistics of the least-squares weight: Σ ⟨a − l, t − l⟩ and Σ ‖a − l‖² over frames.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WeightFit {
    pub num: f64,
    pub den: f64,
}

impl WeightFit {
    /// Adds frames with linear predictions `l`, autoregressive ones `a` and the truth `t`.
    pub fn add(&mut self, l: &[Vec<f64>], a: &[Vec<f64>], t: &[Vec<f64>]) {
        for ((l, a), t) in l.iter().zip(a).zip(t) {
            for j in 0..l.len() {
                let d = a[j] - l[j];
                self.num += d * (t[j] - l[j]);
                self.den += d * d;
            }
        }
    }

    /// The weight minimising Σ ‖(1 − w) l + w a − t‖², unclamped; `None` when the two predictions coincide.
    pub fn raw(&self) -> Option<f64> {
        (self.den > 0.0 && self.num.is_finite()).then(|| self.num / self.den)
    }

    /// The least-squares weight clamped to [0, 1] (0.5 when the two predictions coincide: any weight fits).
    pub fn weight(&self) -> f64 {
        self.raw().map_or(0.5, |w| w.clamp(0.0, 1.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(seed: u64, n: usize, k: usize) -> Vec<Vec<f64>> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                (0..k)
                    .map(|_| {
                        s = s
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
                    })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn weights_zero_and_one_give_the_parts_exactly() {
        let (l, a) = (frames(1, 7, 5), frames(2, 7, 5));
        assert_eq!(mix(&l, &a, 0.0), l);
        assert_eq!(mix(&l, &a, 1.0), a);
        let half = mix(&l, &a, 0.5);
        assert_eq!(half[3][2], 0.5 * l[3][2] + 0.5 * a[3][2]);
        assert_ne!(half, l);
    }

    #[test]
    fn least_squares_weight_recovers_a_known_mixture() {
        let (l, a) = (frames(3, 40, 6), frames(4, 40, 6));
        let t = mix(&l, &a, 0.3);
        let mut f = WeightFit::default();
        f.add(&l, &a, &t);
        assert!((f.weight() - 0.3).abs() < 1e-12, "{}", f.weight());
        // Noise orthogonal in expectation moves it only a little; a truth beyond the rollout clamps to 1.
        let beyond = mix(&l, &a, 1.7);
        let mut g = WeightFit::default();
        g.add(&l, &a, &beyond);
        assert!((g.raw().unwrap() - 1.7).abs() < 1e-12);
        assert_eq!(g.weight(), 1.0);
        // Identical predictions: no information, the even blend.
        let mut h = WeightFit::default();
        h.add(&l, &l, &t);
        assert_eq!(h.raw(), None);
        assert_eq!(h.weight(), 0.5);
    }

    #[test]
    fn weights_outside_the_unit_interval_are_refused() {
        for w in [-0.1, 1.5, f64::NAN] {
            let e = BlendSpec::fixed(w).unwrap_err().to_string();
            assert!(e.contains("blend_weight"), "{e}");
        }
        assert_eq!(BlendSpec::fixed(0.5).unwrap().weight, 0.5);
    }
}
