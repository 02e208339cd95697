//! Flattening a fold seed's patch by unfolding it: the patch parameterisation of tracing, without a sparse
//! solve per seed. Tracing falls back to LSCM ([`super::lscm`]) for a patch whose unfolded layout folds
//! triangles over (`trace.rs`, `unfolds_without_overlap`).
//!
//! Vertices are laid out from the seed outwards, in order of their 3D distance from the seed triangle's
//! centroid. A vertex can be placed once some patch triangle holds it and two vertices already laid out; each
//! such triangle puts it where the triangle's own 3D shape and size put it beside that edge. The vertex goes to
//! the mean of what all those triangles say rather than where the first one puts it: a single chain of triangles carries its shear outwards and bends the plane
//! under a fold axis, while the mean over every upwind triangle spreads it (a discrete upwind exponential map).
//!
//! On a developable patch every triangle agrees and the layout is exact; there is no solve, so a patch costs a
//! few hundred small placements instead of a factorisation. Nothing depends on the triangles' corner order
//! beyond the side a vertex goes to, and that flips with it: seed edge, triangle edges and sums are taken in
//! vertex and triangle index order, so the mesh with every triangle flipped gives the mirrored layout
//! (v ↦ −v) bit for bit, and the fold found in it is the same.

use crate::mesh::{Topology, NONE};
use crate::vec3::{self, V3};
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// A patch of the traced mesh in its local numbering: `tri_local[t]` is `NONE` for triangles outside it and
/// `vert_local[v]` the local index of every vertex of its triangles (`verts[k]` the global one).
pub struct PatchRef<'a> {
    pub topo: &'a Topology,
    /// Number of patch triangles (`tri_local` numbers them `0..n_tris`).
    pub n_tris: usize,
    pub p: &'a [V3],
    pub tri_local: &'a [u32],
    pub vert_local: &'a [u32],
    pub verts: &'a [u32],
}

/// Scratch reused from patch to patch (one per tracing thread), so that unfolding allocates only its output.
#[derive(Default)]
pub struct Unfolder {
    /// Vertices that can be placed, nearest to the seed first: (squared distance bits, global vertex).
    front: BinaryHeap<Reverse<(u64, u32)>>,
    /// Per local vertex: 0 untouched, 1 in the front, 2 placed.
    state: Vec<u8>,
    /// Per local triangle: how many of its corners are placed. A triangle can place its third corner exactly
    /// when this is 2, which one counter tells instead of looking up its three corners' states each time a
    /// neighbouring vertex is placed or placeable (that bookkeeping was half of unfolding's own time).
    placed: Vec<u8>,
}

const QUEUED: u8 = 1;
const PLACED: u8 = 2;

/// Where triangle `tri` (global corners, winding order) puts its corner `r` beside its other two corners, which
/// are laid out in `uv`: the triangle's 3D shape scaled to the laid-out edge, on the side that keeps the
/// triangle's winding counter-clockwise. `None` for a degenerate edge.
fn place_beside(
    p: &[V3],
    uv_of: impl Fn(u32) -> [f64; 2],
    tri: [u32; 3],
    r: u32,
) -> Option<[f64; 2]> {
    let k = tri.iter().position(|&v| v == r)?;
    let (i, j) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
    // r lies left of i → j when the winding is counter-clockwise; the edge is taken from its lower index.
    let (a, b, side) = if i < j { (i, j, 1.0) } else { (j, i, -1.0) };
    let d = vec3::sub(p[b as usize], p[a as usize]);
    let w = vec3::sub(p[r as usize], p[a as usize]);
    let l2 = vec3::dot(d, d);
    if !(l2 > 0.0 && l2.is_finite()) {
        return None;
    }
    let along = vec3::dot(w, d) / l2;
    let across = side * vec3::norm(vec3::cross(d, w)) / l2;
    let (pa, pb) = (uv_of(a), uv_of(b));
    // The laid-out edge's direction at the edge's 3D length: the triangle keeps its 3D size. (Scaled to the
    // laid-out edge instead, a similarity, errors in scale compound from ring to ring on a curved patch.)
    let e = [pb[0] - pa[0], pb[1] - pa[1]];
    let k = l2.sqrt() / (e[0] * e[0] + e[1] * e[1]).sqrt();
    let e = [e[0] * k, e[1] * k];
    let q = [
        pa[0] + along * e[0] - across * e[1],
        pa[1] + along * e[1] + across * e[0],
    ];
    (q[0].is_finite() && q[1].is_finite()).then_some(q)
}

