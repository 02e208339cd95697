//! The triangle rasterizer: z-buffered, two-sided Lambert shading with a camera-relative key and fill light,
//! smooth (area-weighted vertex normal) or flat shading, per-triangle colours, per-vertex occlusion, and
//! supersampling.
//!
//! # Method
//! Every triangle is rasterized with *homogeneous* edge functions: with camera-space vertices `A, B, C` as the
//! columns of `M`, the rows of `M⁻¹` dotted with the pixel ray `((u - cx) / fx, (v - cy) / fy, 1)` give
//! `e_i = b_i / z`, the barycentric coordinates divided by depth. They are affine in pixel coordinates, a pixel is
//! covered exactly when all three are non-negative, `Σ e_i = 1 / z` is the depth key (larger is nearer), and
//! `b_i = e_i / Σ e` are the perspective-correct barycentrics used for shading. Parts of a triangle behind the
//! camera have `Σ e < 0` and parts in front of the near plane have `Σ e > 1 / near`, so triangles crossing the
//! camera plane need no clipping (only their screen bounding box is computed from the near-clipped polygon).
//!
//! # Determinism and parallelism
//! The image is split into bands of output rows rendered in parallel. Each band rasterizes the triangles binned to
//! it in triangle order, with a strict depth test (the first triangle wins exact ties), and writes only its own
//! rows, so the result is bit-identical for any number of threads.

use super::camera::Projection;
use crate::mesh::Topology;
use crate::vec3::{self, V3};
use image::RgbImage;
use rayon::prelude::*;

/// Default surface colour: a neutral, slightly warm cloth grey.
pub const CLOTH_GREY: [u8; 3] = [188, 186, 180];

/// Appearance options for [`render`]. `Style::default()` gives smooth-shaded cloth grey on white, 2x2
/// supersampled; override fields with struct-update syntax:
/// `Style { triangle_colors: Some(&colors), ..Style::default() }`.
#[derive(Debug, Clone, Copy)]
pub struct Style<'a> {
    /// One colour per triangle (in topology order), shaded like the base colour. Triangles without an entry (a
    /// short slice) use `base_color`.
    pub triangle_colors: Option<&'a [[u8; 3]]>,
    /// Per-vertex brightness multiplier in `[0, 1]` (ambient-occlusion-like darkening), interpolated across
    /// triangles. Missing or non-finite entries count as 1; values are clamped to `[0, 1]`.
    pub vertex_occlusion: Option<&'a [f32]>,
    /// Surface colour when `triangle_colors` is `None`.
    pub base_color: [u8; 3],
    pub background: [u8; 3],
    /// Interpolate area-weighted vertex normals (true) or use face normals (false).
    pub smooth: bool,
    /// Supersampling factor per axis (1 = off, 2 = 2x2, ...), clamped to `1..=4`. The image is rendered at this
    /// multiple of the camera's resolution and box-filtered down.
    pub supersample: u32,
    /// Near-plane distance in world units: surface closer to the camera than this is not drawn. Non-positive or
    /// non-finite values fall back to `1e-9`.
    pub near: f64,
}

impl Default for Style<'_> {
    fn default() -> Self {
        Style {
            triangle_colors: None,
            vertex_occlusion: None,
            base_color: CLOTH_GREY,
            background: [255, 255, 255],
            smooth: true,
            supersample: 2,
            near: 1e-4,
        }
    }
}

/// Output rows per parallel band.
const BAND_ROWS: usize = 8;
const AMBIENT: f64 = 0.16;
const KEY: f64 = 0.74;
const FILL: f64 = 0.30;
/// Direction towards the key light in camera coordinates (x right, y down, z forward): upper left, in front.
const KEY_DIR: V3 = [-0.45, -0.55, -0.80];
/// Direction towards the fill light: right, slightly below, in front.
const FILL_DIR: V3 = [0.75, 0.15, -0.65];

/// Renders a mesh. `positions` are indexed like the topology's vertices; see [`render_triangles`].
pub fn render(
    positions: &[V3],
    topology: &Topology,
    camera: &(impl Projection + ?Sized),
    style: &Style,
) -> RgbImage {
    render_triangles(positions, topology.triangles(), camera, style)
}

