//! Mesh-space detail for captured input: the fine surface predicted from a capture of it, with no knowledge
//! of how the capture was made, and a guard that falls back to the capture's own normals where the model is
//! out of its depth.
//!
//! What is left of a fold in a capture is, where it survives at all, an attenuated and noisy copy of it at the
//! same place. So the fine shape is predicted as the coarse one plus a linear filter of it,
//! d = Σ_j w_j(s) T_j(P) Δc: P the cotangent averaging walk of the coarse surface ([`operator::Walk`]),
//! Δc = Pc − c, T_j Chebyshev polynomials. The weights depend linearly on a signature s of the input frame
//! ([`signature`]): how fast its detail falls off from one scale to the next. A gentle capture keeps much of
//! the short folds and wants a gentle sharpening; a harsh one keeps little and, if it is also noisy, wants
//! the short band suppressed rather than amplified; the signature tells them apart from the data alone. The
//! weights are fitted by ridge least squares on pairs of a detailed training frame and a random capture of
//! it ([`captures`]); the ridge is chosen on the last training sequence held out (with one sequence, on its
//! last quarter).
//!
//! Every feature is a linear, rotation- and translation-equivariant function of the positions, measured in
//! the frame's own mean edge length, so the filter depends on the local shape of the surface, never on vertex
//! identity or units.
//!
//! The guard ([`Guard`]) compares each input frame with what the model saw in training: its mean edge length
//! (another unit or garment is refused with an error), its signature (a frame unlike every training capture
//! falls back) and the size of the detail the filter would add (more than any training capture needed falls
//! back). A fallback frame gets the capture's own normals and says so.
//!
//! Before any of that, the guard asks whether the capture lost any surface at all ([`LostSurface`]). Cloth
//! hardly stretches or compresses in its plane, so a capture that smoothed folds away has less area than the
//! garment (Chen's integrated shrinkage, over the whole garment); a capture that kept its folds has the
//! garment's area, whatever its noise. The garment's area is the median of the detailed training frames', and
//! the cloth's own compression is the most any of them lost against it. The question is asked of the whole
//! capture ([`SurfaceGate`]), by the mean over its frames: a capture system smooths every frame alike, while
//! one frame's loss also depends on how much the cloth is folded then (a smoothed capture's nearly flat
//! frames lose as little as the cloth itself, and the filter still helps them). A capture that lost no more
//! than the cloth's own compression keeps its own normals; between that and twice that the detail is added in
//! part. This is what keeps a sharp capture with reconstruction noise, which any filter trained on smoothed
//! captures would sharpen, as good as it came in.

pub mod captures;
pub mod operator;
pub mod relief;

use crate::nn::seed::Rng;
use captures::CaptureDraw;
use crease_core::mesh::{geometry, Topology};
use crease_core::shape::mean_edge_length;
use crease_core::vec3::{self, V3};
use crease_core::{Error, Result};
use faer::{Mat, Side};
use operator::Walk;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Chebyshev degree of the default filter.
pub const DEFAULT_DEGREE: usize = 16;
/// Random captures drawn per training frame.
pub const DEFAULT_CAPTURES_PER_FRAME: usize = 1;
/// Ridge weights tried (relative to the mean diagonal of the normal equations) on the held-out sequence.
pub const RIDGES: [f64; 9] = [1e-10, 1e-8, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0];
/// Numbers in a frame's signature.
pub const SIGNATURE_LEN: usize = 7;
/// Margin of the guard over the most extreme training frame.
pub const GUARD_MARGIN: f64 = 1.25;
/// Mean edge lengths the guard accepts, as a factor either side of the training range.
pub const SCALE_TOLERANCE: f64 = 1.5;
/// The lost surface at which a frame gets the whole detail, as a multiple of the cloth's own compression
/// ([`LostSurface::limit`]); from that limit up to this multiple the detail is added in part.
pub const LOST_SURFACE_RAMP: f64 = 2.0;

/// Chebyshev degree of the band-pass filters the signature measures with.
const SIGNATURE_DEGREE: usize = 16;
/// Band edges of the signature, as θ = arccos(a) in degrees for an eigenvalue a of P. On a grid of unit edges a
/// flat wave of wavelength λ has a = (1 + cos 2π/λ)/2: the bands run from waves longer than about 16 edges,
/// through 10, 7, 5 and 3.5 edges, to the shortest the mesh can carry (noise).
const SIGNATURE_BANDS: [f64; 7] = [0.0, 16.0, 25.0, 36.0, 50.0, 70.0, 180.0];

