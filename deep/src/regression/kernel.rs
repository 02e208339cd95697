//! Kernel ridge regression from a short window of poses to subspace coefficients.
//!
//! How the sleeve folds is not linear in the pose: where along the arm the cloth bunches depends on how far the
//! cuff has travelled *and* how far it has turned, and on how it got there over the last few frames. The linear
//! map (Lähner et al. §3.3) can only add those effects up; the autoregressive rollout carries the history but
//! drifts. A Gaussian kernel over a window of recent poses lets nearby pose trajectories share their shapes
//! and far ones not, with no feedback and so no drift: the prediction of frame t reads poses t − w … t only.
//!
//! The inputs are the pose file's own numbers (not the rigid features' products and sines, which would count
//! the location several times in a distance and fold the angle's sign into a cosine: on sleeve-train the
//! location and the sine and cosine of the twist measured 3.84–3.88 mm held out where the location and the
//! angle measured 3.51 mm), each standardised on the training poses, at the frame and at a few earlier frames
//! (`window`). The kernel is exp(−(w / d)‖x − y‖²) for inputs of d varying numbers (constant ones do not
//! count), so its relative width w means the same for any window and pose size; w and the ridge λ are chosen by an inner leave-one-sequence-out over the
//! training sequences (a sequence and its reflection held out together): nothing of the held-out motion
//! decides them.
//!
//! Not every number of the window matters alike: the frame's own pose says more about its folds than the pose
//! six frames back, and one pose number (how far the cuff travelled) may move the cloth more per standard
//! deviation than another (how far it turned). One width for all of them makes a distance that counts the
//! oldest lag as much as the newest. So each input number is weighted, by a decay per frame of lag and a
//! factor per pose number ([`InputWeights`]), searched by the same inner leave-one-out one coordinate at a
//! time (the decay, then each varying pose number's factor); the weights are normalised to a root mean square
//! of 1 over the varying numbers, so the width keeps its meaning. On sleeve-train the search weighs the newest
//! poses most and the cuff's travel above its twist (bench/results/2026-12-07-deep-kernel-weights.md).

use crease_core::{Error, Result};
use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Relative kernel widths tried by the inner leave-one-out (γ · d: the inverse squared distance, in standard
/// deviations per input number, at which two frames' weights fall to 1/e).
pub const WIDTHS: [f64; 5] = [0.125, 0.25, 0.5, 1.0, 2.0];
/// Ridges tried (the kernel's diagonal is 1).
pub const RIDGES: [f64; 3] = [1e-3, 1e-2, 1e-1];
/// A frame whose input lies further than this from every training frame's ([`KernelRegression::distances`])
/// is outside what the regression learned: it predicts little more than the mean shape there, and says so.
pub const OUTSIDE: f64 = 0.75;
/// Width and ridge when there is no second training sequence to choose them on.
pub const FALLBACK: (f64, f64) = (0.5, 1e-2);
/// Decays per frame of lag tried by the weight search (besides 1, no decay).
pub const DECAYS: [f64; 3] = [0.63, 0.84, 1.18];
/// Factors a varying pose number's weight is tried at, one number at a time, after the decay.
pub const NUMBER_FACTORS: [f64; 2] = [0.5, 2.0];
/// Times one factor is applied in a row while it lowers the inner error (a weight moves by at most 8×).
pub const FACTOR_STEPS: usize = 3;
/// Pose files with more varying numbers than this get the decay only: each number costs two or more inner
/// leave-one-outs, and a rig of many joints would spend an hour on them.
pub const MAX_WEIGHED_NUMBERS: usize = 8;

/// How much each input number counts in the kernel's distance: pose number j at window lag l is weighted
/// `decay^l · numbers[j]`, the whole normalised to a root mean square of 1 over the varying numbers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputWeights {
    /// Weight factor per frame of lag (1: the oldest pose counts as much as the newest).
    pub decay: f64,
    /// Factor per pose number (constant ones are unused).
    pub numbers: Vec<f64>,
}

impl InputWeights {
    /// Every number alike: the kernel of models trained before the weights existed.
    pub fn uniform(numbers: usize) -> Self {
        InputWeights {
            decay: 1.0,
            numbers: vec![1.0; numbers],
        }
    }