/// Renders an indexed triangle list (which need not form a valid [`Topology`]) at the camera's resolution.
///
/// Never panics on bad input: triangles with out-of-range indices, non-finite positions, zero area, or seen
/// exactly edge-on are skipped; a camera with non-finite parameters or zero focal length renders the background.
pub fn render_triangles(
    positions: &[V3],
    triangles: &[[u32; 3]],
    camera: &(impl Projection + ?Sized),
    style: &Style,
) -> RgbImage {
    let cam = camera.calibrated();
    let (w, h) = (cam.width as usize, cam.height as usize);
    let bg = style.background;
    if w == 0 || h == 0 || !cam.is_usable() {
        return RgbImage::from_pixel(cam.width, cam.height, image::Rgb(bg));
    }
    let ss = style.supersample.clamp(1, 4) as usize;
    let ssf = ss as f64;
    let near = if style.near > 0.0 && style.near.is_finite() {
        style.near
    } else {
        1e-9
    };
    // Intrinsics of the supersampled image: output pixel i covers sub-pixels ss*i .. ss*i + ss - 1.
    let k = Intrinsics {
        fx: cam.fx * ssf,
        fy: cam.fy * ssf,
        cx: cam.cx * ssf + 0.5 * (ssf - 1.0),
        cy: cam.cy * ssf + 0.5 * (ssf - 1.0),
        sw: w * ss,
        sh: h * ss,
    };

    let pc: Vec<V3> = positions
        .par_iter()
        .with_min_len(4096)
        .map(|&p| cam.to_camera(p))
        .collect();
    let normals = if style.smooth {
        vertex_normals(&pc, triangles)
    } else {
        Vec::new()
    };
    let setups: Vec<Setup> = triangles
        .par_iter()
        .with_min_len(1024)
        .map(|&t| setup(t, &pc, &k, near).unwrap_or(Setup::EMPTY))
        .collect();

    // Bin triangles to bands (CSR, triangle order within each band).
    let band_sub = BAND_ROWS * ss;
    let n_bands = h.div_ceil(BAND_ROWS);
    let mut offsets = vec![0usize; n_bands + 1];
    for s in setups.iter().filter(|s| s.valid()) {
        for b in s.y0 as usize / band_sub..=s.y1 as usize / band_sub {
            offsets[b + 1] += 1;
        }
    }
    for b in 0..n_bands {
        offsets[b + 1] += offsets[b];
    }
    let mut fill = offsets.clone();
    let mut binned = vec![0u32; offsets[n_bands]];
    for (i, s) in setups.iter().enumerate().filter(|(_, s)| s.valid()) {
        for b in s.y0 as usize / band_sub..=s.y1 as usize / band_sub {
            binned[fill[b]] = i as u32;
            fill[b] += 1;
        }
    }

    let shader = Shader {
        pc: &pc,
        normals: &normals,
        triangles,
        setups: &setups,
        style,
        key: vec3::normalize(KEY_DIR),
        fill: vec3::normalize(FILL_DIR),
    };
    let mut buf = vec![0u8; w * h * 3];
    buf.par_chunks_mut(BAND_ROWS * w * 3)
        .enumerate()
        .for_each(|(b, out)| {
            let rows = out.len() / (w * 3);
            let band = Band {
                sy0: b * band_sub,
                sw: k.sw,
                sh: rows * ss,
            };
            let ids = band.rasterize(&binned[offsets[b]..offsets[b + 1]], &setups, 1.0 / near);
            let n = (ss * ss) as u32;
            for oy in 0..rows {
                for ox in 0..w {
                    let mut acc = [0u32; 3];
                    for sy in oy * ss..(oy + 1) * ss {
                        for sx in ox * ss..(ox + 1) * ss {
                            let id = ids[sy * band.sw + sx];
                            let c = if id == NO_TRI {
                                bg
                            } else {
                                shader
                                    .shade(id as usize, sx as f64, (band.sy0 + sy) as f64)
                                    .unwrap_or(bg)
                            };
                            for ch in 0..3 {
                                acc[ch] += c[ch] as u32;
                            }
                        }
                    }
                    let o = (oy * w + ox) * 3;
                    for ch in 0..3 {
                        out[o + ch] = ((acc[ch] + n / 2) / n) as u8;
                    }
                }
            }
        });
    RgbImage::from_raw(cam.width, cam.height, buf).expect("buffer size matches the image size")
}

