//! Least-squares conformal map of a surface patch (Lévy et al. 2002), the local 2D parameterisation in which
//! folds are traced (Chen 2011 §4.4 uses ABF++; LSCM is its linear cousin, with the same aim — low angle
//! distortion — and no non-linear solve, which matters because one patch is flattened per fold seed).
//!
//! For a piecewise-linear map w = u + iv, conformality on a triangle is ∂w/∂z̄ = 0, which for the triangle's
//! complex edge vectors ε_k (edge opposite corner k, in the triangle's own 2D frame) reads Σ_k ε_k w_k = 0.
//! Summing |Σ_k ε_k w_k|² / A_T over the triangles gives a quadratic energy in (u, v); two pinned vertices fix
//! the similarity it leaves free. The normal equations are sparse SPD and solved with Jacobi-preconditioned
//! conjugate gradients. The result is rescaled so the patch keeps its 3D area (distances in the plane are
//! then comparable to distances on the surface).

use super::symbolic::SymbolicCache;
use super::tensor::shape;
use crate::vec3::{self, V3};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::SymbolicSparseColMatRef;
use faer::Side;
use std::sync::Arc;

/// Flattens the patch (`positions` indexed by the local vertex ids of `tris`), pinning local vertex `pin.0`
/// at the origin and `pin.1` on the positive u axis. Returns `None` when the solve breaks down (degenerate
/// patch).
pub fn lscm(positions: &[V3], tris: &[[u32; 3]], pin: (usize, usize)) -> Option<Vec<[f64; 2]>> {
    lscm_with(positions, tris, pin, None)
}