impl Unfolder {
    /// Lays out the patch around seed triangle `seed` (local coordinates indexed like `patch.verts`). `None`
    /// when the seed triangle is degenerate.
    pub fn unfold(&mut self, patch: &PatchRef, seed: usize) -> Option<Vec<[f64; 2]>> {
        let PatchRef {
            topo,
            n_tris,
            p,
            tri_local,
            vert_local,
            verts,
        } = *patch;
        let n = verts.len();
        let mut uv = vec![[0.0f64; 2]; n];
        self.state.clear();
        self.state.resize(n, 0);
        self.placed.clear();
        self.placed.resize(n_tris, 0);
        self.front.clear();
        let local = |v: u32| vert_local[v as usize] as usize;
        // The seed triangle: its lowest vertex at the origin, the next lowest on the +u axis.
        let tri = topo.triangles()[seed];
        let mut sorted = tri;
        sorted.sort_unstable();
        let [a, b, c] = sorted;
        let ab = vec3::norm(vec3::sub(p[b as usize], p[a as usize]));
        if !(ab > 0.0 && ab.is_finite()) {
            return None;
        }
        uv[local(a)] = [0.0, 0.0];
        uv[local(b)] = [ab, 0.0];
        self.state[local(a)] = PLACED;
        self.state[local(b)] = PLACED;
        uv[local(c)] = place_beside(p, |v| uv[local(v)], tri, c)?;
        if uv[local(c)][1] == 0.0 {
            return None;
        }
        self.state[local(c)] = PLACED;
        let c0 = vec3::scale(
            vec3::add(vec3::add(p[a as usize], p[b as usize]), p[c as usize]),
            1.0 / 3.0,
        );
        let key = |v: u32| {
            let d = vec3::sub(p[v as usize], c0);
            vec3::dot(d, d).to_bits()
        };
        // All three are placed before any is counted, so the seed triangle itself queues nothing.
        for v in sorted {
            self.count_placed(topo, tri_local, &local, v, &key);
        }
        while let Some(Reverse((_, r))) = self.front.pop() {
            let lr = local(r);
            if self.state[lr] == PLACED {
                continue;
            }
            // The mean over every patch triangle that can place r now (its other two corners placed), in
            // triangle order.
            let (mut sum, mut count) = ([0.0f64; 2], 0usize);
            let mut fallback = None;
            for &t in topo.vertex_triangles(r as usize) {
                let lt = tri_local[t as usize];
                if lt == NONE || self.placed[lt as usize] != 2 {
                    continue;
                }
                let tri = topo.triangles()[t as usize];
                match place_beside(p, |v| uv[local(v)], tri, r) {
                    Some(q) => {
                        sum = [sum[0] + q[0], sum[1] + q[1]];
                        count += 1;
                    }
                    None => {
                        // A degenerate triangle: the midpoint of its laid-out edge, if nothing better.
                        let k = tri.iter().position(|&v| v == r).unwrap_or(0);
                        let (i, j) = (uv[local(tri[(k + 1) % 3])], uv[local(tri[(k + 2) % 3])]);
                        fallback.get_or_insert([0.5 * (i[0] + j[0]), 0.5 * (i[1] + j[1])]);
                    }
                }
            }
            uv[lr] = if count > 0 {
                let k = count as f64;
                [sum[0] / k, sum[1] / k]
            } else {
                fallback?
            };
            self.state[lr] = PLACED;
            self.count_placed(topo, tri_local, &local, r, &key);
        }
        // Every patch vertex is reached: the patch is edge-connected from the seed.
        self.state.iter().all(|&s| s == PLACED).then_some(uv)
    }

