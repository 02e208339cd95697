//! Merging broken fold contours (Popa et al. 2009 §4 "Merging").
//!
//! Edge detection breaks continuous contours into pieces. Two oriented edges are joined when they are oriented
//! consistently (the end of one leads into the start of the other, same darker side), their facing ends are
//! close, and the joined edge can still be fitted by one low-curvature quadric (§4 "Edge Extraction").

use super::orient::{tangent, Edge};
use super::quadric;

/// Merges `edges` greedily: repeatedly joins an edge's end to the nearest compatible start within `max_gap`
/// whose union still fits within `tolerance` and `max_curvature`. The union keeps the fitted points of both
/// pieces (re-fitted) and the length-weighted contrast.
pub fn merge(mut edges: Vec<Edge>, max_gap: f64, tolerance: f64, max_curvature: f64) -> Vec<Edge> {
    let cos_max = (35f64).to_radians().cos();
    let mut i = 0;
    while i < edges.len() {
        let a = &edges[i];
        let end = *a.points.last().expect("edges are not empty");
        let ta = tangent(&a.points, a.points.len() - 1);
        let mut best: Option<(usize, f64)> = None;
        for (j, b) in edges.iter().enumerate() {
            if j == i {
                continue;
            }
            let start = b.points[0];
            let gap = [start[0] - end[0], start[1] - end[1]];
            let dist = gap[0].hypot(gap[1]);
            if dist > max_gap || best.is_some_and(|(_, d)| d <= dist) {
                continue;
            }
            let tb = tangent(&b.points, 0);
            if ta[0] * tb[0] + ta[1] * tb[1] < cos_max {
                continue;
            }
            if dist > 1e-9 && (gap[0] * ta[0] + gap[1] * ta[1]) / dist < cos_max {
                continue;
            }
            best = Some((j, dist));
        }
        let Some((j, _)) = best else {
            i += 1;
            continue;
        };
        let mut joined = edges[i].points.clone();
        joined.extend_from_slice(&edges[j].points);
        let fit = quadric::fit(&joined);
        match fit {
            Some(f) if quadric::acceptable(&f, tolerance, max_curvature) => {
                let (la, lb) = (
                    quadric::length(&edges[i].points),
                    quadric::length(&edges[j].points),
                );
                let contrast =
                    (edges[i].contrast * la + edges[j].contrast * lb) / (la + lb).max(1e-9);
                edges[i] = Edge {
                    points: f.points,
                    contrast,
                };
                edges.remove(j);
                if j < i {
                    i -= 1;
                }
                // Try to extend the merged edge again.
            }
            _ => i += 1,
        }
    }
    edges
}

#[cfg(test)]
mod tests {
    use super::*;

    fn edge(pts: Vec<[f64; 2]>) -> Edge {
        Edge {
            points: pts,
            contrast: 10.0,
        }
    }

    #[test]
    fn collinear_pieces_join_and_others_do_not() {
        let a = edge((0..20).map(|i| [i as f64, 10.0]).collect());
        let b = edge((23..45).map(|i| [i as f64, 10.2]).collect());
        // Opposite orientation (dark side flips): must not join.
        let c = edge((50..70).rev().map(|i| [i as f64, 10.0]).collect());
        // Far away.
        let d = edge((0..20).map(|i| [i as f64, 40.0]).collect());
        // Perpendicular, close to a's end.
        let e = edge((12..30).map(|i| [21.0, i as f64]).collect());
        let out = merge(vec![b, c, a, d, e], 5.0, 1.0, 0.05);
        assert_eq!(out.len(), 4, "{out:?}");
        assert!(out.iter().any(|e| e.points.len() == 42));
    }
}