/// [`lscm`], taking the symbolic factorisation from `cache` when a patch with the same pattern was flattened
/// before (the result is the same bit for bit).
pub fn lscm_with(
    positions: &[V3],
    tris: &[[u32; 3]],
    pin: (usize, usize),
    cache: Option<&SymbolicCache>,
) -> Option<Vec<[f64; 2]>> {
    let n = positions.len();
    if n < 3 || pin.0 == pin.1 || pin.0 >= n || pin.1 >= n {
        return None;
    }
    // Unknown index: u_k → k, v_k → n + k. The normal matrix couples vertices sharing a triangle, so its
    // sparsity is known from the vertex rings: row u_i (and v_i) holds u_j then v_j for each j in the
    // closed ring of i, sorted. Building it that way avoids sorting ~72 triplets per triangle.
    let rings = Rings::new(n, tris);
    let ring = |i: usize| rings.ring(i);
    let m = 2 * n;
    let mut row_ptr = Vec::with_capacity(m + 1);
    let mut total = 0usize;
    row_ptr.push(total);
    for i in 0..m {
        total += 2 * ring(i % n).len();
        row_ptr.push(total);
    }
    let mut cols: Vec<u32> = vec![0; row_ptr[m]];
    for (i, &base) in row_ptr[..m].iter().enumerate() {
        let r = ring(i % n);
        for (k, &j) in r.iter().enumerate() {
            cols[base + k] = j;
            cols[base + r.len() + k] = j + n as u32;
        }
    }
    let mut vals: Vec<f64> = vec![0.0; row_ptr[m]];
    let mut area3 = 0.0;
    for tri in tris {
        let p = tri.map(|v| positions[v as usize]);
        let [l1, a, b] = shape(p);
        let area = 0.5 * l1 * b;
        if area <= 0.0 || !area.is_finite() {
            continue;
        }
        area3 += area;
        let z = [[0.0, 0.0], [l1, 0.0], [a, b]];
        let s = 1.0 / area.sqrt();
        // ε_k = z_{k+2} − z_{k+1} (edge opposite corner k).
        let eps: [[f64; 2]; 3] = std::array::from_fn(|k| {
            let (p1, p2) = (z[(k + 1) % 3], z[(k + 2) % 3]);
            [(p2[0] - p1[0]) * s, (p2[1] - p1[1]) * s]
        });
        // Real row: Σ a_k u_k − b_k v_k; imaginary row: Σ b_k u_k + a_k v_k.
        let re = [
            eps[0][0], eps[1][0], eps[2][0], -eps[0][1], -eps[1][1], -eps[2][1],
        ];
        let im = [
            eps[0][1], eps[1][1], eps[2][1], eps[0][0], eps[1][0], eps[2][0],
        ];
        // Where corner b sits in corner a's ring: 9 searches per triangle rather than 36.
        let slot: [[usize; 3]; 3] = std::array::from_fn(|a| {
            let r = ring(tri[a] as usize);
            std::array::from_fn(|b| {
                r.iter()
                    .position(|&w| w == tri[b])
                    .expect("ring holds the triangle")
            })
        });
        for x in 0..6 {
            let vi = tri[x % 3] as usize;
            let row = vi + if x < 3 { 0 } else { n };
            let len = ring(vi).len();
            for y in 0..6 {
                let k = slot[x % 3][y % 3];
                let at = row_ptr[row] + k + if y < 3 { 0 } else { len };
                vals[at] += re[x] * re[y] + im[x] * im[y];
            }
        }
    }
    if area3 <= 0.0 {
        return None;
    }
    // Pinned values.
    let d = vec3::norm(vec3::sub(positions[pin.1], positions[pin.0])).max(1e-12);
    let mut fixed = vec![None; m];
    fixed[pin.0] = Some(0.0);
    fixed[n + pin.0] = Some(0.0);
    fixed[pin.1] = Some(d);
    fixed[n + pin.1] = Some(0.0);
    let mut x: Vec<f64> = (0..m).map(|i| fixed[i].unwrap_or(0.0)).collect();
    // b = −N_fp x_p.
    let mut b = vec![0.0; m];
    for i in 0..m {
        if fixed[i].is_some() {
            continue;
        }
        let mut s = 0.0;
        for k in row_ptr[i]..row_ptr[i + 1] {
            if let Some(xp) = fixed[cols[k] as usize] {
                s += vals[k] * xp;
            }
        }
        b[i] = -s;
    }
    // Sparse Cholesky of N_ff (a patch has a few hundred vertices: a direct solve is far cheaper than CG,
    // which converges slowly on a map pinned at only two vertices). CG remains the fallback.
    let symbolic = |sym: SymbolicSparseColMatRef<'_, usize>| {
        let compute = || {
            factorize_symbolic_cholesky(
                sym,
                Side::Lower,
                SymmetricOrdering::Amd,
                Default::default(),
            )
            .ok()
        };
        match cache {
            Some(c) => c.get_or_compute(n, pin, tris, compute),
            None => compute().map(Arc::new),
        }
    };
    // The iterative fallback's setup is only built when the direct solve breaks down.
    let xf = match direct_solve(m, &row_ptr, &cols, &vals, &fixed, &b, symbolic) {
        Some(sol) => sol,
        None => {
            // N_ff x_f = −N_fp x_p: the free unknowns given the pins.
            let mat_vec = |x: &[f64], y: &mut [f64]| {
                for i in 0..m {
                    if fixed[i].is_some() {
                        y[i] = 0.0;
                        continue;
                    }
                    let mut s = 0.0;
                    for k in row_ptr[i]..row_ptr[i + 1] {
                        let j = cols[k] as usize;
                        if fixed[j].is_none() {
                            s += vals[k] * x[j];
                        }
                    }
                    y[i] = s;
                }
            };
            let diag: Vec<f64> = (0..m)
                .map(|i| {
                    (row_ptr[i]..row_ptr[i + 1])
                        .find(|&k| cols[k] as usize == i)
                        .map(|k| vals[k])
                        .unwrap_or(0.0)
                })
                .collect();
            let precond = |r: &[f64], z: &mut [f64]| {
                for i in 0..m {
                    z[i] = if fixed[i].is_none() && diag[i] > 0.0 {
                        r[i] / diag[i]
                    } else {
                        0.0
                    };
                }
            };
            // Start from the orthographic projection onto the patch's mean plane, aligned with the pins: for
            // the gently curved patches that folds live on this is close to the answer, so CG needs few
            // iterations.
            let mut normal = [0.0; 3];
            for tri in tris {
                let p = tri.map(|v| positions[v as usize]);
                normal = vec3::add(
                    normal,
                    vec3::cross(vec3::sub(p[1], p[0]), vec3::sub(p[2], p[0])),
                );
            }
            let normal = vec3::normalize(normal);
            let o = positions[pin.0];
            let along = vec3::sub(positions[pin.1], o);
            let ax_u = vec3::sub(along, vec3::scale(normal, vec3::dot(along, normal)));
            let du = vec3::norm(ax_u);
            let mut xf = vec![0.0; m];
            if du > 1e-12 * d {
                let ax_u = vec3::scale(ax_u, 1.0 / du);
                let ax_v = vec3::cross(normal, ax_u);
                let k = d / du;
                for i in 0..n {
                    let r = vec3::sub(positions[i], o);
                    if fixed[i].is_none() {
                        xf[i] = k * vec3::dot(r, ax_u);
                    }
                    if fixed[n + i].is_none() {
                        xf[n + i] = k * vec3::dot(r, ax_v);
                    }
                }
            }
            conjugate_gradients(m, &mat_vec, &precond, &b, &mut xf);
            xf
        }
    };
    for i in 0..m {
        if fixed[i].is_none() {
            x[i] = xf[i];
        }
    }
    let mut uv: Vec<[f64; 2]> = (0..n).map(|k| [x[k], x[n + k]]).collect();
    if uv.iter().any(|q| !q[0].is_finite() || !q[1].is_finite()) {
        return None;
    }
    // Keep the patch's 3D area.
    let area_uv: f64 = tris
        .iter()
        .map(|t| {
            let (a, b, c) = (uv[t[0] as usize], uv[t[1] as usize], uv[t[2] as usize]);
            0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]))
        })
        .sum();
    if area_uv.is_nan() || area_uv <= 0.0 {
        return None;
    }
    let s = (area3 / area_uv).sqrt();
    for q in &mut uv {
        q[0] *= s;
        q[1] *= s;
    }
    Some(uv)
}

