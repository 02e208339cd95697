//! Raw fold-edge candidates: Canny edges at several resolutions and Gaussian radii, chained into pixel polylines
//! and fitted with quadrics (Popa et al. 2009 §4 "Edge Extraction" and "Multi-Resolution Processing").
//!
//! Canny ([`canny`]: imageproc's detector, made fast) smooths with a fixed σ = 1.4, so a level of radius `r` at
//! resolution `s` is made by resampling the image: for `r ≥ 1.4` the image is resized by `s` and blurred by
//! `√(r² − 1.4²)` first; for smaller radii it is enlarged by `s · 1.4 / r`, so that Canny's σ = 1.4 on the
//! enlarged image is `r` pixels of the resolution-`s` image. Edge coordinates are mapped back to full-resolution
//! pixels. Resampling ([`resample`]), blurs ([`blur`]) and Canny reproduce the `image`/imageproc functions this
//! module used before bit for bit, so the edges are the same.

use super::blur::{self, Store};
use super::cameras::Photo;
use super::params::VideoParams;
use super::scratch::Scratch;
use super::{canny, quadric, resample};

/// σ of the Gaussian inside Canny ([`canny::SIGMA`], which is this in `f32`; the level geometry has always used
/// the `f64` value).
const CANNY_SIGMA: f64 = 1.4;

/// One detection level: an image resolution and a Canny radius.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Level {
    /// Fraction of the full resolution.
    pub scale: f64,
    /// Gaussian σ in pixels of the resolution-`scale` image.
    pub radius: f64,
}

/// All (scale, radius) combinations of the parameters, in order.
pub fn levels(params: &VideoParams) -> Vec<Level> {
    params
        .scales
        .iter()
        .flat_map(|&scale| {
            params
                .radii
                .iter()
                .map(move |&radius| Level { scale, radius })
        })
        .collect()
}

/// The edges found at one level, in full-resolution pixel coordinates, and the level's smoothed image for the
/// orientation test.
#[derive(Debug, Clone)]
pub struct LevelEdges {
    pub level: Level,
    /// Level pixels per full-resolution pixel.
    pub factor: f64,
    /// The grey image at the level's pixel grid, blurred by the level's extra Gaussian (before Canny's own).
    pub smoothed: Vec<f32>,
    pub width: u32,
    pub height: u32,
    /// Raw pixel chains (for overlays).
    pub chains: Vec<Vec<[f64; 2]>>,
    /// Quadric-fitted pieces, split where the fit error or curvature is too high.
    pub edges: Vec<Vec<[f64; 2]>>,
}

impl LevelEdges {
    /// Smoothed grey value at a full-resolution point.
    pub fn smoothed_at(&self, p: [f64; 2]) -> f32 {
        super::cameras::bilinear(
            &self.smoothed,
            self.width,
            self.height,
            [p[0] * self.factor, p[1] * self.factor],
        )
    }
}

/// `(v · 255).round().clamp(0, 255) as u8`, as an `f32`: the byte a level pixel becomes for Canny. `round` is
/// a libm call per pixel on baseline x86-64; for `x ≥ 0` the fraction `x − trunc(x)` is exact, so comparing it
/// with ½ rounds half away from zero as `round` does (negative values and NaN end at 0 both ways).
#[inline]
fn to_byte(v: f32) -> f32 {
    let x = v * 255.0;
    let t = (x as i32) as f32;
    let r = if x - t >= 0.5 { t + 1.0 } else { t };
    r.clamp(0.0, 255.0)
}

/// Canny's low and high thresholds at `level`, on a grid of `factor` level pixels per full-resolution pixel.
///
/// Enlarging by `u` divides image gradients by `u`, so the thresholds are scaled to match. The same thresholds
/// hold at every radius: a wider level asks for a contour that much more contrasted, which keeps the soft
/// contours of wide folds out along with the noise (dividing them by the radius found those contours but as
/// many false ones, bench/results/2026-12-02-sleeve-video-kappa.md).
pub fn canny_thresholds(level: Level, factor: f64, params: &VideoParams) -> (f32, f32) {
    let k = level.scale / factor;
    let low = (params.canny_low * k) as f32;
    let high = (params.canny_high * k) as f32;
    (low, high.max(low))
}