    /// Counts the just placed vertex `v` in each patch triangle around it, and puts into the front the last
    /// open corner of every triangle that now has two corners placed (unless it is queued already): exactly
    /// the vertices that become placeable by `v`.
    fn count_placed(
        &mut self,
        topo: &Topology,
        tri_local: &[u32],
        local: &impl Fn(u32) -> usize,
        v: u32,
        key: &impl Fn(u32) -> u64,
    ) {
        for &t in topo.vertex_triangles(v as usize) {
            let lt = tri_local[t as usize];
            if lt == NONE {
                continue;
            }
            let placed = &mut self.placed[lt as usize];
            *placed += 1;
            if *placed != 2 {
                continue;
            }
            let tri = topo.triangles()[t as usize];
            if let Some(&r) = tri.iter().find(|&&w| self.state[local(w)] != PLACED) {
                if self.state[local(r)] == 0 {
                    self.state[local(r)] = QUEUED;
                    self.front.push(Reverse((key(r), r)));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    /// The whole mesh as one patch around `seed`, unfolded.
    fn unfold_all(topo: &Topology, p: &[V3], seed: usize) -> Option<Vec<[f64; 2]>> {
        let tri_local: Vec<u32> = (0..topo.n_triangles() as u32).collect();
        let verts: Vec<u32> = (0..topo.n_vertices() as u32).collect();
        Unfolder::default().unfold(
            &PatchRef {
                topo,
                n_tris: topo.n_triangles(),
                p,
                tri_local: &tri_local,
                vert_local: &verts,
                verts: &verts,
            },
            seed,
        )
    }

    fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
    }

    fn signed_area(uv: &[[f64; 2]], t: [u32; 3]) -> f64 {
        let (a, b, c) = (uv[t[0] as usize], uv[t[1] as usize], uv[t[2] as usize]);
        0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]))
    }

    /// A sheet rolled onto a cylinder is developable (each grid quad stays a flat rectangle): unfolding lays
    /// every edge out at its 3D length, keeps every triangle counter-clockwise, and recovers the distances of
    /// the rolled-out polyhedral sheet.
    #[test]
    fn developable_patch_is_laid_out_exactly() {
        let (topo, flat) = crate::synth::sheet(11, 9, 0.1).unwrap();
        let rolled: Vec<V3> = flat
            .iter()
            .map(|p| {
                let th = p[0] / 0.5;
                [0.5 * th.sin(), p[1], 0.5 * (1.0 - th.cos())]
            })
            .collect();
        let seed = topo.n_triangles() / 2 + 3;
        let uv = unfold_all(&topo, &rolled, seed).unwrap();
        for t in topo.triangles() {
            assert!(signed_area(&uv, *t) > 0.0, "{t:?} folded over");
            for k in 0..3 {
                let (i, j) = (t[k] as usize, t[(k + 1) % 3] as usize);
                let d3 = vec3::norm(vec3::sub(rolled[i], rolled[j]));
                assert!(
                    (dist(uv[i], uv[j]) - d3).abs() < 1e-12,
                    "edge {i}-{j}: {} vs {d3}",
                    dist(uv[i], uv[j])
                );
            }
        }
        // Far apart points: distances of the rolled-out sheet (the chord grid), not the 3D chords.
        let chord = 2.0 * 0.5 * (0.1f64 / 0.5 / 2.0).sin();
        let (i, j) = (0usize, 10usize);
        assert!((dist(uv[i], uv[j]) - 10.0 * chord).abs() < 1e-12);
    }

    /// Flipping every triangle mirrors the layout bit for bit.
    #[test]
    fn flipped_winding_mirrors_the_layout_bit_for_bit() {
        let seq = crate::synth::compressed_tube(2500, 3, 0.3, 0.5).unwrap();
        let topo = &seq.topology;
        let flipped = Topology::new(
            topo.n_vertices(),
            topo.triangles()
                .iter()
                .map(|t| [t[0], t[2], t[1]])
                .collect(),
        )
        .map(Arc::new)
        .unwrap();
        let p = &seq.frames[2];
        for seed in [0, 777, 1500] {
            let a = unfold_all(topo, p, seed).unwrap();
            let b = unfold_all(&flipped, p, seed).unwrap();
            for (x, y) in a.iter().zip(&b) {
                // Float equality is bit equality here, but for the sign of the seed edge's zeros.
                assert!(x[0] == y[0] && x[1] == -y[1], "{x:?} vs {y:?}");
            }
            assert!(a.iter().any(|q| q[1] != 0.0));
        }
    }

