//! Small sequences and byte readers shared by the writers' unit tests.

use crate::mesh::{Sequence, Topology};
use std::sync::Arc;

/// A unit square of two triangles whose corners move differently in each of `n` frames.
pub fn two_triangles(n: usize) -> Sequence {
    let topo = Arc::new(Topology::new(4, vec![[0, 1, 2], [0, 2, 3]]).unwrap());
    let frames = (0..n)
        .map(|t| {
            let s = t as f64 * 0.1;
            vec![
                [0.0, 0.0, s],
                [1.0 + s, 0.0, 0.0],
                [1.0, 1.0, 0.5 * s],
                [0.0, 1.0 - 0.25 * s, 0.0],
            ]
        })
        .collect();
    Sequence::new(topo, frames).unwrap()
}

pub fn read_be_i32(b: &[u8], at: usize) -> i32 {
    i32::from_be_bytes(b[at..at + 4].try_into().unwrap())
}
pub fn read_be_f32(b: &[u8], at: usize) -> f32 {
    f32::from_be_bytes(b[at..at + 4].try_into().unwrap())
}
pub fn read_le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}
pub fn read_le_f32(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}