/// A level's pixel grid, its image before Canny and its Canny edges.
struct LevelImage {
    /// Level pixels per full-resolution pixel.
    factor: f64,
    width: u32,
    height: u32,
    /// The grey image resampled to the level grid and blurred by the level's extra Gaussian, 0–1.
    image: Scratch<f32>,
    /// Canny edge pixels of the level grid.
    edge_map: Scratch<bool>,
}

/// Resamples and blurs `photo` for `level` and runs Canny on it.
fn level_image(photo: &Photo, level: Level, params: &VideoParams) -> LevelImage {
    let (w, h) = (photo.width, photo.height);
    let (factor, pre_sigma) = if level.radius >= CANNY_SIGMA {
        (
            level.scale,
            (level.radius * level.radius - CANNY_SIGMA * CANNY_SIGMA).sqrt(),
        )
    } else {
        (level.scale * CANNY_SIGMA / level.radius, 0.0)
    };
    let lw = ((w as f64 * factor).round() as u32).max(1);
    let lh = ((h as f64 * factor).round() as u32).max(1);
    let (wu, hu, lwu, lhu) = (w as usize, h as usize, lw as usize, lh as usize);
    // Grey in 0–1, as the `image` crate's resize expects of f32 pixels (it clamps to that range).
    let mut unit = Scratch::filled(wu * hu, 0.0f32);
    for (u, &g) in unit.iter_mut().zip(&photo.gray) {
        *u = g / 255.0;
    }
    let mut img = Scratch::filled(lwu * lhu, 0.0f32);
    resample::resize_triangle(&unit, wu, hu, lwu, lhu, &mut img);
    drop(unit);
    if pre_sigma > 0.05 {
        let mut blurred = Scratch::filled(lwu * lhu, 0.0f32);
        let kernel = blur::gaussian_kernel(pre_sigma as f32);
        blur::separable(&img, lwu, lhu, &kernel, Store::F32, &mut blurred);
        img = blurred;
    }
    let mut gray = Scratch::filled(lwu * lhu, 0.0f32);
    for (g, &v) in gray.iter_mut().zip(img.iter()) {
        *g = to_byte(v);
    }
    let (low, high) = canny_thresholds(level, factor, params);
    let mut edge_map = Scratch::filled(lwu * lhu, false);
    canny::canny(&gray, lwu, lhu, low, high, &mut edge_map);
    LevelImage {
        factor,
        width: lw,
        height: lh,
        image: img,
        edge_map,
    }
}

/// Runs Canny at `level` on `photo`, keeps edge pixels inside `mask` (full-resolution, usually the eroded
/// garment mask), chains and fits them.
pub fn extract(photo: &Photo, mask: &[bool], level: Level, params: &VideoParams) -> LevelEdges {
    let (w, h) = (photo.width, photo.height);
    let LevelImage {
        factor,
        width: lw,
        height: lh,
        image,
        mut edge_map,
    } = level_image(photo, level, params);
    // The orientation test compares brightness a blur radius away on either side of an edge; the pre-blurred
    // level image is smooth enough for that and saves a second blur.
    let mut smoothed = image.into_vec();
    smoothed.iter_mut().for_each(|v| *v *= 255.0);

    let inside = |x: u32, y: u32| {
        let ox = ((x as f64) / factor).round();
        let oy = ((y as f64) / factor).round();
        ox >= 0.0
            && oy >= 0.0
            && ox < w as f64
            && oy < h as f64
            && mask[oy as usize * w as usize + ox as usize]
    };
    for (i, e) in edge_map.iter_mut().enumerate() {
        if *e {
            *e = inside(i as u32 % lw, i as u32 / lw);
        }
    }
    let pixel_chains = chain(&edge_map, lw, lh);
    // Tolerances are given in pixels of the resolution-`scale` image; the level grid may be finer.
    let up = factor / level.scale;
    let mut chains = Vec::with_capacity(pixel_chains.len());
    let mut edges = Vec::new();
    for c in pixel_chains {
        let pts: Vec<[f64; 2]> = c.iter().map(|&(x, y)| [x as f64, y as f64]).collect();
        for piece in quadric::fit_and_split(
            &pts,
            params.fit_tolerance * up,
            params.max_curvature / factor,
            params.min_edge_length * factor,
        ) {
            edges.push(
                piece
                    .iter()
                    .map(|p| [p[0] / factor, p[1] / factor])
                    .collect(),
            );
        }
        chains.push(pts.iter().map(|p| [p[0] / factor, p[1] / factor]).collect());
    }
    LevelEdges {
        level,
        factor,
        smoothed,
        width: lw,
        height: lh,
        chains,
        edges,
    }
}

