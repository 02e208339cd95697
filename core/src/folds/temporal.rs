//! Temporal coherence of detected anchors: folds that persist keep their anchors, their angles change smoothly,
//! and a fold seen in a single frame neither appears nor vanishes for that frame alone.
//!
//! Detectors find anchors frame by frame (video edges) or carry only a seed memory (geometry), so the same fold
//! gets anchors on slightly different triangles, with a different angle, or goes missing for a frame; the
//! deformation turns each of those changes into a visible pop. Here anchors are matched from frame to frame —
//! an anchor at triangle `i` in frame `t` matches the anchor of frame `t + k` on `i` or a triangle sharing a
//! vertex with it whose rotation turns the same way, the closest one in rotation — and each anchor's rotation
//! becomes a Gaussian-weighted mean over `±radius` frames of its matches, a missing match counting as no
//! rotation. So a fold fades in and out over a few frames instead of switching. Anchors with no match in
//! either neighbouring frame are dropped (single-frame births and deaths), and a triangle whose fold is matched
//! in the frames before and after but missed in between gets an anchor there.
//!
//! Rotations are compared in each triangle's own frame (first edge, normal), carried along with the cloth, so
//! a fold that moves rigidly with the garment matches itself. Only a window of `2·radius + 1` frames of
//! triangle frames is held at a time.

use super::{Anchor, FrameAnchors};
use crate::error::{Error, Result};
use crate::mesh::{FrameSource, Topology, NONE};
use crate::vec3::{self, V3};
use rayon::prelude::*;
use std::collections::VecDeque;
use std::ops::Range;

/// Orthonormal frame (e1, e2, n) of every triangle of one frame.
type Frames = Vec<[V3; 3]>;

/// Frames anchored to the edge between the triangle's two lowest vertex indices, so that the transport from
/// frame to frame does not depend on the corner order (winding) of the triangle list.
fn triangle_frames(topo: &Topology, p: &[V3]) -> Frames {
    topo.triangles()
        .par_iter()
        .with_min_len(4096)
        .map(|t| {
            let q = t.map(|v| p[v as usize]);
            let n = vec3::normalize(vec3::cross(vec3::sub(q[1], q[0]), vec3::sub(q[2], q[0])));
            let mut s = *t;
            s.sort_unstable();
            let e1 = vec3::normalize(vec3::sub(p[s[1] as usize], p[s[0] as usize]));
            [e1, vec3::cross(n, e1), n]
        })
        .collect()
}

fn to_local(f: &[V3; 3], v: V3) -> V3 {
    [vec3::dot(v, f[0]), vec3::dot(v, f[1]), vec3::dot(v, f[2])]
}

fn to_world(f: &[V3; 3], c: V3) -> V3 {
    vec3::add(
        vec3::add(vec3::scale(f[0], c[0]), vec3::scale(f[1], c[1])),
        vec3::scale(f[2], c[2]),
    )
}

/// Gaussian weight of a frame `k` frames away, σ = radius / 2 (at least 0.5).
fn weight(k: usize, radius: usize) -> f64 {
    let sigma = (radius as f64 / 2.0).max(0.5);
    (-(k as f64).powi(2) / (2.0 * sigma * sigma)).exp()
}

