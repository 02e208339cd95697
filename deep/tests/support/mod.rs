//! Small procedural meshes for the crease-deep tests.
#![allow(dead_code)]

use crease_core::mesh::Topology;
use crease_core::vec3::V3;
use crease_deep::normal_maps::uv::UvLayout;
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
/// on the sleeve. Writes `dir/pose.json`; the meshes stay in memory.
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

/// A training sequence of in-memory frames and their poses; writes `dir/pose.json` (with the
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

/// A sheet of `n` × `n` vertices with planar UVs, and per frame t (of `frames`) the vertex normals of a smooth
/// tilt moving with t (the input) and of the same tilt twice as steep (the target, a local function of the
/// input that a small convolutional network can learn from crops): cGAN training data.
pub struct RippleData {
    pub topo: Arc<Topology>,
    pub layout: UvLayout,
    pub frames: Vec<(Vec<V3>, Vec<V3>)>,
}

pub fn ripple_data(n: usize, frames: usize) -> RippleData {
    let (topo, p) = sheet(n, |_, _| 0.0);
    let layout = UvLayout {
        uv: p.iter().map(|q| [q[0], q[1]]).collect(),
        corners: topo.triangles().to_vec(),
    };
    let normals = |t: usize, steep: f64| -> Vec<V3> {
        p.iter()
            .map(|q| {
                let u = q[0];
                let tilt = 0.3 * (u * 6.0 + t as f64 * 0.4).sin();
                let v = [steep * tilt, 0.1, 1.0];
                let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                [v[0] / l, v[1] / l, v[2] / l]
            })
            .collect()
    };
    RippleData {
        topo,
        layout,
        frames: (0..frames)
            .map(|t| (normals(t, 1.0), normals(t, 2.0)))
            .collect(),
    }
}

pub fn write_pc2(path: &std::path::Path, frames: &[Vec<V3>]) {
    let mut b = Vec::new();
    b.extend_from_slice(b"POINTCACHE2\0");
    b.extend_from_slice(&1i32.to_le_bytes());
    b.extend_from_slice(&(frames[0].len() as i32).to_le_bytes());
    b.extend_from_slice(&1f32.to_le_bytes());
    b.extend_from_slice(&1f32.to_le_bytes());
    b.extend_from_slice(&(frames.len() as i32).to_le_bytes());
    for f in frames {
        for p in f {
            for c in p {
                b.extend_from_slice(&(*c as f32).to_le_bytes());
            }
        }
    }
    std::fs::write(path, b).unwrap();
}

/// `dir/mesh.obj` + `dir/frames.pc2`, the layout `crease deep apply --coarse` reads. Returns the frames as
/// they read back (f32).
pub fn write_sequence(dir: &std::path::Path, topo: &Topology, frames: &[Vec<V3>]) -> Vec<Vec<V3>> {
    std::fs::create_dir_all(dir).unwrap();
    let mut obj = String::new();
    for p in &frames[0] {
        obj.push_str(&format!(
            "v {} {} {}\n",
            p[0] as f32, p[1] as f32, p[2] as f32
        ));
    }
    for t in topo.triangles() {
        obj.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    std::fs::write(dir.join("mesh.obj"), obj).unwrap();
    write_pc2(&dir.join("frames.pc2"), frames);
    frames
        .iter()
        .map(|f| {
            f.iter()
                .map(|p| p.map(|c| c as f32 as f64))
                .collect::<Vec<_>>()
        })
        .collect()
}
