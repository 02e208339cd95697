//! The fold relief a capture damped, estimated from the capture alone: what a deconvolution adds to each
//! captured frame along its normal, made coherent over time, and kept only where it stands above the capture's
//! noise.
//!
//! A capture (multi-view reconstruction, a tracked template, a scanner's own smoothing) low-passes the cloth:
//! folds a few edges wide lose much of their height, wider ones little, and what it keeps sits exactly where the
//! real ridges and valleys are. crease does not know that low-pass. It models the capture as the smoothest
//! generic one, the surface's heat kernel H ([`crate::heat`]) at a *detail scale* ℓ (the wavelength H halves;
//! by default five mean edge lengths of the input: a capture mesh is normally about as fine as the detail it
//! resolves, and a user who knows better gives ℓ in millimetres), and undoes it by Van Cittert's iteration
//! g ← g + (c − H g) from g = c, `steps` times. A component H keeps a fraction T of comes back multiplied by
//! Σ_{j≤steps} (1 − T)^j: unchanged where T = 1 (the garment's shape, wide folds), at most `steps + 1` times
//! where T is small, never more, so the gain is bounded whatever the capture was.
//!
//! The relief η_t = n_t · (g_t − c_t) is a scalar per vertex and frame (n_t the captured vertex normal): the
//! component across the surface, which is what folds are. Two properties of real folds separate them from a
//! capture's reconstruction noise, which is new in every frame:
//! - folds are coherent over a few frames at video rates, so η is averaged over time with a Gaussian of
//!   `temporal_sigma` frames (per vertex: the relief rides on the cloth, not in space);
//! - the noise's share is measured: for noise independent between frames, the second temporal difference
//!   η_t − (η_{t−1} + η_{t+1}) / 2 has 3/2 of its variance, while a fold's relief barely changes over one frame.
//!   Its robust spread (median absolute value, per frame, the median over the frames the average reads) gives
//!   the noise variance σ², and the averaged relief keeps, per vertex, the Wiener fraction (P − σ²ₐ) / P of
//!   itself, P its local power (smoothed over two rings) and σ²ₐ the noise variance left after averaging. Where
//!   the relief is noise, the fraction is 0 and the capture comes back as it was; noise is never amplified.
//!
//! Everything here reads the captured frames only, so a frame's relief heights are a pure function of the input
//! frames t − radius − 1 … t + radius + 1: where they are computed (which task, which machine) changes nothing.

use crate::heat::{self, Series, SurfaceOperator};
use crate::mesh::{geometry, Topology};
use crate::vec3::{self, V3};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// How the relief is estimated and combined over time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReliefParams {
    /// Detail scale ℓ in metres: the wavelength the modelled capture halves. 0 = five mean edge lengths of the
    /// input's first frame.
    #[serde(default)]
    pub scale: f64,
    /// Van Cittert steps of the deconvolution (0 = no relief); the gain on what the capture damped most is at
    /// most `steps + 1`.
    #[serde(default = "default_steps")]
    pub steps: u32,
    /// Standard deviation, in frames, of the temporal average (0 = none).
    #[serde(default = "default_temporal_sigma")]
    pub temporal_sigma: f64,
}

fn default_steps() -> u32 {
    8
}

fn default_temporal_sigma() -> f64 {
    2.5
}

/// The noise power is subtracted this many times over (spectral subtraction's over-subtraction): the local
/// power of pure noise scatters around its mean, and the part above it must not come back as relief.
const NOISE_MARGIN: f64 = 3.0;

/// The relief's smooth part, removed as shape, is what the heat kernel halving this many detail scales keeps.
pub const SHAPE_FACTOR: f64 = 2.0;

/// Order of the high-pass that removes it: (1 − H)^order, sharper than 1 − H (a 10-edge wave at the default
/// scale keeps 1/8 of itself instead of 1/2, a 5-edge one 0.82 instead of 0.94).
pub const SHAPE_ORDER: i32 = 3;

/// Heights are compressed towards this fraction of ℓ / 2π (the height of a 45° sinusoid of wavelength ℓ).
pub const HEIGHT_CAP: f64 = 0.5;

/// Smoothing rounds (half the vertex, half its one-ring mean) of the local power.
const POWER_ROUNDS: usize = 4;

/// The detail scale in mean edge lengths when none is given.
pub const DEFAULT_SCALE_EDGES: f64 = 5.0;

impl Default for ReliefParams {
    fn default() -> Self {
        ReliefParams {
            scale: 0.0,
            steps: default_steps(),
            temporal_sigma: default_temporal_sigma(),
        }
    }
}

