//! Template registration to scans (Lähner et al. §3.1): non-rigid ICP over an embedded deformation graph.
//!
//! Graph nodes are template vertices a few edges apart; each carries an affine map (A_j, t_j) and moves the
//! vertices near it: v' = Σ_j w_j(v) (A_j (v − g_j) + g_j + t_j) (Sumner et al. 2007, the "grid deformation"
//! the paper cites). Eq. 1 is minimised by Gauss–Newton:
//! * E_data: deformed vertices to their nearest scan points, along the scan's normal there (point to plane)
//!   plus a weak point-to-point part (pairs farther than a shrinking threshold are dropped, which is how holes
//!   stay holes instead of pulling the surface in);
//! * E_rigid: each A_j close to a rotation (orthonormal columns), weight ω_r = 500;
//! * E_smooth: neighbouring nodes agree on where they move each other, ω_s = 500;
//! * E_bound: template boundary vertices to scan boundary points chosen by the paper's Eq. 2 rule, ω_b = 10.
//!   Distances are measured in template mean edge lengths so the paper's weights keep their balance whatever
//!   the units. As in Li et al. 2009, ω_r and ω_s are halved whenever the energy falls by less than 5 %, down to a
//!   floor, so the fit starts stiff and ends detailed. The floor follows the scan's noise (`noise_floor` · σ²):
//!   a noisy scan keeps the graph stiff enough not to follow the noise, a clean one lets it relax to follow a
//!   large deformation. Data targets averaged over several scan points (`target_points`) and a pull toward
//!   the previous frame's transforms (`w_temporal`) are available, off by default (they measured worse).

pub mod kdtree;
pub mod point_normals;
mod system;

use crate::registration::kdtree::KdTree;
use crate::registration::point_normals::estimate_normals;
use crate::registration::system::{DataRows, Plan, RigidRows, Rows, SmoothRows, NV};
use crease_core::mesh::geometry::vertex_normals;
use crease_core::mesh::{Topology, NONE};
use crease_core::vec3::{self, V3};
use crease_core::{Error, Result};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RegisterParams {
    pub w_rigid: f64,
    pub w_smooth: f64,
    pub w_bound: f64,
    /// Node spacing in template edge lengths.
    pub node_spacing: f64,
    /// Nodes influencing each vertex.
    pub k_nodes: usize,
    /// ICP iterations (correspondence updates) per scan.
    pub iterations: usize,
    /// Gauss–Newton steps per correspondence update: the pairs are fixed, so a few steps converge the
    /// non-linear rigidity term before new pairs are searched.
    pub gn_steps: usize,
    /// Weight of the point-to-plane data term (distance along the scan normal).
    pub w_plane: f64,
    /// Weight of the point-to-point data term; small, it only keeps vertices from sliding freely.
    pub w_point: f64,
    /// Pairs whose template and scan normals differ by more than this (degrees, unoriented) are rejected.
    pub max_normal_angle: f64,
    /// Pairs farther than this (edge lengths) are ignored; it shrinks to a third over the iterations.
    pub max_pair_dist: f64,
    /// Lower bound of the relaxed ω_r and ω_s.
    pub min_weight: f64,
    /// Scan points averaged into each data target: a vertex is pulled to the centroid of its `target_points`
    /// nearest scan points (within the pair distance) instead of to the single nearest one. With 2 mm of noise
    /// per coordinate on a 5.5 mm mesh, the nearest point alone carries the full noise into the fit, which the
    /// relaxed regularisation then follows; the centroid of k points carries 1/√k of it. 1: the nearest point.
    #[serde(default = "default_target_points")]
    pub target_points: usize,
    /// Weight of a pull of every node's transform toward its value when the scan's registration began (the
    /// previous frame's result, in tracking): ω_t Σ_j ‖A_j − A_j⁰‖² s² + ‖t_j − t_j⁰‖², s the node spacing,
    /// so both parts are displacements in edge lengths. The data term does not see a vertex sliding along the
    /// surface; this term makes every move pay, so only moves the scan asks for are made. 0: off.
    #[serde(default)]
    pub w_temporal: f64,
    /// Floor of the relaxed ω_r, ω_s tied to the scan's noise: max(`min_weight`, `noise_floor` · σ²), σ² the
    /// scan's noise variance along its normal in squared edge lengths ([`crate::registration::point_normals::noise_variance`]).
    /// A MAP fit weighs the data term by 1/σ², so regularisation relative to it scales with σ²: a clean scan
    /// lets the graph relax to follow a large deformation, a noisy one keeps it stiff. 0: off.
    #[serde(default)]
    pub noise_floor: f64,
    /// Acceptance test: after the fit (tracked from the previous result), the previous result and the
    /// unregistered template are candidates too, and of them the state with the lowest Eq. 1 energy
    /// (truncated data term, ω_r = ω_s = the relaxed floor) is kept. Where the template is already close,
    /// the relaxed fit follows the scan's noise and slides along the surface, which the data term cannot
    /// see; keeping the template there costs one energy evaluation per candidate. false: the fit only.
    #[serde(default)]
    pub multi_start: bool,
    /// With `multi_start`, also fit the scan from the unregistered template and make that fit a candidate
    /// (twice the time per scan). On a rotationally symmetric surface it loses a twist the tracking followed
    /// (the bend test: 18.6 mm against 12.0), so it is off by default.
    #[serde(default)]
    pub restart_from_template: bool,
}

