//! Strain limiting: the last step of the positioning shortens the few edges stretched past a cap.
//!
//! The positioning solves for deformation gradients in the least-squares sense, so where the anchors ask for
//! rotations no surface can realise (a narrow fold crest, the end of a fold that fades within a triangle or
//! two) the solve spreads the conflict as stretch; the stretch passes relax most of it, and the shape
//! projection, linear in the displacement and blind to triangle shapes, puts some back. What is left is a thin
//! tail: on the demo a hundred interior triangles (0.03% of the samples) in the frames of one fold go above
//! 10% while p99 is 2% (bench/results/2026-12-03-strain-limiting.md). Cloth does not stretch that
//! far, so the tail is an artefact, and reshaping the whole frame to remove it (another pass, another
//! projection order) trades it against the drift and the folds everywhere else.
//!
//! This module removes only the tail, in the way cloth simulators bound stretch (Provot 1995; position-based
//! strain limiting): every edge longer than `(1 + cap)` times its reference length is shortened back to that
//! length by moving its two ends toward each other by equal amounts along the edge, in Gauss–Seidel sweeps
//! over the edges in mesh order. An edge within the cap is never touched, so a vertex whose edges are all
//! within it never moves; compression, which is what folds are made of, is not limited; each correction keeps
//! the edge's midpoint, so the garment's shape and the folds' positions stay where they were. Sweeps stop
//! early once one moves nothing.
//!
//! **Reference lengths** ([`StrainReference`]): by default the rest lengths of [`crate::rest_stretch`], per
//! edge its longest captured length over the sequence (the cloth's rest state as far as the capture shows
//! it, and the reference the real-data stretch is reported against): a fold may give back the length the
//! capture flattened away, but no edge becomes longer than the cloth between its ends has ever been, plus the
//! cap. It needs every captured frame, so it is computed once per sequence (a cluster worker once per input it
//! opens) and is the same for every frame wherever it is positioned. `frame` takes each frame's own captured
//! edge lengths instead, for an input that is the rest state in every frame (the synthetic demo); on a
//! capture it would forbid the folds the length they lost. There the frame *is* the rest state, so an edge
//! compressed by more than the cap is strain too and is lengthened back to `(1 − cap)` times its length (the
//! demo's stretch, per triangle, counts both ways); against the sequence, compression is folding and is free.
//!
//! Everything is sequential within a frame in a fixed order, so the result does not depend on the thread
//! count or on which machine positions the frame.

use crate::error::{Error, Result};
use crate::mesh::{FrameSource, Topology};
use crate::rest_stretch::{self, RestLengths};
use crate::vec3::{self, V3};
use serde::{Deserialize, Serialize};

/// Default cap: edges more than 5% longer than their reference are shortened back to it (docs/fidelity.md):
/// cloth stretches a few percent at most, the tail above it is the solve's, and on the public cases the figures
/// of the folds do not move (10% leaves the demo's triangles at 12.1%;
/// bench/results/2026-12-03-strain-limiting.md).
pub const DEFAULT_STRAIN_LIMIT: f64 = 0.05;

/// Cap against a true rest state (an input that is its own rest state in every frame, like the built-in demo):
/// there the reference is exact, so the cap can be as tight as cloth is stiff (Popa et al. report 4% per
/// triangle; 2% per edge gives the demo 4.1% per triangle, 5% leaves 8.4%). The sequence reference needs the
/// looser [`DEFAULT_STRAIN_LIMIT`]: it is short wherever a region stays folded in every frame (the ground truth
/// itself exceeds it by 7.8% at p99 on the public sleeve).
pub const REST_STATE_STRAIN_LIMIT: f64 = 0.02;

/// Default Gauss–Seidel sweeps (each touches only the edges still above the cap).
pub const DEFAULT_STRAIN_LIMIT_SWEEPS: usize = 20;

/// Most sweeps accepted.
pub const MAX_STRAIN_LIMIT_SWEEPS: usize = 1000;

/// Largest cap accepted (a fraction; 1 = twice the reference length).
pub const MAX_STRAIN_LIMIT: f64 = 1.0;

/// The length each edge is limited against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StrainReference {
    /// Per edge, its longest captured length over the sequence ([`crate::rest_stretch`]).
    #[default]
    Sequence,
    /// Per edge, its captured length in the frame being positioned (an input that is its own rest state).
    Frame,
}

impl std::str::FromStr for StrainReference {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "sequence" => Ok(StrainReference::Sequence),
            "frame" => Ok(StrainReference::Frame),
            _ => Err(Error::param(
                "strain_reference",
                format!("`{s}` is not one of: sequence, frame"),
            )),
        }
    }
}

