//! Fold tracing on one frame (Chen 2011 §4.4): seeds, axis, control lines, region of influence, anchors.
//!
//! * **Seeds** come from a priority queue of integrated shrinkage (absolute change), largest first, one at a
//!   time; seeds of the previous frame go first (the thesis' seed memory, which keeps folds where they were).
//! * **Axis**: the patch around the seed is flattened with [`super::lscm`]; from the seed's centroid a line
//!   is marched in the plane perpendicular to the shrinkage direction, following each crossed triangle's own
//!   direction, in both senses, until the shrinkage fades below `fade` of the seed's or the direction turns by
//!   more than `max_turn`.
//! * **Control lines** at ± width/2 beside the axis, width = `fold_width / |v|` (inversely proportional to the
//!   absolute change), mapped back to 3D with barycentric coordinates.
//! * **Region of influence**: patch triangles within α·|v| of the axis (eq. 4.3, measured from the traced axis
//!   rather than the seed point alone, so one long fold is not seeded twice); their seeds leave the queue.
//! * **Anchors** (§4.5): the triangles the control lines cross, rotating about the local fold direction —
//!   opposite senses on the two lines, so the strip between them rises into a ridge on the side of the
//!   normal (Popa et al. 2009 §5.1 rotate counter-clockwise about the fold edge) — by an angle proportional to
//!   the local shrinkage, capped at `max_angle`.

use super::lscm::lscm;
use super::params::StretchParams;
use super::smooth::FrameGeometry;
use super::tensor::shape;
use crate::folds::Anchor;
use crate::mesh::{Topology, NONE};
use crate::vec3::{self, V3};
use std::collections::{BTreeMap, BinaryHeap};

/// One traced fold.
#[derive(Debug, Clone)]
pub struct TracedFold {
    pub seed: u32,
    /// Absolute change |v| of the integrated shrinkage at the seed.
    pub change: f64,
    /// Distance between the control lines (same units as the mesh).
    pub width: f64,
    /// Axis polyline on the surface.
    pub axis: Vec<V3>,
    /// Unit fold direction (axis tangent) at the seed, on the seed triangle.
    pub direction: V3,
    /// The two control lines (each possibly split where it leaves the patch).
    pub lines: Vec<Vec<V3>>,
}

/// Result of tracing one frame.
#[derive(Debug, Clone, Default)]
pub struct FrameFolds {
    pub folds: Vec<TracedFold>,
    /// Sorted by triangle, unique.
    pub anchors: Vec<Anchor>,
    /// Seeds taken from the queue (each one flattened a patch), folds or not.
    pub seeds_tried: usize,
}

/// Traces frames one after the other, carrying the seed memory (O(triangles)).
pub struct FoldTracer {
    prev_seed: Vec<bool>,
    tri_local: Vec<u32>,
    vert_local: Vec<u32>,
}

/// A flattened patch around a seed.
struct Patch {
    tris: Vec<u32>,
    verts: Vec<u32>,
    uv: Vec<[f64; 2]>,
}

fn tri_pts(topo: &Topology, p: &[V3], t: usize) -> [V3; 3] {
    topo.triangles()[t].map(|v| p[v as usize])
}

fn norm2(a: [f64; 2]) -> f64 {
    (a[0] * a[0] + a[1] * a[1]).sqrt()
}

impl FoldTracer {
    pub fn new(topo: &Topology) -> Self {
        FoldTracer {
            prev_seed: vec![false; topo.n_triangles()],
            tri_local: vec![NONE; topo.n_triangles()],
            vert_local: vec![NONE; topo.n_vertices()],
        }
    }