impl ReliefParams {
    pub fn validate(&self) -> Result<()> {
        if !(self.scale.is_finite() && self.scale >= 0.0) {
            return Err(Error::param(
                "relief.scale",
                format!(
                    "must be a length ≥ 0 in metres (0 = automatic), got {}",
                    self.scale
                ),
            ));
        }
        if self.steps > 32 {
            return Err(Error::param(
                "relief.steps",
                format!("must be at most 32, got {}", self.steps),
            ));
        }
        if !(self.temporal_sigma.is_finite() && (0.0..=8.0).contains(&self.temporal_sigma)) {
            return Err(Error::param(
                "relief.temporal_sigma",
                format!(
                    "must be between 0 and 8 frames, got {}",
                    self.temporal_sigma
                ),
            ));
        }
        Ok(())
    }

    /// Whether the relief adds anything.
    pub fn is_active(&self) -> bool {
        self.steps > 0
    }

    /// Frames each side of t whose relief the heights of frame t read (the temporal average's radius).
    pub fn radius(&self) -> usize {
        if self.temporal_sigma <= 0.0 {
            0
        } else {
            (2.5 * self.temporal_sigma).ceil() as usize
        }
    }

    /// The frames whose relief the heights of frame `t` of an `n`-frame sequence read: the temporal average's
    /// span and one more frame each side for the noise estimate.
    pub fn span(&self, t: usize, n: usize) -> std::ops::Range<usize> {
        let r = self.radius() + 1;
        t.saturating_sub(r)..(t + r + 1).min(n)
    }

    /// The detail scale for a sequence whose first frame has mean edge length `edge`.
    pub fn scale_for(&self, edge: f64) -> f64 {
        if self.scale > 0.0 {
            self.scale
        } else {
            DEFAULT_SCALE_EDGES * edge
        }
    }
}

/// The relief's transfer as a function of the heat kernel's eigenvalue λ: the deconvolution's detail
/// Σ_{j=1..steps} (1 − e^{−tλ})^j, times the high-pass (1 − e^{−sλ})^[`SHAPE_ORDER`] at the shape scale (s the
/// diffusion time halving [`SHAPE_FACTOR`] detail scales). The deconvolution also inflates whatever is curved on
/// the garment's own scale (the heat kernel shrinks a cylinder; undoing it widens the cylinder): that part is
/// smooth, and it is shape, not folds, so the high-pass takes it out.
pub fn detail_series(op: &SurfaceOperator, scale: f64, steps: u32) -> Series {
    let t = heat::diffusion_time(scale);
    let s = heat::diffusion_time(SHAPE_FACTOR * scale);
    Series::new(op.lambda_max(), move |l| {
        let damped = 1.0 - (-t * l).exp();
        let (mut sum, mut power) = (0.0, 1.0);
        for _ in 0..steps {
            power *= damped;
            sum += power;
        }
        sum * (1.0 - (-s * l).exp()).powi(SHAPE_ORDER)
    })
}

/// The relief of one captured frame `c`: per vertex, the deconvolution's detail along the captured normal.
pub fn frame_relief(topo: &Topology, c: &[V3], scale: f64, steps: u32) -> Vec<f64> {
    if steps == 0 {
        return vec![0.0; c.len()];
    }
    let op = SurfaceOperator::new(topo, c);
    // The series annihilates constants; subtracting the mean first keeps the result independent of where
    // the garment stands, to rounding.
    let mean = c.iter().fold([0.0; 3], |a, p| vec3::add(a, *p));
    let mean = vec3::scale(mean, 1.0 / c.len().max(1) as f64);
    let centred: Vec<V3> = c.iter().map(|p| vec3::sub(*p, mean)).collect();
    let detail = op.apply(&detail_series(&op, scale, steps), &centred);
    let normals = geometry::vertex_normals(topo, c);
    // A sinusoidal fold of the detail wavelength steeper than 45° (height above ℓ / 2π) is a pleat whose
    // shape no deconvolution can know: heights beyond that are compressed smoothly towards it.
    let cap = HEIGHT_CAP * scale / (2.0 * std::f64::consts::PI);
    detail
        .iter()
        .zip(&normals)
        .map(|(d, n)| {
            let h = vec3::dot(*d, *n);
            if h.is_finite() {
                cap * (h / cap).tanh()
            } else {
                0.0
            }
        })
        .collect()
}

