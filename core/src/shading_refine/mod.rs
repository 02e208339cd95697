//! Shading-based refinement of a frame from its calibrated images (after Wu et al. 2011, "Shading-based dynamic
//! shape refinement from multi-view video under general illumination"): the surface is moved along its normals
//! until the shading it predicts under the lighting fitted to it matches what the cameras saw.
//!
//! Popa et al. 2009 read the images only for fold *edges*; the fold's height is then whatever the deformation
//! makes of its anchors. The images hold more: on a diffuse garment under distant light the grey level is a
//! function of the surface normal, so where the shape lacks a fold its predicted shading is wrong in a
//! pattern that says which way each part of the fold tilts. The lighting is fitted per view and frame to the
//! mesh being refined (order-2 spherical harmonics, robust, [`crate::folds::video::shading`]); the refinement
//! then solves for one offset per vertex along its normal, linearised around the current shape:
//!
//! * **data**: per garment pixel seen by a view, the residual `image − shading(n)` against the change of
//!   shading a change of normal causes, `∇shading · δn`, where `δn = −∇h` is the tilt made by the offsets `h`
//!   interpolated over the triangle under the pixel (Tukey-weighted with the view's residual scale, so cast
//!   shadows, specks and misregistered silhouette pixels drop out);
//! * **smoothness**: the squared umbrella Laplacian of the offsets, so the image's grain does not become
//!   bumps;
//! * **prior**: the offsets themselves, so where no view says anything the input shape (with the folds the
//!   anchors made) stays.
//!
//! Each view's pixels count by the inverse square of that image's own grain (read from the image: a pixel
//! against its eight neighbours), and the offsets are measured in fifths of the sequence's detail scale with the
//! priors per unit of surface, so a noisy camera is trusted less and the settings mean the same in any units and
//! on the same garment meshed finer. A few Gauss–Newton rounds re-render
//! the moved surface; the lighting stays the one fitted to the input. Image grey levels are taken back to linear
//! radiance (the sRGB transfer curve) first, where Lambert's law holds. Last, the offsets lose their long
//! wavelengths (the positioning's shape projection at its shape scale): shading says little about them, and
//! the garment's shape is the capture's.

mod images;
mod solve;

pub use images::ImageRefiner;

use crate::error::{Error, Result};
use crate::folds::video::cameras::Photo;
use crate::folds::video::shading;
use crate::heat::{self, SurfaceOperator};
use crate::mesh::{geometry, Topology};
use crate::render::CalibratedCamera;
use crate::shape::mean_edge_length;
use crate::spacetime::shape::lost_area::Trace;
use crate::spacetime::shape::relief::DEFAULT_SCALE_EDGES;
use crate::spacetime::shape::{projection, SHAPE_SCALES};
use crate::vec3::{self, V3};

/// Tukey biweight constant, in units of a view's robust residual scale.
const TUKEY_C: f64 = 4.685;
/// Smallest image grain assumed (linear grey levels): half a step of an 8-bit image.
const GRAIN_FLOOR: f64 = 0.5;

