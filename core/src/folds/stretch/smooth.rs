//! Outlier removal and smoothing of a per-triangle tensor field over the surface (Chen 2011 §4.2).
//!
//! **Outliers.** Two tests, as in the thesis: a valid magnitude range (an absolute change above
//! `max_change` is a registration error, not cloth), and the histogram tails — the signed log-change
//! ln v is binned, and the sparse bins at the extreme stretch and extreme shrinkage ends are dropped, walking
//! inwards until a bin holds at least `tail_fraction` of the triangles (never more than 1% per side).
//!
//! **Smoothing scheme.** The three independent components are smoothed separately by Jacobi iterations over
//! each triangle and its edge neighbours, weighted by triangle area: Γ and γ by plain weighted means; the
//! direction angle as an *axial* quantity — each neighbour's Γ direction is projected into the triangle's
//! plane, expressed as an angle θ in the triangle's own local frame, and the doubled angles (cos 2θ, sin 2θ)
//! are averaged (so d and −d agree), weighted also by the anisotropy ln Γ − ln γ (a nearly isotropic tensor has
//! no meaningful direction). Dropped outliers contribute nothing and are refilled from their neighbours.

use super::tensor::{absolute_change, axial_angle, Tensor};
use crate::mesh::{Topology, NONE};
use crate::vec3::{self, V3};
use rayon::prelude::*;

/// Per-frame geometry the field operations need: unit normals, local frames and areas of every triangle.
pub struct FrameGeometry {
    pub normals: Vec<V3>,
    pub e1: Vec<V3>,
    pub e2: Vec<V3>,
    pub areas: Vec<f64>,
    pub centroids: Vec<V3>,
}

impl FrameGeometry {
    pub fn new(topo: &Topology, p: &[V3]) -> Self {
        let n = topo.n_triangles();
        let mut g = FrameGeometry {
            normals: Vec::with_capacity(n),
            e1: Vec::with_capacity(n),
            e2: Vec::with_capacity(n),
            areas: Vec::with_capacity(n),
            centroids: Vec::with_capacity(n),
        };
        for tri in topo.triangles() {
            let q = tri.map(|v| p[v as usize]);
            let c = vec3::cross(vec3::sub(q[1], q[0]), vec3::sub(q[2], q[0]));
            let (e1, e2, nrm) = super::tensor::local_frame(q);
            g.normals.push(nrm);
            g.e1.push(e1);
            g.e2.push(e2);
            g.areas.push(0.5 * vec3::norm(c));
            g.centroids.push(vec3::scale(
                vec3::add(vec3::add(q[0], q[1]), q[2]),
                1.0 / 3.0,
            ));
        }
        g
    }
}

/// Marks outliers as `None` (magnitude range, then histogram tails). Returns how many were dropped.
pub fn remove_outliers(
    field: &mut [Option<Tensor>],
    normals: &[V3],
    max_change: f64,
    tail_fraction: f64,
) -> usize {
    let mut dropped = 0;
    let mut logs: Vec<(usize, f64)> = Vec::with_capacity(field.len());
    for (i, f) in field.iter_mut().enumerate() {
        if let Some(t) = f {
            let (v, _) = t.dominant(normals[i]);
            let c = absolute_change(v);
            if c.is_nan() || c > max_change {
                *f = None;
                dropped += 1;
            } else {
                logs.push((i, v.ln()));
            }
        }
    }
    let n = logs.len();
    if tail_fraction <= 0.0 || n < 100 {
        return dropped;
    }
    const BINS: usize = 64;
    let (lo, hi) = logs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &(_, l)| {
            (a.min(l), b.max(l))
        });
    if hi - lo <= 1e-12 {
        return dropped;
    }
    let bin = |l: f64| (((l - lo) / (hi - lo) * BINS as f64) as usize).min(BINS - 1);
    let mut counts = [0usize; BINS];
    for &(_, l) in &logs {
        counts[bin(l)] += 1;
    }
    let sparse = (tail_fraction * n as f64).max(1.0);
    let budget = n / 100;
    // Walk in from each end while bins are sparse and the per-side budget allows.
    let mut top = BINS; // bins >= top are dropped
    let mut removed = 0;
    while top > BINS / 2 && (counts[top - 1] as f64) < sparse && removed + counts[top - 1] <= budget
    {
        removed += counts[top - 1];
        top -= 1;
    }
    let mut bottom = 0; // bins < bottom are dropped
    removed = 0;
    while bottom < BINS / 2
        && (counts[bottom] as f64) < sparse
        && removed + counts[bottom] <= budget
    {
        removed += counts[bottom];
        bottom += 1;
    }
    for &(i, l) in &logs {
        let b = bin(l);
        if b >= top || b < bottom {
            field[i] = None;
            dropped += 1;
        }
    }
    dropped
}

