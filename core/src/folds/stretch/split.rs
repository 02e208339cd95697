//! The stretch detector cut into stages that can run on different machines, with the single-run result bit
//! for bit.
//!
//! [`StretchDetector::run`] streams the sequence twice in one process. Its work splits along what depends on
//! what:
//!
//! 1. **Steps** ([`steps`]): the smoothed step tensor of every adjacent frame pair, in both directions of time,
//!    reduced to what the phase test reads — the dominant value and its direction angle. Independent per
//!    frame pair, so any frame chunk can be computed anywhere.
//! 2. **Phases** ([`Phases`]): the continuity test (eq. 4.2) over time, both passes. Sequential, but it only
//!    reads the step records (two numbers per triangle and step), never geometry, and writes for every frame
//!    and pass the frame each triangle's phase started at ([`PhaseCode`]), so it is cheap.
//! 3. **Tracing** ([`ChunkTracer`]): per frame, the integrated tensor against those reference frames, the two
//!    passes combined exactly as the streaming run combines them, and the folds traced. Independent per frame
//!    (the default); with the seed memory on ([`StretchParams::seed_memory`]) a frame's folds depend on the
//!    previous frame's seeds.
//! 4. **Reconcile** ([`reconcile`]): a tracing chunk starts with an empty seed memory a few frames early (a
//!    warm-up) and records the memory it reached at its first frame. The true memory there is the previous
//!    chunk's last seeds; when they agree the chunk is exact, otherwise its frames are traced again from the
//!    true memory until the seeds agree with the chunk's own (from then on its frames are exact). So the result
//!    is the streaming run's for any chunking; chunking only moves work into the reconcile when warm-ups do not
//!    catch the memory. Measured on the sleeve, they never do (48 frames in two chunks: all 24 frames of the
//!    second traced again, in order), which is why the memory is off by default: then chunks need no warm-up
//!    and the reconcile only checks and gathers.
//!
//! Then [`StretchDetector::finish`] (temporal coherence, `folds.png`) as in the single run.

pub mod file;

use super::overlay::OverlayFrame;
use super::phases::{integrated_signal, step_dominants, PhaseClock, Restart, Signal};
use super::smooth::FrameGeometry;
use super::tensor::shape;
use super::trace::FrameField;
use super::tracer::FoldTracer;
use super::{combine, mean_edge_length, realise, StretchDetector, StretchParams};
use crate::error::{Error, Result};
use crate::folds::{Anchor, FrameAnchors};
use crate::mesh::subdivide::Subdivision;
use crate::mesh::{FrameSource, Topology};
use crate::progress::Progress;
use crate::vec3::V3;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::ops::Range;

/// One frame's step record per triangle: forward step (frame − 1 → frame) dominant value and angle, backward
/// step (frame + 1 → frame) dominant value and angle. A step that does not exist (forward at frame 0, backward
/// at the last frame) is recorded as (1, 0) and never read.
pub type StepRecord = [f64; 4];

/// A triangle's phase at one frame of one pass: `reference_frame << 1 | shrinking`.
pub type PhaseCode = u32;

/// The frame a [`PhaseCode`] refers to, and whether its phase is one of shrinkage.
#[inline]
pub fn decode(code: PhaseCode) -> (usize, bool) {
    ((code >> 1) as usize, code & 1 == 1)
}

fn encode(frame: usize, shrinking: bool) -> PhaseCode {
    ((frame as u32) << 1) | shrinking as u32
}

/// The longest sequence the phase codes can name.
pub const MAX_FRAMES: usize = 1 << 31;

/// The mesh the detector traces on (the input of a subdivided source) and the subdivision levels.
pub fn traced_source(source: &dyn FrameSource) -> (&dyn FrameSource, usize) {
    match source.subdivided_from() {
        Some((base, sub)) => (base, sub.levels()),
        None => (source, 0),
    }
}

