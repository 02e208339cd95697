//! Fold estimation from the geometry alone (Chen 2011 ch. 4): stretch analysis between adjacent frames,
//! phase detection and integration forwards and backwards in time, and fold tracing in a local 2D
//! parameterisation. The result is anchors for the space-time deformation of Popa et al. 2009 §5.
//!
//! Module map: [`tensor`] §2.1/§4.2 (Jacobian, SVD, dominant direction), [`smooth`] §4.2 (outliers,
//! smoothing), [`phases`] §4.3 (continuity eq. 4.2, integration against the phase's first frame), [`unfold`],
//! [`lscm`] and [`trace`] §4.4 (parameterisation, axis, control lines, region of influence eq. 4.3 of one
//! seed), [`tracer`] §4.4 (the frame's seeds in order, seed memory), [`realise`] §4.5 (anchors).
//!
//! Memory is O(triangles) at any sequence length (§6.1): frames are streamed, each pass keeps one reference
//! layout per triangle, and the backward pass's per-frame signal (8 bytes per triangle and frame) is spilled
//! to an anonymous temporary file that the forward pass reads back frame by frame.

pub mod lscm;
pub mod overlay;
pub mod params;
pub mod phases;
pub mod realise;
pub mod smooth;
mod speculate;
pub mod split;
pub mod symbolic;
pub mod tensor;
pub mod trace;
pub mod tracer;
pub mod unfold;
mod wide_sweep;

pub use params::StretchParams;
pub use trace::TracedFold;
pub use tracer::FrameFolds;

use super::{Artifact, FoldDetector, FrameAnchors, Granularity};
use crate::error::{Error, Result};
use crate::mesh::{FrameSource, Topology};
use crate::progress::Progress;
use crate::vec3::{self, V3};
use overlay::OverlayFrame;
use phases::{PhaseTracker, Signal};
use rayon::prelude::*;
use smooth::FrameGeometry;
use std::io::{Read, Seek, SeekFrom, Write};
use std::ops::Range;

/// The geometric fold detector. Whole-sequence: phases (and the seed memory, when on) carry state through time.
#[derive(Debug, Clone, Default)]
pub struct StretchDetector {
    pub params: StretchParams,
    /// Frames drawn into `folds.png` by [`FoldDetector::detect_with_artifacts`] (none: no image).
    pub overlay_frames: Vec<usize>,
    /// Tile size of `folds.png`, pixels.
    pub overlay_size: u32,
}

/// Mean edge length of a frame (each interior edge counted twice; the mean is what matters).
pub fn mean_edge_length(topo: &Topology, p: &[V3]) -> f64 {
    let mut sum = 0.0;
    for tri in topo.triangles() {
        for k in 0..3 {
            sum += vec3::norm(vec3::sub(p[tri[k] as usize], p[tri[(k + 1) % 3] as usize]));
        }
    }
    sum / (3 * topo.n_triangles()) as f64
}

const STAGE: &str = "stretch folds";

/// The backward pass's signal of triangle `i` as it is kept until the forward pass reaches its frame:
/// shrinkage and direction angle in the triangle's local frame, both f32 (8 bytes per triangle and frame).
pub(crate) fn backward_record(sig: &Signal, geom: &FrameGeometry, i: usize) -> (f32, f32) {
    let angle = tensor::axial_angle(sig.dir[i], geom.e1[i], geom.e2[i]) as f32;
    (sig.shrink[i] as f32, angle)
}

/// The fold signal of triangle `i`: the forward pass's `sig`, or the backward pass's `record` where it shrank
/// more.
pub(crate) fn combine(sig: &mut Signal, geom: &FrameGeometry, i: usize, record: (f32, f32)) {
    combine_one(
        &mut sig.shrink[i],
        &mut sig.dir[i],
        (geom.e1[i], geom.e2[i]),
        record,
    );
}

