//! Normal maps in UV space (Lähner et al. 2018 §4.1).
//!
//! Low-resolution maps interpolate a coarse mesh's vertex normals over its faces; high-resolution maps project
//! the fine surface onto the coarse one (a ray along the coarse normal, both ways) and keep the fine normal
//! where it lands, so the detail is stored in the coarse mesh's own layout. World space is what the cGAN
//! conditions on (the paper's point: a low-resolution map is constant in tangent space); tangent space is what
//! engines want, so both are written. PNG: 16-bit RGBA, n = 2·c/65535 − 1, alpha 65535 on covered texels; the
//! RGB is dilated a few texels into the gutter so bilinear lookups at chart borders do not fetch blanks.

/// Texels per side of the normal maps a model draws unless told otherwise. Why 512 and not the paper's 256: a
/// map is the deliverable, and at 256² a garment of about 7,000 vertices gets five or six texels per vertex, too
/// few to carry the normals the detail restores (on a held-out sleeve the 256² map of a mildly smoothed capture
/// was further from the cloth than the capture's own mesh normals); 512² costs a few milliseconds more per frame
/// to draw and write, within the real-time budget.
pub const DEFAULT_RESOLUTION: usize = 512;

pub mod bake;
pub mod raster;
pub mod uv;

use crate::normal_maps::raster::TexelMap;
use crate::normal_maps::uv::UvLayout;
use crease_core::mesh::geometry;
use crease_core::mesh::{Topology, NONE};
use crease_core::vec3::{self, V3};
use crease_core::{Error, Result};
use parry3d::math::Vector;
use parry3d::query::{Ray, RayCast};
use parry3d::shape::TriMesh;
use std::path::Path;

/// Which frame the stored normals are expressed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Space {
    World,
    Tangent,
}

impl std::str::FromStr for Space {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "world" => Ok(Space::World),
            "tangent" => Ok(Space::Tangent),
            _ => Err(format!("unknown normal space `{s}` (world or tangent)")),
        }
    }
}

/// A normal per texel (row-major, row 0 = top) and whether the surface covers it.
#[derive(Debug, Clone, PartialEq)]
pub struct NormalMap {
    pub width: usize,
    pub height: usize,
    pub n: Vec<[f32; 3]>,
    pub covered: Vec<bool>,
}

impl NormalMap {
    fn empty(width: usize, height: usize) -> Self {
        NormalMap {
            width,
            height,
            n: vec![[0.0; 3]; width * height],
            covered: vec![false; width * height],
        }
    }

    /// Mean angle (degrees) between two maps over the texels both cover.
    pub fn mean_angle_deg(&self, other: &NormalMap) -> f64 {
        let (mut s, mut c) = (0.0, 0usize);
        for k in 0..self.n.len().min(other.n.len()) {
            if self.covered[k] && other.covered[k] {
                s += angle_deg(self.n[k], other.n[k]);
                c += 1;
            }
        }
        if c == 0 {
            0.0
        } else {
            s / c as f64
        }
    }

    /// Writes a 16-bit RGBA PNG (atomically, synced).
    pub fn write_png(&self, path: &Path) -> Result<()> {
        let mut scratch = PngScratch::default();
        let bytes = self.encode_png(path, PngSettings::default(), &mut scratch)?;
        crease_core::fsutil::write_atomic(path, bytes)
    }

