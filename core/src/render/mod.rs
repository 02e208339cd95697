//! Preview rendering: a small deterministic software rasterizer for before/after pictures of garment meshes, a
//! stretch colour ramp, image grids, a bitmap font for labels, a line plot, and atomic PNG output.
//!
//! A typical preview:
//! ```no_run
//! # use crease_core::render::*;
//! # use crease_core::mesh::{geometry, Topology};
//! # fn demo(before: &[[f64; 3]], after: &[[f64; 3]], topo: &Topology, stretch: &[f64]) -> crease_core::Result<()> {
//! let (lo, hi) = geometry::bounding_box(before);
//! let cam = Camera::fit(lo, hi, [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], 512, 512);
//! let colors: Vec<[u8; 3]> = stretch.iter().map(|&s| stretch_color(s, 0.2)).collect();
//! let a = render(before, topo, &cam, &Style::default());
//! let b = render(after, topo, &cam, &Style::default());
//! let c = render(after, topo, &cam, &Style { triangle_colors: Some(&colors), ..Style::default() });
//! let white = [255, 255, 255];
//! let row = vec![caption(&a, "INPUT", 2, [0; 3], white), caption(&b, "OUTPUT", 2, [0; 3], white),
//!                caption(&c, "STRETCH", 2, [0; 3], white)];
//! save_png(&grid(&[row], 8, white), std::path::Path::new("preview.png"))
//! # }
//! ```

mod camera;
mod font;
mod plot;
mod raster;

pub use camera::{CalibratedCamera, Camera, Projection};
pub use font::{
    draw_text, draw_text_vertical, text_size, ADVANCE, GLYPH_HEIGHT, GLYPH_WIDTH, LINE_HEIGHT,
};
pub use plot::{plot_lines, Series};
pub use raster::{render, render_triangles, Style, CLOTH_GREY};

use crate::error::{Error, Result};
use image::RgbImage;
use std::path::Path;

/// Colour ramp for stretch: light grey at `stretch <= 0`, through yellow and orange, to dark red at
/// `stretch >= max` (lightness decreases monotonically, so it also reads in greyscale). A non-finite `stretch`
/// or a `max` that is not positive and finite maps any positive stretch to the red end.
pub fn stretch_color(stretch: f64, max: f64) -> [u8; 3] {
    const STOPS: [(f64, [f64; 3]); 4] = [
        (0.0, [232.0, 232.0, 232.0]),
        (0.3, [250.0, 222.0, 96.0]),
        (0.65, [238.0, 128.0, 40.0]),
        (1.0, [186.0, 22.0, 28.0]),
    ];
    let t = if max > 0.0 && max.is_finite() && stretch.is_finite() {
        (stretch / max).clamp(0.0, 1.0)
    } else if stretch > 0.0 || stretch.is_nan() {
        1.0
    } else {
        0.0
    };
    let k = STOPS
        .windows(2)
        .position(|w| t <= w[1].0)
        .unwrap_or(STOPS.len() - 2);
    let ((t0, c0), (t1, c1)) = (STOPS[k], STOPS[k + 1]);
    let f = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
    [0, 1, 2].map(|i| (c0[i] + (c1[i] - c0[i]) * f).round() as u8)
}

/// Composes images into a grid: `images[row][column]`, each cell as wide as the widest image in its column and as
/// tall as the tallest in its row, images centred in their cells, `pad` pixels around and between cells. Rows may
/// have different lengths (missing cells stay background). The result is at least 1x1.
pub fn grid(images: &[Vec<RgbImage>], pad: u32, background: [u8; 3]) -> RgbImage {
    let n_cols = images.iter().map(Vec::len).max().unwrap_or(0);
    let mut col_w = vec![0u64; n_cols];
    let mut row_h = vec![0u64; images.len()];
    for (r, row) in images.iter().enumerate() {
        for (c, img) in row.iter().enumerate() {
            col_w[c] = col_w[c].max(img.width() as u64);
            row_h[r] = row_h[r].max(img.height() as u64);
        }
    }
    let pad = pad as u64;
    let total = |sizes: &[u64]| {
        (pad + sizes.iter().map(|s| s + pad).sum::<u64>()).clamp(1, u32::MAX as u64) as u32
    };
    let mut out = RgbImage::from_pixel(total(&col_w), total(&row_h), image::Rgb(background));
    let mut y = pad;
    for (r, row) in images.iter().enumerate() {
        let mut x = pad;
        for (c, img) in row.iter().enumerate() {
            let ox = x + (col_w[c] - img.width() as u64) / 2;
            let oy = y + (row_h[r] - img.height() as u64) / 2;
            image::imageops::replace(&mut out, img, ox as i64, oy as i64);
            x += col_w[c] + pad;
        }
        y += row_h[r] + pad;
    }
    out
}

/// Returns `img` with a strip above it holding `text` centred in `color` on `background` (font `scale`).
pub fn caption(
    img: &RgbImage,
    text: &str,
    scale: u32,
    color: [u8; 3],
    background: [u8; 3],
) -> RgbImage {
    let (tw, th) = text_size(text, scale);
    let margin = 2 * scale.max(1);
    let strip = th + 2 * margin;
    let width = img.width().max(tw.saturating_add(2 * margin));
    let mut out = RgbImage::from_pixel(
        width,
        img.height().saturating_add(strip),
        image::Rgb(background),
    );
    let x = (width - tw) / 2;
    draw_text(&mut out, x as i32, margin as i32, text, color, scale);
    image::imageops::replace(
        &mut out,
        img,
        ((width - img.width()) / 2) as i64,
        strip as i64,
    );
    out
}

