//! "Shape kept" figures (docs/fidelity.md): how far a result moved the garment itself, as opposed to adding folds.
//!
//! Folds are short-wavelength; the garment's pose and outline are long-wavelength. So the displacement
//! d = output − captured is split by a low-pass: what survives it is **drift**, a change of the garment's shape
//! that the folds must not make. The low-pass is the caller's: `report.json` uses crease's own (the surface heat
//! kernel at the run's shape scale, [`crate::heat`]), `crease eval` a fixed measuring ruler
//! ([`crate::eval::drift_ruler`]) so its figures compare across runs and settings. The ground truth's own
//! displacement gt − captured, measured the same way, is the yardstick: real folds drift by a few hundredths of
//! an edge. Lengths are in units of the captured frame's mean edge length, so figures compare across garments
//! and resolutions; the extent change is a fraction of the captured frame's largest extent.

use crate::mesh::{Topology, NONE};
use crate::vec3::{self, V3};
use serde::{Deserialize, Serialize};

/// Taubin's λ|μ low-pass filter with uniform (umbrella) weights.
#[derive(Debug, Clone)]
pub struct TaubinFilter {
    offsets: Vec<u32>,
    neighbors: Vec<u32>,
    pub lambda: f64,
    pub mu: f64,
    pub iterations: usize,
}

impl TaubinFilter {
    /// Interior vertices average over their whole one-ring; boundary vertices only over their neighbours along
    /// the boundary, so an open rim is smoothed along itself instead of being pulled into the surface (pulling
    /// the rim inwards would read as a shrinkage that is none).
    pub fn new(topo: &Topology, lambda: f64, mu: f64, iterations: usize) -> Self {
        let nv = topo.n_vertices();
        let mut boundary_nb: Vec<Vec<u32>> = vec![Vec::new(); nv];
        for (t, tri) in topo.triangles().iter().enumerate() {
            for k in 0..3 {
                if topo.tri_adj()[t][k] == NONE {
                    let (a, b) = (tri[k], tri[(k + 1) % 3]);
                    boundary_nb[a as usize].push(b);
                    boundary_nb[b as usize].push(a);
                }
            }
        }
        let mut offsets = Vec::with_capacity(nv + 1);
        let mut neighbors = Vec::new();
        offsets.push(0u32);
        for (v, bn) in boundary_nb.iter_mut().enumerate() {
            if bn.is_empty() {
                neighbors.extend(topo.vertex_neighbors(v));
            } else {
                bn.sort_unstable();
                bn.dedup();
                neighbors.extend_from_slice(bn);
            }
            offsets.push(neighbors.len() as u32);
        }
        TaubinFilter {
            offsets,
            neighbors,
            lambda,
            mu,
            iterations,
        }
    }

