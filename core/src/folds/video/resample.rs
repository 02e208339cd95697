//! Resizing a one-channel `f32` image with the triangle (bilinear) filter, bit for bit as
//! `image::imageops::resize(.., FilterType::Triangle)` (image 0.25) resizes a `Luma<f32>` image: columns first,
//! then rows, weights normalised per output pixel, the result clamped to 0–1. The `image` crate does this on
//! four channels through generic pixel accessors; the detection levels only need one, and the column pass here
//! runs over whole rows so that it vectorises.

use super::scratch::Scratch;

/// The source pixels and normalised weights of every output pixel along one axis.
struct Taps {
    /// First source pixel of each output pixel.
    first: Vec<usize>,
    /// Weights of each output pixel (as many as it has source pixels), in source order.
    weights: Vec<Vec<f32>>,
}

/// The `image` crate's sampling geometry for `n` source pixels resized to `m`, with the triangle kernel.
fn taps(n: usize, m: usize) -> Taps {
    let ratio = n as f32 / m as f32;
    let sratio = if ratio < 1.0 { 1.0 } else { ratio };
    // The triangle filter's support is 1.
    let support = sratio;
    let kernel = |x: f32| {
        if x.abs() < 1.0 {
            1.0 - x.abs()
        } else {
            0.0
        }
    };
    let mut first = Vec::with_capacity(m);
    let mut weights = Vec::with_capacity(m);
    for o in 0..m {
        let centre = (o as f32 + 0.5) * ratio;
        let left = ((centre - support).floor() as i64).clamp(0, n as i64 - 1) as usize;
        let right = ((centre + support).ceil() as i64).clamp(left as i64 + 1, n as i64) as usize;
        let centre = centre - 0.5;
        let mut ws: Vec<f32> = (left..right)
            .map(|i| kernel((i as f32 - centre) / sratio))
            .collect();
        let mut sum = 0.0f32;
        for &w in &ws {
            sum += w;
        }
        for w in ws.iter_mut() {
            *w /= sum;
        }
        first.push(left);
        weights.push(ws);
    }
    Taps { first, weights }
}

/// Resizes the `w x h` image `src` (values in 0–1) to `nw x nh` into `out`. Equal sizes copy, as `image` does.
pub fn resize_triangle(src: &[f32], w: usize, h: usize, nw: usize, nh: usize, out: &mut [f32]) {
    assert_eq!(src.len(), w * h, "image buffer matches its size");
    assert_eq!(out.len(), nw * nh, "output buffer matches the new size");
    if (w, h) == (nw, nh) {
        out.copy_from_slice(src);
        return;
    }
    if w == 0 || h == 0 || nw == 0 || nh == 0 {
        out.fill(0.0);
        return;
    }
    // Columns: output row y is a weighted sum of source rows; summed over whole rows at once.
    let vt = taps(h, nh);
    let mut tmp = Scratch::filled(w * nh, 0.0f32);
    for (y, row) in tmp.chunks_exact_mut(w).enumerate() {
        for (i, &wt) in vt.weights[y].iter().enumerate() {
            let sy = vt.first[y] + i;
            for (t, &p) in row.iter_mut().zip(&src[sy * w..(sy + 1) * w]) {
                *t += p * wt;
            }
        }
    }
    // Rows: each output pixel sums a few neighbours of its row, then is clamped into 0–1.
    let ht = taps(w, nw);
    for (row, orow) in tmp.chunks_exact(w).zip(out.chunks_exact_mut(nw)) {
        for (x, o) in orow.iter_mut().enumerate() {
            let mut t = 0.0f32;
            for (i, &wt) in ht.weights[x].iter().enumerate() {
                t += row[ht.first[x] + i] * wt;
            }
            // `image`'s clamp (below the minimum → minimum, above the maximum → maximum, else, NaN too, as is) is
            // `f32::clamp`.
            *o = t.clamp(0.0, 1.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{ImageBuffer, Luma};

    #[test]
    fn matches_the_image_crate_bit_for_bit() {
        let (w, h) = (83usize, 57usize);
        let mut s = 11u64;
        let src: Vec<f32> = (0..w * h)
            .map(|i| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let x = (i % w) as f32;
                let base = 0.5 + 0.3 * (0.11 * x).sin();
                (base + ((s >> 40) % 100) as f32 / 1000.0).clamp(0.0, 1.0)
            })
            .collect();
        let buf: ImageBuffer<Luma<f32>, Vec<f32>> =
            ImageBuffer::from_raw(w as u32, h as u32, src.clone()).unwrap();
        // Enlarging (the small-radius levels: 640x480 → 896x672 is x1.4), shrinking (coarse scales) and mixed.
        for &(nw, nh) in &[(116usize, 80usize), (42, 29), (17, 90), (83, 57), (1, 1)] {
            let want = image::imageops::resize(
                &buf,
                nw as u32,
                nh as u32,
                image::imageops::FilterType::Triangle,
            )
            .into_raw();
            let mut got = vec![f32::NAN; nw * nh];
            resize_triangle(&src, w, h, nw, nh, &mut got);
            assert_eq!(
                got.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                want.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                "{w}x{h} → {nw}x{nh}"
            );
        }
    }
}
