//! Stretch against the cloth's rest lengths, as far as a capture shows them.
//!
//! [`crate::metrics`] compares each output triangle with the captured triangle of the same frame. On captured
//! data that is not the cloth's rest state: the capture low-passed the cloth, and a folded region comes out
//! shorter than the cloth it shows (the public sleeve's ground truth measures p99 179% per triangle against
//! it). Folds that give that length back must "stretch" the captured triangles, so per-triangle stretch against
//! the same captured frame measures the capture's smoothing as much as any defect (docs/fidelity.md,
//! "Measuring a result").
//!
//! Cloth barely stretches but folds and unfolds freely, so a captured edge is at most as long as the cloth
//! between its ends, and it reaches that length in the frames where the region lies flat. Per edge, the
//! **least-compressed captured length over the sequence** (the longest one, Chen 2011's integration of the
//! sequence into one rest state, per edge) is therefore the best rest length the input offers, and the
//! stretch of an output edge is its **tension** against it, `max(0, L / L_ref − 1)`: compression is what folds
//! are made of and is not counted. On the public data the ground truth itself measures p99 7.8% / max 51%
//! against it (sleeve; drape 1.4% / 89%): the reference is not exact (a region folded in every frame never
//! shows its full length), which bounds what a maximum can mean (docs/fidelity.md).
//!
//! Edges rather than triangles: three edge lengths fix a triangle's shape, and the simulated cloth shears
//! freely (its own triangles change shape by tens of % while its edges stay within a few %), so a
//! per-triangle measure would charge shear, which real cloth does cheaply, as stretch.

use crate::mesh::{FrameSource, Topology, NONE};
use crate::vec3::{self, V3};
use crate::{Error, Result};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// How [`RestLengths`] are obtained, stated in reports beside the figures.
pub const REFERENCE: &str =
    "per edge, its longest captured length over the sequence (least-compressed \
                             state); tension only: max(0, L / L_ref - 1) over all edges and frames";

/// The mesh's undirected edges, each once, as (lower, higher) vertex pairs in triangle order.
pub fn edges(topo: &Topology) -> Vec<[u32; 2]> {
    let mut out = Vec::with_capacity(3 * topo.n_triangles() / 2 + 1);
    for (t, tri) in topo.triangles().iter().enumerate() {
        for k in 0..3 {
            let adj = topo.tri_adj()[t][k];
            // Interior edges are seen from both sides: take them from the lower-index triangle only.
            if adj == NONE || (adj as usize) > t {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                out.push([a.min(b), a.max(b)]);
            }
        }
    }
    out
}

fn length(p: &[V3], e: [u32; 2]) -> f64 {
    vec3::norm(vec3::sub(p[e[0] as usize], p[e[1] as usize]))
}

/// Per edge, the longest length seen over the frames added so far.
#[derive(Debug, Clone, PartialEq)]
pub struct RestLengths {
    edges: Vec<[u32; 2]>,
    rest: Vec<f64>,
}

impl RestLengths {
    /// No frame yet: every rest length 0.
    pub fn new(topo: &Topology) -> Self {
        let edges = edges(topo);
        let rest = vec![0.0; edges.len()];
        RestLengths { edges, rest }
    }

    /// Takes each edge's length in `p` into its maximum.
    pub fn add_frame(&mut self, p: &[V3]) {
        for (r, &e) in self.rest.iter_mut().zip(&self.edges) {
            *r = r.max(length(p, e));
        }
    }

    /// The maximum of two partial sequences (order-free: max is exact).
    pub fn merge(&mut self, other: &RestLengths) {
        for (a, b) in self.rest.iter_mut().zip(&other.rest) {
            *a = a.max(*b);
        }
    }

    /// The rest lengths of a whole captured sequence, its frames read in parallel chunks (memory: a few frames).
    pub fn of_sequence(source: &dyn FrameSource) -> Result<Self> {
        Ok(Self::read(source, false)?.0)
    }

    /// Like [`Self::of_sequence`], but a frame whose contents are invalid (malformed file, non-finite or
    /// degenerate geometry: errors every reader of that frame meets alike) is left out instead of failing, and
    /// its number returned. Why: the strain limiter needs the whole sequence's lengths, yet a bad frame must fail
    /// only the task that positions it (that task reads the frame and names the problem), not every positioning
    /// task of the job — which therefore never completes on a reference missing a frame. I/O errors still fail:
    /// a flaky read on one worker must never give that worker a different reference from the others.
    pub fn of_valid_frames(source: &dyn FrameSource) -> Result<(Self, Vec<usize>)> {
        Self::read(source, true)
    }

