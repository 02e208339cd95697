//! Separable Gaussian blur of a one-channel `f32` image, bit for bit the blur of
//! `imageproc::filter::gaussian_blur_f32` (imageproc 0.25), but with the taps as the outer loop and the pixels of
//! a row as the inner one, so the compiler vectorises it, and with borders handled by padding instead of a
//! clamp per tap.
//!
//! Bit-identity matters because the blurred levels feed Canny's thresholds and non-maximum suppression: a last
//! bit changed at one pixel can move an edge pixel and so a fold pair and its anchors. Every output pixel adds
//! the same products in the same order as imageproc does (`acc = acc + pixel * tap`, taps in kernel order, from
//! 0), so the rounding is the same.

use super::scratch::Scratch;

/// The normalised kernel imageproc uses for `sigma` (radius `⌈2σ⌉`), computed with the same expressions.
pub fn gaussian_kernel(sigma: f32) -> Vec<f32> {
    let radius = (2.0 * sigma).ceil() as usize;
    let gaussian = |x: f32| {
        ((2.0 * std::f32::consts::PI).sqrt() * sigma).recip()
            * (-x.powi(2) / (2.0 * sigma.powi(2))).exp()
    };
    let mut k = vec![0.0f32; 2 * radius + 1];
    for i in 0..=radius {
        let v = gaussian(i as f32);
        k[radius + i] = v;
        k[radius - i] = v;
    }
    let sum: f32 = k.iter().sum();
    k.iter_mut().for_each(|x| *x /= sum);
    k
}

/// What each pass stores: the `f32` sum as it is (imageproc's blur of an `f32` image), or truncated into 0–255
/// like imageproc's `f32 → u8` clamp (its blur of a `u8` image stores each pass as `u8`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Store {
    F32,
    U8,
}

#[inline]
fn store(v: f32, s: Store) -> f32 {
    match s {
        Store::F32 => v,
        // imageproc: `if x < 255 { if x > 0 { x as u8 } else { 0 } } else { 255 }`; for finite sums clamping
        // first and truncating is the same.
        Store::U8 => (v.clamp(0.0, 255.0) as u8) as f32,
    }
}

