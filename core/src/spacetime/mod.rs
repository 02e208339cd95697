//! Space-time deformation (Popa et al. 2009 §5), one folder per step of the paper:
//!
//! - [`weights`] — §5.3 space-time rotation: the blending weights of every triangle and frame of a time window,
//!   solved as one sparse SPD system (fused: three right-hand sides; per-anchor: one column per anchor);
//! - [`windows`] — §5.3: the staggered windows of 10 frames shifted by 7 that the weights are solved on;
//! - [`blend`] — §5.3: the windows' rotation-vector fields cross-faded into per-frame rotations (Alexa blend);
//! - [`position`] — §5.4 vertex positioning (gradient-domain Poisson solve, its parallel factor solve) and §5.5
//!   stretch reduction, ending with the strain limit;
//! - [`shape`] — what keeps the captured shape and gives back the folds it damped: the shape projection and
//!   the fold relief;
//! - [`stages`] and [`deform`] — §5.2: the frame stages a cluster task runs, and the streaming driver that runs
//!   them window by window on one machine; [`params`] — every setting of the deformation.

pub mod blend;
pub mod deform;
pub mod params;
pub mod position;
pub mod shape;
pub mod stages;
pub mod weights;
pub mod windows;

pub use deform::{deform, DeformReport};
pub use params::{DeformParams, WeightMode};
pub use position::Pinning;
pub use weights::operator::Coefficients;