    fn read(source: &dyn FrameSource, skip_invalid: bool) -> Result<(Self, Vec<usize>)> {
        let topo = source.topology();
        let chunk = (2 * rayon::current_num_threads()).max(1);
        let mut all = RestLengths::new(topo);
        let mut skipped = Vec::new();
        for start in (0..source.n_frames()).step_by(chunk) {
            let end = (start + chunk).min(source.n_frames());
            let parts: Vec<Option<RestLengths>> = (start..end)
                .into_par_iter()
                .map(|t| match source.read_frame(t) {
                    Ok(p) => {
                        let mut r = RestLengths::new(topo);
                        r.add_frame(&p);
                        Ok(Some(r))
                    }
                    Err(Error::Mesh { .. } | Error::Format { .. }) if skip_invalid => Ok(None),
                    Err(e) => Err(e),
                })
                .collect::<Result<_>>()?;
            for (t, p) in (start..end).zip(&parts) {
                match p {
                    Some(p) => all.merge(p),
                    None => skipped.push(t),
                }
            }
        }
        Ok((all, skipped))
    }

    pub fn edges(&self) -> &[[u32; 2]] {
        &self.edges
    }

    pub fn lengths(&self) -> &[f64] {
        &self.rest
    }

    /// Per edge, the tension max(0, L / L_ref − 1) of `p` (its first vertices are the mesh's; a subdivided
    /// output is measured on the chords between them); `None` for an edge whose rest length is 0.
    pub fn tension(&self, p: &[V3]) -> Vec<Option<f64>> {
        self.edges
            .iter()
            .zip(&self.rest)
            .map(|(&e, &r)| (r > 0.0).then(|| (length(p, e) / r - 1.0).max(0.0)))
            .collect()
    }
}

/// Figures of [`RestStretchAccumulator`], fractions (0.04 = 4%).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct RestStretchStats {
    /// 99th percentile of edge tension over all edges and frames.
    pub p99: f64,
    pub max: f64,
    /// Mean edge tension (compressed edges count as 0).
    pub mean: f64,
    /// Fraction of edge samples longer than their rest length by more than 1%.
    pub above_1pct: f64,
}

const BINS: usize = 10_000;
/// Histogram range: tension up to 200% in 2e-4 steps (larger values land in the last bin; `max` is exact).
const RANGE: f64 = 2.0;

/// Accumulates edge tension over frames (exact sequence figures: a histogram, not averages of averages).
#[derive(Debug, Clone, Default)]
pub struct RestStretchAccumulator {
    sum: f64,
    max: f64,
    count: u64,
    above_1pct: u64,
    hist: Vec<u64>,
}

impl RestStretchAccumulator {
    /// Adds the tension of frame `p` against `rest`.
    pub fn add_frame(&mut self, rest: &RestLengths, p: &[V3]) {
        if self.hist.is_empty() {
            self.hist = vec![0; BINS + 1];
        }
        for s in rest.tension(p).into_iter().flatten() {
            self.sum += s;
            self.max = self.max.max(s);
            self.count += 1;
            self.above_1pct += u64::from(s > 0.01);
            self.hist[((s / RANGE * BINS as f64) as usize).min(BINS)] += 1;
        }
    }

    pub fn merge(&mut self, other: &RestStretchAccumulator) {
        if other.hist.is_empty() {
            return;
        }
        if self.hist.is_empty() {
            self.hist = vec![0; BINS + 1];
        }
        self.sum += other.sum;
        self.max = self.max.max(other.max);
        self.count += other.count;
        self.above_1pct += other.above_1pct;
        for (a, b) in self.hist.iter_mut().zip(&other.hist) {
            *a += b;
        }
    }

    pub fn stats(&self) -> RestStretchStats {
        if self.count == 0 {
            return RestStretchStats::default();
        }
        let target = (self.count as f64 * 0.99).ceil() as u64;
        let mut cum = 0;
        let mut p99 = self.max;
        for (b, &c) in self.hist.iter().enumerate() {
            cum += c;
            if cum >= target {
                // Upper edge of the bin; 0 when the bin is the zero-tension one and most edges are slack.
                p99 = if b == 0 {
                    0.0
                } else {
                    (b as f64 + 1.0) * RANGE / BINS as f64
                };
                break;
            }
        }
        RestStretchStats {
            p99: p99.min(self.max),
            max: self.max,
            mean: self.sum / self.count as f64,
            above_1pct: self.above_1pct as f64 / self.count as f64,
        }
    }
}