const NO_TRI: u32 = u32::MAX;

#[derive(Debug, Clone, Copy)]
struct Intrinsics {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    /// Supersampled image size.
    sw: usize,
    sh: usize,
}

/// Per-triangle rasterization data: `e_i(x, y) = a[i] x + b[i] y + c[i]` in sub-pixel coordinates, and the
/// inclusive sub-pixel bounding box.
#[derive(Debug, Clone, Copy)]
struct Setup {
    a: [f64; 3],
    b: [f64; 3],
    c: [f64; 3],
    x0: u32,
    x1: u32,
    y0: u32,
    y1: u32,
    /// The triangle's winding normal points away from the camera: shading flips it (two-sided lighting).
    flip: bool,
}

impl Setup {
    const EMPTY: Setup = Setup {
        a: [0.0; 3],
        b: [0.0; 3],
        c: [0.0; 3],
        x0: 1,
        x1: 0,
        y0: 1,
        y1: 0,
        flip: false,
    };

    #[inline]
    fn valid(&self) -> bool {
        self.x0 <= self.x1 && self.y0 <= self.y1
    }

    #[inline]
    fn edges(&self, x: f64, y: f64) -> [f64; 3] {
        [
            self.a[0] * x + self.b[0] * y + self.c[0],
            self.a[1] * x + self.b[1] * y + self.c[1],
            self.a[2] * x + self.b[2] * y + self.c[2],
        ]
    }
}

/// Triangle setup; `None` when the triangle cannot or need not be drawn.
fn setup(tri: [u32; 3], pc: &[V3], k: &Intrinsics, near: f64) -> Option<Setup> {
    let idx = tri.map(|v| v as usize);
    if idx.iter().any(|&v| v >= pc.len()) {
        return None;
    }
    let p = idx.map(|v| pc[v]);
    if !p.iter().all(|&q| vec3::is_finite(q)) || p.iter().all(|q| q[2] < near) {
        return None;
    }
    let n = vec3::cross(vec3::sub(p[1], p[0]), vec3::sub(p[2], p[0]));
    let det = vec3::dot(n, p[0]);
    let reach = p.iter().map(|&q| vec3::norm(q)).fold(0.0, f64::max);
    // Skip zero-area triangles and triangles seen edge-on (the camera centre lies in their plane).
    let visible = det.abs() > 1e-10 * vec3::norm(n) * reach;
    if !visible {
        return None;
    }
    let inv = 1.0 / det;
    let rows = [
        vec3::cross(p[1], p[2]),
        vec3::cross(p[2], p[0]),
        vec3::cross(p[0], p[1]),
    ];
    let mut s = Setup {
        flip: det > 0.0,
        ..Setup::EMPTY
    };
    for (i, row) in rows.iter().enumerate() {
        let r = vec3::scale(*row, inv);
        s.a[i] = r[0] / k.fx;
        s.b[i] = r[1] / k.fy;
        s.c[i] = r[2] - s.a[i] * k.cx - s.b[i] * k.cy;
    }
    if !s.a.iter().chain(&s.b).chain(&s.c).all(|v| v.is_finite()) {
        return None;
    }

    // Screen bounding box of the part of the triangle beyond the near plane.
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    let mut include = |q: V3| {
        let uv = [k.fx * q[0] / q[2] + k.cx, k.fy * q[1] / q[2] + k.cy];
        for d in 0..2 {
            lo[d] = lo[d].min(uv[d]);
            hi[d] = hi[d].max(uv[d]);
        }
    };
    for i in 0..3 {
        let (a, b) = (p[i], p[(i + 1) % 3]);
        let (a_in, b_in) = (a[2] >= near, b[2] >= near);
        if a_in {
            include(a);
        }
        if a_in != b_in {
            let t = (near - a[2]) / (b[2] - a[2]);
            let mut m = vec3::add(a, vec3::scale(vec3::sub(b, a), t));
            m[2] = near;
            include(m);
        }
    }
    const SLACK: f64 = 1e-6;
    let x0 = (lo[0] - SLACK).ceil().max(0.0);
    let y0 = (lo[1] - SLACK).ceil().max(0.0);
    let x1 = (hi[0] + SLACK).floor().min(k.sw as f64 - 1.0);
    let y1 = (hi[1] + SLACK).floor().min(k.sh as f64 - 1.0);
    if !(x0 <= x1 && y0 <= y1) {
        return None;
    }
    // The comparisons above fail on NaN, so the casts below see finite values in range.
    s.x0 = x0 as u32;
    s.x1 = x1 as u32;
    s.y0 = y0 as u32;
    s.y1 = y1 as u32;
    Some(s)
}