/// Robust variance of the part of frame `k`'s relief that is new in that frame, from its second temporal
/// difference; `None` at the sequence's ends (no neighbour on one side).
fn incoherent_variance(reliefs: &[&[f64]], k: usize) -> Option<f64> {
    if k == 0 || k + 1 >= reliefs.len() {
        return None;
    }
    let (a, b, c) = (reliefs[k - 1], reliefs[k], reliefs[k + 1]);
    let mut d: Vec<f64> = (0..b.len())
        .map(|v| (b[v] - 0.5 * (a[v] + c[v])).abs())
        .collect();
    if d.is_empty() {
        return Some(0.0);
    }
    let mid = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(mid, |x, y| x.total_cmp(y));
    // Median of |N(0, s²)| is 0.6745 s; the second difference of independent noise has variance 3/2 σ².
    let s = *m / 0.6745;
    Some(s * s / 1.5)
}

/// The heights added to frame `t` along its captured normal: the temporal average of the reliefs, each vertex
/// keeping its Wiener fraction. `reliefs[k]` is the relief of frame `first + k`; it must hold frames
/// t − radius − 1 ..= t + radius + 1 where the sequence has them (fewer at its ends).
pub fn heights(
    topo: &Topology,
    params: &ReliefParams,
    reliefs: &[&[f64]],
    first: usize,
    t: usize,
) -> Result<Vec<f64>> {
    let n = topo.n_vertices();
    let k = t
        .checked_sub(first)
        .filter(|&k| k < reliefs.len())
        .ok_or_else(|| {
            Error::param(
                "relief",
                format!(
                    "frame {t} is not among the {} reliefs given from frame {first}",
                    reliefs.len()
                ),
            )
        })?;
    if let Some(bad) = reliefs.iter().position(|r| r.len() != n) {
        return Err(Error::param(
            "relief",
            format!(
                "frame {} has {} values for {n} vertices",
                first + bad,
                reliefs[bad].len()
            ),
        ));
    }
    let radius = params.radius();
    let lo = k.saturating_sub(radius);
    let hi = (k + radius).min(reliefs.len() - 1);
    let sigma = params.temporal_sigma;
    let mut weights: Vec<f64> = (lo..=hi)
        .map(|j| {
            if sigma > 0.0 {
                let d = (j as f64 - k as f64) / sigma;
                (-0.5 * d * d).exp()
            } else {
                1.0
            }
        })
        .collect();
    let total: f64 = weights.iter().sum();
    weights.iter_mut().for_each(|w| *w /= total);
    let mut averaged = vec![0.0; n];
    for (j, w) in (lo..=hi).zip(&weights) {
        for (a, r) in averaged.iter_mut().zip(reliefs[j]) {
            *a += w * r;
        }
    }
    // The noise variance: the median of the frames' estimates over the average's span. Without any estimate
    // (a sequence of one or two frames) nothing tells folds from noise, and nothing is added.
    let mut estimates: Vec<f64> = (lo..=hi)
        .filter_map(|j| incoherent_variance(reliefs, j))
        .collect();
    if estimates.is_empty() {
        return Ok(vec![0.0; n]);
    }
    estimates.sort_by(|a, b| a.total_cmp(b));
    let noise =
        NOISE_MARGIN * estimates[estimates.len() / 2] * weights.iter().map(|w| w * w).sum::<f64>();
    // Local power of the averaged relief, smoothed over a few rings.
    let mut power: Vec<f64> = averaged.iter().map(|a| a * a).collect();
    let mut next = vec![0.0; n];
    for _ in 0..POWER_ROUNDS {
        for (v, p) in next.iter_mut().enumerate() {
            let nb = topo.vertex_neighbors(v);
            let sum: f64 = nb.iter().map(|&u| power[u as usize]).sum();
            *p = if nb.is_empty() {
                power[v]
            } else {
                0.5 * power[v] + 0.5 * sum / nb.len() as f64
            };
        }
        std::mem::swap(&mut power, &mut next);
    }
    Ok(averaged
        .iter()
        .zip(&power)
        .map(|(a, p)| {
            if *p > 0.0 {
                a * ((p - noise) / p).clamp(0.0, 1.0)
            } else {
                0.0
            }
        })
        .collect())
}

/// The reliefs of a streamed sequence: computed when a frame first needs them, dropped once no later frame
/// will (frames are asked for in increasing order, as the streaming driver releases them).
pub struct ReliefFrames {
    params: ReliefParams,
    scale: f64,
    n_frames: usize,
    reliefs: std::collections::BTreeMap<usize, Vec<f64>>,
}

