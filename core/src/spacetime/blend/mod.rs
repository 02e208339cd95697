//! Rotation blending (Popa et al. 2009 §5.3, after Alexa 2002): a triangle's rotation is exp of the weighted
//! sum of the anchors' rotation vectors, and the overlapping frames of consecutive windows are cross-faded.
//!
//! - [`so3`] — the exponential and logarithm maps of SO(3) and the rotation between two directions;
//! - [`crossfade`] — the windows' rotation-vector fields mixed into per-frame fields, and turned into
//!   rotations.

pub mod crossfade;
pub mod so3;

pub use crossfade::{fade_into, rotations, CrossFade};
