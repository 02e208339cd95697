//! The tilt of the cloth beside a detected fold, read from the shading the captured mesh does not explain
//! (shape from shading on the lighting residual; beyond Popa et al. 2009, whose anchors lie only on the edges).
//!
//! The ground truth folds densely around each detected edge pair — the neighbouring ripples of the same fold —
//! while anchors on the edges alone leave that cloth at the captured (smoothed) shape. Under the lighting fitted
//! to the captured mesh ([`super::shading`]), a pixel with captured normal `n` is predicted the grey level
//! `S(n)`. Tilting the cloth there by `θ` about the fold's direction `d` (the anchor rotation about `−d`, as in
//! [`super::project`]) turns the normal to `n + θ (n × d)` to first order, and the grey level by
//! `θ ∇S(n)·(n × d)`. So each pixel's residual `r = image − S(n)` is one linear measurement of its triangle's
//! tilt about the nearby fold's direction; over a triangle's pixels the least-squares tilt is
//! `Σ r s / Σ s²` with `s = ∇S(n)·(n × d)`. The fold axis comes from the edge, so only the angle is estimated
//! from the image.
//!
//! The estimate is trusted as much as the data allow: with the residual's robust scale `σ` as the noise of
//! one pixel and a zero-mean prior of scale `σ_p` on the tilt (the cloth beside a fold is flat until shown
//! otherwise), the posterior mean shrinks it by `Σ s² / (Σ s² + σ²/σ_p²)`; triangles the light barely shades
//! along the tilt (small `Σ s²`) or whose residual is noise get a small angle. Tilts below `min_tilt` are not
//! anchored (they would pin the cloth flat), and a flank never tilts more than its fold's edges.
//!
//! Only triangles within `band` pair widths of the pair's edges (walking the triangle adjacency from the crossed
//! triangles) are considered: the ground-truth rotation there is what lifts κ (bench/results/2026-12-02-sleeve-video-kappa.md).

use super::project::ProjectedPair;
use super::shading::ViewShading;
use crate::folds::Anchor;
use crate::mesh::{Topology, NONE};
use crate::vec3::{self, V3};
use std::collections::{HashMap, VecDeque};

/// Settings of the flank estimate (see [`super::VideoParams`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlankSettings {
    /// Reach beside the edges, in pair widths.
    pub band: f64,
    /// Smallest tilt anchored, radians.
    pub min_tilt: f64,
    /// Prior scale of the tilt, radians.
    pub prior: f64,
    /// Fewest pixels of a triangle for an estimate.
    pub min_pixels: usize,
}

/// The garment pixels of each triangle seen in one view, as ranges into one index list.
pub struct TrianglePixels {
    start: Vec<u32>,
    pixels: Vec<u32>,
}