    /// The PNG file's bytes (16-bit RGBA, RGB dilated 3 texels into the gutter, alpha = coverage) in
    /// `scratch`, whose buffers are reused from frame to frame. `path` only names the file in an error.
    pub fn encode_png<'s>(
        &self,
        path: &Path,
        settings: PngSettings,
        scratch: &'s mut PngScratch,
    ) -> Result<&'s [u8]> {
        let PngScratch {
            dilated,
            dilation,
            pixels,
            bytes,
        } = scratch;
        self.dilate_into(3, dilated, dilation);
        let enc = |x: f32| (((x.clamp(-1.0, 1.0) + 1.0) * 0.5) * 65535.0).round() as u16;
        pixels.clear();
        pixels.reserve(8 * self.n.len());
        for (n, &covered) in dilated.n.iter().zip(&self.covered) {
            let a: u16 = if covered { 65535 } else { 0 };
            for c in [enc(n[0]), enc(n[1]), enc(n[2]), a] {
                pixels.extend_from_slice(&c.to_ne_bytes());
            }
        }
        bytes.clear();
        use image::ImageEncoder as _;
        image::codecs::png::PngEncoder::new_with_quality(
            &mut *bytes,
            settings.compression,
            settings.filter,
        )
        .write_image(
            pixels,
            self.width as u32,
            self.height as u32,
            image::ExtendedColorType::Rgba16,
        )
        .map_err(|e| Error::format(path, None, format!("cannot encode PNG: {e}")))?;
        Ok(bytes)
    }

    /// Reads a normal map PNG (8 or 16 bit, RGB or RGBA; without alpha every texel counts as covered).
    pub fn read_png(path: &Path) -> Result<Self> {
        let img = image::open(path)
            .map_err(|e| Error::format(path, None, format!("not a readable PNG: {e}")))?;
        let has_alpha = img.color().has_alpha();
        let img = img.to_rgba16();
        let (w, h) = (img.width() as usize, img.height() as usize);
        let mut m = NormalMap::empty(w, h);
        for (k, px) in img.pixels().enumerate() {
            let d = |c: u16| c as f32 / 65535.0 * 2.0 - 1.0;
            m.n[k] = normalize_f32([d(px[0]), d(px[1]), d(px[2])]);
            m.covered[k] = !has_alpha || px[3] > 0;
        }
        Ok(m)
    }

    /// Copies covered normals into uncovered texels next to them, `rings` times (the gutter fill).
    pub fn dilated(&self, rings: usize) -> NormalMap {
        let mut out = NormalMap::empty(0, 0);
        self.dilate_into(rings, &mut out, &mut Dilation::default());
        out
    }

    /// [`NormalMap::dilated`] into `out`, reusing its buffers and `work`'s. Each ring fills an uncovered texel
    /// with the normalised sum of its covered 8-neighbours as they were before the ring; only the texels next
    /// to the previous ring's new ones can change, so a ring visits those instead of the whole map.
    pub fn dilate_into(&self, rings: usize, out: &mut NormalMap, work: &mut Dilation) {
        out.width = self.width;
        out.height = self.height;
        out.n.clone_from(&self.n);
        out.covered.clone_from(&self.covered);
        let (w, h) = (self.width as i64, self.height as i64);
        let neighbours = |k: usize| {
            let (x, y) = ((k as i64) % w, (k as i64) / w);
            DILATION_NEIGHBOURS.iter().filter_map(move |&(dx, dy)| {
                let (xx, yy) = (x + dx, y + dy);
                (xx >= 0 && yy >= 0 && xx < w && yy < h).then_some((yy * w + xx) as usize)
            })
        };
        let Dilation {
            candidates,
            seen,
            filled,
        } = work;
        seen.clear();
        seen.resize(self.n.len(), 0);
        candidates.clear();
        if rings > 0 {
            candidates.extend(
                (0..self.n.len())
                    .filter(|&k| !out.covered[k] && neighbours(k).any(|j| out.covered[j])),
            );
        }
        for ring in 1..=rings {
            filled.clear();
            for &k in candidates.iter() {
                let mut acc = [0.0f32; 3];
                let mut any = false;
                for j in neighbours(k) {
                    if out.covered[j] {
                        for (a, v) in acc.iter_mut().zip(out.n[j]) {
                            *a += v;
                        }
                        any = true;
                    }
                }
                if any {
                    filled.push((k, normalize_f32(acc)));
                }
            }
            for &(k, n) in filled.iter() {
                out.n[k] = n;
                out.covered[k] = true;
            }
            if ring == rings {
                break;
            }
            // The next ring's candidates: uncovered neighbours of this ring's texels, each once.
            candidates.clear();
            for &(k, _) in filled.iter() {
                for j in neighbours(k) {
                    if !out.covered[j] && seen[j] != ring as u32 {
                        seen[j] = ring as u32;
                        candidates.push(j);
                    }
                }
            }
        }
    }

    /// Bilinear lookup at (u, v) (the output contract's pixel convention), weighting only covered texels; `None` when none
    /// of the four is covered.
    pub fn sample(&self, uv: [f64; 2]) -> Option<V3> {
        let x = uv[0] * self.width as f64 - 0.5;
        let y = (1.0 - uv[1]) * self.height as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let mut acc = [0.0; 3];
        let mut wsum = 0.0;
        for (dx, dy, wt) in [
            (0, 0, (1.0 - fx) * (1.0 - fy)),
            (1, 0, fx * (1.0 - fy)),
            (0, 1, (1.0 - fx) * fy),
            (1, 1, fx * fy),
        ] {
            let xi = (x0 as i64 + dx).clamp(0, self.width as i64 - 1) as usize;
            let yi = (y0 as i64 + dy).clamp(0, self.height as i64 - 1) as usize;
            let k = yi * self.width + xi;
            if self.covered[k] && wt > 0.0 {
                for (a, v) in acc.iter_mut().zip(self.n[k]) {
                    *a += wt * v as f64;
                }
                wsum += wt;
            }
        }
        (wsum > 0.0).then(|| vec3::normalize(acc))
    }
}