/// One frame's signature: ½ log of the mean |Δc|² over h², then ½ log of each band's share of that energy
/// (the bands of [`SIGNATURE_BANDS`]). Together they say how much curvature detail the frame has and how it
/// is spread from long folds to the shortest waves: a capture that keeps little of the short folds has little
/// there, a noisy one has much at the very top. Measured on interior vertices, from the data alone.
pub fn signature(features: &[Vec<V3>], walk: &Walk, h: f64) -> [f64; SIGNATURE_LEN] {
    let d = SIGNATURE_DEGREE.min(features.len() - 1);
    let interior: Vec<usize> = (0..walk.n_vertices())
        .filter(|&v| !walk.is_boundary(v))
        .collect();
    let n = interior.len().max(1) as f64;
    // Gram matrix of the features: every band's energy is a quadratic form in it.
    let mut g = vec![0.0; (d + 1) * (d + 1)];
    for i in 0..=d {
        for j in i..=d {
            let e = interior
                .iter()
                .map(|&v| vec3::dot(features[i][v], features[j][v]))
                .sum::<f64>()
                / n;
            g[i * (d + 1) + j] = e;
            g[j * (d + 1) + i] = e;
        }
    }
    let tiny = 1e-300;
    let total = g[0].max(tiny);
    let mut s = [0.0; SIGNATURE_LEN];
    s[0] = 0.5 * (total / (h * h).max(tiny)).ln();
    for (b, slot) in s.iter_mut().skip(1).enumerate() {
        let c = band_coefficients(SIGNATURE_BANDS[b], SIGNATURE_BANDS[b + 1], d);
        let mut e = 0.0;
        for i in 0..=d {
            for j in 0..=d {
                e += c[i] * g[i * (d + 1) + j] * c[j];
            }
        }
        *slot = 0.5 * (e.max(tiny * total) / total).ln();
    }
    s
}

/// Jackson-damped Chebyshev coefficients of the indicator of θ ∈ [lo, hi) degrees (a = cos θ), degree `d`.
fn band_coefficients(lo: f64, hi: f64, d: usize) -> Vec<f64> {
    let nodes = 8 * (d + 1);
    let mut c = vec![0.0; d + 1];
    for q in 0..nodes {
        let theta = std::f64::consts::PI * (q as f64 + 0.5) / nodes as f64;
        let deg = theta.to_degrees();
        if deg >= lo && deg < hi {
            for (j, cj) in c.iter_mut().enumerate() {
                *cj += 2.0 / nodes as f64 * (j as f64 * theta).cos();
            }
        }
    }
    c[0] *= 0.5;
    let m = (d + 1) as f64;
    let a = std::f64::consts::PI / (m + 1.0);
    for (j, cj) in c.iter_mut().enumerate() {
        let j = j as f64;
        *cj *= ((m - j + 1.0) * (j * a).cos() + (j * a).sin() / a.tan()) / (m + 1.0);
    }
    c
}

/// T_j(P) Δc for j = 0..=degree.
pub fn features(walk: &Walk, coarse: &[V3], degree: usize) -> Vec<Vec<V3>> {
    let mut out: Vec<Vec<V3>> = Vec::with_capacity(degree + 1);
    out.push(walk.laplacian(coarse));
    if degree >= 1 {
        let mut t1 = vec![[0.0; 3]; coarse.len()];
        walk.average_into(&out[0], &mut t1);
        out.push(t1);
    }
    for j in 2..=degree {
        let mut t = vec![[0.0; 3]; coarse.len()];
        walk.average_into(&out[j - 1], &mut t);
        for (a, b) in t.iter_mut().zip(&out[j - 2]) {
            *a = vec3::sub(vec3::scale(*a, 2.0), *b);
        }
        out.push(t);
    }
    out
}

/// The conditioning vector of a signature: 1, then each number standardised and clamped to ±3.
fn conditioning(s: &[f64; SIGNATURE_LEN], mean: &[f64], std: &[f64]) -> [f64; SIGNATURE_LEN + 1] {
    let mut x = [1.0; SIGNATURE_LEN + 1];
    for i in 0..SIGNATURE_LEN {
        x[i + 1] = ((s[i] - mean[i]) / std[i].max(1e-12)).clamp(-3.0, 3.0);
    }
    x
}

/// Distance of a signature from the training mean, in training standard deviations (not clamped).
fn signature_distance(s: &[f64; SIGNATURE_LEN], mean: &[f64], std: &[f64]) -> f64 {
    (0..SIGNATURE_LEN)
        .map(|i| ((s[i] - mean[i]) / std[i].max(1e-12)).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// What the guard accepts, measured on the training captures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Guard {
    /// Smallest and largest mean edge length of the training frames (m).
    pub edge_length: [f64; 2],
    /// Largest signature distance of a training capture, times [`GUARD_MARGIN`].
    pub max_signature_distance: f64,
    /// Largest RMS of the predicted detail of a training capture in its mean edge lengths, times the margin.
    pub max_detail: f64,
    /// The garment's surface and how much of it the cloth itself gives up; absent in models trained before
    /// the guard looked at it, which add the whole detail to every frame they accept.
    #[serde(default)]
    pub lost_surface: Option<LostSurface>,
}

/// The garment's own surface, from the detailed training frames: what a capture's frame is measured against
/// to tell whether it lost folds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LostSurface {
    /// Median total area of the detailed training frames (m²).
    pub rest_area: f64,
    /// The largest share of `rest_area` a detailed training frame lost (the cloth's own compression): a frame
    /// that lost no more keeps its own normals.
    pub limit: f64,
}

