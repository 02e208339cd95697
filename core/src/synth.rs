//! Procedural garment-like sequences with known folds, for the demo, tests and benchmarks.
//!
//! The demo garment is an open tube (a sleeve) that sways and bends over time. Folds are specified in the
//! tube's (arc length around, height) parameter plane as short straight segments; each fold becomes two
//! parallel control lines a fold-width apart — the paired fold edges of Popa et al. 2009 §4 — and the triangles
//! the lines cross become anchors rotating about the line tangent in opposite senses, so that the surface
//! between them rises into a ridge. Each fold has a time envelope (appears, grows, holds, vanishes) and drifts
//! across the surface, which exercises the temporal side of the space-time solve.

use crate::error::Result;
use crate::folds::{Anchor, AnchorSet};
use crate::mesh::{Frame, Sequence, Topology};
use crate::vec3::{self, V3};
use std::f64::consts::{FRAC_PI_2, PI};
use std::sync::Arc;

/// A regular grid on a surface patch: `cols × rows` vertices, two triangles per cell.
#[derive(Debug, Clone)]
pub struct Grid {
    pub cols: usize,
    pub rows: usize,
    /// Whether the columns wrap around (a tube) or not (a sheet).
    pub periodic: bool,
}

impl Grid {
    pub fn n_vertices(&self) -> usize {
        self.cols * self.rows
    }
    pub fn vertex(&self, c: usize, r: usize) -> u32 {
        (r * self.cols + (c % self.cols)) as u32
    }
    /// Triangles with alternating diagonals (less directional bias than one diagonal everywhere).
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let cells_c = if self.periodic {
            self.cols
        } else {
            self.cols - 1
        };
        let mut tris = Vec::with_capacity(cells_c * (self.rows - 1) * 2);
        for r in 0..self.rows - 1 {
            for c in 0..cells_c {
                let a = self.vertex(c, r);
                let b = self.vertex(c + 1, r);
                let d = self.vertex(c, r + 1);
                let e = self.vertex(c + 1, r + 1);
                if (r + c) % 2 == 0 {
                    tris.push([a, b, e]);
                    tris.push([a, e, d]);
                } else {
                    tris.push([a, b, d]);
                    tris.push([b, e, d]);
                }
            }
        }
        tris
    }
    pub fn topology(&self) -> Result<Topology> {
        Topology::new(self.n_vertices(), self.triangles())
    }
}

/// Grid size giving roughly `triangles` triangles on a tube whose cells are about square.
pub fn tube_grid_for(triangles: usize, radius: f64, length: f64) -> Grid {
    // cols · (rows − 1) · 2 ≈ triangles with cols / (rows − 1) ≈ 2πr / length.
    let aspect = 2.0 * PI * radius / length;
    let cells = triangles as f64 / 2.0;
    let rows_m1 = (cells / aspect).sqrt().round().max(2.0);
    let cols = (cells / rows_m1).round().max(8.0);
    Grid {
        cols: cols as usize,
        rows: rows_m1 as usize + 1,
        periodic: true,
    }
}

/// The demo scene description.
#[derive(Debug, Clone)]
pub struct DemoSpec {
    pub triangles: usize,
    pub frames: usize,
    pub radius: f64,
    pub length: f64,
    /// Anchors per frame are roughly proportional to the number of folds and their length; this scales the
    /// number of folds for benchmarks that need a given anchor count.
    pub fold_scale: f64,
}

impl Default for DemoSpec {
    fn default() -> Self {
        DemoSpec {
            triangles: 40_000,
            frames: 36,
            radius: 0.12,
            length: 0.9,
            fold_scale: 1.0,
        }
    }
}

/// One fold: a segment in the (around, height) parameter plane (both in metres on the rest tube).
#[derive(Debug, Clone, Copy)]
pub struct FoldSpec {
    /// Centre at frame `t_begin` and its drift per frame.
    pub centre: [f64; 2],
    pub drift: [f64; 2],
    /// Direction angle in the parameter plane (0 = around the tube, π/2 = along it).
    pub direction: f64,
    pub half_length: f64,
    /// Distance between the paired control lines.
    pub width: f64,
    /// Peak rotation (radians); Popa uses 60° for the narrowest pairs down to 30° for the widest.
    pub angle: f64,
    /// Frames: appears at `t_begin`, full strength from `t_full`, fading from `t_fade`, gone at `t_end`.
    pub t_begin: f64,
    pub t_full: f64,
    pub t_fade: f64,
    pub t_end: f64,
}

