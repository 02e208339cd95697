//! Stretch of an output frame relative to its input (Sander et al. 2001; Popa et al. 2009 §5.5).
//!
//! Each triangle's map from its original shape to its output shape is affine; its 3x2 Jacobian (in a 2D frame
//! of the original triangle) has singular values σ₁ ≥ σ₂, the largest and smallest length ratios. Garments
//! barely stretch, so these are the numbers that say whether added folds are physically believable:
//! - per-triangle stretch: max(σ₁ − 1, 1 − σ₂), the largest relative length change in any direction;
//! - L2 stretch: sqrt(Σ A (σ₁² + σ₂²)/2 / Σ A), area-weighted over the original areas (1 = isometric).

use crate::mesh::Topology;
use crate::vec3::{self, V3};
use serde::Serialize;

/// Singular values (σ₁ ≥ σ₂) of the affine map taking triangle `rest` to triangle `out`.
pub fn triangle_singular_values(rest: [V3; 3], out: [V3; 3]) -> (f64, f64) {
    RestTriangle::of(rest).singular_values(out)
}

/// What the stretch of a triangle needs of its original shape: its 2D frame (the inverse of its first edge's
/// length, and its third vertex (a, b) in that frame, as 1 / b) and its area. A deformation measures the
/// stretch of every frame after positioning and after each pass against the same original frame, so it
/// computes these once per frame ([`RestTriangles`]) and leaves only the output's half to each measurement:
/// the same numbers, computed by the same operations, as computing them every time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RestTriangle {
    inv_l1: f64,
    a: f64,
    inv_b: f64,
    area: f64,
}

impl RestTriangle {
    /// The frame and area of the triangle `rest`.
    #[inline]
    pub fn of(rest: [V3; 3]) -> Self {
        let e1 = vec3::sub(rest[1], rest[0]);
        let e2 = vec3::sub(rest[2], rest[0]);
        let l1 = vec3::norm(e1);
        let inv_l1 = 1.0 / l1;
        let u = vec3::scale(e1, inv_l1);
        let n = vec3::cross(e1, e2);
        let v = vec3::normalize(vec3::cross(n, e1));
        // Rest triangle in its own 2D frame: (0,0), (l1, 0), (a, b).
        let (a, b) = (vec3::dot(e2, u), vec3::dot(e2, v));
        RestTriangle {
            inv_l1,
            a,
            inv_b: 1.0 / b,
            area: 0.5 * vec3::norm(n),
        }
    }

    /// Singular values (σ₁ ≥ σ₂) of the affine map taking this triangle to `out`.
    #[inline]
    pub fn singular_values(&self, out: [V3; 3]) -> (f64, f64) {
        let f1 = vec3::sub(out[1], out[0]);
        let f2 = vec3::sub(out[2], out[0]);
        // J = [f1 f2] P⁻¹ with P = [[l1, a], [0, b]] → columns j1 = f1 / l1, j2 = (f2 − a j1) / b.
        let j1 = vec3::scale(f1, self.inv_l1);
        let j2 = vec3::scale(vec3::sub(f2, vec3::scale(j1, self.a)), self.inv_b);
        // Eigenvalues of JᵀJ.
        let (p, q, r) = (vec3::dot(j1, j1), vec3::dot(j1, j2), vec3::dot(j2, j2));
        let mean = 0.5 * (p + r);
        let disc = (0.25 * (p - r) * (p - r) + q * q).sqrt();
        ((mean + disc).max(0.0).sqrt(), (mean - disc).max(0.0).sqrt())
    }
}

/// [`RestTriangle`] of every triangle of a frame, in triangle order.
pub struct RestTriangles(Vec<RestTriangle>);

impl RestTriangles {
    pub fn new(topo: &Topology, rest: &[V3]) -> Self {
        RestTriangles(
            topo.triangles()
                .iter()
                .map(|t| RestTriangle::of(t.map(|i| rest[i as usize])))
                .collect(),
        )
    }
}

/// Stretch summary of one frame (or a whole sequence, see [`StretchAccumulator`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct StretchStats {
    /// Sander et al. L2 stretch (1 = no stretch).
    pub l2: f64,
    /// Maximum per-triangle stretch, as a fraction (0.04 = 4%).
    pub max: f64,
    /// 99th percentile of per-triangle stretch (robust to a handful of outliers).
    pub p99: f64,
    /// Area-weighted mean per-triangle stretch.
    pub mean: f64,
}

