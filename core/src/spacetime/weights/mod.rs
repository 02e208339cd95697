//! The space-time weights (Popa et al. 2009 §5.3): per triangle and frame of a window, the convex weights of
//! the anchor rotations, from one sparse SPD system M W = c_a E.
//!
//! - [`operator`] — M itself (space and time Laplacians, mitigation and anchor terms), applied matrix-free;
//! - [`fused`] — the blend needs only X = W Φ, which solves M X = c_a E Φ: three right-hand sides (the f64
//!   statement of the block CG), and [`lean_cg`] the same iteration in the bandwidth-lean form the
//!   deformation runs;
//! - [`per_anchor`] — the paper's formulation, one CG column per anchor, in blocks a cluster distributes;
//! - [`solve`] — one window's problem and its solve in either mode, as the stages a cluster task runs.

pub mod fused;
pub mod lean_cg;
pub mod operator;
pub mod per_anchor;
pub mod solve;

pub use solve::{
    anchor_block, anchor_blocks, fused_window_field, reduce_blocks, reduce_into, solve_window,
    WindowProblem, WindowStats,
};
