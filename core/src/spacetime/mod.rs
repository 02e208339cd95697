//! Space-time deformation (Popa et al. 2009 §5): weights over space and time, rotation blending, vertex
//! positioning, stretch reduction, and the streaming driver that runs them window by window.

pub mod blend;
mod chunk_sgs;
pub mod deconvolve;
pub mod deform;
pub mod factor_solve;
pub mod fused;
pub mod lean_cg;
pub mod operator;
pub mod params;
pub mod per_anchor;
pub mod position;
pub mod restore;
pub mod shape_projection;
pub mod so3;
pub mod stages;
mod stencil_sweep;
pub mod strain_limit;
pub mod stretch;
pub mod weights;
pub mod windows;

pub use deform::{deform, DeformReport};
pub use operator::Coefficients;
pub use params::{DeformParams, WeightMode};
pub use position::Pinning;