/// Smooths Γ, γ and the direction angle separately (see the module doc) for `iterations` Jacobi sweeps.
/// Triangles with no data take their neighbours' values; those with no valid neighbour stay the identity.
pub fn smooth(
    topo: &Topology,
    geom: &FrameGeometry,
    field: &[Option<Tensor>],
    iterations: usize,
) -> Vec<Tensor> {
    let adj = topo.tri_adj();
    let mut cur: Vec<Option<Tensor>> = field.to_vec();
    for _ in 0..iterations {
        cur = (0..cur.len())
            .into_par_iter()
            .with_min_len(1024)
            .map(|i| {
                let (e1, e2) = (geom.e1[i], geom.e2[i]);
                let (mut wsum, mut big, mut small) = (0.0, 0.0, 0.0);
                let (mut c2, mut s2) = (0.0, 0.0);
                let mut add = |j: usize| {
                    if let Some(t) = cur[j] {
                        let w = geom.areas[j];
                        wsum += w;
                        big += w * t.big;
                        small += w * t.small;
                        let aniso = (t.big / t.small.max(1e-12)).ln().max(0.0);
                        let th = axial_angle(t.dir_big, e1, e2);
                        let wd = w * aniso;
                        c2 += wd * (2.0 * th).cos();
                        s2 += wd * (2.0 * th).sin();
                    }
                };
                add(i);
                for &j in &adj[i] {
                    if j != NONE {
                        add(j as usize);
                    }
                }
                if wsum <= 0.0 {
                    return None;
                }
                let dir = if c2 * c2 + s2 * s2 > 0.0 {
                    let th = 0.5 * s2.atan2(c2);
                    vec3::add(vec3::scale(e1, th.cos()), vec3::scale(e2, th.sin()))
                } else {
                    cur[i].map(|t| t.dir_big).unwrap_or(e1)
                };
                Some(Tensor {
                    big: big / wsum,
                    small: small / wsum,
                    dir_big: dir,
                })
            })
            .collect();
    }
    cur.into_iter()
        .enumerate()
        .map(|(i, t)| {
            t.unwrap_or(Tensor {
                dir_big: geom.e1[i],
                ..Tensor::IDENTITY
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::folds::stretch::tensor::{jacobian, shape};

    #[test]
    fn smoothing_averages_axial_directions_and_fills_outliers() {
        let (topo, p) = crate::synth::sheet(12, 12, 0.1).unwrap();
        let geom = FrameGeometry::new(&topo, &p);
        // Compression along x everywhere, with alternating sign of the direction vector and one wild triangle.
        let mut field: Vec<Option<Tensor>> = topo
            .triangles()
            .iter()
            .enumerate()
            .map(|(i, tri)| {
                let q = tri.map(|v| p[v as usize]);
                let r = q.map(|x| [0.9 * x[0], x[1], x[2]]);
                let mut t = jacobian(shape(q), r).unwrap();
                if i % 2 == 1 {
                    t.dir_big = vec3::scale(t.dir_big, -1.0);
                }
                Some(t)
            })
            .collect();
        field[50] = Some(Tensor {
            big: 5.0,
            small: 0.1,
            dir_big: [1.0, 0.0, 0.0],
        });
        let dropped = remove_outliers(&mut field, &geom.normals, 2.0, 0.001);
        assert_eq!(dropped, 1);
        assert!(field[50].is_none());
        let s = smooth(&topo, &geom, &field, 3);
        for t in &s {
            assert!(
                (t.small - 0.9).abs() < 1e-9 && (t.big - 1.0).abs() < 1e-9,
                "{t:?}"
            );
            // Γ direction (y) survives the sign flips.
            assert!(t.dir_big[1].abs() > 0.999, "{t:?}");
        }
    }
}