fn default_target_points() -> usize {
    RegisterParams::default().target_points
}

impl Default for RegisterParams {
    fn default() -> Self {
        RegisterParams {
            w_rigid: 500.0,
            w_smooth: 500.0,
            w_bound: 10.0,
            node_spacing: 2.5,
            k_nodes: 4,
            iterations: 40,
            gn_steps: 1,
            // Point-to-plane data term with a weak point-to-point one, and the floor of ω_r, ω_s tied to the
            // scan's noise (750 σ², σ² in squared edge lengths: ≈ 58 on the sleeve's scans, 2 mm noise on a
            // 5.5 mm mesh; ≈ 8 on the bend test's). The nearest point pulls a vertex along the surface
            // too, toward wherever a noisy point happens to be, and holds on to any slide the tracking made;
            // along the normal alone, the regularisation (which measures deformation from the template) puts
            // the vertices back where the template's own layout says. On sleeve-train seed_3 (gt frame 1
            // tracked through scans of frames 11, 41, 81, 111) this measured 12.87 / 3.12 / 3.47 / 21.00 mm
            // against the unregistered 26.30 / 4.05 / 3.12 / 41.41 and the previous defaults' 12.31 / 5.50 /
            // 5.52 / 22.07; the bend test 11.99 mm (12.94 before) (bench/results/2026-12-05-deep-registration.md).
            w_plane: 1.0,
            w_point: 0.01,
            max_normal_angle: 90.0,
            max_pair_dist: 6.0,
            min_weight: 1.0,
            target_points: 1,
            w_temporal: 0.0,
            noise_floor: 750.0,
            multi_start: false,
            restart_from_template: false,
        }
    }
}

impl RegisterParams {
    pub fn validate(&self) -> Result<()> {
        for (n, v) in [
            ("w-rigid", self.w_rigid),
            ("w-smooth", self.w_smooth),
            ("w-bound", self.w_bound),
            ("min-weight", self.min_weight),
            ("w-plane", self.w_plane),
            ("w-point", self.w_point),
            ("max-normal-angle", self.max_normal_angle),
            ("w-temporal", self.w_temporal),
            ("noise-floor", self.noise_floor),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::param(n, "must be a non-negative number"));
            }
        }
        if !(self.node_spacing.is_finite() && self.node_spacing > 0.0) {
            return Err(Error::param("node-spacing", "must be positive"));
        }
        if !(self.max_pair_dist.is_finite() && self.max_pair_dist > 0.0) {
            return Err(Error::param("max-pair-dist", "must be positive"));
        }
        if self.k_nodes < 1 || self.iterations < 1 || self.gn_steps < 1 || self.target_points < 1 {
            return Err(Error::param(
                "k-nodes/iterations/gn-steps",
                "must be at least 1",
            ));
        }
        Ok(())
    }
}

/// A scan: points, and which of them lie on the garment's boundary (the paper marks boundaries in colour).
#[derive(Debug, Clone, Default)]
pub struct Scan {
    pub points: Vec<V3>,
    pub boundary: Vec<bool>,
}

