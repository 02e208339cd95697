//! Fidelity of a result against ground truth (docs/fidelity.md): how well the folds put back into a captured sequence
//! agree with the folds a real cloth simulator made.
//!
//! Three sequences with the same frames take part: the **input** (the "captured" sequence, folds smoothed
//! away), the **ground truth** (the simulation with folds, same connectivity as the input) and the **output**
//! (crease's result; it may be subdivided, in which case its first vertices are the input's, in order). The
//! *fold signal* of a vertex in a frame is the angle between its area-weighted normal in a sequence and in the
//! input: s for the output, s_gt for the ground truth. Normals rather than positions, because a fold is a
//! change of orientation that positions barely show and that shading (what people see) shows fully.
//!
//! Reported over all vertices and frames: the Pearson correlation of s and s_gt; Cohen's κ between the fold
//! regions {s > τ} and {s_gt > τ} (τ = 10° by default; κ corrects the raw agreement for chance, which matters
//! because most of a garment is fold-free); the mean angle between output and ground-truth normals next to the
//! input's; the IoU of the fold regions after a one-ring dilation (forgiving one-triangle misplacements, but
//! generous to noise: secondary); and temporal popping, the mean frame-to-frame change of s relative to that of
//! s_gt. The captured baseline (s = 0 everywhere) is reported beside every figure.
//!
//! Beside the folds, whether the shape was kept ([`crate::shape`]): displacement, low-frequency drift and extent
//! change of the output against the input, next to the same figures of the ground truth against the input.
//!
//! And stretch, of the output and of the ground truth: edge tension against the least-compressed captured edge
//! lengths ([`crate::rest_stretch`], the cloth's rest state as far as the input shows it), and the per-triangle
//! stretch against the captured triangle of the same frame ([`crate::metrics`], what `report.json`'s
//! `stretch` lists; on captured data it measures the capture's smoothing as much as stretch).

use crate::mesh::{geometry, FrameSource, Topology};
use crate::metrics::{StretchAccumulator, StretchStats};
use crate::progress::Progress;
use crate::render::{caption, grid, render, stretch_color, Camera, Style};
use crate::rest_stretch::{RestLengths, RestStretchAccumulator, RestStretchStats};
use crate::shape::{ShapeAccumulator, ShapeStats, TaubinFilter};
use crate::vec3::{self, V3};
use crate::{Error, Result};
use image::RgbImage;
use rayon::prelude::*;
use serde::Serialize;

/// `crease eval`'s drift ruler: Taubin's λ|μ low-pass (λ 0.5, μ −0.53, 40 iterations of one λ and one μ step,
/// uniform weights, a rim smoothed along itself). A fixed ruler, the same for every run, so drift figures
/// compare across results and settings; it is not what crease keeps the shape with (its own low-pass is the heat
/// kernel of [`crate::heat`]), and nothing in a run depends on it.
pub fn drift_ruler(topo: &Topology) -> TaubinFilter {
    TaubinFilter::new(topo, 0.5, -0.53, 80)
}

/// Evaluation settings.
#[derive(Debug, Clone, Copy)]
pub struct EvalParams {
    /// Fold-region threshold τ on the fold signal, in degrees.
    pub threshold_deg: f64,
}

impl Default for EvalParams {
    fn default() -> Self {
        EvalParams {
            threshold_deg: 10.0,
        }
    }
}

impl EvalParams {
    pub fn validate(&self) -> Result<()> {
        if !(self.threshold_deg > 0.0 && self.threshold_deg < 180.0) {
            return Err(Error::param(
                "threshold",
                format!(
                    "must be an angle in (0°, 180°), got {}°",
                    self.threshold_deg
                ),
            ));
        }
        Ok(())
    }
}

/// Pearson correlation accumulated with centred co-moments (Welford/Chan), so that chunks of frames can be
/// summed in any grouping without the cancellation of raw sums of squares.
#[derive(Debug, Clone, Copy, Default)]
pub struct Pearson {
    n: f64,
    mean_x: f64,
    mean_y: f64,
    m_xx: f64,
    m_yy: f64,
    m_xy: f64,
}