impl LostSurface {
    /// From detailed frames: the median of their total areas, and the largest share of it any of them lost.
    pub fn measure<'a>(topo: &Topology, frames: impl Iterator<Item = &'a [V3]>) -> Option<Self> {
        let mut areas: Vec<f64> = frames.map(|f| total_area(topo, f)).collect();
        if areas.is_empty() || !areas.iter().all(|a| a.is_finite() && *a > 0.0) {
            return None;
        }
        areas.sort_by(f64::total_cmp);
        let rest_area = areas[areas.len() / 2];
        // A share, never below a hair: a model trained on frames of one area still ramps over a finite span.
        let limit = (1.0 - areas[0] / rest_area).max(1e-3);
        Some(LostSurface { rest_area, limit })
    }

    /// The share of the garment's surface `p` lost.
    pub fn lost(&self, topo: &Topology, p: &[V3]) -> f64 {
        1.0 - total_area(topo, p) / self.rest_area
    }

    /// How much of the model's detail a frame that lost `lost` gets: none up to the limit, all from
    /// [`LOST_SURFACE_RAMP`] times it, a smooth step between.
    pub fn share(&self, lost: f64) -> f64 {
        let x = ((lost - self.limit) / ((LOST_SURFACE_RAMP - 1.0) * self.limit)).clamp(0.0, 1.0);
        x * x * (3.0 - 2.0 * x)
    }

    fn check(&self) -> std::result::Result<(), String> {
        if !(self.rest_area.is_finite() && self.rest_area > 0.0) {
            return Err(format!(
                "lost_surface.rest_area {} is not a positive area",
                self.rest_area
            ));
        }
        if !(self.limit > 0.0 && self.limit < 1.0) {
            return Err(format!(
                "lost_surface.limit {} is not a share in (0, 1)",
                self.limit
            ));
        }
        Ok(())
    }
}

fn total_area(topo: &Topology, p: &[V3]) -> f64 {
    geometry::triangle_areas(topo, p).iter().sum()
}

/// The scalar part of the detail model (the manifest's `detail`); the weights are `detail.npy`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetailSpec {
    pub degree: usize,
    pub ridge: f64,
    pub captures_per_frame: usize,
    pub seed: u64,
    pub signature_mean: Vec<f64>,
    pub signature_std: Vec<f64>,
    pub guard: Guard,
    /// Mean normal error (°) on the held-out training sequence's random captures: of the captures themselves,
    /// and of the model's prediction (guard included).
    pub held_out_capture_deg: f64,
    pub held_out_model_deg: f64,
    /// Whether `apply --coarse` takes a capture's detail from the relief or from this filter by default
    /// ([`relief::choose`]); absent in models trained before the relief was an option, which use the filter.
    #[serde(default)]
    pub coarse: Option<relief::CoarseChoice>,
}

/// The fitted model: weights per class (interior, boundary vertices), (degree + 1) × (signature + 1).
#[derive(Debug, Clone, PartialEq)]
pub struct DetailModel {
    pub spec: DetailSpec,
    pub interior: Vec<f64>,
    pub boundary: Vec<f64>,
}

/// Why a frame got the capture's own normals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fallback {
    /// The frame's signature is further from the training captures' than any of them.
    Signature { distance: f64, limit: f64 },
    /// The filter would add more detail than any training capture needed.
    Detail { rms_edges: f64, limit: f64 },
    /// The capture lost no more of the garment's surface than the cloth itself does: no fold was smoothed away.
    NothingLost { lost: f64, limit: f64 },
}

impl std::fmt::Display for Fallback {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Fallback::Signature { distance, limit } => write!(
                f,
                "the frame's detail spectrum is {distance:.2} standard deviations from the training captures' (limit {limit:.2})"
            ),
            Fallback::Detail { rms_edges, limit } => write!(
                f,
                "the model would add {rms_edges:.3} edge lengths of detail (RMS; limit {limit:.3})"
            ),
            Fallback::NothingLost { lost, limit } => write!(
                f,
                "the capture lost {:.1} % of the garment's surface over its frames, no more than the cloth \
                 itself does ({:.1} %): no fold was smoothed away",
                lost * 100.0,
                limit * 100.0
            ),
        }
    }
}

/// How much of its detail the model adds to a capture's frames, for the surface the capture lost
/// ([`DetailModel::surface_gate`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceGate {
    /// 0 to 1.
    pub share: f64,
    /// The capture's mean lost share of the garment's surface and the cloth's own limit, where measured.
    pub lost: Option<(f64, f64)>,
}

impl SurfaceGate {
    /// Everything through (a model without the measure).
    pub const OPEN: SurfaceGate = SurfaceGate {
        share: 1.0,
        lost: None,
    };