/// The neighbours a gutter texel averages, in the order their normals are summed (the order fixes the bits).
const DILATION_NEIGHBOURS: [(i64, i64); 8] = [
    (-1, 0),
    (1, 0),
    (0, -1),
    (0, 1),
    (-1, -1),
    (1, 1),
    (-1, 1),
    (1, -1),
];

/// Work lists of [`NormalMap::dilate_into`], kept between frames.
#[derive(Debug, Clone, Default)]
pub struct Dilation {
    candidates: Vec<usize>,
    seen: Vec<u32>,
    filled: Vec<(usize, [f32; 3])>,
}

/// Encoder settings of the normal-map PNGs. The default is the `image` crate's default (its fast deflate,
/// fdeflate, and the adaptive filter): the bytes every earlier `crease deep apply` wrote, and the fastest
/// setting that still compresses (`crease bench --deep` times the others).
#[derive(Debug, Clone, Copy)]
pub struct PngSettings {
    pub compression: image::codecs::png::CompressionType,
    pub filter: image::codecs::png::FilterType,
}

impl Default for PngSettings {
    fn default() -> Self {
        PngSettings {
            compression: image::codecs::png::CompressionType::Fast,
            filter: image::codecs::png::FilterType::Adaptive,
        }
    }
}

/// Buffers of [`NormalMap::encode_png`], kept between frames (a 256² map is 0.5 MB of pixels).
#[derive(Debug, Clone)]
pub struct PngScratch {
    dilated: NormalMap,
    dilation: Dilation,
    pixels: Vec<u8>,
    bytes: Vec<u8>,
}

impl Default for PngScratch {
    fn default() -> Self {
        PngScratch {
            dilated: NormalMap::empty(0, 0),
            dilation: Dilation::default(),
            pixels: Vec::new(),
            bytes: Vec::new(),
        }
    }
}

pub fn angle_deg(a: [f32; 3], b: [f32; 3]) -> f64 {
    let d = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) as f64;
    d.clamp(-1.0, 1.0).acos().to_degrees()
}

fn normalize_f32(a: [f32; 3]) -> [f32; 3] {
    let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    if n > 0.0 {
        [a[0] / n, a[1] / n, a[2] / n]
    } else {
        [0.0, 0.0, 1.0]
    }
}

fn to_f32(a: V3) -> [f32; 3] {
    [a[0] as f32, a[1] as f32, a[2] as f32]
}

fn interp(b: [f32; 3], tri: [u32; 3], per_vertex: &[V3]) -> V3 {
    let mut p = [0.0; 3];
    for k in 0..3 {
        p = vec3::add(p, vec3::scale(per_vertex[tri[k] as usize], b[k] as f64));
    }
    p
}

/// Low-resolution map: the coarse mesh's area-weighted vertex normals interpolated over each face (world space).
pub fn bake_coarse(texels: &TexelMap, topo: &Topology, positions: &[V3]) -> NormalMap {
    let vn = geometry::vertex_normals(topo, positions);
    let mut m = NormalMap::empty(texels.width, texels.height);
    let tris = topo.triangles();
    for k in 0..texels.tri.len() {
        let t = texels.tri[k];
        if t == NONE {
            continue;
        }
        m.n[k] = to_f32(vec3::normalize(interp(
            texels.bary[k],
            tris[t as usize],
            &vn,
        )));
        m.covered[k] = true;
    }
    m
}

/// A fine surface prepared for projection: its BVH and vertex normals.
pub struct FineSurface {
    mesh: TriMesh,
    tris: Vec<[u32; 3]>,
    positions: Vec<V3>,
    normals: Vec<V3>,
    origin: V3,
}

