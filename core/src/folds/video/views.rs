//! View selection (Popa et al. 2009 §4 "View Selection").
//!
//! Per frame, the best front and back cameras are those most orthogonal to the garment at a tracked front vertex
//! and a tracked back vertex: the largest dot product of the vertex's *stable* normal — the area-weighted normal
//! averaged over a large (eight-ring) neighbourhood, so that the folds themselves do not swing it — with the unit
//! vector from the vertex to the camera. Vertex identity is tracked through the sequence by the shared
//! connectivity.
//!
//! The normal's sign is not the mesh's winding (which is arbitrary). The front normal points away from the
//! garment's centroid where that is clear (closed and tube-like garments); on open garments (a hanging sheet) or
//! at a rim, where the centroid lies in the surface's own plane, it points to the camera that faces the surface
//! most squarely. The back normal then points away from the chosen front camera, so the back view sees the other
//! side of the garment whichever vertices are tracked: the far side of a tube, the reverse of a sheet.

use super::cameras::CameraRig;
use crate::mesh::{geometry, Topology};
use crate::vec3::{self, V3};

/// Stable normal at `v`: the mean of the area-weighted vertex normals `normals` over `rings` rings, with the
/// mesh's (arbitrary) sign.
pub fn ring_normal(topo: &Topology, normals: &[V3], v: usize, rings: usize) -> V3 {
    let mut n = [0.0; 3];
    for u in topo.vertex_ring_neighborhood(v, rings) {
        n = vec3::add(n, normals[u as usize]);
    }
    vec3::normalize(n)
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
        // Away from the centroid where that is clear, else towards `d` (open garments, rims).
        let outward = |i: usize| {
            let n = normals[i];
            let o = vec3::normalize(vec3::sub(positions[i], c));
            let k = vec3::dot(n, o);
            let s = if k.abs() >= CLEAR_OUTWARD {
                k.signum()
            } else {
                vec3::dot(n, d).signum()
            };
            vec3::scale(n, s)
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

/// Below this |cosine| between a vertex's normal and its offset from the centroid, "away from the centroid" says
/// nothing about the side (the vertex lies in the surface's plane through the centroid, or on a rim).
const CLEAR_OUTWARD: f64 = 0.3;

/// Picks the front and back cameras of frame `t` for the tracked vertices. Cameras that see none of the garment
/// are skipped with a note naming camera and frame; the back view is a different camera from the front view and
/// looks at the side of the garment facing away from the front camera (module documentation).
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
    let c = centroid(positions);
    let mut pick = |v: usize, n: V3, exclude: Option<usize>, which: &str| {
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
    let (vf, vb) = vertices;
    let raw_normal = |v: usize| ring_normal(topo, &normals, v, rings);
    let nf = raw_normal(vf);
    let out = vec3::normalize(vec3::sub(positions[vf], c));
    let cos_out = vec3::dot(nf, out);
    let nf = if cos_out.abs() >= CLEAR_OUTWARD {
        vec3::scale(nf, cos_out.signum())
    } else {
        // No inside or outside here: face the camera that sees this spot most squarely.
        let scores = camera_scores(rig, positions[vf], nf);
        let best = (0..scores.len())
            .filter(|&c| sees[c])
            .max_by(|&a, &b| scores[a].abs().total_cmp(&scores[b].abs()));
        match best {
            Some(b) if scores[b] < 0.0 => vec3::scale(nf, -1.0),
            _ => nf,
        }
    };
    let front = pick(vf, nf, None, "front");
    let mut nb = raw_normal(vb);
    let away = match front {
        Some(f) => vec3::sub(positions[vb], rig.cameras[f].camera.center()),
        None => vec3::sub(positions[vb], c),
    };
    if vec3::dot(nb, away) < 0.0 {
        nb = vec3::scale(nb, -1.0);
    }
    let back = pick(vb, nb, front, "back");
    ViewChoice { front, back, notes }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::folds::video::cameras::{NamedCamera, DEFAULT_IMAGE_PATTERN};
    use crate::render::{Camera, Projection};

    /// A flat 1 m sheet in z = 0 and four cameras, two over each side, one of each pair more oblique.
    fn sheet_and_rig() -> (std::sync::Arc<Topology>, Vec<V3>, CameraRig) {
        let (topo, p) = crate::synth::sheet(21, 21, 0.05).unwrap();
        let (lo, hi) = geometry::bounding_box(&p);
        let dirs: [V3; 4] = [
            [0.1, 0.0, -1.0],
            [0.8, 0.2, -1.0],
            [-0.1, 0.1, 1.0],
            [-0.7, -0.3, 1.0],
        ];
        let cameras = dirs
            .iter()
            .enumerate()
            .map(|(k, &d)| NamedCamera {
                name: format!("cam{k:02}"),
                camera: Camera::fit(lo, hi, d, [0.0, 1.0, 0.0], 200, 200).calibrated(),
            })
            .collect();
        let rig = CameraRig {
            cameras,
            images_dir: std::path::PathBuf::from("unused"),
            image_pattern: DEFAULT_IMAGE_PATTERN.to_string(),
        };
        (topo, p, rig)
    }

    /// The drape case: the tracked vertices of an open sheet land on its rim (or in its middle); the front and
    /// back views must still look at opposite faces of the sheet, not at the same face twice.
    #[test]
    fn open_sheet_views_see_opposite_sides() {
        let (topo, p, rig) = sheet_and_rig();
        let side = |c: usize| rig.cameras[c].camera.center()[2].signum();
        let centre = 10 * 21 + 10;
        let cases = [(0, 20), (5, 5), (0, 440), (centre, centre), (20, centre)];
        for (vf, vb) in cases {
            let choice = select(&rig, &topo, &p, (vf, vb), 8, 0);
            let (Some(f), Some(b)) = (choice.front, choice.back) else {
                panic!("{vf}/{vb}: a view is missing: {choice:?}");
            };
            assert_ne!(side(f), side(b), "{vf}/{vb}: {choice:?}");
        }
        // Flipping every triangle changes nothing.
        let flipped: Vec<[u32; 3]> = topo
            .triangles()
            .iter()
            .map(|t| [t[0], t[2], t[1]])
            .collect();
        let topo2 = Topology::new(p.len(), flipped).unwrap();
        for (vf, vb) in cases {
            assert_eq!(
                select(&rig, &topo2, &p, (vf, vb), 8, 0),
                select(&rig, &topo, &p, (vf, vb), 8, 0)
            );
        }
        // The automatic vertices are an interior front and back, with views on opposite sides as well.
        let (vf, vb) = auto_vertices(&topo, &p, &rig);
        let choice = select(&rig, &topo, &p, (vf, vb), 8, 0);
        assert_ne!(side(choice.front.unwrap()), side(choice.back.unwrap()));
    }
}
