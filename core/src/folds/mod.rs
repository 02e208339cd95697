//! Fold estimates and their hand-off to the deformation: anchors (triangle, axis, angle) per frame.

pub mod anchors;

pub use anchors::{Anchor, AnchorSet};