/// The step records of `frames` (a range of the sequence), one vector per frame, in order.
pub fn steps(
    source: &dyn FrameSource,
    frames: Range<usize>,
    params: &StretchParams,
    progress: &dyn Progress,
) -> Result<Vec<Vec<StepRecord>>> {
    params.validate()?;
    let (source, _) = traced_source(source);
    let n = source.n_frames();
    check_range(&frames, n)?;
    let topo = source.topology();
    let mut out = Vec::with_capacity(frames.len());
    let mut prev = match frames.start {
        0 => None,
        a => Some(source.read_frame(a - 1)?),
    };
    let mut cur = source.read_frame(frames.start)?;
    progress.begin("stretch steps", frames.len() as u64);
    for t in frames.clone() {
        if progress.cancelled() {
            return Err(Error::Cancelled);
        }
        let next = if t + 1 < n {
            Some(source.read_frame(t + 1)?)
        } else {
            None
        };
        let geom = FrameGeometry::new(topo, &cur);
        let mut rec = vec![[1.0, 0.0, 1.0, 0.0]; topo.n_triangles()];
        if let Some(p) = &prev {
            for (r, (v, a)) in rec
                .iter_mut()
                .zip(step_dominants(topo, p, &cur, &geom, params))
            {
                r[0] = v;
                r[1] = a;
            }
        }
        if let Some(q) = &next {
            for (r, (v, a)) in rec
                .iter_mut()
                .zip(step_dominants(topo, q, &cur, &geom, params))
            {
                r[2] = v;
                r[3] = a;
            }
        }
        out.push(rec);
        progress.advance("stretch steps", 1);
        prev = Some(std::mem::replace(&mut cur, next.unwrap_or_default()));
    }
    progress.end("stretch steps");
    Ok(out)
}

fn check_range(frames: &Range<usize>, n: usize) -> Result<()> {
    if frames.start >= frames.end || frames.end > n {
        return Err(Error::param(
            "frames",
            format!(
                "{}..{} is not a non-empty range of the sequence's {n} frames",
                frames.start, frames.end
            ),
        ));
    }
    if n > MAX_FRAMES {
        return Err(Error::param(
            "frames",
            format!("{n} frames: the split detector handles at most {MAX_FRAMES}"),
        ));
    }
    Ok(())
}

/// Which pass of the phase test.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pass {
    Forward,
    Backward,
}

/// The phase test of both passes over step records read one frame at a time.
pub struct Phases<'a> {
    pub n_frames: usize,
    pub n_triangles: usize,
    pub params: &'a StretchParams,
}

impl Phases<'_> {
    /// Runs the backward pass (frames `n − 2` down to 0), then the forward pass (1 up to `n − 1`), calling
    /// `read(t)` for frame `t`'s step records (each frame read once per pass) and `write(t, pass, codes)` with the
    /// phase of every triangle there. Frames without a step in a pass (the pass's first frame) get no codes.
    pub fn run(
        &self,
        mut read: impl FnMut(usize) -> Result<Vec<StepRecord>>,
        mut write: impl FnMut(usize, Pass, Vec<PhaseCode>) -> Result<()>,
        progress: &dyn Progress,
    ) -> Result<()> {
        self.params.validate()?;
        let n = self.n_frames;
        if n > MAX_FRAMES {
            return Err(Error::param(
                "frames",
                format!("{n} frames: the split detector handles at most {MAX_FRAMES}"),
            ));
        }
        let theta0 = self.params.theta0_deg.to_radians();
        // One unit per frame step of each pass, as the single detector counts its two passes.
        progress.begin("stretch phases", 2 * n.saturating_sub(1) as u64);
        for pass in [Pass::Backward, Pass::Forward] {
            let (first, order): (usize, Vec<usize>) = match pass {
                Pass::Backward => (
                    n.saturating_sub(1),
                    (0..n.saturating_sub(1)).rev().collect(),
                ),
                Pass::Forward => (0, (1..n).collect()),
            };
            let mut clocks = vec![PhaseClock::default(); self.n_triangles];
            let mut refs = vec![first; self.n_triangles];
            let mut befores = vec![first; self.n_triangles];
            for t in order {
                if progress.cancelled() {
                    return Err(Error::Cancelled);
                }
                let rec = read(t)?;
                if rec.len() != self.n_triangles {
                    return Err(Error::param(
                        "steps",
                        format!(
                            "frame {t}: {} step records for {} triangles",
                            rec.len(),
                            self.n_triangles
                        ),
                    ));
                }
                let (col, prev) = match pass {
                    Pass::Forward => (0, t - 1),
                    Pass::Backward => (2, t + 1),
                };
                let codes = clocks
                    .iter_mut()
                    .zip(refs.iter_mut().zip(befores.iter_mut()))
                    .zip(&rec)
                    .map(|((clock, (r, before)), rec)| {
                        match clock.advance(rec[col], rec[col + 1], theta0, self.params) {
                            Restart::Keep => {}
                            Restart::AtCurrent => *r = t,
                            Restart::AtPrevious => {
                                *before = *r;
                                *r = prev;
                            }
                            Restart::Resume => *r = *before,
                        }
                        encode(*r, clock.state == -1)
                    })
                    .collect();
                write(t, pass, codes)?;
                progress.advance("stretch phases", 1);
            }
        }
        progress.end("stretch phases");
        Ok(())
    }
}