/// Area-weighted vertex normals (camera space) over the triangles with valid, finite vertices; zero for vertices
/// without any.
fn vertex_normals(pc: &[V3], triangles: &[[u32; 3]]) -> Vec<V3> {
    let mut n = vec![[0.0; 3]; pc.len()];
    for tri in triangles {
        let idx = tri.map(|v| v as usize);
        if idx.iter().any(|&v| v >= pc.len()) {
            continue;
        }
        let p = idx.map(|v| pc[v]);
        let c = vec3::cross(vec3::sub(p[1], p[0]), vec3::sub(p[2], p[0]));
        if !vec3::is_finite(c) {
            continue;
        }
        for v in idx {
            n[v] = vec3::add(n[v], c);
        }
    }
    n.into_iter()
        .map(|v| {
            if vec3::is_finite(v) {
                vec3::normalize(v)
            } else {
                [0.0; 3]
            }
        })
        .collect()
}

/// One band of sub-pixel rows.
struct Band {
    /// First sub-pixel row.
    sy0: usize,
    sw: usize,
    sh: usize,
}

impl Band {
    /// Triangle id of the nearest surface at every sub-pixel of the band ([`NO_TRI`] where there is none). The
    /// depth key is `1 / z` (0 = empty; larger is nearer).
    fn rasterize(&self, tris: &[u32], setups: &[Setup], inv_near: f64) -> Vec<u32> {
        let mut depth = vec![0.0f64; self.sw * self.sh];
        let mut ids = vec![NO_TRI; self.sw * self.sh];
        let band_y1 = self.sy0 + self.sh - 1;
        for &ti in tris {
            let s = &setups[ti as usize];
            let ya = (s.y0 as usize).max(self.sy0);
            let yb = (s.y1 as usize).min(band_y1);
            for y in ya..=yb {
                let yf = y as f64;
                let r = [
                    s.b[0] * yf + s.c[0],
                    s.b[1] * yf + s.c[1],
                    s.b[2] * yf + s.c[2],
                ];
                let row = (y - self.sy0) * self.sw;
                for x in s.x0 as usize..=s.x1 as usize {
                    let xf = x as f64;
                    let e0 = s.a[0] * xf + r[0];
                    let e1 = s.a[1] * xf + r[1];
                    let e2 = s.a[2] * xf + r[2];
                    if e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0 {
                        let inv_z = e0 + e1 + e2;
                        let i = row + x;
                        if inv_z > depth[i] && inv_z < inv_near {
                            depth[i] = inv_z;
                            ids[i] = ti;
                        }
                    }
                }
            }
        }
        ids
    }
}

struct Shader<'a> {
    pc: &'a [V3],
    normals: &'a [V3],
    triangles: &'a [[u32; 3]],
    setups: &'a [Setup],
    style: &'a Style<'a>,
    key: V3,
    fill: V3,
}

