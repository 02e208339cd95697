//! Canny edge maps, pixel for pixel those of `imageproc::edges::canny` (imageproc 0.25) on the same `u8` image
//! and thresholds, at a fraction of its cost.
//!
//! imageproc blurs through generic per-pixel accessors, runs Sobel as a 3x3 correlation with a clamp per tap,
//! and calls `atan2` at every pixel to pick the non-maximum-suppression direction. Here the blur is the
//! vectorised [`blur::separable`], Sobel works row by row on a ring of three gradient rows (no image-sized
//! gradient buffers), and the direction is found
//! by comparing the gradient with tan 22.5° and tan 67.5° — only a gradient within 0.1 % of those lines (where
//! the rounding of `atan2` could decide) falls back to imageproc's `atan2` expression. Suppression only runs
//! where the magnitude reaches the low threshold (a suppressed or weaker pixel can never be an edge), and
//! hysteresis keeps imageproc's neighbourhood: from an edge pixel it follows the six neighbours E, SE, S, NW, W,
//! SW, not N or NE. Which pixels end up on does not depend on the order they are reached in, so the map is the
//! same.
//!
//! Gradients are whole numbers of at most 4 × 255 = 1020, so `gx² + gy²` is exact in `f32` and its `f32`
//! square root is imageproc's `f32::hypot` (a unit test checks every gradient pair).

use super::blur::{self, Store};
use super::scratch::Scratch;

/// σ of imageproc's Canny blur.
pub const SIGMA: f32 = 1.4;

/// Suppression direction of a gradient (imageproc's 0°, 45°, 90°, 135° bins).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Bin {
    D0,
    D45,
    D90,
    D135,
}

/// imageproc's binning: `atan2` in degrees, folded into [0, 180).
fn bin_by_angle(gx: f32, gy: f32) -> Bin {
    const RADIANS_TO_DEGREES: f32 = 180f32 / std::f32::consts::PI;
    let mut angle = gy.atan2(gx) * RADIANS_TO_DEGREES;
    if angle < 0.0 {
        angle += 180.0
    }
    if !(22.5..157.5).contains(&angle) {
        Bin::D0
    } else if (22.5..67.5).contains(&angle) {
        Bin::D45
    } else if (67.5..112.5).contains(&angle) {
        Bin::D90
    } else {
        Bin::D135
    }
}

/// The same bins from tangent comparisons; `atan2` only near a bin boundary.
#[inline]
fn bin(gx: f32, gy: f32) -> Bin {
    const TAN_22_5: f32 = 0.414_213_57; // √2 − 1
    const MARGIN: f32 = 1e-3;
    // Fold into the upper half plane: the direction of (gx, gy) and (−gx, −gy) is the same bin.
    let (x, y) = if gy < 0.0 { (-gx, -gy) } else { (gx, gy) };
    let ax = x.abs();
    let near = MARGIN * (ax + y);
    let d0 = y - TAN_22_5 * ax; // < 0: within 22.5° of the x axis
    let d90 = ax - TAN_22_5 * y; // < 0: within 22.5° of the y axis
    if d0.abs() <= near || d90.abs() <= near {
        return bin_by_angle(gx, gy);
    }
    if d0 < 0.0 {
        Bin::D0
    } else if d90 < 0.0 {
        Bin::D90
    } else if x > 0.0 {
        Bin::D45
    } else {
        Bin::D135
    }
}

/// Sobel gradients and their magnitude along row `y` of the blurred `w x h` image `b`, with clamped borders
/// (imageproc pads by continuity). `smooth` and `diff` are row-sized work space.
#[allow(clippy::too_many_arguments)]
fn sobel_row(
    b: &[f32],
    w: usize,
    h: usize,
    y: usize,
    gx: &mut [f32],
    gy: &mut [f32],
    mag: &mut [f32],
    smooth: &mut [f32],
    diff: &mut [f32],
) {
    let up = &b[y.saturating_sub(1) * w..][..w];
    let mid = &b[y * w..][..w];
    let down = &b[(y + 1).min(h - 1) * w..][..w];
    // Per column: the vertical smoothing [1 2 1]ᵀ of the horizontal kernel and the vertical difference of the
    // vertical one; then gx = s(x+1) − s(x−1) and gy = d(x−1) + 2 d(x) + d(x+1). All whole numbers, exact.
    for x in 0..w {
        smooth[x] = up[x] + 2.0 * mid[x] + down[x];
        diff[x] = down[x] - up[x];
    }
    for x in 0..w {
        let (xl, xr) = (x.saturating_sub(1), (x + 1).min(w - 1));
        gx[x] = smooth[xr] - smooth[xl];
        gy[x] = diff[xl] + 2.0 * diff[x] + diff[xr];
    }
    for ((m, &a), &c) in mag.iter_mut().zip(gx.iter()).zip(gy.iter()) {
        *m = (a * a + c * c).sqrt();
    }
}