/// One traced frame as a tracing chunk stores it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ChunkFrame {
    /// What the streaming run hands to temporal coherence for this frame (realised on the subdivided mesh when
    /// there is one).
    pub anchors: FrameAnchors,
    /// The seed memory after this frame (seeds that gave folds), increasing.
    pub seeds: Vec<u32>,
    /// For frames drawn into `folds.png`: the anchors on the traced mesh and the number of folds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub overlay: Option<(Vec<Anchor>, usize)>,
}

/// A tracing chunk's result.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TracedChunk {
    /// First frame of the chunk.
    pub first: usize,
    /// The seed memory the warm-up reached entering `first` (empty for a chunk at frame 0: exact).
    pub entry_seeds: Vec<u32>,
    pub frames: Vec<ChunkFrame>,
}

/// Traces frames from their phase codes, keeping the frames the codes refer to while they are referred to.
pub struct ChunkTracer<'a> {
    source: &'a dyn FrameSource,
    sub: Option<&'a Subdivision>,
    topo: std::sync::Arc<Topology>,
    params: StretchParams,
    overlay_frames: Vec<usize>,
    h: f64,
    tracer: FoldTracer,
    frames: HashMap<usize, Vec<V3>>,
}

impl<'a> ChunkTracer<'a> {
    /// A tracer over `source` (subdivided or not, as given to the detector) with an empty seed memory.
    pub fn new(detector: &StretchDetector, source: &'a dyn FrameSource) -> Result<Self> {
        detector.params.validate()?;
        let sub = source.subdivided_from().map(|(_, s)| s);
        let (source, levels) = traced_source(source);
        let topo = source.topology().clone();
        let first = source.read_frame(0)?;
        let h = mean_edge_length(&topo, &first);
        let tracer = FoldTracer::new(&topo, levels);
        Ok(ChunkTracer {
            source,
            sub,
            topo,
            params: detector.params.clone(),
            overlay_frames: detector.overlay_frames.clone(),
            h,
            tracer,
            frames: HashMap::new(),
        })
    }

    pub fn n_frames(&self) -> usize {
        self.source.n_frames()
    }

    pub fn seeds(&self) -> Vec<u32> {
        self.tracer.seeds()
    }

    pub fn set_seeds(&mut self, seeds: &[u32]) {
        self.tracer.set_seeds(seeds)
    }

    /// Loads the frames `codes` refer to (and `t`), dropping those no longer referred to.
    fn hold(&mut self, t: usize, codes: &[&[PhaseCode]]) -> Result<()> {
        let n = self.source.n_frames();
        let mut wanted = vec![false; n];
        wanted[t] = true;
        for c in codes {
            for &code in c.iter() {
                let f = decode(code).0;
                if f >= n {
                    return Err(Error::param(
                        "phases",
                        format!("frame {t}: a phase refers to frame {f}, the sequence has {n}"),
                    ));
                }
                wanted[f] = true;
            }
        }
        let need: Vec<usize> = (0..n).filter(|&f| wanted[f]).collect();
        self.frames.retain(|&f, _| wanted[f]);
        for f in need {
            if let std::collections::hash_map::Entry::Vacant(e) = self.frames.entry(f) {
                e.insert(self.source.read_frame(f)?);
            }
        }
        Ok(())
    }