impl Shader<'_> {
    /// Colour of triangle `id` at sub-pixel `(x, y)`.
    fn shade(&self, id: usize, x: f64, y: f64) -> Option<[u8; 3]> {
        let s = self.setups.get(id)?;
        let idx = self.triangles.get(id)?.map(|v| v as usize);
        let e = s.edges(x, y);
        let sum = e[0] + e[1] + e[2];
        let bary = [e[0] / sum, e[1] / sum, e[2] / sum];

        let face = || {
            let p = idx.map(|v| self.pc[v]);
            vec3::normalize(vec3::cross(vec3::sub(p[1], p[0]), vec3::sub(p[2], p[0])))
        };
        let mut n = if self.style.smooth && !self.normals.is_empty() {
            let m = (0..3).fold([0.0; 3], |acc, i| {
                vec3::add(acc, vec3::scale(self.normals[idx[i]], bary[i]))
            });
            let len = vec3::norm(m);
            if len > 1e-6 && len.is_finite() {
                vec3::scale(m, 1.0 / len)
            } else {
                face()
            }
        } else {
            face()
        };
        if s.flip {
            n = vec3::scale(n, -1.0);
        }
        let mut light = AMBIENT
            + KEY * vec3::dot(n, self.key).max(0.0)
            + FILL * vec3::dot(n, self.fill).max(0.0);
        if let Some(occ) = self.style.vertex_occlusion {
            if idx.iter().all(|&v| v < occ.len()) {
                let o = (0..3).map(|i| bary[i] * occ[idx[i]] as f64).sum::<f64>();
                if o.is_finite() {
                    light *= o.clamp(0.0, 1.0);
                }
            }
        }
        if !light.is_finite() {
            return None;
        }
        let base = self
            .style
            .triangle_colors
            .and_then(|c| c.get(id).copied())
            .unwrap_or(self.style.base_color);
        Some(base.map(|c| (c as f64 * light).round().clamp(0.0, 255.0) as u8))
    }
}

#[cfg(test)]
mod tests {
    use super::super::camera::{CalibratedCamera, Camera};
    use super::*;
    use crate::mesh::geometry;

    const BG: [u8; 3] = [10, 20, 30];

    fn front_camera(w: u32, h: u32) -> Camera {
        Camera {
            eye: [0.0, 0.0, 3.0],
            target: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 60.0,
            width: w,
            height: h,
        }
    }