    /// The vertices `v` averages over (its one-ring, or its boundary neighbours on an open rim): the operator
    /// A of every step x ← x + f (A x − x), which the fold restoration's Chebyshev series applies directly.
    pub fn neighbors(&self, v: usize) -> &[u32] {
        &self.neighbors[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }

    /// Low-pass of a per-vertex vector field: `iterations` alternating steps x ← x + f (avg(x) − x) with
    /// f = λ then μ. Vertices without neighbours keep their value.
    pub fn apply(&self, field: &[V3]) -> Vec<V3> {
        let mut x = field.to_vec();
        let mut next = x.clone();
        for it in 0..self.iterations {
            let f = if it % 2 == 0 { self.lambda } else { self.mu };
            for (v, out) in next.iter_mut().enumerate() {
                let nb = &self.neighbors[self.offsets[v] as usize..self.offsets[v + 1] as usize];
                if nb.is_empty() {
                    *out = x[v];
                    continue;
                }
                let mut avg = [0.0; 3];
                for &w in nb {
                    avg = vec3::add(avg, x[w as usize]);
                }
                let avg = vec3::scale(avg, 1.0 / nb.len() as f64);
                *out = vec3::add(x[v], vec3::scale(vec3::sub(avg, x[v]), f));
            }
            std::mem::swap(&mut x, &mut next);
        }
        x
    }
}

/// Mean edge length of a frame (each undirected edge once).
pub fn mean_edge_length(topo: &Topology, p: &[V3]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for (t, tri) in topo.triangles().iter().enumerate() {
        for k in 0..3 {
            let adj = topo.tri_adj()[t][k];
            // Interior edges are seen from both sides: count them from the lower-index triangle only.
            if adj == NONE || (adj as usize) > t {
                sum += vec3::norm(vec3::sub(p[tri[k] as usize], p[tri[(k + 1) % 3] as usize]));
                n += 1;
            }
        }
    }
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

/// Shape figures of one sequence against the captured one (see the module documentation).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ShapeStats {
    /// |output − captured| per vertex, in mean edge lengths.
    pub displacement_mean: f64,
    pub displacement_p99: f64,
    pub displacement_max: f64,
    /// |low-pass(output − captured)| per vertex, in mean edge lengths.
    pub drift_mean: f64,
    pub drift_max: f64,
    /// max over frames and axes of |extent(output) − extent(captured)| / largest extent(captured).
    pub extent_change: f64,
}

/// Histogram resolution for the displacement percentile: 1/1000 edge, up to 100 edges (the rest in the last bin).
const BIN: f64 = 1e-3;
const BINS: usize = 100_000;

/// Accumulates [`ShapeStats`] over frames, in any grouping (sums, maxima and a histogram merge exactly).
#[derive(Debug, Clone, Default)]
pub struct ShapeAccumulator {
    count: u64,
    sum_d: f64,
    max_d: f64,
    sum_drift: f64,
    max_drift: f64,
    max_extent: f64,
    hist: Vec<u64>,
}

impl ShapeAccumulator {
    /// Adds one frame: `out` compared with `captured` (the first `captured.len()` vertices of `out`; a subdivided
    /// output keeps the original vertices first).
    pub fn add_frame(
        &mut self,
        topo: &Topology,
        low_pass: &dyn Fn(&[V3]) -> Vec<V3>,
        captured: &[V3],
        out: &[V3],
    ) {
        let n = captured.len();
        let out = &out[..n.min(out.len())];
        let h = mean_edge_length(topo, captured);
        let unit = if h > 0.0 { 1.0 / h } else { 0.0 };
        let d: Vec<V3> = out
            .iter()
            .zip(captured)
            .map(|(o, c)| vec3::sub(*o, *c))
            .collect();
        let low = low_pass(&d);
        if self.hist.is_empty() {
            self.hist = vec![0; BINS + 1];
        }
        for (dv, lv) in d.iter().zip(&low) {
            let a = vec3::norm(*dv) * unit;
            let b = vec3::norm(*lv) * unit;
            self.sum_d += a;
            self.max_d = self.max_d.max(a);
            self.sum_drift += b;
            self.max_drift = self.max_drift.max(b);
            self.hist[((a / BIN) as usize).min(BINS)] += 1;
            self.count += 1;
        }
        self.max_extent = self.max_extent.max(extent_change(captured, out));
    }

    pub fn merge(&mut self, o: &ShapeAccumulator) {
        if o.hist.is_empty() {
            return;
        }
        if self.hist.is_empty() {
            self.hist = vec![0; BINS + 1];
        }
        self.count += o.count;
        self.sum_d += o.sum_d;
        self.max_d = self.max_d.max(o.max_d);
        self.sum_drift += o.sum_drift;
        self.max_drift = self.max_drift.max(o.max_drift);
        self.max_extent = self.max_extent.max(o.max_extent);
        for (a, b) in self.hist.iter_mut().zip(&o.hist) {
            *a += b;
        }
    }

    /// Exact, compact encoding (f64 bit patterns, the count, and the non-empty histogram bins as (bin, count)
    /// pairs; `u64::MAX` in place of the bin count when nothing was added), as
    /// [`StretchAccumulator::to_words`](crate::metrics::StretchAccumulator::to_words): a frame's figures computed
    /// where the frame was positioned merge into the same sequence figures as in one process.
    pub fn to_words(&self) -> Vec<u64> {
        let mut w = vec![
            self.count,
            self.sum_d.to_bits(),
            self.max_d.to_bits(),
            self.sum_drift.to_bits(),
            self.max_drift.to_bits(),
            self.max_extent.to_bits(),
        ];
        if self.hist.is_empty() {
            w.push(u64::MAX);
        } else {
            let start = w.len();
            w.push(0);
            for (b, &c) in self.hist.iter().enumerate().filter(|b| *b.1 != 0) {
                w.extend([b as u64, c]);
            }
            w[start] = ((w.len() - start - 1) / 2) as u64;
        }
        w
    }

    /// Decodes [`ShapeAccumulator::to_words`]; returns the accumulator and the number of words used, or `None`
    /// when the words are not such an encoding.
    pub fn from_words(w: &[u64]) -> Option<(Self, usize)> {
        let head = w.get(..7)?;
        let mut acc = ShapeAccumulator {
            count: head[0],
            sum_d: f64::from_bits(head[1]),
            max_d: f64::from_bits(head[2]),
            sum_drift: f64::from_bits(head[3]),
            max_drift: f64::from_bits(head[4]),
            max_extent: f64::from_bits(head[5]),
            hist: Vec::new(),
        };
        if head[6] == u64::MAX {
            return Some((acc, 7));
        }
        let n = usize::try_from(head[6]).ok()?;
        let pairs = w.get(7..7 + n.checked_mul(2)?)?;
        acc.hist = vec![0; BINS + 1];
        for p in pairs.chunks_exact(2) {
            *acc.hist.get_mut(usize::try_from(p[0]).ok()?)? = p[1];
        }
        Some((acc, 7 + 2 * n))
    }