    /// Why the capture keeps its own normals, if it does.
    pub fn fallback(&self) -> Option<Fallback> {
        match self.lost {
            Some((lost, limit)) if self.share == 0.0 => Some(Fallback::NothingLost { lost, limit }),
            _ => None,
        }
    }
}

/// The result of one frame: the fine shape (with the share of the detail it got, below 1 where the capture
/// lost little surface), or the capture itself with the reason.
pub enum Prediction {
    Fine { shape: Vec<V3>, share: f64 },
    Fallback(Fallback),
}

impl DetailModel {
    fn unknowns(degree: usize) -> usize {
        (degree + 1) * (SIGNATURE_LEN + 1)
    }

    /// Checks the weights against the stored degree (a damaged or foreign `detail.npy`) and the spec's numbers.
    pub fn check(&self) -> std::result::Result<(), String> {
        let m = Self::unknowns(self.spec.degree);
        if self.interior.len() != m || self.boundary.len() != m {
            return Err(format!(
                "{} and {} weights for degree {} ({m} expected)",
                self.interior.len(),
                self.boundary.len(),
                self.spec.degree
            ));
        }
        if !self
            .interior
            .iter()
            .chain(&self.boundary)
            .all(|w| w.is_finite())
        {
            return Err("a weight is not a finite number".into());
        }
        let s = &self.spec;
        if s.signature_mean.len() != SIGNATURE_LEN || s.signature_std.len() != SIGNATURE_LEN {
            return Err(format!("the signature has {SIGNATURE_LEN} numbers"));
        }
        let g = &s.guard;
        if !(g.edge_length[0] > 0.0
            && g.edge_length[1] >= g.edge_length[0]
            && g.max_signature_distance > 0.0
            && g.max_detail > 0.0)
        {
            return Err("guard limits must be positive".into());
        }
        if let Some(l) = &g.lost_surface {
            l.check()?;
        }
        Ok(())
    }

    /// What the surface `frames` (a capture's, all of them) lost lets the model add: see [`LostSurface`]. A
    /// model trained before the guard measured it lets everything through.
    /// The frames are read one at a time and only while needed (not at all by such a model), so a long capture
    /// can be streamed through.
    pub fn surface_gate<F: AsRef<[V3]>>(
        &self,
        topo: &Topology,
        frames: impl IntoIterator<Item = F>,
    ) -> SurfaceGate {
        let Some(l) = &self.spec.guard.lost_surface else {
            return SurfaceGate::OPEN;
        };
        let (sum, n) = frames.into_iter().fold((0.0, 0usize), |(s, n), f| {
            (s + l.lost(topo, f.as_ref()), n + 1)
        });
        let lost = sum / n.max(1) as f64;
        SurfaceGate {
            share: l.share(lost),
            lost: Some((lost, l.limit)),
        }
    }

    /// Refuses a frame whose mean edge length is outside what the model was trained on (another unit or
    /// garment): an error naming the frame and both lengths.
    pub fn check_scale(&self, topo: &Topology, coarse: &[V3], what: &str) -> Result<f64> {
        let h = mean_edge_length(topo, coarse);
        let [lo, hi] = self.spec.guard.edge_length;
        if !(h >= lo / SCALE_TOLERANCE && h <= hi * SCALE_TOLERANCE) {
            return Err(Error::param(
                "coarse",
                format!(
                    "{what}: mean edge length {:.3} mm is outside what the model was trained on ({:.3}–{:.3} mm, \
                     accepted down to {:.3} and up to {:.3} mm): another unit or another garment?",
                    h * 1e3,
                    lo * 1e3,
                    hi * 1e3,
                    lo / SCALE_TOLERANCE * 1e3,
                    hi * SCALE_TOLERANCE * 1e3
                ),
            ));
        }
        Ok(h)
    }

    /// The detail d the filter adds to `coarse` (not guarded), with the frame's signature.
    pub fn detail(
        &self,
        topo: &Topology,
        coarse: &[V3],
        h: f64,
    ) -> (Vec<V3>, [f64; SIGNATURE_LEN]) {
        let walk = Walk::cotangent(topo, coarse);
        let f = features(&walk, coarse, self.spec.degree.max(SIGNATURE_DEGREE));
        let s = signature(&f, &walk, h);
        let x = conditioning(&s, &self.spec.signature_mean, &self.spec.signature_std);
        let k = SIGNATURE_LEN + 1;
        let mix = |w: &[f64]| -> Vec<f64> {
            (0..=self.spec.degree)
                .map(|j| (0..k).map(|i| w[j * k + i] * x[i]).sum())
                .collect()
        };
        let (wi, wb) = (mix(&self.interior), mix(&self.boundary));
        let d = (0..coarse.len())
            .map(|v| {
                let w = if walk.is_boundary(v) { &wb } else { &wi };
                let mut acc = [0.0; 3];
                for (j, fj) in f.iter().take(self.spec.degree + 1).enumerate() {
                    acc = vec3::add(acc, vec3::scale(fj[v], w[j]));
                }
                acc
            })
            .collect();
        (d, s)
    }