impl TrianglePixels {
    /// Groups the pixels of `shading.surface` inside `mask` by triangle.
    pub fn new(shading: &ViewShading, mask: &[bool], n_triangles: usize) -> Self {
        let mut count = vec![0u32; n_triangles + 1];
        for (s, &m) in shading.surface.iter().zip(mask) {
            if let (Some((t, _)), true) = (s, m) {
                count[*t as usize + 1] += 1;
            }
        }
        for i in 0..n_triangles {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut pixels = vec![0u32; count[n_triangles] as usize];
        for (k, (s, &m)) in shading.surface.iter().zip(mask).enumerate() {
            if let (Some((t, _)), true) = (s, m) {
                let slot = &mut fill[*t as usize];
                pixels[*slot as usize] = k as u32;
                *slot += 1;
            }
        }
        TrianglePixels {
            start: count,
            pixels,
        }
    }

    fn of(&self, t: u32) -> &[u32] {
        let t = t as usize;
        self.pixels
            .get(self.start[t] as usize..self.start[t + 1] as usize)
            .unwrap_or(&[])
    }
}

/// Gauss-Newton rounds of the per-triangle tilt fit (the first is the linear estimate).
const ROUNDS: usize = 4;

/// `n` rotated by `theta` about the unit axis `k` (Rodrigues).
fn rotate(n: V3, k: V3, theta: f64) -> V3 {
    let (s, c) = theta.sin_cos();
    vec3::add(
        vec3::add(vec3::scale(n, c), vec3::scale(vec3::cross(k, n), s)),
        vec3::scale(k, vec3::dot(k, n) * (1.0 - c)),
    )
}

/// Tilt (radians, about `−d`) of triangle `t` from the residual image `residual_gray` (image − shading + mean)
/// under `shading`: the posterior mean under the zero-mean prior (module documentation), fitted by Gauss-Newton
/// on the full spherical-harmonic shading so that tilts of 20–30° are not underestimated by the linearisation.
/// `None` when the triangle has fewer than `settings.min_pixels` pixels.
pub fn triangle_tilt(
    t: u32,
    d: V3,
    shading: &ViewShading,
    residual_gray: &[f32],
    pixels: &TrianglePixels,
    settings: &FlankSettings,
) -> Option<f64> {
    let px = pixels.of(t);
    if px.len() < settings.min_pixels.max(1) {
        return None;
    }
    let samples: Vec<(V3, f64, f64)> = px
        .iter()
        .filter_map(|&k| {
            let (_, n) = shading.surface[k as usize]?;
            let r = residual_gray[k as usize] as f64 - shading.mean;
            Some((n, shading.shade(n), r))
        })
        .collect();
    let lambda = (shading.noise.max(0.5) / settings.prior).powi(2);
    let k = vec3::scale(d, -1.0);
    let mut theta = 0.0;
    for _ in 0..ROUNDS {
        let (mut jr, mut jj) = (0.0, 0.0);
        for &(n, s0, r) in &samples {
            let m = rotate(n, k, theta);
            let j = vec3::dot(shading.shade_gradient(m), vec3::cross(m, d));
            jr += j * (r - (shading.shade(m) - s0));
            jj += j * j;
        }
        let step = (jr - lambda * theta) / (jj + lambda);
        if !step.is_finite() {
            return None;
        }
        theta = (theta + step).clamp(-1.2, 1.2);
    }
    Some(theta)
}

/// Anchors for the flanks of `pair`: triangles within `settings.band` pair widths of its edges, other than the
/// ones the edges cross, tilted about the nearest edge's direction by the angle their shading residual gives,
/// clamped to `max_angle` (the edges' own angle).
#[allow(clippy::too_many_arguments)]
pub fn pair_flanks(
    topo: &Topology,
    positions: &[V3],
    normals: &[V3],
    pair: &ProjectedPair,
    shading: &ViewShading,
    residual_gray: &[f32],
    pixels: &TrianglePixels,
    settings: &FlankSettings,
    max_angle: f64,
) -> Vec<Anchor> {
    let tris = topo.triangles();
    let adj = topo.tri_adj();
    let centroid = |t: u32| {
        let q = tris[t as usize].map(|v| positions[v as usize]);
        vec3::scale(vec3::add(vec3::add(q[0], q[1]), q[2]), 1.0 / 3.0)
    };
    let reach = settings.band * pair.width;
    // Seeds: crossed triangles with the edge point and direction that reached them.
    let mut source: HashMap<u32, (V3, V3)> = HashMap::new();
    let mut queue = VecDeque::new();
    for hits in [&pair.a, &pair.b] {
        for k in 0..hits.len() {
            let t = hits[k].triangle;
            if source.contains_key(&t) {
                continue;
            }
            let d = vec3::sub(
                hits[(k + 1).min(hits.len() - 1)].point,
                hits[k.saturating_sub(1)].point,
            );
            let d = vec3::normalize(d);
            if !vec3::is_finite(d) || vec3::norm(d) < 0.5 {
                continue;
            }
            source.insert(t, (hits[k].point, d));
            queue.push_back(t);
        }
    }
    let mut order = Vec::new();
    while let Some(t) = queue.pop_front() {
        let (p, d) = source[&t];
        for &u in &adj[t as usize] {
            if u == NONE || source.contains_key(&u) {
                continue;
            }
            if vec3::norm(vec3::sub(centroid(u), p)) > reach {
                continue;
            }
            source.insert(u, (p, d));
            order.push(u);
            queue.push_back(u);
        }
    }
    let mut out = Vec::new();
    for t in order {
        let (_, d) = source[&t];
        let n = normals[t as usize];
        let d = vec3::normalize(vec3::sub(d, vec3::scale(n, vec3::dot(n, d))));
        if !vec3::is_finite(d) || vec3::norm(d) < 0.5 {
            continue;
        }
        let Some(theta) = triangle_tilt(t, d, shading, residual_gray, pixels, settings) else {
            continue;
        };
        if !theta.is_finite() || theta.abs() < settings.min_tilt {
            continue;
        }
        let angle = theta.abs().min(max_angle);
        // A negative tilt about −d is a positive one about d.
        let axis = if theta > 0.0 { vec3::scale(d, -1.0) } else { d };
        out.push(Anchor {
            triangle: t,
            axis,
            angle,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::folds::video::cameras::Photo;
    use crate::folds::video::pairing::Pair;
    use crate::folds::video::project::MeshCaster;
    use crate::folds::video::shading::surface_image;
    use crate::mesh::geometry;
    use crate::render::CalibratedCamera;

    /// A flat 1 x 1 sheet (5 cm edges) in z = 0 under a camera looking down -z.
    fn setup() -> (std::sync::Arc<Topology>, Vec<V3>, CalibratedCamera) {
        let (topo, frame) = crate::synth::sheet(21, 21, 0.05).unwrap();
        let cam = CalibratedCamera {
            fx: 400.0,
            fy: 400.0,
            cx: 199.5,
            cy: 199.5,
            r: [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            t: [-0.5, 0.5, 2.0],
            width: 400,
            height: 400,
        };
        (topo, frame, cam)
    }

    /// A known Lambertian light from the side (+x, up): grey = 40 + 180 n·L.
    fn light() -> ([f64; 9], V3) {
        let l = vec3::normalize([0.6, 0.0, 0.8]);
        (
            [
                40.0,
                180.0 * l[0],
                180.0 * l[1],
                180.0 * l[2],
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
            ],
            l,
        )
    }

    /// The image of the flat captured sheet whose true triangle normals are `truth(triangle, captured
    /// normal)`, as a residual image under the known light, with that light's [`ViewShading`].
    fn residual(
        topo: &Topology,
        p: &[V3],
        cam: &CalibratedCamera,
        truth: &dyn Fn(u32, V3) -> V3,
    ) -> (ViewShading, Photo) {
        let (coef, l) = light();
        let surface = surface_image(topo, p, cam);
        let gray: Vec<f32> = surface
            .iter()
            .map(|s| match s {
                Some((t, n)) => (40.0 + 180.0 * vec3::dot(truth(*t, *n), l)) as f32,
                None => 0.0,
            })
            .collect();
        let mask: Vec<bool> = surface.iter().map(|s| s.is_some()).collect();
        let photo = Photo {
            width: cam.width,
            height: cam.height,
            rgb: gray.iter().map(|&g| [g; 3]).collect(),
            gray,
            mask,
            has_alpha: true,
        };
        let shading = ViewShading {
            coef,
            mean: 100.0,
            noise: 2.0,
            surface,
        };
        let res = crate::folds::video::shading::residual_of(&photo, &shading);
        (shading, res)
    }

    fn centroid(topo: &Topology, p: &[V3], t: u32) -> V3 {
        let q = topo.triangles()[t as usize].map(|v| p[v as usize]);
        vec3::scale(vec3::add(vec3::add(q[0], q[1]), q[2]), 1.0 / 3.0)
    }

    /// Strips of the sheet tilted by +20° and -12° about the y axis, the rest flat: the shading residual gives
    /// each strip's tilt and sign (Gauss-Newton on the shading, within 1°) and the flat cloth no tilt.
    #[test]
    fn a_flank_tilt_is_read_from_its_shading_residual() {
        let (topo, p, cam) = setup();
        let d = [0.0, 1.0, 0.0];
        let tilt_of = |t: u32| {
            let x = centroid(&topo, &p, t)[0];
            if (0.3..0.4).contains(&x) {
                20f64.to_radians()
            } else if (0.6..0.7).contains(&x) {
                -12f64.to_radians()
            } else {
                0.0
            }
        };
        let (shading, res) = residual(&topo, &p, &cam, &|t, n| {
            rotate(n, vec3::scale(d, -1.0), tilt_of(t))
        });
        let pixels = TrianglePixels::new(&shading, &res.mask, topo.n_triangles());
        let settings = FlankSettings {
            band: 1.0,
            min_tilt: 0.0,
            prior: 1.0,
            min_pixels: 4,
        };
        let mut checked = 0;
        for t in 0..topo.n_triangles() as u32 {
            let c = centroid(&topo, &p, t);
            if !(0.1..0.9).contains(&c[1]) {
                continue;
            }
            let got = triangle_tilt(t, d, &shading, &res.gray, &pixels, &settings).unwrap();
            let want = tilt_of(t);
            // Shrinkage by the prior of 1 rad is far under 1%.
            assert!(
                (got - want).abs() < 1f64.to_radians(),
                "triangle {t} at {c:?}: {} vs {}",
                got.to_degrees(),
                want.to_degrees()
            );
            checked += 1;
        }
        assert!(checked > 300, "{checked}");
        // The same tilt about the opposite direction reads as the opposite angle.
        let t = (0..topo.n_triangles() as u32)
            .find(|&t| tilt_of(t) > 0.0 && centroid(&topo, &p, t)[1] > 0.3)
            .unwrap();
        let flipped = triangle_tilt(t, [0.0, -1.0, 0.0], &shading, &res.gray, &pixels, &settings);
        assert!((flipped.unwrap() + 20f64.to_radians()).abs() < 1f64.to_radians());
        // A prior far below what the data show (0.05°, against ~50 pixels of noise 2) pulls the estimate most of
        // the way to the flat cloth.
        let shy = FlankSettings {
            prior: 0.05f64.to_radians(),
            ..settings
        };
        let small = triangle_tilt(t, d, &shading, &res.gray, &pixels, &shy).unwrap();
        assert!(
            small > 0.0 && small < 5f64.to_radians(),
            "{}",
            small.to_degrees()
        );
    }

    /// A fold pair along y with its flanks tilted (+18° left of it, -15° right of it, flat beyond 0.1 m): the
    /// flank anchors cover the tilted cloth beside the edges, not the crossed triangles or the flat cloth, and
    /// each rotates the captured normal to the true one.
    #[test]
    fn flanks_beside_a_pair_are_anchored_with_the_rotation_their_shading_shows() {
        let (topo, p, cam) = setup();
        let d = [0.0, 1.0, 0.0];
        // Edges at x = 0.42 and 0.52 (pair width 0.1); the flanks 0.32..0.42 and 0.52..0.62.
        let tilt_of = |t: u32| {
            let x = centroid(&topo, &p, t)[0];
            if (0.32..0.42).contains(&x) {
                18f64.to_radians()
            } else if (0.52..0.62).contains(&x) {
                -15f64.to_radians()
            } else {
                0.0
            }
        };
        let (shading, res) = residual(&topo, &p, &cam, &|t, n| {
            rotate(n, vec3::scale(d, -1.0), tilt_of(t))
        });
        let pixels = TrianglePixels::new(&shading, &res.mask, topo.n_triangles());
        let caster = MeshCaster::new(&topo, &p, &cam).unwrap();
        let line = |x: f64| -> Vec<[f64; 2]> {
            (0..30)
                .map(|i| cam.project([x, 0.2 + 0.02 * i as f64, 0.0]).unwrap())
                .collect()
        };
        let (a, _) = caster.cast_polyline(&line(0.42), 0.5, 0.2);
        let (b, _) = caster.cast_polyline(&line(0.52), 0.5, 0.2);
        let crossed: Vec<u32> = a.iter().chain(&b).map(|h| h.triangle).collect();
        let pair = ProjectedPair {
            pair: Pair {
                a: line(0.42),
                b: line(0.52),
                ridge: false,
                width: 0.0,
                length: 0.0,
                midline: Vec::new(),
                level: 0,
            },
            a,
            b,
            width: 0.1,
        };
        let normals = geometry::triangle_normals(&topo, &p);
        let settings = FlankSettings {
            band: 1.0,
            min_tilt: 8f64.to_radians(),
            prior: 30f64.to_radians(),
            min_pixels: 4,
        };
        let max = 40f64.to_radians();
        let anchors = pair_flanks(
            &topo, &p, &normals, &pair, &shading, &res.gray, &pixels, &settings, max,
        );
        assert!(anchors.len() >= 20, "{}", anchors.len());
        let mut sides = [0, 0];
        for a in &anchors {
            assert!(!crossed.contains(&a.triangle), "{a:?}");
            let want = tilt_of(a.triangle);
            assert!(want != 0.0, "flat triangle anchored: {a:?}");
            sides[usize::from(want < 0.0)] += 1;
            let n = normals[a.triangle as usize];
            let got = rotate(n, a.axis, a.angle);
            let truth = rotate(n, vec3::scale(d, -1.0), want);
            let err = vec3::dot(got, truth).clamp(-1.0, 1.0).acos();
            assert!(err < 1.5f64.to_radians(), "{a:?}: {}°", err.to_degrees());
        }
        assert!(sides[0] >= 8 && sides[1] >= 8, "{sides:?}");
        // Nothing beyond one pair width from the edges.
        for a in &anchors {
            let x = centroid(&topo, &p, a.triangle)[0];
            assert!((0.32 - 0.03..0.62 + 0.03).contains(&x), "{x}");
        }
    }
}
