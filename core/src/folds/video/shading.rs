//! Shading the captured mesh under lighting estimated from the image, so that fold edges are found in what the
//! shading of the capture does not explain (beyond Popa et al. 2009, whose cue is raw darkness).
//!
//! "Dark equals deep" holds under diffuse light. Under a directional light, a smooth bend facing away from the
//! light is as dark as a fold, and on one garment a whole view can sit in shadow. The captured mesh already has
//! the garment's large-scale shape, just not the folds, so per camera and frame the lighting is fitted to it:
//! low-order spherical harmonics (order 2, nine coefficients — Lambertian reflection of any distant lighting is
//! within a few percent of that, Ramamoorthi and Hanrahan 2001) of the mesh normal seen at each garment pixel,
//! least squares against the observed grey levels, reweighted (Tukey's biweight on the residual, scale from the
//! median absolute deviation) so the folds themselves do not bend the fit. The image edges are then looked for
//! in the residual `image − shading` (plus the image's mean level, so thresholds keep their meaning). What the
//! capture's shape explains — gradients of directional light, attached shadows — vanishes from it; folds, which
//! the capture lacks, remain, and a valley is still darker than predicted: dark equals deep on the residual.

use super::cameras::Photo;
use crate::mesh::{geometry, Topology};
use crate::render::CalibratedCamera;
use crate::vec3::{self, V3};

/// Number of spherical-harmonic basis functions up to order 2.
const N_SH: usize = 9;
/// Reweighting rounds of the robust fit.
const IRLS_ROUNDS: usize = 6;
/// Tukey biweight constant, in units of the robust residual scale.
const TUKEY_C: f64 = 4.685;

/// The real spherical-harmonic basis of order ≤ 2 at unit normal `n` (constant factors dropped: the fit
/// absorbs them).
pub fn sh_basis(n: V3) -> [f64; N_SH] {
    let [x, y, z] = n;
    [
        1.0,
        x,
        y,
        z,
        x * y,
        y * z,
        x * z,
        x * x - y * y,
        3.0 * z * z - 1.0,
    ]
}

/// The captured mesh's smooth (vertex-interpolated) unit normal at every pixel of `camera`'s image, facing the
/// camera; `None` where the mesh is not seen. A z-buffer rasterisation of the triangles.
pub fn normal_image(
    topo: &Topology,
    positions: &[V3],
    camera: &CalibratedCamera,
) -> Vec<Option<V3>> {
    surface_image(topo, positions, camera)
        .into_iter()
        .map(|s| s.map(|(_, n)| n))
        .collect()
}

