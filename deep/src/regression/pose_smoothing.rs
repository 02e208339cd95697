//! The shape `apply --pose` writes: the regression's reconstruction made smooth before its mesh and map are
//! drawn (model format 8).
//!
//! Why smooth it: from pose alone the regression predicts the garment's shape to 4.4–4.5 mm on an unseen
//! motion of sleeve-train, but the folds in its reconstruction are other training frames' folds mixed by the
//! subspace. Taken apart (docs/deepwrinkles.md, "Pose-only normals taken apart"), the predicted folds on top
//! of the *true* low band score 9.7–10.3° against the captured mesh's 8.5–8.7° with no folds at all: they cost
//! more than they give, and the detail filter, which sharpens whatever folds its input holds, makes them worse
//! (17.3–18.0° through the maps against 16.2–17.6° without it). Removing them with a low-pass of the same kind
//! as the capture's (Taubin λ|μ with uniform weights on the capture filter's neighbour lists) lowers the map
//! normal error by 0.5–1.2° per split and the vertex error slightly (a truncation to the leading subspace
//! components is available, off by default: it did not help on every split). What stays is the predicted low
//! band's own error (11.4–12.5° from the captured mesh's normals), which no smoothing can remove: the pose-only
//! normal error stays far above the captured input's.

use crate::subspace::Subspace;
use crease_core::mesh::Topology;
use crease_core::shape::TaubinFilter;
use crease_core::vec3::V3;
use serde::{Deserialize, Serialize};

/// λ|μ steps of the default low-pass (the capture filter's own operator and factors; the data's capture is
/// 80 steps). Chosen over the three leave-one-sequence-out splits of sleeve-train (docs/deepwrinkles.md).
pub const DEFAULT_STEPS: usize = 160;
/// Leading subspace coefficients the default keeps (0: all). Keeping 10 was better on two splits of
/// sleeve-train and worse on the third, and costs 0.1 mm of vertex error, so the default keeps all.
pub const DEFAULT_COMPONENTS: usize = 0;
/// The λ and μ factors of the low-pass: the capture filter's ([`TaubinFilter::capture`]).
pub const LAMBDA: f64 = 0.5;
pub const MU: f64 = -0.53;
/// Bound on the steps a model may ask for (a foreign or damaged manifest must not make apply run for hours).
pub const MAX_STEPS: usize = 100_000;

/// How the pose-only shape is smoothed (the manifest's `pose_smoothing`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseSmoothing {
    /// Leading subspace coefficients kept (the others set to zero); 0 keeps all.
    pub components: usize,
    /// λ|μ steps of the Taubin low-pass on the reconstruction; 0: none.
    pub steps: usize,
    pub lambda: f64,
    pub mu: f64,
}

impl PoseSmoothing {
    /// The default smoothing with `components` and `steps` (the CLI's `--pose-components`, `--pose-smoothing`).
    pub fn new(components: usize, steps: usize) -> Self {
        PoseSmoothing {
            components,
            steps,
            lambda: LAMBDA,
            mu: MU,
        }
    }

    /// What a manifest may hold: finite factors and at most [`MAX_STEPS`] steps.
    pub fn check(&self) -> std::result::Result<(), String> {
        if !(self.lambda.is_finite() && self.mu.is_finite()) {
            return Err(format!(
                "λ {} and μ {} must be numbers",
                self.lambda, self.mu
            ));
        }
        if self.steps > MAX_STEPS {
            return Err(format!("{} steps is more than {MAX_STEPS}", self.steps));
        }
        Ok(())
    }

    /// The coefficients with only the leading `components` kept.
    pub fn truncate(&self, coeffs: &[f64]) -> Vec<f64> {
        let mut c = coeffs.to_vec();
        if self.components > 0 {
            c.iter_mut().skip(self.components).for_each(|x| *x = 0.0);
        }
        c
    }

    /// The low-pass as a filter on `topo` (`None` with 0 steps).
    pub fn filter(&self, topo: &Topology) -> Option<TaubinFilter> {
        (self.steps > 0).then(|| TaubinFilter::new(topo, self.lambda, self.mu, self.steps))
    }

    /// The smooth shape of one frame's coefficients ([`Self::truncate`]d, reconstructed, low-passed).
    pub fn shape(&self, sub: &Subspace, filter: Option<&TaubinFilter>, coeffs: &[f64]) -> Vec<V3> {
        // Reconstructing from the leading coefficients alone is the truncation (a zero adds nothing).
        let kept = if self.components > 0 {
            &coeffs[..self.components.min(coeffs.len())]
        } else {
            coeffs
        };
        let x = sub.reconstruct(kept);
        match filter {
            Some(f) => f.apply(&x),
            None => x,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Mat;

    #[test]
    fn truncation_keeps_the_leading_coefficients_and_zero_steps_is_no_filter() {
        let s = PoseSmoothing::new(2, 0);
        assert_eq!(s.truncate(&[1.0, 2.0, 3.0, 4.0]), vec![1.0, 2.0, 0.0, 0.0]);
        assert_eq!(
            PoseSmoothing::new(0, 0).truncate(&[1.0, 2.0]),
            vec![1.0, 2.0]
        );
        let topo = Topology::new(3, vec![[0, 1, 2]]).unwrap();
        assert!(s.filter(&topo).is_none());
        // One component of a 3-vertex "subspace": the shape is mean + c0 · b0, the second coefficient dropped.
        let sub = Subspace {
            mean: vec![0.0; 9],
            basis: Mat::from_fn(9, 2, |r, c| if r == c { 1.0 } else { 0.0 }),
            singular_values: vec![1.0, 1.0],
        };
        let got = PoseSmoothing::new(1, 0).shape(&sub, None, &[0.5, 0.25]);
        assert_eq!(got[0], [0.5, 0.0, 0.0]);
    }

    #[test]
    fn bad_factors_or_too_many_steps_are_refused() {
        assert!(PoseSmoothing::new(10, 160).check().is_ok());
        assert!(PoseSmoothing::new(0, MAX_STEPS + 1).check().is_err());
        let nan = PoseSmoothing {
            lambda: f64::NAN,
            ..PoseSmoothing::new(0, 1)
        };
        assert!(nan.check().unwrap_err().contains("λ"));
    }
}
