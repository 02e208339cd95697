//! crease-core: geometry and numerics for putting folds back into captured garment sequences.
//!
//! Maps to the papers as follows: [`spacetime`] is Popa et al. 2009 §5 (space-time rotation weights, Alexa
//! blending, gradient-domain positioning, stretch reduction); [`folds`] holds fold estimates as anchors;
//! [`metrics`] measures stretch (Sander et al. 2001) against the captured frame, [`rest_stretch`] against the
//! least-compressed captured edge lengths. No async and no networking here: services call into this
//! crate.

pub mod error;
pub mod eval;
pub mod export;
pub mod float_text;
pub mod folds;
pub mod fsutil;
pub mod heat;
pub mod mesh;
pub mod metrics;
pub mod npy;
pub mod preview;
pub mod progress;
pub mod render;
pub mod rest_stretch;
pub mod shading_refine;
pub mod shape;
pub mod spacetime;
pub mod synth;
pub mod synth_video;
pub mod vec3;
pub mod view;

pub use error::{Error, Result};
