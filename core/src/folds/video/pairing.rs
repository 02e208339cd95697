//! Pairing fold edges and combining resolutions (Popa et al. 2009 §3.1, §4 "Pairing", "Multi-Resolution
//! Processing").
//!
//! A fold component is a generalised cylinder seen as two roughly parallel contours. With every edge oriented
//! dark-on-the-left, the two contours of one cylinder run in opposite directions: a *ridge* pair has the bright
//! area between the edges (each edge lies on the other's right), a *valley* pair the dark area. Two edges pair when,
//! along the part where they run side by side, their tangents at closest points are anti-parallel within the
//! maximum angle and their average and maximal distances are within bounds. Ambiguities are resolved greedily in
//! the paper's order of preference: ridge pairs before valley pairs, then longer pairs first. Pairs from all
//! levels are then united, keeping the best of overlapping pairs by the same criteria.

use super::orient::{left_of, tangent, Edge};
use super::params::VideoParams;
use super::quadric::length;
use std::cmp::Ordering;

/// Two paired edges, trimmed to the part where they run side by side, in full-resolution pixels. Both keep
/// their orientation (darker side on the left).
#[derive(Debug, Clone, PartialEq)]
pub struct Pair {
    pub a: Vec<[f64; 2]>,
    pub b: Vec<[f64; 2]>,
    /// Bright between the edges (ridge) rather than dark (valley).
    pub ridge: bool,
    /// Average distance between the edges (pixels).
    pub width: f64,
    /// Combined length of the two trimmed edges (pixels).
    pub length: f64,
    /// Midpoints between `a`'s points and their closest points on `b`.
    pub midline: Vec<[f64; 2]>,
    /// Index of the level the pair was found at.
    pub level: usize,
}

impl Pair {
    /// Preference order of §4: ridges first, then longer, then narrower.
    pub fn better(&self, other: &Pair) -> Ordering {
        other
            .ridge
            .cmp(&self.ridge)
            .then(other.length.total_cmp(&self.length))
            .then(self.width.total_cmp(&other.width))
    }
}