/// How strongly the refinement follows the images.
#[derive(Debug, Clone, PartialEq)]
pub struct ShadingRefineParams {
    /// Gauss–Newton rounds (each re-renders the surface); 0 turns the refinement off. Three by default: each
    /// round linearises the shading around the surface the last one moved, and where the capture erased its
    /// folds the first two leave part of a fold's tilt unexplained (a third raised the fold agreement on both
    /// erased captures measured, and on most others, for about a third more refinement time).
    pub rounds: usize,
    /// Weight of the offsets' squared umbrella Laplacian, the offsets measured in mean edge lengths, against
    /// the data's squared residuals measured in the images' grain.
    pub smoothness: f64,
    /// Weight of the offsets themselves (staying at the input shape), in the same units.
    pub stay: f64,
    /// The stay weight where the capture kept no trace of the surface it lost there (its fold relief gives back
    /// none of it; [`crate::spacetime::shape::lost_area::Trace`]), rising to `stay` where the relief gives back
    /// `erased_share` of it. Why: where the capture kept an attenuated copy of a fold, the input shape (the
    /// relief's sharpened copy) is a good prior and the images only correct it; where it erased the fold, the
    /// input holds only the anchors' rough fold and the images are the one precise source.
    pub erased_stay: f64,
    /// The share of its lost surface given back by the relief from which a vertex's stay is `stay`; 0 turns
    /// the lower stay off.
    pub erased_share: f64,
    /// The stay weight where the relief gives back all of the surface the capture lost, rising geometrically
    /// from `stay` at `erased_share`. Why: where the capture kept its folds in attenuated form the relief has
    /// already restored them, and what the images would add there is mostly the shading model's own error.
    pub kept_stay: f64,
    /// Pixels this close to the garment's silhouette in an image are not used (misregistration).
    pub margin_px: f64,
    /// Pixels whose surface is seen more obliquely than this (cosine between normal and view ray) are not used.
    pub min_facing: f64,
    /// Largest offset, in fifths of the detail scale (mean edge lengths at the default one): a round's step is
    /// scaled down to keep every offset within it.
    pub max_offset_edges: f64,
    /// Wavelength below which the offsets are kept, in the mesh's units; their longer part (which moves the
    /// garment rather than folding it) is removed as the positioning's shape projection removes it. 0: the
    /// positioning's shape scale, twice the detail scale.
    pub shape_scale: f64,
    /// The sequence's detail scale ([`crate::spacetime::shape::relief`]), in the mesh's units; the offsets,
    /// their bound and the stay are measured in fifths of it ("detail edges"), so that the same garment meshed
    /// finer is refined the same way (the stay is a weight per vertex: in mean edge lengths it would grow with
    /// the fourth power of the resolution and hold a fine mesh still). 0: five mean edge lengths of the frame
    /// (the detail scale's own default).
    pub detail_scale: f64,
}

impl Default for ShadingRefineParams {
    fn default() -> Self {
        ShadingRefineParams {
            rounds: 3,
            smoothness: 5.0e3,
            stay: 5.0e3,
            erased_stay: 1.0e3,
            erased_share: 0.2,
            kept_stay: 2.0e4,
            margin_px: 2.0,
            min_facing: 0.25,
            max_offset_edges: 1.5,
            shape_scale: 0.0,
            detail_scale: 0.0,
        }
    }
}

impl ShadingRefineParams {
    /// Checks every field, naming the one out of range.
    pub fn validate(&self) -> Result<()> {
        let check = |name: &str, v: f64, ok: bool, want: &str| {
            if v.is_finite() && ok {
                Ok(())
            } else {
                Err(Error::param(name, format!("{v} is not {want}")))
            }
        };
        check(
            "smoothness",
            self.smoothness,
            self.smoothness >= 0.0,
            "a finite value ≥ 0",
        )?;
        check("stay", self.stay, self.stay > 0.0, "a finite value > 0")?;
        check(
            "erased_stay",
            self.erased_stay,
            self.erased_stay > 0.0,
            "a finite value > 0",
        )?;
        check(
            "kept_stay",
            self.kept_stay,
            self.kept_stay > 0.0,
            "a finite value > 0",
        )?;
        check(
            "erased_share",
            self.erased_share,
            (0.0..=1.0).contains(&self.erased_share),
            "a share in [0, 1]",
        )?;
        check(
            "margin_px",
            self.margin_px,
            self.margin_px >= 0.0,
            "a finite value ≥ 0",
        )?;
        check(
            "min_facing",
            self.min_facing,
            (0.0..1.0).contains(&self.min_facing),
            "in [0, 1)",
        )?;
        check(
            "scale",
            self.shape_scale,
            self.shape_scale >= 0.0,
            "a length ≥ 0 (0 = automatic)",
        )?;
        check(
            "detail_scale",
            self.detail_scale,
            self.detail_scale >= 0.0,
            "a length ≥ 0 (0 = five mean edge lengths)",
        )?;
        check(
            "max_offset",
            self.max_offset_edges,
            self.max_offset_edges > 0.0,
            "a finite value > 0",
        )
    }
}

