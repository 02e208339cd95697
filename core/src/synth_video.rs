//! Synthetic capture video for tests and demos: the demo's ground-truth folded sequence rendered from a ring of
//! calibrated cameras with the project's rasterizer.
//!
//! Popa et al. 2009 §3.1 assume Lambertian cloth under diffuse light, where valleys are darker than ridges
//! because they see a narrower solid angle of sky ("dark equals deep"). The rasterizer's lights are directional,
//! so a cheap ambient-occlusion term supplies that: per vertex, the height of the vertex above the mean of its
//! ring neighbourhood along its outward normal; vertices below their neighbourhood (valleys) are darkened,
//! vertices above it (ridges) lit fully. Images are RGBA with the garment's coverage as alpha, like a matted
//! capture.

use crate::error::Result;
use crate::folds::video::cameras::{CameraRig, NamedCamera, DEFAULT_IMAGE_PATTERN};
use crate::mesh::{geometry, Topology};
use crate::render::{self, Camera, Projection, Style};
use crate::vec3::{self, V3};
use image::RgbaImage;
use std::path::Path;

/// Rings of the neighbourhood the occlusion term compares a vertex with.
const OCCLUSION_RINGS: usize = 3;
/// Brightness of flat cloth; ridges reach 1, valleys go down to [`MIN_OCCLUSION`].
const FLAT_OCCLUSION: f64 = 0.75;
const MIN_OCCLUSION: f64 = 0.2;
/// Darkening per mean edge length of depth below the neighbourhood.
const OCCLUSION_GAIN: f64 = 2.5;

/// Per-vertex occlusion in `[MIN_OCCLUSION, 1]` (see the module documentation). Normals are oriented away from
/// the frame's centroid, which suits closed and tube-like garments.
pub fn occlusion(topo: &Topology, positions: &[V3]) -> Vec<f32> {
    let normals = geometry::vertex_normals(topo, positions);
    let c = crate::folds::video::views::centroid(positions);
    let mut edge_sum = 0.0;
    let mut edge_n = 0usize;
    for t in topo.triangles() {
        for k in 0..3 {
            edge_sum += vec3::norm(vec3::sub(
                positions[t[k] as usize],
                positions[t[(k + 1) % 3] as usize],
            ));
            edge_n += 1;
        }
    }
    let ell = (edge_sum / edge_n.max(1) as f64).max(1e-12);
    (0..positions.len())
        .map(|v| {
            let ring = topo.vertex_ring_neighborhood(v, OCCLUSION_RINGS);
            let mean = vec3::scale(
                ring.iter()
                    .fold([0.0; 3], |a, &u| vec3::add(a, positions[u as usize])),
                1.0 / ring.len().max(1) as f64,
            );
            let mut n = normals[v];
            if vec3::dot(n, vec3::sub(positions[v], c)) < 0.0 {
                n = vec3::scale(n, -1.0);
            }
            let height = vec3::dot(vec3::sub(positions[v], mean), n) / ell;
            (FLAT_OCCLUSION + OCCLUSION_GAIN * height).clamp(MIN_OCCLUSION, 1.0) as f32
        })
        .collect()
}

/// `n` cameras on a ring around the vertical (z) axis of the box `[lo, hi]`, looking slightly down at it, each
/// framing the whole box at `width x height` pixels.
pub fn ring_cameras(lo: V3, hi: V3, n: usize, width: u32, height: u32) -> Vec<NamedCamera> {
    (0..n)
        .map(|k| {
            let phi = 2.0 * std::f64::consts::PI * (k as f64 + 0.125) / n as f64;
            let dir = [-phi.cos(), -phi.sin(), -0.2];
            let cam = Camera::fit(lo, hi, dir, [0.0, 0.0, 1.0], width, height).calibrated();
            NamedCamera {
                name: format!("cam{k:02}"),
                camera: cam,
            }
        })
        .collect()
}

/// Renders one frame from one camera: shaded cloth with occlusion, alpha = coverage.
pub fn render_frame(
    topo: &Topology,
    positions: &[V3],
    occ: &[f32],
    camera: &crate::render::CalibratedCamera,
) -> RgbaImage {
    let style = |bg: [u8; 3]| Style {
        vertex_occlusion: Some(occ),
        background: bg,
        supersample: 2,
        ..Style::default()
    };
    let black = render::render(positions, topo, camera, &style([0, 0, 0]));
    let white = render::render(positions, topo, camera, &style([255, 255, 255]));
    let mut out = RgbaImage::new(black.width(), black.height());
    for (x, y, px) in out.enumerate_pixels_mut() {
        let b = black.get_pixel(x, y).0;
        let w = white.get_pixel(x, y).0;
        // On black, a pixel is coverage · colour; on white, coverage · colour + (1 − coverage) · 255.
        let cover = 1.0 - (0..3).map(|k| w[k] as f64 - b[k] as f64).sum::<f64>() / (3.0 * 255.0);
        let cover = cover.clamp(0.0, 1.0);
        let rgb = if cover > 0.0 {
            b.map(|c| (c as f64 / cover).round().clamp(0.0, 255.0) as u8)
        } else {
            [255, 255, 255]
        };
        *px = image::Rgba([rgb[0], rgb[1], rgb[2], (cover * 255.0).round() as u8]);
    }
    out
}