/// Encodes `img` as PNG bytes, for outputs that go to storage rather than a local file (job tasks). `label`
/// names the file in the error.
pub fn png_bytes(img: &RgbImage, label: &Path) -> Result<Vec<u8>> {
    use image::ImageEncoder;
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new(&mut bytes)
        .write_image(
            img.as_raw(),
            img.width(),
            img.height(),
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| match e {
            image::ImageError::IoError(io) => Error::io(label, io),
            other => Error::format(label, None, format!("cannot encode PNG: {other}")),
        })?;
    Ok(bytes)
}

/// Writes `img` as a PNG through [`crate::fsutil::write_atomic`] (the file is either complete or absent).
/// Encoding failures are [`Error::Format`], file-system failures [`Error::Io`], both naming `path`.
pub fn save_png(img: &RgbImage, path: &Path) -> Result<()> {
    crate::fsutil::write_atomic(path, &png_bytes(img, path)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stretch_color_ramp() {
        assert_eq!(stretch_color(0.0, 1.0), [232, 232, 232]);
        assert_eq!(stretch_color(-3.0, 1.0), [232, 232, 232]);
        assert_eq!(stretch_color(1.0, 1.0), [186, 22, 28]);
        assert_eq!(stretch_color(7.0, 1.0), [186, 22, 28]);
        assert_eq!(stretch_color(0.3, 1.0), [250, 222, 96]);
        assert_eq!(stretch_color(f64::NAN, 1.0), [186, 22, 28]);
        assert_eq!(stretch_color(0.5, 0.0), [186, 22, 28]);
        assert_eq!(stretch_color(0.0, f64::NAN), [232, 232, 232]);
        // Darker (by Rec. 601 luma) as stretch grows.
        let luma = |c: [u8; 3]| 0.299 * c[0] as f64 + 0.587 * c[1] as f64 + 0.114 * c[2] as f64;
        let mut prev = f64::INFINITY;
        for i in 0..=50 {
            let l = luma(stretch_color(i as f64 / 50.0, 1.0));
            assert!(l <= prev + 1e-9, "{i}");
            prev = l;
        }
    }

    #[test]
    fn grid_dimensions_and_placement() {
        let img = |w, h, v| RgbImage::from_pixel(w, h, image::Rgb([v; 3]));
        let g = grid(
            &[vec![img(10, 20, 1), img(30, 5, 2)], vec![img(15, 15, 3)]],
            4,
            [9, 9, 9],
        );
        // Columns 15 and 30 wide, rows 20 and 15 tall.
        assert_eq!(g.dimensions(), (4 + 15 + 4 + 30 + 4, 4 + 20 + 4 + 15 + 4));
        assert_eq!(g.get_pixel(0, 0).0, [9; 3]);
        assert_eq!(g.get_pixel(4 + 2, 4).0, [1; 3]); // 10-wide image centred in the 15-wide column
        assert_eq!(g.get_pixel(4 + 15 + 4, 4 + 7).0, [2; 3]);
        assert_eq!(g.get_pixel(4, 4 + 20 + 4).0, [3; 3]);
        assert_eq!(g.get_pixel(4 + 15 + 4 + 5, 4 + 20 + 4 + 5).0, [9; 3]); // missing cell
        assert_eq!(grid(&[], 0, [0; 3]).dimensions(), (1, 1));
        assert_eq!(
            grid(&[vec![], vec![img(3, 3, 0)]], 2, [0; 3]).dimensions(),
            (7, 2 + 2 + 3 + 2)
        );
    }

    #[test]
    fn caption_adds_a_labelled_strip() {
        let img = RgbImage::from_pixel(100, 50, image::Rgb([200; 3]));
        let c = caption(&img, "OUTPUT", 2, [0; 3], [255; 3]);
        let strip = text_size("OUTPUT", 2).1 + 8;
        assert_eq!(c.dimensions(), (100, 50 + strip));
        assert!(c.pixels().any(|p| p.0 == [0; 3]));
        assert_eq!(c.get_pixel(50, strip + 10).0, [200; 3]);
        // A label wider than the image widens the result.
        let narrow = RgbImage::new(4, 4);
        assert!(caption(&narrow, "STRETCH", 1, [0; 3], [255; 3]).width() > 4);
    }

    #[test]
    fn save_png_round_trips_and_names_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        let mut img = RgbImage::from_pixel(7, 5, image::Rgb([1, 2, 3]));
        img.put_pixel(6, 4, image::Rgb([250, 0, 9]));
        save_png(&img, &path).unwrap();
        let back = image::open(&path).unwrap().to_rgb8();
        assert_eq!(back.as_raw(), img.as_raw());
        let bad = dir.path().join("missing").join("b.png");
        let err = save_png(&img, &bad).unwrap_err();
        assert!(matches!(err, Error::Io { .. }), "{err}");
        assert!(err.to_string().contains("b.png"), "{err}");
        let err = save_png(&RgbImage::new(0, 0), &path).unwrap_err();
        assert!(err.to_string().contains("a.png"), "{err}");
    }
}
