//! Quadric fitting of edge chains with recursive splitting (Popa et al. 2009 §4 "Edge Extraction").
//!
//! Fold edges follow the contours of generalised cylinders whose axes bend little, so each edge should be a low
//! degree curve of bounded curvature. A chain is fitted, in the frame of its principal axis, with the parabola
//! `y = a x² + b x + c` (least squares); when the largest deviation or the largest curvature of the parabola over
//! the chain is too high, or the chain folds back on itself (not a graph over its axis), it is split at its point
//! of largest deviation and both halves are fitted again. The fitted curve replaces the pixel chain, which removes
//! the staircase of the pixel grid before orientation and pairing.

/// A fitted chain: the parabola evaluated at every input point, in input coordinates.
#[derive(Debug, Clone)]
pub struct QuadricFit {
    pub points: Vec<[f64; 2]>,
    /// Largest distance of an input point from the parabola (along the axis normal).
    pub max_error: f64,
    /// Largest curvature of the parabola over the chain's extent.
    pub max_curvature: f64,
    /// The input points are not monotone along the principal axis.
    pub folds_back: bool,
}

/// Fits one parabola to `points` (at least 3). `None` for fewer points or a degenerate (single-point) chain.
pub fn fit(points: &[[f64; 2]]) -> Option<QuadricFit> {
    let n = points.len();
    if n < 3 {
        return None;
    }
    let m = points
        .iter()
        .fold([0.0, 0.0], |a, p| [a[0] + p[0], a[1] + p[1]]);
    let m = [m[0] / n as f64, m[1] / n as f64];
    // Principal axis of the scatter matrix.
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let (dx, dy) = (p[0] - m[0], p[1] - m[1]);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let e1 = [theta.cos(), theta.sin()];
    let e2 = [-e1[1], e1[0]];
    let local: Vec<[f64; 2]> = points
        .iter()
        .map(|p| {
            let d = [p[0] - m[0], p[1] - m[1]];
            [d[0] * e1[0] + d[1] * e1[1], d[0] * e2[0] + d[1] * e2[1]]
        })
        .collect();
    let (xmin, xmax) = local
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
            (lo.min(q[0]), hi.max(q[0]))
        });
    let half = 0.5 * (xmax - xmin);
    if half.is_nan() || half <= 1e-9 {
        return None;
    }
    // Normal equations in the scaled variable s = x / half (well conditioned).
    let mut ata = [[0.0f64; 3]; 3];
    let mut aty = [0.0f64; 3];
    for q in &local {
        let s = q[0] / half;
        let row = [s * s, s, 1.0];
        for i in 0..3 {
            for j in 0..3 {
                ata[i][j] += row[i] * row[j];
            }
            aty[i] += row[i] * q[1];
        }
    }
    let [a_s, b_s, c] = solve3(ata, aty)?;
    let a = a_s / (half * half);
    let b = b_s / half;
    let f = |x: f64| a * x * x + b * x + c;
    let mut max_error: f64 = 0.0;
    let mut out = Vec::with_capacity(n);
    for q in &local {
        let y = f(q[0]);
        max_error = max_error.max((q[1] - y).abs());
        out.push([
            m[0] + q[0] * e1[0] + y * e2[0],
            m[1] + q[0] * e1[1] + y * e2[1],
        ]);
    }
    // Curvature |2a| / (1 + f'²)^{3/2} is largest where f' is closest to 0 over [xmin, xmax].
    let x_star = if a.abs() > 1e-15 {
        (-b / (2.0 * a)).clamp(xmin, xmax)
    } else {
        xmin
    };
    let slope = 2.0 * a * x_star + b;
    let max_curvature = (2.0 * a).abs() / (1.0 + slope * slope).powf(1.5);
    // Monotone along the axis (allowing one pixel of jitter).
    let dir = (local[n - 1][0] - local[0][0]).signum();
    let mut folds_back = false;
    let mut run_max = local[0][0] * dir;
    for q in &local[1..] {
        let x = q[0] * dir;
        if x < run_max - 1.0 {
            folds_back = true;
            break;
        }
        run_max = run_max.max(x);
    }
    Some(QuadricFit {
        points: out,
        max_error,
        max_curvature,
        folds_back,
    })
}

fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(&a);
    if d.is_nan() || d.abs() <= 1e-12 {
        return None;
    }
    let mut x = [0.0; 3];
    for (k, xk) in x.iter_mut().enumerate() {
        let mut m = a;
        for i in 0..3 {
            m[i][k] = b[i];
        }
        *xk = det(&m) / d;
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Length of a polyline.
pub fn length(points: &[[f64; 2]]) -> f64 {
    points
        .windows(2)
        .map(|w| ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt())
        .sum()
}

/// Whether a fit is good enough to be one fold edge.
pub fn acceptable(f: &QuadricFit, tolerance: f64, max_curvature: f64) -> bool {
    !f.folds_back && f.max_error <= tolerance && f.max_curvature <= max_curvature
}

/// Fits `points` and splits recursively until every piece fits within `tolerance` with curvature at most
/// `max_curvature`; pieces shorter than `min_length` are dropped. Returns the fitted pieces in chain order.
pub fn fit_and_split(
    points: &[[f64; 2]],
    tolerance: f64,
    max_curvature: f64,
    min_length: f64,
) -> Vec<Vec<[f64; 2]>> {
    let mut out = Vec::new();
    split_into(points, tolerance, max_curvature, min_length, 0, &mut out);
    out
}

fn split_into(
    points: &[[f64; 2]],
    tol: f64,
    kmax: f64,
    min_length: f64,
    depth: usize,
    out: &mut Vec<Vec<[f64; 2]>>,
) {
    if points.len() < 3 || length(points) < min_length {
        return;
    }
    let Some(f) = fit(points) else { return };
    if acceptable(&f, tol, kmax) {
        out.push(f.points);
        return;
    }
    if depth > 32 {
        return;
    }
    // Split at the largest deviation from the fit unless it is at an end; then split in the middle.
    let n = points.len();
    let dev = |i: usize| {
        let (p, q) = (points[i], f.points[i]);
        (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)
    };
    let margin = (n / 5).max(1);
    let mut k = (margin..n - margin)
        .max_by(|&i, &j| dev(i).total_cmp(&dev(j)))
        .unwrap_or(n / 2);
    if k == 0 || k >= n - 1 {
        k = n / 2;
    }
    split_into(&points[..=k], tol, kmax, min_length, depth + 1, out);
    split_into(&points[k..], tol, kmax, min_length, depth + 1, out);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn straight_and_gently_curved_chains_fit_whole() {
        let line: Vec<[f64; 2]> = (0..40).map(|i| [i as f64, 0.5 * i as f64 + 3.0]).collect();
        let f = fit(&line).unwrap();
        assert!(f.max_error < 1e-9 && f.max_curvature < 1e-9 && !f.folds_back);
        let arc: Vec<[f64; 2]> = (0..40)
            .map(|i| [i as f64, 0.005 * (i as f64 - 20.0).powi(2)])
            .collect();
        let pieces = fit_and_split(&arc, 0.5, 0.05, 5.0);
        assert_eq!(pieces.len(), 1);
        assert_eq!(pieces[0].len(), 40);
    }

    #[test]
    fn corners_and_hairpins_are_split() {
        // An L: two straight legs meeting at a right angle.
        let mut l: Vec<[f64; 2]> = (0..30).map(|i| [i as f64, 0.0]).collect();
        l.extend((1..30).map(|i| [29.0, i as f64]));
        let pieces = fit_and_split(&l, 0.75, 0.05, 5.0);
        assert!(pieces.len() >= 2, "{}", pieces.len());
        for p in &pieces {
            let f = fit(p).unwrap();
            assert!(acceptable(&f, 0.75, 0.05));
        }
        // A hairpin folds back over its principal axis.
        let mut u: Vec<[f64; 2]> = (0..30).map(|i| [i as f64, 0.0]).collect();
        u.extend((0..30).rev().map(|i| [i as f64, 6.0]));
        assert!(!acceptable(&fit(&u).unwrap(), 10.0, 10.0));
        assert!(fit_and_split(&u, 0.75, 0.05, 5.0).len() >= 2);
        // Too short to keep.
        assert!(fit_and_split(&l[..4], 0.75, 0.05, 5.0).is_empty());
    }
}