    /// Traces the folds of one frame from its integrated shrinkage `shrink` (absolute change per triangle)
    /// and unit shrinkage directions `dir`. `h` is the mesh's mean edge length.
    #[allow(clippy::too_many_arguments)]
    pub fn trace(
        &mut self,
        topo: &Topology,
        p: &[V3],
        geom: &FrameGeometry,
        shrink: &[f64],
        dir: &[V3],
        h: f64,
        params: &StretchParams,
    ) -> FrameFolds {
        let n_tri = topo.n_triangles();
        let seed_min = 1.0 + params.min_shrink;
        let mut heap: BinaryHeap<(bool, u64, std::cmp::Reverse<u32>)> = shrink
            .iter()
            .enumerate()
            .filter(|(_, &s)| s >= seed_min && s.is_finite())
            .map(|(t, &s)| (self.prev_seed[t], s.to_bits(), std::cmp::Reverse(t as u32)))
            .collect();
        let mut consumed = vec![false; n_tri];
        let mut new_seed = vec![false; n_tri];
        let mut anchors: BTreeMap<u32, Anchor> = BTreeMap::new();
        let mut folds = Vec::new();
        let mut seeds_tried = 0;
        while let Some((_, _, std::cmp::Reverse(s))) = heap.pop() {
            let s = s as usize;
            if consumed[s] {
                continue;
            }
            consumed[s] = true;
            seeds_tried += 1;
            let Some(patch) = self.patch(topo, p, geom, s, params.patch_radius * h) else {
                continue;
            };
            let fold = self.trace_seed(
                topo,
                p,
                geom,
                shrink,
                dir,
                h,
                params,
                s,
                &patch,
                &mut anchors,
            );
            if let Some(fold) = fold {
                // Region of influence (eq. 4.3), measured from the axis in the plane.
                let reach = params.alpha * shrink[s] * h;
                let axis_uv = &fold.1;
                for &t in &patch.tris {
                    let c = self.uv_centroid(topo, &patch, t as usize);
                    if dist_to_polyline(c, axis_uv) <= reach {
                        consumed[t as usize] = true;
                    }
                }
                new_seed[s] = true;
                folds.push(fold.0);
            }
            self.release(&patch);
        }
        self.prev_seed = new_seed;
        FrameFolds {
            folds,
            anchors: anchors.into_values().collect(),
            seeds_tried,
        }
    }

    /// Triangles whose centroid lies within `radius` of the seed's (breadth-first, so the patch is connected),
    /// flattened with LSCM. Fills `tri_local` / `vert_local`; [`Self::release`] clears them.
    fn patch(
        &mut self,
        topo: &Topology,
        p: &[V3],
        geom: &FrameGeometry,
        s: usize,
        radius: f64,
    ) -> Option<Patch> {
        let c0 = geom.centroids[s];
        let mut tris = vec![s as u32];
        self.tri_local[s] = 0;
        let mut k = 0;
        while k < tris.len() {
            let t = tris[k] as usize;
            k += 1;
            for &u in &topo.tri_adj()[t] {
                if u == NONE || self.tri_local[u as usize] != NONE {
                    continue;
                }
                if vec3::norm(vec3::sub(geom.centroids[u as usize], c0)) <= radius {
                    self.tri_local[u as usize] = tris.len() as u32;
                    tris.push(u);
                }
            }
        }
        let mut verts = Vec::new();
        let mut local_tris = Vec::with_capacity(tris.len());
        for &t in &tris {
            let tri = topo.triangles()[t as usize];
            local_tris.push(tri.map(|v| {
                if self.vert_local[v as usize] == NONE {
                    self.vert_local[v as usize] = verts.len() as u32;
                    verts.push(v);
                }
                self.vert_local[v as usize]
            }));
        }
        let pos: Vec<V3> = verts.iter().map(|&v| p[v as usize]).collect();
        let pin0 = local_tris[0][0] as usize;
        let pin1 = (0..pos.len())
            .max_by(|&a, &b| {
                let da = vec3::norm(vec3::sub(pos[a], pos[pin0]));
                let db = vec3::norm(vec3::sub(pos[b], pos[pin0]));
                da.total_cmp(&db)
            })
            .unwrap_or(pin0);
        let patch_uv = lscm(&pos, &local_tris, (pin0, pin1));
        let patch = Patch {
            tris,
            verts,
            uv: patch_uv.unwrap_or_default(),
        };
        if patch.uv.is_empty() {
            self.release(&patch);
            return None;
        }
        Some(patch)
    }

    fn release(&mut self, patch: &Patch) {
        for &t in &patch.tris {
            self.tri_local[t as usize] = NONE;
        }
        for &v in &patch.verts {
            self.vert_local[v as usize] = NONE;
        }
    }

    fn uv_tri(&self, topo: &Topology, patch: &Patch, t: usize) -> [[f64; 2]; 3] {
        topo.triangles()[t].map(|v| patch.uv[self.vert_local[v as usize] as usize])
    }

    fn uv_centroid(&self, topo: &Topology, patch: &Patch, t: usize) -> [f64; 2] {
        let q = self.uv_tri(topo, patch, t);
        [
            (q[0][0] + q[1][0] + q[2][0]) / 3.0,
            (q[0][1] + q[1][1] + q[2][1]) / 3.0,
        ]
    }

    /// The linear map of triangle `t` from its local 3D frame (e1, e2) to the plane, as a 2x2 matrix.
    fn uv_map(&self, topo: &Topology, p: &[V3], patch: &Patch, t: usize) -> Option<[[f64; 2]; 2]> {
        let [l1, a, b] = shape(tri_pts(topo, p, t));
        if l1 <= 0.0 || b <= 0.0 {
            return None;
        }
        let q = self.uv_tri(topo, patch, t);
        let d1 = [q[1][0] - q[0][0], q[1][1] - q[0][1]];
        let d2 = [q[2][0] - q[0][0], q[2][1] - q[0][1]];
        // B [l1 a; 0 b] = [d1 d2]  ⇒  B = [d1/l1, (d2 − a d1/l1)/b].
        let c1 = [d1[0] / l1, d1[1] / l1];
        let c2 = [(d2[0] - a * c1[0]) / b, (d2[1] - a * c1[1]) / b];
        Some([[c1[0], c2[0]], [c1[1], c2[1]]])
    }

