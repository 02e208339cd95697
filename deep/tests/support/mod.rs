//! Small procedural meshes for the crease-deep tests.
#![allow(dead_code)]

use crease_core::mesh::Topology;
use crease_core::vec3::V3;
use std::sync::Arc;

/// Quad grid of `nx` × `ny` vertices split into triangles (a, b, c), (a, c, d), like the sleeve data.
pub fn grid_tris(nx: usize, ny: usize, wrap_x: bool) -> Vec<[u32; 3]> {
    let mut tris = Vec::new();
    let cols = if wrap_x { nx } else { nx - 1 };
    for j in 0..ny - 1 {
        for i in 0..cols {
            let i1 = (i + 1) % nx;
            let a = (j * nx + i) as u32;
            let b = (j * nx + i1) as u32;
            let c = ((j + 1) * nx + i1) as u32;
            let d = ((j + 1) * nx + i) as u32;
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    tris
}

/// A flat sheet in z = height(x, y), 1 × 1 m.
pub fn sheet(n: usize, height: impl Fn(f64, f64) -> f64) -> (Arc<Topology>, Vec<V3>) {
    let tris = grid_tris(n, n, false);
    let mut p = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f64 / (n - 1) as f64, j as f64 / (n - 1) as f64);
            p.push([x, y, height(x, y)]);
        }
    }
    (Arc::new(Topology::new(n * n, tris).unwrap()), p)
}

/// An open tube along +x (like the sleeve): `na` vertices around, `nr` rings, radius `r(a, ring)`.
pub fn tube(na: usize, nr: usize, radius: impl Fn(f64, f64) -> f64) -> (Arc<Topology>, Vec<V3>) {
    let tris = grid_tris(na, nr, true);
    let mut p = Vec::new();
    for j in 0..nr {
        for i in 0..na {
            let phi = std::f64::consts::TAU * i as f64 / na as f64;
            let x = 0.5 * j as f64 / (nr - 1) as f64;
            let r = radius(phi, x);
            p.push([x, r * phi.cos(), r * phi.sin()]);
        }
    }
    (Arc::new(Topology::new(na * nr, tris).unwrap()), p)
}
