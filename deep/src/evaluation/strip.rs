//! The paper's Fig. 11 as a strip of one held-out frame's normal maps side by side: the capture's own, the
//! model's (what `apply --coarse` writes by default), the ground truth's; world-space normals as colours
//! ((n + 1) / 2 per channel), uncovered texels black.

use crate::apply::{frame_map, CoarseDetail, Source};
use crate::cgan::enhance::Enhancer;
use crate::detail::relief::CoarseRelief;
use crate::model::Model;
use crate::normal_maps::raster::TexelMap;
use crate::normal_maps::{world_from_vertex_normals, NormalMap, Space};
use crease_core::mesh::{geometry, Frame, Sequence};
use crease_core::vec3::V3;
use crease_core::{Error, Result};
use std::path::Path;

fn paint(img: &mut image::RgbImage, m: &NormalMap, x0: u32) {
    for y in 0..m.height {
        for x in 0..m.width {
            let k = y * m.width + x;
            let px = if m.covered[k] {
                let c = |v: f32| ((v.clamp(-1.0, 1.0) + 1.0) * 0.5 * 255.0).round() as u8;
                image::Rgb([c(m.n[k][0]), c(m.n[k][1]), c(m.n[k][2])])
            } else {
                image::Rgb([0, 0, 0])
            };
            img.put_pixel(x0 + x as u32, y as u32, px);
        }
    }
}

/// Writes the strip of frame `t` (0-based) of a capture sequence (`captures`, read from `capture_path`) and its
/// ground truth `gt` to `out` (PNG). The middle map is `apply --coarse`'s default for this model: the learned
/// filter's, or the capture with its relief (which reads the frames around `t`).
pub fn write_strip(
    model: &Model,
    captures: &[Frame],
    capture_path: &Path,
    gt: &[V3],
    t: usize,
    out: &Path,
) -> Result<()> {
    let res = model.manifest.resolution;
    let texels = TexelMap::new(&model.layout, res, res);
    let topo = &model.topology;
    let enhancer = Enhancer::for_model(model)?.filter(|e| e.spec.use_coarse);
    let capture = &captures[t];
    let gate = model
        .detail
        .surface_gate(topo, captures.iter().map(|f| f.as_slice()));
    let relieved = match model.coarse_detail() {
        CoarseDetail::Relief | CoarseDetail::Blend => {
            let seq = Sequence::new(topo.clone(), captures.to_vec())?;
            let mut relief = CoarseRelief::new(&seq)?;
            let heights = relief.heights(&seq, &[t])?;
            Some(relief.relieved(topo, capture, &heights[0]))
        }
        CoarseDetail::Model => None,
    };
    let maps = [
        world_from_vertex_normals(&texels, topo, &geometry::vertex_normals(topo, capture)),
        frame_map(
            model,
            &texels,
            capture,
            match &relieved {
                Some(r) if model.coarse_detail() == CoarseDetail::Blend => {
                    Source::Blended(capture_path, r, gate)
                }
                Some(r) => Source::Relieved(capture_path, r, gate),
                None => Source::Capture(capture_path, gate),
            },
            t,
            enhancer.as_ref(),
            Space::World,
        )?
        .map,
        world_from_vertex_normals(&texels, topo, &geometry::vertex_normals(topo, gt)),
    ];
    let mut img = image::RgbImage::new(3 * res as u32, res as u32);
    for (i, m) in maps.iter().enumerate() {
        paint(&mut img, m, (i * res) as u32);
    }
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| Error::format(out, None, format!("cannot encode PNG: {e}")))?;
    crease_core::fsutil::write_atomic(out, &bytes)
}