/// Checks a cap and a sweep count, naming the field.
pub fn validate(cap: f64, sweeps: usize) -> Result<()> {
    if !(cap.is_finite() && (0.0..=MAX_STRAIN_LIMIT).contains(&cap)) {
        return Err(Error::param(
            "strain_limit",
            format!("must be a fraction in [0, {MAX_STRAIN_LIMIT}] (0: off), got {cap}"),
        ));
    }
    if cap > 0.0 && !(1..=MAX_STRAIN_LIMIT_SWEEPS).contains(&sweeps) {
        return Err(Error::param(
            "strain_limit_sweeps",
            format!("must be between 1 and {MAX_STRAIN_LIMIT_SWEEPS}, got {sweeps}"),
        ));
    }
    Ok(())
}

/// What one application did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LimitOutcome {
    /// Sweeps run (the last one moved nothing when it is below the sweep limit).
    pub sweeps: usize,
    /// Edge corrections made over all sweeps.
    pub corrections: usize,
}

/// A strain limiter for one mesh: its edges, the cap and, for [`StrainReference::Sequence`], the rest lengths.
///
/// The edges are swept in the order of their (lower, higher) vertex pairs, which depends on neither the
/// triangles' order nor their winding: a mesh with flipped triangles is limited identically.
#[derive(Debug, Clone, PartialEq)]
pub struct StrainLimiter {
    edges: Vec<[u32; 2]>,
    /// Per-edge reference lengths (sequence reference, tension only); `None`: each frame's captured lengths,
    /// limited both ways.
    reference: Option<Vec<f64>>,
    cap: f64,
    sweeps: usize,
}

impl StrainLimiter {
    /// Limits against the sequence's rest lengths.
    pub fn with_rest_lengths(rest: &RestLengths, cap: f64, sweeps: usize) -> Result<Self> {
        validate(cap, sweeps)?;
        let mut pairs: Vec<([u32; 2], f64)> = rest
            .edges()
            .iter()
            .copied()
            .zip(rest.lengths().iter().copied())
            .collect();
        pairs.sort_unstable_by_key(|p| p.0);
        Ok(StrainLimiter {
            edges: pairs.iter().map(|p| p.0).collect(),
            reference: Some(pairs.iter().map(|p| p.1).collect()),
            cap,
            sweeps,
        })
    }

    /// Limits against each frame's own captured edge lengths.
    pub fn per_frame(topo: &Topology, cap: f64, sweeps: usize) -> Result<Self> {
        validate(cap, sweeps)?;
        let mut edges = rest_stretch::edges(topo);
        edges.sort_unstable();
        Ok(StrainLimiter {
            edges,
            reference: None,
            cap,
            sweeps,
        })
    }

    /// The limiter a deformation with these settings uses on `source` (reading every frame once for the
    /// sequence reference; a frame with invalid contents is left out of it, since the task positioning that
    /// frame fails on it anyway: [`RestLengths::of_valid_frames`]), or `None` when the cap is 0 (off).
    pub fn for_source(
        source: &dyn FrameSource,
        cap: f64,
        sweeps: usize,
        reference: StrainReference,
    ) -> Result<Option<Self>> {
        validate(cap, sweeps)?;
        if cap == 0.0 {
            return Ok(None);
        }
        Ok(Some(match reference {
            StrainReference::Sequence => {
                Self::with_rest_lengths(&RestLengths::of_valid_frames(source)?.0, cap, sweeps)?
            }
            StrainReference::Frame => Self::per_frame(source.topology(), cap, sweeps)?,
        }))
    }

    pub fn cap(&self) -> f64 {
        self.cap
    }

