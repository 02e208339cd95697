//! Rasterisation of a mesh in UV space: which triangle, at which barycentric coordinates, every texel centre
//! lies on. It depends only on the layout and the resolution, so it is computed once and every frame's map is
//! a gather through it (the per-frame cost is then linear in texels, which is what keeps inference fast).

use crate::normal_maps::uv::UvLayout;
use crease_core::mesh::NONE;

/// Per texel (row-major, row 0 at the top = v near 1): the covering triangle (or [`NONE`]) and barycentrics.
#[derive(Debug, Clone)]
pub struct TexelMap {
    pub width: usize,
    pub height: usize,
    pub tri: Vec<u32>,
    pub bary: Vec<[f32; 3]>,
}

impl TexelMap {
    /// Texel centre (x, y) is at u = (x + 0.5) / W, v = 1 − (y + 0.5) / H (the output contract: x = u·W − 0.5,
    /// y = (1 − v)·H − 0.5). A texel on a shared edge goes to the first triangle that claims it.
    pub fn new(layout: &UvLayout, width: usize, height: usize) -> Self {
        let mut tri = vec![NONE; width * height];
        let mut bary = vec![[0.0f32; 3]; width * height];
        let (w, h) = (width as f64, height as f64);
        for (t, c) in layout.corners.iter().enumerate() {
            let p: Vec<[f64; 2]> = c
                .iter()
                .map(|&i| {
                    let q = layout.uv[i as usize];
                    [q[0] * w - 0.5, (1.0 - q[1]) * h - 0.5]
                })
                .collect();
            let det = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1])
                - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
            if det.abs() < 1e-14 {
                continue;
            }
            let x0 = p
                .iter()
                .map(|q| q[0])
                .fold(f64::INFINITY, f64::min)
                .ceil()
                .max(0.0) as i64;
            let x1 = p
                .iter()
                .map(|q| q[0])
                .fold(f64::NEG_INFINITY, f64::max)
                .floor()
                .min(w - 1.0) as i64;
            let y0 = p
                .iter()
                .map(|q| q[1])
                .fold(f64::INFINITY, f64::min)
                .ceil()
                .max(0.0) as i64;
            let y1 = p
                .iter()
                .map(|q| q[1])
                .fold(f64::NEG_INFINITY, f64::max)
                .floor()
                .min(h - 1.0) as i64;
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let (fx, fy) = (x as f64, y as f64);
                    let b1 = ((fx - p[0][0]) * (p[2][1] - p[0][1])
                        - (p[2][0] - p[0][0]) * (fy - p[0][1]))
                        / det;
                    let b2 = ((p[1][0] - p[0][0]) * (fy - p[0][1])
                        - (fx - p[0][0]) * (p[1][1] - p[0][1]))
                        / det;
                    let b0 = 1.0 - b1 - b2;
                    let eps = -1e-9;
                    if b0 >= eps && b1 >= eps && b2 >= eps {
                        let k = y as usize * width + x as usize;
                        if tri[k] == NONE {
                            tri[k] = t as u32;
                            bary[k] = [b0 as f32, b1 as f32, b2 as f32];
                        }
                    }
                }
            }
        }
        TexelMap {
            width,
            height,
            tri,
            bary,
        }
    }

    /// Share of texels covered by some triangle.
    pub fn coverage(&self) -> f64 {
        self.tri.iter().filter(|&&t| t != NONE).count() as f64 / self.tri.len().max(1) as f64
    }
}