impl FoldSpec {
    fn envelope(&self, t: f64) -> f64 {
        let smooth = |x: f64| {
            let x = x.clamp(0.0, 1.0);
            x * x * (3.0 - 2.0 * x)
        };
        if t <= self.t_begin || t >= self.t_end {
            0.0
        } else if t < self.t_full {
            smooth((t - self.t_begin) / (self.t_full - self.t_begin))
        } else if t > self.t_fade {
            smooth((self.t_end - t) / (self.t_end - self.t_fade))
        } else {
            1.0
        }
    }
}

/// Rotation angle for a fold pair of `width`, inversely proportional to width between 60° (narrow) and 30°.
pub fn angle_for_width(width: f64, narrow: f64, wide: f64) -> f64 {
    let f = ((width - narrow) / (wide - narrow)).clamp(0.0, 1.0);
    let inv = 1.0 / (1.0 + f); // 1 → 0.5
    (PI / 3.0) * inv
}

/// Folds of the demo: ring folds and diagonal folds that appear, grow, drift and vanish.
pub fn demo_folds(spec: &DemoSpec) -> Vec<FoldSpec> {
    let circ = 2.0 * PI * spec.radius;
    let len = spec.length;
    let n = spec.frames as f64;
    // Garment folds are quasi-developable: long folds run along the tube or diagonally (twist), and folds
    // around it are short arcs. A ridge running all the way around a closed tube would have to lengthen the
    // circumference by amplitude/radius, which no cloth does; real sleeves buckle into diamonds instead.
    #[rustfmt::skip]
    let base: [[f64; 11]; 5] = [
        // (centre around, centre height, drift around/frame, drift height/frame, direction, half length, width,
        //  begin, full, fade, end); positions as fractions of circumference/length, times of the sequence.
        [0.0,  0.30,  0.0,    0.004,  0.35,   0.2,  0.024, 0.02, 0.25, 0.65, 0.85],
        [0.25, 0.62,  0.002,  0.0,    0.6,    0.16, 0.02,  0.2,  0.4,  0.8,  0.98],
        [0.55, 0.62,  0.0,   -0.003,  FRAC_PI_2, 0.25, 0.03,  0.35, 0.6,  0.9,  1.2],
        [0.6,  0.45, -0.003,  0.0,   -1.1,    0.12, 0.018, -0.2, 0.0,  0.3,  0.5],
        [0.85, 0.18,  0.0,    0.0,    0.15,   0.1,  0.022, 0.45, 0.6,  0.75, 0.95],
    ];
    let mut folds = Vec::new();
    let copies = spec.fold_scale.max(0.0);
    let whole = copies.floor() as usize;
    let frac = copies - whole as f64;
    for copy in 0..=whole {
        for (k, b) in base.iter().enumerate() {
            if copy == whole && (k as f64) >= frac * base.len() as f64 {
                break;
            }
            // Copies are shifted around the tube and in height so they do not coincide.
            let shift_around = copy as f64 * 0.37;
            let shift_height = copy as f64 * 0.11;
            let width = b[6] * len / 0.9;
            folds.push(FoldSpec {
                centre: [
                    ((b[0] + shift_around) % 1.0) * circ,
                    ((b[1] + shift_height) % 0.8 + 0.1) * len,
                ],
                drift: [b[2] * circ * 36.0 / n, b[3] * len * 36.0 / n],
                direction: b[4],
                half_length: b[5] * len,
                width,
                angle: angle_for_width(width, 0.018 * len / 0.9, 0.03 * len / 0.9),
                t_begin: b[7] * n,
                t_full: b[8] * n,
                t_fade: b[9] * n,
                t_end: b[10] * n,
            });
        }
    }
    folds
}

