//! Small procedural meshes for the crease-deep tests.
#![allow(dead_code)]

use crease_core::mesh::Topology;
use crease_core::vec3::V3;
use crease_deep::cgan::Sample;
use crease_deep::normal_maps::NormalMap;
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

/// A training directory's worth of tube frames whose bulge follows a leaky integral of the pose
/// (s_t = 0.8 s_{t−1} + 0.5 pose_t): the same pose gives different shapes depending on the poses before it, as
/// on the sleeve. Writes `dir/pose.json`; the meshes stay in memory (fine = coarse).
pub fn leaky_sequence(
    dir: &std::path::Path,
    frames: usize,
    freq: f64,
    phase: f64,
) -> crease_deep::train::TrainingSequence {
    let (topo, _) = tube(16, 8, |_, _| 0.07);
    let (mut fine, mut poses) = (Vec::new(), Vec::new());
    let mut s = 0.0;
    for t in 0..frames {
        let a = (freq * t as f64 + phase).sin();
        s = 0.8 * s + 0.5 * a;
        poses.push(vec![a, 0.0, 0.2]);
        fine.push(
            tube(16, 8, |phi, x| {
                0.07 + 0.01 * s * (6.0 * x).sin() + 0.003 * a * (4.0 * phi).cos()
            })
            .1,
        );
    }
    pose_sequence(dir, topo, fine, poses, None)
}

/// A training sequence of in-memory frames (fine = coarse) and their poses; writes `dir/pose.json` (with the
/// pose names when given) the way `crease deep train` expects it beside the meshes.
pub fn pose_sequence(
    dir: &std::path::Path,
    topology: Arc<Topology>,
    fine: Vec<Vec<V3>>,
    poses: Vec<Vec<f64>>,
    names: Option<&[&str]>,
) -> crease_deep::train::TrainingSequence {
    std::fs::create_dir_all(dir).unwrap();
    let doc = match names {
        Some(n) => serde_json::json!({ "pose_vectors": poses, "pose_vector_names": n }),
        None => serde_json::json!({ "pose_vectors": poses }),
    };
    std::fs::write(dir.join("pose.json"), doc.to_string()).unwrap();
    crease_deep::train::TrainingSequence {
        dir: dir.to_path_buf(),
        topology,
        coarse: fine.clone(),
        fine,
        poses,
        pose_names: names.map(|n| n.iter().map(|s| s.to_string()).collect()),
    }
}

/// Mean Euclidean distance between corresponding vertices of two equally long frame sequences: the
/// millimetre figure the regression tables report.
pub fn mean_vertex_error(a: &[Vec<[f64; 3]>], b: &[Vec<[f64; 3]>]) -> f64 {
    let (mut s, mut n) = (0.0, 0.0);
    for (fa, fb) in a.iter().zip(b) {
        for (p, q) in fa.iter().zip(fb) {
            s += ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
            n += 1.0;
        }
    }
    s / n
}

/// cGAN samples on `res`² maps: input a smooth tilted map, target the same with a ripple, the ripple's phase
/// moving with t (temporal data, so `prev_target` differs from `target`).
pub fn ripple_samples(n: usize, res: usize) -> Vec<Sample> {
    let map = |t: usize, ripple: f32| {
        let mut m = NormalMap {
            width: res,
            height: res,
            n: vec![[0.0; 3]; res * res],
            covered: vec![false; res * res],
        };
        for y in 0..res {
            for x in 0..res {
                let k = y * res + x;
                let u = x as f32 / res as f32;
                let tilt = 0.3 * (u * 3.0 + t as f32 * 0.2).sin();
                let r = ripple * (u * 25.0 + t as f32 * 0.5).sin();
                let v = [tilt + r, 0.1, 1.0];
                let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                m.n[k] = [v[0] / l, v[1] / l, v[2] / l];
                m.covered[k] = x > 1 && y > 1;
            }
        }
        m
    };
    (0..n)
        .map(|t| Sample {
            input: map(t, 0.0),
            target: map(t, 0.4),
            prev_target: map(t.saturating_sub(1), 0.4),
        })
        .collect()
}