    /// Shortens the edges of `out` longer than (1 + cap) × their reference back to that length, `captured`
    /// being the frame's captured positions (the reference of [`StrainReference::Frame`], which also lengthens
    /// edges shorter than (1 − cap) × their captured length). Edges with a zero reference length are left alone.
    pub fn apply(&self, captured: &[V3], out: &mut [V3]) -> LimitOutcome {
        // Per edge, the [shortest, longest] length allowed.
        let bounds: Vec<[f64; 2]> = match &self.reference {
            Some(r) => r.iter().map(|l| [0.0, (1.0 + self.cap) * l]).collect(),
            None => self
                .edges
                .iter()
                .map(|e| {
                    let d = vec3::sub(captured[e[1] as usize], captured[e[0] as usize]);
                    let l = vec3::norm(d);
                    [(1.0 - self.cap) * l, (1.0 + self.cap) * l]
                })
                .collect(),
        };
        let mut outcome = LimitOutcome::default();
        for _ in 0..self.sweeps {
            outcome.sweeps += 1;
            let mut moved = 0;
            for (&[a, b], &[lo, hi]) in self.edges.iter().zip(&bounds) {
                let (a, b) = (a as usize, b as usize);
                let d = vec3::sub(out[b], out[a]);
                let len = vec3::norm(d);
                let target = if len > hi && hi > 0.0 {
                    hi
                } else if len < lo && len > 0.0 {
                    lo
                } else {
                    continue;
                };
                // Each end moves half the excess along the edge: the midpoint stays.
                let half = vec3::scale(d, 0.5 * (len - target) / len);
                out[a] = vec3::add(out[a], half);
                out[b] = vec3::sub(out[b], half);
                moved += 1;
            }
            outcome.corrections += moved;
            if moved == 0 {
                break;
            }
        }
        outcome
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth;

    fn max_tension(rest: &RestLengths, p: &[V3]) -> f64 {
        rest.tension(p).into_iter().flatten().fold(0.0, f64::max)
    }

    /// A sheet with a bump pulled out of it: the edges over the bump are stretched far past the cap. The limiter
    /// brings the maximum down to (about) the cap, moves only vertices that had an over-cap edge or were moved
    /// by a neighbour's correction, and leaves every vertex whose edges were all under the cap in the input
    /// in place when no correction reaches it.
    #[test]
    fn shortens_only_edges_above_the_cap() {
        let (topo, flat) = synth::sheet(21, 21, 0.05).unwrap();
        let mut rest = RestLengths::new(&topo);
        rest.add_frame(&flat);
        // A narrow spike: the centre vertex lifted by 2 edge lengths (its edges stretch by ~120%), plus a gentle
        // wide wave everywhere (every edge under 3%).
        let centre = 10 * 21 + 10;
        let mut out: Vec<V3> = flat
            .iter()
            .map(|q| [q[0], q[1], 0.01 * (q[0] * 3.0).sin()])
            .collect();
        out[centre][2] += 0.1;
        assert!(max_tension(&rest, &out) > 1.0);
        let limiter = StrainLimiter::with_rest_lengths(&rest, 0.05, 200).unwrap();
        let before = out.clone();
        let outcome = limiter.apply(&flat, &mut out);
        assert!(outcome.corrections > 0, "{outcome:?}");
        let after = max_tension(&rest, &out);
        assert!(after <= 0.05 + 1e-3, "max tension {after}");
        // Far from the spike nothing moved, bit for bit; the spike's vertex came down.
        let moved: Vec<usize> = (0..out.len()).filter(|&v| out[v] != before[v]).collect();
        assert!(moved.contains(&centre));
        for &v in &moved {
            let (dx, dy) = (flat[v][0] - flat[centre][0], flat[v][1] - flat[centre][1]);
            assert!(
                dx.hypot(dy) < 0.05 * 5.0,
                "vertex {v} moved, far from the spike"
            );
        }
        assert!(
            moved.len() < out.len() / 4,
            "{} of {}",
            moved.len(),
            out.len()
        );
        assert!(out[centre][2] < before[centre][2]);
    }

    /// A frame whose edges are all within the cap (a wave, and a sheet compressed by 30%: folds are
    /// compression) comes back bit for bit, with no sweep's correction.
    #[test]
    fn a_frame_within_the_cap_is_not_touched() {
        let (topo, flat) = synth::sheet(15, 11, 0.1).unwrap();
        let mut rest = RestLengths::new(&topo);
        rest.add_frame(&flat);
        let limiter = StrainLimiter::with_rest_lengths(&rest, 0.05, 10).unwrap();
        for frame in [
            flat.iter()
                .map(|q| [q[0], q[1], 0.01 * (q[0] * 5.0).sin()])
                .collect::<Vec<V3>>(),
            flat.iter().map(|q| [0.7 * q[0], q[1], q[2]]).collect(),
        ] {
            let mut out = frame.clone();
            let o = limiter.apply(&flat, &mut out);
            assert_eq!(
                o,
                LimitOutcome {
                    sweeps: 1,
                    corrections: 0
                }
            );
            assert_eq!(out, frame);
        }
    }

    /// The frame reference limits against the captured frame, the sequence reference against the longest
    /// captured length: a capture squeezed to 80% and positioned back to full length is limited by the first
    /// (25% over its frame) and left alone by the second.
    #[test]
    fn the_reference_decides_what_counts_as_stretch() {
        let (topo, flat) = synth::sheet(9, 9, 0.1).unwrap();
        let squeezed: Vec<V3> = flat.iter().map(|q| [0.8 * q[0], q[1], q[2]]).collect();
        let mut rest = RestLengths::new(&topo);
        rest.add_frame(&squeezed);
        rest.add_frame(&flat);
        let seq = StrainLimiter::with_rest_lengths(&rest, 0.1, 50).unwrap();
        let mut out = flat.clone();
        assert_eq!(seq.apply(&squeezed, &mut out).corrections, 0);
        assert_eq!(out, flat);
        let per_frame = StrainLimiter::per_frame(&topo, 0.1, 500).unwrap();
        let o = per_frame.apply(&squeezed, &mut out);
        assert!(o.corrections > 0, "{o:?}");
        let mut frame_rest = RestLengths::new(&topo);
        frame_rest.add_frame(&squeezed);
        let t = max_tension(&frame_rest, &out);
        assert!(t < 0.12, "{t}");
    }

    /// The demo positioned with its stretch tail limited against its own frames (cap 2%, well under the tail the
    /// positioning leaves: the test fails without the limit) has no edge more than the cap longer than in its
    /// input frame, and gives the same bits on 1 and 3 threads.
    #[test]
    fn the_demo_stays_within_the_cap_on_any_thread_count() {
        use crate::mesh::MemorySink;
        use crate::progress::NoProgress;
        use crate::spacetime::{deform, DeformParams};
        let (seq, anchors) = synth::demo(&synth::DemoSpec {
            triangles: 3000,
            frames: 6,
            ..Default::default()
        })
        .unwrap();
        let run = |cap: f64, threads: usize| -> Vec<Vec<V3>> {
            let params = DeformParams {
                strain_limit: cap,
                strain_limit_sweeps: 200,
                strain_reference: StrainReference::Frame,
                ..DeformParams::default()
            };
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut sink = MemorySink::default();
                deform(&seq, &anchors, &params, &mut sink, &NoProgress, &[]).unwrap();
                sink.frames.into_values().collect()
            })
        };
        // Largest tension of any output edge against the same edge in its input frame.
        let worst = |out: &[Vec<V3>]| -> f64 {
            out.iter()
                .enumerate()
                .map(|(t, o)| {
                    let mut own = RestLengths::new(&seq.topology);
                    own.add_frame(&seq.frames[t]);
                    max_tension(&own, o)
                })
                .fold(0.0, f64::max)
        };
        // Largest compression likewise (the frame reference limits both ways).
        let squeeze = |out: &[Vec<V3>]| -> f64 {
            let e = rest_stretch::edges(&seq.topology);
            let frames = &seq.frames;
            let len =
                |p: &[V3], [a, b]: [u32; 2]| vec3::norm(vec3::sub(p[b as usize], p[a as usize]));
            out.iter()
                .enumerate()
                .flat_map(|(t, o)| e.iter().map(move |&k| 1.0 - len(o, k) / len(&frames[t], k)))
                .fold(0.0, f64::max)
        };
        let cap = 0.02;
        let free = worst(&run(0.0, 2));
        assert!(
            free > 1.5 * cap,
            "the test needs a tail above the cap: {free}"
        );
        let limited = run(cap, 1);
        let got = worst(&limited);
        assert!(
            got <= cap + 1e-3,
            "max tension {got} (without the limit {free})"
        );
        let sq = squeeze(&limited);
        assert!(sq <= cap + 1e-3, "max compression {sq}");
        let bits = |f: &[Vec<V3>]| -> Vec<u64> {
            f.iter().flatten().flatten().map(|x| x.to_bits()).collect()
        };
        assert_eq!(bits(&limited), bits(&run(cap, 3)));
    }

    /// Bad caps and sweep counts name their field.
    #[test]
    fn bad_settings_name_the_field() {
        let (topo, _) = synth::sheet(3, 3, 0.1).unwrap();
        for cap in [-0.1, 1.5, f64::NAN, f64::INFINITY] {
            let err = StrainLimiter::per_frame(&topo, cap, 5)
                .unwrap_err()
                .to_string();
            assert!(err.contains("strain_limit"), "{cap}: {err}");
        }
        for sweeps in [0, MAX_STRAIN_LIMIT_SWEEPS + 1] {
            let err = StrainLimiter::per_frame(&topo, 0.1, sweeps)
                .unwrap_err()
                .to_string();
            assert!(err.contains("strain_limit_sweeps"), "{sweeps}: {err}");
        }
        // Off needs no sweeps.
        assert!(validate(0.0, 0).is_ok());
        let err = "rest".parse::<StrainReference>().unwrap_err().to_string();
        assert!(err.contains("strain_reference"), "{err}");
    }
}