/// The demo sequence: a swaying, bending tube with the folds of [`demo_folds`] as anchors.
pub fn demo(spec: &DemoSpec) -> Result<(Sequence, AnchorSet)> {
    let grid = tube_grid_for(spec.triangles, spec.radius, spec.length);
    let topo = Arc::new(grid.topology()?);
    let frames: Vec<Frame> = (0..spec.frames)
        .map(|t| tube_frame(&grid, spec, t as f64))
        .collect();
    let folds = demo_folds(spec);
    let lists = frames
        .iter()
        .enumerate()
        .map(|(t, f)| fold_anchors(&grid, &topo, spec, f, &folds, t as f64))
        .collect();
    let anchors = AnchorSet::from_frames(lists, topo.n_triangles(), None)?;
    let seq = Sequence::new(topo, frames)?;
    Ok((seq, anchors))
}

/// Position of parameter point (u around in metres, h height in metres) at frame `t`: the tube's axis bends in
/// a slowly swaying arc and the tube twists slightly, like a sleeve on a moving arm.
fn tube_point(spec: &DemoSpec, u: f64, h: f64, t: f64) -> V3 {
    let phase = 2.0 * PI * t / spec.frames.max(1) as f64;
    let curvature = 0.9 * phase.sin() / spec.length; // up to ~50° of bend over the length
    let sway = 0.3 * (0.5 * phase).sin();
    let twist = 0.25 * (h / spec.length) * phase.cos();
    let theta = u / spec.radius + twist;
    // Centreline: arc in the plane spanned by z (axis) and the sway direction.
    let k = curvature;
    let (cx, cz, tz, tx) = if k.abs() < 1e-9 {
        (0.0, h, 1.0, 0.0)
    } else {
        (
            (1.0 - (k * h).cos()) / k,
            (k * h).sin() / k,
            (k * h).cos(),
            (k * h).sin(),
        )
    };
    let (sd, cd) = sway.sin_cos();
    let dir = [cd, sd, 0.0]; // bending direction in the xy plane
    let side = [-sd, cd, 0.0];
    let centre = [dir[0] * cx, dir[1] * cx, cz];
    // Tangent T = tz·ẑ + tx·dir; normal N = −tx·ẑ + tz·dir; binormal = side.
    let nvec = [dir[0] * tz, dir[1] * tz, -tx];
    let (s, c) = theta.sin_cos();
    vec3::add(
        centre,
        vec3::add(
            vec3::scale(nvec, spec.radius * c),
            vec3::scale(side, spec.radius * s),
        ),
    )
}

fn grid_param(grid: &Grid, spec: &DemoSpec, c: f64, r: f64) -> (f64, f64) {
    let circ = 2.0 * PI * spec.radius;
    (
        c / grid.cols as f64 * circ,
        r / (grid.rows - 1) as f64 * spec.length,
    )
}

fn tube_frame(grid: &Grid, spec: &DemoSpec, t: f64) -> Frame {
    let mut out = Vec::with_capacity(grid.n_vertices());
    for r in 0..grid.rows {
        for c in 0..grid.cols {
            let (u, h) = grid_param(grid, spec, c as f64, r as f64);
            out.push(tube_point(spec, u, h, t));
        }
    }
    out
}