/// Triangles sharing a vertex with `t` (including `t`).
fn ring(topo: &Topology, t: usize) -> Vec<u32> {
    let mut out: Vec<u32> = topo.triangles()[t]
        .iter()
        .flat_map(|&v| topo.vertex_triangles(v as usize).iter().copied())
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// Makes `frames` (one entry per frame of `source`, in order) temporally coherent; `radius` = 0 returns them
/// unchanged. Control lines are kept as detected.
pub fn settle(
    source: &dyn FrameSource,
    frames: Vec<FrameAnchors>,
    radius: usize,
) -> Result<Vec<FrameAnchors>> {
    let n = frames.len();
    if radius == 0 || n < 2 {
        return Ok(frames);
    }
    settle_range(source, &frames, 0, n, 0..n, radius)
}

/// The input frames [`settle_range`] needs to settle `range` of an `n`-frame sequence: `range` widened by
/// `radius` on each side, clipped to the sequence.
pub fn settle_input(range: Range<usize>, n: usize, radius: usize) -> Range<usize> {
    range.start.saturating_sub(radius)..(range.end + radius).min(n)
}

/// [`settle`] for the frames `range` of an `n`-frame sequence only, so that the settle can be split into
/// tasks. `frames[k]` holds the detected anchors of frame `offset + k` and must cover at least
/// [`settle_input`]`(range, n, radius)`; `source` is the whole sequence (frames are read by absolute index).
///
/// Exactly as good as the whole-sequence settle: frame `t`'s result reads only the anchors and meshes of frames
/// `t − radius ..= t + radius` (the previous frame's anchors and the next frame's matches lie in that window
/// whenever `radius ≥ 1`), never another settled frame, and its sums run over absolute frame indices in
/// increasing order. So the settled frames of `range` are bit-identical to those `settle` gives for them, for
/// any split of the sequence into ranges.
pub fn settle_range(
    source: &dyn FrameSource,
    frames: &[FrameAnchors],
    offset: usize,
    n: usize,
    range: Range<usize>,
    radius: usize,
) -> Result<Vec<FrameAnchors>> {
    let need = settle_input(range.clone(), n, radius);
    if range.start > range.end
        || range.end > n
        || need.start < offset
        || need.end > offset + frames.len()
    {
        return Err(Error::Anchors {
            path: None,
            msg: format!(
            "temporal settle of frames {}..{} of {n}: needs the anchors of frames {}..{}, got {}..{}",
            range.start,
            range.end,
            need.start,
            need.end,
            offset,
            offset + frames.len()
            ),
        });
    }
    if radius == 0 || n < 2 {
        return Ok(frames[range.start - offset..range.end - offset].to_vec());
    }
    let topo = source.topology().clone();
    let nt = topo.n_triangles();
    let anchors_of = |u: usize| &frames[u - offset];
    // Frames t − radius ..= t + radius, their triangle frames and anchors by triangle; `window[k]` and
    // `lookup[k]` are frame `first + k`.
    let mut window: VecDeque<Frames> = VecDeque::new();
    let mut lookup: VecDeque<ByTriangle> = VecDeque::new();
    let mut first = need.start;
    let mut out = Vec::with_capacity(range.len());
    for t in range {
        let fa = anchors_of(t);
        let lo = t.saturating_sub(radius);
        let hi = (t + radius).min(n - 1);
        while first < lo {
            window.pop_front();
            lookup.pop_front();
            first += 1;
        }
        while first + window.len() <= hi {
            let u = first + window.len();
            let p = source.read_frame(u)?;
            window.push_back(triangle_frames(&topo, &p));
            lookup.push_back(ByTriangle::new(anchors_of(u), nt)?);
        }
        let (window, lookup) = (&window, &lookup);
        let fr = |u: usize| &window[u - first];
        // The best match in frame `u` of a rotation `c` (local coordinates of triangle `i`, whose vertex ring
        // is `cand`), in the local coordinates of `i` at `u`.
        let find = |cand: &[u32], i: u32, c: V3, u: usize| -> Option<V3> {
            let at = &lookup[u - first];
            cand.iter()
                .filter_map(|&j| at.get(j))
                .map(|&phi| to_local(&fr(u)[i as usize], phi))
                .filter(|m| vec3::dot(*m, c) > 0.0)
                .min_by(|a, b| {
                    vec3::norm(vec3::sub(*a, c)).total_cmp(&vec3::norm(vec3::sub(*b, c)))
                })
        };
        // Gaussian mean over the window of the matches of `c` (its value at `t`), missing ones counting as 0.
        let smooth = |cand: &[u32], i: u32, c: V3| {
            let (mut sum, mut wsum) = ([0.0; 3], 0.0);
            for u in lo..=hi {
                let w = weight(u.abs_diff(t), radius);
                wsum += w;
                let m = if u == t { Some(c) } else { find(cand, i, c, u) };
                if let Some(m) = m {
                    sum = vec3::add(sum, vec3::scale(m, w));
                }
            }
            vec3::scale(sum, 1.0 / wsum)
        };
        // Each anchor's settled rotation depends on read-only data only, so anchors are settled in parallel and
        // kept in their order: the same values, pushed in the same order, as one after the other.
        let kept: Vec<Option<(u32, V3)>> = fa
            .anchors
            .par_iter()
            .with_min_len(PAR_MIN_ANCHORS)
            .map(|a| {
                let i = a.triangle;
                let cand = ring(&topo, i as usize);
                let c = to_local(&fr(t)[i as usize], a.rotation_vector());
                let before = t > 0 && find(&cand, i, c, t - 1).is_some();
                let after = t + 1 < n && find(&cand, i, c, t + 1).is_some();
                if !before && !after {
                    return None;
                }
                let s = smooth(&cand, i, c);
                Some((i, to_world(&fr(t)[i as usize], s)))
            })
            .collect();
        let mut anchors: Vec<Anchor> = Vec::with_capacity(fa.anchors.len());
        for (i, phi) in kept.into_iter().flatten() {
            push(&mut anchors, i, phi);
        }
        // Single-frame gaps: a fold matched in the frames before and after, missing here.
        if t > 0 && t + 1 < n {
            let filled: Vec<Option<(u32, V3)>> = anchors_of(t - 1)
                .anchors
                .par_iter()
                .with_min_len(PAR_MIN_ANCHORS)
                .map(|a| {
                    let i = a.triangle;
                    let cand = ring(&topo, i as usize);
                    let c = to_local(&fr(t - 1)[i as usize], a.rotation_vector());
                    if find(&cand, i, c, t).is_some() {
                        return None;
                    }
                    let next = find(&cand, i, c, t + 1)?;
                    let mid = vec3::scale(vec3::add(c, next), 0.5);
                    let s = smooth(&cand, i, mid);
                    Some((i, to_world(&fr(t)[i as usize], s)))
                })
                .collect();
            for (i, phi) in filled.into_iter().flatten() {
                push(&mut anchors, i, phi);
            }
        }
        anchors.sort_by_key(|a| a.triangle);
        anchors.dedup_by_key(|a| a.triangle);
        out.push(FrameAnchors {
            frame: fa.frame,
            anchors,
            control_lines: fa.control_lines.clone(),
            detection: fa.detection,
        });
    }
    Ok(out)
}

/// Anchors settled per parallel work item: below this a frame's anchors are not worth splitting.
const PAR_MIN_ANCHORS: usize = 256;

/// One frame's anchor rotations by triangle, for the settle's lookups: `slot[i]` indexes `rot` (`u32::MAX`:
/// no anchor on `i`). Dense rather than hashed: the settle probes every triangle of a vertex ring about ten
/// times per anchor, and hashing those probes was most of its time. A triangle listed twice keeps its last
/// rotation, as collecting into a map did. Only the frames of the settle window are held.
struct ByTriangle {
    slot: Vec<u32>,
    rot: Vec<V3>,
}

impl ByTriangle {
    fn new(f: &FrameAnchors, nt: usize) -> Result<Self> {
        let mut slot = vec![u32::MAX; nt];
        let mut rot = Vec::with_capacity(f.anchors.len());
        for a in &f.anchors {
            let s = slot
                .get_mut(a.triangle as usize)
                .ok_or_else(|| Error::Anchors {
                    path: None,
                    msg: format!(
                        "temporal settle: frame {} has an anchor on triangle {}, the mesh has {nt}",
                        f.frame, a.triangle
                    ),
                })?;
            if *s == u32::MAX {
                *s = rot.len() as u32;
                rot.push(a.rotation_vector());
            } else {
                rot[*s as usize] = a.rotation_vector();
            }
        }
        Ok(ByTriangle { slot, rot })
    }

    #[inline]
    fn get(&self, j: u32) -> Option<&V3> {
        match self.slot[j as usize] {
            u32::MAX => None,
            s => Some(&self.rot[s as usize]),
        }
    }
}

fn push(anchors: &mut Vec<Anchor>, triangle: u32, phi: V3) {
    let angle = vec3::norm(phi);
    if angle > 1e-9 && angle.is_finite() && triangle != NONE {
        anchors.push(Anchor {
            triangle,
            axis: vec3::scale(phi, 1.0 / angle),
            angle: angle.min(std::f64::consts::PI),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{demo, DemoSpec};

    /// A small demo sleeve whose fold anchors persist, drift, appear and vanish, with single-frame gaps and
    /// single-frame births added, so that every branch of the settle (drop, keep, gap fill) is exercised.
    fn case() -> (crate::mesh::Sequence, Vec<FrameAnchors>) {
        let spec = DemoSpec {
            triangles: 3_000,
            frames: 14,
            ..Default::default()
        };
        let (seq, set) = demo(&spec).unwrap();
        let frames = (0..set.n_frames())
            .map(|t| {
                let mut anchors: Vec<Anchor> = set
                    .frame(t)
                    .iter()
                    .filter(|a| !(a.triangle as usize + t).is_multiple_of(5))
                    .copied()
                    .collect();
                // A lone anchor seen in this frame only.
                anchors.push(Anchor {
                    triangle: (t * 211 + 17) as u32,
                    axis: [1.0, 0.0, 0.0],
                    angle: 0.4,
                });
                anchors.sort_by_key(|a| a.triangle);
                anchors.dedup_by_key(|a| a.triangle);
                FrameAnchors {
                    frame: t,
                    anchors,
                    ..Default::default()
                }
            })
            .collect();
        (seq, frames)
    }

    fn bytes(frames: &[FrameAnchors]) -> String {
        serde_json::to_string(frames).unwrap()
    }

    #[test]
    fn settle_range_is_bit_identical_to_settle_for_any_chunking() {
        let (seq, frames) = case();
        let n = frames.len();
        for radius in [0usize, 1, 3] {
            let whole = settle(&seq, frames.clone(), radius).unwrap();
            if radius > 0 {
                // The settle does something here, so the comparison below is not vacuous.
                assert_ne!(bytes(&whole), bytes(&frames), "radius {radius}");
            }
            for chunk in [1, 2, radius.saturating_sub(1).max(1), 7] {
                let mut split = Vec::new();
                for a in (0..n).step_by(chunk) {
                    let range = a..(a + chunk).min(n);
                    // Give each range only the input frames it needs, as a task would get them.
                    let need = settle_input(range.clone(), n, radius);
                    let part = &frames[need.clone()];
                    split.extend(settle_range(&seq, part, need.start, n, range, radius).unwrap());
                }
                assert_eq!(
                    bytes(&split),
                    bytes(&whole),
                    "radius {radius}, chunk {chunk}"
                );
            }
        }
    }

    #[test]
    fn an_anchor_off_the_mesh_is_an_error_naming_its_frame() {
        let (seq, mut frames) = case();
        let nt = seq.topology.n_triangles();
        frames[5].anchors.push(Anchor {
            triangle: nt as u32 + 3,
            axis: [0.0, 0.0, 1.0],
            angle: 0.2,
        });
        let msg = settle(&seq, frames, 2).unwrap_err().to_string();
        assert!(msg.contains("frame 5"), "{msg}");
        assert!(msg.contains(&format!("triangle {}", nt + 3)), "{msg}");
    }

    #[test]
    fn settle_range_names_missing_input_frames() {
        let (seq, frames) = case();
        let n = frames.len();
        // Frames 4..6 with radius 3 need input 1..9; give it 2..9.
        let err = settle_range(&seq, &frames[2..9], 2, n, 4..6, 3).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("frames 1..9"), "{msg}");
        assert!(msg.contains("got 2..9"), "{msg}");
    }
}