    /// Per input number (window-lag-major, as [`window_inputs`] lays them out), normalised over the numbers
    /// whose `scale` is nonzero.
    pub fn per_input(&self, scale: &[f64], window: &[usize]) -> Vec<f64> {
        let raw: Vec<f64> = window
            .iter()
            .flat_map(|&lag| {
                let d = self.decay.powi(lag.min(i32::MAX as usize) as i32);
                self.numbers.iter().map(move |w| d * w)
            })
            .collect();
        let (sum, count) = raw
            .iter()
            .zip(scale.iter().cycle())
            .filter(|(_, s)| **s != 0.0)
            .fold((0.0, 0usize), |(a, c), (w, _)| (a + w * w, c + 1));
        let norm = if count > 0 && sum > 0.0 {
            (sum / count as f64).sqrt()
        } else {
            1.0
        };
        raw.iter().map(|w| w / norm).collect()
    }
}

/// One weighting the search tried and its best inner leave-one-out error over the widths and ridges.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WeightTrial {
    pub weights: InputWeights,
    pub error: f64,
}

/// The scalar part of a kernel regression, stored in the model's manifest; its arrays are files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KernelSpec {
    /// Earlier frames whose poses join the input (0 is the frame itself; clamped at the first frame).
    pub window: Vec<usize>,
    /// Per pose number: mean and scale (1 / std, 0 for a constant number).
    pub mean: Vec<f64>,
    pub scale: Vec<f64>,
    /// Relative width (γ · d) and ridge.
    pub width: f64,
    pub ridge: f64,
    /// Training frames (the kernel's centres).
    pub centres: usize,
    /// `inner-leave-one-out` or `fixed` (fewer than two training sequences).
    pub method: String,
    /// Inner leave-one-out error of every (width, ridge) tried: mean squared coefficient error (m², the
    /// subspace's basis is orthonormal, so per vertex coordinate summed over the coefficients), for people
    /// judging how sharp the choice was; empty when fixed.
    #[serde(default)]
    pub scores: Vec<[f64; 3]>,
    /// How much each input number counts ([`InputWeights`]); uniform in models trained before it existed.
    #[serde(default)]
    pub weights: Option<InputWeights>,
    /// Every weighting the search tried, in order, with its inner leave-one-out error; empty when fixed.
    #[serde(default)]
    pub weight_trials: Vec<WeightTrial>,
}

/// γ, the centres, their dual weights and the coefficients' mean.
#[derive(Debug, Clone, PartialEq)]
pub struct KernelRegression {
    pub spec: KernelSpec,
    /// Centres, `centres × input_len`, row-major.
    pub inputs: Vec<f64>,
    /// Dual weights, `centres × k`, row-major.
    pub dual: Vec<f64>,
    /// Mean training coefficients (k).
    pub offset: Vec<f64>,
}

/// Inputs of every frame of one sequence of pose numbers: the standardised numbers at each window lag.
pub fn window_inputs(
    numbers: &[Vec<f64>],
    mean: &[f64],
    scale: &[f64],
    window: &[usize],
) -> Vec<Vec<f64>> {
    let z: Vec<Vec<f64>> = numbers
        .iter()
        .map(|r| {
            r.iter()
                .zip(mean.iter().zip(scale))
                .map(|(x, (m, s))| (x - m) * s)
                .collect()
        })
        .collect();
    (0..z.len())
        .map(|t| {
            window
                .iter()
                .flat_map(|&lag| z[t.saturating_sub(lag)].iter().copied())
                .collect()
        })
        .collect()
}

fn sq_dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The numbers of an input that vary: the pose numbers with a nonzero scale, once per window lag. The width is
/// relative to this count, so that a pose file's constant numbers (a fixed object, an unused axis) change nothing.
pub fn varying_len(scale: &[f64], window: &[usize]) -> usize {
    (scale.iter().filter(|s| **s != 0.0).count() * window.len()).max(1)
}

