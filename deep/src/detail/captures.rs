//! Training captures made from the detailed meshes themselves: random low-passes, resolution loss and noise.
//!
//! A real capture system (multi-view reconstruction, a scanner, a registration) follows none of these
//! exactly; what it loses below its resolution is gone, and what it keeps carries noise. A model trained on
//! one capture's (captured, detailed) pairs learns to undo that capture and nothing else. So the detail model
//! never sees a training directory's `captured/` meshes: every pair it learns from is a detailed frame and a
//! capture of it drawn here, from one of four families of random strength, with random noise on top:
//!
//! - **heat**: implicit diffusion with cotangent weights, ((1 + t) I − t P) x' = x, one linear solve;
//! - **band**: a smooth spectral cut of the same operator (pass below one frequency, stop above a higher one,
//!   a cosine between), as a damped Chebyshev expansion, without any eigendecomposition;
//! - **sweeps**: explicit λ|μ averaging sweeps of the lazy walk (I + P)/2 (uniform or cotangent weights,
//!   random λ, pass band and count);
//! - **resample**: resolution loss: the surface kept only at scattered samples a few edges apart and
//!   rebuilt between them by a smooth partition of unity, then lightly diffused.
//!
//! The strengths are drawn log-uniformly over wide ranges, stated as the wavelength (in mean edge lengths) at
//! which a flat sinusoid keeps about half its amplitude: [`HALF_WAVELENGTH`]. Noise is Gaussian, isotropic,
//! correlated over 0–3 rings and new in every frame, with a standard deviation drawn log-uniformly in
//! [`NOISE_SIGMA`] mean edge lengths, on [`NOISE_SHARE`] of the captures.

use super::operator::Walk;
use crate::nn::seed::Rng;
use crease_core::mesh::Topology;
use crease_core::vec3::{self, V3};
use serde::{Deserialize, Serialize};

/// Range of the half-amplitude wavelength of a capture's low-pass, in mean edge lengths.
pub const HALF_WAVELENGTH: (f64, f64) = (3.5, 14.0);
/// Range of the noise's standard deviation, in mean edge lengths.
pub const NOISE_SIGMA: (f64, f64) = (0.004, 0.08);
/// Share of the captures that get noise.
pub const NOISE_SHARE: f64 = 0.75;
/// Degree of the Chebyshev expansion of the band family's cut.
const BAND_DEGREE: usize = 80;

/// Which family a capture came from, with its drawn parameters (for logs and tests).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Family {
    Heat {
        half_wavelength: f64,
    },
    Band {
        pass: f64,
        stop: f64,
    },
    Sweeps {
        lambda: f64,
        mu: f64,
        steps: usize,
        cotangent: bool,
    },
    Resample {
        spacing: usize,
        half_wavelength: f64,
    },
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaptureDraw {
    pub family: Family,
    /// Noise standard deviation in mean edge lengths (0: none) and its correlation rings.
    pub noise_sigma: f64,
    pub noise_rings: usize,
}

/// The eigenvalue of I − P that a flat sinusoid of `wavelength` edges has under an averaging walk whose
/// neighbours lie about one edge away on two axes (the cotangent walk of a quad-like grid): (1 − cos ω)/2.
pub fn frequency_of(wavelength: f64) -> f64 {
    0.5 * (1.0 - (std::f64::consts::TAU / wavelength).cos())
}

fn log_uniform(rng: &mut Rng, (lo, hi): (f64, f64)) -> f64 {
    (lo.ln() + rng.uniform() * (hi.ln() - lo.ln())).exp()
}

