//! Texture coordinates of a mesh, kept per triangle corner.
//!
//! A vertex on a UV seam has one texture coordinate per chart it borders, so coordinates cannot be a
//! per-vertex attribute: each triangle corner indexes its own entry of a separate table (the way OBJ's
//! `f v/vt` stores them), and seams stay exact. Like the connectivity, the UV set of frame 0 (or of the
//! point cache's topology OBJ) holds for every frame. Formats that need one coordinate per vertex (glTF)
//! split the seam vertices with [`UvSet::split_seams`].

use crate::error::{Error, Result};
use std::collections::HashMap;

/// Texture coordinates and, for each triangle, the index of each corner's coordinate.
#[derive(Debug, Clone, PartialEq)]
pub struct UvSet {
    uv: Vec<[f32; 2]>,
    corners: Vec<[u32; 3]>,
}

impl UvSet {
    /// Checks that every corner index is in range and every coordinate is finite; errors name the triangle or
    /// the coordinate (1-based, as OBJ numbers `vt` lines).
    pub fn new(uv: Vec<[f32; 2]>, corners: Vec<[u32; 3]>) -> Result<Self> {
        if let Some(i) = uv
            .iter()
            .position(|c| !(c[0].is_finite() && c[1].is_finite()))
        {
            return Err(Error::mesh(format!(
                "texture coordinate {} is not finite ({:?})",
                i + 1,
                uv[i]
            )));
        }
        for (t, c) in corners.iter().enumerate() {
            if let Some(&k) = c.iter().find(|&&k| k as usize >= uv.len()) {
                return Err(Error::mesh(format!(
                    "triangle {t} uses texture coordinate {}, but there are only {}",
                    u64::from(k) + 1,
                    uv.len()
                )));
            }
        }
        Ok(UvSet { uv, corners })
    }

    /// The coordinates, in OBJ's convention (origin at the bottom left of the image, v up).
    pub fn uv(&self) -> &[[f32; 2]] {
        &self.uv
    }

    /// `corners()[t][k]` indexes [`UvSet::uv`] for corner `k` of triangle `t`.
    pub fn corners(&self) -> &[[u32; 3]] {
        &self.corners
    }

    /// One coordinate per vertex, duplicating the vertices that carry more than one (the seams). Vertex `v`
    /// keeps index `v` with the first coordinate a triangle gives it, so a mesh without seams maps to itself;
    /// the extra copies follow, in order of first use. `triangles` are the input triangles re-indexed.
    pub fn split_seams(&self, n_vertices: usize, triangles: &[[u32; 3]]) -> SeamSplit {
        let mut first: Vec<Option<u32>> = vec![None; n_vertices];
        let mut extra: HashMap<(u32, u32), u32> = HashMap::new();
        let mut source: Vec<u32> = (0..n_vertices as u32).collect();
        let mut uv_of: Vec<u32> = vec![u32::MAX; n_vertices];
        let mut tris = Vec::with_capacity(triangles.len());
        for (tri, corner) in triangles.iter().zip(&self.corners) {
            let mut out = [0u32; 3];
            for k in 0..3 {
                let (v, c) = (tri[k], corner[k]);
                out[k] = match first[v as usize] {
                    None => {
                        first[v as usize] = Some(c);
                        uv_of[v as usize] = c;
                        v
                    }
                    Some(f) if f == c => v,
                    Some(_) => *extra.entry((v, c)).or_insert_with(|| {
                        source.push(v);
                        uv_of.push(c);
                        (source.len() - 1) as u32
                    }),
                };
            }
            tris.push(out);
        }
        // A vertex no triangle uses gets (0, 0): glTF needs a coordinate for every vertex of the accessor.
        let uv = uv_of
            .iter()
            .map(|&c| self.uv.get(c as usize).copied().unwrap_or([0.0, 0.0]))
            .collect();
        SeamSplit {
            source,
            uv,
            triangles: tris,
        }
    }

    /// One round of 1-to-4 midpoint subdivision, matching [`crate::mesh::subdivide`]'s child triangles
    /// (`[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]`). A new corner gets the midpoint of the two
    /// corner coordinates of its edge *in that triangle*, keyed by that pair of coordinates: across a seam the
    /// two sides differ and each gets its own midpoint, elsewhere both sides share one.
    pub(crate) fn subdivide(&self) -> UvSet {
        let mut uv = self.uv.clone();
        let mut mids: HashMap<(u32, u32), u32> = HashMap::with_capacity(self.corners.len() * 2);
        let mut mid = |a: u32, b: u32, uv: &mut Vec<[f32; 2]>| -> u32 {
            if a == b {
                return a;
            }
            let key = (a.min(b), a.max(b));
            *mids.entry(key).or_insert_with(|| {
                let (p, q) = (uv[a as usize], uv[b as usize]);
                uv.push([0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]);
                (uv.len() - 1) as u32
            })
        };
        let mut corners = Vec::with_capacity(4 * self.corners.len());
        for &[a, b, c] in &self.corners {
            let (ab, bc, ca) = (mid(a, b, &mut uv), mid(b, c, &mut uv), mid(c, a, &mut uv));
            corners.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        UvSet { uv, corners }
    }
}

/// A mesh re-indexed so that every vertex has exactly one texture coordinate (see [`UvSet::split_seams`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SeamSplit {
    /// The original vertex of each split vertex: gather positions, normals and morph targets through it.
    pub source: Vec<u32>,
    /// The coordinate of each split vertex.
    pub uv: Vec<[f32; 2]>,
    pub triangles: Vec<[u32; 3]>,
}

