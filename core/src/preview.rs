//! Pictures of a deformation result: before / after / stretch renders of a few frames, and a per-frame stretch
//! plot. People judge folds by eye first; these are what a run leaves next to its numbers.

use crate::mesh::{geometry, Frame, Topology};
use crate::metrics::{per_triangle_stretch, StretchStats};
use crate::render::{caption, grid, plot_lines, render, stretch_color, Camera, Style};
use crate::vec3::{self, V3};
use image::RgbImage;

const WHITE: [u8; 3] = [255, 255, 255];
const INK: [u8; 3] = [20, 20, 20];

/// Mean unit normal of the given triangles in `positions`, if they agree enough to define a side to look at.
pub fn fold_focus(
    topo: &Topology,
    positions: &[V3],
    triangles: impl Iterator<Item = u32>,
) -> Option<V3> {
    let normals = geometry::triangle_normals(topo, positions);
    let (mut sum, mut n) = ([0.0; 3], 0usize);
    for t in triangles {
        sum = vec3::add(sum, normals[t as usize]);
        n += 1;
    }
    (n > 0 && vec3::norm(sum) > 0.2 * n as f64).then(|| vec3::normalize(sum))
}

/// One row per kept frame: input, output, output seen from the far side, and output coloured by per-triangle
/// stretch (0 to `stretch_max`).
/// `focus` is the direction the folds face (see [`fold_focus`]); the camera looks at that side.
pub fn before_after(
    topo: &Topology,
    frames: &[(usize, Frame, Frame)],
    size: u32,
    stretch_max: f64,
    focus: Option<V3>,
) -> RgbImage {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for (_, rest, out) in frames {
        for p in [rest, out] {
            let (l, h) = geometry::bounding_box(p);
            for k in 0..3 {
                lo[k] = lo[k].min(l[k]);
                hi[k] = hi[k].max(h[k]);
            }
        }
    }
    let (dir, up) = match frames.first() {
        Some((_, rest, _)) => crate::view::view_for(rest, focus),
        None => crate::view::view_for(&[], focus),
    };
    let cam = Camera::fit(lo, hi, dir, up, size, size);
    // The far side, where folds hidden from the first camera show.
    let back_dir = {
        let h = vec3::sub(dir, vec3::scale(up, vec3::dot(dir, up)));
        vec3::normalize(vec3::sub(vec3::scale(dir, 1.0), vec3::scale(h, 2.0)))
    };
    let back = Camera::fit(lo, hi, back_dir, up, size, size);
    let scale = (size / 256).max(1);
    let rows: Vec<Vec<RgbImage>> = frames
        .iter()
        .map(|(t, rest, out)| {
            let stretch = per_triangle_stretch(topo, rest, out);
            let colors: Vec<[u8; 3]> = stretch
                .iter()
                .map(|&s| stretch_color(s, stretch_max))
                .collect();
            let a = render(rest, topo, &cam, &Style::default());
            let b = render(out, topo, &cam, &Style::default());
            let d = render(out, topo, &back, &Style::default());
            let c = render(
                out,
                topo,
                &cam,
                &Style {
                    triangle_colors: Some(&colors),
                    ..Style::default()
                },
            );
            vec![
                caption(&a, &format!("FRAME {t} INPUT"), scale, INK, WHITE),
                caption(&b, &format!("FRAME {t} OUTPUT"), scale, INK, WHITE),
                caption(&d, "OUTPUT, FAR SIDE", scale, INK, WHITE),
                caption(
                    &c,
                    &format!("STRETCH 0-{:.0}%", stretch_max * 100.0),
                    scale,
                    INK,
                    WHITE,
                ),
            ]
        })
        .collect();
    grid(&rows, 6, WHITE)
}

/// Per-frame maximum and 99th-percentile stretch (in %) after positioning and after each stretch pass.
pub fn stretch_plot(frame_stretch: &[Vec<StretchStats>], width: u32, height: u32) -> RgbImage {
    let passes = frame_stretch.iter().map(Vec::len).max().unwrap_or(0);
    let palette = [
        [200, 60, 40],
        [230, 150, 30],
        [40, 120, 200],
        [60, 160, 80],
        [120, 80, 160],
    ];
    let mut series = Vec::new();
    let names: Vec<String> = (0..passes)
        .map(|p| {
            if p == 0 {
                "POSITIONED".to_string()
            } else {
                format!("PASS {p}")
            }
        })
        .collect();
    for p in 0..passes {
        let pts: Vec<(f64, f64)> = frame_stretch
            .iter()
            .enumerate()
            .filter_map(|(t, s)| s.get(p).map(|s| (t as f64, s.max * 100.0)))
            .collect();
        series.push((names[p].as_str(), palette[p % palette.len()], pts));
    }
    plot_lines(
        &series,
        width,
        height,
        "MAX STRETCH PER FRAME",
        "FRAME",
        "MAX STRETCH %",
    )
}