impl Pearson {
    pub fn push(&mut self, x: f64, y: f64) {
        self.n += 1.0;
        let dx = x - self.mean_x;
        self.mean_x += dx / self.n;
        let dy = y - self.mean_y;
        self.mean_y += dy / self.n;
        self.m_xx += dx * (x - self.mean_x);
        self.m_yy += dy * (y - self.mean_y);
        self.m_xy += dx * (y - self.mean_y);
    }

    pub fn merge(&mut self, o: &Pearson) {
        if o.n == 0.0 {
            return;
        }
        if self.n == 0.0 {
            *self = *o;
            return;
        }
        let n = self.n + o.n;
        let dx = o.mean_x - self.mean_x;
        let dy = o.mean_y - self.mean_y;
        let f = self.n * o.n / n;
        self.m_xx += o.m_xx + dx * dx * f;
        self.m_yy += o.m_yy + dy * dy * f;
        self.m_xy += o.m_xy + dx * dy * f;
        self.mean_x += dx * o.n / n;
        self.mean_y += dy * o.n / n;
        self.n = n;
    }

    /// None when either variable is constant (e.g. the captured baseline, s = 0 everywhere).
    pub fn correlation(&self) -> Option<f64> {
        let d = (self.m_xx * self.m_yy).sqrt();
        (d > 0.0 && d.is_finite()).then(|| (self.m_xy / d).clamp(-1.0, 1.0))
    }
}

/// 2x2 agreement table of two binary labellings: `both`, `only_a`, `only_b`, `neither`.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Agreement {
    pub both: u64,
    pub only_a: u64,
    pub only_b: u64,
    pub neither: u64,
}

impl Agreement {
    pub fn push(&mut self, a: bool, b: bool) {
        match (a, b) {
            (true, true) => self.both += 1,
            (true, false) => self.only_a += 1,
            (false, true) => self.only_b += 1,
            (false, false) => self.neither += 1,
        }
    }

    pub fn merge(&mut self, o: &Agreement) {
        self.both += o.both;
        self.only_a += o.only_a;
        self.only_b += o.only_b;
        self.neither += o.neither;
    }

    fn total(&self) -> f64 {
        (self.both + self.only_a + self.only_b + self.neither) as f64
    }

    /// Cohen's κ = (p_o − p_e) / (1 − p_e). None when chance agreement is already perfect (both labellings
    /// constant and equal), where κ is undefined.
    pub fn kappa(&self) -> Option<f64> {
        let n = self.total();
        if n == 0.0 {
            return None;
        }
        let p_o = (self.both + self.neither) as f64 / n;
        let a1 = (self.both + self.only_a) as f64 / n;
        let b1 = (self.both + self.only_b) as f64 / n;
        let p_e = a1 * b1 + (1.0 - a1) * (1.0 - b1);
        (1.0 - p_e > 1e-15).then(|| (p_o - p_e) / (1.0 - p_e))
    }

    /// |A ∩ B| / |A ∪ B|; None when both are empty.
    pub fn iou(&self) -> Option<f64> {
        let u = self.both + self.only_a + self.only_b;
        (u > 0).then(|| self.both as f64 / u as f64)
    }
}

/// Angle in radians between two directions, accurate near 0 and π (atan2 of sine and cosine); 0 when either
/// is the zero vector (an isolated vertex has no normal).
fn angle(a: V3, b: V3) -> f64 {
    vec3::norm(vec3::cross(a, b)).atan2(vec3::dot(a, b))
}

/// Per-frame figures.
#[derive(Debug, Clone, Serialize)]
pub struct FrameEval {
    pub frame: usize,
    pub correlation: Option<f64>,
    pub kappa: Option<f64>,
    pub iou_dilated: Option<f64>,
    /// Mean angle (degrees) between output and ground-truth normals.
    pub normal_error_deg: f64,
    /// The same for the input (captured) sequence.
    pub captured_normal_error_deg: f64,
    /// Fraction of vertices in the output's and the ground truth's fold regions.
    pub fold_fraction: f64,
    pub gt_fold_fraction: f64,
}

