//! UV layouts: the texture coordinates normal maps live in.
//!
//! A layout stores texture coordinates per triangle corner, because a seam vertex has one coordinate per chart
//! it belongs to. It comes from the template OBJ's `vt` lines when there are any; otherwise it is computed
//! ([`auto_atlas`]): triangles are grouped into charts by their dominant normal direction, each chart is
//! flattened with LSCM (crease-core) and the charts are packed into the unit square with a gutter, so that the
//! bilinear sampling of a map never mixes two charts.

use crease_core::folds::stretch::lscm::lscm;
use crease_core::mesh::geometry;
use crease_core::mesh::{Topology, NONE};
use crease_core::vec3::{self, V3};
use crease_core::{Error, Result};
use std::path::Path;

/// Texture coordinates per triangle corner. `corners[t][k]` indexes `uv` for corner `k` of triangle `t`.
#[derive(Debug, Clone, PartialEq)]
pub struct UvLayout {
    pub uv: Vec<[f64; 2]>,
    pub corners: Vec<[u32; 3]>,
}

impl UvLayout {
    /// Checks that the layout fits `topo`: one corner triple per triangle, indices in range, finite values.
    pub fn check(&self, topo: &Topology, what: &str) -> Result<()> {
        if self.corners.len() != topo.n_triangles() {
            return Err(Error::mesh(format!(
                "{what}: UV layout has {} triangles, the mesh {}",
                self.corners.len(),
                topo.n_triangles()
            )));
        }
        for (t, c) in self.corners.iter().enumerate() {
            for &i in c {
                if i as usize >= self.uv.len() {
                    return Err(Error::mesh(format!(
                        "{what}: triangle {t} uses texture coordinate {} of {}",
                        i + 1,
                        self.uv.len()
                    )));
                }
            }
        }
        if let Some(i) = self
            .uv
            .iter()
            .position(|p| !p[0].is_finite() || !p[1].is_finite())
        {
            return Err(Error::mesh(format!(
                "{what}: texture coordinate {} is not finite",
                i + 1
            )));
        }
        Ok(())
    }

    /// The texture coordinate of every vertex, taken from its first corner; seam vertices have others too.
    pub fn vertex_uv(&self, topo: &Topology) -> Vec<[f64; 2]> {
        let mut out = vec![[f64::NAN; 2]; topo.n_vertices()];
        for (tri, c) in topo.triangles().iter().zip(&self.corners) {
            for k in 0..3 {
                let v = tri[k] as usize;
                if out[v][0].is_nan() {
                    out[v] = self.uv[c[k] as usize];
                }
            }
        }
        out
    }
}

/// Reads the `vt` lines and `f v/vt` corners of an OBJ. `Ok(None)` when the file has no texture coordinates.
/// Polygons are fan-triangulated like crease-core does, and the result must match `topo` triangle by triangle.
pub fn read_obj_uv(path: &Path, topo: &Topology) -> Result<Option<UvLayout>> {
    let (_, tris, layout) = parse_obj(path)?;
    let Some(layout) = layout else {
        return Ok(None);
    };
    if tris.as_slice() != topo.triangles() {
        return Err(Error::format(
            path,
            None,
            format!(
                "its faces ({} triangles) do not match the model's mesh ({} triangles)",
                tris.len(),
                topo.n_triangles()
            ),
        ));
    }
    layout.check(topo, &path.display().to_string())?;
    Ok(Some(layout))
}

/// Reads a single OBJ mesh (a template): topology, positions and its UV layout if it has one.
pub fn read_obj_mesh(path: &Path) -> Result<(std::sync::Arc<Topology>, Vec<V3>, Option<UvLayout>)> {
    let (positions, tris, layout) = parse_obj(path)?;
    let topo =
        Topology::new(positions.len(), tris).map_err(|e| e.at(Some(path.to_path_buf()), None))?;
    crease_core::mesh::geometry::validate_frame(&topo, &positions)
        .map_err(|e| e.at(Some(path.to_path_buf()), None))?;
    if let Some(l) = &layout {
        l.check(&topo, &path.display().to_string())?;
    }
    Ok((std::sync::Arc::new(topo), positions, layout))
}

type ParsedObj = (Vec<V3>, Vec<[u32; 3]>, Option<UvLayout>);