    /// The fold signal of frame `t` from its forward codes (`None` at frame 0) and backward codes (`None` at
    /// the last frame), as the streaming run computes it. Returns the frame's positions too.
    pub fn signal(
        &mut self,
        t: usize,
        forward: Option<&[PhaseCode]>,
        backward: Option<&[PhaseCode]>,
    ) -> Result<(Vec<V3>, FrameGeometry, Signal)> {
        let n = self.source.n_frames();
        let nt = self.topo.n_triangles();
        if (t == 0) != forward.is_none() || (t + 1 == n) != backward.is_none() {
            return Err(Error::param(
                "phases",
                format!("frame {t} of {n}: phase codes missing or unexpected"),
            ));
        }
        for c in [forward, backward].into_iter().flatten() {
            if c.len() != nt {
                return Err(Error::param(
                    "phases",
                    format!("frame {t}: {} phase codes for {nt} triangles", c.len()),
                ));
            }
        }
        let held: Vec<&[PhaseCode]> = [forward, backward].into_iter().flatten().collect();
        self.hold(t, &held)?;
        let topo: &Topology = &self.topo;
        let frames = &self.frames;
        let cur = &frames[&t];
        let geom = FrameGeometry::new(topo, cur);
        let reference = |codes: &[PhaseCode], i: usize| {
            let (f, _) = decode(codes[i]);
            shape(topo.triangles()[i].map(|v| frames[&f][v as usize]))
        };
        let mut sig = match forward {
            None => Signal {
                shrink: vec![1.0; nt],
                dir: geom.e1.clone(),
            },
            Some(c) => integrated_signal(
                topo,
                &geom,
                |i| reference(c, i),
                |i| decode(c[i]).1,
                cur,
                &self.params,
            ),
        };
        if let Some(c) = backward {
            let back = integrated_signal(
                topo,
                &geom,
                |i| reference(c, i),
                |i| decode(c[i]).1,
                cur,
                &self.params,
            );
            for i in 0..nt {
                combine(&mut sig, &geom, i, super::backward_record(&back, &geom, i));
            }
        }
        Ok((cur.clone(), geom, sig))
    }

    /// Traces frame `t` after the frame whose seeds the tracer holds.
    pub fn trace(
        &mut self,
        t: usize,
        forward: Option<&[PhaseCode]>,
        backward: Option<&[PhaseCode]>,
    ) -> Result<ChunkFrame> {
        let (cur, geom, sig) = self.signal(t, forward, backward)?;
        let field = FrameField {
            topo: &self.topo,
            p: &cur,
            geom: &geom,
            shrink: &sig.shrink,
            dir: &sig.dir,
            h: self.h,
        };
        let folds = self.tracer.trace(&field, &self.params);
        let overlay = self
            .overlay_frames
            .contains(&t)
            .then(|| (folds.anchors.clone(), folds.folds.len()));
        let detection = Some(super::super::FrameDetection {
            folds: folds.folds.len(),
            seeds_tried: Some(folds.seeds_tried),
        });
        Ok(ChunkFrame {
            anchors: FrameAnchors {
                frame: t,
                anchors: match self.sub {
                    Some(sub) => realise::anchors(&folds.folds, Some(sub)),
                    None => folds.anchors,
                },
                detection,
                control_lines: folds.folds.into_iter().flat_map(|f| f.lines).collect(),
            },
            seeds: self.tracer.seeds(),
            overlay,
        })
    }
}

/// The frames a tracing chunk `frames` traces before its first one, to warm its seed memory up.
pub fn warm_up_start(frames: &Range<usize>, warm_up: usize) -> usize {
    frames.start.saturating_sub(warm_up)
}