/// Figures for one sequence (the output, or the captured baseline).
#[derive(Debug, Clone, Serialize)]
pub struct Figures {
    pub correlation: Option<f64>,
    pub kappa: Option<f64>,
    pub iou_dilated: Option<f64>,
    pub normal_error_deg: f64,
    /// Mean |s(t) − s(t−1)| divided by the same for s_gt; None with a single frame or a static ground truth.
    pub popping: Option<f64>,
    pub fold_fraction: f64,
}

/// "Shape kept" figures (docs/fidelity.md) of the output and of the ground truth, both against the input.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ShapeComparison {
    pub output: ShapeStats,
    pub ground_truth: ShapeStats,
}

/// Stretch figures of the output and of the ground truth, each under the reference it is measured against.
#[derive(Debug, Clone, Serialize)]
pub struct StretchComparison {
    /// How the rest lengths of `vs_rest` are obtained ([`crate::rest_stretch::REFERENCE`]).
    pub rest_reference: &'static str,
    /// Edge tension against the least-compressed captured edge lengths: (output, ground truth).
    pub vs_rest: StretchPair<RestStretchStats>,
    /// Per-triangle stretch max(σ₁ − 1, 1 − σ₂) against the captured triangle of the same frame; the output's
    /// is None when it does not have the input's triangles (a subdivided result).
    pub vs_captured_frame: StretchPair<Option<StretchStats>>,
}

/// A stretch figure of the output beside the ground truth's.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct StretchPair<T> {
    pub output: T,
    pub ground_truth: T,
}

/// The whole evaluation.
#[derive(Debug, Clone, Serialize)]
pub struct EvalReport {
    pub frames: usize,
    pub vertices: usize,
    pub threshold_deg: f64,
    pub gt_fold_fraction: f64,
    pub output: Figures,
    pub captured_baseline: Figures,
    pub shape: ShapeComparison,
    pub stretch: StretchComparison,
    pub per_frame: Vec<FrameEval>,
}

/// Fold signals of one frame, kept for pictures.
#[derive(Debug, Clone)]
pub struct FrameSignal {
    pub frame: usize,
    pub input: Vec<V3>,
    pub s: Vec<f32>,
    pub s_gt: Vec<f32>,
}

struct FrameResult {
    eval: FrameEval,
    pearson: Pearson,
    regions: Agreement,
    dilated: Agreement,
    normal_error_sum: f64,
    captured_error_sum: f64,
    shape_out: ShapeAccumulator,
    shape_gt: ShapeAccumulator,
    rest_out: RestStretchAccumulator,
    rest_gt: RestStretchAccumulator,
    frame_out: Option<StretchAccumulator>,
    frame_gt: StretchAccumulator,
    s: Vec<f32>,
    s_gt: Vec<f32>,
    input: Vec<V3>,
}

