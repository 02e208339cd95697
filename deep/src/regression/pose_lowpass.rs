//! The shape `apply --pose` writes: the regression's reconstruction, optionally truncated to its leading
//! subspace components and low-passed before its mesh and map are drawn.
//!
//! Why low-pass it: the folds in a pose-only reconstruction are mostly other training frames' folds mixed by
//! the subspace; where they are in the wrong place they cost more normal error than no folds at all. The
//! low-pass is implicit cotangent diffusion ([`crate::detail::operator::Walk::diffuse`]) whose strength is
//! stated as the wavelength, in mean edge lengths of the shape, that keeps half its amplitude: a length on the
//! surface, not a property of any capture. It acts on the reconstruction's departure from the subspace's mean
//! shape, not on the shape itself: diffusing a curved garment shrinks it (a tube loses radius), while the
//! departure from the mean is where the mixed-in folds are.

use crate::detail::captures::frequency_of;
use crate::detail::operator::Walk;
use crate::subspace::Subspace;
use crease_core::mesh::Topology;
use crease_core::vec3::{self, V3};
use serde::{Deserialize, Serialize};

/// Bound on the half-amplitude wavelength a model may ask for, in edge lengths (beyond it the diffusion would
/// flatten the garment, and a damaged manifest must not make apply run for minutes per frame).
pub const MAX_HALF_WAVELENGTH: f64 = 200.0;

/// How the pose-only shape is made smooth (the manifest's `pose_lowpass`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseLowpass {
    /// Leading subspace coefficients kept (the others set to zero); 0 keeps all.
    pub components: usize,
    /// Wavelength (mean edge lengths) the diffusion halves; 0: no low-pass.
    pub half_wavelength: f64,
}

impl PoseLowpass {
    /// What a manifest may hold.
    pub fn check(&self) -> std::result::Result<(), String> {
        if !(self.half_wavelength == 0.0
            || (self.half_wavelength >= 2.0 && self.half_wavelength <= MAX_HALF_WAVELENGTH))
        {
            return Err(format!(
                "half_wavelength {} is neither 0 nor in 2..={MAX_HALF_WAVELENGTH} edge lengths",
                self.half_wavelength
            ));
        }
        Ok(())
    }

    /// The smooth shape of one frame's coefficients: truncated, reconstructed, its departure from the mean
    /// diffused (with the operator of the reconstruction's own surface).
    pub fn shape(&self, topo: &Topology, sub: &Subspace, coeffs: &[f64]) -> Vec<V3> {
        // Reconstructing from the leading coefficients alone is the truncation (a zero adds nothing).
        let kept = if self.components > 0 {
            &coeffs[..self.components.min(coeffs.len())]
        } else {
            coeffs
        };
        let x = sub.reconstruct(kept);
        if self.half_wavelength == 0.0 {
            return x;
        }
        let mean = crate::subspace::unflatten(&sub.mean);
        let d: Vec<V3> = x
            .iter()
            .zip(&mean)
            .map(|(p, m)| vec3::sub(*p, *m))
            .collect();
        let smooth =
            Walk::cotangent(topo, &x).diffuse(&d, 1.0 / frequency_of(self.half_wavelength));
        mean.iter()
            .zip(&smooth)
            .map(|(m, e)| vec3::add(*m, *e))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Mat;

    #[test]
    fn truncation_keeps_the_leading_coefficients_and_zero_is_no_filter() {
        let topo = Topology::new(3, vec![[0, 1, 2]]).unwrap();
        let sub = Subspace {
            mean: vec![0.0; 9],
            basis: Mat::from_fn(9, 2, |r, c| if r == c { 1.0 } else { 0.0 }),
            singular_values: vec![1.0, 1.0],
        };
        let keep_one = PoseLowpass {
            components: 1,
            half_wavelength: 0.0,
        };
        let got = keep_one.shape(&topo, &sub, &[0.5, 0.25]);
        assert_eq!(got[0], [0.5, 0.0, 0.0]);
        assert!(keep_one.check().is_ok());
    }

    #[test]
    fn bad_strengths_are_refused() {
        for hw in [1.0, f64::NAN, MAX_HALF_WAVELENGTH + 1.0, -3.0] {
            let p = PoseLowpass {
                components: 0,
                half_wavelength: hw,
            };
            assert!(p.check().unwrap_err().contains("half_wavelength"), "{hw}");
        }
    }
}