/// Standard normal draw (Box–Muller).
pub fn gaussian(rng: &mut Rng) -> f64 {
    let u = rng.uniform().max(1e-300);
    let v = rng.uniform();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// Draws a capture's family and strength and its noise.
pub fn draw(rng: &mut Rng) -> CaptureDraw {
    let family = match (rng.uniform() * 4.0) as usize {
        0 => Family::Heat {
            half_wavelength: log_uniform(rng, HALF_WAVELENGTH),
        },
        1 => {
            let half = log_uniform(rng, HALF_WAVELENGTH);
            // The taper spans a random share around the half point, from nearly a hard cut to a soft one.
            let width = 1.1 + rng.uniform() * 0.6;
            Family::Band {
                pass: half * width.sqrt(),
                stop: half / width.sqrt(),
            }
        }
        2 => {
            let lambda = 0.3 + rng.uniform() * 0.5;
            let mut pass_band = 0.01 + rng.uniform() * 0.12;
            let half = log_uniform(rng, HALF_WAVELENGTH);
            // λ|μ sweeps lift the waves below their pass band a little (Taubin's bump); repeated, that would
            // amplify long waves, which no capture does: the pass band shrinks until the whole filter lifts
            // nothing by more than 5 %.
            let (mu, steps) = loop {
                let mu = 1.0 / (pass_band - 1.0 / lambda);
                let steps = sweeps_for(lambda, mu, 0.5 * frequency_of(half));
                if max_gain(lambda, mu).powi(steps as i32) <= 1.05 || pass_band < 1e-4 {
                    break (mu, steps);
                }
                pass_band *= 0.5;
            };
            Family::Sweeps {
                lambda,
                mu,
                steps,
                cotangent: rng.uniform() < 0.5,
            }
        }
        _ => Family::Resample {
            spacing: 2 + (rng.uniform() * 3.0) as usize,
            half_wavelength: log_uniform(rng, (HALF_WAVELENGTH.0, HALF_WAVELENGTH.0 * 2.0)),
        },
    };
    let (noise_sigma, noise_rings) = if rng.uniform() < NOISE_SHARE {
        (
            log_uniform(rng, NOISE_SIGMA),
            (rng.uniform() * 4.0) as usize,
        )
    } else {
        (0.0, 0)
    };
    CaptureDraw {
        family,
        noise_sigma,
        noise_rings,
    }
}

/// Largest gain of one λ|μ sweep over the lazy walk's frequencies [0, 1].
pub fn max_gain(lambda: f64, mu: f64) -> f64 {
    (0..=200)
        .map(|q| {
            let k = q as f64 / 200.0;
            ((1.0 - lambda * k) * (1.0 - mu * k)).abs()
        })
        .fold(0.0, f64::max)
}

/// λ|μ sweeps after which frequency `k` keeps half its amplitude (at least one).
fn sweeps_for(lambda: f64, mu: f64, k: f64) -> usize {
    let per_sweep = ((1.0 - lambda * k) * (1.0 - mu * k)).abs().max(1e-6);
    if per_sweep >= 1.0 {
        return 1;
    }
    ((0.5f64.ln() / per_sweep.ln()).round() as usize).clamp(1, 400)
}

/// A capture of `fine` (a detailed frame of `topo`) as `draw` describes it; `h` is the frame's mean edge
/// length and `rng` draws the noise.
pub fn capture(topo: &Topology, fine: &[V3], h: f64, d: &CaptureDraw, rng: &mut Rng) -> Vec<V3> {
    let cot = Walk::cotangent(topo, fine);
    let mut x = match &d.family {
        Family::Heat { half_wavelength } => cot.diffuse(fine, 1.0 / frequency_of(*half_wavelength)),
        Family::Band { pass, stop } => band(&cot, fine, frequency_of(*pass), frequency_of(*stop)),
        Family::Sweeps {
            lambda,
            mu,
            steps,
            cotangent,
        } => {
            let walk = if *cotangent { cot } else { Walk::uniform(topo) };
            sweeps(&walk, fine, *lambda, *mu, *steps)
        }
        Family::Resample {
            spacing,
            half_wavelength,
        } => {
            let r = resample(topo, fine, *spacing, rng);
            cot.diffuse(&r, 1.0 / frequency_of(*half_wavelength))
        }
    };
    if d.noise_sigma > 0.0 {
        add_noise(topo, &mut x, d.noise_sigma * h, d.noise_rings, rng);
    }
    x
}

/// Explicit λ|μ sweeps of the lazy walk: x ← x + λ Δx, then x ← x + μ Δx, `steps` times, with Δx = (Px − x)/2.
/// The lazy walk's frequencies lie in [0, 1], where every drawn λ|μ pair damps (|(1 − λk)(1 − μk)| < 1): P's
/// own reach 2 on a checkerboard, where a λ|μ pair can amplify and a capture would blow up.
pub fn sweeps(walk: &Walk, x: &[V3], lambda: f64, mu: f64, steps: usize) -> Vec<V3> {
    let (lambda, mu) = (0.5 * lambda, 0.5 * mu);
    let mut y = x.to_vec();
    let mut tmp = vec![[0.0; 3]; x.len()];
    for _ in 0..steps {
        for f in [lambda, mu] {
            walk.average_into(&y, &mut tmp);
            for (p, a) in y.iter_mut().zip(&tmp) {
                *p = vec3::add(*p, vec3::scale(vec3::sub(*a, *p), f));
            }
        }
    }
    y
}

/// A smooth cut in the frequency k of I − P (spectrum in [0, 2]): gain 1 below `pass`, 0 above `stop`, a
/// raised cosine between; applied as a Jackson-damped Chebyshev series in P (spectrum [−1, 1]).
pub fn band(walk: &Walk, x: &[V3], pass: f64, stop: f64) -> Vec<V3> {
    let gain = |k: f64| {
        if k <= pass {
            1.0
        } else if k >= stop {
            0.0
        } else {
            0.5 * (1.0 + (std::f64::consts::PI * (k - pass) / (stop - pass)).cos())
        }
    };
    // k = 1 − a for a in [−1, 1]: Chebyshev coefficients of g(1 − a) by Chebyshev–Gauss quadrature.
    let n = BAND_DEGREE;
    let nodes = 4 * n;
    let mut coeff = vec![0.0; n + 1];
    for q in 0..nodes {
        let theta = std::f64::consts::PI * (q as f64 + 0.5) / nodes as f64;
        let g = gain(1.0 - theta.cos());
        for (j, c) in coeff.iter_mut().enumerate() {
            *c += 2.0 / nodes as f64 * g * (j as f64 * theta).cos();
        }
    }
    coeff[0] *= 0.5;
    // Jackson damping keeps the truncated series free of Gibbs overshoot.
    let m = (n + 1) as f64;
    for (j, c) in coeff.iter_mut().enumerate() {
        let j = j as f64;
        let a = std::f64::consts::PI / (m + 1.0);
        *c *= ((m - j + 1.0) * (j * a).cos() + (j * a).sin() / a.tan()) / (m + 1.0);
    }
    // The series variable a is an eigenvalue of P itself (k = 1 − a), so the recurrence multiplies by P.
    let apply_a = |y: &[V3], out: &mut [V3]| walk.average_into(y, out);
    let len = x.len();
    let mut t_prev = x.to_vec();
    let mut t_cur = vec![[0.0; 3]; len];
    apply_a(&t_prev, &mut t_cur);
    let mut out: Vec<V3> = (0..len)
        .map(|v| {
            vec3::add(
                vec3::scale(t_prev[v], coeff[0]),
                vec3::scale(t_cur[v], coeff[1]),
            )
        })
        .collect();
    let mut t_next = vec![[0.0; 3]; len];
    for c in coeff.iter().skip(2) {
        apply_a(&t_cur, &mut t_next);
        for v in 0..len {
            t_next[v] = vec3::sub(vec3::scale(t_next[v], 2.0), t_prev[v]);
            out[v] = vec3::add(out[v], vec3::scale(t_next[v], *c));
        }
        std::mem::swap(&mut t_prev, &mut t_cur);
        std::mem::swap(&mut t_cur, &mut t_next);
    }
    out
}

/// Resolution loss: samples at least `spacing` rings apart (greedy, random order), and every vertex rebuilt as
/// the Gaussian-weighted mean of the samples within 2 · `spacing` rings (its own position where none is).
pub fn resample(topo: &Topology, x: &[V3], spacing: usize, rng: &mut Rng) -> Vec<V3> {
    let n = x.len();
    let mut order: Vec<usize> = (0..n).collect();
    rng.shuffle(&mut order);
    let mut blocked = vec![false; n];
    let mut sample = vec![false; n];
    for &v in &order {
        if blocked[v] {
            continue;
        }
        sample[v] = true;
        for w in topo.vertex_ring_neighborhood(v, spacing.saturating_sub(1)) {
            blocked[w as usize] = true;
        }
    }
    let sigma2 = (spacing * spacing) as f64;
    (0..n)
        .map(|v| {
            let (mut acc, mut wsum) = ([0.0; 3], 0.0);
            for (ring, w) in rings(topo, v, 2 * spacing) {
                if sample[w] {
                    let g = (-((ring * ring) as f64) / sigma2).exp();
                    acc = vec3::add(acc, vec3::scale(x[w], g));
                    wsum += g;
                }
            }
            if wsum > 0.0 {
                vec3::scale(acc, 1.0 / wsum)
            } else {
                x[v]
            }
        })
        .collect()
}

/// (ring distance, vertex) of every vertex within `rings` hops of `v`.
fn rings(topo: &Topology, v: usize, rings: usize) -> Vec<(usize, usize)> {
    let mut out = vec![(0, v)];
    let mut seen = std::collections::HashSet::from([v]);
    let mut frontier = vec![v];
    for r in 1..=rings {
        let mut next = Vec::new();
        for &u in &frontier {
            for w in topo.vertex_neighbors(u) {
                if seen.insert(w as usize) {
                    next.push(w as usize);
                    out.push((r, w as usize));
                }
            }
        }
        frontier = next;
    }
    out
}

/// Isotropic Gaussian noise of standard deviation `sigma` per axis, correlated by `rings` uniform averaging
/// passes (then rescaled to `sigma`).
pub fn add_noise(topo: &Topology, x: &mut [V3], sigma: f64, rings: usize, rng: &mut Rng) {
    let mut e: Vec<V3> = (0..x.len())
        .map(|_| [gaussian(rng), gaussian(rng), gaussian(rng)])
        .collect();
    if rings > 0 {
        let walk = Walk::uniform(topo);
        let mut tmp = e.clone();
        for _ in 0..rings {
            walk.average_into(&e, &mut tmp);
            std::mem::swap(&mut e, &mut tmp);
        }
    }
    let rms =
        (e.iter().map(|p| vec3::dot(*p, *p)).sum::<f64>() / (3 * e.len().max(1)) as f64).sqrt();
    let f = if rms > 0.0 { sigma / rms } else { 0.0 };
    for (p, n) in x.iter_mut().zip(&e) {
        *p = vec3::add(*p, vec3::scale(*n, f));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detail::operator::tests::grid;

    /// Share of a sinusoid's amplitude (wavelength `lambda` edges along x, height along z) that survives `f`
    /// in the middle of a large flat grid.
    fn kept(lambda: f64, f: impl Fn(&Topology, &[V3]) -> Vec<V3>) -> f64 {
        let (topo, mut p) = grid(60, 20);
        let w = std::f64::consts::TAU / lambda;
        // A small amplitude: the operator is the surface's own, and a steep wave would change it.
        for q in p.iter_mut() {
            q[2] = 0.05 * (w * q[0]).sin();
        }
        let out = f(&topo, &p);
        // Least-squares amplitude over the central vertices (away from the boundary).
        let (mut num, mut den) = (0.0, 0.0);
        for (q, o) in p.iter().zip(&out) {
            if (15.0..45.0).contains(&q[0]) && (6.0..14.0).contains(&q[1]) {
                num += o[2] * q[2];
                den += q[2] * q[2];
            }
        }
        num / den
    }

    #[test]
    fn every_family_keeps_long_waves_and_halves_near_its_stated_wavelength() {
        let half = 7.0;
        let k = frequency_of(half);
        let heat_f = |t: &Topology, p: &[V3]| Walk::cotangent(t, p).diffuse(p, 1.0 / k);
        let band_f = |t: &Topology, p: &[V3]| {
            band(
                &Walk::cotangent(t, p),
                p,
                frequency_of(half * 1.2),
                frequency_of(half / 1.2),
            )
        };
        let (l, m) = (0.5, 1.0 / (0.05 - 1.0 / 0.5));
        let sweeps_f = |t: &Topology, p: &[V3]| {
            sweeps(&Walk::cotangent(t, p), p, l, m, sweeps_for(l, m, 0.5 * k))
        };
        for (name, f) in [
            ("heat", &heat_f as &dyn Fn(&Topology, &[V3]) -> Vec<V3>),
            ("band", &band_f),
            ("sweeps", &sweeps_f),
        ] {
            let long = kept(40.0, f);
            let at_half = kept(half, f);
            let short = kept(3.0, f);
            assert!(long > 0.9, "{name}: 40 edges keep {long}");
            assert!(
                (0.3..0.7).contains(&at_half),
                "{name}: {half} edges keep {at_half}"
            );
            // Diffusion is the gentlest of the three (1 / (1 + t k)): a third still passes at 3 edges.
            assert!(
                short < 0.4 && short < 0.75 * at_half,
                "{name}: 3 edges keep {short}"
            );
        }
    }

    #[test]
    fn no_drawn_sweeps_amplify_any_frequency_of_the_lazy_walk_by_more_than_five_percent() {
        let mut rng = Rng::new(11);
        for _ in 0..2000 {
            if let Family::Sweeps {
                lambda, mu, steps, ..
            } = draw(&mut rng).family
            {
                let g = max_gain(lambda, mu).powi(steps as i32);
                assert!(g <= 1.05 + 1e-12, "λ {lambda} μ {mu} × {steps}: gain {g}");
            }
        }
    }

    #[test]
    fn captures_are_deterministic_per_seed_and_noise_has_its_size() {
        let (topo, p) = grid(30, 12);
        let mut p = p;
        for q in p.iter_mut() {
            q[2] = 0.3 * (q[0] * 1.3).sin() * (q[1] * 0.7).cos();
        }
        for seed in 0..8 {
            let d = draw(&mut Rng::new(seed));
            let a = capture(&topo, &p, 1.0, &d, &mut Rng::new(seed + 100));
            let b = capture(&topo, &p, 1.0, &d, &mut Rng::new(seed + 100));
            assert_eq!(a, b);
            assert!(a.iter().all(|q| q.iter().all(|c| c.is_finite())), "{d:?}");
        }
        let mut flat = grid(40, 40).1;
        let before = flat.clone();
        add_noise(&grid(40, 40).0, &mut flat, 0.05, 2, &mut Rng::new(3));
        let rms = (flat
            .iter()
            .zip(&before)
            .map(|(a, b)| vec3::dot(vec3::sub(*a, *b), vec3::sub(*a, *b)))
            .sum::<f64>()
            / (3 * flat.len()) as f64)
            .sqrt();
        assert!((rms - 0.05).abs() < 1e-9, "{rms}");
    }
}