impl FineSurface {
    pub fn new(topo: &Topology, positions: &[V3]) -> Result<Self> {
        let (lo, hi) = geometry::bounding_box(positions);
        let origin = vec3::scale(vec3::add(lo, hi), 0.5);
        let verts: Vec<Vector> = positions
            .iter()
            .map(|&p| {
                let q = vec3::sub(p, origin);
                Vector::new(q[0] as f32, q[1] as f32, q[2] as f32)
            })
            .collect();
        let mesh = TriMesh::new(verts, topo.triangles().to_vec()).map_err(|e| {
            Error::mesh(format!(
                "cannot build the projection BVH of the fine mesh: {e:?}"
            ))
        })?;
        Ok(FineSurface {
            mesh,
            tris: topo.triangles().to_vec(),
            positions: positions.to_vec(),
            normals: geometry::vertex_normals(topo, positions),
            origin,
        })
    }

    /// The fine surface's interpolated normal where the line through `p` along `dir` first meets it within
    /// `max_dist` on either side.
    pub fn project(&self, p: V3, dir: V3, max_dist: f64) -> Option<V3> {
        let q = vec3::sub(p, self.origin);
        let o = Vector::new(q[0] as f32, q[1] as f32, q[2] as f32);
        let mut best: Option<(f64, u32)> = None;
        for s in [1.0f64, -1.0] {
            let d = Vector::new(
                (dir[0] * s) as f32,
                (dir[1] * s) as f32,
                (dir[2] * s) as f32,
            );
            if let Some(hit) =
                self.mesh
                    .cast_local_ray_and_get_normal(&Ray::new(o, d), max_dist as f32, false)
            {
                let signed = hit.time_of_impact as f64 * s;
                if best.is_none_or(|b| signed.abs() < b.0.abs()) {
                    best = Some((signed, hit.subshape));
                }
            }
        }
        let (toi, tri) = best?;
        let tri_v = self.tris.get(tri as usize)?;
        let [a, b, c] = [0, 1, 2].map(|k| self.positions[tri_v[k] as usize]);
        let hit = vec3::add(p, vec3::scale(dir, toi));
        let w = barycentric(hit, a, b, c);
        let mut n = [0.0; 3];
        for k in 0..3 {
            n = vec3::add(n, vec3::scale(self.normals[tri_v[k] as usize], w[k]));
        }
        Some(vec3::normalize(n))
    }
}

fn barycentric(p: V3, a: V3, b: V3, c: V3) -> [f64; 3] {
    let (v0, v1, v2) = (vec3::sub(b, a), vec3::sub(c, a), vec3::sub(p, a));
    let (d00, d01, d11) = (vec3::dot(v0, v0), vec3::dot(v0, v1), vec3::dot(v1, v1));
    let (d20, d21) = (vec3::dot(v2, v0), vec3::dot(v2, v1));
    let den = d00 * d11 - d01 * d01;
    if den.abs() < 1e-30 {
        return [1.0 / 3.0; 3];
    }
    let v = ((d11 * d20 - d01 * d21) / den).clamp(0.0, 1.0);
    let w = ((d00 * d21 - d01 * d20) / den).clamp(0.0, 1.0 - v);
    [1.0 - v - w, v, w]
}

/// High-resolution map: every covered texel's point on the coarse mesh is projected along the coarse normal
/// onto the fine surface, whose normal is stored (world space). Texels whose ray meets nothing within
/// `max_dist` stay uncovered (the paper's grey "no information" areas).
pub fn bake_fine(
    texels: &TexelMap,
    coarse_topo: &Topology,
    coarse: &[V3],
    fine: &FineSurface,
    max_dist: f64,
) -> NormalMap {
    use rayon::prelude::*;
    let vn = geometry::vertex_normals(coarse_topo, coarse);
    let tris = coarse_topo.triangles();
    let cells: Vec<Option<[f32; 3]>> = (0..texels.tri.len())
        .into_par_iter()
        .map(|k| {
            let t = texels.tri[k];
            if t == NONE {
                return None;
            }
            let tri = tris[t as usize];
            let p = interp(texels.bary[k], tri, coarse);
            let n = vec3::normalize(interp(texels.bary[k], tri, &vn));
            fine.project(p, n, max_dist).map(to_f32)
        })
        .collect();
    let mut m = NormalMap::empty(texels.width, texels.height);
    for (k, c) in cells.into_iter().enumerate() {
        if let Some(n) = c {
            m.n[k] = n;
            m.covered[k] = true;
        }
    }
    m
}

