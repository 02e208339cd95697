//! The work on one seed of a frame (Chen 2011 §4.4): patch, axis, control lines, region of influence, anchors.
//! The seeds' order and the seed memory are [`super::tracer`]'s.
//!
//! * **Axis** ([`SeedWork::axis`]): the patch around the seed is flattened ([`super::unfold`] by default, with
//!   LSCM where unfolding folds triangles over; on request [`super::lscm`] everywhere); from the seed's centroid a line
//!   is marched in the plane perpendicular to the shrinkage direction, following each crossed triangle's own
//!   direction, in both senses, until the shrinkage fades below `fade` of the seed's or the direction turns by
//!   more than `max_turn`.
//! * **Control lines** ([`SeedWork::control_lines`]) at ± width/2 beside the axis, width = `fold_width / |v|`
//!   (inversely proportional to the absolute change), located on the traced mesh as (triangle, barycentric)
//!   samples, so that they can be realised on a finer mesh than the one traced ([`super::realise`]).
//! * **Region of influence** ([`SeedWork::region`]): patch triangles within α·|v| of the axis (eq. 4.3,
//!   measured from the traced axis rather than the seed point alone, so one long fold is not seeded twice);
//!   their seeds leave the queue.
//! * **Ridge side** ([`ridge_sign`]): the strip between the control lines rises towards the side where the
//!   captured surface already bulges along the axis (the capture flattened the fold but kept a trace of it), else
//!   away from the frame's centroid. Never the mesh's winding: flipping every triangle gives the same fold.
//! * **Anchors** (§4.5, [`super::realise`]): the triangles the control lines cross, rotating about the local
//!   fold direction by opposite senses on the two lines, so the strip between them rises into a ridge (Popa et
//!   al. 2009 §5.1 rotate counter-clockwise about the fold edge), by the angle [`fold_angle`] that gives back
//!   the length the capture lost.

use super::lscm::lscm_with;
use super::params::StretchParams;
use super::smooth::FrameGeometry;
use super::symbolic::SymbolicCache;
use super::tensor::shape;
use super::unfold::{PatchRef, Unfolder};
use crate::mesh::{Topology, NONE};
use crate::vec3::{self, V3};
use std::sync::Arc;

/// What tracing reads of one frame.
pub struct FrameField<'a> {
    pub topo: &'a Topology,
    pub p: &'a [V3],
    pub geom: &'a FrameGeometry,
    /// Integrated shrinkage (absolute change, 1 = none) per triangle.
    pub shrink: &'a [f64],
    /// Unit shrinkage direction per triangle.
    pub dir: &'a [V3],
    /// Mean edge length of the traced mesh.
    pub h: f64,
}

/// One sample of a control line, located on the traced mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineSample {
    pub triangle: u32,
    pub bary: [f64; 3],
    pub point: V3,
    /// The anchor's rotation vector direction there: the local fold direction, signed so that the strip
    /// between the control lines rises on the fold's ridge side.
    pub axis: V3,
    /// Anchor rotation angle, radians (> 0).
    pub angle: f64,
}

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
    /// Control-line samples that carry anchors, in order, dense enough for the mesh they are realised on.
    pub samples: Vec<LineSample>,
}

/// What tracing one seed gives: its fold and the triangles of the fold's region of influence, or nothing (no
/// patch, or an axis too short).
pub(super) type Outcome = Option<(TracedFold, Vec<u32>)>;

/// The work on one seed — patch, axis, control lines, region — which reads the frame but nothing of the other
/// seeds, so seeds can be traced on several threads, each with its own local numbering (O(triangles)).
pub(super) struct SeedWork {
    tri_local: Vec<u32>,
    vert_local: Vec<u32>,
    /// Shared by the pool's [`SeedWork`]s (LSCM: chosen, or unfolding's fallback).
    patterns: Arc<SymbolicCache>,
    unfolder: Unfolder,
    /// Control-line samples per axis step: 2^levels when the lines are realised on a mesh subdivided `levels`
    /// times, so that every fine triangle they cross is sampled.
    density: usize,
}

/// A flattened patch around a seed.
struct Patch {
    tris: Vec<u32>,
    /// The corners of `tris[k]` in the local vertex numbering (`verts`, `uv`), looked up once per patch: the
    /// passes over the patch (overlap check, axis, control lines, region) read a triangle's layout through
    /// these rather than through three global-to-local lookups each time.
    corners: Vec<[u32; 3]>,
    verts: Vec<u32>,
    uv: Vec<[f64; 2]>,
}