/// Anchors of all active folds at frame `t`: the triangles whose parameter-space centroid lies within half a
/// cell of a control line, rotating about the line's 3D tangent (opposite senses on the two lines).
fn fold_anchors(
    grid: &Grid,
    topo: &Topology,
    spec: &DemoSpec,
    frame: &[V3],
    folds: &[FoldSpec],
    t: f64,
) -> Vec<Anchor> {
    let circ = 2.0 * PI * spec.radius;
    let cell = (circ / grid.cols as f64).max(spec.length / (grid.rows - 1) as f64);
    let tris = topo.triangles();
    // Parameter coordinates of triangle centroids (unwrapped around the seam).
    let param = |v: u32| -> (f64, f64) {
        let (r, c) = (v as usize / grid.cols, v as usize % grid.cols);
        grid_param(grid, spec, c as f64, r as f64)
    };
    let mut chosen: std::collections::BTreeMap<u32, Anchor> = Default::default();
    for f in folds {
        let env = f.envelope(t);
        if env < 0.05 {
            continue;
        }
        let dt = t - f.t_begin;
        let centre = [f.centre[0] + f.drift[0] * dt, f.centre[1] + f.drift[1] * dt];
        let d = [f.direction.cos(), f.direction.sin()];
        let perp = [-d[1], d[0]];
        for (side, sign) in [(-0.5, 1.0), (0.5, -1.0)] {
            let o = [
                centre[0] + perp[0] * side * f.width,
                centre[1] + perp[1] * side * f.width,
            ];
            for (ti, tri) in tris.iter().enumerate() {
                let ps = tri.map(param);
                // Unwrap the around coordinate near the seam relative to the first corner.
                let mut us = ps.map(|p| p.0);
                for u in us.iter_mut().skip(1) {
                    if *u - ps[0].0 > circ / 2.0 {
                        *u -= circ;
                    } else if ps[0].0 - *u > circ / 2.0 {
                        *u += circ;
                    }
                }
                let cu = (us[0] + us[1] + us[2]) / 3.0;
                let ch = (ps[0].1 + ps[1].1 + ps[2].1) / 3.0;
                // Distance to the line segment, taking the periodic direction into account.
                let mut best = f64::INFINITY;
                let mut taper = 0.0;
                let envelope_len = f.half_length * (0.5 + 0.5 * env);
                for wrap in [-circ, 0.0, circ] {
                    let rel = [cu + wrap - o[0], ch - o[1]];
                    let along = rel[0] * d[0] + rel[1] * d[1];
                    let across = rel[0] * perp[0] + rel[1] * perp[1];
                    if along.abs() <= envelope_len && across.abs() < best {
                        best = across.abs();
                        // Real folds fade out at their ends rather than stopping abruptly.
                        taper = (0.5 * PI * along / envelope_len).cos().powf(2.0);
                    }
                }
                if h_outside(ch, spec.length, cell) || best > 0.5 * cell {
                    continue;
                }
                // 3D tangent of the line at this triangle, from the frame's own geometry.
                let tri_pts = tri.map(|v| frame[v as usize]);
                let tangent = line_tangent(tri_pts, [us[0], us[1], us[2]], ps.map(|p| p.1), d);
                let tangent = vec3::normalize(tangent);
                if vec3::norm(tangent) == 0.0 {
                    continue;
                }
                chosen.insert(
                    ti as u32,
                    Anchor {
                        triangle: ti as u32,
                        axis: vec3::scale(tangent, sign),
                        angle: env * taper * f.angle,
                    },
                );
            }
        }
    }
    chosen.into_values().collect()
}

fn h_outside(h: f64, length: f64, cell: f64) -> bool {
    h < 1.5 * cell || h > length - 1.5 * cell
}

/// Maps a parameter-plane direction to 3D through the triangle's affine parameterisation.
fn line_tangent(p: [V3; 3], u: [f64; 3], h: [f64; 3], d: [f64; 2]) -> V3 {
    // Solve for the 3D images of the parameter axes: P(u,h) = p0 + Xu·(u−u0) + Xh·(h−h0).
    let (du1, dh1) = (u[1] - u[0], h[1] - h[0]);
    let (du2, dh2) = (u[2] - u[0], h[2] - h[0]);
    let det = du1 * dh2 - du2 * dh1;
    if det.abs() < 1e-18 {
        return [0.0; 3];
    }
    let e1 = vec3::sub(p[1], p[0]);
    let e2 = vec3::sub(p[2], p[0]);
    let xu = vec3::scale(
        vec3::sub(vec3::scale(e1, dh2), vec3::scale(e2, dh1)),
        1.0 / det,
    );
    let xh = vec3::scale(
        vec3::sub(vec3::scale(e2, du1), vec3::scale(e1, du2)),
        1.0 / det,
    );
    vec3::add(vec3::scale(xu, d[0]), vec3::scale(xh, d[1]))
}

/// A flat rectangular sheet of `cols × rows` vertices with spacing `h`, in the xy plane.
pub fn sheet(cols: usize, rows: usize, h: f64) -> Result<(Arc<Topology>, Frame)> {
    let grid = Grid {
        cols,
        rows,
        periodic: false,
    };
    let topo = Arc::new(grid.topology()?);
    let mut p = Vec::with_capacity(grid.n_vertices());
    for r in 0..rows {
        for c in 0..cols {
            p.push([c as f64 * h, r as f64 * h, 0.0]);
        }
    }
    Ok((topo, p))
}