/// Reads a scan from an OBJ's `v x y z [r g b]` lines (faces ignored); red points (r > 0.5, g and b < 0.5)
/// are boundary points.
pub fn read_scan(path: &Path) -> Result<Scan> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut scan = Scan::default();
    for (i, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        if it.next() != Some("v") {
            continue;
        }
        let vals: Vec<f64> = it
            .map(|s| s.parse::<f64>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| Error::format(path, Some(i + 1), "malformed `v` line"))?;
        if vals.len() < 3 || vals.iter().any(|v| !v.is_finite()) {
            return Err(Error::format(
                path,
                Some(i + 1),
                "a `v` line needs 3 finite coordinates",
            ));
        }
        scan.points.push([vals[0], vals[1], vals[2]]);
        scan.boundary
            .push(vals.len() >= 6 && vals[3] > 0.5 && vals[4] < 0.5 && vals[5] < 0.5);
    }
    if scan.points.is_empty() {
        return Err(Error::format(path, None, "no points (`v` lines)"));
    }
    Ok(scan)
}

/// Writes a scan as OBJ points, boundary points red.
pub fn write_scan(path: &Path, scan: &Scan) -> Result<()> {
    use std::fmt::Write as _;
    let mut s = String::new();
    for (p, &b) in scan.points.iter().zip(&scan.boundary) {
        let c = if b { "1 0 0" } else { "0.7 0.7 0.7" };
        let _ = writeln!(s, "v {} {} {} {c}", p[0], p[1], p[2]);
    }
    crease_core::fsutil::write_atomic(path, s.as_bytes())
}

/// The deformation graph of a template, reused for every scan of a sequence.
pub struct Registration {
    params: RegisterParams,
    topo: std::sync::Arc<Topology>,
    rest: Vec<V3>,
    scale: f64,
    nodes: Vec<V3>,
    /// Per vertex: (node, weight) pairs.
    influence: Vec<Vec<(u32, f64)>>,
    /// Node graph edges (j, k), both directions.
    edges: Vec<(u32, u32)>,
    boundary_vertices: Vec<u32>,
    /// Current node transforms: A (row-major 9) then t (3), in scaled units.
    x: Vec<f64>,
    /// Per vertex: start of its entries in `coef` (the influence lists, flattened).
    infl_start: Vec<usize>,
    /// Per influence entry (vertex v, node j, weight w): (w·d₀, w·d₁, w·d₂, w), d = v − g_j: the Jacobian of
    /// each deformed coordinate w.r.t. node j's A row and t component, the same for every step.
    coef: Vec<[f64; 4]>,
    /// The normal equations' fixed sparsity (every Gauss–Newton step of every scan has the same blocks), who
    /// contributes to each block, the symbolic Cholesky factor and the numeric buffers, made once.
    plan: Plan,
    /// The last scan's noise variance along its normal (squared edge lengths), when it was estimated.
    last_noise: Option<f64>,
    /// The floor ω_r, ω_s relaxed to on the last scan.
    last_floor: f64,
}

