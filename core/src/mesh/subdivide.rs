//! Midpoint subdivision of a sequence, so folds narrower than a triangle can form (Chen 2011 §4.4,
//! "multi-resolution processing").
//!
//! Each level splits every triangle into four at its edge midpoints. Midpoint (rather than Loop) subdivision
//! keeps the original vertices where they are and adds no smoothing of its own: the subdivided frame is the
//! same surface, so the stretch analysis and the fold metrics see the capture unchanged. The original
//! vertices keep their indices and come first; the new edge vertices follow in order of first appearance.
//! Topology is shared by all frames, so it is built once and every frame is subdivided lazily. Texture
//! coordinates, when the input has them, are subdivided per triangle corner with the topology.

use super::{Frame, FrameSource, Topology};
use crate::error::{Error, Result};
use crate::vec3::{self, V3};
use std::collections::HashMap;
use std::sync::Arc;

/// One or more levels of midpoint subdivision of a topology.
#[derive(Debug, Clone)]
pub struct Subdivision {
    topology: Arc<Topology>,
    /// Per level: the coarse edges whose midpoints are the new vertices, in new-vertex order.
    levels: Vec<Vec<[u32; 2]>>,
}

fn one_level(topo: &Topology) -> Result<(Topology, Vec<[u32; 2]>)> {
    let nv = topo.n_vertices();
    let mut edge_id: HashMap<(u32, u32), u32> = HashMap::with_capacity(topo.n_triangles() * 2);
    let mut edges: Vec<[u32; 2]> = Vec::new();
    let mut mid = |a: u32, b: u32| -> u32 {
        let key = (a.min(b), a.max(b));
        *edge_id.entry(key).or_insert_with(|| {
            edges.push([key.0, key.1]);
            (nv + edges.len() - 1) as u32
        })
    };
    let mut tris = Vec::with_capacity(4 * topo.n_triangles());
    for &[a, b, c] in topo.triangles() {
        let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
        tris.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    let n = nv + edges.len();
    Ok((Topology::new(n, tris)?, edges))
}

impl Subdivision {
    /// `levels` rounds of 1-to-4 midpoint subdivision (each multiplies the triangle count by 4).
    pub fn new(topo: &Topology, levels: usize) -> Result<Self> {
        if levels > 4 {
            return Err(Error::param(
                "subdivide",
                format!("at most 4 levels (256× the triangles), got {levels}"),
            ));
        }
        let mut cur = topo.clone();
        let mut all = Vec::with_capacity(levels);
        for _ in 0..levels {
            let (next, edges) = one_level(&cur)?;
            // Texture coordinates follow the same children, seam-aware (`UvSet::subdivide`).
            let uvs = cur.uvs().map(|u| u.subdivide());
            all.push(edges);
            cur = next.with_uvs(uvs)?;
        }
        Ok(Subdivision {
            topology: Arc::new(cur),
            levels: all,
        })
    }

    pub fn topology(&self) -> &Arc<Topology> {
        &self.topology
    }

    /// Rounds of subdivision.
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// The subdivided triangle holding the point with barycentrics `bary` in coarse triangle `tri`, and its
    /// barycentrics there. Children of coarse triangle `i` are `4i..4i+4`: corner a, corner b, corner c, middle.
    pub fn locate(&self, tri: usize, bary: [f64; 3]) -> (usize, [f64; 3]) {
        let (mut t, [mut a, mut b, mut c]) = (tri, bary);
        for _ in 0..self.levels.len() {
            let (k, next) = if a >= 0.5 {
                (0, [2.0 * a - 1.0, 2.0 * b, 2.0 * c])
            } else if b >= 0.5 {
                (1, [2.0 * a, 2.0 * b - 1.0, 2.0 * c])
            } else if c >= 0.5 {
                (2, [2.0 * a, 2.0 * b, 2.0 * c - 1.0])
            } else {
                // Middle child [ab, bc, ca].
                (3, [1.0 - 2.0 * c, 1.0 - 2.0 * a, 1.0 - 2.0 * b])
            };
            t = 4 * t + k;
            [a, b, c] = next;
        }
        (t, [a, b, c])
    }

    /// Positions on the subdivided mesh: the originals first, then the edge midpoints.
    pub fn apply(&self, p: &[V3]) -> Frame {
        let mut cur = p.to_vec();
        for edges in &self.levels {
            cur.reserve(edges.len());
            for &[a, b] in edges {
                let m = vec3::scale(vec3::add(cur[a as usize], cur[b as usize]), 0.5);
                cur.push(m);
            }
        }
        cur
    }
}

/// The source under a [`SubdividedSource`]: borrowed for a one-off pass, owned where the subdivided source
/// must outlive the scope that opened the input (a job task's per-process input cache).
enum Inner<'a> {
    Borrowed(&'a dyn FrameSource),
    Owned(Box<dyn FrameSource + 'a>),
}

/// A source whose frames are subdivided on demand (nothing beyond one frame is held).
pub struct SubdividedSource<'a> {
    inner: Inner<'a>,
    subdivision: Subdivision,
}

impl<'a> SubdividedSource<'a> {
    pub fn new(inner: &'a dyn FrameSource, levels: usize) -> Result<Self> {
        Ok(SubdividedSource {
            subdivision: Subdivision::new(inner.topology(), levels)?,
            inner: Inner::Borrowed(inner),
        })
    }

    /// Like [`SubdividedSource::new`], taking ownership of the source.
    pub fn owned(inner: Box<dyn FrameSource + 'a>, levels: usize) -> Result<Self> {
        Ok(SubdividedSource {
            subdivision: Subdivision::new(inner.topology(), levels)?,
            inner: Inner::Owned(inner),
        })
    }

    fn inner(&self) -> &dyn FrameSource {
        match &self.inner {
            Inner::Borrowed(s) => *s,
            Inner::Owned(s) => s.as_ref(),
        }
    }
    pub fn subdivision(&self) -> &Subdivision {
        &self.subdivision
    }
}

impl FrameSource for SubdividedSource<'_> {
    fn topology(&self) -> &Arc<Topology> {
        self.subdivision.topology()
    }
    fn subdivided_from(&self) -> Option<(&dyn FrameSource, &Subdivision)> {
        Some((self.inner(), &self.subdivision))
    }
    fn n_frames(&self) -> usize {
        self.inner().n_frames()
    }
    fn read_frame(&self, t: usize) -> Result<Frame> {
        Ok(self.subdivision.apply(&self.inner().read_frame(t)?))
    }
    fn describe_frame(&self, t: usize) -> String {
        format!(
            "{} (subdivided {}×)",
            self.inner().describe_frame(t),
            self.subdivision.levels.len()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Sequence, UvSet};

    /// A point given on the coarse mesh lands on the fine triangle that holds the same 3D point.
    #[test]
    fn coarse_points_locate_on_their_fine_triangle() {
        let (topo, p) = crate::synth::sheet(4, 4, 1.0).unwrap();
        let p: Vec<V3> = p
            .iter()
            .map(|q| [q[0], q[1], 0.3 * (q[0] * 1.3).sin() * q[1]])
            .collect();
        let sub = Subdivision::new(&topo, 3).unwrap();
        let fine = sub.apply(&p);
        let ft = sub.topology().triangles();
        for (tri, bary) in [
            (0usize, [0.7, 0.2, 0.1]),
            (5, [0.1, 0.1, 0.8]),
            (7, [0.34, 0.33, 0.33]),
            (11, [0.05, 0.6, 0.35]),
        ] {
            let at = |pts: [V3; 3], b: [f64; 3]| {
                (0..3).fold([0.0; 3], |acc, k| vec3::add(acc, vec3::scale(pts[k], b[k])))
            };
            let want = at(topo.triangles()[tri].map(|v| p[v as usize]), bary);
            let (t, b) = sub.locate(tri, bary);
            assert_eq!(t / 64, tri);
            assert!(b.iter().all(|&x| x >= -1e-12) && (b.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let got = at(ft[t].map(|v| fine[v as usize]), b);
            assert!(
                vec3::norm(vec3::sub(got, want)) < 1e-12,
                "{tri}: {got:?} {want:?}"
            );
        }
    }

    /// Texture coordinates on a sheet cut by a seam: triangles left of x = 1.5 map (x, y) to (x, y), the others
    /// to (x + 10, y), so the vertices on the cut carry two coordinates. Midpoints are exact averages, so on the
    /// subdivided mesh every corner must still sit at its chart's affine map of its position.
    #[test]
    fn texture_coordinates_subdivide_per_corner_across_a_seam() {
        let (topo, p) = crate::synth::sheet(4, 3, 1.0).unwrap();
        let chart = |t: &[u32; 3], pts: &[V3]| -> f32 {
            let cx: f64 = t.iter().map(|&v| pts[v as usize][0]).sum::<f64>() / 3.0;
            if cx < 1.5 {
                0.0
            } else {
                10.0
            }
        };
        let mut uv = Vec::new();
        let mut corners = Vec::new();
        for t in topo.triangles() {
            let shift = chart(t, &p);
            let mut c = [0u32; 3];
            for k in 0..3 {
                let q = p[t[k] as usize];
                let want = [q[0] as f32 + shift, q[1] as f32];
                c[k] = match uv.iter().position(|u| *u == want) {
                    Some(i) => i as u32,
                    None => {
                        uv.push(want);
                        (uv.len() - 1) as u32
                    }
                };
            }
            corners.push(c);
        }
        let topo = (*topo)
            .clone()
            .with_uvs(Some(UvSet::new(uv, corners).unwrap()))
            .unwrap();
        let sub = Subdivision::new(&topo, 2).unwrap();
        let fine = sub.topology();
        let uvs = fine
            .uvs()
            .expect("subdivision keeps the texture coordinates");
        assert_eq!(uvs.corners().len(), fine.n_triangles());
        let q = sub.apply(&p);
        let mut seam_corners = 0;
        for (t, (tri, c)) in fine.triangles().iter().zip(uvs.corners()).enumerate() {
            // The coarse parent (children of i are 16i..16i+16 after two levels) decides the chart.
            let shift = chart(&topo.triangles()[t / 16], &p);
            for k in 0..3 {
                let x = q[tri[k] as usize];
                let got = uvs.uv()[c[k] as usize];
                assert!(
                    (got[0] - (x[0] as f32 + shift)).abs() < 1e-5
                        && (got[1] - x[1] as f32).abs() < 1e-5,
                    "fine triangle {t} corner {k}: uv {got:?} at {x:?}"
                );
                if (x[0] - 1.0).abs() < 1e-9 || (x[0] - 2.0).abs() < 1e-9 {
                    seam_corners += 1;
                }
            }
        }
        assert!(seam_corners > 0);
        // Two coordinates for the fine vertices on the cut: seam-aware midpoints, not one shared per edge.
        let split = uvs.split_seams(fine.n_vertices(), fine.triangles());
        assert!(split.source.len() > fine.n_vertices());
    }

    #[test]
    fn midpoint_keeps_original_vertices_first_and_the_surface() {
        let (topo, p) = crate::synth::sheet(5, 4, 0.2).unwrap();
        let seq = Sequence::new(topo.clone(), vec![p.clone()]).unwrap();
        let sub = SubdividedSource::new(&seq, 2).unwrap();
        let st = sub.topology();
        assert_eq!(st.n_triangles(), 16 * topo.n_triangles());
        // Euler: V − E + F stays 1 for a disk.
        let nv = st.n_vertices() as i64;
        let f = st.n_triangles() as i64;
        let e = (3 * f
            + st.tri_adj()
                .iter()
                .flatten()
                .filter(|&&u| u == crate::mesh::NONE)
                .count() as i64)
            / 2;
        assert_eq!(nv - e + f, 1);
        let q = sub.read_frame(0).unwrap();
        assert_eq!(&q[..p.len()], &p[..]);
        // Same area, same orientation.
        let area = |t: &Topology, x: &[V3]| -> (f64, f64) {
            let n = crate::mesh::geometry::triangle_normals(t, x);
            (
                crate::mesh::geometry::triangle_areas(t, x).iter().sum(),
                n.iter().map(|n| n[2]).fold(f64::INFINITY, f64::min),
            )
        };
        let (a0, n0) = area(&topo, &p);
        let (a1, n1) = area(st, &q);
        assert!((a0 - a1).abs() < 1e-12 && n0 > 0.99 && n1 > 0.99);
        assert!(Subdivision::new(&topo, 5)
            .unwrap_err()
            .to_string()
            .contains("subdivide"));
    }
}
