//! A minimal line plot (axes, ticks, grid, legend) drawn with the bitmap font.

use super::font::{self, draw_text, draw_text_vertical, put, text_size};
use image::RgbImage;

const WHITE: [u8; 3] = [255, 255, 255];
const BLACK: [u8; 3] = [0, 0, 0];
const GRID: [u8; 3] = [228, 228, 228];
const FRAME: [u8; 3] = [150, 150, 150];

/// One plotted series: legend name (may be empty), line colour, and `(x, y)` points in drawing order.
pub type Series<'a> = (&'a str, [u8; 3], Vec<(f64, f64)>);

/// Plots each series `(name, colour, points)` as a polyline over shared axes: white background, title on top,
/// axis labels, "nice" ticks with labels and light grid lines, and a legend in the top-right corner (series with
/// an empty name are left out of it). Non-finite points break a line. The y range is widened to whole tick
/// steps; the x range is the data's. Text scales up for large images. Never panics; an image too small for the
/// axes gets only the title.
pub fn plot_lines(
    series: &[Series],
    width: u32,
    height: u32,
    title: &str,
    x_label: &str,
    y_label: &str,
) -> RgbImage {
    let mut img = RgbImage::from_pixel(width, height, image::Rgb(WHITE));
    if width == 0 || height == 0 {
        return img;
    }
    let s = (width.min(height) / 400).max(1);
    let (wi, hi) = (width as i64, height as i64);
    let si = s as i64;
    let ch = (font::GLYPH_HEIGHT * s) as i64;
    let pad = 6 * si;
    let tick = 4 * si;

    // Data ranges.
    let finite = || {
        series
            .iter()
            .flat_map(|(_, _, p)| p.iter())
            .filter(|(x, y)| x.is_finite() && y.is_finite())
    };
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in finite() {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let (x0, x1) = widen(x0, x1);
    let (y0, y1) = widen(y0, y1);

    // Layout: margins depend on the tick labels, which depend on the (estimated) plot height.
    let top = pad + if title.is_empty() { 0 } else { ch + pad };
    let bottom = tick + pad + ch + pad + if x_label.is_empty() { 0 } else { ch + pad };
    let y_target = ((hi - top - bottom) / (ch * 4)).clamp(2, 10) as usize;
    let y_step = nice_step(y1 - y0, y_target);
    let (y0, y1) = (
        (y0 / y_step).floor() * y_step,
        (y1 / y_step).ceil() * y_step,
    );
    let (y0, y1) = if y0 < y1 && (y1 - y0).is_finite() {
        (y0, y1)
    } else {
        widen(y0, y0)
    };
    let y_ticks = ticks(y0, y1, y_step);
    let y_labels: Vec<String> = y_ticks
        .iter()
        .map(|&v| format_tick(v, y_step, y0, y1))
        .collect();
    let y_label_w = y_labels
        .iter()
        .map(|l| text_size(l, s).0 as i64)
        .max()
        .unwrap_or(0);
    let left = pad + if y_label.is_empty() { 0 } else { ch + pad } + y_label_w + pad / 2 + tick;
    let x_probe = format_tick(x1, nice_step(x1 - x0, 5), x0, x1);
    let right = pad + text_size(&x_probe, s).0 as i64 / 2;
    let (px0, px1, py0, py1) = (left, wi - 1 - right, top, hi - 1 - bottom);

    if !title.is_empty() {
        let tw = text_size(title, s).0 as i64;
        draw_text(
            &mut img,
            clamp_i32((wi - tw) / 2),
            clamp_i32(pad),
            title,
            BLACK,
            s,
        );
    }
    if px1 - px0 < 8 || py1 - py0 < 8 {
        return img;
    }

    let label_w = text_size(&x_probe, s).0 as i64 + 6 * font::ADVANCE as i64 * si;
    let x_target = ((px1 - px0) / label_w.max(1)).clamp(2, 10) as usize;
    let x_step = nice_step(x1 - x0, x_target);
    let x_ticks = ticks(x0, x1, x_step);
    let map_x = |x: f64| px0 as f64 + (x - x0) / (x1 - x0) * (px1 - px0) as f64;
    let map_y = |y: f64| py1 as f64 - (y - y0) / (y1 - y0) * (py1 - py0) as f64;

    // Grid, axes, ticks, labels.
    for &v in &y_ticks {
        let y = map_y(v).round() as i64;
        hline(&mut img, px0, px1, y, GRID);
        hline(&mut img, px0 - tick, px0, y, BLACK);
    }
    for &v in &x_ticks {
        let x = map_x(v).round() as i64;
        vline(&mut img, x, py0, py1, GRID);
        vline(&mut img, x, py1, py1 + tick, BLACK);
    }
    hline(&mut img, px0, px1, py1, BLACK);
    vline(&mut img, px0, py0, py1, BLACK);
    for (v, label) in y_ticks.iter().zip(&y_labels) {
        let (lw, _) = text_size(label, s);
        let y = map_y(*v).round() as i64 - ch / 2;
        draw_text(
            &mut img,
            clamp_i32(px0 - tick - pad / 2 - lw as i64),
            clamp_i32(y),
            label,
            BLACK,
            s,
        );
    }
    for &v in &x_ticks {
        let label = format_tick(v, x_step, x0, x1);
        let (lw, _) = text_size(&label, s);
        let x = map_x(v).round() as i64 - lw as i64 / 2;
        draw_text(
            &mut img,
            clamp_i32(x),
            clamp_i32(py1 + tick + pad / 2),
            &label,
            BLACK,
            s,
        );
    }
    if !x_label.is_empty() {
        let (lw, _) = text_size(x_label, s);
        let x = (px0 + px1) / 2 - lw as i64 / 2;
        draw_text(
            &mut img,
            clamp_i32(x),
            clamp_i32(py1 + tick + pad + ch + pad / 2),
            x_label,
            BLACK,
            s,
        );
    }
    if !y_label.is_empty() {
        let (lw, _) = text_size(y_label, s);
        let y = (py0 + py1) / 2 + lw as i64 / 2;
        draw_text_vertical(&mut img, clamp_i32(pad), clamp_i32(y), y_label, BLACK, s);
    }

    // Series.
    let thick = si + 1;
    for (_, color, points) in series {
        let mut prev: Option<(f64, f64)> = None;
        for (i, &(x, y)) in points.iter().enumerate() {
            if !(x.is_finite() && y.is_finite()) {
                prev = None;
                continue;
            }
            let q = (map_x(x), map_y(y));
            match prev {
                Some(p) => line(&mut img, p, q, thick, *color),
                None => {
                    // An isolated point (no finite neighbour on either side) is drawn as a dot.
                    let next_ok = points
                        .get(i + 1)
                        .is_some_and(|(a, b)| a.is_finite() && b.is_finite());
                    if !next_ok {
                        dot(&mut img, q, 2 * thick + 1, *color);
                    }
                }
            }
            prev = Some(q);
        }
    }

    // Legend.
    let named: Vec<_> = series.iter().filter(|(n, _, _)| !n.is_empty()).collect();
    if !named.is_empty() {
        let swatch = 3 * font::ADVANCE as i64 * si;
        let name_w = named
            .iter()
            .map(|(n, _, _)| text_size(n, s).0 as i64)
            .max()
            .unwrap_or(0);
        let line_h = ch + pad / 2;
        let bw = pad + swatch + pad + name_w + pad;
        let bh = pad + named.len() as i64 * line_h - pad / 2 + pad;
        let bx0 = px1 - pad - bw;
        let by0 = py0 + pad;
        for y in by0..by0 + bh {
            hline(&mut img, bx0, bx0 + bw, y, WHITE);
        }
        hline(&mut img, bx0, bx0 + bw, by0, FRAME);
        hline(&mut img, bx0, bx0 + bw, by0 + bh, FRAME);
        vline(&mut img, bx0, by0, by0 + bh, FRAME);
        vline(&mut img, bx0 + bw, by0, by0 + bh, FRAME);
        for (k, (name, color, _)) in named.iter().enumerate() {
            let y = by0 + pad + k as i64 * line_h;
            let mid = (y + ch / 2) as f64;
            line(
                &mut img,
                ((bx0 + pad) as f64, mid),
                ((bx0 + pad + swatch) as f64, mid),
                thick,
                *color,
            );
            draw_text(
                &mut img,
                clamp_i32(bx0 + 2 * pad + swatch),
                clamp_i32(y),
                name,
                BLACK,
                s,
            );
        }
    }
    img
}

/// A non-empty, finite range: empty input gives `[0, 1]`, a single value is widened around itself.
fn widen(lo: f64, hi: f64) -> (f64, f64) {
    if !(lo.is_finite() && hi.is_finite()) || lo > hi {
        return (0.0, 1.0);
    }
    if hi - lo > 0.0 && (hi - lo).is_finite() {
        return (lo, hi);
    }
    let d = (lo.abs() * 0.1).max(0.5);
    if (lo - d).is_finite() && (hi + d).is_finite() {
        (lo - d, hi + d)
    } else {
        (0.0, 1.0)
    }
}

/// A 1, 2 or 5 times a power of ten step giving about `target` intervals over `span`.
fn nice_step(span: f64, target: usize) -> f64 {
    let raw = span / target.max(1) as f64;
    if !raw.is_finite() || raw <= 0.0 {
        return 1.0;
    }
    let mag = 10f64.powf(raw.log10().floor());
    let m = raw / mag;
    let nice = if m <= 1.0 {
        1.0
    } else if m <= 2.0 {
        2.0
    } else if m <= 5.0 {
        5.0
    } else {
        10.0
    };
    if (nice * mag) > 0.0 && (nice * mag).is_finite() {
        nice * mag
    } else {
        1.0
    }
}

/// Multiples of `step` in `[lo, hi]` (at most 100).
fn ticks(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let first = (lo / step - 1e-9).ceil();
    (0..100)
        .map(|k| (first + k as f64) * step)
        .take_while(|&v| v <= hi + step * 1e-9)
        .collect()
}

/// Tick label with as many decimals as the step needs; scientific notation for very large or small ranges.
fn format_tick(v: f64, step: f64, lo: f64, hi: f64) -> String {
    let v = if v.abs() < step * 1e-6 { 0.0 } else { v };
    let big = lo.abs().max(hi.abs());
    if big >= 1e6 || (big > 0.0 && big < 1e-3) {
        return format!("{v:.2e}");
    }
    let decimals = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()).clamp(0.0, 9.0) as usize
    };
    format!("{v:.decimals$}")
}