/// Random anchors for benchmarks: `per_frame` anchors per frame on distinct triangles, with random axes in each
/// triangle's plane and angles between 30° and 60°. Deterministic for a given seed.
pub fn random_anchors(
    topo: &Topology,
    frames: &[Frame],
    per_frame: usize,
    seed: u64,
) -> Result<AnchorSet> {
    let mut state = seed ^ 0x9E37_79B9_7F4A_7C15;
    let mut next = || {
        // xorshift64*
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        state.wrapping_mul(0x2545_F491_4F6C_DD1D)
    };
    let n_tri = topo.n_triangles();
    let per_frame = per_frame.min(n_tri);
    let mut lists = Vec::with_capacity(frames.len());
    for frame in frames {
        let mut picked = std::collections::BTreeMap::new();
        while picked.len() < per_frame {
            let t = (next() % n_tri as u64) as u32;
            let tri = topo.triangles()[t as usize].map(|v| frame[v as usize]);
            let n = vec3::normalize(vec3::cross(
                vec3::sub(tri[1], tri[0]),
                vec3::sub(tri[2], tri[0]),
            ));
            let e = vec3::normalize(vec3::sub(tri[1], tri[0]));
            let b = vec3::cross(n, e);
            let a = (next() % 10_000) as f64 / 10_000.0 * 2.0 * PI;
            let axis = vec3::add(vec3::scale(e, a.cos()), vec3::scale(b, a.sin()));
            let angle = (PI / 6.0) * (1.0 + (next() % 10_000) as f64 / 10_000.0);
            picked.insert(
                t,
                Anchor {
                    triangle: t,
                    axis,
                    angle,
                },
            );
        }
        lists.push(picked.into_values().collect());
    }
    AnchorSet::from_frames(lists, n_tri, None)
}

/// A flat `cols × rows` sheet (spacing `h`) whose band `band.0 ≤ s ≤ band.1` — `s` the coordinate along the
/// in-plane unit direction (cos φ, sin φ), as a fraction of the sheet's extent along it — is compressed along
/// that direction by the fraction `amount · envelope(t)`; material beyond the band moves with its ends. The
/// whole sheet also turns rigidly by `spin` radians per frame about the z axis. This is what a capture that
/// lost its folds looks like where cloth buckled: the material seems to shrink across the fold direction.
/// Known answers for fold detection: fold axes perpendicular to (cos φ, sin φ), seeds inside the band.
#[allow(clippy::too_many_arguments)]
pub fn compressed_sheet(
    cols: usize,
    rows: usize,
    h: f64,
    phi: f64,
    band: (f64, f64),
    amount: f64,
    spin: f64,
    envelope: &[f64],
) -> Result<Sequence> {
    let (topo, flat) = sheet(cols, rows, h)?;
    let c = [phi.cos(), phi.sin(), 0.0];
    let s_of = |p: V3| vec3::dot(p, c);
    let (lo, hi) = flat
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &p| {
            (a.min(s_of(p)), b.max(s_of(p)))
        });
    let (b0, b1) = (lo + band.0 * (hi - lo), lo + band.1 * (hi - lo));
    let frames = envelope
        .iter()
        .enumerate()
        .map(|(t, &e)| {
            let k = 1.0 - amount * e;
            let (sn, cs) = (spin * t as f64).sin_cos();
            flat.iter()
                .map(|&p| {
                    let s = s_of(p);
                    let g = if s < b0 {
                        s
                    } else if s <= b1 {
                        b0 + k * (s - b0)
                    } else {
                        b0 + k * (b1 - b0) + (s - b1)
                    };
                    let q = vec3::add(p, vec3::scale(c, g - s));
                    [cs * q[0] - sn * q[1], sn * q[0] + cs * q[1], q[2]]
                })
                .collect()
        })
        .collect();
    Sequence::new(topo, frames)
}

/// A sleeve-like tube of about `triangles` triangles that is compressed along its axis by up to `amount` and
/// twisted by up to `twist` radians (end to end) and released again over `frames` frames (a raised-cosine
/// cycle), with no folds in the geometry: what a capture of a compressed sleeve looks like once its folds are
/// smoothed away. Benchmarks and tests of the geometric fold estimation use it.
pub fn compressed_tube(
    triangles: usize,
    frames: usize,
    amount: f64,
    twist: f64,
) -> Result<Sequence> {
    let (radius, length) = (0.07, 0.5);
    let grid = tube_grid_for(triangles, radius, length);
    let topo = Arc::new(grid.topology()?);
    let frames = (0..frames)
        .map(|t| {
            let e = 0.5 * (1.0 - (2.0 * PI * t as f64 / frames.max(2) as f64).cos());
            let mut p = Vec::with_capacity(grid.n_vertices());
            for r in 0..grid.rows {
                for c in 0..grid.cols {
                    let h = r as f64 / (grid.rows - 1) as f64;
                    // Stronger compression in the middle of the sleeve than at its pinned ends.
                    let s = h - amount * e * (h - (2.0 * PI * h).sin() / (2.0 * PI));
                    let th = 2.0 * PI * c as f64 / grid.cols as f64 + twist * e * h;
                    p.push([radius * th.cos(), radius * th.sin(), s * length]);
                }
            }
            p
        })
        .collect();
    Sequence::new(topo, frames)
}

