//! The streaming driver of the space-time deformation.
//!
//! For each time window in order: solve the weights (fused or per-anchor), cross-fade into the previous
//! window's tail, and for every frame that is now final — in parallel across frames, while the next window's
//! weights are solved — read its original geometry, factorise its positioning matrix once, blend the
//! rotations, position the vertices, run the stretch-reduction passes reusing the factor, measure stretch
//! after each step, and hand the frame to the sink. Frames are read when needed and written when done, so
//! memory is bounded by one window's solve plus one window's released frames, whatever the sequence length.

use super::blend::CrossFade;
use super::params::DeformParams;
use super::position::PositionSystem;
use super::shape::lost_area::RestAreas;
use super::shape::relief::ReliefFrames;
use super::stages::{position_frame, PositionedFrame};
use super::weights::{solve_window, WindowProblem, WindowStats};
use super::windows::plan_windows;
use crate::error::{Error, Result};
use crate::folds::AnchorSet;
use crate::mesh::{Frame, FrameSink, FrameSource};
use crate::metrics::{StretchAccumulator, StretchStats};
use crate::progress::Progress;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Seconds spent per stage, summed over all frames and windows (work time: with frames positioned in parallel
/// the wall time is lower; see `wall`).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct StageTimings {
    pub symbolic: f64,
    pub read: f64,
    /// Wall time of each window's weight solve, summed; the solve runs while the previous window's frames are
    /// positioned, so it shares the threads with them.
    pub weights: f64,
    pub blend: f64,
    /// Numeric Cholesky factorisation of each frame's positioning matrix.
    pub factor: f64,
    /// First positioning solve (right-hand side + triangular solves).
    pub position: f64,
    /// Each stretch-reduction pass (normal rotations + solve with the reused factor).
    pub stretch_passes: Vec<f64>,
    pub metrics: f64,
    pub write: f64,
    /// Wall-clock time of the whole deformation.
    pub wall: f64,
}

/// What a deformation did and measured.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct DeformReport {
    pub params: DeformParams,
    pub frames: usize,
    pub vertices: usize,
    pub triangles: usize,
    pub anchors: usize,
    pub windows: Vec<WindowStats>,
    /// Sequence stretch after positioning (index 0) and after each stretch pass (index k).
    pub stretch: Vec<StretchStats>,
    /// Per frame, the same list.
    pub frame_stretch: Vec<Vec<StretchStats>>,
    /// Per frame, the share of the surface its deformation added that the capture had lost: the lost-area
    /// bound's judgement ([`super::shape::lost_area::trust`]: below 0.1 the frame came back as captured, from
    /// 0.25 its deformation stands whole). `None` where the bound did not run.
    #[serde(default)]
    pub frame_lost_share: Vec<Option<f64>>,
    /// Per frame, the share of the surface the capture lost that the fold relief gives back
    /// ([`super::shape::lost_area::Trace::share`]): a capture that blurred its folds keeps a copy to sharpen, one
    /// that erased them keeps almost none. `None` without the bound or the relief, or where nothing was lost.
    #[serde(default)]
    pub frame_relief_share: Vec<Option<f64>>,
    pub timings: StageTimings,
}

/// Original and output geometry of frames the caller asked to keep (for previews).
#[derive(Debug, Clone, Default)]
pub struct KeptFrames {
    pub frames: Vec<(usize, Frame, Frame)>,
}