/// The closed one-rings of a patch's vertices (each vertex and those sharing a triangle with it), sorted, in
/// one flat array: built without a vector per vertex, since a patch is flattened per fold seed.
struct Rings {
    ptr: Vec<usize>,
    idx: Vec<u32>,
}

impl Rings {
    fn new(n: usize, tris: &[[u32; 3]]) -> Self {
        // Every corner of every incident triangle, then sorted and deduplicated per vertex in place.
        let mut ptr = vec![0usize; n + 1];
        for tri in tris {
            for &i in tri {
                ptr[i as usize + 1] += 3;
            }
        }
        for i in 0..n {
            ptr[i + 1] += ptr[i];
        }
        let mut fill = ptr[..n].to_vec();
        let mut idx = vec![0u32; ptr[n]];
        for tri in tris {
            for &i in tri {
                let at = &mut fill[i as usize];
                idx[*at..*at + 3].copy_from_slice(tri);
                *at += 3;
            }
        }
        let mut len = 0;
        let mut start = 0;
        for i in 0..n {
            let end = ptr[i + 1];
            let r = &mut idx[start..end];
            r.sort_unstable();
            let mut k = 0;
            for j in 0..r.len() {
                if j == 0 || r[j] != r[k - 1] {
                    r[k] = r[j];
                    k += 1;
                }
            }
            idx.copy_within(start..start + k, len);
            ptr[i] = len;
            len += k;
            start = end;
        }
        ptr[n] = len;
        idx.truncate(len);
        Rings { ptr, idx }
    }

    fn ring(&self, i: usize) -> &[u32] {
        &self.idx[self.ptr[i]..self.ptr[i + 1]]
    }
}