/// [`normal_image`] with the triangle seen at every pixel: `(triangle, camera-facing smooth normal)`.
pub fn surface_image(
    topo: &Topology,
    positions: &[V3],
    camera: &CalibratedCamera,
) -> Vec<Option<(u32, V3)>> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let normals = geometry::vertex_normals(topo, positions);
    let cam: Vec<V3> = positions.iter().map(|&p| camera.to_camera(p)).collect();
    let mut depth = vec![f64::INFINITY; w * h];
    let mut hit: Vec<Option<(u32, [f64; 3])>> = vec![None; w * h];
    for (ti, tri) in topo.triangles().iter().enumerate() {
        let q = tri.map(|v| cam[v as usize]);
        if q.iter().any(|c| c[2].is_nan() || c[2] <= 1e-9) {
            continue;
        }
        let uv = q.map(|c| {
            [
                camera.fx * c[0] / c[2] + camera.cx,
                camera.fy * c[1] / c[2] + camera.cy,
            ]
        });
        let det = (uv[1][0] - uv[0][0]) * (uv[2][1] - uv[0][1])
            - (uv[2][0] - uv[0][0]) * (uv[1][1] - uv[0][1]);
        if det.is_nan() || det.abs() <= 1e-12 {
            continue;
        }
        let lo = |k: usize| uv.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min);
        let hi = |k: usize| uv.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max);
        let x0 = lo(0).ceil().max(0.0) as usize;
        let y0 = lo(1).ceil().max(0.0) as usize;
        let x1 = hi(0).floor().min(w as f64 - 1.0);
        let y1 = hi(1).floor().min(h as f64 - 1.0);
        if x1 < 0.0 || y1 < 0.0 {
            continue;
        }
        for y in y0..=y1 as usize {
            for x in x0..=x1 as usize {
                let (px, py) = (x as f64, y as f64);
                let l1 = ((px - uv[0][0]) * (uv[2][1] - uv[0][1])
                    - (uv[2][0] - uv[0][0]) * (py - uv[0][1]))
                    / det;
                let l2 = ((uv[1][0] - uv[0][0]) * (py - uv[0][1])
                    - (px - uv[0][0]) * (uv[1][1] - uv[0][1]))
                    / det;
                let b = [1.0 - l1 - l2, l1, l2];
                if b.iter().any(|&v| v < -1e-9) {
                    continue;
                }
                // Perspective-correct depth: 1/z is affine in the image.
                let inv_z = b[0] / q[0][2] + b[1] / q[1][2] + b[2] / q[2][2];
                let z = 1.0 / inv_z;
                let k = y * w + x;
                if z < depth[k] {
                    depth[k] = z;
                    hit[k] = Some((ti as u32, b));
                }
            }
        }
    }
    let eye = camera.center();
    hit.iter()
        .map(|hk| {
            let (t, b) = (*hk)?;
            let tri = topo.triangles()[t as usize];
            let mut n = [0.0; 3];
            let mut p = [0.0; 3];
            for k in 0..3 {
                n = vec3::add(n, vec3::scale(normals[tri[k] as usize], b[k]));
                p = vec3::add(p, vec3::scale(positions[tri[k] as usize], b[k]));
            }
            let n = vec3::normalize(n);
            if !vec3::is_finite(n) || vec3::norm(n) < 0.5 {
                return None;
            }
            let n = if vec3::dot(n, vec3::sub(eye, p)) < 0.0 {
                vec3::scale(n, -1.0)
            } else {
                n
            };
            Some((t, n))
        })
        .collect()
}