impl Registration {
    /// Builds the graph on `template` (the template in its starting pose).
    pub fn new(
        topo: std::sync::Arc<Topology>,
        template: &[V3],
        params: RegisterParams,
    ) -> Result<Self> {
        params.validate()?;
        let edge = crate::normal_maps::bake::mean_edge_length(&topo, template);
        if !(edge.is_finite() && edge > 0.0) {
            return Err(Error::mesh("template has no edges of positive length"));
        }
        let scale = 1.0 / edge;
        let rest: Vec<V3> = template.iter().map(|p| vec3::scale(*p, scale)).collect();
        // Greedy Poisson-disk sampling of the vertices.
        let r2 = params.node_spacing * params.node_spacing;
        let mut nodes: Vec<V3> = Vec::new();
        for p in &rest {
            if nodes.iter().all(|g| dist2(*g, *p) >= r2) {
                nodes.push(*p);
            }
        }
        let k = params.k_nodes.min(nodes.len());
        let mut influence = Vec::with_capacity(rest.len());
        let mut pair_set = std::collections::BTreeSet::new();
        for p in &rest {
            let mut d: Vec<(f64, u32)> = nodes
                .iter()
                .enumerate()
                .map(|(j, g)| (dist2(*g, *p), j as u32))
                .collect();
            let take = (k + 1).min(d.len());
            d.select_nth_unstable_by(take - 1, |a, b| a.0.total_cmp(&b.0));
            d[..take].sort_by(|a, b| a.0.total_cmp(&b.0));
            let dmax = d[take - 1].0.sqrt().max(1e-9) * 1.0001;
            let mut w: Vec<(u32, f64)> = d[..k]
                .iter()
                .map(|&(d2, j)| (j, (1.0 - d2.sqrt() / dmax).powi(2)))
                .collect();
            let s: f64 = w.iter().map(|e| e.1).sum();
            for e in w.iter_mut() {
                e.1 = if s > 0.0 { e.1 / s } else { 1.0 / k as f64 };
            }
            for a in &w {
                for b in &w {
                    if a.0 != b.0 {
                        pair_set.insert((a.0, b.0));
                    }
                }
            }
            influence.push(w);
        }
        let boundary_vertices = boundary_vertices(&topo);
        let mut x = vec![0.0; nodes.len() * NV];
        for j in 0..nodes.len() {
            x[j * NV] = 1.0;
            x[j * NV + 4] = 1.0;
            x[j * NV + 8] = 1.0;
        }
        let edges: Vec<(u32, u32)> = pair_set.into_iter().collect();
        let plan = Plan::new(nodes.len(), &influence, &edges)?;
        let mut infl_start = Vec::with_capacity(rest.len() + 1);
        let mut coef = Vec::new();
        for (p, inf) in rest.iter().zip(&influence) {
            infl_start.push(coef.len());
            for &(j, w) in inf {
                let d = vec3::sub(*p, nodes[j as usize]);
                coef.push([w * d[0], w * d[1], w * d[2], w]);
            }
        }
        infl_start.push(coef.len());
        Ok(Registration {
            last_floor: params.min_weight,
            params,
            topo,
            rest,
            scale,
            nodes,
            influence,
            edges,
            boundary_vertices,
            x,
            infl_start,
            coef,
            plan,
            last_noise: None,
        })
    }

    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// The last scan's estimated noise variance along its normal (squared template edge lengths), when
    /// `noise_floor` asked for it, and the floor ω_r, ω_s were relaxed to.
    pub fn last_noise(&self) -> (Option<f64>, f64) {
        (self.last_noise, self.last_floor)
    }

    /// Deformed template (scaled units).
    fn deformed(&self) -> Vec<V3> {
        self.rest
            .iter()
            .zip(&self.influence)
            .map(|(v, inf)| {
                let mut out = [0.0; 3];
                for &(j, w) in inf {
                    out = vec3::add(out, vec3::scale(self.apply_node(j as usize, *v), w));
                }
                out
            })
            .collect()
    }

    fn apply_node(&self, j: usize, p: V3) -> V3 {
        let x = &self.x[j * NV..(j + 1) * NV];
        let g = self.nodes[j];
        let d = vec3::sub(p, g);
        [
            x[0] * d[0] + x[1] * d[1] + x[2] * d[2] + g[0] + x[9],
            x[3] * d[0] + x[4] * d[1] + x[5] * d[2] + g[1] + x[10],
            x[6] * d[0] + x[7] * d[1] + x[8] * d[2] + g[2] + x[11],
        ]
    }