fn clamp_i32(v: i64) -> i32 {
    v.clamp(i32::MIN as i64, i32::MAX as i64) as i32
}

fn hline(img: &mut RgbImage, x0: i64, x1: i64, y: i64, c: [u8; 3]) {
    if y < 0 || y >= img.height() as i64 {
        return;
    }
    for x in x0.max(0)..=x1.min(img.width() as i64 - 1) {
        put(img, x, y, c);
    }
}

fn vline(img: &mut RgbImage, x: i64, y0: i64, y1: i64, c: [u8; 3]) {
    if x < 0 || x >= img.width() as i64 {
        return;
    }
    for y in y0.max(0)..=y1.min(img.height() as i64 - 1) {
        put(img, x, y, c);
    }
}

fn dot(img: &mut RgbImage, p: (f64, f64), size: i64, c: [u8; 3]) {
    if !(p.0.is_finite() && p.1.is_finite()) {
        return;
    }
    let x0 = (p.0 - (size - 1) as f64 / 2.0).round() as i64;
    let y0 = (p.1 - (size - 1) as f64 / 2.0).round() as i64;
    for y in y0..y0 + size {
        hline(img, x0, x0 + size - 1, y, c);
    }
}

/// A line of `thick x thick` squares stepped at most one pixel apart.
fn line(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), thick: i64, c: [u8; 3]) {
    if !(a.0.is_finite() && a.1.is_finite() && b.0.is_finite() && b.1.is_finite()) {
        return;
    }
    let limit = 4.0 * (img.width() as f64 + img.height() as f64);
    let steps = (b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil().min(limit) as usize;
    for i in 0..=steps {
        let t = if steps == 0 {
            0.0
        } else {
            i as f64 / steps as f64
        };
        dot(
            img,
            (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t),
            thick,
            c,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plot_has_requested_size_and_content() {
        let a: Vec<(f64, f64)> = (0..50)
            .map(|i| (i as f64, 1.0 + 0.3 * (i as f64 * 0.2).sin()))
            .collect();
        let b: Vec<(f64, f64)> = (0..50)
            .map(|i| (i as f64, 1.05 + 0.001 * i as f64))
            .collect();
        let img = plot_lines(
            &[("PASS 1", [220, 40, 40], a), ("pass 2", [40, 90, 220], b)],
            640,
            360,
            "STRETCH PER FRAME",
            "frame",
            "max stretch",
        );
        assert_eq!(img.dimensions(), (640, 360));
        let count = |c: [u8; 3]| img.pixels().filter(|p| p.0 == c).count();
        assert!(count([220, 40, 40]) > 100);
        assert!(count([40, 90, 220]) > 100);
        assert!(count(BLACK) > 300);
        assert!(img.pixels().filter(|p| p.0 != WHITE).count() > 1000);
    }

    #[test]
    fn plot_degenerate_inputs_do_not_panic() {
        let odd = vec![
            (f64::NAN, 1.0),
            (2.0, f64::INFINITY),
            (3.0, 3.0),
            (1e300, -1e300),
            (-1e300, 1e300),
        ];
        for (w, h) in [(0, 0), (1, 1), (20, 10), (300, 200), (2000, 900)] {
            for data in [
                vec![],
                vec![(1.0, 1.0)],
                vec![(5.0, 2.0), (5.0, 2.0)],
                odd.clone(),
            ] {
                let img = plot_lines(
                    &[("", [0, 0, 0], data.clone()), ("X", [1, 2, 3], data)],
                    w,
                    h,
                    "T",
                    "",
                    "Y",
                );
                assert_eq!(img.dimensions(), (w, h));
            }
        }
        let img = plot_lines(&[], 200, 100, "", "", "");
        assert!(
            img.pixels().any(|p| p.0 != WHITE),
            "axes are drawn even without data"
        );
    }

    #[test]
    fn tick_helpers() {
        assert_eq!(nice_step(10.0, 5), 2.0);
        assert_eq!(nice_step(1.0, 4), 0.5);
        assert_eq!(nice_step(0.0, 4), 1.0);
        assert_eq!(ticks(0.0, 1.0, 0.25), vec![0.0, 0.25, 0.5, 0.75, 1.0]);
        assert_eq!(format_tick(0.5, 0.5, 0.0, 2.0), "0.5");
        assert_eq!(format_tick(20.0, 10.0, 0.0, 100.0), "20");
        assert_eq!(format_tick(-1e-17, 0.1, -1.0, 1.0), "0.0");
    }
}