/// The 8-neighbourhood in the order chaining tries it (the order decides between equally good continuations).
const NB: [(i64, i64); 8] = [
    (1, 0),
    (0, 1),
    (-1, 0),
    (0, -1),
    (1, 1),
    (-1, 1),
    (-1, -1),
    (1, -1),
];

/// Cost of stepping by `NB[k]` after having stepped by `NB[prev]` (or first, `prev = None`): the turn, plus a
/// hundredth of the step length so that straight steps win ties.
fn step_cost(prev: Option<usize>, k: usize) -> f64 {
    let (dx, dy) = NB[k];
    let len = ((dx * dx + dy * dy) as f64).sqrt();
    match prev {
        Some(p) => {
            let (px, py) = NB[p];
            let pl = ((px * px + py * py) as f64).sqrt();
            1.0 - (px * dx + py * dy) as f64 / (pl * len) + 0.01 * len
        }
        None => len,
    }
}

/// Chains the set pixels of a `w x h` edge map into 8-connected polylines. Tracing starts at chain ends and
/// junctions, continues straight through junctions (choosing the neighbour that turns least) and leaves the
/// other branches for later chains; closed loops are traced last. Every set pixel ends up in exactly one chain.
///
/// The map is copied into a grid with a one-pixel empty border (no bounds checks while walking), the step
/// costs are tabulated, and only set pixels are visited when looking for chain starts; the chains are those of
/// the plain per-pixel scan (a unit test compares them).
pub fn chain(on: &[bool], w: u32, h: u32) -> Vec<Vec<(u32, u32)>> {
    const OFF: u8 = 0;
    const ON: u8 = 1;
    const VISITED: u8 = 2;
    let (w, h) = (w as usize, h as usize);
    let pw = w + 2;
    let mut grid = Scratch::filled(pw * (h + 2), OFF);
    let mut starts = Vec::new();
    for (i, _) in on.iter().enumerate().filter(|(_, &b)| b) {
        let g = (i / w + 1) * pw + i % w + 1;
        grid[g] = ON;
        starts.push(g);
    }
    let delta: [isize; 8] = NB.map(|(dx, dy)| dy as isize * pw as isize + dx as isize);
    let mut cost = [[0.0f64; 8]; 9];
    for (p, row) in cost.iter_mut().enumerate() {
        for (k, c) in row.iter_mut().enumerate() {
            *c = step_cost((p < 8).then_some(p), k);
        }
    }
    let at = |g: usize| ((g % pw - 1) as u32, (g / pw - 1) as u32);

    // Walks from g along unvisited pixels, preferring the straightest continuation.
    let walk = |g0: usize, grid: &mut [u8], path: &mut Vec<(u32, u32)>| {
        path.clear();
        let mut g = g0;
        let mut dir = 8; // none yet
        loop {
            let mut best: Option<(usize, f64)> = None;
            for k in 0..8 {
                if grid[g.wrapping_add_signed(delta[k])] != ON {
                    continue;
                }
                let c = cost[dir][k];
                if best.is_none_or(|(_, b)| c < b) {
                    best = Some((k, c));
                }
            }
            let Some((k, _)) = best else { break };
            g = g.wrapping_add_signed(delta[k]);
            grid[g] = VISITED;
            path.push(at(g));
            dir = k;
        }
    };

    let mut out = Vec::new();
    let (mut forward, mut back) = (Vec::new(), Vec::new());
    for pass in 0..2 {
        for &g in &starts {
            if grid[g] != ON {
                continue;
            }
            if pass == 0 {
                let degree = delta
                    .iter()
                    .filter(|&&d| grid[g.wrapping_add_signed(d)] != OFF)
                    .count();
                if degree == 2 {
                    continue;
                }
            }
            grid[g] = VISITED;
            walk(g, &mut grid, &mut forward);
            // Extend backwards from the start too (the start may be in the middle of a loop or a line).
            walk(g, &mut grid, &mut back);
            let mut c: Vec<(u32, u32)> = Vec::with_capacity(back.len() + 1 + forward.len());
            c.extend(back.iter().rev());
            c.push(at(g));
            c.extend_from_slice(&forward);
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`chain`] as it was first written: a scan of every pixel with bounds-checked neighbours and the step
    /// costs computed at every step.
    fn reference_chain(on: &[bool], w: u32, h: u32) -> Vec<Vec<(u32, u32)>> {
        let (w, h) = (w as i64, h as i64);
        let idx = |x: i64, y: i64| (y * w + x) as usize;
        let set = |x: i64, y: i64| x >= 0 && y >= 0 && x < w && y < h && on[idx(x, y)];
        const NB: [(i64, i64); 8] = [
            (1, 0),
            (0, 1),
            (-1, 0),
            (0, -1),
            (1, 1),
            (-1, 1),
            (-1, -1),
            (1, -1),
        ];
        let degree = |x: i64, y: i64| NB.iter().filter(|(dx, dy)| set(x + dx, y + dy)).count();
        let mut visited = vec![false; on.len()];
        let mut out = Vec::new();

        // Walks from (x, y) along unvisited pixels, preferring the straightest continuation.
        let walk = |x0: i64, y0: i64, visited: &mut Vec<bool>, first_dir: Option<(i64, i64)>| {
            let mut path = Vec::new();
            let (mut x, mut y) = (x0, y0);
            let mut dir = first_dir;
            loop {
                let mut best: Option<((i64, i64), f64)> = None;
                for &(dx, dy) in &NB {
                    let (nx, ny) = (x + dx, y + dy);
                    if !set(nx, ny) || visited[idx(nx, ny)] {
                        continue;
                    }
                    let len = ((dx * dx + dy * dy) as f64).sqrt();
                    let cost = match dir {
                        Some((px, py)) => {
                            let pl = ((px * px + py * py) as f64).sqrt();
                            1.0 - (px * dx + py * dy) as f64 / (pl * len) + 0.01 * len
                        }
                        None => len,
                    };
                    if best.is_none_or(|(_, c)| cost < c) {
                        best = Some(((dx, dy), cost));
                    }
                }
                let Some(((dx, dy), _)) = best else { break };
                x += dx;
                y += dy;
                visited[idx(x, y)] = true;
                path.push((x as u32, y as u32));
                dir = Some((dx, dy));
            }
            path
        };

        for pass in 0..2 {
            for y in 0..h {
                for x in 0..w {
                    if !set(x, y) || visited[idx(x, y)] || (pass == 0 && degree(x, y) == 2) {
                        continue;
                    }
                    visited[idx(x, y)] = true;
                    let forward = walk(x, y, &mut visited, None);
                    // Extend backwards from the start too (the start may be in the middle of a loop or a line).
                    let back = walk(x, y, &mut visited, None);
                    let mut c: Vec<(u32, u32)> = back.into_iter().rev().collect();
                    c.push((x as u32, y as u32));
                    c.extend(forward);
                    out.push(c);
                }
            }
        }
        out
    }

    #[test]
    fn bytes_round_like_round() {
        let slow = |v: f32| ((v * 255.0).round().clamp(0.0, 255.0) as u8) as f32;
        let check = |v: f32| assert_eq!(to_byte(v).to_bits(), slow(v).to_bits(), "{v:e}");
        // Thousands of ulps around every half-way point, where rounding decides ...
        for k in 0..256 {
            let mid = (k as f32 + 0.5) / 255.0;
            for d in -3000i32..=3000 {
                check(f32::from_bits((mid.to_bits() as i32 + d) as u32));
            }
        }
        // ... a sweep of [0, 1] and beyond, and the odd values.
        let mut bits = 0u32;
        while bits < 1.2f32.to_bits() {
            check(f32::from_bits(bits));
            check(-f32::from_bits(bits));
            bits += 101;
        }
        for v in [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1e10,
            -1e10,
            3.0,
            1.0,
            0.0,
            -0.0,
        ] {
            check(v);
        }
    }

    #[test]
    fn fast_chaining_equals_the_per_pixel_scan() {
        let mut s = 9u64;
        for &(w, h, density) in &[
            (64u32, 48u32, 3u64),
            (64, 48, 6),
            (31, 77, 2),
            (1, 5, 2),
            (5, 1, 2),
        ] {
            // Random maps (crossings, blobs, loops, pixels on the border) ...
            let on: Vec<bool> = (0..w * h)
                .map(|_| {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    (s >> 40).is_multiple_of(density)
                })
                .collect();
            assert_eq!(chain(&on, w, h), reference_chain(&on, w, h), "{w}x{h}");
        }
        // ... and real Canny maps.
        let img = crate::synth_video::folded_demo_image(4_000, 200, 150).unwrap();
        let photo = Photo::from_rgba(&img);
        let params = VideoParams::default();
        for level in levels(&params) {
            let li = level_image(&photo, level, &params);
            assert_eq!(
                chain(&li.edge_map, li.width, li.height),
                reference_chain(&li.edge_map, li.width, li.height),
                "{level:?}"
            );
        }
    }

    /// The level image and edge map as this module made them with the `image` and imageproc functions.
    fn reference_level_image(photo: &Photo, level: Level, params: &VideoParams) -> LevelImage {
        use image::{GrayImage, ImageBuffer, Luma};
        let (w, h) = (photo.width, photo.height);
        let (factor, pre_sigma) = if level.radius >= CANNY_SIGMA {
            (
                level.scale,
                (level.radius * level.radius - CANNY_SIGMA * CANNY_SIGMA).sqrt(),
            )
        } else {
            (level.scale * CANNY_SIGMA / level.radius, 0.0)
        };
        let lw = ((w as f64 * factor).round() as u32).max(1);
        let lh = ((h as f64 * factor).round() as u32).max(1);
        let unit: Vec<f32> = photo.gray.iter().map(|&g| g / 255.0).collect();
        let base: ImageBuffer<Luma<f32>, Vec<f32>> = ImageBuffer::from_raw(w, h, unit).unwrap();
        let mut img = if (lw, lh) != (w, h) {
            image::imageops::resize(&base, lw, lh, image::imageops::FilterType::Triangle)
        } else {
            base
        };
        if pre_sigma > 0.05 {
            img = imageproc::filter::gaussian_blur_f32(&img, pre_sigma as f32);
        }
        let bytes: Vec<u8> = img
            .as_raw()
            .iter()
            .map(|&v| (v * 255.0).round().clamp(0.0, 255.0) as u8)
            .collect();
        let gray = GrayImage::from_raw(lw, lh, bytes).unwrap();
        let (low, high) = canny_thresholds(level, factor, params);
        let canny = imageproc::edges::canny(&gray, low, high);
        LevelImage {
            factor,
            width: lw,
            height: lh,
            image: {
                let mut m = Scratch::filled((lw * lh) as usize, 0.0f32);
                m.copy_from_slice(img.as_raw());
                m
            },
            edge_map: {
                let mut m = Scratch::filled((lw * lh) as usize, false);
                for (m, v) in m.iter_mut().zip(canny.into_raw()) {
                    *m = v > 0;
                }
                m
            },
        }
    }

    #[test]
    fn level_images_and_edges_match_the_image_and_imageproc_pipeline() {
        // The folded benchmark render at a small size: real fold shading, every default radius and two scales.
        let img = crate::synth_video::folded_demo_image(4_000, 200, 150).unwrap();
        let photo = Photo::from_rgba(&img);
        let params = VideoParams {
            radii: vec![0.5, 1.0, 1.5, 2.5, 3.5],
            scales: vec![1.0, 0.5],
            ..Default::default()
        };
        let mut edge_pixels = 0;
        for level in levels(&params) {
            let got = level_image(&photo, level, &params);
            let want = reference_level_image(&photo, level, &params);
            assert_eq!(
                (got.factor, got.width, got.height),
                (want.factor, want.width, want.height)
            );
            assert!(
                got.image
                    .iter()
                    .zip(want.image.iter())
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{level:?}: level image differs"
            );
            assert!(
                got.edge_map[..] == want.edge_map[..],
                "{level:?}: edge map differs"
            );
            edge_pixels += got.edge_map.iter().filter(|&&e| e).count();
        }
        assert!(edge_pixels > 100, "only {edge_pixels} edge pixels");
    }

    #[test]
    fn chaining_covers_every_pixel_once_and_keeps_lines_whole() {
        let (w, h) = (40u32, 30u32);
        let mut on = vec![false; (w * h) as usize];
        // A diagonal line, a horizontal line crossing it, and a small closed square.
        for i in 0..20 {
            on[((5 + i) * w + 5 + i) as usize] = true;
            on[(15 * w + 2 + i) as usize] = true;
        }
        for i in 0..4 {
            for (x, y) in [(30 + i, 3), (30 + i, 7), (30, 3 + i), (34, 3 + i)] {
                on[(y * w + x) as usize] = true;
            }
        }
        let chains = chain(&on, w, h);
        let total: usize = chains.iter().map(Vec::len).sum();
        assert_eq!(total, on.iter().filter(|&&b| b).count());
        let mut seen = std::collections::HashSet::new();
        for c in &chains {
            for p in c {
                assert!(seen.insert(*p));
            }
            for pair in c.windows(2) {
                let (a, b) = (pair[0], pair[1]);
                assert!(
                    (a.0 as i64 - b.0 as i64).abs() <= 1 && (a.1 as i64 - b.1 as i64).abs() <= 1
                );
            }
        }
        // The longest chain is one of the crossing lines, traced straight through the junction.
        assert!(chains.iter().map(Vec::len).max().unwrap() >= 19);
    }

    #[test]
    fn canny_levels_find_a_step_at_every_radius() {
        let (w, h) = (120u32, 90u32);
        let mut img = image::RgbaImage::from_pixel(w, h, image::Rgba([90, 90, 90, 255]));
        for y in 0..h {
            for x in 60..w {
                img.put_pixel(x, y, image::Rgba([170, 170, 170, 255]));
            }
        }
        let photo = Photo::from_rgba(&img);
        let params = VideoParams {
            radii: vec![0.5, 1.0, 2.5, 4.0],
            scales: vec![1.0, 0.5],
            ..Default::default()
        };
        for level in levels(&params) {
            let e = extract(&photo, &photo.mask, level, &params);
            let long = e
                .edges
                .iter()
                .find(|p| {
                    let mean_x = p.iter().map(|q| q[0]).sum::<f64>() / p.len() as f64;
                    quadric::length(p) > 50.0 && (mean_x - 59.5).abs() < 3.0
                })
                .unwrap_or_else(|| panic!("{level:?}: no long edge"));
            // Vertical, at the step between columns 59 and 60 (away from the image border, where the blur of
            // the coarsest levels bends it).
            for p in long.iter().filter(|p| (15.0..75.0).contains(&p[1])) {
                assert!((p[0] - 59.5).abs() < 1.5, "{level:?}: {p:?}");
            }
        }
    }
}