    /// Registers the (current) template to `scan`, starting from the previous result; returns the deformed
    /// template in the input units.
    pub fn register(&mut self, scan: &Scan) -> Result<Vec<V3>> {
        if scan.points.len() != scan.boundary.len() || scan.points.is_empty() {
            return Err(Error::param(
                "scan",
                "empty scan or boundary flags of another length",
            ));
        }
        let pts: Vec<V3> = scan
            .points
            .iter()
            .map(|p| vec3::scale(*p, self.scale))
            .collect();
        let tree = KdTree::new(&pts);
        let use_normals = self.params.w_plane > 0.0 || self.params.max_normal_angle < 90.0;
        let normals = if use_normals {
            estimate_normals(&pts, &tree, 10)
        } else {
            vec![[0.0; 3]; pts.len()]
        };
        let bpts: Vec<V3> = pts
            .iter()
            .zip(&scan.boundary)
            .filter(|(_, &b)| b)
            .map(|(p, _)| *p)
            .collect();
        let mut floor = self.params.min_weight;
        self.last_noise = None;
        if self.params.noise_floor > 0.0 {
            let var = crate::registration::point_normals::noise_variance(&pts, &tree, 16, 7);
            floor = floor.max(self.params.noise_floor * var);
            self.last_noise = Some(var);
        }
        self.last_floor = floor;
        let scan = ScaledScan {
            pts: &pts,
            tree: &tree,
            normals: &normals,
            bpts: &bpts,
            use_normals,
        };
        let x_prev = self.x.clone();
        self.fit(&scan, floor)?;
        if self.params.multi_start {
            // The candidates' energies at the floor weights and the last pair distance, unpaired vertices
            // counted at that distance, so a state cannot win by losing pairs.
            let max_d = self.params.max_pair_dist / 3.0;
            let tracked = self.x.clone();
            let mut identity = vec![0.0; self.x.len()];
            for j in 0..self.nodes.len() {
                identity[j * NV] = 1.0;
                identity[j * NV + 4] = 1.0;
                identity[j * NV + 8] = 1.0;
            }
            let mut candidates = vec![tracked, x_prev.clone(), identity.clone()];
            if self.params.restart_from_template {
                self.x = identity;
                self.fit(&scan, floor)?;
                candidates.push(self.x.clone());
            }
            let mut best: Option<(f64, Vec<f64>)> = None;
            for (i, cand) in candidates.into_iter().enumerate() {
                self.x = cand;
                let e = self.energy(&scan, floor, max_d, &x_prev)?;
                let name = ["fit", "previous", "template", "fit from template"][i];
                tracing::debug!(candidate = name, energy = e, "registration acceptance test");
                if best.as_ref().is_none_or(|b| e < b.0) {
                    best = Some((e, std::mem::take(&mut self.x)));
                }
            }
            if let Some((_, x)) = best {
                self.x = x;
            }
        }
        Ok(self
            .deformed()
            .iter()
            .map(|p| vec3::scale(*p, 1.0 / self.scale))
            .collect())
    }

    /// Data pairs of the current deformed template with `scan` within `max_d`, and the boundary pairs.
    fn pairs(&self, scan: &ScaledScan<'_>, max_d: f64) -> (Vec<Option<Pair>>, Vec<(u32, V3)>) {
        let cos_max = self.params.max_normal_angle.to_radians().cos();
        let (pts, tree, normals, use_normals) =
            (scan.pts, scan.tree, scan.normals, scan.use_normals);
        let cur = self.deformed();
        let cur_n = vertex_normals(&self.topo, &cur);
        let pairs: Vec<Option<Pair>> = cur
            .par_iter()
            .zip(&cur_n)
            .map(|(p, n)| {
                let (i, d2) = tree.nearest(*p)?;
                let m = normals[i];
                let compatible = !use_normals || vec3::dot(vec3::normalize(*n), m).abs() >= cos_max;
                if !(d2 <= max_d * max_d && compatible) {
                    return None;
                }
                let target = if self.params.target_points > 1 {
                    let near = tree.k_nearest(*p, self.params.target_points);
                    let within: Vec<V3> = near
                        .iter()
                        .filter(|(_, d2)| *d2 <= max_d * max_d)
                        .map(|&(j, _)| pts[j])
                        .collect();
                    let sum = within.iter().fold([0.0; 3], |a, q| vec3::add(a, *q));
                    vec3::scale(sum, 1.0 / within.len() as f64)
                } else {
                    pts[i]
                };
                Some(Pair { target, normal: m })
            })
            .collect();
        let bound = boundary_pairs(&self.boundary_vertices, &cur, scan.bpts);
        (pairs, bound)
    }

    /// Eq. 1 at the current transforms with ω_r = ω_s = `floor`, pairs within `max_d`; every vertex without a
    /// pair adds (w_plane + w_point) · max_d², what a pair at that distance would at most cost.
    fn energy(
        &mut self,
        scan: &ScaledScan<'_>,
        floor: f64,
        max_d: f64,
        x_start: &[f64],
    ) -> Result<f64> {
        let (pairs, bound) = self.pairs(scan, max_d);
        let unpaired = pairs.iter().filter(|p| p.is_none()).count() as f64;
        let e = self.gauss_newton_step(&pairs, &bound, floor, floor, x_start, false)?;
        Ok(e + unpaired * (self.params.w_plane + self.params.w_point) * max_d * max_d)
    }

