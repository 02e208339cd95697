//! The `folds.png` overlay: a few frames of the input with the fold signal and the traced control lines, so a
//! user can judge the detection before (or instead of) running the deformation.
//!
//! Triangles are tinted by the integrated shrinkage (white → amber at `1 + 4·min_shrink` and above); the
//! triangles the control lines cross — the anchors — are drawn red where they rotate about +tangent and blue
//! where they rotate about −tangent (the two sides of a ridge). Shown from the side the anchors face, and
//! from the opposite side.

use crate::folds::Anchor;
use crate::mesh::{geometry, Frame, Topology};
use crate::render::{caption, grid, render, Camera, Style};
use crate::vec3;
use image::RgbImage;

/// What the overlay needs of one frame.
#[derive(Debug, Clone)]
pub struct OverlayFrame {
    pub frame: usize,
    pub positions: Frame,
    pub shrink: Vec<f64>,
    pub anchors: Vec<Anchor>,
    pub n_folds: usize,
}

const AMBER: [u8; 3] = [235, 160, 40];
const RED: [u8; 3] = [210, 30, 30];
const BLUE: [u8; 3] = [30, 70, 210];
const WHITE: [u8; 3] = [255, 255, 255];
const INK: [u8; 3] = [20, 20, 20];

fn mix(a: [u8; 3], b: [u8; 3], t: f64) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    std::array::from_fn(|k| (a[k] as f64 * (1.0 - t) + b[k] as f64 * t).round() as u8)
}

/// One row per frame: the front (the side the anchors face) and the back. `saturate` is the shrinkage
/// (absolute change) drawn fully amber.
pub fn overlay(topo: &Topology, frames: &[OverlayFrame], size: u32, saturate: f64) -> RgbImage {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for f in frames {
        let (l, h) = geometry::bounding_box(&f.positions);
        for k in 0..3 {
            lo[k] = lo[k].min(l[k]);
            hi[k] = hi[k].max(h[k]);
        }
    }
    // Look at the side most anchors face (summed anchor normals over the shown frames).
    let mut facing = [0.0; 3];
    for f in frames {
        let normals = geometry::triangle_normals(topo, &f.positions);
        for a in &f.anchors {
            facing = vec3::add(facing, normals[a.triangle as usize]);
        }
    }
    let ext = vec3::sub(hi, lo);
    // Up: the bounding box's longest axis reads best horizontally, so up is the shortest of the other two.
    let longest = (0..3)
        .max_by(|&a, &b| ext[a].total_cmp(&ext[b]))
        .unwrap_or(0);
    let up_axis = (0..3)
        .filter(|&k| k != longest)
        .max_by(|&a, &b| ext[b].total_cmp(&ext[a]))
        .unwrap_or(2);
    let mut up = [0.0; 3];
    up[up_axis] = 1.0;
    let mut view = vec3::scale(facing, -1.0);
    view = vec3::sub(view, vec3::scale(up, vec3::dot(view, up)));
    if vec3::norm(view) < 1e-9 {
        view = [0.0; 3];
        view[3 - longest - up_axis] = -1.0;
    }
    let view = vec3::normalize(vec3::sub(vec3::normalize(view), vec3::scale(up, 0.25)));
    let back = vec3::normalize(vec3::add(
        vec3::scale(vec3::sub(view, vec3::scale(up, vec3::dot(view, up))), -1.0),
        vec3::scale(up, vec3::dot(view, up)),
    ));
    let cams = [
        Camera::fit(lo, hi, view, up, size, size),
        Camera::fit(lo, hi, back, up, size, size),
    ];
    let scale = (size / 256).max(1);
    let rows: Vec<Vec<RgbImage>> = frames
        .iter()
        .map(|f| {
            let mut colors: Vec<[u8; 3]> = f
                .shrink
                .iter()
                .map(|&s| mix(WHITE, AMBER, (s - 1.0) / (saturate - 1.0).max(1e-9)))
                .collect();
            for a in &f.anchors {
                colors[a.triangle as usize] = if side_sign(a) { RED } else { BLUE };
            }
            let style = Style {
                triangle_colors: Some(&colors),
                ..Style::default()
            };
            cams.iter()
                .enumerate()
                .map(|(k, cam)| {
                    let img = render(&f.positions, topo, cam, &style);
                    let label = if k == 0 {
                        format!(
                            "FRAME {} {} FOLDS {} ANCHORS",
                            f.frame,
                            f.n_folds,
                            f.anchors.len()
                        )
                    } else {
                        "FAR SIDE".to_string()
                    };
                    caption(&img, &label, scale, INK, WHITE)
                })
                .collect()
        })
        .collect();
    grid(&rows, 6, WHITE)
}

/// The two control lines of a fold carry opposite axes; the sign of the axis' largest component tells them
/// apart (stable along a smooth fold, opposite on its two lines).
fn side_sign(a: &Anchor) -> bool {
    let ax = a.axis;
    let k = (0..3)
        .max_by(|&i, &j| ax[i].abs().total_cmp(&ax[j].abs()))
        .unwrap_or(0);
    ax[k] >= 0.0
}
