//! Shared connectivity of a mesh sequence and its adjacency structures.
//!
//! Captured garment sequences keep one triangle list for every frame, so everything that depends only on
//! connectivity (the dual graph used by the space-time weight solve, vertex rings, connected components used to
//! pin the positioning solve) is computed once here and shared by all frames.

use super::uv::UvSet;
use crate::error::{Error, Result};
use std::sync::Arc;

/// Marker for "no neighbour" (a boundary edge) in [`Topology::tri_adj`].
pub const NONE: u32 = u32::MAX;

/// Triangle connectivity shared by all frames of a sequence, with adjacency.
#[derive(Debug, Clone)]
pub struct Topology {
    n_vertices: usize,
    tris: Vec<[u32; 3]>,
    /// `tri_adj[t][k]` is the triangle across edge `k` = (v\[k\], v\[(k+1)%3\]) of triangle `t`, or [`NONE`].
    tri_adj: Vec<[u32; 3]>,
    /// Vertex → incident triangles, CSR layout.
    vt_offsets: Vec<u32>,
    vt_tris: Vec<u32>,
    /// Connected component id of every vertex (isolated vertices get their own component).
    vertex_component: Vec<u32>,
    n_components: usize,
    /// Texture coordinates when the input has them; shared like the connectivity by every frame.
    uvs: Option<Arc<UvSet>>,
}

