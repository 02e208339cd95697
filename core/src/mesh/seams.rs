//! Seams: vertices that a garment's file keeps apart but that lie at one point of the surface.
//!
//! Garments are often written as panels whose shared border vertices are duplicated, not welded: the sewing
//! lines of a pattern-based garment, or the UV seams of an exporter that splits a vertex wherever its texture
//! coordinates differ. For crease each copy is a vertex on an open rim, and everything it computes per vertex
//! (normals, the relief's heights along them, the anchors' rotations on either side, the shading refinement)
//! differs between the two sides. Left alone, the two rims of every seam move apart: on a sleeve cut open
//! along its length the output's copies stood a tenth of an edge apart on average and up to three quarters of
//! one, a crack along the whole seam, further than the folds moved the cloth.
//!
//! So a finished frame closes its seams: every group of vertices that coincide in the captured frame gets the
//! mean of the group's output positions. The folds on either side are still made by each side alone; what the
//! seam guarantees is that the garment stays in one piece wherever its capture was in one piece.
//!
//! Coincide means closer than [`TOLERANCE`] mean edge lengths in the captured frame and not sharing a
//! triangle (a short edge of a valid triangle is cloth, not a seam). Found afresh in every frame from that
//! frame alone, so the result is a pure function of the frame and comes out the same wherever it is computed.

use crate::mesh::Topology;
use crate::vec3::{self, V3};

/// Vertices closer than this many mean edge lengths are one point of the surface (a sewing line written with
/// rounding, or two copies of the same number).
pub const TOLERANCE: f64 = 1e-3;

/// The sweep's direction (unit length, oblique to the axes).
const DIRECTION: V3 = [
    0.577_350_269_189_625_8,
    0.654_653_670_707_977_1,
    0.487_950_036_474_266_7,
];

/// The groups of coincident vertices of one captured frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Seams {
    /// Members of every group, group after group, each in increasing vertex order.
    members: Vec<u32>,
    /// Start of each group in `members`, and its end.
    offsets: Vec<usize>,
}

impl Seams {
    /// The coincident vertices of frame `p` (positions indexed like `topo`'s vertices).
    pub fn of_frame(topo: &Topology, p: &[V3]) -> Self {
        let n = topo.n_vertices();
        if p.len() < n {
            return Seams::default();
        }
        let tol = TOLERANCE * crate::shape::mean_edge_length(topo, p);
        if !(tol > 0.0 && tol.is_finite()) || n < 2 {
            return Seams::default();
        }
        // Sorted along a direction, a pair closer than `tol` is at most `tol` apart along it: each vertex is
        // compared with the few that follow it within that, so the search is one sort and a sweep (no seams:
        // about one comparison per vertex). The direction is oblique to every axis, so that the rows and columns
        // of a mesh laid out on a grid do not share one coordinate.
        let along: Vec<f64> = p[..n].iter().map(|q| vec3::dot(*q, DIRECTION)).collect();
        let mut order: Vec<u32> = (0..n as u32)
            .filter(|&v| along[v as usize].is_finite())
            .collect();
        order.sort_by(|&a, &b| {
            along[a as usize]
                .total_cmp(&along[b as usize])
                .then(a.cmp(&b))
        });
        let mut parent: Vec<u32> = (0..n as u32).collect();
        for (k, &v) in order.iter().enumerate() {
            let q = p[v as usize];
            for &u in &order[k + 1..] {
                let r = p[u as usize];
                if along[u as usize] - along[v as usize] > tol {
                    break;
                }
                if vec3::norm(vec3::sub(q, r)) <= tol
                    && !share_triangle(topo, v as usize, u as usize)
                {
                    union(&mut parent, v, u);
                }
            }
        }
        // Groups in the order of their smallest vertex (every root is its group's smallest), members in
        // increasing order; a vertex alone is no seam.
        let roots: Vec<u32> = (0..n as u32).map(|v| find(&mut parent, v)).collect();
        let mut size = vec![0u32; n];
        for &r in &roots {
            size[r as usize] += 1;
        }
        let mut slot = vec![usize::MAX; n];
        let mut groups: Vec<Vec<u32>> = Vec::new();
        for (v, &r) in roots.iter().enumerate() {
            if size[r as usize] > 1 {
                if slot[r as usize] == usize::MAX {
                    slot[r as usize] = groups.len();
                    groups.push(Vec::new());
                }
                groups[slot[r as usize]].push(v as u32);
            }
        }
        let mut seams = Seams::default();
        for g in groups {
            seams.offsets.push(seams.members.len());
            seams.members.extend(g);
        }
        seams.offsets.push(seams.members.len());
        seams
    }

