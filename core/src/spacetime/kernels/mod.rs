//! Hand-vectorised kernels of the deformation, each bit for bit its scalar form (which runs where the CPU lacks
//! the instructions).

pub(in crate::spacetime) mod stencil_sweep;