/// [`combine`] on one triangle's signal, so that the frame's triangles can be combined in parallel.
#[inline]
fn combine_one(shrink: &mut f64, dir: &mut V3, (e1, e2): (V3, V3), record: (f32, f32)) {
    let s = record.0 as f64;
    if s > *shrink {
        let a = record.1 as f64;
        *shrink = s;
        *dir = vec3::add(vec3::scale(e1, a.cos()), vec3::scale(e2, a.sin()));
    }
}

/// One triangle's backward record as stored in the spill file: little-endian shrinkage then angle.
fn decode_record(b: &[u8]) -> (f32, f32) {
    (
        f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        f32::from_le_bytes([b[4], b[5], b[6], b[7]]),
    )
}

/// What [`StretchDetector::run_timed`] measured besides the folds.
#[derive(Debug, Clone, Copy, Default)]
pub struct RunTiming {
    /// Seconds spent tracing, summed over frames (the rest is the two passes and `each`).
    pub tracing: f64,
    /// Seeds traced ahead of their turn on other threads ([`speculate`]), and those of them discarded because
    /// an earlier fold consumed their seed.
    pub traced_ahead: usize,
    pub wasted: usize,
}

impl StretchDetector {
    pub fn new(params: StretchParams) -> Self {
        StretchDetector {
            params,
            overlay_frames: Vec::new(),
            overlay_size: 384,
        }
    }

    /// Runs the whole analysis and calls `each` with every frame's traced folds, in frame order, together with
    /// the fold signal (integrated shrinkage per triangle, the larger of the two passes). A subdivided `source`
    /// is analysed and traced on its input mesh ([`FrameSource::subdivided_from`]): positions, signal and
    /// `FrameFolds::anchors` are then the input mesh's, and [`realise::anchors`] puts the folds on the subdivided
    /// one.
    pub fn run(
        &self,
        source: &dyn FrameSource,
        progress: &dyn Progress,
        each: impl FnMut(usize, &[V3], &[f64], FrameFolds) -> Result<()>,
    ) -> Result<()> {
        self.run_timed(source, progress, each).map(|_| ())
    }