/// Per-triangle tangent and bitangent directions (∂p/∂u, ∂p/∂v) of the layout.
fn triangle_tangents(topo: &Topology, positions: &[V3], layout: &UvLayout) -> Vec<(V3, V3)> {
    topo.triangles()
        .iter()
        .zip(&layout.corners)
        .map(|(t, c)| {
            let [p0, p1, p2] = [0, 1, 2].map(|k| positions[t[k] as usize]);
            let [w0, w1, w2] = [0, 1, 2].map(|k| layout.uv[c[k] as usize]);
            let (e1, e2) = (vec3::sub(p1, p0), vec3::sub(p2, p0));
            let (du1, dv1, du2, dv2) = (w1[0] - w0[0], w1[1] - w0[1], w2[0] - w0[0], w2[1] - w0[1]);
            let det = du1 * dv2 - du2 * dv1;
            if det.abs() < 1e-20 {
                return ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
            }
            let r = 1.0 / det;
            let tan = vec3::scale(vec3::sub(vec3::scale(e1, dv2), vec3::scale(e2, dv1)), r);
            let bit = vec3::scale(vec3::sub(vec3::scale(e2, du1), vec3::scale(e1, du2)), r);
            (tan, bit)
        })
        .collect()
}

/// The orthonormal (T, B, N) frame at a texel: N interpolated, T from ∂p/∂u made orthogonal to N, B = ±N×T
/// with the sign of ∂p/∂v (mirrored charts keep a right-handed meaning of "up" in the map).
fn frame_at(
    k: usize,
    texels: &TexelMap,
    topo: &Topology,
    vn: &[V3],
    tb: &[(V3, V3)],
) -> Option<[V3; 3]> {
    let t = texels.tri[k];
    if t == NONE {
        return None;
    }
    let n = vec3::normalize(interp(texels.bary[k], topo.triangles()[t as usize], vn));
    let (tan, bit) = tb[t as usize];
    let tt = vec3::normalize(vec3::sub(tan, vec3::scale(n, vec3::dot(n, tan))));
    let mut b = vec3::cross(n, tt);
    if vec3::dot(b, bit) < 0.0 {
        b = vec3::scale(b, -1.0);
    }
    Some([tt, b, n])
}

/// Re-expresses a world-space map in the tangent frames of the coarse mesh `positions` with `layout`
/// (`to_tangent = false` goes back).
pub fn convert_space(
    map: &NormalMap,
    texels: &TexelMap,
    topo: &Topology,
    positions: &[V3],
    layout: &UvLayout,
    to_tangent: bool,
) -> NormalMap {
    let vn = geometry::vertex_normals(topo, positions);
    let tb = triangle_tangents(topo, positions, layout);
    let mut out = map.clone();
    for k in 0..map.n.len() {
        if !map.covered[k] {
            continue;
        }
        if let Some([t, b, n]) = frame_at(k, texels, topo, &vn, &tb) {
            let v = [map.n[k][0] as f64, map.n[k][1] as f64, map.n[k][2] as f64];
            let r = if to_tangent {
                [vec3::dot(v, t), vec3::dot(v, b), vec3::dot(v, n)]
            } else {
                vec3::add(
                    vec3::add(vec3::scale(t, v[0]), vec3::scale(b, v[1])),
                    vec3::scale(n, v[2]),
                )
            };
            out.n[k] = to_f32(vec3::normalize(r));
        }
    }
    out
}

/// Per original vertex: the map sampled at each of its face corners' UVs and averaged (as the normal error is measured).
/// Vertices no covered texel reaches get `None`.
pub fn sample_vertex_normals(
    map: &NormalMap,
    topo: &Topology,
    layout: &UvLayout,
) -> Vec<Option<V3>> {
    let mut acc = vec![[0.0; 3]; topo.n_vertices()];
    let mut cnt = vec![0usize; topo.n_vertices()];
    for (tri, c) in topo.triangles().iter().zip(&layout.corners) {
        for k in 0..3 {
            if let Some(n) = map.sample(layout.uv[c[k] as usize]) {
                let v = tri[k] as usize;
                acc[v] = vec3::add(acc[v], n);
                cnt[v] += 1;
            }
        }
    }
    acc.into_iter()
        .zip(cnt)
        .map(|(a, c)| (c > 0).then(|| vec3::normalize(a)))
        .collect()
}

/// Stored-map helper for tests and tools: the map's world-space normal at every texel as an image-sized array.
pub fn world_from_vertex_normals(texels: &TexelMap, topo: &Topology, vn: &[V3]) -> NormalMap {
    let mut m = NormalMap::empty(texels.width, texels.height);
    for k in 0..texels.tri.len() {
        let t = texels.tri[k];
        if t != NONE {
            m.n[k] = to_f32(vec3::normalize(interp(
                texels.bary[k],
                topo.triangles()[t as usize],
                vn,
            )));
            m.covered[k] = true;
        }
    }
    m
}
