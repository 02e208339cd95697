//! What the positioning ends with, so that the output keeps the captured shape and gives back the folds the
//! capture smoothed away.
//!
//! - [`projection`] — the shape projection: the displacement loses the band the capture kept;
//! - [`restore`] — the fold restoration: a deconvolution of the capture's low-pass, applied along the normal;
//! - [`deconvolve`] — that deconvolution as one Chebyshev series, a few dozen sweeps per frame.

pub mod deconvolve;
pub mod projection;
pub mod restore;