#[allow(clippy::needless_range_loop)]
/// Solves the symmetric positive (semi)definite system `a x = b` by Cholesky, with a tiny ridge.
fn solve(mut a: [[f64; N_SH]; N_SH], b: [f64; N_SH]) -> Option<[f64; N_SH]> {
    let scale = (0..N_SH).map(|i| a[i][i]).fold(0.0, f64::max).max(1e-300);
    for (i, row) in a.iter_mut().enumerate() {
        row[i] += 1e-9 * scale;
    }
    let mut l = [[0.0; N_SH]; N_SH];
    for i in 0..N_SH {
        for j in 0..=i {
            let s: f64 = a[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if s.is_nan() || s <= 0.0 {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut y = [0.0; N_SH];
    for i in 0..N_SH {
        y[i] = (b[i] - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
    }
    let mut x = [0.0; N_SH];
    for i in (0..N_SH).rev() {
        x[i] = (y[i] - (i + 1..N_SH).map(|k| l[k][i] * x[k]).sum::<f64>()) / l[i][i];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[allow(clippy::needless_range_loop)] // Matrix code reads best with indices.
/// Robust least-squares lighting: SH coefficients such that `sh_basis(n) · c ≈ g` over the samples `(n, g)`.
pub fn fit_lighting(samples: &[(V3, f32)]) -> Option<[f64; N_SH]> {
    if samples.len() < 4 * N_SH {
        return None;
    }
    let mut weights = vec![1.0f64; samples.len()];
    let mut coef = None;
    for _ in 0..IRLS_ROUNDS {
        let mut a = [[0.0; N_SH]; N_SH];
        let mut b = [0.0; N_SH];
        for (&(n, g), &w) in samples.iter().zip(&weights) {
            if w <= 0.0 {
                continue;
            }
            let y = sh_basis(n);
            for i in 0..N_SH {
                b[i] += w * y[i] * g as f64;
                for j in 0..=i {
                    a[i][j] += w * y[i] * y[j];
                }
            }
        }
        for i in 0..N_SH {
            for j in 0..i {
                a[j][i] = a[i][j];
            }
        }
        let c = solve(a, b)?;
        let res: Vec<f64> = samples
            .iter()
            .map(|&(n, g)| g as f64 - dot(&sh_basis(n), &c))
            .collect();
        let mut abs: Vec<f64> = res.iter().map(|r| r.abs()).collect();
        let mid = abs.len() / 2;
        let mad = *abs.select_nth_unstable_by(mid, f64::total_cmp).1;
        let sigma = (1.4826 * mad).max(0.5);
        for (w, r) in weights.iter_mut().zip(&res) {
            let u = r / (TUKEY_C * sigma);
            *w = if u.abs() < 1.0 {
                (1.0 - u * u).powi(2)
            } else {
                0.0
            };
        }
        coef = Some(c);
    }
    coef
}

fn dot(a: &[f64; N_SH], b: &[f64; N_SH]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The lighting of one view fitted to the captured mesh, with what it needs to read normals from the residual.
#[derive(Debug, Clone)]
pub struct ViewShading {
    /// Spherical-harmonic coefficients: the shading of unit normal `n` is `sh_basis(n) · coef`.
    pub coef: [f64; N_SH],
    /// Mean grey level of the garment pixels (added back to the residual image).
    pub mean: f64,
    /// Robust scale of the residual over the garment (1.4826 × median absolute residual), grey levels: the
    /// noise a shading-based estimate is weighed against (an overestimate, since folds are part of it).
    pub noise: f64,
    /// Triangle and camera-facing smooth normal of the captured mesh at every pixel, `None` off the mesh.
    pub surface: Vec<Option<(u32, V3)>>,
}

impl ViewShading {
    /// The shading predicted for unit normal `n`.
    pub fn shade(&self, n: V3) -> f64 {
        shade(&self.coef, n)
    }

    /// Gradient of [`Self::shade`] with respect to the normal.
    pub fn shade_gradient(&self, n: V3) -> V3 {
        shade_gradient(&self.coef, n)
    }
}

/// The shading of unit normal `n` under the lighting `coef`: `sh_basis(n) · coef`.
pub fn shade(coef: &[f64; N_SH], n: V3) -> f64 {
    dot(&sh_basis(n), coef)
}

/// Gradient of [`shade`] with respect to the normal (grey levels per radian of tilt along a unit tangent
/// direction, once projected onto it).
pub fn shade_gradient(coef: &[f64; N_SH], n: V3) -> V3 {
    let [x, y, z] = n;
    let c = coef;
    [
        c[1] + c[4] * y + c[6] * z + 2.0 * c[7] * x,
        c[2] + c[4] * x + c[5] * z - 2.0 * c[7] * y,
        c[3] + c[5] * y + c[6] * x + 6.0 * c[8] * z,
    ]
}

/// Fits the lighting of `photo` seen by `camera` to the captured mesh (module documentation). `None` when too
/// few garment pixels see the mesh for a fit.
pub fn fit_view(
    photo: &Photo,
    topo: &Topology,
    positions: &[V3],
    camera: &CalibratedCamera,
) -> Option<ViewShading> {
    if camera.width != photo.width || camera.height != photo.height {
        return None;
    }
    let surface = surface_image(topo, positions, camera);
    let samples: Vec<(V3, f32)> = surface
        .iter()
        .zip(&photo.gray)
        .zip(&photo.mask)
        .filter_map(|((s, &g), &m)| if m { s.map(|(_, n)| (n, g)) } else { None })
        .collect();
    let coef = fit_lighting(&samples)?;
    let mean = samples.iter().map(|s| s.1 as f64).sum::<f64>() / samples.len() as f64;
    let mut abs: Vec<f64> = samples
        .iter()
        .map(|&(n, g)| (g as f64 - dot(&sh_basis(n), &coef)).abs())
        .collect();
    let mid = abs.len() / 2;
    let noise = 1.4826 * *abs.select_nth_unstable_by(mid, f64::total_cmp).1;
    Some(ViewShading {
        coef,
        mean,
        noise,
        surface,
    })
}

/// `photo` with its grey image replaced by the residual of `shading` (module documentation), plus the mean
/// level; colour and mask are kept.
pub fn residual_of(photo: &Photo, shading: &ViewShading) -> Photo {
    let gray = shading
        .surface
        .iter()
        .zip(&photo.gray)
        .zip(&photo.mask)
        .map(|((s, &g), &m)| match s {
            Some((_, n)) if m => {
                (g as f64 - dot(&sh_basis(*n), &shading.coef) + shading.mean) as f32
            }
            _ => shading.mean as f32,
        })
        .collect();
    Photo {
        gray,
        ..photo.clone()
    }
}

/// `photo` with its grey image replaced by the residual of the lighting fitted to the captured mesh seen from
/// `camera` (module documentation); colour and mask are kept. `None` when too few garment pixels see the mesh
/// for a fit (the caller then keeps the raw image).
pub fn residual_photo(
    photo: &Photo,
    topo: &Topology,
    positions: &[V3],
    camera: &CalibratedCamera,
) -> Option<Photo> {
    let shading = fit_view(photo, topo, positions, camera)?;
    Some(residual_of(photo, &shading))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::folds::video::{image_pairs, VideoParams};

    /// A smooth corrugated sheet (no folds: the capture has all of it) under a directional light from the side.
    fn scene() -> (std::sync::Arc<Topology>, Vec<V3>, CalibratedCamera, Photo) {
        let (topo, flat) = crate::synth::sheet(81, 81, 0.0125).unwrap();
        // Wavelength 0.1 (16 px in the image), slopes up to ~30°.
        let p: Vec<V3> = flat
            .iter()
            .map(|q| {
                [
                    q[0],
                    q[1],
                    0.009 * (q[0] * std::f64::consts::TAU / 0.1).sin(),
                ]
            })
            .collect();
        let cam = CalibratedCamera {
            fx: 320.0,
            fy: 320.0,
            cx: 99.5,
            cy: 99.5,
            r: [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            t: [-0.5, 0.5, 2.0],
            width: 200,
            height: 200,
        };
        let light = vec3::normalize([0.8, 0.1, 0.6]);
        let normals = normal_image(&topo, &p, &cam);
        let (mut gray, mut rgb, mut mask) = (Vec::new(), Vec::new(), Vec::new());
        for n in &normals {
            let (g, m) = match n {
                Some(n) => (230.0 * vec3::dot(*n, light).max(0.0) + 10.0, true),
                None => (255.0, false),
            };
            gray.push(g as f32);
            rgb.push([g as f32; 3]);
            mask.push(m);
        }
        let photo = Photo {
            width: 200,
            height: 200,
            gray,
            rgb,
            mask,
            has_alpha: true,
        };
        (topo, p, cam, photo)
    }

    #[test]
    fn lighting_residual_removes_a_directional_light_gradient() {
        let (topo, p, cam, photo) = scene();
        let params = VideoParams::default();
        // Raw darkness: the shading stripes of the smooth waves look like folds.
        let (_, raw) = image_pairs(&photo, &params);
        assert!(!raw.is_empty(), "the raw image should show fold pairs");
        let res = residual_photo(&photo, &topo, &p, &cam).expect("fit");
        let (_, pairs) = image_pairs(&res, &params);
        assert!(
            pairs.is_empty(),
            "{} pairs left: {:?}",
            pairs.len(),
            pairs.first()
        );
        // The residual is flat where the mesh explains the image.
        let inside: Vec<f32> = res
            .gray
            .iter()
            .zip(res.eroded_mask(3.0))
            .filter_map(|(g, m)| m.then_some(*g))
            .collect();
        let (lo, hi) = inside
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &g| {
                (a.min(g), b.max(g))
            });
        assert!(hi - lo < 4.0, "{lo}..{hi}");
    }

    /// Lighting recovered from samples with a fifth of them "folds" (much darker): the fit ignores them.
    #[test]
    fn robust_fit_ignores_outliers() {
        let light = vec3::normalize([0.3, -0.2, 0.9]);
        let mut samples = Vec::new();
        for i in 0..400 {
            let a = i as f64 * 0.37;
            let b = (i as f64 * 0.11).sin() * 0.9;
            let n = vec3::normalize([a.cos() * b, a.sin() * b, 1.0]);
            let g = 40.0 + 180.0 * vec3::dot(n, light);
            let g = if i % 5 == 0 { g - 80.0 } else { g };
            samples.push((n, g as f32));
        }
        let c = fit_lighting(&samples).unwrap();
        let n = vec3::normalize([0.2, 0.1, 1.0]);
        let want = 40.0 + 180.0 * vec3::dot(n, light);
        assert!((dot(&sh_basis(n), &c) - want).abs() < 1.0);
    }
}