    pub fn stats(&self) -> ShapeStats {
        if self.count == 0 {
            return ShapeStats::default();
        }
        let target = (self.count as f64 * 0.99).ceil() as u64;
        let mut cum = 0;
        let mut p99 = self.max_d;
        for (b, &c) in self.hist.iter().enumerate() {
            cum += c;
            if cum >= target {
                p99 = ((b as f64 + 1.0) * BIN).min(self.max_d);
                break;
            }
        }
        let n = self.count as f64;
        ShapeStats {
            displacement_mean: self.sum_d / n,
            displacement_p99: p99,
            displacement_max: self.max_d,
            drift_mean: self.sum_drift / n,
            drift_max: self.max_drift,
            extent_change: self.max_extent,
        }
    }
}

/// Largest per-axis change of the axis-aligned bounding box, relative to the captured frame's largest extent.
pub fn extent_change(captured: &[V3], out: &[V3]) -> f64 {
    let (lo_c, hi_c) = crate::mesh::geometry::bounding_box(captured);
    let (lo_o, hi_o) = crate::mesh::geometry::bounding_box(out);
    let ext_c = vec3::sub(hi_c, lo_c);
    let ext_o = vec3::sub(hi_o, lo_o);
    let largest = ext_c[0].max(ext_c[1]).max(ext_c[2]);
    if largest.is_nan() || largest <= 0.0 {
        return 0.0;
    }
    (0..3)
        .map(|k| (ext_o[k] - ext_c[k]).abs() / largest)
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth;

    fn sheet() -> (std::sync::Arc<Topology>, Vec<V3>) {
        synth::sheet(41, 41, 0.01).unwrap()
    }

    #[test]
    fn taubin_keeps_constants_and_linear_fields() {
        let (topo, p) = sheet();
        let f = crate::eval::drift_ruler(&topo);
        // A constant field is a fixed point (every update is avg − x = 0).
        let c = vec![[0.3, -0.2, 0.1]; p.len()];
        for (a, b) in f.apply(&c).iter().zip(&c) {
            assert!(vec3::norm(vec3::sub(*a, *b)) < 1e-14);
        }
        // A linear field is kept at interior vertices whose one-ring is symmetric (umbrella average = value).
        let lin: Vec<V3> = p.iter().map(|q| [q[0] * 2.0, q[1] - q[0], 0.5]).collect();
        let out = f.apply(&lin);
        let centre = 20 * 41 + 20;
        assert!(vec3::norm(vec3::sub(out[centre], lin[centre])) < 1e-12);
    }

    #[test]
    fn taubin_removes_short_waves_and_keeps_long_ones() {
        let (topo, p) = sheet();
        let f = crate::eval::drift_ruler(&topo);
        // Waves along x with 3 and 20 edges per period, evaluated at the centre row (far from the boundary).
        let wave = |edges: f64| -> f64 {
            let k = 2.0 * std::f64::consts::PI / (edges * 0.01);
            let field: Vec<V3> = p.iter().map(|q| [0.0, 0.0, (k * q[0]).cos()]).collect();
            let out = f.apply(&field);
            // Gain at the centre (a plane wave is an eigenvector of the umbrella operator away from the boundary).
            let v = 20 * 41 + 20;
            out[v][2] / field[v][2]
        };
        let short = wave(3.0);
        let long = wave(20.0);
        assert!(short.abs() < 0.05, "3-edge wave kept {short}");
        assert!(long > 0.9, "20-edge wave kept only {long}");
    }

    /// The words give back the same accumulator: merged in the same order, the same figures bit for bit.
    #[test]
    fn words_round_trip() {
        let (topo, p) = sheet();
        let f = crate::eval::drift_ruler(&topo);
        let bent: Vec<V3> = p
            .iter()
            .map(|q| [q[0], q[1], 0.02 * (40.0 * q[0]).sin() * q[1]])
            .collect();
        let mut a = ShapeAccumulator::default();
        a.add_frame(&topo, &|d: &[V3]| f.apply(d), &p, &bent);
        let empty = ShapeAccumulator::default();
        let mut words = a.to_words();
        words.extend(empty.to_words());
        let (b, used) = ShapeAccumulator::from_words(&words).unwrap();
        let (e, rest) = ShapeAccumulator::from_words(&words[used..]).unwrap();
        assert_eq!(used + rest, words.len());
        assert!(e.hist.is_empty() && e.count == 0);
        assert_eq!(b.to_words(), a.to_words());
        let (mut x, mut y) = (ShapeAccumulator::default(), ShapeAccumulator::default());
        x.merge(&a);
        x.merge(&a);
        y.merge(&b);
        y.merge(&b);
        assert_eq!(x.to_words(), y.to_words());
        assert_eq!(format!("{:?}", x.stats()), format!("{:?}", y.stats()));
        // Truncated words and bins out of range are refused, not read past.
        assert!(ShapeAccumulator::from_words(&words[..used - 1]).is_none());
        let mut bad = a.to_words();
        bad[7] = (BINS + 1) as u64;
        assert!(ShapeAccumulator::from_words(&bad).is_none());
    }

    #[test]
    fn figures_of_known_displacements() {
        let (topo, p) = sheet();
        let f = crate::eval::drift_ruler(&topo);
        assert!((mean_edge_length(&topo, &p) - 0.01 * (2.0 + 2f64.sqrt()) / 3.0).abs() < 1e-4);
        let h = mean_edge_length(&topo, &p);
        // A translation by 3 mean edge lengths is all drift; the extent does not change.
        let moved: Vec<V3> = p
            .iter()
            .map(|q| vec3::add(*q, [0.0, 0.0, 3.0 * h]))
            .collect();
        let mut acc = ShapeAccumulator::default();
        acc.add_frame(&topo, &|d: &[V3]| f.apply(d), &p, &moved);
        let s = acc.stats();
        assert!((s.displacement_mean - 3.0).abs() < 1e-9);
        assert!((s.displacement_max - 3.0).abs() < 1e-9);
        assert!((s.displacement_p99 - 3.0).abs() < 2e-3);
        assert!((s.drift_mean - 3.0).abs() < 1e-9 && (s.drift_max - 3.0).abs() < 1e-9);
        assert!(s.extent_change < 1e-12);
        // A 3-edge ripple (shorter than any wavelength the filter keeps) moves vertices but hardly drifts: only
        // the left and right rims, smoothed along themselves (across the ripple's crests), keep it.
        let k = 2.0 * std::f64::consts::PI / (3.0 * 0.01);
        let ripple: Vec<V3> = p
            .iter()
            .map(|q| vec3::add(*q, [0.0, 0.0, h * (k * q[0]).cos()]))
            .collect();
        let mut acc = ShapeAccumulator::default();
        acc.add_frame(&topo, &|d: &[V3]| f.apply(d), &p, &ripple);
        let s = acc.stats();
        assert!((s.displacement_max - 1.0).abs() < 1e-9);
        assert!(s.displacement_mean > 0.6, "{s:?}");
        assert!(s.drift_mean < 0.1, "ripple drift {}", s.drift_mean);
        // Scaling the sheet by 0.95 in x: the extent changes by 5% of the (square) sheet's largest extent.
        let narrow: Vec<V3> = p.iter().map(|q| [q[0] * 0.95, q[1], q[2]]).collect();
        let mut acc = ShapeAccumulator::default();
        acc.add_frame(&topo, &|d: &[V3]| f.apply(d), &p, &narrow);
        assert!((acc.stats().extent_change - 0.05).abs() < 1e-9);
        // Merging two halves gives the figures of the whole.
        let mut a = ShapeAccumulator::default();
        a.add_frame(&topo, &|d: &[V3]| f.apply(d), &p, &moved);
        let mut b = ShapeAccumulator::default();
        b.add_frame(&topo, &|d: &[V3]| f.apply(d), &p, &narrow);
        let mut whole = ShapeAccumulator::default();
        whole.add_frame(&topo, &|d: &[V3]| f.apply(d), &p, &moved);
        whole.add_frame(&topo, &|d: &[V3]| f.apply(d), &p, &narrow);
        a.merge(&b);
        let (m, w) = (a.stats(), whole.stats());
        // Same sums, added in another order: equal up to round-off; maxima and the percentile exactly.
        assert!((m.displacement_mean - w.displacement_mean).abs() < 1e-12);
        assert!((m.drift_mean - w.drift_mean).abs() < 1e-12);
        assert_eq!(
            (
                m.displacement_p99,
                m.displacement_max,
                m.drift_max,
                m.extent_change
            ),
            (
                w.displacement_p99,
                w.displacement_max,
                w.drift_max,
                w.extent_change
            )
        );
    }
}