    /// A 3D tangent vector of triangle `t` in the plane.
    fn to_uv(
        &self,
        topo: &Topology,
        p: &[V3],
        geom: &FrameGeometry,
        patch: &Patch,
        t: usize,
        d: V3,
    ) -> Option<[f64; 2]> {
        let m = self.uv_map(topo, p, patch, t)?;
        let x = [vec3::dot(d, geom.e1[t]), vec3::dot(d, geom.e2[t])];
        Some([
            m[0][0] * x[0] + m[0][1] * x[1],
            m[1][0] * x[0] + m[1][1] * x[1],
        ])
    }

    /// A plane vector at triangle `t` back on the surface (unit 3D tangent).
    fn to_3d(
        &self,
        topo: &Topology,
        p: &[V3],
        geom: &FrameGeometry,
        patch: &Patch,
        t: usize,
        d: [f64; 2],
    ) -> Option<V3> {
        let m = self.uv_map(topo, p, patch, t)?;
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        if det.abs() < 1e-300 {
            return None;
        }
        let x = [
            (m[1][1] * d[0] - m[0][1] * d[1]) / det,
            (-m[1][0] * d[0] + m[0][0] * d[1]) / det,
        ];
        let v = vec3::normalize(vec3::add(
            vec3::scale(geom.e1[t], x[0]),
            vec3::scale(geom.e2[t], x[1]),
        ));
        (vec3::norm(v) > 0.0).then_some(v)
    }