/// Dual weights (K + λI)⁻¹ (Y − offset) for centres `x`, targets `y` (n × k), at γ = `gamma`.
fn solve(x: &[Vec<f64>], y: &[Vec<f64>], gamma: f64, ridge: f64) -> Result<(Mat<f64>, Vec<f64>)> {
    let (n, k) = (x.len(), y[0].len());
    let offset: Vec<f64> = (0..k)
        .map(|j| y.iter().map(|r| r[j]).sum::<f64>() / n as f64)
        .collect();
    let rows: Vec<Vec<f64>> = (0..n)
        .into_par_iter()
        .map(|i| {
            (0..n)
                .map(|j| (-gamma * sq_dist(&x[i], &x[j])).exp() + if i == j { ridge } else { 0.0 })
                .collect()
        })
        .collect();
    let kmat = Mat::<f64>::from_fn(n, n, |i, j| rows[i][j]);
    let rhs = Mat::<f64>::from_fn(n, k, |i, j| y[i][j] - offset[j]);
    let llt = kmat.llt(Side::Lower).map_err(|e| Error::Numeric {
        stage: "kernel regression".into(),
        msg: format!("Cholesky factorisation of the kernel matrix: {e:?}"),
    })?;
    Ok((llt.solve(&rhs), offset))
}

fn predict_with(
    centres: &[Vec<f64>],
    dual: &Mat<f64>,
    offset: &[f64],
    gamma: f64,
    x: &[f64],
) -> Vec<f64> {
    let mut out = offset.to_vec();
    for (i, c) in centres.iter().enumerate() {
        let w = (-gamma * sq_dist(c, x)).exp();
        if w < 1e-300 {
            continue;
        }
        for (j, o) in out.iter_mut().enumerate() {
            *o += w * dual[(i, j)];
        }
    }
    out
}

/// One training sequence's inputs and target coefficients; `group` ties a sequence to its reflection.
pub struct KernelData<'a> {
    pub inputs: &'a [Vec<f64>],
    pub targets: &'a [Vec<f64>],
    pub group: usize,
}

