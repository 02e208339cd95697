//! View selection (Popa et al. 2009 §4 "View Selection").
//!
//! Per frame, the best front and back cameras are those most orthogonal to the garment at a tracked front vertex
//! and a tracked back vertex: the largest dot product of the vertex's *stable* normal — the area-weighted normal
//! averaged over a large (eight-ring) neighbourhood, so that the folds themselves do not swing it — with the unit
//! vector from the vertex to the camera. Vertex identity is tracked through the sequence by the shared
//! connectivity. Normals are oriented away from the garment's centroid, so the choice does not depend on the
//! mesh's winding.

use super::cameras::CameraRig;
use crate::mesh::{geometry, Topology};
use crate::vec3::{self, V3};

/// Stable normal at `v`: the mean of the area-weighted vertex normals over `rings` rings, oriented away from the
/// centroid of `positions`.
pub fn stable_normal(
    topo: &Topology,
    positions: &[V3],
    normals: &[V3],
    v: usize,
    rings: usize,
) -> V3 {
    let mut n = [0.0; 3];
    for u in topo.vertex_ring_neighborhood(v, rings) {
        n = vec3::add(n, normals[u as usize]);
    }
    let n = vec3::normalize(n);
    let c = centroid(positions);
    if vec3::dot(n, vec3::sub(positions[v], c)) < 0.0 {
        vec3::scale(n, -1.0)
    } else {
        n
    }
}

pub fn centroid(positions: &[V3]) -> V3 {
    let s = positions.iter().fold([0.0; 3], |a, &p| vec3::add(a, p));
    vec3::scale(s, 1.0 / positions.len().max(1) as f64)
}

/// Automatic front and back vertices from the first frame of the sequence. With `dir` the unit vector from the
/// garment's centroid towards the first camera, the front vertex is, among the vertices whose outward normal
/// faces `dir` (cosine > 0.8), the one closest to the line through the centroid along `dir` — the middle of the
/// side the first camera sees, away from openings and borders; the back vertex is the same for `-dir`. When no
/// vertex qualifies, the vertex farthest along `±dir` is taken.
pub fn auto_vertices(topo: &Topology, positions: &[V3], rig: &CameraRig) -> (usize, usize) {
    let c = centroid(positions);
    let dir = vec3::normalize(vec3::sub(rig.cameras[0].camera.center(), c));
    let normals = geometry::vertex_normals(topo, positions);
    let pick = |d: V3| {
        let off_axis = |i: usize| {
            let r = vec3::sub(positions[i], c);
            vec3::norm(vec3::sub(r, vec3::scale(d, vec3::dot(r, d))))
        };
        let outward = |i: usize| {
            let n = normals[i];
            if vec3::dot(n, vec3::sub(positions[i], c)) < 0.0 {
                vec3::scale(n, -1.0)
            } else {
                n
            }
        };
        (0..positions.len())
            .filter(|&i| {
                vec3::dot(outward(i), d) > 0.8 && vec3::dot(vec3::sub(positions[i], c), d) > 0.0
            })
            .min_by(|&a, &b| off_axis(a).total_cmp(&off_axis(b)))
            .unwrap_or_else(|| {
                let key = |i: usize| vec3::dot(vec3::sub(positions[i], c), d);
                (0..positions.len())
                    .max_by(|&a, &b| key(a).total_cmp(&key(b)))
                    .unwrap_or(0)
            })
    };
    (pick(dir), pick(vec3::scale(dir, -1.0)))
}

/// How well each camera faces a vertex: dot of its stable normal with the unit vector to the camera centre.
pub fn camera_scores(rig: &CameraRig, position: V3, normal: V3) -> Vec<f64> {
    rig.cameras
        .iter()
        .map(|c| {
            vec3::dot(
                normal,
                vec3::normalize(vec3::sub(c.camera.center(), position)),
            )
        })
        .collect()
}

/// Fraction of the frame's vertices that project inside camera `cam`'s image (in front of it).
pub fn coverage(rig: &CameraRig, cam: usize, positions: &[V3]) -> f64 {
    let c = &rig.cameras[cam].camera;
    let (w, h) = (c.width as f64, c.height as f64);
    let inside = positions
        .iter()
        .filter(|&&p| {
            c.project(p)
                .is_some_and(|[u, v]| u >= -0.5 && v >= -0.5 && u < w - 0.5 && v < h - 0.5)
        })
        .count();
    inside as f64 / positions.len().max(1) as f64
}

/// The chosen views of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewChoice {
    pub front: Option<usize>,
    pub back: Option<usize>,
    /// Warnings (cameras skipped because they see no garment, vertices no camera faces).
    pub notes: Vec<String>,
}

/// Picks the front and back cameras of frame `t` for the tracked vertices. Cameras that see none of the garment
/// are skipped with a note naming camera and frame; the back view is a different camera from the front view.
pub fn select(
    rig: &CameraRig,
    topo: &Topology,
    positions: &[V3],
    vertices: (usize, usize),
    rings: usize,
    t: usize,
) -> ViewChoice {
    let normals = geometry::vertex_normals(topo, positions);
    let mut notes = Vec::new();
    let sees: Vec<bool> = (0..rig.cameras.len())
        .map(|c| {
            let ok = coverage(rig, c, positions) > 0.0;
            if !ok {
                notes.push(format!(
                    "camera {} sees no garment at frame {t}; it is not used for this frame",
                    rig.cameras[c].name
                ));
            }
            ok
        })
        .collect();
    let mut pick = |v: usize, exclude: Option<usize>, which: &str| {
        let n = stable_normal(topo, positions, &normals, v, rings);
        let scores = camera_scores(rig, positions[v], n);
        let best = (0..scores.len())
            .filter(|&c| sees[c] && Some(c) != exclude)
            .max_by(|&a, &b| scores[a].total_cmp(&scores[b]));
        match best {
            Some(c) if scores[c] > 0.0 => Some(c),
            Some(c) => {
                notes.push(format!(
                    "frame {t}: no camera faces the {which} vertex {v} (best: {} at {:.0}°); no {which} view",
                    rig.cameras[c].name,
                    scores[c].clamp(-1.0, 1.0).acos().to_degrees()
                ));
                None
            }
            None => None,
        }
    };
    let front = pick(vertices.0, None, "front");
    let back = pick(vertices.1, front, "back");
    ViewChoice { front, back, notes }
}