/// Tension figures of a sequence `frames` (read one by one through `frame(t)`) against `rest`.
pub fn measure(
    rest: &RestLengths,
    n_frames: usize,
    mut frame: impl FnMut(usize) -> Result<Vec<V3>>,
) -> Result<RestStretchStats> {
    let mut acc = RestStretchAccumulator::default();
    for t in 0..n_frames {
        acc.add_frame(rest, &frame(t)?);
    }
    Ok(acc.stats())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::StretchAccumulator;
    use crate::synth;

    /// A sheet compressed along x (a capture's flattened fold region) in the first frames and released to its
    /// full length later: against the least-compressed state it has no tension, against the captured frame
    /// of the first frames the released sheet is stretched by the compression it no longer has.
    #[test]
    fn a_compressed_then_released_sequence_has_no_tension_against_its_rest_lengths() {
        let (topo, flat) = synth::sheet(11, 11, 0.1).unwrap();
        let squeeze = |f: f64| -> Vec<V3> { flat.iter().map(|q| [f * q[0], q[1], q[2]]).collect() };
        let captured: Vec<Vec<V3>> = [0.8, 0.85, 0.9, 1.0, 1.0].map(squeeze).into();
        let mut rest = RestLengths::new(&topo);
        for c in &captured {
            rest.add_frame(c);
        }
        // Rest lengths are the released sheet's own.
        for (&e, &r) in rest.edges().iter().zip(rest.lengths()) {
            assert!((r - length(&flat, e)).abs() < 1e-15);
        }
        // The output of every frame is the released sheet (the folds give the length back).
        let out = rest_stats(&rest, &vec![flat.clone(); captured.len()]);
        assert!(out.max < 1e-12 && out.p99 == 0.0, "{out:?}");
        // Against the same captured frame the first frame is stretched by 25% along x.
        let mut same = StretchAccumulator::default();
        for c in &captured {
            same.add_frame(&topo, c, &flat);
        }
        let same = same.stats();
        assert!((same.max - 0.25).abs() < 1e-9, "{same:?}");
        assert!(same.p99 > 0.2, "{same:?}");
        // Pulling the released sheet 10% further along x is tension on the x edges (and the diagonals).
        let pulled: Vec<V3> = flat.iter().map(|q| [1.1 * q[0], q[1], q[2]]).collect();
        let s = rest_stats(&rest, &vec![pulled; 2]);
        assert!((s.max - 0.1).abs() < 1e-9, "{s:?}");
        assert!(s.p99 > 0.09 && s.p99 <= s.max, "{s:?}");
        assert!(s.mean > 0.03 && s.mean < 0.1, "{s:?}");
        assert!(s.above_1pct > 0.5 && s.above_1pct < 1.0, "{s:?}");
    }

    fn rest_stats(rest: &RestLengths, frames: &[Vec<V3>]) -> RestStretchStats {
        measure(rest, frames.len(), |t| Ok(frames[t].clone())).unwrap()
    }

    /// Every undirected edge exactly once; compression is not tension; merging partial sequences is the
    /// maximum over the whole one.
    #[test]
    fn edges_once_compression_free_and_merge_exact() {
        let (topo, p) = synth::sheet(5, 4, 0.1).unwrap();
        let e = edges(&topo);
        let mut sorted = e.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), e.len());
        // A 5x4 grid of quads split in two: horizontal 4*4, vertical 5*3, diagonals 4*3.
        assert_eq!(e.len(), 16 + 15 + 12);
        let half: Vec<V3> = p.iter().map(|q| vec3::scale(*q, 0.5)).collect();
        let (mut a, mut b, mut whole) = (
            RestLengths::new(&topo),
            RestLengths::new(&topo),
            RestLengths::new(&topo),
        );
        a.add_frame(&half);
        b.add_frame(&p);
        whole.add_frame(&p);
        whole.add_frame(&half);
        a.merge(&b);
        assert_eq!(a, whole);
        assert!(a.tension(&half).iter().all(|s| *s == Some(0.0)));
    }

    /// A source whose frame 1 has invalid contents and frame 2 fails to read from disk.
    struct Faulty {
        topo: std::sync::Arc<Topology>,
        frames: Vec<Vec<V3>>,
        io_error_at: Option<usize>,
    }

    impl FrameSource for Faulty {
        fn topology(&self) -> &std::sync::Arc<Topology> {
            &self.topo
        }
        fn n_frames(&self) -> usize {
            self.frames.len()
        }
        fn read_frame(&self, t: usize) -> Result<Vec<V3>> {
            if t == 1 {
                return Err(Error::Mesh {
                    path: None,
                    frame: Some(t),
                    msg: "vertex 0 has a non-finite coordinate".into(),
                });
            }
            if self.io_error_at == Some(t) {
                return Err(Error::Io {
                    path: "frame".into(),
                    source: std::io::Error::other("flaky mount"),
                });
            }
            Ok(self.frames[t].clone())
        }
        fn describe_frame(&self, t: usize) -> String {
            format!("frame {t}")
        }
    }

    /// The strain limiter's reading: an invalid frame is left out (and named), the others still count; the
    /// strict reading fails on it; an I/O error fails both (a flaky read must not change a reference).
    #[test]
    fn invalid_frames_are_left_out_only_when_asked_and_io_errors_always_fail() {
        let (topo, flat) = synth::sheet(5, 4, 0.1).unwrap();
        let long: Vec<V3> = flat.iter().map(|q| [1.2 * q[0], q[1], q[2]]).collect();
        let mut source = Faulty {
            topo: topo.clone(),
            frames: vec![flat.clone(), flat.clone(), long.clone(), flat.clone()],
            io_error_at: None,
        };
        let (rest, skipped) = RestLengths::of_valid_frames(&source).unwrap();
        assert_eq!(skipped, vec![1]);
        let mut expected = RestLengths::new(&topo);
        expected.add_frame(&flat);
        expected.add_frame(&long);
        assert_eq!(rest, expected);
        assert!(matches!(
            RestLengths::of_sequence(&source),
            Err(Error::Mesh { frame: Some(1), .. })
        ));
        source.io_error_at = Some(2);
        assert!(matches!(
            RestLengths::of_valid_frames(&source),
            Err(Error::Io { .. })
        ));
    }
}