    /// The fine shape predicted for `coarse` (mean edge length `h`), a frame of a capture that `gate` was
    /// measured on, or why the guard refused it.
    pub fn predict(&self, topo: &Topology, coarse: &[V3], h: f64, gate: SurfaceGate) -> Prediction {
        if let Some(why) = gate.fallback() {
            return Prediction::Fallback(why);
        }
        let share = gate.share;
        let (d, s) = self.detail(topo, coarse, h);
        let g = &self.spec.guard;
        let distance = signature_distance(&s, &self.spec.signature_mean, &self.spec.signature_std);
        if distance > g.max_signature_distance {
            return Prediction::Fallback(Fallback::Signature {
                distance,
                limit: g.max_signature_distance,
            });
        }
        let rms = rms(&d) / h;
        if rms > g.max_detail {
            return Prediction::Fallback(Fallback::Detail {
                rms_edges: rms,
                limit: g.max_detail,
            });
        }
        Prediction::Fine {
            shape: coarse
                .iter()
                .zip(&d)
                .map(|(c, e)| vec3::add(*c, vec3::scale(*e, share)))
                .collect(),
            share,
        }
    }

    /// The predicted fine shape of `coarse`, or on a fallback `coarse` itself.
    pub fn fine_or_coarse(
        &self,
        topo: &Topology,
        coarse: &[V3],
        h: f64,
        gate: SurfaceGate,
    ) -> Vec<V3> {
        match self.predict(topo, coarse, h, gate) {
            Prediction::Fine { shape, .. } => shape,
            Prediction::Fallback(_) => coarse.to_vec(),
        }
    }

    /// The vertex normals the model stands for on `coarse`: the predicted fine shape's, or on a fallback the
    /// capture's own.
    pub fn normals(
        &self,
        topo: &Topology,
        coarse: &[V3],
        h: f64,
        gate: SurfaceGate,
    ) -> (Vec<V3>, Option<Fallback>) {
        match self.predict(topo, coarse, h, gate) {
            Prediction::Fine { shape, .. } => (geometry::vertex_normals(topo, &shape), None),
            Prediction::Fallback(f) => (geometry::vertex_normals(topo, coarse), Some(f)),
        }
    }
}

/// RMS length of a displacement field.
fn rms(d: &[V3]) -> f64 {
    (d.iter().map(|e| vec3::dot(*e, *e)).sum::<f64>() / d.len().max(1) as f64).sqrt()
}

/// Mean angle (°) between two normal fields.
pub fn mean_angle_deg(a: &[V3], b: &[V3]) -> f64 {
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| vec3::dot(*x, *y).clamp(-1.0, 1.0).acos())
        .sum();
    (sum / a.len().max(1) as f64).to_degrees()
}

/// The training data of the detail model: detailed frames grouped by sequence (the last one is held out to
/// choose the ridge and calibrate nothing else).
pub struct DetailData<'a> {
    pub topo: &'a Topology,
    pub sequences: Vec<&'a [Vec<V3>]>,
}

/// Options of [`fit`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetailParams {
    pub degree: usize,
    pub captures_per_frame: usize,
    pub seed: u64,
}

impl Default for DetailParams {
    fn default() -> Self {
        DetailParams {
            degree: DEFAULT_DEGREE,
            captures_per_frame: DEFAULT_CAPTURES_PER_FRAME,
            seed: 1,
        }
    }
}

/// One (capture, fine) pair's contribution: the Gram matrix and right-hand side of its features over both
/// weight sets (interior vertices' then boundary vertices'), before the conditioning vector is applied, and the
/// frame's signature and scale.
struct PairSystem {
    gram: Vec<f64>,
    rhs: Vec<f64>,
    signature: [f64; SIGNATURE_LEN],
    h: f64,
}

/// The capture of training frame `frame` of sequence `seq`, draw `k`: seeded by all four numbers, so the
/// training pairs are the same whatever the thread count.
pub fn training_capture(
    topo: &Topology,
    fine: &[V3],
    h: f64,
    seed: u64,
    seq: usize,
    frame: usize,
    k: usize,
) -> (Vec<V3>, CaptureDraw) {
    let mix = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((seq as u64) << 40)
        .wrapping_add((frame as u64) << 8)
        .wrapping_add(k as u64);
    let mut rng = Rng::new(mix);
    let d = captures::draw(&mut rng);
    let c = captures::capture(topo, fine, h, &d, &mut rng);
    (c, d)
}