fn parse_obj(path: &Path) -> Result<ParsedObj> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut positions: Vec<V3> = Vec::new();
    let mut uv = Vec::new();
    let mut tris: Vec<[u32; 3]> = Vec::new();
    let mut corners: Vec<[u32; 3]> = Vec::new();
    let mut any_face_uv = false;
    let mut n_v = 0usize;
    for (lineno, line) in text.lines().enumerate() {
        let line_no = lineno + 1;
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Vec<f64> = it.take(3).filter_map(|t| t.parse().ok()).collect();
                if c.len() != 3 || c.iter().any(|x| !x.is_finite()) {
                    return Err(Error::format(
                        path,
                        Some(line_no),
                        "a `v` line needs 3 finite coordinates",
                    ));
                }
                positions.push([c[0], c[1], c[2]]);
                n_v += 1;
            }
            Some("vt") => {
                let u: Option<f64> = it.next().and_then(|s| s.parse().ok());
                let v: Option<f64> = it.next().and_then(|s| s.parse().ok());
                match (u, v) {
                    (Some(u), Some(v)) if u.is_finite() && v.is_finite() => uv.push([u, v]),
                    _ => return Err(Error::format(path, Some(line_no), "malformed `vt` line")),
                }
            }
            Some("f") => {
                let mut face: Vec<(u32, Option<u32>)> = Vec::new();
                for tok in it {
                    let mut parts = tok.split('/');
                    let vi = resolve(parts.next(), n_v, path, line_no, "vertex")?;
                    let ti = match parts.next() {
                        Some(s) if !s.is_empty() => {
                            Some(resolve(Some(s), uv.len(), path, line_no, "texture")?)
                        }
                        _ => None,
                    };
                    face.push((vi, ti));
                }
                if face.len() < 3 {
                    return Err(Error::format(
                        path,
                        Some(line_no),
                        "face with fewer than 3 corners",
                    ));
                }
                let has_uv = face.iter().all(|c| c.1.is_some());
                if has_uv {
                    any_face_uv = true;
                } else if face.iter().any(|c| c.1.is_some()) || any_face_uv {
                    return Err(Error::format(
                        path,
                        Some(line_no),
                        "some faces have texture coordinates and others not",
                    ));
                }
                for k in 1..face.len() - 1 {
                    tris.push([face[0].0, face[k].0, face[k + 1].0]);
                    if has_uv {
                        corners.push([
                            face[0].1.unwrap_or(0),
                            face[k].1.unwrap_or(0),
                            face[k + 1].1.unwrap_or(0),
                        ]);
                    }
                }
            }
            _ => {}
        }
    }
    let layout = any_face_uv.then_some(UvLayout { uv, corners });
    Ok((positions, tris, layout))
}

/// OBJ index (1-based, or negative = relative to the end) → 0-based.
fn resolve(tok: Option<&str>, count: usize, path: &Path, line: usize, what: &str) -> Result<u32> {
    let bad = || {
        Error::format(
            path,
            Some(line),
            format!("malformed or out-of-range {what} index"),
        )
    };
    let i: i64 = tok.and_then(|s| s.parse().ok()).ok_or_else(bad)?;
    let idx = if i > 0 {
        i - 1
    } else if i < 0 {
        count as i64 + i
    } else {
        return Err(bad());
    };
    if idx < 0 || idx as usize >= count {
        return Err(bad());
    }
    Ok(idx as u32)
}

/// Charts smaller than this many triangles are merged into a neighbour: slivers waste atlas space and give
/// LSCM too little to hold on to.
const MIN_CHART: usize = 24;