    /// Whether the frame has no coincident vertices.
    pub fn is_empty(&self) -> bool {
        self.members.is_empty()
    }

    /// Number of groups of coincident vertices.
    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// The groups, each a slice of vertex indices in increasing order.
    pub fn groups(&self) -> impl Iterator<Item = &[u32]> {
        self.offsets.windows(2).map(|w| &self.members[w[0]..w[1]])
    }

    /// Every group of `out` moved to the mean of its members' positions (summed in vertex order).
    pub fn close(&self, out: &mut [V3]) {
        for g in self.groups() {
            if g.iter().any(|&v| v as usize >= out.len()) {
                continue;
            }
            let sum = g
                .iter()
                .fold([0.0; 3], |s, &v| vec3::add(s, out[v as usize]));
            let mean = vec3::scale(sum, 1.0 / g.len() as f64);
            for &v in g {
                out[v as usize] = mean;
            }
        }
    }
}

fn share_triangle(topo: &Topology, a: usize, b: usize) -> bool {
    topo.vertex_triangles(a)
        .iter()
        .any(|&t| topo.triangles()[t as usize].contains(&(b as u32)))
}

fn find(parent: &mut [u32], v: u32) -> u32 {
    let mut r = v;
    while parent[r as usize] != r {
        r = parent[r as usize];
    }
    let mut x = v;
    while parent[x as usize] != r {
        let next = parent[x as usize];
        parent[x as usize] = r;
        x = next;
    }
    r
}

fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        // The smaller index is the root, so roots do not depend on the order of the unions.
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        parent[hi as usize] = lo;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A strip of `n` quads along x; with `cut`, split into two panels at that column, whose two border
    /// vertices the right panel has copies of.
    fn strip(n: usize, cut: Option<usize>) -> (Topology, Vec<V3>) {
        let mut p = Vec::new();
        for i in 0..=n {
            p.push([i as f64, 0.0, 0.0]);
            p.push([i as f64, 1.0, 0.0]);
        }
        let copies = (p.len() as u32, p.len() as u32 + 1);
        if let Some(c) = cut {
            p.push(p[2 * c]);
            p.push(p[2 * c + 1]);
        }
        let mut tris = Vec::new();
        for i in 0..n {
            let mut a = (2 * i) as u32;
            let mut b = a + 1;
            let (c, d) = (a + 2, a + 3);
            if cut == Some(i) {
                (a, b) = copies;
            }
            tris.push([a, c, b]);
            tris.push([b, c, d]);
        }
        (Topology::new(p.len(), tris).unwrap(), p)
    }

    #[test]
    fn split_panels_are_found_and_closed() {
        let (topo, p) = strip(6, Some(3));
        let seams = Seams::of_frame(&topo, &p);
        let groups: Vec<Vec<u32>> = seams.groups().map(|g| g.to_vec()).collect();
        assert_eq!(groups, vec![vec![6, 14], vec![7, 15]]);
        let mut out = p.clone();
        out[6][2] = 0.2;
        out[14][2] = -0.1;
        out[15][1] = 1.3;
        seams.close(&mut out);
        assert!((out[6][2] - 0.05).abs() < 1e-15 && out[6] == out[14]);
        assert!((out[7][1] - 1.15).abs() < 1e-15 && out[7] == out[15]);
        assert_eq!(out[5], p[5]);
    }

    /// A welded mesh has no seams, and a vertex a hair from its neighbour across a triangle is cloth, not a
    /// seam.
    #[test]
    fn welded_cloth_has_none() {
        let (topo, mut p) = strip(6, None);
        assert!(Seams::of_frame(&topo, &p).is_empty());
        p[3] = vec3::add(p[2], [1e-6, 1e-6, 0.0]);
        assert!(Seams::of_frame(&topo, &p).is_empty());
    }
}