/// Per-triangle stretch max(σ₁ − 1, 1 − σ₂) of `out` relative to `rest`.
pub fn per_triangle_stretch(topo: &Topology, rest: &[V3], out: &[V3]) -> Vec<f64> {
    topo.triangles()
        .iter()
        .map(|t| {
            let (s1, s2) =
                triangle_singular_values(t.map(|i| rest[i as usize]), t.map(|i| out[i as usize]));
            (s1 - 1.0).max(1.0 - s2)
        })
        .collect()
}

/// Accumulates stretch over frames so that sequence-level figures are exact (not averages of averages).
#[derive(Debug, Clone, Default)]
pub struct StretchAccumulator {
    sum_area_sigma2: f64,
    sum_area_stretch: f64,
    sum_area: f64,
    max: f64,
    /// Histogram of per-triangle stretch in 1e-4 bins up to 100% (for percentiles).
    hist: Vec<u64>,
    count: u64,
}

const BINS: usize = 10_000;

impl StretchAccumulator {
    pub fn add_frame(&mut self, topo: &Topology, rest: &[V3], out: &[V3]) {
        self.start_histogram();
        for t in topo.triangles() {
            let r = RestTriangle::of(t.map(|i| rest[i as usize]));
            self.add_triangle(&r, t.map(|i| out[i as usize]));
        }
    }

    /// [`Self::add_frame`] with the original frame's triangles computed beforehand (`rest` must be
    /// [`RestTriangles::new`] of the same topology): the same figures, bit for bit.
    pub fn add_frame_with(&mut self, topo: &Topology, rest: &RestTriangles, out: &[V3]) {
        assert_eq!(
            rest.0.len(),
            topo.n_triangles(),
            "rest triangles of another mesh"
        );
        self.start_histogram();
        for (t, r) in topo.triangles().iter().zip(&rest.0) {
            self.add_triangle(r, t.map(|i| out[i as usize]));
        }
    }

    fn start_histogram(&mut self) {
        if self.hist.is_empty() {
            self.hist = vec![0; BINS + 1];
        }
    }

    /// One triangle's figures (the histogram started).
    #[inline]
    fn add_triangle(&mut self, r: &RestTriangle, out: [V3; 3]) {
        let (s1, s2) = r.singular_values(out);
        let area = r.area;
        let s = (s1 - 1.0).max(1.0 - s2);
        self.sum_area_sigma2 += area * 0.5 * (s1 * s1 + s2 * s2);
        self.sum_area_stretch += area * s;
        self.sum_area += area;
        self.max = self.max.max(s);
        self.hist[((s * BINS as f64) as usize).min(BINS)] += 1;
        self.count += 1;
    }

    pub fn merge(&mut self, other: &StretchAccumulator) {
        if self.hist.is_empty() {
            self.hist = vec![0; BINS + 1];
        }
        self.sum_area_sigma2 += other.sum_area_sigma2;
        self.sum_area_stretch += other.sum_area_stretch;
        self.sum_area += other.sum_area;
        self.max = self.max.max(other.max);
        for (a, b) in self.hist.iter_mut().zip(&other.hist) {
            *a += b;
        }
        self.count += other.count;
    }

    /// Exact, compact encoding (f64 bit patterns, counts, and the non-empty histogram bins as (bin, count)
    /// pairs), so accumulators computed on different machines merge into the same sequence figures as on one.
    pub fn to_words(&self) -> Vec<u64> {
        let mut w = vec![
            self.sum_area_sigma2.to_bits(),
            self.sum_area_stretch.to_bits(),
            self.sum_area.to_bits(),
            self.max.to_bits(),
            self.count,
        ];
        if self.hist.is_empty() {
            w.push(u64::MAX);
        } else {
            let bins: Vec<(usize, u64)> = self
                .hist
                .iter()
                .copied()
                .enumerate()
                .filter(|b| b.1 != 0)
                .collect();
            w.push(bins.len() as u64);
            for (b, c) in bins {
                w.push(b as u64);
                w.push(c);
            }
        }
        w
    }