/// Writes `seq` as numbered OBJ frames `frame_0001.obj`, … (frame numbers from 1, zero-padded to at least four
/// digits) into `dir`: the layout every demo, test fixture and benchmark input uses.
pub fn write_frames(dir: &std::path::Path, seq: &Sequence) -> Result<Vec<std::path::PathBuf>> {
    let width = seq.frames.len().to_string().len().max(4);
    crate::mesh::io::write_obj_sequence(
        dir,
        &seq.topology,
        seq.frames
            .iter()
            .enumerate()
            .map(|(t, f)| (format!("frame_{:0width$}.obj", t + 1), f.as_slice())),
    )
}

/// Writes a demo (or any generated) sequence and its anchors as `crease run` reads them: `root/input/`
/// (see [`write_frames`]) and `root/anchors.json`. Returns (input directory, anchors file).
pub fn write_demo(
    root: &std::path::Path,
    seq: &Sequence,
    anchors: &AnchorSet,
) -> Result<(std::path::PathBuf, std::path::PathBuf)> {
    let input = root.join("input");
    write_frames(&input, seq)?;
    let anchors_path = root.join("anchors.json");
    anchors.write(&anchors_path)?;
    Ok((input, anchors_path))
}

/// A small tube with texture coordinates and a seam, moving over `n_frames` frames: `cols` vertices around,
/// `rows` along its axis, u = column / cols and v = row / (rows − 1). The columns wrap, so the vertices of
/// column 0 are on the UV seam with two coordinates each (u = 0 and u = 1), which is what the UV paths of the
/// readers, subdivision and exporters must keep exact. The fixture of the UV tests.
pub fn uv_tube(cols: usize, rows: usize, n_frames: usize) -> Result<Sequence> {
    if cols < 3 || rows < 2 {
        return Err(crate::Error::param(
            "uv_tube",
            format!("needs at least 3 columns and 2 rows, got {cols} × {rows}"),
        ));
    }
    let grid = Grid {
        cols,
        rows,
        periodic: true,
    };
    let tris = grid.triangles();
    let uv_index = |c: usize, r: usize| (r * (cols + 1) + c) as u32;
    let mut uv = Vec::with_capacity((cols + 1) * rows);
    for r in 0..rows {
        for c in 0..=cols {
            uv.push([c as f32 / cols as f32, r as f32 / (rows - 1).max(1) as f32]);
        }
    }
    let corners = tris
        .iter()
        .map(|t| {
            let col = |v: u32| v as usize % cols;
            // The wrapping cell joins column cols − 1 to column 0: there, column 0 is u = 1.
            let wraps = t.iter().any(|&v| col(v) == cols - 1) && t.iter().any(|&v| col(v) == 0);
            t.map(|v| {
                let c = col(v);
                let c = if wraps && c == 0 { cols } else { c };
                uv_index(c, v as usize / cols)
            })
        })
        .collect();
    let topo = grid
        .topology()?
        .with_uvs(Some(crate::mesh::UvSet::new(uv, corners)?))?;
    let frames = (0..n_frames)
        .map(|t| {
            let phase = 0.6 * t as f64;
            (0..rows)
                .flat_map(|r| {
                    (0..cols).map(move |c| {
                        let a = 2.0 * PI * c as f64 / cols as f64;
                        let z = r as f64 * 0.05;
                        let radius = 0.1 + 0.01 * (phase + 3.0 * a + 20.0 * z).sin();
                        [radius * a.cos(), radius * a.sin(), z]
                    })
                })
                .collect()
        })
        .collect();
    Sequence::new(Arc::new(topo), frames)
}