/// The pair's normal equations. The residual is measured along every edge, as the difference of the
/// residuals at its two ends: a normal is the surface's slope, and fitting positions instead spends the fit on
/// long waves whose slopes hardly matter (same held-out normal error on sleeve-train, by a hair worse).
fn pair_system(topo: &Topology, capture: &[V3], fine: &[V3], degree: usize) -> PairSystem {
    let h = mean_edge_length(topo, capture);
    let walk = Walk::cotangent(topo, capture);
    let f = features(&walk, capture, degree.max(SIGNATURE_DEGREE));
    let s = signature(&f, &walk, h);
    let m = degree + 1;
    let n = 2 * m;
    let mut gram = vec![0.0; n * n];
    let mut rhs = vec![0.0; n];
    let r: Vec<V3> = fine
        .iter()
        .zip(capture)
        .map(|(a, b)| vec3::sub(*a, *b))
        .collect();
    let class = |v: usize| usize::from(walk.is_boundary(v));
    let mut row = vec![[0.0; 3]; n];
    let mut add = |row: &[V3], target: V3| {
        for i in 0..n {
            if row[i] == [0.0; 3] {
                continue;
            }
            rhs[i] += vec3::dot(row[i], target);
            for j in i..n {
                gram[i * n + j] += vec3::dot(row[i], row[j]);
            }
        }
    };
    for (t, tri) in topo.triangles().iter().enumerate() {
        for k in 0..3 {
            let adj = topo.tri_adj()[t][k];
            if !(adj == crease_core::mesh::NONE || (adj as usize) > t) {
                continue;
            }
            let (a, b) = (tri[k] as usize, tri[(k + 1) % 3] as usize);
            row.iter_mut().for_each(|x| *x = [0.0; 3]);
            for j in 0..m {
                let ra = &mut row[class(a) * m + j];
                *ra = vec3::add(*ra, f[j][a]);
                let rb = &mut row[class(b) * m + j];
                *rb = vec3::sub(*rb, f[j][b]);
            }
            add(&row, vec3::sub(r[a], r[b]));
        }
    }
    for i in 0..n {
        for j in 0..i {
            gram[i * n + j] = gram[j * n + i];
        }
    }
    PairSystem {
        gram,
        rhs,
        signature: s,
        h,
    }
}

/// Normal equations of the conditioned model over some pairs: unknown (c · m + j) · k + i is weight j of
/// class c (interior, boundary) times conditioning number i.
struct System {
    gram: Vec<f64>,
    rhs: Vec<f64>,
    n: usize,
}

impl System {
    fn new(degree: usize) -> System {
        let n = 2 * DetailModel::unknowns(degree);
        System {
            gram: vec![0.0; n * n],
            rhs: vec![0.0; n],
            n,
        }
    }

    fn add(&mut self, p: &PairSystem, x: &[f64; SIGNATURE_LEN + 1]) {
        let k = SIGNATURE_LEN + 1;
        let (pn, n) = (p.rhs.len(), self.n);
        for a in 0..pn {
            for i in 0..k {
                self.rhs[a * k + i] += p.rhs[a] * x[i];
                for b in 0..pn {
                    let g = p.gram[a * pn + b] * x[i];
                    if g == 0.0 {
                        continue;
                    }
                    let start = (a * k + i) * n + b * k;
                    for (q, r) in self.gram[start..start + k].iter_mut().enumerate() {
                        *r += g * x[q];
                    }
                }
            }
        }
    }

    /// The ridge solution split into the two classes' weights.
    fn solve(&self, ridge: f64) -> Result<[Vec<f64>; 2]> {
        let n = self.n;
        let mut w = vec![0.0; n];
        let mean_diag = (0..n).map(|i| self.gram[i * n + i]).sum::<f64>() / n as f64;
        if mean_diag > 0.0 && mean_diag.is_finite() {
            let g = Mat::<f64>::from_fn(n, n, |i, j| {
                self.gram[i * n + j] + if i == j { ridge * mean_diag } else { 0.0 }
            });
            let eig = g
                .self_adjoint_eigen(Side::Lower)
                .map_err(|e| Error::Numeric {
                    stage: "detail model".into(),
                    msg: format!("eigendecomposition of the normal equations: {e:?}"),
                })?;
            let s = eig.S().column_vector();
            let u = eig.U();
            let smax = (0..n).map(|i| s[i]).fold(0.0f64, f64::max);
            for k in 0..n {
                if s[k] <= smax * 1e-14 {
                    continue;
                }
                let proj: f64 = (0..n).map(|i| u[(i, k)] * self.rhs[i]).sum::<f64>() / s[k];
                for (i, wi) in w.iter_mut().enumerate() {
                    *wi += u[(i, k)] * proj;
                }
            }
        }
        let boundary = w.split_off(n / 2);
        Ok([w, boundary])
    }
}

/// Fits the detail model: random captures of every training frame, the ridge chosen on the last sequence
/// held out (by the mean normal error of its captures' predictions), then the weights refitted on all
/// sequences and the guard calibrated on every training capture. Deterministic for a seed.
pub fn fit(data: &DetailData, params: &DetailParams) -> Result<DetailModel> {
    Ok(fit_with_held_out(data, params)?.model)
}