    /// [`Self::run`], returning the seconds spent tracing and how the seeds were traced ([`RunTiming`]), so
    /// that `crease bench` can tell the costs apart.
    pub fn run_timed(
        &self,
        source: &dyn FrameSource,
        progress: &dyn Progress,
        mut each: impl FnMut(usize, &[V3], &[f64], FrameFolds) -> Result<()>,
    ) -> Result<RunTiming> {
        self.params.validate()?;
        let (source, levels) = match source.subdivided_from() {
            Some((base, sub)) => (base, sub.levels()),
            None => (source, 0),
        };
        let topo = source.topology().clone();
        let n = source.n_frames();
        let nt = topo.n_triangles();
        if n == 0 {
            return Ok(RunTiming::default());
        }
        let params = &self.params;
        progress.begin(STAGE, 2 * n as u64);
        let check = || -> Result<()> {
            if progress.cancelled() {
                Err(Error::Cancelled)
            } else {
                Ok(())
            }
        };
        // Backward pass: time reversed, so that folds vanishing in forward time are emerging ones (§4.3).
        let mut spill = tempfile::tempfile().map_err(|e| Error::io(std::env::temp_dir(), e))?;
        let record = 8 * nt;
        let spill_err = |e| Error::io(std::env::temp_dir().join("(stretch folds spill file)"), e);
        {
            let mut prev = source.read_frame(n - 1)?;
            let mut tracker = PhaseTracker::new(&topo, &prev);
            let mut buf = vec![0u8; record];
            spill.set_len((record * n) as u64).map_err(spill_err)?;
            for t in (0..n.saturating_sub(1)).rev() {
                check()?;
                let cur = source.read_frame(t)?;
                let geom = FrameGeometry::new(&topo, &cur);
                let sig = tracker.step(&topo, &prev, &cur, &geom, params);
                buf.par_chunks_mut(8)
                    .with_min_len(4096)
                    .enumerate()
                    .for_each(|(i, b)| {
                        let (shrink, angle) = backward_record(&sig, &geom, i);
                        b[..4].copy_from_slice(&shrink.to_le_bytes());
                        b[4..].copy_from_slice(&angle.to_le_bytes());
                    });
                spill
                    .seek(SeekFrom::Start((record * t) as u64))
                    .and_then(|_| spill.write_all(&buf))
                    .map_err(spill_err)?;
                prev = cur;
                progress.advance(STAGE, 1);
            }
            progress.advance(STAGE, 1);
        }
        // Forward pass, combined with the backward signal and traced frame by frame.
        let first = source.read_frame(0)?;
        let h = mean_edge_length(&topo, &first);
        let mut tracker = PhaseTracker::new(&topo, &first);
        let mut tracer = tracer::FoldTracer::new(&topo, levels);
        // Frame t's positions, geometry and forward signal (the tracker's step from frame t − 1).
        let forward = |t: usize,
                       prev: &[V3],
                       tracker: &mut PhaseTracker|
         -> Result<(Vec<V3>, FrameGeometry, Signal)> {
            let cur = if t == 0 {
                prev.to_vec()
            } else {
                source.read_frame(t)?
            };
            let geom = FrameGeometry::new(&topo, &cur);
            let sig = if t == 0 {
                Signal {
                    shrink: vec![1.0; nt],
                    dir: geom.e1.clone(),
                }
            } else {
                tracker.step(&topo, prev, &cur, &geom, params)
            };
            Ok((cur, geom, sig))
        };
        let mut next = Some(forward(0, &first, &mut tracker)?);
        drop(first);
        let mut buf = vec![0u8; record];
        let mut timing = RunTiming::default();
        for t in 0..n {
            check()?;
            let (cur, geom, mut sig) = next.take().expect("frame t was stepped");
            if t + 1 < n {
                spill
                    .seek(SeekFrom::Start((record * t) as u64))
                    .and_then(|_| spill.read_exact(&mut buf))
                    .map_err(spill_err)?;
                sig.shrink
                    .par_iter_mut()
                    .zip(sig.dir.par_iter_mut())
                    .zip(buf.par_chunks(8))
                    .with_min_len(4096)
                    .enumerate()
                    .for_each(|(i, ((shrink, dir), b))| {
                        combine_one(shrink, dir, (geom.e1[i], geom.e2[i]), decode_record(b));
                    });
            }
            let field = trace::FrameField {
                topo: &topo,
                p: &cur,
                geom: &geom,
                shrink: &sig.shrink,
                dir: &sig.dir,
                h,
            };
            let mut trace_timed = || {
                let started = std::time::Instant::now();
                let folds = tracer.trace(&field, params);
                (folds, started.elapsed().as_secs_f64())
            };
            // Tracing reads only frame t; the step to frame t + 1 only the two frames and the tracker, so the
            // step runs beside the tracing on the threads its seeds leave idle (the output is the same).
            let ((folds, seconds), stepped) = if t + 1 < n {
                let (traced, stepped) =
                    rayon::join(trace_timed, || forward(t + 1, &cur, &mut tracker));
                (traced, Some(stepped))
            } else {
                (trace_timed(), None)
            };
            timing.tracing += seconds;
            each(t, &cur, &sig.shrink, folds)?;
            drop((geom, sig));
            if let Some(stepped) = stepped {
                next = Some(stepped?);
            }
            progress.advance(STAGE, 1);
        }
        (timing.traced_ahead, timing.wasted) = tracer.traced_ahead();
        progress.end(STAGE);
        Ok(timing)
    }
}

impl StretchDetector {
    /// The whole-sequence end of detection, shared by the streaming run and the split one ([`split`]):
    /// temporal coherence over the traced frames `out` (all frames, in order), and `folds.png` from the
    /// overlay frames `shown`.
    pub fn finish(
        &self,
        source: &dyn FrameSource,
        out: Vec<FrameAnchors>,
        shown: &[OverlayFrame],
    ) -> Result<(Vec<FrameAnchors>, Vec<Artifact>)> {
        let out = crate::folds::temporal::settle(source, out, self.params.temporal_radius)?;
        let mut artifacts = Vec::new();
        if !shown.is_empty() && self.overlay_size > 0 {
            // Drawn on the traced (input) mesh, with the anchors as traced there.
            let traced_topo = split::traced_source(source).0.topology();
            let img = overlay::overlay(
                traced_topo,
                shown,
                self.overlay_size,
                1.0 + 4.0 * self.params.min_shrink,
            );
            artifacts.push(Artifact {
                key: "folds.png".into(),
                bytes: crate::render::png_bytes(&img, std::path::Path::new("folds.png"))?,
            });
        }
        Ok((out, artifacts))
    }
}