/// Per vertex, the stay weight: from [`ShadingRefineParams::erased_stay`] where the relief gives back none of
/// what the capture lost there, through `stay` at `erased_share`, to `kept_stay` where it gives back all; `stay`
/// where the vertex lost nothing, and everywhere without a trace (or with one for another mesh).
fn stay_weights(params: &ShadingRefineParams, trace: Option<&Trace>, n: usize) -> Vec<f64> {
    let given = trace.map(|t| t.given_back()).filter(|g| g.len() == n);
    let Some(given) = given else {
        return vec![params.stay; n];
    };
    given
        .iter()
        .map(|g| match *g {
            None => params.stay,
            Some(g) if g < params.erased_share => {
                params.erased_stay + (params.stay - params.erased_stay) * g / params.erased_share
            }
            Some(g) => {
                let up = if params.erased_share < 1.0 {
                    (g - params.erased_share) / (1.0 - params.erased_share)
                } else {
                    0.0
                };
                params.stay * (params.kept_stay / params.stay).powf(up)
            }
        })
        .collect()
}

/// One calibrated view of the frame.
pub struct RefineView<'a> {
    pub camera: &'a CalibratedCamera,
    pub photo: &'a Photo,
}

/// A refined frame and what the images said.
#[derive(Debug, Clone)]
pub struct Refined {
    pub positions: Vec<V3>,
    /// Offset of every vertex along its normal, in the mesh's units.
    pub offsets: Vec<f64>,
    /// Views whose lighting could be fitted (the others were not used).
    pub views_used: usize,
    /// Weighted RMS of the shading residual (linear grey levels, 0–255) of the first and the last round, over
    /// the pixels each used.
    pub residual_first: f64,
    pub residual_last: f64,
}

/// sRGB-encoded grey (0–255) to linear radiance on the same scale.
fn linear_grey(g: f32) -> f32 {
    let c = (g / 255.0).clamp(0.0, 1.0);
    let lin = if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    };
    255.0 * lin
}

/// The grey image in linear radiance on the garment's pixels (0 elsewhere), through a table of the sRGB curve
/// (a quarter grey level apart, linear in between: far below an 8-bit image's step).
fn linear_gray(p: &Photo) -> Vec<f32> {
    const STEPS: usize = 1024;
    let table: Vec<f32> = (0..=STEPS)
        .map(|i| linear_grey(255.0 * i as f32 / STEPS as f32))
        .collect();
    p.gray
        .iter()
        .zip(&p.mask)
        .map(|(&g, &m)| {
            if !m {
                return 0.0;
            }
            let x = (g.clamp(0.0, 255.0) / 255.0) * STEPS as f32;
            let i = (x as usize).min(STEPS - 1);
            let f = x - i as f32;
            table[i] * (1.0 - f) + table[i + 1] * f
        })
        .collect()
}

/// One view ready for the refinement: its linear image, the lighting fitted to the input, and what every round
/// reuses (the pixels away from the silhouette, the image's grain and the outlier scale).
struct LitView<'a> {
    camera: &'a CalibratedCamera,
    gray: Vec<f32>,
    width: usize,
    /// Spherical-harmonic lighting fitted to the input ([`shading::shade`]).
    lighting: [f64; 9],
    inner: Vec<bool>,
    /// 1 / grain²: how much one pixel of this image counts.
    precision: f64,
    /// Residuals beyond this are outliers (Tukey's biweight).
    reject: f64,
}

/// Every `LIGHTING_STRIDE`-th pixel along each axis feeds the lighting fit: nine coefficients need far fewer
/// than a view's tens of thousands of garment pixels.
const LIGHTING_STRIDE: usize = 2;

/// What a view's camera sees of the mesh at every pixel: triangle and camera-facing smooth normal.
type Surface = Vec<Option<(u32, V3)>>;