/// Canny edges of the `w x h` grey image `gray` (whole numbers 0–255, row-major) with hysteresis thresholds
/// `0 < low ≤ high` on the Sobel magnitude (as [`super::VideoParams::validate`] ensures), into `out`: `true`
/// where imageproc's `canny` returns 255.
pub fn canny(gray: &[f32], w: usize, h: usize, low: f32, high: f32, out: &mut [bool]) {
    assert_eq!(gray.len(), w * h, "image buffer matches its size");
    assert_eq!(out.len(), w * h, "edge map matches the image size");
    out.fill(false);
    // imageproc leaves the one-pixel border black and cannot suppress without both neighbours.
    if w < 3 || h < 3 {
        return;
    }
    let n = w * h;
    let mut b = Scratch::filled(n, 0.0f32);
    blur::separable(gray, w, h, &blur::gaussian_kernel(SIGMA), Store::U8, &mut b);

    // Gradients are needed three rows at a time (suppression looks one row up and down): a ring of rows.
    let (mut gx, mut gy, mut mag) = (
        vec![0.0f32; 3 * w],
        vec![0.0f32; 3 * w],
        vec![0.0f32; 3 * w],
    );
    let (mut smooth, mut diff) = (vec![0.0f32; w], vec![0.0f32; w]);
    for y in 0..2 {
        let s = y * w..(y + 1) * w;
        sobel_row(
            &b,
            w,
            h,
            y,
            &mut gx[s.clone()],
            &mut gy[s.clone()],
            &mut mag[s],
            &mut smooth,
            &mut diff,
        );
    }

    // Suppression and thresholds on the interior: 0 below low (or suppressed), 1 weak, 2 strong.
    let mut class = Scratch::filled(n, 0u8);
    for y in 1..h - 1 {
        let s = (y + 1) % 3 * w..((y + 1) % 3 + 1) * w;
        sobel_row(
            &b,
            w,
            h,
            y + 1,
            &mut gx[s.clone()],
            &mut gy[s.clone()],
            &mut mag[s],
            &mut smooth,
            &mut diff,
        );
        let row = |r: usize| (r % 3) * w;
        let (prev, cur, next) = (
            &mag[row(y - 1)..][..w],
            &mag[row(y)..][..w],
            &mag[row(y + 1)..][..w],
        );
        let (gxr, gyr) = (&gx[row(y)..][..w], &gy[row(y)..][..w]);
        let crow = &mut class[y * w..][..w];
        for x in 1..w - 1 {
            let g = cur[x];
            if g < low {
                continue;
            }
            let (c1, c2) = match bin(gxr[x], gyr[x]) {
                Bin::D0 => (cur[x - 1], cur[x + 1]),
                Bin::D45 => (next[x + 1], prev[x - 1]),
                Bin::D90 => (prev[x], next[x]),
                Bin::D135 => (next[x - 1], prev[x + 1]),
            };
            if g < c1 || g < c2 {
                continue;
            }
            crow[x] = if g >= high { 2 } else { 1 };
        }
    }

    // Hysteresis: everything reachable from a strong pixel through weak or strong ones.
    let mut stack: Vec<usize> = Vec::new();
    for seed in 0..n {
        if class[seed] != 2 || out[seed] {
            continue;
        }
        out[seed] = true;
        stack.push(seed);
        while let Some(i) = stack.pop() {
            // Every pixel on the stack is interior, so all six neighbours are inside the image.
            for j in [i + 1, i + w + 1, i + w, i - w - 1, i - 1, i + w - 1] {
                if class[j] != 0 && !out[j] {
                    out[j] = true;
                    stack.push(j);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::GrayImage;

    #[test]
    fn float_square_root_of_whole_gradients_is_hypot() {
        // Every (|gx|, |gy|) Sobel can produce on a u8 image.
        for a in 0..=1020i32 {
            for c in 0..=1020i32 {
                let h = (a as f32).hypot(c as f32);
                let s = ((a * a + c * c) as f32).sqrt();
                assert_eq!(h.to_bits(), s.to_bits(), "({a}, {c})");
            }
        }
    }

    #[test]
    fn bins_from_tangents_match_atan2_for_all_gradients() {
        for a in -1020..=1020i32 {
            for c in -1020..=1020i32 {
                let (x, y) = (a as f32, c as f32);
                assert_eq!(bin(x, y), bin_by_angle(x, y), "({a}, {c})");
            }
        }
    }

    fn imageproc_map(gray: &[f32], w: usize, h: usize, low: f32, high: f32) -> Vec<bool> {
        let bytes: Vec<u8> = gray.iter().map(|&v| v as u8).collect();
        let img = GrayImage::from_raw(w as u32, h as u32, bytes).unwrap();
        imageproc::edges::canny(&img, low, high)
            .into_raw()
            .into_iter()
            .map(|v| v > 0)
            .collect()
    }

    #[test]
    fn edge_maps_match_imageproc_pixel_for_pixel() {
        let mut s = 5u64;
        for &(w, h) in &[(160usize, 120usize), (37, 91), (3, 3), (4, 50)] {
            // Rings, a ramp, steps and noise: edges in every direction, ties and weak chains.
            let img: Vec<f32> = (0..w * h)
                .map(|i| {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let (x, y) = ((i % w) as f32, (i / w) as f32);
                    let r = ((x - 0.4 * w as f32).powi(2) + (y - 0.5 * h as f32).powi(2)).sqrt();
                    let rings = 60.0 * (0.35 * r).sin();
                    let step = if x > 0.7 * w as f32 { 40.0 } else { 0.0 };
                    let noise = ((s >> 40) % 17) as f32;
                    (120.0 + rings + step + 0.3 * y + noise)
                        .clamp(0.0, 255.0)
                        .floor()
                })
                .collect();
            for &(low, high) in &[(12.0f32, 30.0f32), (6.0, 6.0), (40.0, 120.0), (8.4, 21.0)] {
                let mut got = vec![true; w * h];
                canny(&img, w, h, low, high, &mut got);
                let want = imageproc_map(&img, w, h, low, high);
                assert!(
                    want.iter().any(|&v| v) || w * h < 20,
                    "{w}x{h}: no edges at all"
                );
                let diff = got.iter().zip(&want).filter(|(a, b)| a != b).count();
                assert_eq!(diff, 0, "{w}x{h} thresholds {low}/{high}");
            }
        }
    }
}
