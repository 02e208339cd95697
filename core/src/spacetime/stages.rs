//! The deformation as separately callable stages, so the single-machine driver ([`super::deform`]) and a cluster
//! of workers run the very same arithmetic (one implementation, bit-identical results):
//!
//! 1. **weights** of one window and 2. their **reduce** — in [`super::weights`]: fused, one solve with three
//!    right-hand sides; per-anchor, one solve per anchor-column block, the blocks' partial blends summed in
//!    block order;
//! 3. **cross-fade** of the windows covering a frame — [`crossfade_frame`] (Popa et al. 2009 §5.3);
//! 4. **positioning + stretch reduction** of one frame — [`position_frame`] (§5.4, §5.5).
//!
//! Every stage is a pure function of its inputs: where a stage runs (which thread, which machine, how many
//! times) cannot change its output bits, provided the callers sum blocks in block order and windows in window
//! order, as these functions do.

use super::blend::{self, fade_into};
use super::position::strain_limit::StrainLimiter;
use super::position::stretch::StretchRotation;
use super::position::PositionSystem;
use super::shape::lost_area::RestAreas;
use super::shape::ShapeEnding;
use super::windows::{crossfade_weight, Window};
use crate::error::{Error, Result};
use crate::mesh::seams::Seams;
use crate::mesh::{Frame, FrameSource};
use crate::metrics::{RestTriangles, StretchAccumulator, StretchStats};
use crate::vec3::V3;
use std::time::Instant;

/// The cross-faded rotation-vector field of frame `t`: Σ_k a_k(t) X_k(t) over the windows k covering `t`, in
/// window order, starting from zero, with a_k the normalised tent weights of [`crossfade_weight`].
/// `frame_of_window(k)` returns window k's field restricted to frame `t` (`n_tri` vectors).
pub fn crossfade_frame<'a>(
    windows: &[Window],
    t: usize,
    n_tri: usize,
    mut frame_of_window: impl FnMut(usize) -> Result<&'a [V3]>,
) -> Result<Vec<V3>> {
    let mut acc = vec![[0.0; 3]; n_tri];
    for (k, w) in windows.iter().enumerate() {
        if t < w.start || t >= w.end() {
            continue;
        }
        let src = frame_of_window(k)?;
        if src.len() != n_tri {
            return Err(Error::param(
                "window field",
                format!(
                    "window {k} gives {} vectors for frame {t}, expected {n_tri}",
                    src.len()
                ),
            ));
        }
        fade_into(&mut acc, crossfade_weight(windows, k, t), src);
    }
    Ok(acc)
}

/// Indices of the windows covering frame `t`.
pub fn windows_covering(windows: &[Window], t: usize) -> Vec<usize> {
    (0..windows.len())
        .filter(|&k| windows[k].start <= t && t < windows[k].end())
        .collect()
}

/// A last step of a finished frame from evidence beyond the mesh (the shading refinement reads the frame's
/// images, [`crate::shading_refine::ImageRefiner`]). It sees frame `t`'s finished shape, and what the frame's
/// fold relief gives back of the surface its capture lost where that was measured (`trace`), and returns the
/// shape to keep; it must be a pure function of its inputs so that wherever a frame is positioned it comes out
/// the same.
pub trait FrameRefiner: Sync {
    fn refine(
        &self,
        topo: &crate::mesh::Topology,
        t: usize,
        positions: &[V3],
        trace: Option<&super::shape::lost_area::Trace>,
    ) -> Result<Vec<V3>>;
}

/// One frame positioned and stretch-reduced, with its stretch after each step and the seconds each step took.
pub struct PositionedFrame {
    pub t: usize,
    /// The original (captured) geometry.
    pub rest: Frame,
    /// The output geometry.
    pub out: Frame,
    /// Stretch after positioning (index 0) and after each pass, as accumulators (for exact sequence totals) and
    /// as the frame's own figures.
    pub stretch: Vec<(StretchAccumulator, StretchStats)>,
    pub read: f64,
    pub blend: f64,
    pub factor: f64,
    pub position: f64,
    pub passes: Vec<f64>,
    pub metrics: f64,
    /// The share of the surface the frame's deformation added that the capture had lost (the lost-area bound's
    /// judgement of the frame, [`super::shape::lost_area::trust`]); `None` where the bound did not run (no bound,
    /// or nothing changed the frame).
    pub lost_share: Option<f64>,
    /// The share of the surface the capture lost that the fold relief gives back
    /// ([`super::shape::lost_area::Trace::share`]); `None` without the bound or the relief, or where the frame lost
    /// nothing.
    pub relief_share: Option<f64>,
}