impl ReliefFrames {
    /// For a sequence of `n_frames` frames at detail scale `scale`.
    pub fn new(params: ReliefParams, scale: f64, n_frames: usize) -> Self {
        ReliefFrames {
            params,
            scale,
            n_frames,
            reliefs: Default::default(),
        }
    }

    /// Computes (in parallel) the reliefs frames `frames` need that are not there yet, and drops those no frame
    /// from the smallest of `frames` on needs.
    pub fn prepare(
        &mut self,
        source: &dyn crate::mesh::FrameSource,
        frames: &[usize],
    ) -> Result<()> {
        use rayon::prelude::*;
        let Some(&first) = frames.iter().min() else {
            return Ok(());
        };
        let keep_from = self.params.span(first, self.n_frames).start;
        self.reliefs.retain(|&k, _| k >= keep_from);
        let mut missing: Vec<usize> = frames
            .iter()
            .flat_map(|&t| self.params.span(t, self.n_frames))
            .filter(|k| !self.reliefs.contains_key(k))
            .collect();
        missing.sort_unstable();
        missing.dedup();
        let topo = source.topology().clone();
        let (scale, steps) = (self.scale, self.params.steps);
        let computed: Vec<(usize, Vec<f64>)> = missing
            .into_par_iter()
            .map(|k| Ok((k, frame_relief(&topo, &source.read_frame(k)?, scale, steps))))
            // Every outcome is kept so that a bad input names its first bad frame, not the one a thread met.
            .collect::<Vec<Result<_>>>()
            .into_iter()
            .collect::<Result<_>>()?;
        self.reliefs.extend(computed);
        Ok(())
    }

    /// The heights of frame `t` ([`heights`]); its span must have been prepared.
    pub fn heights(&self, topo: &Topology, t: usize) -> Result<Vec<f64>> {
        let span = self.params.span(t, self.n_frames);
        let reliefs: Vec<&[f64]> = span
            .clone()
            .map(|k| {
                self.reliefs.get(&k).map(|r| r.as_slice()).ok_or_else(|| {
                    Error::param("relief", format!("frame {k}'s relief was not prepared"))
                })
            })
            .collect::<Result<_>>()?;
        heights(topo, &self.params, &reliefs, span.start, t)
    }
}