/// The view ready for the rounds, and its rendering of `positions` (the first round's, so it is not rendered
/// twice).
fn lit_view<'a>(
    view: RefineView<'a>,
    topo: &Topology,
    positions: &[V3],
    params: &ShadingRefineParams,
) -> Option<(LitView<'a>, Surface)> {
    let (photo, camera) = (view.photo, view.camera);
    if camera.width != photo.width || camera.height != photo.height {
        return None;
    }
    let gray = linear_gray(photo);
    let width = photo.width as usize;
    let surface = shading::surface_image(topo, positions, camera);
    let samples: Vec<(V3, f32)> = surface
        .iter()
        .enumerate()
        .filter(|(k, _)| {
            (k % width).is_multiple_of(LIGHTING_STRIDE)
                && (k / width).is_multiple_of(LIGHTING_STRIDE)
        })
        .filter_map(|(k, s)| photo.mask[k].then_some(((*s)?.1, gray[k])))
        .collect();
    let coef = shading::fit_lighting(&samples)?;
    let mut abs: Vec<f64> = samples
        .iter()
        .map(|&(n, g)| (g as f64 - shading::shade(&coef, n)).abs())
        .collect();
    let mid = abs.len() / 2;
    let noise = 1.4826 * *abs.select_nth_unstable_by(mid, f64::total_cmp).1;
    let inner = photo.eroded_mask(params.margin_px);
    let grain = image_grain(&gray, width, &inner);
    // Pixels the lighting explains worse than the view's own residual scale would suggest are cast shadows,
    // specks or misregistration; but never reject what a tilt of half a radian explains (a clean image's
    // residual scale is tiny, and its folds would all look like outliers).
    let contrast = (coef[1] * coef[1] + coef[2] * coef[2] + coef[3] * coef[3]).sqrt();
    let reject = (TUKEY_C * noise).max(0.5 * contrast).max(GRAIN_FLOOR);
    Some((
        LitView {
            camera,
            gray,
            width,
            lighting: coef,
            inner,
            precision: 1.0 / (grain * grain),
            reject,
        },
        surface,
    ))
}

/// The image's own grain (linear grey levels): the robust spread of each garment pixel against the mean of its
/// eight neighbours, where all nine are inside `inner`. Shading varies little over three pixels; sensor noise,
/// a renderer's sampling grain and compression do not, so this reads the noise from the image without any
/// model of where it came from. Floored at half an 8-bit step.
fn image_grain(gray: &[f32], w: usize, inner: &[bool]) -> f64 {
    let h = gray.len().checked_div(w).unwrap_or(0);
    let mut dev = Vec::new();
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let k = y * w + x;
            let around = [
                k - w - 1,
                k - w,
                k - w + 1,
                k - 1,
                k + 1,
                k + w - 1,
                k + w,
                k + w + 1,
            ];
            if !inner[k] || around.iter().any(|&j| !inner[j]) {
                continue;
            }
            let mean = around.iter().map(|&j| gray[j] as f64).sum::<f64>() / 8.0;
            dev.push((gray[k] as f64 - mean).abs());
        }
    }
    if dev.is_empty() {
        return GRAIN_FLOOR;
    }
    let mid = dev.len() / 2;
    let mad = *dev.select_nth_unstable_by(mid, f64::total_cmp).1;
    // A pixel minus the mean of eight independent others has 1 + 1/8 times the pixel's variance.
    (1.4826 * mad / (1.0f64 + 1.0 / 8.0).sqrt()).max(GRAIN_FLOOR)
}

/// Per-triangle normal equations of the data term: `H` (3 × 3, symmetric) and `g` over the triangle's vertices.
struct DataTerm {
    h: Vec<[[f64; 3]; 3]>,
    g: Vec<[f64; 3]>,
    weighted_sq: f64,
    weight: f64,
}

