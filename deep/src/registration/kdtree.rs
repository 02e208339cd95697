//! A small static 3-d tree for nearest-neighbour queries (scan points during registration).

use crease_core::vec3::V3;

pub struct KdTree {
    points: Vec<V3>,
    /// Point indices in tree order; node = a range, split at its middle element.
    order: Vec<u32>,
}

impl KdTree {
    pub fn new(points: &[V3]) -> Self {
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        build(points, &mut order, 0);
        KdTree {
            points: points.to_vec(),
            order,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Index and squared distance of the point nearest to `q`.
    pub fn nearest(&self, q: V3) -> Option<(usize, f64)> {
        if self.points.is_empty() {
            return None;
        }
        let mut best = (usize::MAX, f64::INFINITY);
        self.search(&self.order, 0, q, &mut best);
        Some(best)
    }

    /// The `k` points nearest to `q`, nearest first, as (index, squared distance).
    pub fn k_nearest(&self, q: V3, k: usize) -> Vec<(usize, f64)> {
        let mut best = Vec::with_capacity(k + 1);
        if k > 0 {
            self.search_k(&self.order, 0, q, k, &mut best);
        }
        best
    }

    fn search_k(&self, slice: &[u32], depth: usize, q: V3, k: usize, best: &mut Vec<(usize, f64)>) {
        if slice.is_empty() {
            return;
        }
        let mid = slice.len() / 2;
        let i = slice[mid] as usize;
        let p = self.points[i];
        let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2);
        if best.len() < k || d2 < best[best.len() - 1].1 {
            let at = best.partition_point(|e| e.1 <= d2);
            best.insert(at, (i, d2));
            best.truncate(k);
        }
        let axis = depth % 3;
        let diff = q[axis] - p[axis];
        let (near, far) = if diff < 0.0 {
            (&slice[..mid], &slice[mid + 1..])
        } else {
            (&slice[mid + 1..], &slice[..mid])
        };
        self.search_k(near, depth + 1, q, k, best);
        if best.len() < k || diff * diff < best[best.len() - 1].1 {
            self.search_k(far, depth + 1, q, k, best);
        }
    }

    fn search(&self, slice: &[u32], depth: usize, q: V3, best: &mut (usize, f64)) {
        if slice.is_empty() {
            return;
        }
        let mid = slice.len() / 2;
        let i = slice[mid] as usize;
        let p = self.points[i];
        let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2);
        if d2 < best.1 {
            *best = (i, d2);
        }
        let axis = depth % 3;
        let diff = q[axis] - p[axis];
        let (near, far) = if diff < 0.0 {
            (&slice[..mid], &slice[mid + 1..])
        } else {
            (&slice[mid + 1..], &slice[..mid])
        };
        self.search(near, depth + 1, q, best);
        if diff * diff < best.1 {
            self.search(far, depth + 1, q, best);
        }
    }
}

fn build(points: &[V3], order: &mut [u32], depth: usize) {
    if order.len() <= 1 {
        return;
    }
    let axis = depth % 3;
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        points[a as usize][axis].total_cmp(&points[b as usize][axis])
    });
    let (left, right) = order.split_at_mut(mid);
    build(points, left, depth + 1);
    build(points, &mut right[1..], depth + 1);
}
