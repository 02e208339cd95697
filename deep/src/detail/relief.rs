//! The capture's detail from crease's fold relief instead of the learned filter: the generic deconvolution of
//! `crease run` ([`crease_core::spacetime::shape::relief`]), run on the whole coarse sequence.
//!
//! The learned filter ([`super::DetailModel`]) predicts the fine surface from one frame, fitted on random
//! captures of the training sequences; the relief undoes the smoothest generic low-pass at the input's own
//! detail scale (five mean edge lengths of its first frame), keeps only what is coherent over a few frames
//! and above the noise it measures on the sequence itself, and never amplifies that noise. On sleeve captures
//! made other ways than the learned filter's training captures (the public capture filter, a spectral cut,
//! implicit low-passes with and without noise) its maps are 0.1–0.4° closer to the cloth; on captures of the
//! learned filter's own families, and on folds that change faster than its temporal average follows, the
//! learned filter is better (docs/deepwrinkles.md has the figures).
//!
//! Which of the two a model uses by default is decided when it is trained ([`choose`]): on captures of the
//! held-out training sequence made the way the learned filter's training captures are, but one family and
//! strength for the whole sequence (a capture system does not change from frame to frame) with noise new in
//! every frame. A sequence whose folds change faster than the relief's temporal average follows is better
//! served by the per-frame filter, and the choice says so.
//!
//! A frame's heights read only the frames around it (the relief's temporal span) and the first frame (the
//! detail scale), so any frame range of an apply gives the same bytes as the whole run.

use super::captures;
use super::DetailModel;
use crate::nn::seed::Rng;
use crease_core::mesh::{geometry, Frame, FrameSource, Sequence, Topology};
use crease_core::shape::mean_edge_length;
use crease_core::spacetime::position::strain_limit::{
    StrainLimiter, StrainReference, DEFAULT_STRAIN_LIMIT, DEFAULT_STRAIN_LIMIT_SWEEPS,
};
use crease_core::spacetime::shape::relief::{add_heights, ReliefFrames, ReliefParams};
use crease_core::vec3::{self, V3};
use crease_core::{Error, Result};
use serde::{Deserialize, Serialize};

/// Where `apply --coarse` takes a capture's detail from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CoarseDetail {
    /// crease's fold relief, run on the whole coarse sequence ([`CoarseRelief`]).
    Relief,
    /// The model's learned detail filter, frame by frame, with its guard ([`crate::detail`]).
    Model,
    /// The midpoint of the two fine shapes ([`blend`]).
    Blend,
}

impl CoarseDetail {
    pub fn as_str(self) -> &'static str {
        match self {
            CoarseDetail::Relief => "relief",
            CoarseDetail::Model => "model",
            CoarseDetail::Blend => "blend",
        }
    }
}

impl std::str::FromStr for CoarseDetail {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "relief" => Ok(CoarseDetail::Relief),
            "model" => Ok(CoarseDetail::Model),
            "blend" => Ok(CoarseDetail::Blend),
            other => Err(Error::param(
                "coarse-detail",
                format!("`{other}` is not `relief`, `model` or `blend`"),
            )),
        }
    }
}

/// The relief of one coarse sequence, computed a few frames at a time in increasing order (it keeps only the
/// captured frames' reliefs the next frames' spans need), and the strain limit `crease run` ends with: no edge
/// stretched past 5 % of its longest captured length (read from every frame once). It takes back part of
/// what the relief adds to a sharp capture with reconstruction noise (on the sleeve's ground truth with noise,
/// maps 5.1° → 4.3° from the cloth; the capture's own, 2.0°). `crease run`'s lost-area bound is left out: it
/// scales the displacement vertex by vertex, and the maps, which hold a few texels per vertex, blur the
/// texture that leaves (a capture low-passed at four edges: 3.2° → 4.0° with it).
pub struct CoarseRelief {
    reliefs: ReliefFrames,
    limiter: Option<StrainLimiter>,
}

impl CoarseRelief {
    /// For `source`, at the detail scale of its first frame.
    pub fn new(source: &dyn FrameSource) -> Result<Self> {
        let params = ReliefParams::default();
        let first = source.read_frame(0)?;
        let scale = params.scale_for(mean_edge_length(source.topology(), &first));
        Ok(CoarseRelief {
            reliefs: ReliefFrames::new(params, scale, source.n_frames()),
            limiter: StrainLimiter::for_source(
                source,
                DEFAULT_STRAIN_LIMIT,
                DEFAULT_STRAIN_LIMIT_SWEEPS,
                StrainReference::Sequence,
            )?,
        })
    }

    /// The heights of `frames` (increasing, after any asked for before), per frame along its captured normals.
    pub fn heights(&mut self, source: &dyn FrameSource, frames: &[usize]) -> Result<Vec<Vec<f64>>> {
        self.reliefs.prepare(source, frames)?;
        frames
            .iter()
            .map(|&t| self.reliefs.heights(source.topology(), t))
            .collect()
    }

    /// Captured frame `c` with its relief `heights` added along its normals, then strain-limited.
    pub fn relieved(&self, topo: &Topology, c: &[V3], heights: &[f64]) -> Vec<V3> {
        let mut out = add_heights(topo, c, c, heights);
        if let Some(l) = &self.limiter {
            l.apply(c, &mut out);
        }
        out
    }
}

/// `coarse` moved `share` of the way to `relieved`: the relief given in part to a capture that lost little of
/// the garment's surface ([`DetailModel::surface_gate`]).
pub fn in_part(coarse: &[V3], relieved: &[V3], share: f64) -> Vec<V3> {
    coarse
        .iter()
        .zip(relieved)
        .map(|(c, r)| vec3::add(*c, vec3::scale(vec3::sub(*r, *c), share)))
        .collect()
}