    /// On a doubly curved cap (not developable) every triangle still keeps its orientation and its edges stay
    /// close to their 3D lengths (the gap that curvature opens is spread over the upwind triangles), closer
    /// than when each vertex is placed by one triangle only.
    #[test]
    fn curved_patch_stays_close_to_isometric() {
        let (topo, flat) = crate::synth::sheet(17, 17, 0.1).unwrap();
        // A spherical cap of radius 6 over the 1.6 × 1.6 sheet (about 11° from its centre to a corner).
        let c = [0.8, 0.8];
        let cap: Vec<V3> = flat
            .iter()
            .map(|p| {
                let (x, y) = (p[0] - c[0], p[1] - c[1]);
                [p[0], p[1], (36.0 - x * x - y * y).sqrt() - 6.0]
            })
            .collect();
        let seed = topo.n_triangles() / 2;
        let uv = unfold_all(&topo, &cap, seed).unwrap();
        let mut worst = 0.0f64;
        for t in topo.triangles() {
            assert!(signed_area(&uv, *t) > 0.0, "{t:?} folded over");
            for k in 0..3 {
                let (i, j) = (t[k] as usize, t[(k + 1) % 3] as usize);
                let d3 = vec3::norm(vec3::sub(cap[i], cap[j]));
                worst = worst.max((dist(uv[i], uv[j]) / d3 - 1.0).abs());
            }
        }
        // One triangle per vertex (plain unfolding) gives 0.049 here; the mean 0.035.
        assert!(worst < 0.045, "edge length distortion {worst}");
        assert!(worst > 0.0, "a curved patch cannot be exact");
    }

    /// Unfolding as first written, deciding placeability from the corners' states every time (what the
    /// placed-corner counters replace): [`Unfolder::unfold`] must give its layouts bit for bit.
    fn unfold_by_states(patch: &PatchRef, seed: usize) -> Option<Vec<[f64; 2]>> {
        let PatchRef {
            topo,
            p,
            tri_local,
            vert_local,
            verts,
            ..
        } = *patch;
        let local = |v: u32| vert_local[v as usize] as usize;
        let mut uv = vec![[0.0f64; 2]; verts.len()];
        let mut state = vec![0u8; verts.len()];
        let mut front = BinaryHeap::new();
        let tri = topo.triangles()[seed];
        let mut sorted = tri;
        sorted.sort_unstable();
        let [a, b, c] = sorted;
        let ab = vec3::norm(vec3::sub(p[b as usize], p[a as usize]));
        if !(ab > 0.0 && ab.is_finite()) {
            return None;
        }
        uv[local(b)] = [ab, 0.0];
        state[local(a)] = PLACED;
        state[local(b)] = PLACED;
        uv[local(c)] = place_beside(p, |v| uv[local(v)], tri, c)?;
        if uv[local(c)][1] == 0.0 {
            return None;
        }
        state[local(c)] = PLACED;
        let c0 = vec3::scale(
            vec3::add(vec3::add(p[a as usize], p[b as usize]), p[c as usize]),
            1.0 / 3.0,
        );
        let key = |v: u32| {
            let d = vec3::sub(p[v as usize], c0);
            vec3::dot(d, d).to_bits()
        };
        let enqueue = |state: &mut Vec<u8>, front: &mut BinaryHeap<_>, v: u32| {
            for &t in topo.vertex_triangles(v as usize) {
                if tri_local[t as usize] == NONE {
                    continue;
                }
                let tri = topo.triangles()[t as usize];
                let mut open = tri.iter().filter(|&&w| state[local(w)] != PLACED);
                if let (Some(&r), None) = (open.next(), open.next()) {
                    if state[local(r)] == 0 {
                        state[local(r)] = QUEUED;
                        front.push(Reverse((key(r), r)));
                    }
                }
            }
        };
        for v in sorted {
            enqueue(&mut state, &mut front, v);
        }
        while let Some(Reverse((_, r))) = front.pop() {
            let lr = local(r);
            let (mut sum, mut count) = ([0.0f64; 2], 0usize);
            let mut fallback = None;
            for &t in topo.vertex_triangles(r as usize) {
                if tri_local[t as usize] == NONE {
                    continue;
                }
                let tri = topo.triangles()[t as usize];
                if tri.iter().any(|&v| v != r && state[local(v)] != PLACED) {
                    continue;
                }
                match place_beside(p, |v| uv[local(v)], tri, r) {
                    Some(q) => {
                        sum = [sum[0] + q[0], sum[1] + q[1]];
                        count += 1;
                    }
                    None => {
                        let k = tri.iter().position(|&v| v == r).unwrap_or(0);
                        let (i, j) = (uv[local(tri[(k + 1) % 3])], uv[local(tri[(k + 2) % 3])]);
                        fallback.get_or_insert([0.5 * (i[0] + j[0]), 0.5 * (i[1] + j[1])]);
                    }
                }
            }
            uv[lr] = if count > 0 {
                [sum[0] / count as f64, sum[1] / count as f64]
            } else {
                fallback?
            };
            state[lr] = PLACED;
            enqueue(&mut state, &mut front, r);
        }
        state.iter().all(|&s| s == PLACED).then_some(uv)
    }