/// One image of folds the video detector actually pairs, for benchmarks and tests: the demo's ground-truth
/// folded sequence (its anchors' full effect, made without the shape screen, as the folds_video test makes
/// its truth) of a `triangles`-triangle tube, frame 1, seen by the first ring camera at `width x height`.
/// The demo's own frames are the smoothed capture, which has no folds to pair.
pub fn folded_demo_image(triangles: usize, width: u32, height: u32) -> Result<RgbaImage> {
    use crate::spacetime::{deform, DeformParams};
    let spec = crate::synth::DemoSpec {
        triangles,
        frames: 4,
        ..Default::default()
    };
    let (seq, anchors) = crate::synth::demo(&spec)?;
    let truth = DeformParams {
        shape_cutoff: 0.0,
        // Popa's stretch passes, not crease's fold-keeping default: the truth stays what it was whatever the
        // reconstruction's defaults become.
        stretch_rotation: crate::spacetime::position::stretch::StretchRotation::Polar,
        // Nor crease's fold relief, which reads the captured surface the truth is made from.
        relief: crate::spacetime::shape::relief::ReliefParams {
            steps: 0,
            ..Default::default()
        },
        // Nor its strain limit, nor the bound by the surface a capture lost (the truth is the anchors' effect).
        strain_limit: 0.0,
        lost_area_bound: false,
        ..DeformParams::default()
    };
    let mut sink = crate::mesh::MemorySink::default();
    deform(
        &seq,
        &anchors,
        &truth,
        &mut sink,
        &crate::progress::NoProgress,
        &[],
    )?;
    let gt: Vec<Vec<V3>> = sink.frames.into_values().collect();
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for f in &gt {
        let (a, b) = geometry::bounding_box(f);
        for k in 0..3 {
            lo[k] = lo[k].min(a[k]);
            hi[k] = hi[k].max(b[k]);
        }
    }
    let cam = &ring_cameras(lo, hi, 1, width, height)[0].camera;
    let f = &gt[1];
    Ok(render_frame(
        &seq.topology,
        f,
        &occlusion(&seq.topology, f),
        cam,
    ))
}

/// Writes `cameras.json` and `images/<camera>/frame_NNNN.png` (NNNN = `first_number + t`) for `frames` into
/// `dir`, from a ring of `n_cameras` cameras. Returns the rig.
pub fn write_video(
    dir: &Path,
    topo: &Topology,
    frames: &[Vec<V3>],
    n_cameras: usize,
    width: u32,
    height: u32,
    first_number: u64,
) -> Result<CameraRig> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for f in frames {
        let (a, b) = geometry::bounding_box(f);
        for k in 0..3 {
            lo[k] = lo[k].min(a[k]);
            hi[k] = hi[k].max(b[k]);
        }
    }
    let rig = CameraRig {
        cameras: ring_cameras(lo, hi, n_cameras.max(1), width, height),
        images_dir: dir.join("images"),
        image_pattern: DEFAULT_IMAGE_PATTERN.to_string(),
    };
    crate::fsutil::write_atomic(&dir.join("cameras.json"), rig.to_json().as_bytes())?;
    for c in 0..rig.cameras.len() {
        let path = rig.image_path(c, first_number);
        if let Some(parent) = path.parent() {
            crate::fsutil::create_dir_all(parent)?;
        }
    }
    use rayon::prelude::*;
    frames
        .par_iter()
        .enumerate()
        .try_for_each(|(t, f)| -> Result<()> {
            let occ = occlusion(topo, f);
            for (c, nc) in rig.cameras.iter().enumerate() {
                let img = render_frame(topo, f, &occ, &nc.camera);
                let path = rig.image_path(c, first_number + t as u64);
                let mut bytes = Vec::new();
                image::DynamicImage::ImageRgba8(img)
                    .write_to(
                        &mut std::io::Cursor::new(&mut bytes),
                        image::ImageFormat::Png,
                    )
                    .map_err(|e| {
                        crate::Error::format(&path, None, format!("cannot encode PNG: {e}"))
                    })?;
                crate::fsutil::write_atomic(&path, &bytes)?;
            }
            Ok(())
        })?;
    Ok(rig)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::folds::video::{image_pairs, Photo, VideoParams};

    /// The video benchmark's image must exercise pairing, not only edge extraction.
    #[test]
    fn the_folded_benchmark_image_yields_pairs() {
        // The same image `crease bench` times.
        let img = folded_demo_image(40_000, 640, 480).unwrap();
        assert_eq!((img.width(), img.height()), (640, 480));
        let (levels, pairs) = image_pairs(&Photo::from_rgba(&img), &VideoParams::default());
        let edges: usize = levels.iter().map(|l| l.edges.len()).sum();
        assert!(edges > 0, "no edges");
        assert!(pairs.len() >= 3, "{} pairs from {edges} edges", pairs.len());
    }
}
