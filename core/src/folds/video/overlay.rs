//! Pictures of the fold-edge stages, like Popa et al. 2009 Figure 4: the input image, the raw edges, the paired
//! fold edges at one resolution, and the union over resolutions after projection — so users can tune the
//! parameters by eye.

use super::{FrameAnalysis, ViewResult};
use crate::render::{caption, grid};
use image::{Rgb, RgbImage};
use imageproc::drawing::draw_line_segment_mut;

const WHITE: [u8; 3] = [255, 255, 255];
const INK: [u8; 3] = [20, 20, 20];
/// Colours per level for raw edges.
const LEVEL_COLORS: [[u8; 3]; 6] = [
    [230, 60, 50],
    [40, 150, 60],
    [40, 90, 220],
    [220, 150, 20],
    [160, 60, 200],
    [20, 170, 190],
];
const EDGE_A: [u8; 3] = [220, 30, 30];
const EDGE_B: [u8; 3] = [30, 80, 230];
const DISCARDED: [u8; 3] = [150, 150, 150];

/// The photo as a dimmed RGB background (edges stand out on it).
fn background(v: &ViewResult, dim: f32) -> RgbImage {
    let p = &v.photo;
    let mut img = RgbImage::new(p.width, p.height);
    for (i, px) in img.pixels_mut().enumerate() {
        let c = p.rgb[i];
        *px = if p.mask[i] {
            Rgb(c.map(|x| (x * dim + 255.0 * (1.0 - dim)).clamp(0.0, 255.0) as u8))
        } else {
            Rgb(WHITE)
        };
    }
    img
}

fn polyline(img: &mut RgbImage, pts: &[[f64; 2]], color: [u8; 3]) {
    for w in pts.windows(2) {
        draw_line_segment_mut(
            img,
            (w[0][0] as f32, w[0][1] as f32),
            (w[1][0] as f32, w[1][1] as f32),
            Rgb(color),
        );
    }
}

/// A small tick on the darker (left) side at the middle of an oriented edge.
fn tick(img: &mut RgbImage, pts: &[[f64; 2]], color: [u8; 3]) {
    if pts.len() < 2 {
        return;
    }
    let i = pts.len() / 2;
    let d = super::orient::tangent(pts, i);
    let l = super::orient::left_of(d);
    let p = pts[i];
    draw_line_segment_mut(
        img,
        (p[0] as f32, p[1] as f32),
        ((p[0] + 4.0 * l[0]) as f32, (p[1] + 4.0 * l[1]) as f32),
        Rgb(color),
    );
}

/// The garment's bounding box in the image (mask), with a margin; the whole image without a mask.
fn garment_box(v: &ViewResult, margin: u32) -> (u32, u32, u32, u32) {
    let p = &v.photo;
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for y in 0..p.height {
        for x in 0..p.width {
            if p.mask[(y * p.width + x) as usize] {
                x0 = x0.min(x);
                y0 = y0.min(y);
                x1 = x1.max(x);
                y1 = y1.max(y);
            }
        }
    }
    if x0 > x1 {
        return (0, 0, p.width, p.height);
    }
    let x0 = x0.saturating_sub(margin);
    let y0 = y0.saturating_sub(margin);
    let x1 = (x1 + margin).min(p.width - 1);
    let y1 = (y1 + margin).min(p.height - 1);
    (x0, y0, x1 - x0 + 1, y1 - y0 + 1)
}

/// One row of four panels for a view, cropped to the garment.
pub fn view_row(v: &ViewResult, camera_name: &str, frame: usize) -> Vec<RgbImage> {
    let (bx, by, bw, bh) = garment_box(v, 12);
    let crop = |img: RgbImage| image::imageops::crop_imm(&img, bx, by, bw, bh).to_image();
    let input = background(v, 1.0);
    let mut raw = background(v, 0.35);
    for (k, l) in v.levels.iter().enumerate() {
        for c in &l.chains {
            polyline(&mut raw, c, LEVEL_COLORS[k % LEVEL_COLORS.len()]);
        }
    }
    let mut paired = background(v, 0.35);
    if let Some(l) = v.levels.first() {
        for p in &l.pairs {
            polyline(&mut paired, &p.a, EDGE_A);
            polyline(&mut paired, &p.b, EDGE_B);
            tick(&mut paired, &p.a, EDGE_A);
            tick(&mut paired, &p.b, EDGE_B);
        }
    }
    let mut union = background(v, 0.35);
    for p in &v.union {
        polyline(&mut union, &p.a, DISCARDED);
        polyline(&mut union, &p.b, DISCARDED);
    }
    for pp in &v.projected {
        let p = &pp.pair;
        polyline(&mut union, &p.a, EDGE_A);
        polyline(&mut union, &p.b, EDGE_B);
        tick(&mut union, &p.a, EDGE_A);
        tick(&mut union, &p.b, EDGE_B);
    }
    let first = v
        .levels
        .first()
        .map(|l| format!("PAIRED (SCALE {} RADIUS {})", l.level.scale, l.level.radius))
        .unwrap_or_else(|| "PAIRED".into());
    let n_raw: usize = v.levels.iter().map(|l| l.chains.len()).sum();
    let (input, raw, paired, union) = (crop(input), crop(raw), crop(paired), crop(union));
    vec![
        caption(
            &input,
            &format!(
                "{} FRAME {frame} {}",
                camera_name.to_uppercase(),
                v.role.to_uppercase()
            ),
            1,
            INK,
            WHITE,
        ),
        caption(&raw, &format!("RAW EDGES ({n_raw})"), 1, INK, WHITE),
        caption(&paired, &first, 1, INK, WHITE),
        caption(
            &union,
            &format!(
                "UNION: {} KEPT, {} OFF GARMENT",
                v.projected.len(),
                v.union.len() - v.projected.len()
            ),
            1,
            INK,
            WHITE,
        ),
    ]
}

/// The overlay of a frame: one row per chosen view. Red and blue are the two edges of a pair, with a tick on
/// each edge's darker side; grey pairs were discarded by the projection.
pub fn frame_overlay(a: &FrameAnalysis, camera_names: &[String]) -> RgbImage {
    let rows: Vec<Vec<RgbImage>> = a
        .views
        .iter()
        .map(|v| view_row(v, &camera_names[v.camera], a.frame))
        .collect();
    grid(&rows, 6, WHITE)
}