/// Positions frame `t` of `source` from its cross-faded rotation-vector field `phi` (Alexa blend, gradient-
/// domain solve), then runs `passes` stretch-reduction passes reusing the frame's factorisation, measuring
/// stretch after each step, and ends with `ending`: the shape projection and the fold relief `heights`
/// ([`super::shape`]), the `refiner` (the shading refinement of video jobs), the bound of what all that adds to
/// the surface the capture lost (`lost_area`,
/// [`super::shape::lost_area`]), then the strain limit (`limit`, [`super::position::strain_limit`]), and closes the
/// capture's unwelded seams ([`crate::mesh::seams`]); the last stretch figures are those of the finished frame.
#[allow(clippy::too_many_arguments)]
pub fn position_frame(
    system: &PositionSystem,
    source: &dyn FrameSource,
    t: usize,
    phi: &[V3],
    passes: usize,
    rotation: StretchRotation,
    ending: &ShapeEnding,
    heights: Option<&[f64]>,
    lost_area: Option<&RestAreas>,
    limit: Option<&StrainLimiter>,
    refiner: Option<&dyn FrameRefiner>,
) -> Result<PositionedFrame> {
    let clock = Instant::now();
    let rest = source.read_frame(t)?;
    let read = clock.elapsed().as_secs_f64();

    // What the relief gives back of the surface the capture lost (reported per frame); where it gives back
    // little, the screen lets go (`release_share`).
    let trace = match (lost_area, heights) {
        (Some(areas), Some(h)) => {
            let relieved = super::shape::relief::add_heights(system.topology(), &rest, &rest, h);
            areas.trace(system.topology(), &rest, &relieved)
        }
        _ => None,
    };
    let hold = trace.as_ref().and_then(|tr| tr.hold(ending.release_share));

    let clock = Instant::now();
    let fp = system
        .factor_frame_held(&rest, hold.as_deref())
        .map_err(|e| match e {
            Error::Numeric { stage, msg } => Error::numeric(
                stage,
                format!("frame {t} ({}): {msg}", source.describe_frame(t)),
            ),
            e => e.at(None, Some(t)),
        })?;
    let factor = clock.elapsed().as_secs_f64();

    let clock = Instant::now();
    let rotations = blend::rotations(phi);
    let blend = clock.elapsed().as_secs_f64();

    // A frame no anchor's weight reaches (every rotation vector exactly zero) stays exactly where it was
    // captured: the solve would give it back only up to round-off, and no anchors must give the input back
    // bit for bit.
    let still = phi.iter().all(|p| *p == [0.0; 3]);
    let clock = Instant::now();
    let mut out = if still {
        rest.clone()
    } else {
        fp.solve(&rotations)
    };
    let position = clock.elapsed().as_secs_f64();

    // The captured frame's triangles, which every stretch measurement below compares against, once.
    let clock = Instant::now();
    let rest_triangles = RestTriangles::new(system.topology(), &rest);
    let mut metrics = clock.elapsed().as_secs_f64();
    let mut stretch = Vec::with_capacity(passes + 1);
    let measure = |out: &Frame, metrics: &mut f64| {
        let clock = Instant::now();
        let mut acc = StretchAccumulator::default();
        acc.add_frame_with(system.topology(), &rest_triangles, out);
        let st = acc.stats();
        *metrics += clock.elapsed().as_secs_f64();
        (acc, st)
    };
    // A frame the positioning left in place has no stretch to reduce: a pass would only add round-off (the
    // closest rotation to an identity gradient is I up to rounding).
    let moved = !still && out != rest;
    // The relief applies to every frame it has heights for, moved or not; the projection only to a moved one.
    let relief = ending.is_active(heights);
    let changed = moved || relief || refiner.is_some();
    // The finished frame's last steps: the shape ending, then edges stretched past the cap are shortened (never
    // in a frame nothing changed).
    let finish = |out: Frame| -> Result<(Frame, Option<f64>)> {
        if !changed {
            return Ok((out, None));
        }
        let mut done = ending.finish(system.topology(), &rest, &out, heights, hold.as_deref());
        if let Some(r) = refiner {
            done = r.refine(system.topology(), t, &done, trace.as_ref())?;
        }
        let share = lost_area.and_then(|areas| areas.limit(system.topology(), &rest, &mut done));
        if let Some(l) = limit {
            l.apply(&rest, &mut done);
        }
        // Last: vertices the capture has at one point (a garment's unwelded seams) leave at one point.
        Seams::of_frame(system.topology(), &rest).close(&mut done);
        Ok((done, share))
    };
    let mut lost_share = None;
    if passes == 0 {
        (out, lost_share) = finish(out)?;
    }
    stretch.push(measure(&out, &mut metrics));
    let mut pass_times = Vec::with_capacity(passes);
    for k in 0..passes {
        let clock = Instant::now();
        if moved {
            out = super::position::stretch::pass(&fp, &out, rotation, &rotations);
        }
        if k + 1 == passes {
            (out, lost_share) = finish(out)?;
        }
        pass_times.push(clock.elapsed().as_secs_f64());
        stretch.push(measure(&out, &mut metrics));
    }
    drop(fp);
    Ok(PositionedFrame {
        t,
        rest,
        out,
        stretch,
        read,
        blend,
        factor,
        position,
        passes: pass_times,
        metrics,
        lost_share,
        relief_share: trace.as_ref().and_then(|tr| tr.share()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::NoProgress;
    use crate::spacetime::blend::CrossFade;
    use crate::spacetime::weights::per_anchor::{BlockWorkspace, PartialBlend};
    use crate::spacetime::weights::{
        anchor_block, anchor_blocks, fused_window_field, reduce_blocks, solve_window, WindowProblem,
    };
    use crate::spacetime::windows::plan_windows;
    use crate::spacetime::{DeformParams, WeightMode};
    use crate::synth::{demo, DemoSpec};

    fn bits(v: &[V3]) -> Vec<u64> {
        v.iter().flatten().map(|x| x.to_bits()).collect()
    }

    /// Stages called one by one (as cluster tasks call them) give the bits of the streaming driver's path.
    #[test]
    fn stages_reproduce_the_driver_bit_for_bit() {
        let (seq, anchors) = demo(&DemoSpec {
            triangles: 800,
            frames: 12,
            ..Default::default()
        })
        .unwrap();
        let topo = seq.topology.clone();
        let n_tri = topo.n_triangles();
        let params = DeformParams {
            window: 5,
            shift: 3,
            mode: WeightMode::PerAnchor,
            anchor_block: 7,
            ..Default::default()
        };
        let windows = plan_windows(12, params.window, params.shift);
        let mut fade = CrossFade::new(windows.clone(), n_tri);
        let mut streamed = Vec::new();
        let mut fields = Vec::new();
        for w in &windows {
            let problem = WindowProblem::new(&topo, &anchors, *w, params.coefficients);
            let (field, _) = solve_window(&problem, &params, &NoProgress).unwrap();
            // Per-anchor: blocks one by one, reduced in block order.
            let mut ws = BlockWorkspace::new(problem.op.n_nodes());
            let partials: Vec<PartialBlend> = anchor_blocks(&problem, &params)
                .into_iter()
                .map(|r| anchor_block(&problem, r, &params, &mut ws).unwrap())
                .collect();
            assert!(partials.len() > 1, "the test needs several blocks");
            let (reduced, _, _) = reduce_blocks(problem.op.n_nodes(), &partials).unwrap();
            assert_eq!(bits(&reduced), bits(&field));
            // Fused: the stage is the driver's solve.
            let fused = DeformParams {
                mode: WeightMode::Fused,
                ..params.clone()
            };
            let (f1, _) = fused_window_field(&problem, &fused).unwrap();
            let (f2, _) = solve_window(&problem, &fused, &NoProgress).unwrap();
            assert_eq!(bits(&f1), bits(&f2));
            streamed.extend(fade.push(&field));
            fields.push(field);
        }
        assert_eq!(streamed.len(), 12);
        for (t, phi) in streamed {
            let faded = crossfade_frame(&windows, t, n_tri, |k| {
                let lt = t - windows[k].start;
                Ok(&fields[k][lt * n_tri..(lt + 1) * n_tri])
            })
            .unwrap();
            assert_eq!(bits(&faded), bits(&phi), "frame {t}");
        }
        let err = anchor_block(
            &WindowProblem::new(&topo, &anchors, windows[0], params.coefficients),
            0..100_000,
            &params,
            &mut BlockWorkspace::new(1),
        )
        .err()
        .unwrap();
        assert!(err.to_string().contains("outside"), "{err}");
    }
}