/// Traces the chunk `frames` after `warm_up` frames of warm-up. `codes(t)` gives frame `t`'s (forward,
/// backward) phase codes. Without the seed memory ([`StretchParams::seed_memory`], the default) a frame's
/// folds depend on that frame alone, so there is nothing to warm up and none is traced.
pub fn trace_chunk(
    tracer: &mut ChunkTracer,
    frames: Range<usize>,
    warm_up: usize,
    mut codes: impl FnMut(usize) -> Result<(Option<Vec<PhaseCode>>, Option<Vec<PhaseCode>>)>,
    progress: &dyn Progress,
) -> Result<TracedChunk> {
    check_range(&frames, tracer.n_frames())?;
    tracer.set_seeds(&[]);
    let mut out = Vec::with_capacity(frames.len());
    let mut entry_seeds = Vec::new();
    let warm_up = if tracer.params.seed_memory {
        warm_up
    } else {
        0
    };
    let start = warm_up_start(&frames, warm_up);
    progress.begin("stretch tracing", (frames.end - start) as u64);
    for t in start..frames.end {
        if progress.cancelled() {
            return Err(Error::Cancelled);
        }
        if t == frames.start {
            entry_seeds = tracer.seeds();
        }
        let (f, b) = codes(t)?;
        let frame = tracer.trace(t, f.as_deref(), b.as_deref())?;
        if t >= frames.start {
            out.push(frame);
        }
        progress.advance("stretch tracing", 1);
    }
    progress.end("stretch tracing");
    Ok(TracedChunk {
        first: frames.start,
        entry_seeds,
        frames: out,
    })
}

/// Joins tracing chunks (in frame order, covering the sequence) into the streaming run's frames, tracing again
/// where a chunk's warm-up did not reach the true seed memory (see the module documentation). `retrace(t,
/// seeds)` traces frame `t` after the seed memory `seeds`. Returns the frames and how many were traced again.
pub fn reconcile(
    chunks: impl IntoIterator<Item = Result<TracedChunk>>,
    n_frames: usize,
    mut retrace: impl FnMut(usize, &[u32]) -> Result<ChunkFrame>,
) -> Result<(Vec<ChunkFrame>, usize)> {
    let mut out: Vec<ChunkFrame> = Vec::with_capacity(n_frames);
    let mut seeds: Vec<u32> = Vec::new();
    let mut retraced = 0;
    for chunk in chunks {
        let chunk = chunk?;
        if chunk.first != out.len() {
            return Err(Error::param(
                "chunks",
                format!(
                    "a tracing chunk starts at frame {}, expected {}",
                    chunk.first,
                    out.len()
                ),
            ));
        }
        let mut exact = chunk.entry_seeds == seeds;
        for (k, frame) in chunk.frames.into_iter().enumerate() {
            let t = chunk.first + k;
            if frame.anchors.frame != t {
                return Err(Error::param(
                    "chunks",
                    format!(
                        "the chunk at frame {} holds frame {} in position {k}",
                        chunk.first, frame.anchors.frame
                    ),
                ));
            }
            let frame = if exact {
                frame
            } else {
                let again = retrace(t, &seeds)?;
                retraced += 1;
                // From here on the chunk's memory is the true one.
                exact = again.seeds == frame.seeds;
                again
            };
            seeds.clone_from(&frame.seeds);
            out.push(frame);
        }
    }
    if out.len() != n_frames {
        return Err(Error::param(
            "chunks",
            format!("tracing chunks cover {} of {n_frames} frames", out.len()),
        ));
    }
    Ok((out, retraced))
}

/// What [`StretchDetector::finish`] needs of an overlay frame that a tracing chunk recorded: the positions and
/// signal are computed again here (no tracing), the anchors come from the chunk.
pub fn overlay_frame(
    tracer: &mut ChunkTracer,
    frame: &ChunkFrame,
    forward: Option<&[PhaseCode]>,
    backward: Option<&[PhaseCode]>,
) -> Result<Option<OverlayFrame>> {
    let Some((anchors, n_folds)) = &frame.overlay else {
        return Ok(None);
    };
    let t = frame.anchors.frame;
    let (positions, _, sig) = tracer.signal(t, forward, backward)?;
    Ok(Some(OverlayFrame {
        frame: t,
        positions,
        shrink: sig.shrink,
        anchors: anchors.clone(),
        n_folds: *n_folds,
    }))
}