/// Computes a seamed UV atlas of the surface `positions`: charts by dominant normal axis (six directions),
/// each flattened by LSCM, packed on shelves into [0, 1]² with `gutter` (in UV units) around every chart.
pub fn auto_atlas(topo: &Topology, positions: &[V3], gutter: f64) -> Result<UvLayout> {
    let tris = topo.triangles();
    let nt = tris.len();
    if nt == 0 {
        return Err(Error::mesh(
            "cannot compute UVs of a mesh without triangles",
        ));
    }
    let normals = geometry::triangle_normals(topo, positions);
    let label: Vec<u8> = normals
        .iter()
        .map(|n| {
            let mut best = 0u8;
            let mut best_d = f64::NEG_INFINITY;
            for (axis, component) in n.iter().enumerate() {
                for (s, sign) in [1.0, -1.0].iter().enumerate() {
                    let d = component * sign;
                    if d > best_d {
                        best_d = d;
                        best = (2 * axis + s) as u8;
                    }
                }
            }
            best
        })
        .collect();
    // Connected components of equal label across shared edges.
    let adj = topo.tri_adj();
    let mut chart = vec![u32::MAX; nt];
    let mut n_charts = 0u32;
    for seed in 0..nt {
        if chart[seed] != u32::MAX {
            continue;
        }
        let mut stack = vec![seed];
        chart[seed] = n_charts;
        while let Some(t) = stack.pop() {
            for &o in &adj[t] {
                if o != NONE && chart[o as usize] == u32::MAX && label[o as usize] == label[t] {
                    chart[o as usize] = n_charts;
                    stack.push(o as usize);
                }
            }
        }
        n_charts += 1;
    }
    // Merge small charts into the neighbour they share most edges with, until none is left small (or isolated).
    loop {
        let mut size = vec![0usize; n_charts as usize];
        for &c in &chart {
            size[c as usize] += 1;
        }
        let mut changed = false;
        for t in 0..nt {
            let c = chart[t] as usize;
            if size[c] >= MIN_CHART {
                continue;
            }
            let best = adj[t]
                .iter()
                .filter(|&&o| o != NONE && chart[o as usize] as usize != c)
                .map(|&o| chart[o as usize])
                .max_by_key(|&o| size[o as usize]);
            if let Some(b) = best {
                if size[b as usize] >= size[c] {
                    let old = chart[t];
                    for x in chart.iter_mut() {
                        if *x == old {
                            *x = b;
                        }
                    }
                    changed = true;
                    break;
                }
            }
        }
        if !changed {
            break;
        }
    }
    // Renumber charts 0..m.
    let mut remap = std::collections::BTreeMap::new();
    for c in chart.iter_mut() {
        let next = remap.len() as u32;
        *c = *remap.entry(*c).or_insert(next);
    }
    let m = remap.len();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); m];
    for (t, &c) in chart.iter().enumerate() {
        members[c as usize].push(t);
    }
    // Flatten each chart.
    let mut uv: Vec<[f64; 2]> = Vec::new();
    let mut corners = vec![[0u32; 3]; nt];
    let mut boxes: Vec<(usize, usize, [f64; 2], [f64; 2])> = Vec::new(); // (uv start, uv end, min, size)
    for ts in members.iter() {
        let mut local = std::collections::HashMap::new();
        let mut local_pos: Vec<V3> = Vec::new();
        let mut local_tris: Vec<[u32; 3]> = Vec::with_capacity(ts.len());
        for &t in ts {
            let mut lt = [0u32; 3];
            for k in 0..3 {
                let v = tris[t][k];
                let id = *local.entry(v).or_insert_with(|| {
                    local_pos.push(positions[v as usize]);
                    (local_pos.len() - 1) as u32
                });
                lt[k] = id;
            }
            local_tris.push(lt);
        }
        let pins = far_pair(&local_pos);
        let flat = lscm(&local_pos, &local_tris, pins)
            .filter(|f| f.iter().all(|p| p[0].is_finite() && p[1].is_finite()))
            .unwrap_or_else(|| planar(&local_pos, members_axis(&label, ts)));
        let mut flat = orient_ccw(flat, &local_tris);
        align_principal(&mut flat);
        let start = uv.len();
        uv.extend_from_slice(&flat);
        for (&t, lt) in ts.iter().zip(&local_tris) {
            corners[t] = [
                lt[0] + start as u32,
                lt[1] + start as u32,
                lt[2] + start as u32,
            ];
        }
        let (lo, hi) = bbox2(&flat);
        boxes.push((start, uv.len(), lo, [hi[0] - lo[0], hi[1] - lo[1]]));
    }
    pack(&mut uv, &boxes, gutter);
    Ok(UvLayout { uv, corners })
}

fn members_axis(label: &[u8], ts: &[usize]) -> u8 {
    let mut count = [0usize; 6];
    for &t in ts {
        count[label[t] as usize] += 1;
    }
    (0..6).max_by_key(|&i| count[i]).unwrap_or(0) as u8
}

/// Projection onto the plane orthogonal to the chart's axis: the fallback when LSCM breaks down.
fn planar(p: &[V3], axis_label: u8) -> Vec<[f64; 2]> {
    let axis = (axis_label / 2) as usize;
    let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
    p.iter().map(|q| [q[a], q[b]]).collect()
}