/// The gradient of each vertex's hat function over triangle `t`, scaled by how much of the vertex's normal
/// offset is a height over the triangle's plane.
fn hat_gradients(p: &[V3], tri: [u32; 3], vn: &[V3]) -> Option<(V3, [V3; 3])> {
    let [a, b, c] = tri.map(|v| p[v as usize]);
    let cr = vec3::cross(vec3::sub(b, a), vec3::sub(c, a));
    let twice_area = vec3::norm(cr);
    if !twice_area.is_finite() || twice_area <= 0.0 {
        return None;
    }
    let n = vec3::scale(cr, 1.0 / twice_area);
    let edges = [vec3::sub(c, b), vec3::sub(a, c), vec3::sub(b, a)];
    let grads = std::array::from_fn(|i| {
        let g = vec3::scale(vec3::cross(n, edges[i]), 1.0 / twice_area);
        vec3::scale(g, vec3::dot(vn[tri[i] as usize], n))
    });
    Some((n, grads))
}

/// The data term at `positions`; `rendered` holds the views' renderings of exactly these positions when they
/// are at hand (else each view is rendered).
fn data_term(
    topo: &Topology,
    positions: &[V3],
    views: &[LitView<'_>],
    rendered: Vec<Surface>,
    params: &ShadingRefineParams,
) -> DataTerm {
    let tris = topo.triangles();
    let vn = geometry::vertex_normals(topo, positions);
    let frames: Vec<Option<(V3, [V3; 3])>> = tris
        .iter()
        .map(|&t| hat_gradients(positions, t, &vn))
        .collect();
    let mut out = DataTerm {
        h: vec![[[0.0; 3]; 3]; tris.len()],
        g: vec![[0.0; 3]; tris.len()],
        weighted_sq: 0.0,
        weight: 0.0,
    };
    let mut rendered = rendered.into_iter();
    for view in views {
        let surface = match rendered.next() {
            Some(s) => s,
            None => shading::surface_image(topo, positions, view.camera),
        };
        let w = view.width;
        for (k, s) in surface.iter().enumerate() {
            let Some((t, n)) = *s else { continue };
            if !view.inner[k] {
                continue;
            }
            let Some((face_n, grads)) = frames[t as usize] else {
                continue;
            };
            let ray = view.camera.ray_direction([(k % w) as f64, (k / w) as f64]);
            if -vec3::dot(ray, n) < params.min_facing {
                continue;
            }
            let r = view.gray[k] as f64 - shading::shade(&view.lighting, n);
            let u = r / view.reject;
            if u.abs() >= 1.0 {
                continue;
            }
            let wt = view.precision * (1.0 - u * u).powi(2);
            let mut jac = shading::shade_gradient(&view.lighting, n);
            jac = vec3::sub(jac, vec3::scale(n, vec3::dot(jac, n)));
            let side = if vec3::dot(n, face_n) >= 0.0 {
                1.0
            } else {
                -1.0
            };
            let a: [f64; 3] = std::array::from_fn(|i| -side * vec3::dot(jac, grads[i]));
            let (h, g) = (&mut out.h[t as usize], &mut out.g[t as usize]);
            for i in 0..3 {
                g[i] += wt * a[i] * r;
                for j in 0..3 {
                    h[i][j] += wt * a[i] * a[j];
                }
            }
            out.weighted_sq += wt * r * r;
            out.weight += wt;
        }
    }
    out
}

/// Refines one frame (module documentation). `positions` is the shape to refine (its folds are the prior); a
/// view whose lighting cannot be fitted (too little garment seen) is left out, and with no view left the frame
/// comes back unchanged.
pub fn refine_frame(
    topo: &Topology,
    positions: &[V3],
    views: Vec<RefineView<'_>>,
    params: &ShadingRefineParams,
) -> Result<Refined> {
    refine_frame_traced(topo, positions, views, params, None)
}

/// [`refine_frame`] with the stay weight following `trace`, what the frame's fold relief gives back of the
/// surface its capture lost: lower where the capture erased the fold, higher where the relief restored it.
pub fn refine_frame_traced(
    topo: &Topology,
    positions: &[V3],
    views: Vec<RefineView<'_>>,
    params: &ShadingRefineParams,
    trace: Option<&Trace>,
) -> Result<Refined> {
    params.validate()?;
    if positions.len() != topo.n_vertices() {
        return Err(Error::param(
            "positions",
            format!(
                "{} positions for a mesh of {} vertices",
                positions.len(),
                topo.n_vertices()
            ),
        ));
    }
    let n = positions.len();
    let (lit, mut rendered): (Vec<LitView<'_>>, Vec<Surface>) = views
        .into_iter()
        .filter_map(|v| lit_view(v, topo, positions, params))
        .unzip();
    let refined = |cur: Vec<V3>, offsets: Vec<f64>, first: f64, last: f64| Refined {
        positions: cur,
        offsets,
        views_used: lit.len(),
        residual_first: first,
        residual_last: last,
    };
    if lit.is_empty() || params.rounds == 0 {
        return Ok(refined(positions.to_vec(), vec![0.0; n], 0.0, 0.0));
    }
    let neighbours: Vec<Vec<u32>> = (0..n).map(|v| topo.vertex_neighbors(v)).collect();
    let edge = mean_edge_length(topo, positions);
    // The detail edge: the unit of the offsets' bound and of the stay (field documentation). A stay per vertex
    // over offsets in mean edge lengths weighs (edge / unit)⁴ as much per area as over offsets in detail edges.
    let unit = if params.detail_scale > 0.0 {
        params.detail_scale / DEFAULT_SCALE_EDGES
    } else {
        edge
    };
    let density = (edge / unit).powi(4);
    let stay: Vec<f64> = stay_weights(params, trace, n)
        .into_iter()
        .map(|w| w * density)
        .collect();
    let max_offset = params.max_offset_edges * unit;
    // Weighted mean square residual, back in grey levels (the weights carry 1 / grain²).
    let rms = |d: &DataTerm| {
        if d.weight > 0.0 {
            (d.weighted_sq / d.weight).sqrt()
        } else {
            0.0
        }
    };
    let mut cur = positions.to_vec();
    let mut offsets = vec![0.0; n];
    let (mut first, mut last) = (None, 0.0);
    for _ in 0..params.rounds {
        let data = data_term(topo, &cur, &lit, std::mem::take(&mut rendered), params);
        last = rms(&data);
        first.get_or_insert(last);
        let step = solve::solve_offsets(
            topo,
            &neighbours,
            &data.h,
            &data.g,
            &offsets,
            params,
            &stay,
            edge,
        );
        let Some(step) = step else { break };
        // Keep every offset within the bound: scale the whole step, so its direction stays the solve's.
        let mut s: f64 = 1.0;
        for (o, d) in offsets.iter().zip(&step) {
            if (o + d).abs() > max_offset && d.abs() > 0.0 {
                s = s.min(((max_offset - o.abs()).max(0.0) / d.abs()).min(1.0));
            }
        }
        let vn = geometry::vertex_normals(topo, &cur);
        for v in 0..n {
            let d = s * step[v];
            offsets[v] += d;
            cur[v] = vec3::add(cur[v], vec3::scale(vn[v], d));
        }
    }
    let scale = if params.shape_scale > 0.0 {
        params.shape_scale
    } else {
        SHAPE_SCALES * DEFAULT_SCALE_EDGES * unit
    };
    let op = SurfaceOperator::with_rims_along_themselves(topo, positions);
    let cur = projection::project(&op, &heat::low_pass(&op, scale), positions, &cur, 1.0);
    if geometry::find_problem(topo, &cur).is_some() {
        // A fold folded over itself: the input is the safer answer.
        return Ok(refined(positions.to_vec(), vec![0.0; n], 0.0, 0.0));
    }
    // What is left of the offsets after the projection, along the input's normals.
    let vn = geometry::vertex_normals(topo, positions);
    let offsets = (0..n)
        .map(|v| vec3::dot(vec3::sub(cur[v], positions[v]), vn[v]))
        .collect();
    Ok(refined(cur, offsets, first.unwrap_or(0.0), last))
}

#[cfg(test)]
mod tests;