impl Topology {
    /// Builds and validates the topology: indices in range, no repeated vertex within a triangle, no edge shared
    /// by more than two triangles (non-manifold). Errors name the triangle and vertex indices.
    pub fn new(n_vertices: usize, tris: Vec<[u32; 3]>) -> Result<Self> {
        if tris.is_empty() {
            return Err(Error::mesh("the mesh has no triangles"));
        }
        if n_vertices >= NONE as usize || tris.len() >= NONE as usize {
            return Err(Error::mesh(format!(
                "{} vertices / {} triangles exceed the supported 2^32-1",
                n_vertices,
                tris.len()
            )));
        }
        for (t, tri) in tris.iter().enumerate() {
            for &v in tri {
                if v as usize >= n_vertices {
                    return Err(Error::mesh(format!(
                        "triangle {t} references vertex {v}, but there are only {n_vertices} vertices"
                    )));
                }
            }
            if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                return Err(Error::mesh(format!(
                    "triangle {t} repeats a vertex ({} {} {}): it has zero area",
                    tri[0], tri[1], tri[2]
                )));
            }
        }
        let tri_adj = build_tri_adjacency(n_vertices, &tris)?;
        let (vt_offsets, vt_tris) = build_vertex_triangles(n_vertices, &tris);
        let (vertex_component, n_components) = components(n_vertices, &tris);
        Ok(Topology {
            n_vertices,
            tris,
            tri_adj,
            vt_offsets,
            vt_tris,
            vertex_component,
            n_components,
            uvs: None,
        })
    }

    /// Attaches texture coordinates (one corner triple per triangle, checked), or removes them with `None`.
    pub fn with_uvs(mut self, uvs: Option<UvSet>) -> Result<Self> {
        if let Some(u) = &uvs {
            if u.corners().len() != self.tris.len() {
                return Err(Error::mesh(format!(
                    "the UV set has corners for {} triangles, the mesh has {}",
                    u.corners().len(),
                    self.tris.len()
                )));
            }
        }
        self.uvs = uvs.map(Arc::new);
        Ok(self)
    }

    /// The texture coordinates, when the input has them.
    pub fn uvs(&self) -> Option<&UvSet> {
        self.uvs.as_deref()
    }

    pub fn n_vertices(&self) -> usize {
        self.n_vertices
    }
    pub fn n_triangles(&self) -> usize {
        self.tris.len()
    }
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.tris
    }
    /// Triangle–triangle adjacency across edges; see the field documentation for the edge numbering.
    pub fn tri_adj(&self) -> &[[u32; 3]] {
        &self.tri_adj
    }
    /// Triangles incident to vertex `v`.
    pub fn vertex_triangles(&self, v: usize) -> &[u32] {
        &self.vt_tris[self.vt_offsets[v] as usize..self.vt_offsets[v + 1] as usize]
    }
    /// Vertices sharing an edge with `v` (its one-ring), sorted and unique.
    pub fn vertex_neighbors(&self, v: usize) -> Vec<u32> {
        let mut out = Vec::new();
        for &t in self.vertex_triangles(v) {
            for &w in &self.tris[t as usize] {
                if w as usize != v {
                    out.push(w);
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }
    /// Component id of every vertex; vertices joined by triangles share an id.
    pub fn vertex_component(&self) -> &[u32] {
        &self.vertex_component
    }
    pub fn n_components(&self) -> usize {
        self.n_components
    }
    /// Number of triangle pairs sharing an edge (edges of the dual graph).
    pub fn n_dual_edges(&self) -> usize {
        self.tri_adj
            .iter()
            .enumerate()
            .map(|(t, adj)| {
                adj.iter()
                    .filter(|&&u| u != NONE && (u as usize) > t)
                    .count()
            })
            .sum()
    }
    /// Vertices within `rings` edge hops of `v` (including `v`), in breadth-first order.
    pub fn vertex_ring_neighborhood(&self, v: usize, rings: usize) -> Vec<u32> {
        let mut seen = std::collections::HashSet::new();
        let mut order = vec![v as u32];
        seen.insert(v as u32);
        let mut frontier = vec![v as u32];
        for _ in 0..rings {
            let mut next = Vec::new();
            for &u in &frontier {
                for w in self.vertex_neighbors(u as usize) {
                    if seen.insert(w) {
                        next.push(w);
                        order.push(w);
                    }
                }
            }
            if next.is_empty() {
                break;
            }
            frontier = next;
        }
        order
    }
}

fn build_tri_adjacency(n_vertices: usize, tris: &[[u32; 3]]) -> Result<Vec<[u32; 3]>> {
    // Sort half-edges by their undirected key; equal keys are the triangles sharing that edge.
    let mut half: Vec<(u64, u32, u8)> = Vec::with_capacity(tris.len() * 3);
    for (t, tri) in tris.iter().enumerate() {
        for k in 0..3 {
            let a = tri[k];
            let b = tri[(k + 1) % 3];
            let (lo, hi) = if a < b { (a, b) } else { (b, a) };
            half.push((
                (lo as u64) * n_vertices as u64 + hi as u64,
                t as u32,
                k as u8,
            ));
        }
    }
    half.sort_unstable();
    let mut adj = vec![[NONE; 3]; tris.len()];
    let mut i = 0;
    while i < half.len() {
        let mut j = i + 1;
        while j < half.len() && half[j].0 == half[i].0 {
            j += 1;
        }
        match j - i {
            1 => {}
            2 => {
                let (_, t0, k0) = half[i];
                let (_, t1, k1) = half[i + 1];
                adj[t0 as usize][k0 as usize] = t1;
                adj[t1 as usize][k1 as usize] = t0;
            }
            n => {
                let key = half[i].0;
                let (a, b) = (key / n_vertices as u64, key % n_vertices as u64);
                let ts: Vec<String> = half[i..j].iter().map(|h| h.1.to_string()).collect();
                return Err(Error::mesh(format!(
                    "non-manifold edge ({a}, {b}) is shared by {n} triangles ({})",
                    ts.join(", ")
                )));
            }
        }
        i = j;
    }
    Ok(adj)
}

fn build_vertex_triangles(n_vertices: usize, tris: &[[u32; 3]]) -> (Vec<u32>, Vec<u32>) {
    let mut counts = vec![0u32; n_vertices + 1];
    for tri in tris {
        for &v in tri {
            counts[v as usize + 1] += 1;
        }
    }
    for i in 0..n_vertices {
        counts[i + 1] += counts[i];
    }
    let mut fill = counts.clone();
    let mut out = vec![0u32; tris.len() * 3];
    for (t, tri) in tris.iter().enumerate() {
        for &v in tri {
            out[fill[v as usize] as usize] = t as u32;
            fill[v as usize] += 1;
        }
    }
    (counts, out)
}

fn components(n_vertices: usize, tris: &[[u32; 3]]) -> (Vec<u32>, usize) {
    let mut parent: Vec<u32> = (0..n_vertices as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    for tri in tris {
        for k in 1..3 {
            let a = find(&mut parent, tri[0]);
            let b = find(&mut parent, tri[k]);
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    let mut label = vec![NONE; n_vertices];
    let mut comp = vec![0u32; n_vertices];
    let mut n = 0u32;
    for v in 0..n_vertices as u32 {
        let r = find(&mut parent, v) as usize;
        if label[r] == NONE {
            label[r] = n;
            n += 1;
        }
        comp[v as usize] = label[r];
    }
    (comp, n as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quad_adjacency_and_rings() {
        // Two triangles sharing edge (1, 2).
        let t = Topology::new(4, vec![[0, 1, 2], [2, 1, 3]]).unwrap();
        assert_eq!(t.tri_adj()[0], [NONE, 1, NONE]);
        assert_eq!(t.tri_adj()[1], [0, NONE, NONE]);
        assert_eq!(t.vertex_neighbors(1), vec![0, 2, 3]);
        assert_eq!(t.n_dual_edges(), 1);
        assert_eq!(t.n_components(), 1);
    }

    #[test]
    fn non_manifold_edge_is_named() {
        let err = Topology::new(5, vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]]).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("non-manifold edge (0, 1)"), "{msg}");
        assert!(msg.contains("0, 1, 2"), "{msg}");
    }

    #[test]
    fn isolated_vertices_are_components() {
        let t = Topology::new(5, vec![[0, 1, 2]]).unwrap();
        assert_eq!(t.n_components(), 3);
    }
}