/// Runs the whole deformation from `source` with `anchors` into `sink`. `keep` lists frames whose original and
/// output positions are returned for previews.
pub fn deform(
    source: &dyn FrameSource,
    anchors: &AnchorSet,
    params: &DeformParams,
    sink: &mut dyn FrameSink,
    progress: &dyn Progress,
    keep: &[usize],
) -> Result<(DeformReport, KeptFrames)> {
    params.validate()?;
    let wall = Instant::now();
    let n = source.n_frames();
    if n == 0 {
        return Err(Error::mesh("the sequence has no frames"));
    }
    if anchors.n_frames() != n {
        return Err(Error::Anchors {
            path: None,
            msg: format!(
                "anchors cover {} frames but the sequence has {n}",
                anchors.n_frames()
            ),
        });
    }
    let topo = source.topology().clone();
    let mut timings = StageTimings {
        stretch_passes: vec![0.0; params.stretch_passes],
        ..Default::default()
    };
    let t0 = Instant::now();
    let edge = crate::shape::mean_edge_length(&topo, &source.read_frame(0)?);
    let scales = params.scales(edge);
    let system = PositionSystem::new(topo.clone(), params.pinning, scales.screen)?;
    // The fold relief of every frame, when the job puts folds in at all (no anchors: the input comes back as it
    // was, bit for bit).
    let mut relief = (anchors.total() > 0 && params.relief.is_active())
        .then(|| ReliefFrames::new(params.relief, scales.detail, n));
    // The bound of what the deformation adds, the surface each neighbourhood shows at its largest over the
    // sequence: one reading pass, only when anything can move.
    let lost_area = if anchors.total() > 0 && params.lost_area_bound {
        Some(RestAreas::of_sequence(source)?)
    } else {
        None
    };
    timings.symbolic = t0.elapsed().as_secs_f64();
    // The strain limit's reference lengths need every captured frame: read once (a few frames at a time) before
    // any frame is positioned. Without anchors no frame moves and the limit never applies: no reading pass.
    let limiter = if anchors.total() > 0 {
        params.strain_limiter(source)?
    } else {
        None
    };

    let windows = plan_windows(n, params.window, params.shift);
    let mut fade = CrossFade::new(windows.clone(), topo.n_triangles());
    let mut window_stats = Vec::with_capacity(windows.len());
    let mut seq_stretch = vec![StretchAccumulator::default(); params.stretch_passes + 1];
    let mut frame_stretch = vec![Vec::new(); n];
    let mut frame_lost_share = vec![None; n];
    let mut frame_relief_share = vec![None; n];
    let mut kept = KeptFrames::default();
    progress.begin("weights", windows.len() as u64);
    progress.begin("position", n as u64);
    // Window k's weights are solved while the frames window k − 1 released are positioned, both on the same
    // thread pool: the solve's parallel sweeps and the per-frame positioning fill each other's idle threads
    // (a window releases 7 frames by default, which 2 threads cannot split evenly, and the solve's reductions
    // wait on their slowest chunk). Every stage is a pure function of its inputs, so the overlap changes no
    // output bit; frames are still written in order, each window's as soon as it is positioned, and at most
    // one window's released frames are read before they are written.
    let position_ready = |ready: Vec<(usize, Vec<crate::vec3::V3>)>,
                          relief: Option<&mut ReliefFrames>|
     -> Vec<Result<PositionedFrame>> {
        let frames: Vec<usize> = ready.iter().map(|(t, _)| *t).collect();
        let relief = match relief {
            Some(r) => match r.prepare(source, &frames) {
                Ok(()) => Some(&*r),
                Err(e) => return vec![Err(e)],
            },
            None => None,
        };
        ready
            .into_par_iter()
            .map(|(t, phi)| {
                if progress.cancelled() {
                    return Err(Error::Cancelled);
                }
                let heights = relief.map(|r| r.heights(&topo, t)).transpose()?;
                let r = position_frame(
                    &system,
                    source,
                    t,
                    &phi,
                    params.stretch_passes,
                    params.stretch_rotation,
                    &scales.ending,
                    heights.as_deref(),
                    lost_area.as_ref(),
                    limiter.as_ref(),
                    None,
                );
                progress.advance("position", 1);
                r
            })
            .collect()
    };
    let mut ready = Vec::new();
    for k in 0..=windows.len() {
        if progress.cancelled() {
            return Err(Error::Cancelled);
        }
        let released = std::mem::take(&mut ready);
        let (solved, outcomes) = rayon::join(
            || {
                windows.get(k).map(|w| {
                    let problem = WindowProblem::new(&topo, anchors, *w, params.coefficients);
                    solve_window(&problem, params, progress)
                })
            },
            || position_ready(released, relief.as_mut()),
        );
        for o in outcomes {
            let o = o?;
            let tw = Instant::now();
            sink.write_frame(o.t, &o.out)?;
            timings.write += tw.elapsed().as_secs_f64();
            timings.read += o.read;
            timings.blend += o.blend;
            timings.factor += o.factor;
            timings.position += o.position;
            timings.metrics += o.metrics;
            for (k, s) in o.passes.iter().enumerate() {
                timings.stretch_passes[k] += s;
            }
            for (k, (acc, st)) in o.stretch.iter().enumerate() {
                seq_stretch[k].merge(acc);
                frame_stretch[o.t].push(*st);
            }
            frame_lost_share[o.t] = o.lost_share;
            frame_relief_share[o.t] = o.relief_share;
            if keep.contains(&o.t) {
                kept.frames.push((o.t, o.rest, o.out));
            }
        }
        let Some(solved) = solved else {
            break;
        };
        let (field, stats) = solved?;
        timings.weights += stats.seconds;
        window_stats.push(stats);
        progress.advance("weights", 1);
        let t_fade = Instant::now();
        ready = fade.push(&field);
        drop(field);
        timings.blend += t_fade.elapsed().as_secs_f64();
    }
    progress.end("weights");
    progress.end("position");
    timings.wall = wall.elapsed().as_secs_f64();
    kept.frames.sort_by_key(|f| f.0);
    let report = DeformReport {
        params: params.clone(),
        frames: n,
        vertices: topo.n_vertices(),
        triangles: topo.n_triangles(),
        anchors: anchors.total(),
        windows: window_stats,
        stretch: seq_stretch.iter().map(|a| a.stats()).collect(),
        frame_stretch,
        frame_lost_share,
        frame_relief_share,
        timings,
    };
    Ok((report, kept))
}