/// Correlates the `w x h` row-major image `src` with `kernel` along rows and then along columns into `out`,
/// padding by continuity (the nearest border pixel), storing each pass as `mode` says. With `Store::U8`, `src`
/// must hold whole numbers in 0–255 (a `u8` image) and so does the result.
pub fn separable(src: &[f32], w: usize, h: usize, kernel: &[f32], mode: Store, out: &mut [f32]) {
    assert_eq!(src.len(), w * h, "image buffer matches its size");
    assert_eq!(out.len(), w * h, "output buffer matches the image size");
    assert!(kernel.len() % 2 == 1, "kernel has a centre tap");
    if w == 0 || h == 0 {
        return;
    }
    let r = kernel.len() / 2;
    // Rows: pad each row by r copies of its end pixels, then every output pixel is a plain dot product.
    let mut tmp = Scratch::filled(w * h, 0.0f32);
    let mut padded = vec![0.0f32; w + 2 * r];
    let mut acc = vec![0.0f32; w];
    for (row, o) in src.chunks_exact(w).zip(tmp.chunks_exact_mut(w)) {
        padded[..r].fill(row[0]);
        padded[r..r + w].copy_from_slice(row);
        padded[r + w..].fill(row[w - 1]);
        acc.fill(0.0);
        for (i, &k) in kernel.iter().enumerate() {
            for (a, &p) in acc.iter_mut().zip(&padded[i..i + w]) {
                *a += p * k;
            }
        }
        for (o, &a) in o.iter_mut().zip(&acc) {
            *o = store(a, mode);
        }
    }
    // Columns: the taps of output row y are the rows y + i - r, clamped into the image.
    for (y, o) in out.chunks_exact_mut(w).enumerate() {
        acc.fill(0.0);
        for (i, &k) in kernel.iter().enumerate() {
            let sy = (y + i).saturating_sub(r).min(h - 1);
            for (a, &p) in acc.iter_mut().zip(&tmp[sy * w..(sy + 1) * w]) {
                *a += p * k;
            }
        }
        for (o, &a) in o.iter_mut().zip(&acc) {
            *o = store(a, mode);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{GrayImage, ImageBuffer, Luma};

    fn separable_vec(src: &[f32], w: usize, h: usize, kernel: &[f32], mode: Store) -> Vec<f32> {
        let mut out = vec![0.0; w * h];
        separable(src, w, h, kernel, mode, &mut out);
        out
    }

    /// A deterministic test image with smooth parts, steps and noise.
    fn pattern(w: usize, h: usize, seed: u64) -> Vec<f32> {
        let mut s = seed;
        (0..w * h)
            .map(|i| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let smooth = 100.0 + 60.0 * (0.07 * x).sin() * (0.05 * y).cos();
                let step = if x + 0.5 * y > w as f32 * 0.6 {
                    50.0
                } else {
                    0.0
                };
                let noise = ((s >> 40) % 21) as f32 - 10.0;
                (smooth + step + noise).clamp(0.0, 255.0).round()
            })
            .collect()
    }

    #[test]
    fn matches_imageproc_bit_for_bit_on_f32_and_u8_images() {
        for &(w, h) in &[(97usize, 61usize), (5, 40), (40, 3), (1, 1)] {
            let img = pattern(w, h, 7);
            for &sigma in &[0.539f32, 1.4, 2.07, 3.2, 5.0] {
                let k = gaussian_kernel(sigma);
                // f32 image (0–1, as the level images are).
                let unit: Vec<f32> = img.iter().map(|v| v / 255.0).collect();
                let buf: ImageBuffer<Luma<f32>, Vec<f32>> =
                    ImageBuffer::from_raw(w as u32, h as u32, unit.clone()).unwrap();
                let want = imageproc::filter::gaussian_blur_f32(&buf, sigma).into_raw();
                let got = separable_vec(&unit, w, h, &k, Store::F32);
                assert_eq!(
                    got.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    want.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    "f32 {w}x{h} sigma {sigma}"
                );
                // u8 image (Canny's own blur).
                let bytes: Vec<u8> = img.iter().map(|&v| v as u8).collect();
                let gray = GrayImage::from_raw(w as u32, h as u32, bytes).unwrap();
                let want = imageproc::filter::gaussian_blur_f32(&gray, sigma).into_raw();
                let got = separable_vec(&img, w, h, &k, Store::U8);
                assert_eq!(
                    got.iter().map(|&v| v as u8).collect::<Vec<_>>(),
                    want,
                    "u8 {w}x{h} sigma {sigma}"
                );
            }
        }
    }

    #[test]
    fn equals_a_direct_two_dimensional_convolution() {
        // The separable form against the 2D sum over the outer-product kernel with clamped coordinates (in f64):
        // the same blur up to f32 rounding.
        let (w, h) = (33usize, 29usize);
        let img: Vec<f32> = pattern(w, h, 3).iter().map(|v| v / 255.0).collect();
        let k = gaussian_kernel(2.07);
        let r = (k.len() / 2) as i64;
        let got = separable_vec(&img, w, h, &k, Store::F32);
        let clampi = |v: i64, n: usize| v.clamp(0, n as i64 - 1) as usize;
        for y in 0..h as i64 {
            for x in 0..w as i64 {
                let mut s = 0.0f64;
                for (j, &kj) in k.iter().enumerate() {
                    for (i, &ki) in k.iter().enumerate() {
                        let sx = clampi(x + i as i64 - r, w);
                        let sy = clampi(y + j as i64 - r, h);
                        s += ki as f64 * kj as f64 * img[sy * w + sx] as f64;
                    }
                }
                let g = got[y as usize * w + x as usize] as f64;
                assert!((g - s).abs() < 1e-6, "({x}, {y}): {g} vs {s}");
            }
        }
        // A constant image stays constant (the kernel sums to 1).
        let flat = separable_vec(&[0.25f32; 12 * 7], 12, 7, &k, Store::F32);
        assert!(flat.iter().all(|&v| (v - 0.25).abs() < 1e-6));
    }
}
