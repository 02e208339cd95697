//! Per-frame geometric quantities (areas, normals) and the geometric validation of a frame.

use crate::error::{Error, Result};
use crate::mesh::Topology;
use crate::vec3::{self, V3};

/// Relative area threshold below which a triangle counts as degenerate: twice its area must exceed
/// `DEGENERATE_EPS` times its longest edge squared (this catches collapsed and needle triangles alike, and is
/// independent of the scene's units).
pub const DEGENERATE_EPS: f64 = 1e-10;

/// Unnormalised triangle normal (length = twice the area).
#[inline]
pub fn tri_cross(p: &[V3], tri: [u32; 3]) -> V3 {
    let a = p[tri[0] as usize];
    vec3::cross(
        vec3::sub(p[tri[1] as usize], a),
        vec3::sub(p[tri[2] as usize], a),
    )
}

/// Unit normals of all triangles.
pub fn triangle_normals(topo: &Topology, p: &[V3]) -> Vec<V3> {
    topo.triangles()
        .iter()
        .map(|&t| vec3::normalize(tri_cross(p, t)))
        .collect()
}

/// Triangle areas.
pub fn triangle_areas(topo: &Topology, p: &[V3]) -> Vec<f64> {
    topo.triangles()
        .iter()
        .map(|&t| 0.5 * vec3::norm(tri_cross(p, t)))
        .collect()
}

/// Area-weighted vertex normals (unit length; zero for isolated vertices).
pub fn vertex_normals(topo: &Topology, p: &[V3]) -> Vec<V3> {
    let mut n = vec![[0.0; 3]; p.len()];
    for &t in topo.triangles() {
        let c = tri_cross(p, t);
        for &v in &t {
            n[v as usize] = vec3::add(n[v as usize], c);
        }
    }
    n.into_iter().map(vec3::normalize).collect()
}

/// The first thing wrong with a frame's positions, by 0-based index, so that a reader can name it the way its
/// file numbers vertices and faces (OBJ counts from 1).
#[derive(Debug, Clone, PartialEq)]
pub enum FrameProblem {
    NonFinite { vertex: usize, at: V3 },
    Degenerate { triangle: usize, vertices: [u32; 3] },
}

/// Finds the first non-finite vertex or degenerate triangle of a frame with the topology's vertex count.
/// (A frame with another vertex count is the caller's to refuse first; it is not looked at.)
pub fn find_problem(topo: &Topology, p: &[V3]) -> Option<FrameProblem> {
    if p.len() != topo.n_vertices() {
        return None;
    }
    if let Some(vertex) = p.iter().position(|v| !vec3::is_finite(*v)) {
        return Some(FrameProblem::NonFinite {
            vertex,
            at: p[vertex],
        });
    }
    for (t, &tri) in topo.triangles().iter().enumerate() {
        let [a, b, c] = tri.map(|i| p[i as usize]);
        let longest = [vec3::sub(b, a), vec3::sub(c, b), vec3::sub(a, c)]
            .iter()
            .map(|e| vec3::dot(*e, *e))
            .fold(0.0, f64::max);
        let twice_area = vec3::norm(tri_cross(p, tri));
        // Written so that NaN areas also count as degenerate.
        if twice_area.partial_cmp(&(DEGENERATE_EPS * longest)) != Some(std::cmp::Ordering::Greater)
        {
            return Some(FrameProblem::Degenerate {
                triangle: t,
                vertices: tri,
            });
        }
    }
    None
}

/// Checks one frame's positions against the topology: vertex count, finite coordinates, non-degenerate
/// triangles. Errors name the vertex or triangle index; callers attach the file and frame with [`Error::at`].
pub fn validate_frame(topo: &Topology, p: &[V3]) -> Result<()> {
    if p.len() != topo.n_vertices() {
        return Err(Error::mesh(format!(
            "has {} vertices, expected {} (the vertex count must be the same in every frame)",
            p.len(),
            topo.n_vertices()
        )));
    }
    match find_problem(topo, p) {
        None => Ok(()),
        Some(FrameProblem::NonFinite { vertex, at }) => Err(Error::mesh(format!(
            "vertex {vertex} has a non-finite coordinate ({}, {}, {})",
            at[0], at[1], at[2]
        ))),
        Some(FrameProblem::Degenerate { triangle, vertices }) => Err(Error::mesh(format!(
            "triangle {triangle} (vertices {} {} {}) is degenerate (zero area)",
            vertices[0], vertices[1], vertices[2]
        ))),
    }
}

/// Axis-aligned bounding box of a point set.
pub fn bounding_box(p: &[V3]) -> (V3, V3) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for v in p {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    (lo, hi)
}

/// Errors unless there is one position per vertex of `topology`, naming the file the positions belong to.
pub fn check_position_count(
    topology: &Topology,
    n_positions: usize,
    path: &std::path::Path,
) -> Result<()> {
    if n_positions != topology.n_vertices() {
        return Err(Error::mesh(format!(
            "{n_positions} positions given for a topology with {} vertices",
            topology.n_vertices()
        ))
        .at(Some(path.to_path_buf()), None));
    }
    Ok(())
}