/// `out` with `heights` added along the captured frame's vertex normals.
pub fn add_heights(topo: &Topology, captured: &[V3], out: &[V3], heights: &[f64]) -> Vec<V3> {
    let normals = geometry::vertex_normals(topo, captured);
    out.iter()
        .zip(&normals)
        .zip(heights)
        .map(|((o, n), h)| {
            if *h == 0.0 || vec3::norm(*n) == 0.0 {
                *o
            } else {
                vec3::add(*o, vec3::scale(*n, *h))
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::heat::tests::waved_grid;

    /// A generic low-pass the relief knows nothing about: an implicit step of the *uniform* Laplacian,
    /// repeated.
    fn blur(topo: &Topology, p: &[V3], rounds: usize) -> Vec<V3> {
        let mut x = p.to_vec();
        for _ in 0..rounds {
            let next: Vec<V3> = (0..x.len())
                .map(|v| {
                    let nb = topo.vertex_neighbors(v);
                    if nb.len() < 6 {
                        return x[v];
                    }
                    let avg = nb
                        .iter()
                        .fold([0.0; 3], |a, &u| vec3::add(a, x[u as usize]));
                    vec3::add(
                        vec3::scale(x[v], 0.6),
                        vec3::scale(avg, 0.4 / nb.len() as f64),
                    )
                })
                .collect();
            x = next;
        }
        x
    }

    /// A ripple damped by a low-pass of another family comes back in phase and closer to its height, never
    /// above it.
    #[test]
    fn a_damped_ripple_comes_back_in_phase_without_overshoot() {
        let (topo, truth) = waved_grid(60, 40, 6.0, 0.3);
        let captured = blur(&topo, &truth, 6);
        let eta = frame_relief(&topo, &captured, 5.0, 8);
        let mut checked = 0;
        for v in 0..truth.len() {
            let (x, y) = (truth[v][0], truth[v][1]);
            if !(15.0..45.0).contains(&x) || !(8.0..25.0).contains(&y) || truth[v][2].abs() < 0.25 {
                continue;
            }
            let kept = captured[v][2] / truth[v][2];
            let restored = (captured[v][2] + eta[v]) / truth[v][2];
            assert!(kept > 0.2 && kept < 0.8, "kept {kept}");
            assert!(restored > kept + 0.1, "vertex {v}: {kept} -> {restored}");
            assert!(restored < 1.05, "vertex {v}: overshoot {restored}");
            checked += 1;
        }
        assert!(checked > 20, "{checked}");
    }

    /// A wave wider than the detail scale several times over is the garment's shape: left alone.
    #[test]
    fn wide_shapes_are_left_alone() {
        let (topo, p) = waved_grid(80, 40, 40.0, 2.0);
        let eta = frame_relief(&topo, &p, 5.0, 8);
        let inner = (0..p.len())
            .filter(|&v| (20.0..60.0).contains(&p[v][0]) && (8.0..25.0).contains(&p[v][1]));
        for v in inner {
            assert!(eta[v].abs() < 0.05 * 2.0, "vertex {v}: {}", eta[v]);
        }
    }

    fn sequence_reliefs(frames: &[Vec<V3>], topo: &Topology) -> Vec<Vec<f64>> {
        frames
            .iter()
            .map(|f| frame_relief(topo, f, 5.0, 8))
            .collect()
    }

    /// Noise that is new in every frame gets no height: the Wiener fraction of pure noise is zero almost
    /// everywhere, and what is left is far below the noise itself.
    #[test]
    fn noise_alone_is_not_amplified() {
        let (topo, flat) = waved_grid(40, 30, 6.0, 0.0);
        let mut state = 12345u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.1
        };
        let frames: Vec<Vec<V3>> = (0..9)
            .map(|_| flat.iter().map(|q| [q[0], q[1], q[2] + noise()]).collect())
            .collect();
        let reliefs = sequence_reliefs(&frames, &topo);
        let refs: Vec<&[f64]> = reliefs.iter().map(|r| r.as_slice()).collect();
        let h = heights(&topo, &ReliefParams::default(), &refs, 0, 4).unwrap();
        let rms = (h.iter().map(|x| x * x).sum::<f64>() / h.len() as f64).sqrt();
        // Uniform noise of half-width 0.05 has an rms of 0.029.
        assert!(rms < 0.005, "rms of the heights {rms}");
    }

    /// A fold present in every frame (the same damped ripple, plus fresh noise) keeps its relief.
    #[test]
    fn a_steady_fold_keeps_its_relief_under_noise() {
        let (topo, truth) = waved_grid(60, 40, 6.0, 0.3);
        let captured = blur(&topo, &truth, 6);
        let mut state = 777u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.02
        };
        let frames: Vec<Vec<V3>> = (0..9)
            .map(|_| {
                captured
                    .iter()
                    .map(|q| [q[0], q[1], q[2] + noise()])
                    .collect()
            })
            .collect();
        let reliefs = sequence_reliefs(&frames, &topo);
        let refs: Vec<&[f64]> = reliefs.iter().map(|r| r.as_slice()).collect();
        let h = heights(&topo, &ReliefParams::default(), &refs, 0, 4).unwrap();
        // What the deconvolution gives the noise-free capture: the noise handling must keep most of it.
        let clean = frame_relief(&topo, &captured, 5.0, 8);
        let (mut agree, mut total) = (0, 0);
        let mut ratios = Vec::new();
        for v in 0..truth.len() {
            let (x, y) = (truth[v][0], truth[v][1]);
            if (15.0..45.0).contains(&x) && (8.0..25.0).contains(&y) && truth[v][2].abs() > 0.25 {
                total += 1;
                let want = truth[v][2] - captured[v][2];
                ratios.push(h[v] / clean[v]);
                if h[v] * want > 0.0 && clean[v] * want > 0.0 && h[v].abs() > 0.5 * clean[v].abs() {
                    agree += 1;
                }
            }
        }
        ratios.sort_by(|a, b| a.total_cmp(b));
        eprintln!(
            "h / clean relief: median {:.3}, tenth {:.3}",
            ratios[ratios.len() / 2],
            ratios[ratios.len() / 10]
        );
        assert!(agree as f64 > 0.9 * total as f64, "{agree} of {total}");
    }

    #[test]
    fn frames_outside_the_given_range_are_named() {
        let (topo, p) = waved_grid(6, 5, 4.0, 0.1);
        let r = frame_relief(&topo, &p, 5.0, 2);
        let err = heights(&topo, &ReliefParams::default(), &[&r], 3, 7).unwrap_err();
        assert!(err.to_string().contains("frame 7"), "{err}");
    }

    #[test]
    fn parameters_are_checked_by_name() {
        let bad = ReliefParams {
            scale: -1.0,
            ..Default::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("relief.scale"));
        let bad = ReliefParams {
            temporal_sigma: f64::NAN,
            ..Default::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("relief.temporal_sigma"));
    }
}