    fn style() -> Style<'static> {
        Style {
            background: BG,
            ..Style::default()
        }
    }

    fn px(img: &RgbImage, uv: [f64; 2]) -> [u8; 3] {
        img.get_pixel(uv[0].round() as u32, uv[1].round() as u32).0
    }

    /// A folded sheet: `n x n` vertices over `[-1, 1]²` with sinusoidal folds in z.
    pub(crate) fn folded_sheet(n: usize) -> (Vec<V3>, Vec<[u32; 3]>) {
        let mut p = Vec::with_capacity(n * n);
        for j in 0..n {
            for i in 0..n {
                let x = -1.0 + 2.0 * i as f64 / (n - 1) as f64;
                let y = -1.0 + 2.0 * j as f64 / (n - 1) as f64;
                let z = 0.08 * (9.0 * x + 2.0 * y).sin() + 0.03 * (23.0 * y).cos() * (1.0 - x * x);
                p.push([x, y, z]);
            }
        }
        let mut t = Vec::with_capacity(2 * (n - 1) * (n - 1));
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let v = (j * n + i) as u32;
                let n = n as u32;
                t.push([v, v + 1, v + n + 1]);
                t.push([v, v + n + 1, v + n]);
            }
        }
        (p, t)
    }

    #[test]
    fn single_triangle_lights_centroid_not_corners() {
        let p = vec![[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]];
        let topo = Topology::new(3, vec![[0, 1, 2]]).unwrap();
        let cam = front_camera(64, 48);
        for smooth in [true, false] {
            let img = render(&p, &topo, &cam, &Style { smooth, ..style() });
            assert_eq!(img.dimensions(), (64, 48));
            let c = cam.project([0.0, -1.0 / 3.0, 0.0]).unwrap();
            let lit = px(&img, c);
            assert_ne!(lit, BG);
            // Front-facing grey under the key and fill light: bright but not saturated.
            assert!(lit[0] > 100 && lit[0] < 255, "{lit:?}");
            for corner in [(0, 0), (63, 0), (0, 47), (63, 47)] {
                assert_eq!(img.get_pixel(corner.0, corner.1).0, BG);
            }
        }
        // Two-sided: the same triangle seen from behind is lit just as well.
        let back = Camera {
            eye: [0.0, 0.0, -3.0],
            ..cam
        };
        let img = render(&p, &topo, &back, &style());
        assert_ne!(px(&img, back.project([0.0, -1.0 / 3.0, 0.0]).unwrap()), BG);
    }

    #[test]
    fn nearer_triangle_occludes_farther() {
        // Triangle 0 (red) at z = 0, triangle 1 (green) at z = 0.5 (nearer to the camera at z = 3).
        let p = vec![
            [-1.0, -1.0, 0.0],
            [1.0, -1.0, 0.0],
            [0.0, 1.0, 0.0],
            [-0.5, -0.5, 0.5],
            [0.5, -0.5, 0.5],
            [0.0, 0.5, 0.5],
        ];
        let cam = front_camera(80, 80);
        let colors = [[255, 0, 0], [0, 255, 0]];
        for tris in [vec![[0, 1, 2], [3, 4, 5]], vec![[3, 4, 5], [0, 1, 2]]] {
            let cols: Vec<[u8; 3]> = if tris[0] == [0, 1, 2] {
                colors.to_vec()
            } else {
                vec![colors[1], colors[0]]
            };
            let st = Style {
                triangle_colors: Some(&cols),
                ..style()
            };
            let img = render_triangles(&p, &tris, &cam, &st);
            let centre = px(&img, cam.project([0.0, -0.1, 0.5]).unwrap());
            assert!(centre[1] > 100 && centre[0] == 0, "{centre:?}");
            // Outside the green triangle but inside the red one.
            let red = px(&img, cam.project([0.0, -0.85, 0.0]).unwrap());
            assert!(red[0] > 100 && red[1] == 0, "{red:?}");
        }
    }

    #[test]
    fn render_is_deterministic_across_runs_and_threads() {
        let (p, t) = folded_sheet(60);
        let (lo, hi) = geometry::bounding_box(&p);
        let cam = Camera::fit(lo, hi, [0.3, -0.2, -1.0], [0.0, 1.0, 0.0], 203, 157);
        let occ: Vec<f32> = (0..p.len())
            .map(|i| 0.5 + 0.5 * ((i % 7) as f32 / 6.0))
            .collect();
        let st = Style {
            vertex_occlusion: Some(&occ),
            ..style()
        };
        let a = render_triangles(&p, &t, &cam, &st);
        let b = render_triangles(&p, &t, &cam, &st);
        assert_eq!(a.as_raw(), b.as_raw());
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let c = pool.install(|| render_triangles(&p, &t, &cam, &st));
            assert_eq!(a.as_raw(), c.as_raw(), "{threads} threads");
        }
        // Most of the framed sheet is covered, and folds produce a range of shades.
        let covered = a.pixels().filter(|q| q.0 != BG).count();
        assert!(covered > 203 * 157 / 4, "{covered}");
        let shades: std::collections::BTreeSet<u8> =
            a.pixels().filter(|q| q.0 != BG).map(|q| q.0[0]).collect();
        assert!(shades.len() > 30, "{}", shades.len());
    }

    #[test]
    fn bad_input_does_not_panic() {
        let (mut p, mut t) = folded_sheet(12);
        p[5] = [f64::NAN, 0.0, 0.0];
        p[17] = [f64::INFINITY, 1.0, 0.0];
        p[30] = [0.0, f64::NEG_INFINITY, f64::NAN];
        p[40] = p[41]; // degenerate triangles
        t.push([0, 1, 100_000]); // out of range
        t.push([3, 3, 3]);
        let cam = front_camera(50, 40);
        let colors = vec![[1, 2, 3]; 4]; // shorter than the triangle list
        let occ = vec![f32::NAN; 10];
        let st = Style {
            triangle_colors: Some(&colors),
            vertex_occlusion: Some(&occ),
            supersample: 0,
            near: f64::NAN,
            ..style()
        };
        let img = render_triangles(&p, &t, &cam, &st);
        assert_eq!(img.dimensions(), (50, 40));
        assert!(img.pixels().any(|q| q.0 != BG));
        // Fewer positions than indices, NaN camera, zero-size image, huge supersampling request.
        let _ = render_triangles(&p[..20], &t, &cam, &style());
        let nan_cam = Camera {
            eye: [f64::NAN; 3],
            ..cam
        };
        let img = render_triangles(&p, &t, &nan_cam, &style());
        assert!(img.pixels().all(|q| q.0 == BG));
        let eye_on_target = Camera {
            eye: [0.0; 3],
            ..cam
        };
        let _ = render_triangles(&p, &t, &eye_on_target, &style());
        let _ = render_triangles(&p, &t, &Camera { width: 0, ..cam }, &style());
        let _ = render_triangles(
            &p,
            &t,
            &cam,
            &Style {
                supersample: 1000,
                ..style()
            },
        );
        let _ = render_triangles(&[], &[], &cam, &style());
        let all_nan = vec![[f64::NAN; 3]; p.len()];
        let img = render_triangles(&all_nan, &t, &cam, &style());
        assert!(img.pixels().all(|q| q.0 == BG));
    }

    #[test]
    fn triangles_crossing_the_camera_plane_are_clipped() {
        // A large floor at y = -1 extending behind a camera at the origin looking along -z.
        let p = vec![[-50.0, -1.0, 10.0], [50.0, -1.0, 10.0], [0.0, -1.0, -60.0]];
        let cam = Camera {
            eye: [0.0; 3],
            target: [0.0, 0.0, -1.0],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 60.0,
            width: 40,
            height: 40,
        };
        let img = render_triangles(&p, &[[0, 1, 2]], &cam, &style());
        // Below the horizon is floor, above it is background.
        assert_ne!(img.get_pixel(20, 35).0, BG);
        assert_ne!(img.get_pixel(2, 39).0, BG);
        assert_eq!(img.get_pixel(20, 5).0, BG);
        // Entirely behind the camera: nothing.
        let behind = vec![[-1.0, -1.0, 5.0], [1.0, -1.0, 5.0], [0.0, 1.0, 5.0]];
        let img = render_triangles(&behind, &[[0, 1, 2]], &cam, &style());
        assert!(img.pixels().all(|q| q.0 == BG));
    }

    #[test]
    fn calibrated_camera_renders_where_it_projects() {
        let cam = CalibratedCamera {
            fx: 100.0,
            fy: 120.0,
            cx: 50.0,
            cy: 40.0,
            r: vec3::IDENTITY,
            t: [0.0, 0.0, 5.0],
            width: 100,
            height: 80,
        };
        // A small triangle around world (1, 0.5, 0), which projects to pixel (70, 52).
        let c = [1.0, 0.5, 0.0];
        let p = vec![
            vec3::add(c, [-0.05, -0.05, 0.0]),
            vec3::add(c, [0.05, -0.05, 0.0]),
            vec3::add(c, [0.0, 0.05, 0.0]),
        ];
        let img = render_triangles(&p, &[[0, 1, 2]], &cam, &style());
        assert_ne!(img.get_pixel(70, 52).0, BG);
        assert_eq!(img.get_pixel(50, 40).0, BG);
        let lit = img.pixels().filter(|q| q.0 != BG).count();
        // Area: 0.1 x 0.1 / 2 world units at depth 5 → (2 x 2.4) / 2 pixels, plus partial edge pixels.
        assert!((1..=12).contains(&lit), "{lit}");
    }

    #[test]
    fn smooth_shading_interpolates() {
        let (p, t) = folded_sheet(6);
        let cam = front_camera(120, 120);
        // Horizontally adjacent covered pixels of different colour: with flat shading only where a triangle edge
        // passes, with smooth shading also inside triangles.
        let changes = |smooth| {
            let img = render_triangles(
                &p,
                &t,
                &cam,
                &Style {
                    smooth,
                    supersample: 1,
                    ..style()
                },
            );
            let mut n = 0;
            for y in 0..120 {
                for x in 1..120 {
                    let (a, b) = (img.get_pixel(x - 1, y).0, img.get_pixel(x, y).0);
                    n += (a != BG && b != BG && a != b) as usize;
                }
            }
            n
        };
        let (smooth, flat) = (changes(true), changes(false));
        assert!(smooth > 3 * flat, "{smooth} vs {flat}");
    }

    #[test]
    fn occlusion_darkens() {
        let p = vec![[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]];
        let cam = front_camera(32, 32);
        let occ = [0.5f32; 3];
        let plain = render_triangles(&p, &[[0, 1, 2]], &cam, &style());
        let dark = render_triangles(
            &p,
            &[[0, 1, 2]],
            &cam,
            &Style {
                vertex_occlusion: Some(&occ),
                ..style()
            },
        );
        let a = plain.get_pixel(16, 18).0;
        let b = dark.get_pixel(16, 18).0;
        assert!((b[0] as i32 - a[0] as i32 / 2).abs() <= 1, "{a:?} {b:?}");
    }
}