/// Mirrors the chart if most of its triangles came out clockwise, so UV winding follows the surface's.
fn orient_ccw(mut flat: Vec<[f64; 2]>, tris: &[[u32; 3]]) -> Vec<[f64; 2]> {
    let mut signed = 0.0;
    for t in tris {
        let (a, b, c) = (
            flat[t[0] as usize],
            flat[t[1] as usize],
            flat[t[2] as usize],
        );
        signed += (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    }
    if signed < 0.0 {
        for p in flat.iter_mut() {
            p[0] = -p[0];
        }
    }
    flat
}

/// Two vertices far apart (a double sweep), the pins that fix LSCM's free similarity.
fn far_pair(p: &[V3]) -> (usize, usize) {
    let farthest = |from: usize| {
        (0..p.len())
            .max_by(|&i, &j| {
                let di = vec3::norm(vec3::sub(p[i], p[from]));
                let dj = vec3::norm(vec3::sub(p[j], p[from]));
                di.total_cmp(&dj)
            })
            .unwrap_or(0)
    };
    let a = farthest(0);
    let b = farthest(a);
    if a == b {
        (0, (a + 1).min(p.len().saturating_sub(1)))
    } else {
        (a, b)
    }
}

fn bbox2(p: &[[f64; 2]]) -> ([f64; 2], [f64; 2]) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for q in p {
        for k in 0..2 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    (lo, hi)
}

/// Turns a chart so its principal axis lies along u: long strips then pack without wasted corners.
fn align_principal(flat: &mut [[f64; 2]]) {
    let n = flat.len().max(1) as f64;
    let c = flat
        .iter()
        .fold([0.0, 0.0], |a, p| [a[0] + p[0] / n, a[1] + p[1] / n]);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in flat.iter() {
        let (x, y) = (p[0] - c[0], p[1] - c[1]);
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let (s, co) = angle.sin_cos();
    for p in flat.iter_mut() {
        let (x, y) = (p[0] - c[0], p[1] - c[1]);
        *p = [co * x + s * y, -s * x + co * y];
    }
}

/// Shelf packing of `boxes` (size only) into rows of width `row_w`: each box's offset and the total size.
fn shelves(sizes: &[[f64; 2]], order: &[usize], row_w: f64, pad: f64) -> (Vec<[f64; 2]>, [f64; 2]) {
    let mut offsets = vec![[0.0; 2]; sizes.len()];
    let (mut x, mut y, mut row_h, mut total_w) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for &i in order {
        let (w, h) = (sizes[i][0] + pad, sizes[i][1] + pad);
        if x > 0.0 && x + w > row_w {
            x = 0.0;
            y += row_h;
            row_h = 0.0;
        }
        offsets[i] = [x + pad / 2.0, y + pad / 2.0];
        x += w;
        total_w = total_w.max(x);
        row_h = row_h.max(h);
    }
    (offsets, [total_w, y + row_h])
}

/// Shelf packing: charts sorted by height, placed left to right in rows; the row width is chosen among a few
/// candidates to make the atlas as square as possible, then everything is scaled uniformly into
/// [gutter, 1 − gutter]² with `gutter` (UV units) around every chart.
fn pack(uv: &mut [[f64; 2]], boxes: &[(usize, usize, [f64; 2], [f64; 2])], gutter: f64) {
    let sizes: Vec<[f64; 2]> = boxes.iter().map(|b| b.3).collect();
    let area: f64 = sizes.iter().map(|s| s[0] * s[1]).sum();
    let widest = sizes.iter().map(|s| s[0]).fold(0.0, f64::max);
    let total: f64 = sizes.iter().map(|s| s[0]).sum();
    let mut order: Vec<usize> = (0..boxes.len()).collect();
    order.sort_by(|&a, &b| sizes[b][1].total_cmp(&sizes[a][1]));
    // Padding in chart units, from the expected scale (the atlas side is about √area).
    let pad = 2.0 * gutter * area.sqrt() * 1.2;
    let mut best: Option<(f64, Vec<[f64; 2]>)> = None;
    for i in 0..=24 {
        let row_w = widest
            + pad
            + (total - widest) * i as f64 / 24.0
            + pad * boxes.len() as f64 * i as f64 / 24.0;
        let (offsets, size) = shelves(&sizes, &order, row_w, pad);
        let side = size[0].max(size[1]);
        if best.as_ref().is_none_or(|b| side < b.0) {
            best = Some((side, offsets));
        }
    }
    let Some((side, offsets)) = best else {
        return;
    };
    let s = (1.0 - 2.0 * gutter) / side.max(1e-12);
    for (i, b) in boxes.iter().enumerate() {
        for p in &mut uv[b.0..b.1] {
            p[0] = gutter + (p[0] - b.2[0] + offsets[i][0]) * s;
            p[1] = gutter + (p[1] - b.2[1] + offsets[i][1]) * s;
        }
    }
}

/// Writes an OBJ with `vt` lines and `f v/vt` faces (1-based), the mesh half of the output contract.
pub fn write_obj_with_uv(
    path: &Path,
    topo: &Topology,
    positions: &[V3],
    layout: &UvLayout,
) -> Result<()> {
    let text = crate::contract::obj_text::ObjText::new(topo, &layout.uv, &layout.corners);
    crease_core::fsutil::write_atomic(
        path,
        &text.file(
            positions,
            "none (the mean shape of a model, with its UV layout)",
        ),
    )
}