/// An axis in the patch's plane: points with the triangle each lies in.
type Axis = Vec<([f64; 2], usize)>;

/// A control-line sample before its anchor is decided: (axis index · density + sub-step, triangle,
/// barycentrics, 3D point, unit 3D fold tangent).
type RawSample = (usize, usize, [f64; 3], V3, Option<V3>);

fn tri_pts(topo: &Topology, p: &[V3], t: usize) -> [V3; 3] {
    topo.triangles()[t].map(|v| p[v as usize])
}

fn norm2(a: [f64; 2]) -> f64 {
    (a[0] * a[0] + a[1] * a[1]).sqrt()
}

fn point3(f: &FrameField, t: usize, bary: [f64; 3]) -> V3 {
    let q = tri_pts(f.topo, f.p, t);
    vec3::add(
        vec3::add(vec3::scale(q[0], bary[0]), vec3::scale(q[1], bary[1])),
        vec3::scale(q[2], bary[2]),
    )
}

/// Anchor angle (radians) of a fold of width `width` (in mean edge lengths) where the integrated shrinkage is
/// `change`. With `angle_gain` > 0 (default), the linear law `gain · (|v| − 1)`. With 0, from the material:
/// the region of influence, 2·α·|v| edge lengths across, was `|v|` times longer in its least-compressed state
/// (the phase's reference, §4.3), so it lost `2α|v|(|v| − 1)`; two anchors rotating ±θ on a strip of width `w`
/// lengthen it by `w (1/cos θ − 1)`, which gives the length back when `1/cos θ = 1 + lost / w`. Capped at
/// `max_angle`.
pub fn fold_angle(change: f64, width: f64, params: &StretchParams) -> f64 {
    let max_angle = params.max_angle_deg.to_radians();
    if change.is_nan() || change <= 1.0 || width.is_nan() || width <= 0.0 {
        return 0.0;
    }
    if params.angle_gain > 0.0 {
        return (params.angle_gain * (change - 1.0)).clamp(0.0, max_angle);
    }
    let lost = 2.0 * params.alpha * change * (change - 1.0);
    (1.0 / (1.0 + lost / width)).acos().min(max_angle)
}

/// +1 when the fold's ridge is on the side of the traced axis triangles' normals, −1 when on the other side.
/// `bulge` sums, along the axis, the height of the axis point above the chord between the two control lines,
/// measured along the axis triangle's normal: the fold the capture flattened still shows there. A flat
/// surface falls back to "away from the frame's centroid".
fn ridge_sign(bulge: f64, scale: f64, outward: f64) -> f64 {
    if bulge.abs() > 1e-9 * scale {
        bulge.signum()
    } else if outward != 0.0 {
        outward.signum()
    } else {
        1.0
    }
}

impl SeedWork {
    pub(super) fn new(
        n_triangles: usize,
        n_vertices: usize,
        levels: usize,
        patterns: Arc<SymbolicCache>,
    ) -> Self {
        SeedWork {
            tri_local: vec![NONE; n_triangles],
            vert_local: vec![NONE; n_vertices],
            patterns,
            unfolder: Unfolder::default(),
            density: 1 << levels.min(8),
        }
    }

    /// What seed `s` gives on its own: its fold and the patch triangles of the fold's region of influence.
    pub(super) fn trace_seed(
        &mut self,
        f: &FrameField,
        params: &StretchParams,
        s: usize,
        centroid: V3,
    ) -> Outcome {
        let patch = self.patch(f, s, params.patch_radius * f.h)?;
        let out = self.axis(f, params, s, &patch).map(|axis| {
            let fold = self.control_lines(f, params, s, &patch, &axis, centroid);
            let reach = params.alpha * f.shrink[s] * f.h;
            (fold, self.region(f, &patch, &axis, reach))
        });
        self.release(&patch);
        out
    }