    /// Walks from triangle `t` to the patch triangle containing plane point `q`; its barycentrics.
    fn locate(
        &self,
        topo: &Topology,
        patch: &Patch,
        mut t: usize,
        q: [f64; 2],
    ) -> Option<(usize, [f64; 3])> {
        for _ in 0..64 {
            let [a, b, c] = self.uv_tri(topo, patch, t);
            let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
            if det.abs() < 1e-300 {
                return None;
            }
            let l1 = ((q[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (q[1] - a[1])) / det;
            let l2 = ((b[0] - a[0]) * (q[1] - a[1]) - (q[0] - a[0]) * (b[1] - a[1])) / det;
            let bary = [1.0 - l1 - l2, l1, l2];
            let (k, &worst) = bary
                .iter()
                .enumerate()
                .min_by(|x, y| x.1.total_cmp(y.1))
                .expect("three");
            if worst >= -1e-9 {
                return Some((t, bary));
            }
            // Cross the edge opposite corner k: edge (k+1, k+2) is topology edge (k+1) % 3.
            let u = topo.tri_adj()[t][(k + 1) % 3];
            if u == NONE || self.tri_local[u as usize] == NONE {
                return None;
            }
            t = u as usize;
        }
        None
    }

    /// Traces the axis and control lines from seed `s`; adds its anchors. Returns the fold and its axis in the
    /// plane, or `None` when the axis is too short to be a fold.
    #[allow(clippy::too_many_arguments)]
    fn trace_seed(
        &self,
        topo: &Topology,
        p: &[V3],
        geom: &FrameGeometry,
        shrink: &[f64],
        dir: &[V3],
        h: f64,
        params: &StretchParams,
        s: usize,
        patch: &Patch,
        anchors: &mut BTreeMap<u32, Anchor>,
    ) -> Option<(TracedFold, Vec<[f64; 2]>)> {
        let axis_of = |t: usize| -> Option<[f64; 2]> {
            let a3 = vec3::cross(geom.normals[t], dir[t]);
            let a = self.to_uv(topo, p, geom, patch, t, a3)?;
            let n = norm2(a);
            (n > 0.0).then(|| [a[0] / n, a[1] / n])
        };
        let start = self.uv_centroid(topo, patch, s);
        let h0 = axis_of(s)?;
        let fade = 1.0 + params.fade * (shrink[s] - 1.0);
        let cos_turn = params.max_turn_deg.to_radians().cos();
        let step = 0.4 * h;
        let max_steps = (2.0 * params.patch_radius * h / step) as usize + 1;
        // March in both senses; each point remembers its triangle.
        let mut halves: [Vec<([f64; 2], usize)>; 2] = [Vec::new(), Vec::new()];
        for (half, sense) in halves.iter_mut().zip([1.0, -1.0]) {
            let mut heading = [h0[0] * sense, h0[1] * sense];
            let (mut q, mut t) = (start, s);
            for _ in 0..max_steps {
                let nq = [q[0] + step * heading[0], q[1] + step * heading[1]];
                let Some((nt, _)) = self.locate(topo, patch, t, nq) else {
                    break;
                };
                if nt != t {
                    if shrink[nt] < fade {
                        break;
                    }
                    let Some(mut a) = axis_of(nt) else { break };
                    let c = a[0] * heading[0] + a[1] * heading[1];
                    if c < 0.0 {
                        a = [-a[0], -a[1]];
                    }
                    if c.abs() < cos_turn {
                        break;
                    }
                    heading = a;
                }
                q = nq;
                t = nt;
                half.push((q, t));
            }
        }
        let mut axis: Vec<([f64; 2], usize)> = halves[1].iter().rev().copied().collect();
        axis.push((start, s));
        axis.extend(halves[0].iter().copied());
        let length: f64 = axis
            .windows(2)
            .map(|w| norm2([w[1].0[0] - w[0].0[0], w[1].0[1] - w[0].0[1]]))
            .sum();
        if length < params.min_length * h || axis.len() < 2 {
            return None;
        }
        let width = params.fold_width * h / shrink[s];
        let max_angle = params.max_angle_deg.to_radians();
        let point3 = |t: usize, bary: [f64; 3]| -> V3 {
            let q = tri_pts(topo, p, t);
            vec3::add(
                vec3::add(vec3::scale(q[0], bary[0]), vec3::scale(q[1], bary[1])),
                vec3::scale(q[2], bary[2]),
            )
        };
        let mut lines: Vec<Vec<V3>> = Vec::new();
        // side −1: the line on the −normal side of the axis rotates about +tangent; side +1 about −tangent.
        for side in [-1.0f64, 1.0] {
            let mut line: Vec<V3> = Vec::new();
            for i in 0..axis.len() {
                let (a, b) = (
                    axis[i.saturating_sub(1)].0,
                    axis[(i + 1).min(axis.len() - 1)].0,
                );
                let tg = [b[0] - a[0], b[1] - a[1]];
                let tn = norm2(tg);
                if tn <= 0.0 {
                    continue;
                }
                let tg = [tg[0] / tn, tg[1] / tn];
                let nrm = [-tg[1], tg[0]];
                let (q, ta) = axis[i];
                let off = [
                    q[0] + side * 0.5 * width * nrm[0],
                    q[1] + side * 0.5 * width * nrm[1],
                ];
                let Some((t, bary)) = self.locate(topo, patch, ta, off) else {
                    if line.len() >= 2 {
                        lines.push(std::mem::take(&mut line));
                    } else {
                        line.clear();
                    }
                    continue;
                };
                line.push(point3(t, bary));
                let Some(tan3) = self.to_3d(topo, p, geom, patch, t, tg) else {
                    continue;
                };
                let angle = (params.angle_gain * (shrink[ta] - 1.0)).clamp(0.0, max_angle);
                if angle <= 0.0 {
                    continue;
                }
                anchors.entry(t as u32).or_insert(Anchor {
                    triangle: t as u32,
                    axis: vec3::scale(tan3, -side),
                    angle,
                });
            }
            if line.len() >= 2 {
                lines.push(line);
            }
        }
        let axis3: Vec<V3> = axis
            .iter()
            .filter_map(|&(q, t)| self.locate(topo, patch, t, q).map(|(t, b)| point3(t, b)))
            .collect();
        let direction = self.to_3d(topo, p, geom, patch, s, h0).unwrap_or([0.0; 3]);
        let axis_uv = axis.iter().map(|a| a.0).collect();
        Some((
            TracedFold {
                seed: s as u32,
                change: shrink[s],
                width,
                axis: axis3,
                direction,
                lines,
            },
            axis_uv,
        ))
    }
}

/// Distance from `q` to the polyline `line` in the plane.
fn dist_to_polyline(q: [f64; 2], line: &[[f64; 2]]) -> f64 {
    if line.len() == 1 {
        return norm2([q[0] - line[0][0], q[1] - line[0][1]]);
    }
    line.windows(2)
        .map(|w| {
            let (a, b) = (w[0], w[1]);
            let ab = [b[0] - a[0], b[1] - a[1]];
            let l2 = ab[0] * ab[0] + ab[1] * ab[1];
            let t = if l2 > 0.0 {
                (((q[0] - a[0]) * ab[0] + (q[1] - a[1]) * ab[1]) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            norm2([q[0] - a[0] - t * ab[0], q[1] - a[1] - t * ab[1]])
        })
        .fold(f64::INFINITY, f64::min)
}