    /// Decodes [`StretchAccumulator::to_words`]; returns the accumulator and the number of words used, or
    /// `None` when the words are not such an encoding.
    pub fn from_words(w: &[u64]) -> Option<(Self, usize)> {
        let head = w.get(..6)?;
        let mut acc = StretchAccumulator {
            sum_area_sigma2: f64::from_bits(head[0]),
            sum_area_stretch: f64::from_bits(head[1]),
            sum_area: f64::from_bits(head[2]),
            max: f64::from_bits(head[3]),
            hist: Vec::new(),
            count: head[4],
        };
        if head[5] == u64::MAX {
            return Some((acc, 6));
        }
        let n = usize::try_from(head[5]).ok()?;
        let pairs = w.get(6..6 + n.checked_mul(2)?)?;
        acc.hist = vec![0; BINS + 1];
        for p in pairs.chunks_exact(2) {
            *acc.hist.get_mut(usize::try_from(p[0]).ok()?)? = p[1];
        }
        Some((acc, 6 + 2 * n))
    }

    pub fn stats(&self) -> StretchStats {
        if self.sum_area == 0.0 {
            return StretchStats::default();
        }
        let target = (self.count as f64 * 0.99).ceil() as u64;
        let mut cum = 0;
        let mut p99 = 0.0;
        for (b, &c) in self.hist.iter().enumerate() {
            cum += c;
            if cum >= target {
                p99 = (b as f64 + 1.0) / BINS as f64;
                break;
            }
        }
        StretchStats {
            l2: (self.sum_area_sigma2 / self.sum_area).sqrt(),
            max: self.max,
            p99: p99.min(self.max),
            mean: self.sum_area_stretch / self.sum_area,
        }
    }
}

/// Stretch of one frame.
pub fn frame_stretch(topo: &Topology, rest: &[V3], out: &[V3]) -> StretchStats {
    let mut acc = StretchAccumulator::default();
    acc.add_frame(topo, rest, out);
    acc.stats()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The original frame's triangles computed once give every figure of the accumulator bit for bit.
    #[test]
    fn rest_triangles_computed_once_give_the_same_figures() {
        let (seq, _) = crate::synth::demo(&crate::synth::DemoSpec {
            triangles: 600,
            frames: 3,
            ..Default::default()
        })
        .unwrap();
        let topo = &seq.topology;
        let rest = &seq.frames[0];
        let out: Vec<V3> = rest
            .iter()
            .enumerate()
            .map(|(i, p)| [p[0] * 1.03, p[1] + 0.01 * (i as f64).sin(), p[2] * 0.97])
            .collect();
        let mut once = StretchAccumulator::default();
        once.add_frame_with(topo, &RestTriangles::new(topo, rest), &out);
        let mut each = StretchAccumulator::default();
        each.add_frame(topo, rest, &out);
        assert_eq!(once.to_words(), each.to_words());
        assert!(once.stats().max > 0.01, "{:?}", once.stats());
    }

    #[test]
    fn singular_values_of_known_maps() {
        let rest = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        // Rigid rotation + translation: isometric.
        let r = crate::spacetime::blend::so3::exp([0.3, -0.5, 0.2]);
        let out = rest.map(|p| vec3::add(vec3::mat_vec(&r, p), [1.0, 2.0, 3.0]));
        let (a, b) = triangle_singular_values(rest, out);
        assert!((a - 1.0).abs() < 1e-12 && (b - 1.0).abs() < 1e-12);
        // Stretch x by 1.1, compress y by 0.95.
        let out = rest.map(|p| [p[0] * 1.1, p[1] * 0.95, 0.0]);
        let (a, b) = triangle_singular_values(rest, out);
        assert!((a - 1.1).abs() < 1e-12 && (b - 0.95).abs() < 1e-12);
    }

    #[test]
    fn accumulator_words_round_trip() {
        let topo = Topology::new(4, vec![[0, 1, 2], [0, 2, 3]]).unwrap();
        let rest = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let out = vec![
            [0.0, 0.0, 0.0],
            [1.1, 0.0, 0.0],
            [1.0, 1.02, 0.1],
            [0.0, 0.9, 0.0],
        ];
        let mut acc = StretchAccumulator::default();
        acc.add_frame(&topo, &rest, &out);
        let mut words = acc.to_words();
        words.extend(StretchAccumulator::default().to_words());
        let (back, used) = StretchAccumulator::from_words(&words).unwrap();
        assert_eq!(back.stats(), acc.stats());
        assert_eq!(back.to_words(), acc.to_words());
        let (empty, rest_used) = StretchAccumulator::from_words(&words[used..]).unwrap();
        assert_eq!(used + rest_used, words.len());
        assert_eq!(empty.stats(), StretchStats::default());
        assert!(StretchAccumulator::from_words(&words[..used - 1]).is_none());
    }
}