/// The midpoint of the relieved frame and the learned filter's fine shape of it. The two err differently: the
/// relief reads the frames around one and knows no garment, the filter reads one frame and knows the garment's
/// folds, and their midpoint is closer to the cloth than either on most captures measured (sleeve-train's
/// held-out captures and five other captures of the public sleeve: docs/deepwrinkles.md).
pub fn blend(relieved: &[V3], fine: &[V3]) -> Vec<V3> {
    relieved
        .iter()
        .zip(fine)
        .map(|(r, f)| vec3::scale(vec3::add(*r, *f), 0.5))
        .collect()
}

/// Sequence captures of the held-out training sequence the choice is made on.
const CHOICE_CAPTURES: usize = 3;
/// Offset of their draws from the learned filter's training and validation draws.
const CHOICE_DRAW: u64 = 0x5EC0_0000;

/// Which detail `apply --coarse` uses by default, and the figures it was decided on (mean normal error in
/// degrees on the held-out training sequence's sequence captures).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CoarseChoice {
    pub capture_deg: f64,
    pub relief_deg: f64,
    pub model_deg: f64,
    /// The blend's error; absent in models trained before it was a candidate.
    #[serde(default)]
    pub blend_deg: Option<f64>,
    /// The relief was closer to the held-out sequence than the learned filter (what models trained before
    /// `chosen` existed decide by).
    pub use_relief: bool,
    /// The path closest to the held-out sequence.
    #[serde(default)]
    pub chosen: Option<CoarseDetail>,
}

impl CoarseChoice {
    /// The path `apply --coarse` uses by default.
    pub fn detail(&self) -> CoarseDetail {
        self.chosen.unwrap_or(if self.use_relief {
            CoarseDetail::Relief
        } else {
            CoarseDetail::Model
        })
    }
}

/// Decides between the relief, `model` (the filter fitted without `held`) and their blend on a few sequence
/// captures of `held` (detailed frames), drawn with `seed`.
pub fn choose(
    topo: &Topology,
    model: &DetailModel,
    held: &[Frame],
    seed: u64,
) -> Result<CoarseChoice> {
    use rayon::prelude::*;
    let (mut capture_deg, mut relief_deg, mut model_deg, mut blend_deg) = (0.0, 0.0, 0.0, 0.0);
    let truth: Vec<Vec<V3>> = held
        .par_iter()
        .map(|f| geometry::vertex_normals(topo, f))
        .collect();
    let error = |n: &[V3], t: usize| -> f64 {
        let sum: f64 = n
            .iter()
            .zip(&truth[t])
            .map(|(a, b)| {
                crease_core::vec3::dot(*a, *b)
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees()
            })
            .sum();
        sum / n.len().max(1) as f64
    };
    for k in 0..CHOICE_CAPTURES {
        let mut rng = Rng::new(seed ^ (CHOICE_DRAW + k as u64));
        let draw = captures::draw(&mut rng);
        let frames: Vec<Frame> = held
            .par_iter()
            .enumerate()
            .map(|(t, fine)| {
                let mut noise = Rng::new(seed ^ (CHOICE_DRAW + ((k as u64) << 20) + t as u64 + 1));
                captures::capture(topo, fine, mean_edge_length(topo, fine), &draw, &mut noise)
            })
            .collect();
        let seq = Sequence::new(std::sync::Arc::new(topo.clone()), frames)?;
        let mut relief = CoarseRelief::new(&seq)?;
        let gate = model.surface_gate(topo, seq.frames.iter().map(|f| f.as_slice()));
        let all: Vec<usize> = (0..seq.n_frames()).collect();
        let n = all.len().max(1) as f64;
        for chunk in all.chunks(32) {
            let heights = relief.heights(&seq, chunk)?;
            let scores: Vec<[f64; 4]> = chunk
                .par_iter()
                .zip(&heights)
                .map(|(&t, h)| {
                    let c = &seq.frames[t];
                    let relieved = in_part(c, &relief.relieved(topo, c, h), gate.share);
                    let fine = model.fine_or_coarse(topo, c, mean_edge_length(topo, c), gate);
                    [
                        error(&geometry::vertex_normals(topo, c), t),
                        error(&geometry::vertex_normals(topo, &relieved), t),
                        error(&geometry::vertex_normals(topo, &fine), t),
                        error(&geometry::vertex_normals(topo, &blend(&relieved, &fine)), t),
                    ]
                })
                .collect();
            for [c, r, m, b] in scores {
                capture_deg += c / (n * CHOICE_CAPTURES as f64);
                relief_deg += r / (n * CHOICE_CAPTURES as f64);
                model_deg += m / (n * CHOICE_CAPTURES as f64);
                blend_deg += b / (n * CHOICE_CAPTURES as f64);
            }
        }
    }
    // Ties go to the filter, then the blend: the paths that need no other frame.
    let chosen = [
        (CoarseDetail::Model, model_deg),
        (CoarseDetail::Blend, blend_deg),
        (CoarseDetail::Relief, relief_deg),
    ]
    .into_iter()
    .fold((CoarseDetail::Model, f64::INFINITY), |best, (d, e)| {
        if e < best.1 {
            (d, e)
        } else {
            best
        }
    })
    .0;
    Ok(CoarseChoice {
        capture_deg,
        relief_deg,
        model_deg,
        blend_deg: Some(blend_deg),
        use_relief: relief_deg < model_deg,
        chosen: Some(chosen),
    })
}