    /// The ICP loop of one scan from the current transforms: `iterations` correspondence updates, ω_r and
    /// ω_s halved down to `floor` whenever the energy stalls.
    fn fit(&mut self, scan: &ScaledScan<'_>, floor: f64) -> Result<()> {
        let x_start = self.x.clone();
        let (mut wr, mut ws) = (self.params.w_rigid, self.params.w_smooth);
        let mut prev_energy = f64::INFINITY;
        let iters = self.params.iterations;
        for it in 0..iters {
            let frac = it as f64 / (iters.max(2) - 1) as f64;
            let max_d = self.params.max_pair_dist * (1.0 - 2.0 / 3.0 * frac);
            let (pairs, bound) = self.pairs(scan, max_d);
            let mut energy = 0.0;
            for step in 0..self.params.gn_steps {
                let e = self.gauss_newton_step(&pairs, &bound, wr, ws, &x_start, true)?;
                if step == 0 {
                    energy = e;
                }
            }
            tracing::debug!(
                iteration = it,
                energy,
                w_rigid = wr,
                w_smooth = ws,
                paired = pairs.iter().filter(|p| p.is_some()).count(),
                boundary = bound.len(),
                "registration step"
            );
            if energy > prev_energy * (1.0 - 5e-2) {
                wr = (wr * 0.5).max(floor);
                ws = (ws * 0.5).max(floor);
            }
            prev_energy = energy;
        }
        Ok(())
    }

    /// One Gauss–Newton step of Eq. 1 at the current transforms (only its energy when `!step`); returns the
    /// energy before the step. The residuals and the energy are computed here, row by row in a fixed order
    /// (temporal, data, boundary, rigidity, smoothness); the normal equations are assembled from them in
    /// parallel in the same order and solved by [`Plan::solve`].
    fn gauss_newton_step(
        &mut self,
        pairs: &[Option<Pair>],
        bound: &[(u32, V3)],
        wr: f64,
        ws: f64,
        x_start: &[f64],
        step: bool,
    ) -> Result<f64> {
        let mut energy = 0.0;
        // Temporal pull toward the transforms this scan started from: one row (coefficient a) per unknown.
        let mut temporal = Vec::new();
        if self.params.w_temporal > 0.0 {
            let wt = self.params.w_temporal;
            let s = self.params.node_spacing;
            temporal.reserve(self.x.len());
            for (i, (x, x0)) in self.x.iter().zip(x_start).enumerate() {
                let a = if i % NV < 9 { s } else { 1.0 };
                let r = a * (x - x0);
                energy += wt * r * r;
                temporal.push((a, r));
            }
        }
        // Data and boundary: per vertex coordinate c, v'_c = Σ_j w (Σ_d A_j[c][d] (v − g_j)_d + g_j[c] +
        // t_j[c]); its Jacobian is `coef`, the current position is the deformed vertex.
        let cur = self.deformed();
        let n_vert = cur.len();
        let (w_point, w_plane, w_bound) = (
            self.params.w_point,
            self.params.w_plane,
            self.params.w_bound,
        );
        let mut data: Vec<Option<DataRows>> = vec![None; n_vert];
        for (v, pair) in pairs.iter().enumerate() {
            let Some(pair) = pair else { continue };
            let p = cur[v];
            let mut point_r = [0.0; 3];
            if w_point > 0.0 {
                for c in 0..3 {
                    let r = p[c] - pair.target[c];
                    energy += w_point * r * r;
                    point_r[c] = r;
                }
            }
            let mut plane_r = 0.0;
            if w_plane > 0.0 {
                // Point-to-plane: n · (v' − s), one row combining the coordinate rows.
                let r = vec3::dot(pair.normal, vec3::sub(p, pair.target));
                energy += w_plane * r * r;
                plane_r = r;
            }
            data[v] = Some(DataRows {
                point_r,
                normal: pair.normal,
                plane_r,
            });
        }
        // Boundary rows are assembled per vertex in vertex order: `boundary_pairs` lists them that way.
        debug_assert!(bound.windows(2).all(|w| w[0].0 < w[1].0));
        let mut bound_r: Vec<Option<[f64; 3]>> = vec![None; n_vert];
        for &(v, t) in bound {
            let p = cur[v as usize];
            let mut r = [0.0; 3];
            for c in 0..3 {
                r[c] = p[c] - t[c];
                energy += w_bound * r[c] * r[c];
            }
            bound_r[v as usize] = Some(r);
        }
        // Rigidity: columns of A orthonormal.
        let mut rigid = vec![RigidRows::default(); self.nodes.len()];
        for (j, rg) in rigid.iter_mut().enumerate() {
            let a = &self.x[j * NV..j * NV + 9];
            let col = |k: usize| [a[k], a[3 + k], a[6 + k]];
            let idx = |k: usize| [k, 3 + k, 6 + k];
            for (row, (p, q)) in [(0, 1), (0, 2), (1, 2)].into_iter().enumerate() {
                let (cp, cq) = (col(p), col(q));
                let r = vec3::dot(cp, cq);
                for i in 0..3 {
                    rg.entries[row][2 * i] = (idx(p)[i], cq[i]);
                    rg.entries[row][2 * i + 1] = (idx(q)[i], cp[i]);
                }
                rg.len[row] = 6;
                rg.r[row] = r;
                energy += wr * r * r;
            }
            for p in 0..3 {
                let cp = col(p);
                let r = vec3::dot(cp, cp) - 1.0;
                for (i, c) in cp.iter().enumerate() {
                    rg.entries[3 + p][i] = (idx(p)[i], 2.0 * c);
                }
                rg.len[3 + p] = 3;
                rg.r[3 + p] = r;
                energy += wr * r * r;
            }
        }
        // Smoothness: node j's map of node k's position agrees with node k's own move.
        let mut smooth = Vec::with_capacity(self.edges.len());
        for &(j, k) in &self.edges {
            let (j, k) = (j as usize, k as usize);
            let d = vec3::sub(self.nodes[k], self.nodes[j]);
            let pj = self.apply_node(j, self.nodes[k]);
            let pk = vec3::add(
                self.nodes[k],
                [self.x[k * NV + 9], self.x[k * NV + 10], self.x[k * NV + 11]],
            );
            let mut r = [0.0; 3];
            for c in 0..3 {
                r[c] = pj[c] - pk[c];
                energy += ws * r[c] * r[c];
            }
            smooth.push(SmoothRows { d, r });
        }
        if !step {
            return Ok(energy);
        }
        let rows = Rows {
            infl_start: &self.infl_start,
            coef: &self.coef,
            data: &data,
            bound: &bound_r,
            w_point,
            w_plane,
            w_bound,
            w_temporal: self.params.w_temporal,
            temporal: &temporal,
            w_rigid: wr,
            rigid: &rigid,
            w_smooth: ws,
            edges: &self.edges,
            smooth: &smooth,
        };
        let delta = self.plan.solve(&rows, 1e-6)?;
        for (x, d) in self.x.iter_mut().zip(&delta) {
            *x -= d;
        }
        Ok(energy)
    }
}

