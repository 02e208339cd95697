//! Raw fold-edge candidates: Canny edges at several resolutions and Gaussian radii, chained into pixel polylines
//! and fitted with quadrics (Popa et al. 2009 §4 "Edge Extraction" and "Multi-Resolution Processing").
//!
//! `imageproc::edges::canny` smooths with a fixed σ = 1.4, so a level of radius `r` at resolution `s` is made
//! by resampling the image: for `r ≥ 1.4` the image is resized by `s` and blurred by `√(r² − 1.4²)` first; for
//! smaller radii it is enlarged by `s · 1.4 / r`, so that Canny's σ = 1.4 on the enlarged image is `r` pixels of
//! the resolution-`s` image. Edge coordinates are mapped back to full-resolution pixels.

use super::cameras::Photo;
use super::params::VideoParams;
use super::quadric;
use image::{GrayImage, ImageBuffer, Luma};

/// σ of the Gaussian inside `imageproc::edges::canny`.
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

/// Runs Canny at `level` on `photo`, keeps edge pixels inside `mask` (full-resolution, usually the eroded
/// garment mask), chains and fits them.
pub fn extract(photo: &Photo, mask: &[bool], level: Level, params: &VideoParams) -> LevelEdges {
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
    // The `image` crate treats f32 pixels as 0–1 (and clamps to it when resizing).
    let unit: Vec<f32> = photo.gray.iter().map(|&g| g / 255.0).collect();
    let base: ImageBuffer<Luma<f32>, Vec<f32>> =
        ImageBuffer::from_raw(w, h, unit).expect("grey buffer matches the image size");
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
    let gray = GrayImage::from_raw(lw, lh, bytes).expect("byte buffer matches the level size");
    // Enlarging by u divides image gradients by u; scale the thresholds to match.
    let k = (level.scale / factor) as f32;
    let low = params.canny_low as f32 * k;
    let high = params.canny_high as f32 * k;
    let canny = imageproc::edges::canny(&gray, low, high.max(low));
    // The orientation test compares brightness a blur radius away on either side of an edge; the pre-blurred
    // level image is smooth enough for that and saves a second blur.
    let smoothed: Vec<f32> = img.into_raw().into_iter().map(|v| v * 255.0).collect();

    let inside = |x: u32, y: u32| {
        let ox = ((x as f64) / factor).round();
        let oy = ((y as f64) / factor).round();
        ox >= 0.0
            && oy >= 0.0
            && ox < w as f64
            && oy < h as f64
            && mask[oy as usize * w as usize + ox as usize]
    };
    let on: Vec<bool> = canny
        .enumerate_pixels()
        .map(|(x, y, p)| p.0[0] > 0 && inside(x, y))
        .collect();
    let pixel_chains = chain(&on, lw, lh);
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

/// Chains the set pixels of a `w x h` edge map into 8-connected polylines. Tracing starts at chain ends and
/// junctions, continues straight through junctions (choosing the neighbour that turns least) and leaves the
/// other branches for later chains; closed loops are traced last. Every set pixel ends up in exactly one chain.
pub fn chain(on: &[bool], w: u32, h: u32) -> Vec<Vec<(u32, u32)>> {
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

#[cfg(test)]
mod tests {
    use super::*;

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