/// The fitted model, and the same fitted without the held-out frames (same ridge and guard): what a decision
/// taken on the held-out sequence ([`relief::choose`]) must use, or it would score the filter on frames it
/// was fitted to.
pub struct DetailFit {
    pub model: DetailModel,
    pub held_out: DetailModel,
}

/// [`fit`], with [`DetailFit::held_out`].
pub fn fit_with_held_out(data: &DetailData, params: &DetailParams) -> Result<DetailFit> {
    let topo = data.topo;
    let n_seq = data.sequences.len();
    if n_seq == 0 || data.sequences.iter().all(|s| s.is_empty()) {
        return Err(Error::param(
            "data",
            "no detailed frames to learn detail from",
        ));
    }
    let degree = params.degree;
    let jobs: Vec<(usize, usize, usize)> = data
        .sequences
        .iter()
        .enumerate()
        .flat_map(|(s, frames)| {
            (0..frames.len())
                .flat_map(move |t| (0..params.captures_per_frame).map(move |k| (s, t, k)))
        })
        .collect();
    let pairs: Vec<(PairSystem, Vec<V3>, f64)> = jobs
        .par_iter()
        .map(|&(s, t, k)| {
            let fine = &data.sequences[s][t];
            let h = mean_edge_length(topo, fine);
            let (c, _) = training_capture(topo, fine, h, params.seed, s, t, k);
            (pair_system(topo, &c, fine, degree), c, h)
        })
        .collect();
    // Signature statistics over every training capture.
    let count = pairs.len() as f64;
    let mut mean = vec![0.0; SIGNATURE_LEN];
    for (p, _, _) in &pairs {
        for (m, x) in mean.iter_mut().zip(&p.signature) {
            *m += x / count;
        }
    }
    let mut std = vec![0.0; SIGNATURE_LEN];
    for (p, _, _) in &pairs {
        for ((s, x), m) in std.iter_mut().zip(&p.signature).zip(&mean) {
            *s += (x - m).powi(2) / count;
        }
    }
    for s in &mut std {
        *s = s.sqrt().max(1e-6);
    }
    // Held out to choose the ridge: the last sequence, or with one sequence its last quarter of frames.
    let held_len = data.sequences[n_seq - 1].len();
    let is_held =
        |s: usize, t: usize| s == n_seq - 1 && (n_seq > 1 || t >= held_len - held_len / 4);
    let mut train_sys = System::new(degree);
    let mut all_sys = System::new(degree);
    for ((p, _, _), &(s, t, _)) in pairs.iter().zip(&jobs) {
        let x = conditioning(&p.signature, &mean, &std);
        all_sys.add(p, &x);
        if !is_held(s, t) {
            train_sys.add(p, &x);
        }
    }
    // The scale the model knows is that of the detailed frames (a capture's mean edge length is a little
    // shorter where it smooths).
    let edge_length = pairs.iter().fold([f64::INFINITY, 0.0f64], |a, (_, _, h)| {
        [a[0].min(*h), a[1].max(*h)]
    });
    let lost_surface = LostSurface::measure(
        topo,
        data.sequences
            .iter()
            .flat_map(|s| s.iter().map(|f| f.as_slice())),
    );
    let provisional = |w: [Vec<f64>; 2], ridge: f64| {
        let [interior, boundary] = w;
        DetailModel {
            spec: DetailSpec {
                degree,
                ridge,
                captures_per_frame: params.captures_per_frame,
                seed: params.seed,
                signature_mean: mean.clone(),
                signature_std: std.clone(),
                guard: Guard {
                    edge_length,
                    max_signature_distance: f64::INFINITY,
                    max_detail: f64::INFINITY,
                    lost_surface,
                },
                held_out_capture_deg: f64::NAN,
                held_out_model_deg: f64::NAN,
                coarse: None,
            },
            interior,
            boundary,
        }
    };
    // The ridge: the one whose fit on the other sequences predicts the held-out sequence's normals best.
    let held_pairs: Vec<usize> = jobs
        .iter()
        .enumerate()
        .filter(|(_, j)| is_held(j.0, j.1))
        .map(|(i, _)| i)
        .collect();
    let score = |m: &DetailModel, guarded: bool| -> (f64, f64) {
        let errs: Vec<(f64, f64)> = held_pairs
            .par_iter()
            .map(|&i| {
                let (s, t, _) = jobs[i];
                let fine = &data.sequences[s][t];
                let c = &pairs[i].1;
                let truth = geometry::vertex_normals(topo, fine);
                let h = pairs[i].0.h;
                let own = geometry::vertex_normals(topo, c);
                let pred = if guarded {
                    // Every held-out frame has a capture of its own: each is its own capture sequence.
                    m.normals(topo, c, h, m.surface_gate(topo, [c.as_slice()]))
                        .0
                } else {
                    let (d, _) = m.detail(topo, c, h);
                    let f: Vec<V3> = c.iter().zip(&d).map(|(a, b)| vec3::add(*a, *b)).collect();
                    geometry::vertex_normals(topo, &f)
                };
                (mean_angle_deg(&own, &truth), mean_angle_deg(&pred, &truth))
            })
            .collect();
        let n = errs.len().max(1) as f64;
        (
            errs.iter().map(|e| e.0).sum::<f64>() / n,
            errs.iter().map(|e| e.1).sum::<f64>() / n,
        )
    };
    let ridge = if held_pairs.is_empty() {
        return Err(Error::param(
            "data",
            "too few detailed frames to hold some out for the detail model",
        ));
    } else {
        let mut best = (f64::INFINITY, RIDGES[0]);
        for &r in &RIDGES {
            let m = provisional(train_sys.solve(r)?, r);
            let (_, e) = score(&m, false);
            if e < best.0 {
                best = (e, r);
            }
        }
        best.1
    };
    let mut model = provisional(all_sys.solve(ridge)?, ridge);
    // The guard: the most extreme signature and detail of any training capture, with a margin.
    let (max_dist, max_detail) = pairs
        .par_iter()
        .map(|(p, c, _)| {
            let dist = signature_distance(&p.signature, &mean, &std);
            let (d, _) = model.detail(topo, c, p.h);
            (dist, rms(&d) / p.h)
        })
        .reduce(|| (0.0f64, 0.0f64), |a, b| (a.0.max(b.0), a.1.max(b.1)));
    model.spec.guard.max_signature_distance = GUARD_MARGIN * max_dist;
    model.spec.guard.max_detail = GUARD_MARGIN * max_detail;
    // Held-out figures of the final ridge, from the fit without the held-out frames.
    let mut held_out = provisional(train_sys.solve(ridge)?, ridge);
    held_out.spec.guard = model.spec.guard.clone();
    let (own, pred) = score(&held_out, true);
    model.spec.held_out_capture_deg = own;
    model.spec.held_out_model_deg = pred;
    held_out.spec.held_out_capture_deg = own;
    held_out.spec.held_out_model_deg = pred;
    Ok(DetailFit { model, held_out })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detail::operator::tests::grid;

    /// A grid with folds of a few wavelengths, moving with `phase`.
    fn folded(phase: f64) -> (Topology, Vec<V3>) {
        let (topo, mut p) = grid(40, 24);
        for q in p.iter_mut() {
            let (x, y) = (q[0], q[1]);
            q[2] = 0.35 * (x * 0.9 + phase).sin() * (y * 0.3).cos()
                + 0.2 * (x * 0.45 - y * 0.6 + phase).sin()
                + 2.0 * (x * 0.05).sin();
        }
        (topo, p)
    }

    #[test]
    fn lost_surface_keeps_captures_that_lost_no_more_than_the_cloth_itself() {
        let (topo, p) = folded(0.0);
        let scaled = |f: f64| -> Vec<V3> { p.iter().map(|q| vec3::scale(*q, f.sqrt())).collect() };
        // Detailed frames of area 1, 0.97 and 1.01 times the first: the garment's area is the median, the
        // cloth's own compression 3 %.
        let frames = [scaled(1.0), scaled(0.97), scaled(1.01)];
        let l = LostSurface::measure(&topo, frames.iter().map(|f| f.as_slice())).unwrap();
        let a0 = total_area(&topo, &p);
        assert!((l.rest_area - a0).abs() < 1e-9 * a0);
        assert!((l.limit - 0.03).abs() < 1e-9);
        assert!((l.lost(&topo, &scaled(0.9)) - 0.1).abs() < 1e-9);
        // Nothing up to the limit (a stretched capture included), all from twice it, half way between.
        for (lost, share) in [
            (-0.05, 0.0),
            (0.0, 0.0),
            (0.03, 0.0),
            (0.045, 0.5),
            (0.06, 1.0),
            (0.3, 1.0),
        ] {
            assert!(
                (l.share(lost) - share).abs() < 1e-12,
                "{lost}: {}",
                l.share(lost)
            );
        }
        assert!(l.check().is_ok());
        assert!(LostSurface { limit: 1.5, ..l }.check().is_err());
        assert!(LostSurface {
            rest_area: f64::NAN,
            ..l
        }
        .check()
        .is_err());
    }

    #[test]
    fn fitted_model_beats_its_captures_on_held_out_frames_and_is_deterministic() {
        let frames: Vec<Vec<V3>> = (0..12).map(|t| folded(0.3 * t as f64).1).collect();
        let topo = folded(0.0).0;
        let data = DetailData {
            topo: &topo,
            sequences: vec![&frames[..6], &frames[6..9], &frames[9..]],
        };
        let params = DetailParams {
            degree: 8,
            captures_per_frame: 2,
            seed: 5,
        };
        let m = fit(&data, &params).unwrap();
        assert!(m.check().is_ok());
        assert!(
            m.spec.held_out_model_deg < m.spec.held_out_capture_deg,
            "{:?}",
            m.spec
        );
        assert_eq!(m, fit(&data, &params).unwrap());
    }
}