/// Closest point on a polyline: (distance, segment index, parameter in the segment, point).
pub fn closest_on(poly: &[[f64; 2]], p: [f64; 2]) -> (f64, usize, f64, [f64; 2]) {
    let mut best = (f64::INFINITY, 0, 0.0, poly[0]);
    if poly.len() == 1 {
        let d = (p[0] - poly[0][0]).hypot(p[1] - poly[0][1]);
        return (d, 0, 0.0, poly[0]);
    }
    for (s, w) in poly.windows(2).enumerate() {
        let (a, b) = (w[0], w[1]);
        let ab = [b[0] - a[0], b[1] - a[1]];
        let l2 = ab[0] * ab[0] + ab[1] * ab[1];
        let t = if l2 > 0.0 {
            (((p[0] - a[0]) * ab[0] + (p[1] - a[1]) * ab[1]) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = [a[0] + t * ab[0], a[1] + t * ab[1]];
        let d = (p[0] - q[0]).hypot(p[1] - q[1]);
        if d < best.0 {
            best = (d, s, t, q);
        }
    }
    best
}

fn bbox(p: &[[f64; 2]]) -> [f64; 4] {
    p.iter().fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |b, q| {
            [
                b[0].min(q[0]),
                b[1].min(q[1]),
                b[2].max(q[0]),
                b[3].max(q[1]),
            ]
        },
    )
}

/// Tests whether two oriented edges form a fold pair; `None` when they do not.
pub fn try_pair(e1: &Edge, e2: &Edge, params: &VideoParams, level: usize) -> Option<Pair> {
    let (a, b) = if length(&e1.points) <= length(&e2.points) {
        (&e1.points, &e2.points)
    } else {
        (&e2.points, &e1.points)
    };
    if a.len() < 2 || b.len() < 2 {
        return None;
    }
    // Cheap rejection first: the middle of the shorter edge must be near the other edge (any real pair overlaps
    // at least half of the shorter edge, so its middle runs alongside).
    if closest_on(b, a[a.len() / 2]).0 > params.max_distance {
        return None;
    }
    let last_seg = b.len() - 2;
    let mut ov = Vec::new(); // (index in a, distance, segment in b, closest point)
    for (k, &p) in a.iter().enumerate() {
        let (d, s, t, q) = closest_on(b, p);
        let interior = !((s == 0 && t <= 0.0) || (s == last_seg && t >= 1.0));
        if interior {
            ov.push((k, d, s, q));
        }
    }
    if (ov.len() as f64) < params.min_overlap * a.len() as f64 || ov.len() < 3 {
        return None;
    }
    let n = ov.len() as f64;
    let avg = ov.iter().map(|o| o.1).sum::<f64>() / n;
    let max = ov.iter().map(|o| o.1).fold(0.0, f64::max);
    if avg > params.max_avg_distance || max > params.max_distance || avg < 1.0 {
        return None;
    }
    // Anti-parallel tangents: compare a's mean tangent with the reversed mean tangent of b over the overlap.
    let (mut ta, mut tb, mut side) = ([0.0f64; 2], [0.0f64; 2], 0.0);
    let mut opposite = 0usize;
    for &(k, _, s, q) in &ov {
        let t1 = tangent(a, k);
        let t2 = tangent(b, s.min(b.len() - 1));
        let t2 = {
            let d = [b[s + 1][0] - b[s][0], b[s + 1][1] - b[s][1]];
            let l = d[0].hypot(d[1]);
            if l > 0.0 {
                [d[0] / l, d[1] / l]
            } else {
                t2
            }
        };
        if t1[0] * t2[0] + t1[1] * t2[1] < 0.0 {
            opposite += 1;
        }
        ta = [ta[0] + t1[0], ta[1] + t1[1]];
        tb = [tb[0] - t2[0], tb[1] - t2[1]];
        let l = left_of(t1);
        side += (q[0] - a[k][0]) * l[0] + (q[1] - a[k][1]) * l[1];
    }
    if (opposite as f64) < 0.8 * n {
        return None;
    }
    let cos =
        (ta[0] * tb[0] + ta[1] * tb[1]) / (ta[0].hypot(ta[1]) * tb[0].hypot(tb[1])).max(1e-12);
    if cos < params.max_angle_deg.to_radians().cos() {
        return None;
    }
    // b on a's right (the brighter side) → bright between the edges → ridge.
    let ridge = side < 0.0;
    let k0 = ov[0].0;
    let k1 = ov[ov.len() - 1].0;
    let s0 = ov.iter().map(|o| o.2).min().unwrap_or(0);
    let s1 = ov.iter().map(|o| o.2).max().unwrap_or(last_seg);
    let a_trim = a[k0..=k1].to_vec();
    let b_trim = b[s0..=s1 + 1].to_vec();
    let midline = ov
        .iter()
        .map(|&(k, _, _, q)| [(a[k][0] + q[0]) * 0.5, (a[k][1] + q[1]) * 0.5])
        .collect();
    Some(Pair {
        length: length(&a_trim) + length(&b_trim),
        a: a_trim,
        b: b_trim,
        ridge,
        width: avg,
        midline,
        level,
    })
}

/// Pairs the edges of one level; every edge is in at most one pair.
pub fn pair_edges(edges: &[Edge], params: &VideoParams, level: usize) -> Vec<Pair> {
    let boxes: Vec<[f64; 4]> = edges.iter().map(|e| bbox(&e.points)).collect();
    let m = params.max_distance;
    let mut candidates = Vec::new();
    for i in 0..edges.len() {
        for j in i + 1..edges.len() {
            let (p, q) = (boxes[i], boxes[j]);
            if p[0] > q[2] + m || q[0] > p[2] + m || p[1] > q[3] + m || q[1] > p[3] + m {
                continue;
            }
            if let Some(pair) = try_pair(&edges[i], &edges[j], params, level) {
                candidates.push((pair, i, j));
            }
        }
    }
    candidates.sort_by(|x, y| x.0.better(&y.0));
    let mut used = vec![false; edges.len()];
    let mut out = Vec::new();
    for (pair, i, j) in candidates {
        if used[i] || used[j] {
            continue;
        }
        used[i] = true;
        used[j] = true;
        out.push(pair);
    }
    out
}

/// Whether two pairs describe (largely) the same fold: a third of either midline lies within half the wider
/// pair's width of the other midline.
pub fn overlap(p: &Pair, q: &Pair) -> bool {
    let reach = 0.5 * p.width.max(q.width) + 1.0;
    let frac = |x: &Pair, y: &Pair| {
        if y.midline.len() < 2 || x.midline.is_empty() {
            return 0.0;
        }
        x.midline
            .iter()
            .filter(|&&m| closest_on(&y.midline, m).0 <= reach)
            .count() as f64
            / x.midline.len() as f64
    };
    frac(p, q) >= 0.3 || frac(q, p) >= 0.3
}

/// The union of the pairs of all levels, keeping the best of overlapping pairs (same order as pairing).
pub fn union(levels: Vec<Vec<Pair>>) -> Vec<Pair> {
    let mut all: Vec<Pair> = levels.into_iter().flatten().collect();
    all.sort_by(|x, y| x.better(y));
    let mut out: Vec<Pair> = Vec::new();
    for p in all {
        if out.iter().all(|q| !overlap(&p, q)) {
            out.push(p);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn edge(from: [f64; 2], to: [f64; 2], n: usize) -> Edge {
        Edge {
            points: (0..n)
                .map(|i| {
                    let t = i as f64 / (n - 1) as f64;
                    [
                        from[0] + t * (to[0] - from[0]),
                        from[1] + t * (to[1] - from[1]),
                    ]
                })
                .collect(),
            contrast: 10.0,
        }
    }

    #[test]
    fn opposite_parallel_edges_pair_as_ridge_or_valley() {
        let p = VideoParams::default();
        // Walking +x, the left is -y. A at y = 10 walking +x has its dark side above (y < 10); B at y = 16
        // walking -x has its dark side below: bright between → ridge.
        let a = edge([0.0, 10.0], [40.0, 10.0], 41);
        let b = edge([42.0, 16.0], [2.0, 16.0], 41);
        let pair = try_pair(&a, &b, &p, 0).expect("ridge pair");
        assert!(pair.ridge);
        assert!((pair.width - 6.0).abs() < 1e-9);
        // Swapping the sides makes the dark area between them: a valley.
        let a2 = edge([40.0, 10.0], [0.0, 10.0], 41);
        let b2 = edge([2.0, 16.0], [42.0, 16.0], 41);
        assert!(!try_pair(&a2, &b2, &p, 0).expect("valley pair").ridge);
    }

    #[test]
    fn same_orientation_too_distant_or_crossing_edges_do_not_pair() {
        let p = VideoParams::default();
        let a = edge([0.0, 10.0], [40.0, 10.0], 41);
        let same = edge([0.0, 16.0], [40.0, 16.0], 41);
        assert!(try_pair(&a, &same, &p, 0).is_none());
        let far = edge(
            [40.0, 10.0 + p.max_distance + 5.0],
            [0.0, 10.0 + p.max_distance + 5.0],
            41,
        );
        assert!(try_pair(&a, &far, &p, 0).is_none());
        // Opposite orientation but at 60° (beyond the 45° default).
        let steep = edge([30.0, 40.0], [10.0, 5.36], 41);
        assert!(try_pair(&a, &steep, &p, 0).is_none());
        // Side by side for only a small part of the shorter edge.
        let offset = edge([70.0, 16.0], [35.0, 16.0], 36);
        assert!(try_pair(&a, &offset, &p, 0).is_none());
    }

    #[test]
    fn ridges_win_ambiguities_and_union_keeps_the_best() {
        let p = VideoParams::default();
        // Middle edge m can pair as a ridge with r (below) or as a valley with v (above).
        let m = edge([0.0, 20.0], [40.0, 20.0], 41);
        let r = edge([40.0, 26.0], [0.0, 26.0], 41);
        let v = edge([40.0, 14.0], [0.0, 14.0], 41);
        // v with m: v walks -x at y = 14, its left is +y (towards m) → dark between → valley.
        let pairs = pair_edges(&[v.clone(), m.clone(), r.clone()], &p, 0);
        assert_eq!(pairs.len(), 1);
        assert!(pairs[0].ridge);
        // The same ridge found at two levels, one shorter: the union keeps one, the longer.
        let short = try_pair(
            &edge([10.0, 20.0], [30.0, 20.0], 21),
            &edge([30.0, 26.0], [10.0, 26.0], 21),
            &p,
            1,
        )
        .unwrap();
        let long = try_pair(&m, &r, &p, 0).unwrap();
        let u = union(vec![vec![short], vec![long.clone()]]);
        assert_eq!(u, vec![long]);
    }
}