/// Checks that the three sequences can be compared and names the one that cannot.
fn check_shapes(
    output: &dyn FrameSource,
    gt: &dyn FrameSource,
    input: &dyn FrameSource,
) -> Result<()> {
    let (ti, tg, to) = (input.topology(), gt.topology(), output.topology());
    let mismatch = |what: &str, msg: String| Error::param(what, msg);
    if gt.n_frames() != input.n_frames() {
        return Err(mismatch(
            "gt",
            format!(
                "{} frames, but the input has {}",
                gt.n_frames(),
                input.n_frames()
            ),
        ));
    }
    if output.n_frames() != input.n_frames() {
        return Err(mismatch(
            "output",
            format!(
                "{} frames, but the input has {}",
                output.n_frames(),
                input.n_frames()
            ),
        ));
    }
    if tg.n_vertices() != ti.n_vertices() || tg.triangles() != ti.triangles() {
        return Err(mismatch(
            "gt",
            format!(
                "its mesh ({} vertices, {} triangles) is not the input's ({} vertices, {} triangles, same \
                 triangle list required)",
                tg.n_vertices(),
                tg.n_triangles(),
                ti.n_vertices(),
                ti.n_triangles()
            ),
        ));
    }
    if to.n_vertices() < ti.n_vertices() {
        return Err(mismatch(
            "output",
            format!(
                "{} vertices, fewer than the input's {} (a subdivided output keeps the input's vertices first)",
                to.n_vertices(),
                ti.n_vertices()
            ),
        ));
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn evaluate_frame(
    t: usize,
    topo: &Topology,
    filter: &TaubinFilter,
    rest: &RestLengths,
    output: &dyn FrameSource,
    gt: &dyn FrameSource,
    input: &dyn FrameSource,
    threshold: f64,
) -> Result<FrameResult> {
    let p_in = input.read_frame(t)?;
    let p_gt = gt.read_frame(t)?;
    let p_out = output.read_frame(t)?;
    let n = topo.n_vertices();
    let n_in = geometry::vertex_normals(topo, &p_in);
    let n_gt = geometry::vertex_normals(topo, &p_gt);
    let n_out = geometry::vertex_normals(output.topology(), &p_out);
    let mut s = Vec::with_capacity(n);
    let mut s_gt = Vec::with_capacity(n);
    let (mut pearson, mut regions) = (Pearson::default(), Agreement::default());
    let (mut err_out, mut err_in) = (0.0, 0.0);
    let (mut in_r, mut in_rgt) = (vec![false; n], vec![false; n]);
    for v in 0..n {
        let a = angle(n_out[v], n_in[v]).to_degrees();
        let b = angle(n_gt[v], n_in[v]).to_degrees();
        pearson.push(a, b);
        in_r[v] = a > threshold;
        in_rgt[v] = b > threshold;
        regions.push(in_r[v], in_rgt[v]);
        err_out += angle(n_out[v], n_gt[v]).to_degrees();
        err_in += angle(n_in[v], n_gt[v]).to_degrees();
        s.push(a as f32);
        s_gt.push(b as f32);
    }
    let dilate = |r: &[bool]| -> Vec<bool> {
        let mut d = r.to_vec();
        for tri in topo.triangles() {
            if tri.iter().any(|&v| r[v as usize]) {
                for &v in tri {
                    d[v as usize] = true;
                }
            }
        }
        d
    };
    let (d_r, d_gt) = (dilate(&in_r), dilate(&in_rgt));
    let mut shape_out = ShapeAccumulator::default();
    shape_out.add_frame(topo, &|d: &[V3]| filter.apply(d), &p_in, &p_out);
    let mut shape_gt = ShapeAccumulator::default();
    shape_gt.add_frame(topo, &|d: &[V3]| filter.apply(d), &p_in, &p_gt);
    let mut dilated = Agreement::default();
    for v in 0..n {
        dilated.push(d_r[v], d_gt[v]);
    }
    let (mut rest_out, mut rest_gt) = (
        RestStretchAccumulator::default(),
        RestStretchAccumulator::default(),
    );
    rest_out.add_frame(rest, &p_out);
    rest_gt.add_frame(rest, &p_gt);
    let mut frame_gt = StretchAccumulator::default();
    frame_gt.add_frame(topo, &p_in, &p_gt);
    let frame_out = (output.topology().triangles() == topo.triangles()).then(|| {
        let mut acc = StretchAccumulator::default();
        acc.add_frame(topo, &p_in, &p_out);
        acc
    });
    let nf = n.max(1) as f64;
    let eval = FrameEval {
        frame: t,
        correlation: pearson.correlation(),
        kappa: regions.kappa(),
        iou_dilated: dilated.iou(),
        normal_error_deg: err_out / nf,
        captured_normal_error_deg: err_in / nf,
        fold_fraction: (regions.both + regions.only_a) as f64 / nf,
        gt_fold_fraction: (regions.both + regions.only_b) as f64 / nf,
    };
    Ok(FrameResult {
        eval,
        pearson,
        regions,
        dilated,
        normal_error_sum: err_out,
        captured_error_sum: err_in,
        shape_out,
        shape_gt,
        rest_out,
        rest_gt,
        frame_out,
        frame_gt,
        s,
        s_gt,
        input: p_in,
    })
}

/// Evaluates `output` against `gt`, both relative to `input`. Frames are read in parallel chunks, so memory is
/// a few frames, not the sequence. Returns the report and the fold signals of the frames listed in `keep`.
pub fn evaluate(
    output: &dyn FrameSource,
    gt: &dyn FrameSource,
    input: &dyn FrameSource,
    params: &EvalParams,
    keep: &[usize],
    progress: &dyn Progress,
) -> Result<(EvalReport, Vec<FrameSignal>)> {
    params.validate()?;
    check_shapes(output, gt, input)?;
    let topo = input.topology().clone();
    let n_frames = input.n_frames();
    let n = topo.n_vertices();
    let chunk = (2 * rayon::current_num_threads()).max(1);
    let (mut pearson, mut regions, mut dilated) = (
        Pearson::default(),
        Agreement::default(),
        Agreement::default(),
    );
    let (mut err_out, mut err_in) = (0.0, 0.0);
    let filter = drift_ruler(&topo);
    let (mut shape_out, mut shape_gt) = (ShapeAccumulator::default(), ShapeAccumulator::default());
    // The rest lengths need the whole input before any frame is measured: one more read of it.
    let rest = RestLengths::of_sequence(input)?;
    let (mut rest_out, mut rest_gt) = (
        RestStretchAccumulator::default(),
        RestStretchAccumulator::default(),
    );
    let mut frame_out =
        (output.topology().triangles() == topo.triangles()).then(StretchAccumulator::default);
    let mut frame_gt = StretchAccumulator::default();
    let (mut pop, mut pop_gt) = (0.0f64, 0.0f64);
    let mut prev: Option<(Vec<f32>, Vec<f32>)> = None;
    let mut per_frame = Vec::with_capacity(n_frames);
    let mut kept = Vec::new();
    progress.begin("eval", n_frames as u64);
    for start in (0..n_frames).step_by(chunk) {
        if progress.cancelled() {
            return Err(Error::Cancelled);
        }
        let end = (start + chunk).min(n_frames);
        let results: Vec<FrameResult> = (start..end)
            .into_par_iter()
            .map(|t| {
                evaluate_frame(
                    t,
                    &topo,
                    &filter,
                    &rest,
                    output,
                    gt,
                    input,
                    params.threshold_deg,
                )
            })
            .collect::<Result<_>>()?;
        for r in results {
            pearson.merge(&r.pearson);
            regions.merge(&r.regions);
            dilated.merge(&r.dilated);
            err_out += r.normal_error_sum;
            err_in += r.captured_error_sum;
            shape_out.merge(&r.shape_out);
            shape_gt.merge(&r.shape_gt);
            rest_out.merge(&r.rest_out);
            rest_gt.merge(&r.rest_gt);
            frame_gt.merge(&r.frame_gt);
            if let (Some(acc), Some(f)) = (frame_out.as_mut(), &r.frame_out) {
                acc.merge(f);
            }
            if let Some((ps, pg)) = &prev {
                for v in 0..n {
                    pop += (r.s[v] - ps[v]).abs() as f64;
                    pop_gt += (r.s_gt[v] - pg[v]).abs() as f64;
                }
            }
            let t = r.eval.frame;
            per_frame.push(r.eval);
            if keep.contains(&t) {
                kept.push(FrameSignal {
                    frame: t,
                    input: r.input,
                    s: r.s.clone(),
                    s_gt: r.s_gt.clone(),
                });
            }
            prev = Some((r.s, r.s_gt));
        }
        progress.advance("eval", (end - start) as u64);
    }
    progress.end("eval");
    let samples = (n * n_frames).max(1) as f64;
    let gt_fold_fraction = (regions.both + regions.only_b) as f64 / samples;
    let popping = (pop_gt > 0.0).then(|| pop / pop_gt);
    let output_figures = Figures {
        correlation: pearson.correlation(),
        kappa: regions.kappa(),
        iou_dilated: dilated.iou(),
        normal_error_deg: err_out / samples,
        popping,
        fold_fraction: (regions.both + regions.only_a) as f64 / samples,
    };
    // s = 0 everywhere: no fold region (κ 0 by definition of chance agreement, IoU 0 whenever the ground truth
    // has folds), no popping, and the captured normals' own error.
    let baseline = Figures {
        correlation: None,
        kappa: Some(0.0),
        iou_dilated: Some(0.0),
        normal_error_deg: err_in / samples,
        popping: (pop_gt > 0.0).then_some(0.0),
        fold_fraction: 0.0,
    };
    Ok((
        EvalReport {
            frames: n_frames,
            vertices: n,
            threshold_deg: params.threshold_deg,
            gt_fold_fraction,
            output: output_figures,
            captured_baseline: baseline,
            shape: ShapeComparison {
                output: shape_out.stats(),
                ground_truth: shape_gt.stats(),
            },
            stretch: StretchComparison {
                rest_reference: crate::rest_stretch::REFERENCE,
                vs_rest: StretchPair {
                    output: rest_out.stats(),
                    ground_truth: rest_gt.stats(),
                },
                vs_captured_frame: StretchPair {
                    output: frame_out.map(|a| a.stats()),
                    ground_truth: Some(frame_gt.stats()),
                },
            },
            per_frame,
        },
        kept,
    ))
}

/// Pictures of the fold signals: per kept frame, the ground truth's and the output's fold signal painted on the
/// input mesh (0 to `max_deg`, same ramp as stretch), so misplaced, missing and invented folds show at a glance.
pub fn signal_picture(topo: &Topology, kept: &[FrameSignal], size: u32, max_deg: f64) -> RgbImage {
    const WHITE: [u8; 3] = [255, 255, 255];
    const INK: [u8; 3] = [20, 20, 20];
    let scale = (size / 256).max(1);
    let tri_colors = |s: &[f32]| -> Vec<[u8; 3]> {
        topo.triangles()
            .iter()
            .map(|t| {
                let m = t.iter().map(|&v| s[v as usize] as f64).sum::<f64>() / 3.0;
                stretch_color(m, max_deg)
            })
            .collect()
    };
    let rows: Vec<Vec<RgbImage>> = kept
        .iter()
        .map(|k| {
            let (lo, hi) = geometry::bounding_box(&k.input);
            let folded: Vec<u32> = topo
                .triangles()
                .iter()
                .enumerate()
                .filter(|(_, t)| t.iter().any(|&v| k.s_gt[v as usize] as f64 > max_deg / 3.0))
                .map(|(i, _)| i as u32)
                .collect();
            let focus = crate::preview::fold_focus(topo, &k.input, folded.into_iter());
            let (dir, up) = crate::view::view_for(&k.input, focus);
            let cam = Camera::fit(lo, hi, dir, up, size, size);
            let gt_colors = tri_colors(&k.s_gt);
            let out_colors = tri_colors(&k.s);
            let paint = |c: &[[u8; 3]]| {
                render(
                    &k.input,
                    topo,
                    &cam,
                    &Style {
                        triangle_colors: Some(c),
                        ..Style::default()
                    },
                )
            };
            vec![
                caption(
                    &paint(&gt_colors),
                    &format!("FRAME {} GROUND TRUTH FOLDS", k.frame),
                    scale,
                    INK,
                    WHITE,
                ),
                caption(
                    &paint(&out_colors),
                    &format!("OUTPUT FOLDS 0-{max_deg:.0} DEG"),
                    scale,
                    INK,
                    WHITE,
                ),
            ]
        })
        .collect();
    grid(&rows, 6, WHITE)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Sequence;
    use crate::synth;

    #[test]
    fn pearson_matches_two_pass_formula_and_merges() {
        let xs: Vec<f64> = (0..200)
            .map(|i| ((i * 37) % 101) as f64 * 0.3 + 1e6)
            .collect();
        let ys: Vec<f64> = xs
            .iter()
            .enumerate()
            .map(|(i, x)| 2.0 * x + ((i * 13) % 7) as f64)
            .collect();
        let (mx, my) = (
            xs.iter().sum::<f64>() / 200.0,
            ys.iter().sum::<f64>() / 200.0,
        );
        let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
        for (x, y) in xs.iter().zip(&ys) {
            sxy += (x - mx) * (y - my);
            sxx += (x - mx) * (x - mx);
            syy += (y - my) * (y - my);
        }
        let exact = sxy / (sxx * syy).sqrt();
        let (mut a, mut b) = (Pearson::default(), Pearson::default());
        for i in 0..200 {
            if i % 3 == 0 {
                a.push(xs[i], ys[i]);
            } else {
                b.push(xs[i], ys[i]);
            }
        }
        a.merge(&b);
        assert!((a.correlation().unwrap() - exact).abs() < 1e-9);
        assert!(Pearson::default().correlation().is_none());
    }

    #[test]
    fn kappa_is_one_for_identity_zero_for_independence() {
        let mut same = Agreement::default();
        let mut indep = Agreement::default();
        for i in 0..1000 {
            same.push(i % 3 == 0, i % 3 == 0);
            indep.push(i % 2 == 0, (i / 2) % 2 == 0);
        }
        assert!((same.kappa().unwrap() - 1.0).abs() < 1e-12);
        assert!(indep.kappa().unwrap().abs() < 1e-9);
        // Output with no fold region against a ground truth with some: no better than chance.
        let mut none = Agreement::default();
        for i in 0..100 {
            none.push(false, i % 4 == 0);
        }
        assert!(none.kappa().unwrap().abs() < 1e-12);
        assert_eq!(none.iou(), Some(0.0));
    }

    fn bumpy(base: &Sequence, amp: f64) -> Sequence {
        let frames = base
            .frames
            .iter()
            .enumerate()
            .map(|(t, f)| {
                f.iter()
                    .map(|p| {
                        let z = amp * ((p[0] * 25.0 + t as f64 * 0.4).sin());
                        [p[0], p[1], p[2] + z]
                    })
                    .collect()
            })
            .collect();
        Sequence::new(base.topology.clone(), frames).unwrap()
    }

    fn flat(frames: usize) -> Sequence {
        let (topo, f) = synth::sheet(30, 20, 0.02).unwrap();
        Sequence::new(topo, vec![f; frames]).unwrap()
    }

    #[test]
    fn ground_truth_against_itself_is_perfect_and_input_is_baseline() {
        let input = flat(3);
        let gt = bumpy(&input, 0.02);
        let (r, kept) = evaluate(
            &gt,
            &gt,
            &input,
            &EvalParams::default(),
            &[1],
            &crate::progress::NoProgress,
        )
        .unwrap();
        assert!((r.output.correlation.unwrap() - 1.0).abs() < 1e-9);
        assert!((r.output.kappa.unwrap() - 1.0).abs() < 1e-12);
        assert_eq!(r.output.iou_dilated, Some(1.0));
        assert!(r.output.normal_error_deg < 1e-9);
        assert!((r.output.popping.unwrap() - 1.0).abs() < 1e-9);
        assert!(
            r.gt_fold_fraction > 0.1,
            "test bumps too weak: {}",
            r.gt_fold_fraction
        );
        assert!(r.captured_baseline.normal_error_deg > 5.0);
        // The ground truth compared with itself: identical shape figures on both sides.
        assert_eq!(r.shape.output, r.shape.ground_truth);
        assert!(r.shape.output.displacement_max > 0.0);
        assert_eq!(kept.len(), 1);
        assert_eq!(kept[0].frame, 1);

        // The input evaluated as an output is exactly the baseline.
        let (b, _) = evaluate(
            &input,
            &gt,
            &input,
            &EvalParams::default(),
            &[],
            &crate::progress::NoProgress,
        )
        .unwrap();
        assert!(b.output.correlation.is_none());
        assert!(b.output.kappa.unwrap().abs() < 1e-12);
        assert_eq!(b.output.iou_dilated, Some(0.0));
        assert!((b.output.normal_error_deg - b.captured_baseline.normal_error_deg).abs() < 1e-9);
        // The input has not moved at all.
        assert_eq!(b.shape.output.displacement_max, 0.0);
        assert_eq!(b.shape.output.extent_change, 0.0);
    }

    /// A capture that flattened a fold region (the sheet compressed along x in the first frames, released
    /// later): an output that gives the length back everywhere measures no tension against the least-compressed
    /// captured lengths, but 25% per-triangle stretch against the same captured frame.
    #[test]
    fn stretch_against_rest_lengths_forgives_a_released_capture() {
        let (topo, sheet) = synth::sheet(30, 20, 0.02).unwrap();
        let squeeze =
            |f: f64| -> Vec<V3> { sheet.iter().map(|q| [f * q[0], q[1], q[2]]).collect() };
        let input = Sequence::new(topo.clone(), [0.8, 0.9, 1.0].map(squeeze).into()).unwrap();
        let released = Sequence::new(topo, vec![sheet.clone(); 3]).unwrap();
        let (r, _) = evaluate(
            &released,
            &released,
            &input,
            &EvalParams::default(),
            &[],
            &crate::progress::NoProgress,
        )
        .unwrap();
        let st = &r.stretch;
        assert_eq!(st.rest_reference, crate::rest_stretch::REFERENCE);
        assert!(st.vs_rest.output.max < 1e-12, "{:?}", st.vs_rest);
        assert_eq!(st.vs_rest.output.p99, 0.0);
        let same = st.vs_captured_frame.output.unwrap();
        assert!((same.max - 0.25).abs() < 1e-9, "{same:?}");
        assert!(same.p99 > 0.1, "{same:?}");
        // Stretching the released sheet by 5% along x is tension against the rest lengths.
        let pulled = Sequence::new(
            released.topology.clone(),
            vec![sheet.iter().map(|q| [1.05 * q[0], q[1], q[2]]).collect(); 3],
        )
        .unwrap();
        let (r, _) = evaluate(
            &pulled,
            &released,
            &input,
            &EvalParams::default(),
            &[],
            &crate::progress::NoProgress,
        )
        .unwrap();
        let v = r.stretch.vs_rest;
        assert!((v.output.max - 0.05).abs() < 1e-9, "{v:?}");
        assert!(v.output.p99 > 0.04, "{v:?}");
        assert!(v.ground_truth.max < 1e-12, "{v:?}");
    }

    #[test]
    fn half_amplitude_folds_correlate_but_score_lower_than_exact() {
        let input = flat(3);
        let gt = bumpy(&input, 0.02);
        let half = bumpy(&input, 0.01);
        let (r, _) = evaluate(
            &half,
            &gt,
            &input,
            &EvalParams::default(),
            &[],
            &crate::progress::NoProgress,
        )
        .unwrap();
        assert!(r.output.correlation.unwrap() > 0.9);
        assert!(r.output.kappa.unwrap() < 1.0);
        assert!(r.output.normal_error_deg > 0.0);
        assert!(r.output.normal_error_deg < r.captured_baseline.normal_error_deg);
    }

    #[test]
    fn mismatched_sequences_are_named() {
        let input = flat(3);
        let short = flat(2);
        let e = evaluate(
            &input,
            &short,
            &input,
            &EvalParams::default(),
            &[],
            &crate::progress::NoProgress,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("gt") && e.contains("2 frames"), "{e}");
        let e = evaluate(
            &short,
            &input,
            &input,
            &EvalParams::default(),
            &[],
            &crate::progress::NoProgress,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("output"), "{e}");
        let bad = EvalParams {
            threshold_deg: -1.0,
        };
        let e = evaluate(
            &input,
            &input,
            &input,
            &bad,
            &[],
            &crate::progress::NoProgress,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("threshold"), "{e}");
    }
}
