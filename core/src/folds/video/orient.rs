//! Edge orientation under the "dark equals deep" model (Popa et al. 2009 §3.1, §4 "Edge Orientation").
//!
//! Under diffuse light, valleys receive light from a narrower solid angle than ridges, so fold contours are image
//! edges with a darker, deeper side. Each fitted edge is oriented so that, walking along it, the darker side is
//! on the left (image axes: x right, y down, so the left of direction `(dx, dy)` is `(dy, -dx)`). Edges whose
//! sides do not differ clearly and consistently in brightness are dropped, and so are edges with a large hue
//! difference across them: those are texture or colour boundaries, not shape.

use super::cameras::Photo;
use super::edges::LevelEdges;
use super::params::VideoParams;

/// An oriented fold-edge candidate (full-resolution pixel coordinates, darker side on the left).
#[derive(Debug, Clone, PartialEq)]
pub struct Edge {
    pub points: Vec<[f64; 2]>,
    /// Mean grey difference right − left (positive).
    pub contrast: f64,
}

/// Why an edge was not kept.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rejection {
    /// The sides are not clearly and consistently different in brightness.
    NoOrientation,
    /// The sides differ in hue (texture, colour boundary).
    Hue,
    /// Too few samples on the garment on both sides.
    OffGarment,
}

/// Unit tangent of a polyline at point `i` (central difference).
pub fn tangent(points: &[[f64; 2]], i: usize) -> [f64; 2] {
    let a = points[i.saturating_sub(1)];
    let b = points[(i + 1).min(points.len() - 1)];
    let d = [b[0] - a[0], b[1] - a[1]];
    let n = (d[0] * d[0] + d[1] * d[1]).sqrt();
    if n > 0.0 {
        [d[0] / n, d[1] / n]
    } else {
        [1.0, 0.0]
    }
}

/// The left normal of a unit image-space direction (y down).
#[inline]
pub fn left_of(d: [f64; 2]) -> [f64; 2] {
    [d[1], -d[0]]
}

/// Chromaticity (r, g) / (r + g + b): hue and saturation without brightness, so shading does not change it.
fn chroma(c: [f32; 3]) -> [f64; 2] {
    let s = (c[0] + c[1] + c[2]) as f64 + 1e-3;
    [c[0] as f64 / s, c[1] as f64 / s]
}

/// Orients `points` (one fitted edge of `level`) or says why it is rejected.
pub fn orient(
    points: &[[f64; 2]],
    level: &LevelEdges,
    photo: &Photo,
    params: &VideoParams,
) -> Result<Edge, Rejection> {
    // Sample just outside the level's blur footprint on both sides.
    let offset = 1.5 * level.level.radius / level.level.scale + 1.0;
    let mut diffs = Vec::with_capacity(points.len());
    let (mut cl, mut cr) = ([0.0f64; 2], [0.0f64; 2]);
    for i in 0..points.len() {
        let p = points[i];
        let n = left_of(tangent(points, i));
        let l = [p[0] + offset * n[0], p[1] + offset * n[1]];
        let r = [p[0] - offset * n[0], p[1] - offset * n[1]];
        if photo.has_alpha && !(photo.on_mask(l) && photo.on_mask(r)) {
            continue;
        }
        diffs.push((level.smoothed_at(r) - level.smoothed_at(l)) as f64);
        let (a, b) = (chroma(photo.rgb_at(l)), chroma(photo.rgb_at(r)));
        for k in 0..2 {
            cl[k] += a[k];
            cr[k] += b[k];
        }
    }
    if diffs.len() * 2 < points.len() || diffs.is_empty() {
        return Err(Rejection::OffGarment);
    }
    let m = diffs.len() as f64;
    let hue = ((cl[0] - cr[0]) / m).hypot((cl[1] - cr[1]) / m);
    if hue > params.max_hue_difference {
        return Err(Rejection::Hue);
    }
    let mean = diffs.iter().sum::<f64>() / m;
    let agree = diffs
        .iter()
        .filter(|d| d.signum() == mean.signum() && **d != 0.0)
        .count() as f64
        / m;
    if mean.abs() < params.min_contrast || agree < params.min_orientation_agreement {
        return Err(Rejection::NoOrientation);
    }
    let mut pts = points.to_vec();
    if mean < 0.0 {
        // The left side is brighter: walk the other way.
        pts.reverse();
    }
    Ok(Edge {
        points: pts,
        contrast: mean.abs(),
    })
}

#[cfg(test)]
mod tests {
    use super::super::edges::{extract, Level};
    use super::*;

    fn level_of(img: &image::RgbaImage) -> (Photo, LevelEdges, VideoParams) {
        let photo = Photo::from_rgba(img);
        let params = VideoParams::default();
        let level = extract(
            &photo,
            &photo.mask,
            Level {
                scale: 1.0,
                radius: 1.5,
            },
            &params,
        );
        (photo, level, params)
    }

    #[test]
    fn darker_side_ends_up_on_the_left() {
        // Dark left half, bright right half: a vertical edge. Walking down (+y) the left is +x... so the edge
        // must walk up (-y), with the dark half (-x) on its left.
        let mut img = image::RgbaImage::from_pixel(64, 48, image::Rgba([60, 60, 60, 255]));
        for y in 0..48 {
            for x in 32..64 {
                img.put_pixel(x, y, image::Rgba([160, 160, 160, 255]));
            }
        }
        let (photo, level, params) = level_of(&img);
        let down: Vec<[f64; 2]> = (5..40).map(|y| [31.5, y as f64]).collect();
        let e = orient(&down, &level, &photo, &params).unwrap();
        assert!(
            e.points[0][1] > e.points.last().unwrap()[1],
            "should walk up"
        );
        assert!(e.contrast > 50.0);
        let up: Vec<[f64; 2]> = down.iter().rev().copied().collect();
        assert_eq!(
            orient(&up, &level, &photo, &params).unwrap().points,
            e.points
        );
    }

    #[test]
    fn an_edge_between_two_hues_is_rejected() {
        // Equal-ish brightness difference, but blue against orange.
        let mut img = image::RgbaImage::from_pixel(64, 48, image::Rgba([40, 60, 150, 255]));
        for y in 0..48 {
            for x in 32..64 {
                img.put_pixel(x, y, image::Rgba([220, 130, 40, 255]));
            }
        }
        let (photo, level, params) = level_of(&img);
        let line: Vec<[f64; 2]> = (5..40).map(|y| [31.5, y as f64]).collect();
        assert_eq!(orient(&line, &level, &photo, &params), Err(Rejection::Hue));
    }

    #[test]
    fn flat_regions_have_no_orientation() {
        let img = image::RgbaImage::from_pixel(64, 48, image::Rgba([100, 100, 100, 255]));
        let (photo, level, params) = level_of(&img);
        let line: Vec<[f64; 2]> = (5..40).map(|y| [31.5, y as f64]).collect();
        assert_eq!(
            orient(&line, &level, &photo, &params),
            Err(Rejection::NoOrientation)
        );
    }
}