/// Jacobi-preconditioned conjugate gradients on the free unknowns, from the initial guess in `xf`.
fn conjugate_gradients(
    m: usize,
    mat_vec: &dyn Fn(&[f64], &mut [f64]),
    precond: &dyn Fn(&[f64], &mut [f64]),
    b: &[f64],
    xf: &mut [f64],
) {
    let mut r = vec![0.0; m];
    mat_vec(xf, &mut r);
    for i in 0..m {
        r[i] = b[i] - r[i];
    }
    let mut z = vec![0.0; m];
    precond(&r, &mut z);
    let mut p = z.clone();
    let mut rz: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
    let bnorm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut ap = vec![0.0; m];
    if bnorm > 0.0 {
        for _ in 0..(4 * m).max(200) {
            mat_vec(&p, &mut ap);
            let pap: f64 = p.iter().zip(&ap).map(|(a, b)| a * b).sum();
            if pap.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                break;
            }
            let alpha = rz / pap;
            for i in 0..m {
                xf[i] += alpha * p[i];
                r[i] -= alpha * ap[i];
            }
            let rn = r.iter().map(|v| v * v).sum::<f64>().sqrt();
            if rn <= 1e-6 * bnorm {
                break;
            }
            precond(&r, &mut z);
            let rz_new: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..m {
                p[i] = z[i] + beta * p[i];
            }
        }
    }
}

