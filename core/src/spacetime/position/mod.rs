//! Vertex positioning (Popa et al. 2009 §5.4) and stretch reduction (§5.5).
//!
//! - [`poisson`] — per frame, the positions whose triangle gradients are closest to the blended rotations, as
//!   a screened Poisson system factored once per frame;
//! - [`factor_solve`] — the triangular solves with that factor, three right-hand sides in one sweep;
//! - [`stretch`] — the stretch-reduction passes: new rotations read off the positioned surface, positioned
//!   again with the same factor;
//! - [`strain_limit`] — the last step: the few edges stretched past a cap shortened back.

pub mod factor_solve;
pub mod poisson;
pub mod strain_limit;
pub mod stretch;

pub use poisson::{FramePositioner, Pinning, PositionSystem};