impl SeamSplit {
    /// `values` (one per original vertex) for the split vertices.
    pub fn gather<T: Copy>(&self, values: &[T]) -> Vec<T> {
        self.source.iter().map(|&v| values[v as usize]).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles sharing edge 1–2, cut by a seam along it: vertices 1 and 2 carry two coordinates each.
    fn seamed() -> (Vec<[u32; 3]>, UvSet) {
        let tris = vec![[0, 1, 2], [2, 1, 3]];
        let uv = vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [0.0, 1.0],
            [0.5, 0.5],
            [0.6, 0.4],
            [0.9, 0.9],
        ];
        let set = UvSet::new(uv, vec![[0, 1, 2], [3, 4, 5]]).unwrap();
        (tris, set)
    }

    #[test]
    fn seams_split_and_everything_else_keeps_its_index() {
        let (tris, set) = seamed();
        let s = set.split_seams(4, &tris);
        assert_eq!(s.source, vec![0, 1, 2, 3, 2, 1]);
        assert_eq!(s.triangles, vec![[0, 1, 2], [4, 5, 3]]);
        assert_eq!(
            s.uv,
            vec![
                [0.0, 0.0],
                [1.0, 0.0],
                [0.0, 1.0],
                [0.9, 0.9],
                [0.5, 0.5],
                [0.6, 0.4]
            ]
        );
        // Every corner sees its own coordinate at its own position.
        for (t, tri) in s.triangles.iter().enumerate() {
            for k in 0..3 {
                assert_eq!(s.source[tri[k] as usize], tris[t][k]);
                assert_eq!(
                    s.uv[tri[k] as usize],
                    set.uv()[set.corners()[t][k] as usize]
                );
            }
        }
        assert_eq!(
            s.gather(&['a', 'b', 'c', 'd']),
            vec!['a', 'b', 'c', 'd', 'c', 'b']
        );
        // No seam: the identity.
        let shared = UvSet::new(
            vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]],
            vec![[0, 1, 2], [2, 1, 3]],
        )
        .unwrap();
        let s = shared.split_seams(4, &tris);
        assert_eq!(s.source, vec![0, 1, 2, 3]);
        assert_eq!(s.triangles, tris);
    }

    #[test]
    fn subdivision_gives_each_side_of_a_seam_its_own_midpoint() {
        let (_, set) = seamed();
        let fine = set.subdivide();
        assert_eq!(fine.corners().len(), 8);
        // Six coarse coordinates plus three midpoints per triangle (no edge is shared in UV space).
        assert_eq!(fine.uv().len(), 12);
        let uv = |t: usize, k: usize| fine.uv()[fine.corners()[t][k] as usize];
        // Triangle 0's child [a, ab, ca]: ab is the midpoint of (0,0) and (1,0).
        assert_eq!(uv(0, 1), [0.5, 0.0]);
        // Edge 1–2 is the seam: triangle 0 sees the midpoint of (1,0),(0,1); triangle 1 that of (0.5,0.5),(0.6,0.4).
        assert_eq!(uv(1, 2), [0.5, 0.5]);
        let got = uv(4, 1);
        assert!(
            (got[0] - 0.55).abs() < 1e-6 && (got[1] - 0.45).abs() < 1e-6,
            "{got:?}"
        );
        // Without a seam the shared edge has one midpoint, used by both sides.
        let shared = UvSet::new(
            vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]],
            vec![[0, 1, 2], [2, 1, 3]],
        )
        .unwrap()
        .subdivide();
        assert_eq!(shared.uv().len(), 4 + 5);
    }

    #[test]
    fn bad_sets_are_named() {
        let e = UvSet::new(vec![[0.0, 0.0]], vec![[0, 0, 1]])
            .unwrap_err()
            .to_string();
        assert!(e.contains("triangle 0 uses texture coordinate 2"), "{e}");
        let e = UvSet::new(vec![[f32::NAN, 0.0]], vec![[0, 0, 0]])
            .unwrap_err()
            .to_string();
        assert!(e.contains("texture coordinate 1 is not finite"), "{e}");
    }
}