impl KernelRegression {
    /// Fits on every sequence of `data` (inputs as [`window_inputs`] makes them, unweighted) with the input
    /// weights (uniform unless `search_weights`), width and ridge that predicted the held-out groups best in an
    /// inner leave-one-group-out (or uniform weights and [`FALLBACK`] with a single group).
    pub fn fit(
        data: &[KernelData<'_>],
        window: Vec<usize>,
        mean: Vec<f64>,
        scale: Vec<f64>,
        search_weights: bool,
    ) -> Result<Self> {
        if data.iter().any(|d| d.inputs.len() != d.targets.len()) || data.is_empty() {
            return Err(Error::param(
                "kernel regression",
                "every training sequence needs one input per target",
            ));
        }
        let varying = varying_len(&scale, &window) as f64;
        let mut groups: Vec<usize> = data.iter().map(|d| d.group).collect();
        groups.sort_unstable();
        groups.dedup();
        let mut trials = Vec::new();
        let (weights, width, ridge, method, scores) = if groups.len() < 2 {
            let w = InputWeights::uniform(mean.len());
            (w, FALLBACK.0, FALLBACK.1, "fixed", Vec::new())
        } else {
            let mut try_weights =
                |w: InputWeights| -> Result<(InputWeights, Vec<[f64; 3]>, [f64; 3])> {
                    let scores =
                        inner_scores(data, &groups, &w.per_input(&scale, &window), varying)?;
                    let best = best_score(&scores)?;
                    trials.push(WeightTrial {
                        weights: w.clone(),
                        error: best[2],
                    });
                    Ok((w, scores, best))
                };
            let mut chosen = try_weights(InputWeights::uniform(mean.len()))?;
            let decays: &[f64] = if search_weights { &DECAYS } else { &[] };
            for &decay in decays {
                let candidate = try_weights(InputWeights {
                    decay,
                    ..chosen.0.clone()
                })?;
                if candidate.2[2] < chosen.2[2] {
                    chosen = candidate;
                }
            }
            // One varying number alone has nothing to be weighed against (the normalisation undoes a factor);
            // many are left alike (MAX_WEIGHED_NUMBERS).
            let varying_numbers: Vec<usize> =
                (0..scale.len()).filter(|&j| scale[j] != 0.0).collect();
            if search_weights && (2..=MAX_WEIGHED_NUMBERS).contains(&varying_numbers.len()) {
                for &j in &varying_numbers {
                    for &f in &NUMBER_FACTORS {
                        // Further the same way while it helps, up to FACTOR_STEPS times.
                        for _ in 0..FACTOR_STEPS {
                            let mut w = chosen.0.clone();
                            w.numbers[j] *= f;
                            let candidate = try_weights(w)?;
                            if candidate.2[2] < chosen.2[2] {
                                chosen = candidate;
                            } else {
                                break;
                            }
                        }
                    }
                }
            }
            let (w, scores, best) = chosen;
            (w, best[0], best[1], "inner-leave-one-out", scores)
        };
        let per_input = weights.per_input(&scale, &window);
        let weighted = weigh_all(data, &per_input);
        let (x, y) = gather(data, &weighted, |_| true);
        let (dual, offset) = solve(&x, &y, width / varying, ridge)?;
        let k = offset.len();
        Ok(KernelRegression {
            spec: KernelSpec {
                window,
                mean,
                scale,
                width,
                ridge,
                centres: x.len(),
                method: method.into(),
                scores,
                weights: Some(weights),
                weight_trials: trials,
            },
            inputs: x.iter().flat_map(|r| r.iter().copied()).collect(),
            dual: (0..x.len())
                .flat_map(|i| (0..k).map(move |j| (i, j)))
                .map(|(i, j)| dual[(i, j)])
                .collect(),
            offset,
        })
    }

    /// Length of one input (pose numbers × window).
    pub fn input_len(&self) -> usize {
        self.spec.mean.len() * self.spec.window.len()
    }

    /// The inputs of every frame of one sequence of pose numbers, standardised as the training poses were.
    fn window_inputs(&self, numbers: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let inputs = window_inputs(
            numbers,
            &self.spec.mean,
            &self.spec.scale,
            &self.spec.window,
        );
        match &self.spec.weights {
            Some(w) => {
                let per_input = w.per_input(&self.spec.scale, &self.spec.window);
                inputs.iter().map(|x| weigh(x, &per_input)).collect()
            }
            None => inputs,
        }
    }

    /// Per frame of one sequence of pose numbers: how far its input lies from the nearest training frame's, as
    /// the root mean square over the varying numbers, in training standard deviations. Unweighted: a number
    /// the kernel weighs lightly still counts in full here, because a pose far outside the training range in
    /// any number is one the regression never saw (a twist twice the largest trained must be named even where
    /// the kernel found the twist to matter less than the travel). Held-out motions of sleeve-train stay within
    /// 0.3; a twist twice as large as any trained reaches 1.3–1.5.
    pub fn distances(&self, numbers: &[Vec<f64>]) -> Vec<f64> {
        let d = self.input_len();
        let varying = varying_len(&self.spec.scale, &self.spec.window) as f64;
        let centres: Vec<f64> = match &self.spec.weights {
            Some(w) => {
                let per_input = w.per_input(&self.spec.scale, &self.spec.window);
                self.inputs
                    .chunks_exact(d)
                    .flat_map(|c| c.iter().zip(&per_input).map(|(v, w)| v / w))
                    .collect()
            }
            None => self.inputs.clone(),
        };
        window_inputs(
            numbers,
            &self.spec.mean,
            &self.spec.scale,
            &self.spec.window,
        )
        .par_iter()
        .map(|x| {
            let nearest = centres
                .chunks_exact(d)
                .map(|c| sq_dist(c, x))
                .fold(f64::INFINITY, f64::min);
            (nearest / varying).sqrt()
        })
        .collect()
    }

    /// Coefficients of every frame of one sequence of pose numbers.
    pub fn predict_sequence(&self, numbers: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let d = self.input_len();
        let gamma = self.spec.width / varying_len(&self.spec.scale, &self.spec.window) as f64;
        let k = self.offset.len();
        self.window_inputs(numbers)
            .par_iter()
            .map(|x| {
                let mut out = self.offset.clone();
                for (c, w) in self.inputs.chunks_exact(d).zip(self.dual.chunks_exact(k)) {
                    let a = (-gamma * sq_dist(c, x)).exp();
                    if a < 1e-300 {
                        continue;
                    }
                    for (o, wj) in out.iter_mut().zip(w) {
                        *o += a * wj;
                    }
                }
                out
            })
            .collect()
    }

    /// Checks the arrays against the spec (a loaded model).
    pub fn check(&self) -> std::result::Result<(), String> {
        let s = &self.spec;
        if s.mean.len() != s.scale.len() || s.window.is_empty() {
            return Err(format!(
                "{} means, {} scales, window {:?}",
                s.mean.len(),
                s.scale.len(),
                s.window
            ));
        }
        if self.inputs.len() != s.centres * self.input_len()
            || self.dual.len() != s.centres * self.offset.len()
        {
            return Err(format!(
                "{} input numbers and {} dual weights for {} centres of {} numbers and {} coefficients",
                self.inputs.len(),
                self.dual.len(),
                s.centres,
                self.input_len(),
                self.offset.len()
            ));
        }
        if !(s.width.is_finite() && s.width > 0.0 && s.ridge.is_finite() && s.ridge >= 0.0) {
            return Err(format!("width {} or ridge {}", s.width, s.ridge));
        }
        if let Some(w) = &s.weights {
            let positive = |v: f64| v.is_finite() && v > 0.0;
            if w.numbers.len() != s.mean.len()
                || !positive(w.decay)
                || !w.numbers.iter().all(|v| positive(*v))
            {
                return Err(format!(
                    "input weights: decay {} and {} number factors {:?} for {} pose numbers",
                    w.decay,
                    w.numbers.len(),
                    w.numbers,
                    s.mean.len()
                ));
            }
        }
        Ok(())
    }
}

fn weigh(x: &[f64], per_input: &[f64]) -> Vec<f64> {
    x.iter().zip(per_input).map(|(v, w)| v * w).collect()
}

/// Every sequence's inputs, weighted.
fn weigh_all(data: &[KernelData<'_>], per_input: &[f64]) -> Vec<Vec<Vec<f64>>> {
    data.iter()
        .map(|d| d.inputs.iter().map(|x| weigh(x, per_input)).collect())
        .collect()
}

/// The weighted inputs and the targets of the sequences `keep` accepts, stacked.
fn gather(
    data: &[KernelData<'_>],
    weighted: &[Vec<Vec<f64>>],
    keep: impl Fn(&KernelData<'_>) -> bool,
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for (d, w) in data.iter().zip(weighted).filter(|(d, _)| keep(d)) {
        x.extend(w.iter().cloned());
        y.extend(d.targets.iter().cloned());
    }
    (x, y)
}

/// Inner leave-one-group-out mean squared error of every width and ridge, with the inputs weighted by
/// `per_input`: `[width, ridge, error]`.
fn inner_scores(
    data: &[KernelData<'_>],
    groups: &[usize],
    per_input: &[f64],
    varying: f64,
) -> Result<Vec<[f64; 3]>> {
    let weighted = weigh_all(data, per_input);
    let mut scores = Vec::new();
    for &w in &WIDTHS {
        for &r in &RIDGES {
            let gamma = w / varying;
            let mut sse = 0.0;
            let mut count = 0usize;
            for &g in groups {
                let (x, y) = gather(data, &weighted, |d| d.group != g);
                let (dual, offset) = solve(&x, &y, gamma, r)?;
                for (d, inputs) in data.iter().zip(&weighted).filter(|(d, _)| d.group == g) {
                    for (xi, yi) in inputs.iter().zip(d.targets) {
                        let p = predict_with(&x, &dual, &offset, gamma, xi);
                        sse += sq_dist(&p, yi);
                        count += 1;
                    }
                }
            }
            scores.push([w, r, sse / count.max(1) as f64]);
        }
    }
    Ok(scores)
}

/// The width, ridge and error of the lowest finite error.
fn best_score(scores: &[[f64; 3]]) -> Result<[f64; 3]> {
    scores
        .iter()
        .filter(|s| s[2].is_finite())
        .min_by(|a, b| a[2].total_cmp(&b[2]))
        .copied()
        .ok_or_else(|| Error::Numeric {
            stage: "kernel regression".into(),
            msg: "no width and ridge gave a finite held-out error".into(),
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::regression::pose::ControlSpec;

    /// A target that is a nonlinear function of the last two poses: the linear map cannot fit it, the kernel
    /// must, from other sequences.
    fn sequence(phase: f64, amp: f64) -> Sequence {
        let poses: Vec<Vec<f64>> = (0..60)
            .map(|t| {
                let s = (t as f64 * 0.15 + phase).sin() * amp;
                vec![s, (t as f64 * 0.07 + 2.0 * phase).cos()]
            })
            .collect();
        let targets = (0..60)
            .map(|t| {
                let (p, q) = (&poses[t], &poses[t.saturating_sub(2)]);
                vec![p[0] * p[1], (p[0] - q[0]).powi(2), p[1].sin()]
            })
            .collect();
        (poses, targets)
    }

    /// One sequence's poses and targets, frame by frame.
    type Sequence = (Vec<Vec<f64>>, Vec<Vec<f64>>);

    /// A kernel fitted on the first four sequences, each its own group, standardised on them.
    fn fit_on_first_four(seqs: &[Sequence], window: &[usize], search: bool) -> KernelRegression {
        let refs: Vec<&[Vec<f64>]> = seqs[..4].iter().map(|s| s.0.as_slice()).collect();
        let ControlSpec { mean, scale, .. } = ControlSpec::fit(&refs, vec![]).unwrap();
        let inputs: Vec<Vec<Vec<f64>>> = seqs[..4]
            .iter()
            .map(|s| window_inputs(&s.0, &mean, &scale, window))
            .collect();
        let data: Vec<KernelData> = (0..4)
            .map(|i| KernelData {
                inputs: &inputs[i],
                targets: &seqs[i].1,
                group: i,
            })
            .collect();
        KernelRegression::fit(&data, window.to_vec(), mean, scale, search).unwrap()
    }

    #[test]
    fn a_nonlinear_function_of_the_window_is_learned_from_other_sequences() {
        let seqs: Vec<_> = (0..5)
            .map(|i| sequence(0.7 * i as f64, 1.0 + 0.1 * i as f64))
            .collect();
        let m = fit_on_first_four(&seqs, &[0, 2], true);
        assert_eq!(m.spec.method, "inner-leave-one-out");
        assert_eq!(m.spec.scores.len(), WIDTHS.len() * RIDGES.len());
        m.check().unwrap();
        // A held-out motion of the same kind lies near the training windows; one ten times as large does not.
        let near = m.distances(&seqs[4].0);
        assert!(near.iter().all(|d| *d < OUTSIDE), "{near:?}");
        let far: Vec<Vec<f64>> = seqs[4].0.iter().map(|p| vec![10.0 * p[0], p[1]]).collect();
        assert!(m.distances(&far).iter().any(|d| *d > OUTSIDE));
        let pred = m.predict_sequence(&seqs[4].0);
        let err: f64 = pred
            .iter()
            .zip(&seqs[4].1)
            .map(|(p, t)| sq_dist(p, t))
            .sum::<f64>();
        let spread: f64 = {
            let mean: Vec<f64> = (0..3)
                .map(|j| seqs[4].1.iter().map(|t| t[j]).sum::<f64>() / 60.0)
                .collect();
            seqs[4].1.iter().map(|t| sq_dist(t, &mean)).sum()
        };
        assert!(
            err < 0.1 * spread,
            "held-out error {err} against the targets' spread {spread}"
        );
    }

    /// Two pose numbers that vary alike, of which only the first moves the cloth, and only at the frame itself.
    fn one_number_matters(phase: f64) -> Sequence {
        let poses: Vec<Vec<f64>> = (0..80)
            .map(|t| {
                let t = t as f64;
                vec![(t * 0.15 + phase).sin(), (t * 0.23 + 3.0 * phase).cos()]
            })
            .collect();
        let targets = poses
            .iter()
            .map(|p| vec![(2.0 * p[0]).sin(), p[0] * p[0]])
            .collect();
        (poses, targets)
    }

    #[test]
    fn the_search_weighs_down_what_does_not_move_the_cloth_and_predicts_better() {
        let seqs: Vec<_> = (0..5).map(|i| one_number_matters(0.9 * i as f64)).collect();
        let (searched, uniform) = (
            fit_on_first_four(&seqs, &[0, 2], true),
            fit_on_first_four(&seqs, &[0, 2], false),
        );
        searched.check().unwrap();
        let w = searched.spec.weights.clone().unwrap();
        assert!(w.numbers[1] < w.numbers[0], "{w:?}");
        assert!(w.decay < 1.0, "{w:?}");
        // The distance check counts every number in full: the weighed-down number far outside its training
        // range is still named.
        let far: Vec<Vec<f64>> = seqs[4].0.iter().map(|p| vec![p[0], 10.0 * p[1]]).collect();
        assert!(searched.distances(&far).iter().any(|d| *d > OUTSIDE));
        assert!(searched.distances(&seqs[4].0).iter().all(|d| *d < OUTSIDE));
        for (a, b) in searched.distances(&far).iter().zip(uniform.distances(&far)) {
            assert!((a - b).abs() < 1e-9 * (1.0 + b), "{a} against {b}");
        }
        assert_eq!(uniform.spec.weights, Some(InputWeights::uniform(2)));
        assert_eq!(uniform.spec.weight_trials.len(), 1);
        assert!(searched.spec.weight_trials.len() > 1);
        let err = |m: &KernelRegression| -> f64 {
            m.predict_sequence(&seqs[4].0)
                .iter()
                .zip(&seqs[4].1)
                .map(|(p, t)| sq_dist(p, t))
                .sum()
        };
        let (e_searched, e_uniform) = (err(&searched), err(&uniform));
        assert!(
            e_searched < 0.7 * e_uniform,
            "held out: searched {e_searched}, uniform {e_uniform}"
        );
    }

    #[test]
    fn a_spec_without_weights_reads_as_uniform() {
        let (poses, targets) = sequence(0.3, 1.0);
        let ControlSpec { mean, scale, .. } =
            ControlSpec::fit(&[poses.as_slice()], vec![]).unwrap();
        let inputs = window_inputs(&poses, &mean, &scale, &[0, 2]);
        let data = [KernelData {
            inputs: &inputs,
            targets: &targets,
            group: 0,
        }];
        let m = KernelRegression::fit(&data, vec![0, 2], mean, scale, true).unwrap();
        // A manifest written before the weights existed has neither field.
        let mut json = serde_json::to_value(&m.spec).unwrap();
        let obj = json.as_object_mut().unwrap();
        obj.remove("weights");
        obj.remove("weight_trials");
        let old: KernelSpec = serde_json::from_value(json).unwrap();
        assert_eq!(old.weights, None);
        let old = KernelRegression {
            spec: old,
            ..m.clone()
        };
        assert_eq!(old.predict_sequence(&poses), m.predict_sequence(&poses));
    }

    #[test]
    fn one_group_takes_the_fixed_width_and_reproduces_its_training_frames() {
        let (poses, targets) = sequence(0.3, 1.0);
        let ControlSpec { mean, scale, .. } =
            ControlSpec::fit(&[poses.as_slice()], vec![]).unwrap();
        let inputs = window_inputs(&poses, &mean, &scale, &[0]);
        let data = [KernelData {
            inputs: &inputs,
            targets: &targets,
            group: 0,
        }];
        let m = KernelRegression::fit(&data, vec![0], mean, scale, true).unwrap();
        assert_eq!((m.spec.width, m.spec.ridge), FALLBACK);
        assert_eq!(m.spec.method, "fixed");
        let pred = m.predict_sequence(&poses);
        let worst = pred
            .iter()
            .zip(&targets)
            .map(|(p, t)| sq_dist(p, t).sqrt())
            .fold(0.0, f64::max);
        assert!(worst < 0.2, "training frame off by {worst}");
    }
}