/// A scan in template edge lengths with its search tree, normals and boundary points.
struct ScaledScan<'a> {
    pts: &'a [V3],
    tree: &'a KdTree,
    normals: &'a [V3],
    bpts: &'a [V3],
    use_normals: bool,
}

/// A data pair: the scan point a vertex is pulled to and the scan's (unoriented) normal there.
#[derive(Debug, Clone, Copy)]
struct Pair {
    target: V3,
    normal: V3,
}

fn dist2(a: V3, b: V3) -> f64 {
    let d = vec3::sub(a, b);
    vec3::dot(d, d)
}

/// Vertices on open boundary edges (an edge with no triangle across).
pub fn boundary_vertices(topo: &Topology) -> Vec<u32> {
    let mut on = vec![false; topo.n_vertices()];
    for (t, adj) in topo.tri_adj().iter().enumerate() {
        for k in 0..3 {
            if adj[k] == NONE {
                let tri = topo.triangles()[t];
                on[tri[k] as usize] = true;
                on[tri[(k + 1) % 3] as usize] = true;
            }
        }
    }
    (0..topo.n_vertices() as u32)
        .filter(|&v| on[v as usize])
        .collect()
}

/// Eq. 2: each scan boundary point votes for its nearest template boundary vertex; each vertex is paired with
/// the farthest point among its voters (none if nobody voted), which spreads the pairs along the boundary and
/// reaches into folds instead of bunching at the closest points.
pub fn boundary_pairs(
    template_boundary: &[u32],
    current: &[V3],
    scan_boundary: &[V3],
) -> Vec<(u32, V3)> {
    if template_boundary.is_empty() || scan_boundary.is_empty() {
        return Vec::new();
    }
    let tpos: Vec<V3> = template_boundary
        .iter()
        .map(|&v| current[v as usize])
        .collect();
    let tree = KdTree::new(&tpos);
    let mut best: Vec<Option<(f64, V3)>> = vec![None; tpos.len()];
    for s in scan_boundary {
        if let Some((i, d2)) = tree.nearest(*s) {
            if best[i].is_none_or(|b| d2 > b.0) {
                best[i] = Some((d2, *s));
            }
        }
    }
    template_boundary
        .iter()
        .zip(best)
        .filter_map(|(&v, b)| b.map(|(_, s)| (v, s)))
        .collect()
}