impl FoldDetector for StretchDetector {
    fn name(&self) -> &'static str {
        "stretch"
    }

    fn granularity(&self) -> Granularity {
        Granularity::WholeSequence
    }

    fn detect(
        &self,
        source: &dyn FrameSource,
        frames: Range<usize>,
        progress: &dyn Progress,
    ) -> Result<Vec<FrameAnchors>> {
        let n = source.n_frames();
        if frames != (0..n) {
            return Err(Error::param(
                "frames",
                format!(
                    "the stretch detector works on the whole sequence (0..{n}), got {}..{}",
                    frames.start, frames.end
                ),
            ));
        }
        Ok(self.detect_with_artifacts(source, frames, progress)?.0)
    }

    /// Also draws `folds.png`: the fold signal and anchors of `overlay_frames`, whose positions and shrinkage
    /// exist only during the run.
    fn detect_with_artifacts(
        &self,
        source: &dyn FrameSource,
        frames: Range<usize>,
        progress: &dyn Progress,
    ) -> Result<(Vec<FrameAnchors>, Vec<Artifact>)> {
        let n = source.n_frames();
        if frames != (0..n) {
            return Err(Error::param(
                "frames",
                format!(
                    "the stretch detector works on the whole sequence (0..{n}), got {}..{}",
                    frames.start, frames.end
                ),
            ));
        }
        let mut out = Vec::with_capacity(n);
        let mut shown: Vec<OverlayFrame> = Vec::new();
        let sub = source.subdivided_from().map(|(_, sub)| sub);
        self.run(source, progress, |t, positions, shrink, folds| {
            if self.overlay_frames.contains(&t) {
                shown.push(OverlayFrame {
                    frame: t,
                    positions: positions.to_vec(),
                    shrink: shrink.to_vec(),
                    anchors: folds.anchors.clone(),
                    n_folds: folds.folds.len(),
                });
            }
            out.push(FrameAnchors {
                frame: t,
                anchors: match sub {
                    Some(sub) => realise::anchors(&folds.folds, Some(sub)),
                    None => folds.anchors,
                },
                detection: Some(super::FrameDetection {
                    folds: folds.folds.len(),
                    seeds_tried: Some(folds.seeds_tried),
                }),
                control_lines: folds.folds.into_iter().flat_map(|f| f.lines).collect(),
            });
            Ok(())
        })?;
        self.finish(source, out, &shown)
    }

    fn summary(&self, _source: &dyn FrameSource) -> Result<serde_json::Value> {
        Ok(serde_json::json!({ "parameters": self.params }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On several threads (seeds traced ahead, passes split over triangles) the run gives what one thread gives,
    /// bit for bit: positions, fold signal and folds of every frame.
    #[test]
    fn runs_on_several_threads_are_the_one_thread_run() {
        let seq = crate::synth::compressed_tube(4000, 6, 0.3, -1.0).unwrap();
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut out = Vec::new();
                StretchDetector::default()
                    .run(&seq, &crate::progress::NoProgress, |t, p, shrink, folds| {
                        out.push(format!("{t} {p:?} {shrink:?} {folds:?}"));
                        Ok(())
                    })
                    .unwrap();
                out
            })
        };
        let one = run(1);
        assert_eq!(one.len(), 6);
        // Frame 0 has no shrinkage yet; the compressed frames after it have folds.
        assert!(
            one[1..].iter().any(|f| f.contains("TracedFold")),
            "no folds"
        );
        let three = run(3);
        for (t, (a, b)) in one.iter().zip(&three).enumerate() {
            assert!(a == b, "frame {t} differs on three threads");
        }
    }
}