    /// Patches of a compressed tube (disc-shaped, as tracing cuts them, so their rims have triangles with one
    /// corner outside) and the whole mesh: the counted unfolding gives the state-checking one's layout, bit for
    /// bit, with one scratch reused from patch to patch.
    #[test]
    fn counted_corners_unfold_as_the_state_checks() {
        let seq = crate::synth::compressed_tube(3000, 3, 0.3, -1.0).unwrap();
        let topo = &seq.topology;
        let p = &seq.frames[2];
        let mut unfolder = Unfolder::default();
        let h = crate::folds::stretch::mean_edge_length(topo, p);
        let mut laid_out = 0;
        for seed in (0..topo.n_triangles()).step_by(97) {
            let centre = topo.triangles()[seed].map(|v| p[v as usize]);
            let centre = vec3::scale(
                vec3::add(vec3::add(centre[0], centre[1]), centre[2]),
                1.0 / 3.0,
            );
            for radius in [2.5 * h, 8.0 * h, f64::INFINITY] {
                // The triangles with a corner within `radius` of the seed's centroid (and the seed).
                let mut tri_local = vec![NONE; topo.n_triangles()];
                let mut vert_local = vec![NONE; topo.n_vertices()];
                let (mut n_tris, mut verts) = (0u32, Vec::new());
                for (t, tri) in topo.triangles().iter().enumerate() {
                    let near = tri
                        .iter()
                        .any(|&v| vec3::norm(vec3::sub(p[v as usize], centre)) <= radius);
                    if t != seed && !near {
                        continue;
                    }
                    tri_local[t] = n_tris;
                    n_tris += 1;
                    for &v in tri {
                        if vert_local[v as usize] == NONE {
                            vert_local[v as usize] = verts.len() as u32;
                            verts.push(v);
                        }
                    }
                }
                let patch = PatchRef {
                    topo,
                    n_tris: n_tris as usize,
                    p,
                    tri_local: &tri_local,
                    vert_local: &vert_local,
                    verts: &verts,
                };
                let want = unfold_by_states(&patch, seed);
                let got = unfolder.unfold(&patch, seed);
                assert_eq!(
                    got.as_ref()
                        .map(|uv| uv.iter().map(|q| q.map(f64::to_bits)).collect::<Vec<_>>()),
                    want.as_ref()
                        .map(|uv| uv.iter().map(|q| q.map(f64::to_bits)).collect::<Vec<_>>()),
                    "seed {seed}, radius {radius}"
                );
                laid_out += got.is_some() as usize;
            }
        }
        assert!(laid_out > 60, "{laid_out}");
    }

    /// A degenerate seed triangle gives no layout (tracing then skips the seed, as for a failed LSCM).
    #[test]
    fn degenerate_seed_gives_nothing() {
        let (topo, mut flat) = crate::synth::sheet(5, 5, 0.1).unwrap();
        let [a, b, _] = topo.triangles()[0];
        flat[b as usize] = flat[a as usize];
        assert!(unfold_all(&topo, &flat, 0).is_none());
    }
}