/// Samples a scan from a mesh: `per_vertex` × vertex-count points, area-weighted on the triangles, with
/// spherical holes removing `hole_fraction` of them, Gaussian noise of `noise` (input units) and the points on
/// boundary edges marked. Deterministic for a seed: it is the test and benchmark input.
pub fn synth_scan(
    topo: &Topology,
    p: &[V3],
    per_vertex: f64,
    hole_fraction: f64,
    noise: f64,
    seed: u64,
) -> Scan {
    let mut rng = crate::nn::seed::Rng::new(seed);
    let tris = topo.triangles();
    let areas: Vec<f64> = tris
        .iter()
        .map(|t| {
            0.5 * vec3::norm(vec3::cross(
                vec3::sub(p[t[1] as usize], p[t[0] as usize]),
                vec3::sub(p[t[2] as usize], p[t[0] as usize]),
            ))
        })
        .collect();
    let total: f64 = areas.iter().sum();
    let mut cdf = Vec::with_capacity(areas.len());
    let mut acc = 0.0;
    for a in &areas {
        acc += a / total;
        cdf.push(acc);
    }
    let n = (per_vertex * p.len() as f64) as usize;
    let gauss = |rng: &mut crate::nn::seed::Rng| {
        let (u1, u2) = (rng.uniform().max(1e-12), rng.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    let mut pts = Vec::with_capacity(n);
    for _ in 0..n {
        let u = rng.uniform();
        let t = cdf.partition_point(|&c| c < u).min(tris.len() - 1);
        let (mut a, mut b) = (rng.uniform(), rng.uniform());
        if a + b > 1.0 {
            a = 1.0 - a;
            b = 1.0 - b;
        }
        let tri = tris[t];
        let q = vec3::add(
            p[tri[0] as usize],
            vec3::add(
                vec3::scale(vec3::sub(p[tri[1] as usize], p[tri[0] as usize]), a),
                vec3::scale(vec3::sub(p[tri[2] as usize], p[tri[0] as usize]), b),
            ),
        );
        pts.push(q);
    }
    // Holes: spheres around random points, until the fraction is gone.
    let edge = crate::normal_maps::bake::mean_edge_length(topo, p);
    let mut keep = vec![true; pts.len()];
    let target = (hole_fraction * pts.len() as f64) as usize;
    let mut removed = 0;
    while removed < target {
        let c = pts[(rng.next_u64() % pts.len() as u64) as usize];
        let r = edge * (3.0 + 5.0 * rng.uniform());
        for (i, q) in pts.iter().enumerate() {
            if keep[i] && dist2(*q, c) < r * r && removed < target {
                keep[i] = false;
                removed += 1;
            }
        }
    }
    let mut scan = Scan::default();
    for (q, k) in pts.iter().zip(&keep) {
        if *k {
            scan.points.push([
                q[0] + noise * gauss(&mut rng),
                q[1] + noise * gauss(&mut rng),
                q[2] + noise * gauss(&mut rng),
            ]);
            scan.boundary.push(false);
        }
    }
    // Boundary points: 4 per boundary edge (the coloured seam of the paper's capture), with noise too.
    for (t, adj) in topo.tri_adj().iter().enumerate() {
        for k in 0..3 {
            if adj[k] == NONE {
                let (a, b) = (p[tris[t][k] as usize], p[tris[t][(k + 1) % 3] as usize]);
                for s in 0..4 {
                    let q = vec3::add(a, vec3::scale(vec3::sub(b, a), (s as f64 + 0.5) / 4.0));
                    scan.points.push([
                        q[0] + noise * gauss(&mut rng),
                        q[1] + noise * gauss(&mut rng),
                        q[2] + noise * gauss(&mut rng),
                    ]);
                    scan.boundary.push(true);
                }
            }
        }
    }
    scan
}