/// Solves N_ff x_f = b by sparse Cholesky (faer, AMD ordering by `symbolic`, sequential); `None` if it breaks
/// down.
fn direct_solve(
    m: usize,
    row_ptr: &[usize],
    cols: &[u32],
    vals: &[f64],
    fixed: &[Option<f64>],
    b: &[f64],
    symbolic: impl FnOnce(SymbolicSparseColMatRef<'_, usize>) -> Option<Arc<SymbolicCholesky<usize>>>,
) -> Option<Vec<f64>> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::sparse::linalg::cholesky::LltRef;
    use faer::sparse::SparseColMatRef;
    use faer::{Conj, Mat, Par};
    let mut free = vec![usize::MAX; m];
    let mut nf = 0;
    for i in 0..m {
        if fixed[i].is_none() {
            free[i] = nf;
            nf += 1;
        }
    }
    // Lower triangle in CSC: column c of the symmetric matrix is row c of the CSR; keep rows >= c (sorted,
    // since each CSR row lists the u block then the v block, both sorted).
    let mut col_ptr = Vec::with_capacity(nf + 1);
    let mut row_idx: Vec<usize> = Vec::with_capacity(vals.len() / 2);
    let mut values: Vec<f64> = Vec::with_capacity(vals.len() / 2);
    col_ptr.push(0);
    for i in 0..m {
        let c = free[i];
        if c == usize::MAX {
            continue;
        }
        for k in row_ptr[i]..row_ptr[i + 1] {
            let r = free[cols[k] as usize];
            if r != usize::MAX && r >= c {
                row_idx.push(r);
                values.push(vals[k]);
            }
        }
        col_ptr.push(row_idx.len());
    }
    let sym = SymbolicSparseColMatRef::new_checked(nf, nf, &col_ptr, None, &row_idx);
    let symbolic = symbolic(sym)?;
    let mut buf = MemBuffer::try_new(
        symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
    )
    .ok()?;
    let mut l_values = vec![0.0f64; symbolic.len_val()];
    symbolic
        .factorize_numeric_llt::<f64>(
            &mut l_values,
            SparseColMatRef::new(sym, &values),
            Side::Lower,
            Default::default(),
            Par::Seq,
            MemStack::new(&mut buf),
            Default::default(),
        )
        .ok()?;
    let mut rhs = Mat::<f64>::zeros(nf, 1);
    for i in 0..m {
        if free[i] != usize::MAX {
            rhs[(free[i], 0)] = b[i];
        }
    }
    let llt = LltRef::<usize, f64>::new(&symbolic, &l_values);
    let mut sbuf = MemBuffer::try_new(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq)).ok()?;
    llt.solve_in_place_with_conj(Conj::No, rhs.as_mut(), Par::Seq, MemStack::new(&mut sbuf));
    let mut x = vec![0.0; m];
    for i in 0..m {
        if free[i] != usize::MAX {
            x[i] = rhs[(free[i], 0)];
            if !x[i].is_finite() {
                return None;
            }
        }
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The flat rings are the per-vertex sets of the triangles' vertices, sorted.
    #[test]
    fn rings_are_the_sorted_closed_one_rings() {
        let (topo, _) = crate::synth::sheet(7, 5, 0.1).unwrap();
        // A patch in scrambled local numbering, with a vertex no triangle uses.
        let n = topo.n_vertices() + 1;
        let tris: Vec<[u32; 3]> = topo
            .triangles()
            .iter()
            .map(|t| t.map(|v| (v * 11 + 3) % n as u32))
            .collect();
        let rings = Rings::new(n, &tris);
        for i in 0..n {
            let mut want: Vec<u32> = tris
                .iter()
                .filter(|t| t.contains(&(i as u32)))
                .flatten()
                .copied()
                .collect();
            want.sort_unstable();
            want.dedup();
            assert_eq!(rings.ring(i), &want[..], "vertex {i}");
        }
    }

    /// A cached symbolic factorisation gives the flattening bit for bit, for the same patch and for another
    /// patch with the same pattern; another pattern is not served from the cache.
    #[test]
    fn cached_factorisations_flatten_bit_for_bit() {
        let (topo, flat) = crate::synth::sheet(9, 7, 0.1).unwrap();
        let bent: Vec<V3> = flat
            .iter()
            .map(|p| [p[0], p[1], 0.3 * (p[0] * 4.0).sin() * p[1]])
            .collect();
        let cache = SymbolicCache::new(4);
        let bits = |uv: Option<Vec<[f64; 2]>>| -> Vec<u64> {
            uv.unwrap()
                .iter()
                .flat_map(|q| [q[0].to_bits(), q[1].to_bits()])
                .collect()
        };
        let tris = topo.triangles();
        for p in [&flat, &bent, &bent] {
            assert_eq!(
                bits(lscm_with(p, tris, (0, 8), Some(&cache))),
                bits(lscm(p, tris, (0, 8)))
            );
        }
        assert_eq!(cache.stats(), (2, 1));
        assert_eq!(
            bits(lscm_with(&bent, tris, (0, 62), Some(&cache))),
            bits(lscm(&bent, tris, (0, 62)))
        );
        assert_eq!(cache.stats(), (2, 2));
    }

    #[test]
    fn developable_patch_is_flattened_isometrically() {
        // A sheet rolled onto a cylinder is developable: LSCM must recover the flat grid up to a similarity.
        let (topo, flat) = crate::synth::sheet(9, 7, 0.1).unwrap();
        let rolled: Vec<V3> = flat
            .iter()
            .map(|p| {
                let th = p[0] / 0.5;
                [0.5 * th.sin(), p[1], 0.5 * (1.0 - th.cos())]
            })
            .collect();
        let uv = lscm(&rolled, topo.triangles(), (0, 8)).unwrap();
        for (i, j) in [(0usize, 62usize), (3, 40), (10, 11), (5, 50)] {
            let d2 = ((uv[i][0] - uv[j][0]).powi(2) + (uv[i][1] - uv[j][1]).powi(2)).sqrt();
            let df = vec3::norm(vec3::sub(flat[i], flat[j]));
            // Chords of the rolled grid are 0.17% shorter than the flat edges (2R sin(θ/2) vs Rθ).
            assert!(
                (d2 - df).abs() < 4e-3 * df.max(0.1),
                "{i}-{j}: {d2} vs {df}"
            );
        }
        // Orientation kept: every triangle has positive area in the plane.
        for t in topo.triangles() {
            let (a, b, c) = (uv[t[0] as usize], uv[t[1] as usize], uv[t[2] as usize]);
            assert!((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]) > 0.0);
        }
    }
}