    /// Triangles whose centroid lies within `radius` of the seed's (breadth-first, so the patch is connected),
    /// flattened by unfolding, or by LSCM where the unfolding folds triangles over. Fills `tri_local` /
    /// `vert_local`; [`Self::release`] clears them. Either flattening is laid out from vertex indices, not corner
    /// order, so a flipped triangle gives the mirrored flattening.
    fn patch(&mut self, f: &FrameField, s: usize, radius: f64) -> Option<Patch> {
        let (topo, geom) = (f.topo, f.geom);
        let c0 = geom.centroids[s];
        // `norm(d) <= radius` without the square root, decided exactly as with it (see `SqrtBound`).
        let near = SqrtBound::new(radius);
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
                let d = vec3::sub(geom.centroids[u as usize], c0);
                if near.holds(vec3::dot(d, d)) {
                    self.tri_local[u as usize] = tris.len() as u32;
                    tris.push(u);
                }
            }
        }
        let mut verts = Vec::new();
        let mut corners = Vec::with_capacity(tris.len());
        for &t in &tris {
            corners.push(topo.triangles()[t as usize].map(|v| {
                if self.vert_local[v as usize] == NONE {
                    self.vert_local[v as usize] = verts.len() as u32;
                    verts.push(v);
                }
                self.vert_local[v as usize]
            }));
        }
        // LSCM: the choice, or what a patch that does not unfold cleanly falls back to.
        let lscm = |vert_local: &[u32]| {
            let local_tris = &corners;
            let pos: Vec<V3> = verts.iter().map(|&v| f.p[v as usize]).collect();
            let seed_min = *topo.triangles()[s].iter().min().expect("three");
            let pin0 = vert_local[seed_min as usize] as usize;
            let pin1 = (0..pos.len())
                .max_by(|&a, &b| {
                    let da = vec3::norm(vec3::sub(pos[a], pos[pin0]));
                    let db = vec3::norm(vec3::sub(pos[b], pos[pin0]));
                    da.total_cmp(&db).then(verts[b].cmp(&verts[a]))
                })
                .unwrap_or(pin0);
            lscm_with(&pos, local_tris, (pin0, pin1), Some(&self.patterns))
        };
        let patch_uv = self
            .unfolder
            .unfold(
                &PatchRef {
                    topo,
                    n_tris: tris.len(),
                    p: f.p,
                    tri_local: &self.tri_local,
                    vert_local: &self.vert_local,
                    verts: &verts,
                },
                s,
            )
            .filter(|uv| unfolds_without_overlap(&corners, uv))
            .or_else(|| lscm(&self.vert_local));
        let patch = Patch {
            tris,
            corners,
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

    /// The layout of patch triangle `t` (global index), corners in the triangle's order.
    fn uv_tri(&self, _topo: &Topology, patch: &Patch, t: usize) -> [[f64; 2]; 3] {
        patch.corners[self.tri_local[t] as usize].map(|k| patch.uv[k as usize])
    }

    fn uv_centroid(&self, topo: &Topology, patch: &Patch, t: usize) -> [f64; 2] {
        centroid_of(self.uv_tri(topo, patch, t))
    }

    /// The linear map of triangle `t` from its local 3D frame (e1, e2) to the plane, as a 2x2 matrix.
    fn uv_map(&self, f: &FrameField, patch: &Patch, t: usize) -> Option<[[f64; 2]; 2]> {
        let [l1, a, b] = shape(tri_pts(f.topo, f.p, t));
        if l1 <= 0.0 || b <= 0.0 {
            return None;
        }
        let q = self.uv_tri(f.topo, patch, t);
        let d1 = [q[1][0] - q[0][0], q[1][1] - q[0][1]];
        let d2 = [q[2][0] - q[0][0], q[2][1] - q[0][1]];
        // B [l1 a; 0 b] = [d1 d2]  ⇒  B = [d1/l1, (d2 − a d1/l1)/b].
        let c1 = [d1[0] / l1, d1[1] / l1];
        let c2 = [(d2[0] - a * c1[0]) / b, (d2[1] - a * c1[1]) / b];
        Some([[c1[0], c2[0]], [c1[1], c2[1]]])
    }

    /// A 3D tangent vector of triangle `t` in the plane.
    fn to_uv(&self, f: &FrameField, patch: &Patch, t: usize, d: V3) -> Option<[f64; 2]> {
        let m = self.uv_map(f, patch, t)?;
        let x = [vec3::dot(d, f.geom.e1[t]), vec3::dot(d, f.geom.e2[t])];
        Some([
            m[0][0] * x[0] + m[0][1] * x[1],
            m[1][0] * x[0] + m[1][1] * x[1],
        ])
    }

    /// A plane vector at triangle `t` back on the surface (unit 3D tangent).
    fn to_3d(&self, f: &FrameField, patch: &Patch, t: usize, d: [f64; 2]) -> Option<V3> {
        let m = self.uv_map(f, patch, t)?;
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        if det.abs() < 1e-300 {
            return None;
        }
        let x = [
            (m[1][1] * d[0] - m[0][1] * d[1]) / det,
            (-m[1][0] * d[0] + m[0][0] * d[1]) / det,
        ];
        let v = vec3::normalize(vec3::add(
            vec3::scale(f.geom.e1[t], x[0]),
            vec3::scale(f.geom.e2[t], x[1]),
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

    /// The fold axis through seed `s` in the patch's plane, marched both ways perpendicular to the shrinkage;
    /// `None` when it is shorter than `min_length`.
    fn axis(
        &self,
        f: &FrameField,
        params: &StretchParams,
        s: usize,
        patch: &Patch,
    ) -> Option<Axis> {
        let axis_of = |t: usize| -> Option<[f64; 2]> {
            let a3 = vec3::cross(f.geom.normals[t], f.dir[t]);
            let a = self.to_uv(f, patch, t, a3)?;
            let n = norm2(a);
            (n > 0.0).then(|| [a[0] / n, a[1] / n])
        };
        let start = self.uv_centroid(f.topo, patch, s);
        let h0 = axis_of(s)?;
        let fade = 1.0 + params.fade * (f.shrink[s] - 1.0);
        let cos_turn = params.max_turn_deg.to_radians().cos();
        let step = 0.4 * f.h;
        let max_steps = (2.0 * params.patch_radius * f.h / step) as usize + 1;
        // March in both senses; each point remembers its triangle.
        let mut halves: [Axis; 2] = [Vec::new(), Vec::new()];
        for (half, sense) in halves.iter_mut().zip([1.0, -1.0]) {
            let mut heading = [h0[0] * sense, h0[1] * sense];
            let (mut q, mut t) = (start, s);
            for _ in 0..max_steps {
                let nq = [q[0] + step * heading[0], q[1] + step * heading[1]];
                let Some((nt, _)) = self.locate(f.topo, patch, t, nq) else {
                    break;
                };
                if nt != t {
                    if f.shrink[nt] < fade {
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
        let mut axis: Axis = halves[1].iter().rev().copied().collect();
        axis.push((start, s));
        axis.extend(halves[0].iter().copied());
        let length: f64 = axis
            .windows(2)
            .map(|w| norm2([w[1].0[0] - w[0].0[0], w[1].0[1] - w[0].0[1]]))
            .sum();
        (length >= params.min_length * f.h && axis.len() >= 2).then_some(axis)
    }

    /// The control lines at ± width/2 beside `axis`, and their anchor samples (ridge side and angle decided
    /// here, see the module documentation).
    fn control_lines(
        &self,
        f: &FrameField,
        params: &StretchParams,
        s: usize,
        patch: &Patch,
        axis: &Axis,
        centroid: V3,
    ) -> TracedFold {
        let width = params.fold_width * f.h / f.shrink[s];
        let density = self.density;
        // Per side: (axis index, sample on the mesh, unit 3D tangent).
        let mut raw: [Vec<RawSample>; 2] = [Vec::new(), Vec::new()];
        let mut lines: Vec<Vec<V3>> = Vec::new();
        for (k, side) in [-1.0f64, 1.0].into_iter().enumerate() {
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
                let (q0, ta) = axis[i];
                let sub = if i + 1 < axis.len() { density } else { 1 };
                for j in 0..sub {
                    let q = if j == 0 {
                        q0
                    } else {
                        let q1 = axis[i + 1].0;
                        let w = j as f64 / sub as f64;
                        [q0[0] + w * (q1[0] - q0[0]), q0[1] + w * (q1[1] - q0[1])]
                    };
                    let off = [
                        q[0] + side * 0.5 * width * nrm[0],
                        q[1] + side * 0.5 * width * nrm[1],
                    ];
                    let Some((t, bary)) = self.locate(f.topo, patch, ta, off) else {
                        if j == 0 {
                            if line.len() >= 2 {
                                lines.push(std::mem::take(&mut line));
                            } else {
                                line.clear();
                            }
                        }
                        continue;
                    };
                    let pt = point3(f, t, bary);
                    if j == 0 {
                        line.push(pt);
                    }
                    let tan3 = self.to_3d(f, patch, t, tg);
                    raw[k].push((i * density + j, t, bary, pt, tan3));
                }
            }
            if line.len() >= 2 {
                lines.push(line);
            }
        }
        let axis3: Vec<Option<(V3, usize)>> = axis
            .iter()
            .map(|&(q, t)| {
                self.locate(f.topo, patch, t, q)
                    .map(|(t, b)| (point3(f, t, b), t))
            })
            .collect();
        // Ridge side: the axis' height above the chord between the lines, along the axis triangle's normal,
        // summed where both lines have a sample beside the same axis point.
        let mut bulge = 0.0;
        for l in raw[0].iter().filter(|l| l.0 % density == 0) {
            let Ok(r) = raw[1].binary_search_by_key(&l.0, |r| r.0) else {
                continue;
            };
            if let Some((a3, at)) = axis3[l.0 / density] {
                let mid = vec3::scale(vec3::add(l.3, raw[1][r].3), 0.5);
                bulge += vec3::dot(vec3::sub(a3, mid), f.geom.normals[at]);
            }
        }
        let outward = vec3::dot(vec3::sub(f.geom.centroids[s], centroid), f.geom.normals[s]);
        let sigma = ridge_sign(bulge, f.h, outward);
        let mut samples = Vec::new();
        for side in &raw {
            for &(idx, t, bary, point, tan3) in side {
                let Some(tan3) = tan3 else { continue };
                let (i, j) = (idx / density, idx % density);
                // The axis point beside this sample, and the sample's offset from it.
                let Some((a0, _)) = axis3[i] else { continue };
                let beside = match (j, axis3.get(i + 1).copied().flatten()) {
                    (0, _) => a0,
                    (_, Some((a1, _))) => {
                        let w = j as f64 / density as f64;
                        vec3::add(vec3::scale(a0, 1.0 - w), vec3::scale(a1, w))
                    }
                    _ => continue,
                };
                let offset = vec3::sub(point, beside);
                let ta = axis[i].1;
                let angle = fold_angle(f.shrink[ta], width / f.h, params);
                // A ridge towards `up` tilts the normal at each control line away from the axis: rotating `up`
                // about `k` by θ > 0 moves it towards `k × up`, which must point along the offset, so
                // `k ∥ up × offset`. Built from the geometry only — neither the tracing order nor the winding.
                let up = vec3::scale(f.geom.normals[t], sigma);
                let sense = vec3::dot(tan3, vec3::cross(up, offset));
                if angle <= 0.0 || sense == 0.0 || !sense.is_finite() {
                    continue;
                }
                samples.push(LineSample {
                    triangle: t as u32,
                    bary,
                    point,
                    axis: vec3::scale(tan3, sense.signum()),
                    angle,
                });
            }
        }
        let start = axis.iter().position(|a| a.1 == s).unwrap_or(0);
        let direction = self
            .to_3d(f, patch, s, {
                let (a, b) = (
                    axis[start.saturating_sub(1)].0,
                    axis[(start + 1).min(axis.len() - 1)].0,
                );
                [b[0] - a[0], b[1] - a[1]]
            })
            .unwrap_or([0.0; 3]);
        TracedFold {
            seed: s as u32,
            change: f.shrink[s],
            width,
            axis: axis3.into_iter().flatten().map(|a| a.0).collect(),
            direction,
            lines,
            samples,
        }
    }

    /// Region of influence (eq. 4.3): the patch triangles within `reach` of the axis, in the plane. Most of a
    /// patch lies beyond reach of the axis' bounding box, which rules a triangle out without looking at the
    /// axis' segments one by one; within the box, a segment whose own box (widened by the same margin) does not
    /// hold the centroid is ruled out the same way, and the distance to the others is compared squared
    /// ([`SqrtBound`]): the same verdicts as [`within_polyline`], which was most of a seed's own time.
    fn region(&self, f: &FrameField, patch: &Patch, axis: &Axis, reach: f64) -> Vec<u32> {
        let axis_uv: Vec<[f64; 2]> = axis.iter().map(|a| a.0).collect();
        // Beyond this margin outside a box no point of the segments in it is within reach, rounding included.
        let margin = reach * (1.0 + 1e-9) + 1e-12 * f.h;
        let (lo, hi) = bounds(&axis_uv);
        let segments = Segments::new(&axis_uv, margin);
        let bound = SqrtBound::new(reach);
        let mut region = Vec::new();
        for (&t, corners) in patch.tris.iter().zip(&patch.corners) {
            let c = centroid_of(corners.map(|k| patch.uv[k as usize]));
            let outside = c[0] < lo[0] - margin
                || c[0] > hi[0] + margin
                || c[1] < lo[1] - margin
                || c[1] > hi[1] + margin;
            if outside {
                continue;
            }
            let within = match (&segments, bound.limit) {
                (Some(segments), Some(_)) => segments.within(c, &bound),
                _ => within_polyline(c, &axis_uv, reach),
            };
            if within {
                region.push(t);
            }
        }
        region
    }
}

/// The centroid of a triangle in the plane.
#[inline]
fn centroid_of(q: [[f64; 2]; 3]) -> [f64; 2] {
    [
        (q[0][0] + q[1][0] + q[2][0]) / 3.0,
        (q[0][1] + q[1][1] + q[2][1]) / 3.0,
    ]
}

/// The bounding box of plane points.
fn bounds(points: &[[f64; 2]]) -> ([f64; 2], [f64; 2]) {
    points.iter().fold(
        ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
        |(lo, hi), q| {
            (
                [lo[0].min(q[0]), lo[1].min(q[1])],
                [hi[0].max(q[0]), hi[1].max(q[1])],
            )
        },
    )
}

/// `x.sqrt() <= r` decided as `x <= limit`, without the square root: IEEE square roots are correctly rounded,
/// hence monotone, so the `x ≥ 0` with `x.sqrt() <= r` are exactly those up to the largest such `x`, found once
/// per bound by stepping from `r * r` one representable number at a time (a step or two). NaN and +∞ fail both
/// tests alike. `limit` is `None` (use the square root) unless `r` is positive, finite and `r * r` is too.
struct SqrtBound {
    limit: Option<f64>,
    r: f64,
}

impl SqrtBound {
    fn new(r: f64) -> Self {
        let limit = (r > 0.0 && (r * r).is_finite()).then(|| {
            let mut x = r * r;
            while x > 0.0 && x.sqrt() > r {
                x = x.next_down();
            }
            while x.next_up().is_finite() && x.next_up().sqrt() <= r {
                x = x.next_up();
            }
            x
        });
        SqrtBound { limit, r }
    }

    /// Whether `x.sqrt() <= r`, for `x` a sum of squares (never below zero).
    #[inline]
    fn holds(&self, x: f64) -> bool {
        match self.limit {
            Some(limit) => x <= limit,
            None => x.sqrt() <= self.r,
        }
    }
}

/// An axis polyline's segments as [`dist_to_segment`] uses them (start, direction, squared length), each with
/// its bounding box widened by a margin beyond which nothing is within reach, and runs of [`SEGMENT_RUN`]
/// consecutive segments with the union of their boxes: a point outside a run's box is outside each of its
/// segments' boxes, so a run rules out its segments with four comparisons (a patch triangle near the axis
/// used to test every segment's box, a fifth of a seed's own time). `None` for a single point.
struct Segments {
    segments: Vec<Segment>,
    /// Per run of consecutive segments: the union of their widened boxes.
    runs: Vec<([f64; 2], [f64; 2])>,
}

/// Consecutive segments per run in [`Segments`].
const SEGMENT_RUN: usize = 8;

struct Segment {
    a: [f64; 2],
    ab: [f64; 2],
    l2: f64,
    lo: [f64; 2],
    hi: [f64; 2],
}

impl Segments {
    fn new(line: &[[f64; 2]], margin: f64) -> Option<Self> {
        (line.len() >= 2).then(|| {
            let segments: Vec<Segment> = line
                .windows(2)
                .map(|w| {
                    let (a, b) = (w[0], w[1]);
                    let ab = [b[0] - a[0], b[1] - a[1]];
                    Segment {
                        a,
                        ab,
                        l2: ab[0] * ab[0] + ab[1] * ab[1],
                        lo: [a[0].min(b[0]) - margin, a[1].min(b[1]) - margin],
                        hi: [a[0].max(b[0]) + margin, a[1].max(b[1]) + margin],
                    }
                })
                .collect();
            let runs = segments
                .chunks(SEGMENT_RUN)
                .map(|run| {
                    run.iter().fold(
                        ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
                        |(lo, hi), s| {
                            (
                                [lo[0].min(s.lo[0]), lo[1].min(s.lo[1])],
                                [hi[0].max(s.hi[0]), hi[1].max(s.hi[1])],
                            )
                        },
                    )
                })
                .collect();
            Segments { segments, runs }
        })
    }

    /// `within_polyline(q, line, bound.r)`: the same arithmetic as [`dist_to_segment`] up to its square root.
    #[inline]
    fn within(&self, q: [f64; 2], bound: &SqrtBound) -> bool {
        let inside = |lo: [f64; 2], hi: [f64; 2]| {
            q[0] >= lo[0] && q[0] <= hi[0] && q[1] >= lo[1] && q[1] <= hi[1]
        };
        let near = self.segments.chunks(SEGMENT_RUN).zip(&self.runs);
        near.filter(|(_, &(lo, hi))| inside(lo, hi))
            .flat_map(|(run, _)| run)
            .any(|s| {
                if !inside(s.lo, s.hi) {
                    return false;
                }
                let t = if s.l2 > 0.0 {
                    (((q[0] - s.a[0]) * s.ab[0] + (q[1] - s.a[1]) * s.ab[1]) / s.l2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let d = [q[0] - s.a[0] - t * s.ab[0], q[1] - s.a[1] - t * s.ab[1]];
                bound.holds(d[0] * d[0] + d[1] * d[1])
            })
    }
}

/// Whether every triangle of the unfolded patch (its `corners`, local vertex indices) keeps its winding in the
/// layout `uv`. Unfolding lays a consistently oriented patch out counter-clockwise, exactly where it is
/// developable; where the patch is too curved for that, the paths around a bump meet with a gap and the
/// triangles closing it fold over. Such a patch is flattened by LSCM instead: on the sleeve sample a fifth of
/// the patches fold over, and there the overlapping triangles' centroids land beside the axis and inflate the
/// region of influence (8 % more triangles than LSCM's, axes 3.6 % shorter), while on the patches that
/// unfold cleanly the two flattenings trace regions, axes and anchors within 0.3 %
/// (bench/results/2026-12-02-stretch-tracing.md). The flipped mesh gives the mirrored layout, so the verdict does not depend on the winding.
fn unfolds_without_overlap(corners: &[[u32; 3]], uv: &[[f64; 2]]) -> bool {
    corners.iter().all(|k| {
        let [a, b, c] = k.map(|k| uv[k as usize]);
        (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]) > 0.0
    })
}

/// Whether `q` lies within `reach` of the polyline `line` in the plane: `dist_to_polyline(q, line) <= reach`,
/// stopping at the first segment close enough.
fn within_polyline(q: [f64; 2], line: &[[f64; 2]], reach: f64) -> bool {
    if line.len() == 1 {
        return norm2([q[0] - line[0][0], q[1] - line[0][1]]) <= reach;
    }
    line.windows(2)
        .any(|w| dist_to_segment(q, w[0], w[1]) <= reach)
}

fn dist_to_segment(q: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1]];
    let l2 = ab[0] * ab[0] + ab[1] * ab[1];
    let t = if l2 > 0.0 {
        (((q[0] - a[0]) * ab[0] + (q[1] - a[1]) * ab[1]) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    norm2([q[0] - a[0] - t * ab[0], q[1] - a[1] - t * ab[1]])
}

/// Distance from `q` to the polyline `line` in the plane.
#[cfg(test)]
fn dist_to_polyline(q: [f64; 2], line: &[[f64; 2]]) -> f64 {
    if line.len() == 1 {
        return norm2([q[0] - line[0][0], q[1] - line[0][1]]);
    }
    line.windows(2)
        .map(|w| dist_to_segment(q, w[0], w[1]))
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The material angle gives back exactly the length the region of influence lost, until the cap.
    #[test]
    fn fold_angle_recovers_the_lost_length() {
        let p = StretchParams {
            angle_gain: 0.0,
            ..Default::default()
        };
        for change in [1.02, 1.05, 1.1] {
            let w = p.fold_width / change;
            let theta = fold_angle(change, w, &p);
            let gained = w * (1.0 / theta.cos() - 1.0);
            let lost = 2.0 * p.alpha * change * (change - 1.0);
            assert!(
                (gained - lost).abs() < 1e-12,
                "{change}: {gained} vs {lost}"
            );
            assert!(theta > 0.0 && theta < p.max_angle_deg.to_radians());
        }
        // Strong shrinkage is capped; none gives no anchor.
        assert_eq!(fold_angle(1.8, 1.0, &p), p.max_angle_deg.to_radians());
        assert_eq!(fold_angle(1.0, 1.0, &p), 0.0);
        // The linear law when asked for.
        let lin = StretchParams {
            angle_gain: 4.0,
            ..p
        };
        assert!((fold_angle(1.05, 1.0, &lin) - 0.2).abs() < 1e-12);
    }

    /// The region test (bounding box, then the first segment within reach) agrees with the distance to the
    /// whole polyline, for points on both sides of the reach.
    #[test]
    fn within_polyline_is_the_polyline_distance_test() {
        let line: Vec<[f64; 2]> = (0..20)
            .map(|i| {
                let x = i as f64 * 0.4;
                [x, (x * 0.7).sin()]
            })
            .collect();
        let mut near = 0;
        for i in 0..400 {
            let q = [(i % 20) as f64 * 0.45 - 0.5, (i / 20) as f64 * 0.2 - 2.0];
            for reach in [0.0, 0.3, 1.0] {
                let inside = dist_to_polyline(q, &line) <= reach;
                assert_eq!(within_polyline(q, &line, reach), inside, "{q:?} {reach}");
                near += inside as usize;
            }
        }
        assert!(near > 50 && near < 800, "{near}");
        assert!(within_polyline([0.0, 0.1], &line[..1], 0.2));
        assert!(!within_polyline([0.0, 0.3], &line[..1], 0.2));
    }

    /// A small deterministic generator in [0, 1) for the tests below.
    fn uniform(state: &mut u64) -> f64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        (*state >> 11) as f64 / (1u64 << 53) as f64
    }

    /// The square-root-free bound gives the square root's verdict for every x, at the boundary (where `r * r`
    /// alone would be wrong) and for the values no bound is made for.
    #[test]
    fn sqrt_bound_is_the_square_root_test() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut moved = 0;
        for _ in 0..5000 {
            let r = 10f64.powf(12.0 * uniform(&mut state) - 6.0);
            let b = SqrtBound::new(r);
            let limit = b.limit.expect("a positive finite bound");
            assert!(limit.sqrt() <= r && limit.next_up().sqrt() > r, "{r}");
            moved += (limit != r * r) as usize;
            let x = 4.0 * r * r * uniform(&mut state);
            for x in [
                limit,
                limit.next_up(),
                limit.next_down(),
                r * r,
                (r * r).next_up(),
                (r * r).next_down(),
                x,
                0.0,
                f64::INFINITY,
                f64::NAN,
            ] {
                assert_eq!(b.holds(x), x.sqrt() <= r, "{x} against {r}");
            }
        }
        // `x <= r * r` would have decided these boundaries wrongly.
        assert!(moved > 100, "{moved}");
        for r in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e200] {
            let b = SqrtBound::new(r);
            assert!(b.limit.is_none());
            for x in [0.0, 1.0, 1e300, f64::NAN] {
                assert_eq!(b.holds(x), x.sqrt() <= r);
            }
        }
    }

    /// The region's segment test (boxes, then squared distances) gives `within_polyline`'s verdicts, for
    /// points scattered round a wiggly axis and for points at exactly the reach from its vertices and segments.
    #[test]
    fn segments_decide_like_the_polyline_distance() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let line: Vec<[f64; 2]> = (0..30)
            .map(|i| {
                let x = i as f64 * 0.4;
                [x + 0.05 * (x * 3.1).cos(), (x * 0.7).sin()]
            })
            .collect();
        let (mut inside, mut checked) = (0, 0);
        for reach in [0.05, 0.37, 1.0, 2.2] {
            let margin = reach * (1.0 + 1e-9) + 1e-12 * 0.4;
            let segs = Segments::new(&line, margin).unwrap();
            let bound = SqrtBound::new(reach);
            let mut points: Vec<[f64; 2]> = (0..3000)
                .map(|_| {
                    [
                        14.0 * uniform(&mut state) - 1.0,
                        6.0 * uniform(&mut state) - 3.0,
                    ]
                })
                .collect();
            // At the reach from vertices (every direction) and from segment midpoints (along the normal).
            for (k, w) in line.windows(2).enumerate() {
                let a = (k as f64) * 0.7;
                points.push([w[0][0] + reach * a.cos(), w[0][1] + reach * a.sin()]);
                let (d, m) = (
                    [w[1][0] - w[0][0], w[1][1] - w[0][1]],
                    [0.5 * (w[0][0] + w[1][0]), 0.5 * (w[0][1] + w[1][1])],
                );
                let n = norm2(d);
                points.push([m[0] - reach * d[1] / n, m[1] + reach * d[0] / n]);
            }
            for q in points {
                let want = within_polyline(q, &line, reach);
                assert_eq!(segs.within(q, &bound), want, "{q:?} {reach}");
                inside += want as usize;
                checked += 1;
            }
        }
        assert!(
            inside > 1000 && inside < checked - 1000,
            "{inside} of {checked}"
        );
        assert!(Segments::new(&line[..1], 0.1).is_none());
    }

    #[test]
    fn ridge_side_follows_the_bulge_then_the_outside() {
        assert_eq!(ridge_sign(0.3, 1.0, -1.0), 1.0);
        assert_eq!(ridge_sign(-0.3, 1.0, 1.0), -1.0);
        assert_eq!(ridge_sign(0.0, 1.0, -2.0), -1.0);
        assert_eq!(ridge_sign(0.0, 1.0, 0.0), 1.0);
    }
}
