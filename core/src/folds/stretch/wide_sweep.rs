//! The smoothing's Jacobi sweeps ([`super::smooth`]) four triangles at a time with AVX2, bit for bit the scalar
//! sweeps.
//!
//! **Why by hand.** The sweeps are a quarter of the stretch detector's time: per triangle and sweep, four
//! doubled angles (two divisions each), a half-angle direction (three square roots, one division), the means
//! (two divisions) and the next sweep's anisotropy (one division, one `ln`). Written per triangle, the compiler
//! vectorises none of it across triangles (the branches per neighbour and the gathers of the neighbours' shares
//! stop it; an SoA rewrite in plain Rust compiled with AVX2 enabled still came out scalar), and scalar divisions
//! and square roots are the cost. Here four triangles share every instruction.
//!
//! **Why the same bits.** Every number is computed with the scalar code's operations in the scalar code's order:
//! additions, multiplications, divisions and square roots are correctly rounded in either form, the `ln` is the
//! same library call per lane, and no multiply-add is fused. Branches become masks: a neighbour that the scalar
//! code skips (no data, or missing) adds +0.0 to each running sum, which leaves it unchanged because the sums
//! start at +0.0 and a rounded sum is −0.0 only when both terms are; a division whose result the scalar code
//! would not compute is made anyway and discarded by the mask. `f64::max`, `clamp` and the negation keep their
//! NaN and sign rules (`vmaxpd` returns its second operand for a NaN, as `max` returns the number). The test
//! `wide_sweeps_are_the_scalar_sweeps` holds the two to the same bits.
//!
//! **Layout.** A triangle's share is one 64-byte row (weight, weighted Γ and γ, direction weight, Γ direction,
//! has-data flag), so a neighbour costs two aligned loads, and four rows are transposed into eight field vectors
//! (and back for the next sweep). A block holds four consecutive triangles' local frames and areas lane by lane
//! and their neighbourhoods (itself first, then the three edge neighbours as the topology lists them; a missing
//! neighbour points at an empty row past the last triangle).

use super::tensor::Tensor;
use crate::mesh::NONE;
use crate::vec3::V3;

/// Triangles per block (one AVX2 vector of doubles).
pub(super) const LANES: usize = 4;

/// One triangle's share of a sweep: weight (area, 0 for no data), area × Γ, area × γ, area × anisotropy, the Γ
/// direction, and 1 when the triangle has data (0 otherwise): what [`super::smooth`]'s `Share` holds.
#[derive(Clone, Copy, Default)]
#[repr(C, align(64))]
pub(super) struct Row(pub(super) [f64; 8]);

/// Four consecutive triangles lane by lane: local frames, areas, and neighbourhoods as row indices.
#[derive(Clone, Copy, Default)]
#[repr(C, align(32))]
pub(super) struct Block {
    e1: [[f64; LANES]; 3],
    e2: [[f64; LANES]; 3],
    area: [f64; LANES],
    nbr: [[u32; LANES]; 4],
}

/// Rows kept for `n` triangles: whole blocks, and always at least one empty row past the last triangle (the
/// missing neighbour's).
pub(super) fn rows_for(n: usize) -> usize {
    (n + 1).div_ceil(LANES) * LANES
}

/// The share row of a triangle's tensor `t` (or of no data), as `Share::of` computes it.
#[inline]
pub(super) fn row_of(t: Option<Tensor>, area: f64) -> Row {
    match t {
        Some(t) => {
            let aniso = (t.big / t.small.max(1e-12)).ln().max(0.0);
            Row([
                area,
                area * t.big,
                area * t.small,
                area * aniso,
                t.dir_big[0],
                t.dir_big[1],
                t.dir_big[2],
                1.0,
            ])
        }
        None => Row::default(),
    }
}

/// The blocks of a mesh, built once per smoothing: every neighbour index is at most `n` (the empty row).
#[derive(Default)]
pub(super) struct Blocks {
    v: Vec<Block>,
    n: usize,
}

impl Blocks {
    /// Rebuilds the blocks for a mesh of `adj.len()` triangles with edge adjacency `adj` and per-triangle frames
    /// and areas, in parallel, reusing the allocation. Lanes past the last triangle have only empty neighbours
    /// and a zero frame, so they sweep to empty rows.
    pub(super) fn build(&mut self, adj: &[[u32; 3]], e1: &[V3], e2: &[V3], areas: &[f64]) {
        use rayon::prelude::*;
        let n = adj.len();
        assert!(
            e1.len() == n && e2.len() == n && areas.len() == n && n < u32::MAX as usize,
            "frames and areas must have one entry per triangle"
        );
        let empty = n as u32;
        self.n = n;
        self.v.resize(n.div_ceil(LANES), Block::default());
        self.v
            .par_iter_mut()
            .with_min_len(256)
            .enumerate()
            .for_each(|(b, fb)| {
                *fb = Block::default();
                for l in 0..LANES {
                    let i = b * LANES + l;
                    if i >= n {
                        for nb in &mut fb.nbr {
                            nb[l] = empty;
                        }
                        continue;
                    }
                    fb.nbr[0][l] = i as u32;
                    for k in 0..3 {
                        let j = adj[i][k];
                        // The kernels load row j unchecked: an index past the mesh would be a topology bug.
                        assert!(
                            j == NONE || (j as usize) < n,
                            "triangle {i}: neighbour {j} out of range"
                        );
                        fb.nbr[k + 1][l] = if j == NONE { empty } else { j };
                        fb.e1[k][l] = e1[i][k];
                        fb.e2[k][l] = e2[i][k];
                    }
                    fb.area[l] = areas[i];
                }
            });
    }

    /// Number of blocks.
    pub(super) fn len(&self) -> usize {
        self.v.len()
    }

    /// One sweep over the blocks `range`, reading the previous sweep's `rows` (all of them: neighbours may lie in
    /// any block) and writing the range's rows for the next sweep to `out` (`LANES` rows per block).
    ///
    /// Panics unless [`available`] says the CPU can (callers check it).
    pub(super) fn sweep(&self, range: std::ops::Range<usize>, rows: &[Row], out: &mut [Row]) {
        let blocks = &self.v[range];
        assert!(rows.len() > self.n, "too few rows");
        assert!(out.len() >= blocks.len() * LANES, "too few output rows");
        #[cfg(target_arch = "x86_64")]
        if detected() {
            // SAFETY: the CPU has AVX2 (just checked), every neighbour index is at most `n` (`build`), below
            // `rows.len()`, and `out` holds `LANES` rows per block (both asserted above).
            unsafe { avx2::sweep(rows, blocks, out) };
            return;
        }
        unreachable!("the wide sweeps need AVX2");
    }

    /// The last sweep over the blocks `range`: the smoothed tensors of their triangles into `out` (one per
    /// triangle, at most `LANES` per block; a triangle with no data around gets Γ = γ = 1 along its first edge).
    pub(super) fn last(&self, range: std::ops::Range<usize>, rows: &[Row], out: &mut [Tensor]) {
        let blocks = &self.v[range];
        assert!(rows.len() > self.n, "too few rows");
        assert!(out.len() <= blocks.len() * LANES, "more tensors than lanes");
        #[cfg(target_arch = "x86_64")]
        if detected() {
            // SAFETY: AVX2 present (just checked), neighbour indices at most `n` < `rows.len()` (asserted).
            unsafe { avx2::last(rows, blocks, out) };
            return;
        }
        unreachable!("the wide sweeps need AVX2");
    }
}

/// Whether this CPU runs the AVX2 sweeps (detected once); the scalar sweeps run elsewhere, with the same bits.
pub(super) fn available() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(detected)
}

#[cfg(target_arch = "x86_64")]
fn detected() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

#[cfg(not(target_arch = "x86_64"))]
fn detected() -> bool {
    false
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{Block, Row, Tensor, LANES};
    use std::arch::x86_64::*;

    /// The rows `idx` (one per lane), transposed: eight vectors, one per field.
    ///
    /// # Safety
    /// AVX2, and every `idx` below the length of the rows at `rows`.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn gather(rows: *const Row, idx: &[u32; LANES]) -> [__m256d; 8] {
        let p = |l: usize| rows.add(idx[l] as usize) as *const f64;
        let (r0, r1, r2, r3) = (p(0), p(1), p(2), p(3));
        let mut out = [_mm256_setzero_pd(); 8];
        for h in 0..2 {
            let a = _mm256_load_pd(r0.add(4 * h));
            let b = _mm256_load_pd(r1.add(4 * h));
            let c = _mm256_load_pd(r2.add(4 * h));
            let d = _mm256_load_pd(r3.add(4 * h));
            let t0 = _mm256_unpacklo_pd(a, b); // a0 b0 a2 b2
            let t1 = _mm256_unpackhi_pd(a, b); // a1 b1 a3 b3
            let t2 = _mm256_unpacklo_pd(c, d); // c0 d0 c2 d2
            let t3 = _mm256_unpackhi_pd(c, d); // c1 d1 c3 d3
            out[4 * h] = _mm256_permute2f128_pd(t0, t2, 0x20);
            out[4 * h + 1] = _mm256_permute2f128_pd(t1, t3, 0x20);
            out[4 * h + 2] = _mm256_permute2f128_pd(t0, t2, 0x31);
            out[4 * h + 3] = _mm256_permute2f128_pd(t1, t3, 0x31);
        }
        out
    }

    /// Eight field vectors written back as the four rows at `dst` (the inverse of [`gather`]).
    ///
    /// # Safety
    /// AVX2, and four writable rows at `dst`.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn scatter(dst: *mut Row, f: &[__m256d; 8]) {
        let d = dst as *mut f64;
        for h in 0..2 {
            let (a, b, c, e) = (f[4 * h], f[4 * h + 1], f[4 * h + 2], f[4 * h + 3]);
            let t0 = _mm256_unpacklo_pd(a, b);
            let t1 = _mm256_unpackhi_pd(a, b);
            let t2 = _mm256_unpacklo_pd(c, e);
            let t3 = _mm256_unpackhi_pd(c, e);
            _mm256_store_pd(d.add(4 * h), _mm256_permute2f128_pd(t0, t2, 0x20));
            _mm256_store_pd(d.add(8 + 4 * h), _mm256_permute2f128_pd(t1, t3, 0x20));
            _mm256_store_pd(d.add(16 + 4 * h), _mm256_permute2f128_pd(t0, t2, 0x31));
            _mm256_store_pd(d.add(24 + 4 * h), _mm256_permute2f128_pd(t1, t3, 0x31));
        }
    }

    /// One Jacobi update of a block's four triangles: whether each has data, its mean Γ and γ, its direction.
    struct Updated {
        valid: __m256d,
        big: __m256d,
        small: __m256d,
        dir: [__m256d; 3],
        e1: [__m256d; 3],
    }

    /// `smooth_in`'s `update` on four triangles (same operations, same order; see the module doc).
    ///
    /// # Safety
    /// AVX2, and the block's neighbour indices below the length of the rows at `rows`.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn update(rows: *const Row, fb: &Block) -> Updated {
        let ld = |a: &[f64; LANES]| _mm256_load_pd(a.as_ptr());
        let e1 = [ld(&fb.e1[0]), ld(&fb.e1[1]), ld(&fb.e1[2])];
        let e2 = [ld(&fb.e2[0]), ld(&fb.e2[1]), ld(&fb.e2[2])];
        let zero = _mm256_setzero_pd();
        let one = _mm256_set1_pd(1.0);
        let two = _mm256_set1_pd(2.0);
        let (mut wsum, mut big, mut small, mut c2, mut s2) = (zero, zero, zero, zero, zero);
        let mut own = [zero; 8];
        for (k, idx) in fb.nbr.iter().enumerate() {
            let f = gather(rows, idx);
            if k == 0 {
                own = f;
            }
            // doubled_angle: x = d·e1, y = d·e2, (x² − y²)/r², 2xy/r², or (1, 0) when r² = 0.
            let x = _mm256_add_pd(
                _mm256_add_pd(_mm256_mul_pd(f[4], e1[0]), _mm256_mul_pd(f[5], e1[1])),
                _mm256_mul_pd(f[6], e1[2]),
            );
            let y = _mm256_add_pd(
                _mm256_add_pd(_mm256_mul_pd(f[4], e2[0]), _mm256_mul_pd(f[5], e2[1])),
                _mm256_mul_pd(f[6], e2[2]),
            );
            let (xx, yy) = (_mm256_mul_pd(x, x), _mm256_mul_pd(y, y));
            let r2 = _mm256_add_pd(xx, yy);
            let pos = _mm256_cmp_pd::<_CMP_GT_OQ>(r2, zero);
            let c = _mm256_blendv_pd(one, _mm256_div_pd(_mm256_sub_pd(xx, yy), r2), pos);
            let s = _mm256_and_pd(
                pos,
                _mm256_div_pd(_mm256_mul_pd(_mm256_mul_pd(two, x), y), r2),
            );
            // Only neighbours with weight > 0 count; the others add +0.0.
            let m = _mm256_cmp_pd::<_CMP_GT_OQ>(f[0], zero);
            wsum = _mm256_add_pd(wsum, _mm256_and_pd(m, f[0]));
            big = _mm256_add_pd(big, _mm256_and_pd(m, f[1]));
            small = _mm256_add_pd(small, _mm256_and_pd(m, f[2]));
            c2 = _mm256_add_pd(c2, _mm256_and_pd(m, _mm256_mul_pd(f[3], c)));
            s2 = _mm256_add_pd(s2, _mm256_and_pd(m, _mm256_mul_pd(f[3], s)));
        }
        // !(wsum <= 0): true for NaN, as the scalar test lets NaN through.
        let valid = _mm256_cmp_pd::<_CMP_NLE_UQ>(wsum, zero);
        // half_angle_direction when c2² + s2² > 0, else the triangle's own direction (if it has data) or e1.
        let nn = _mm256_add_pd(_mm256_mul_pd(c2, c2), _mm256_mul_pd(s2, s2));
        let has = _mm256_cmp_pd::<_CMP_GT_OQ>(nn, zero);
        let mut hc = _mm256_div_pd(c2, _mm256_sqrt_pd(nn));
        let minus_one = _mm256_set1_pd(-1.0);
        // clamp(−1, 1) as f64::clamp does it (NaN passes).
        hc = _mm256_blendv_pd(hc, minus_one, _mm256_cmp_pd::<_CMP_LT_OQ>(hc, minus_one));
        hc = _mm256_blendv_pd(hc, one, _mm256_cmp_pd::<_CMP_GT_OQ>(hc, one));
        let half = _mm256_set1_pd(0.5);
        let cos = _mm256_sqrt_pd(_mm256_mul_pd(half, _mm256_add_pd(one, hc)));
        let sin = _mm256_sqrt_pd(_mm256_mul_pd(half, _mm256_sub_pd(one, hc)));
        let negated = _mm256_xor_pd(sin, _mm256_set1_pd(-0.0));
        let sin = _mm256_blendv_pd(sin, negated, _mm256_cmp_pd::<_CMP_LT_OQ>(s2, zero));
        let own_some = _mm256_cmp_pd::<_CMP_GT_OQ>(own[7], zero);
        let mut dir = [zero; 3];
        for k in 0..3 {
            let h = _mm256_add_pd(_mm256_mul_pd(e1[k], cos), _mm256_mul_pd(e2[k], sin));
            let fallback = _mm256_blendv_pd(e1[k], own[4 + k], own_some);
            dir[k] = _mm256_blendv_pd(fallback, h, has);
        }
        Updated {
            valid,
            big: _mm256_div_pd(big, wsum),
            small: _mm256_div_pd(small, wsum),
            dir,
            e1,
        }
    }

    /// See [`super::Blocks::sweep`].
    ///
    /// # Safety
    /// AVX2, neighbour indices below `rows.len()`, `LANES` rows of `out` per block.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sweep(rows: &[Row], blocks: &[Block], out: &mut [Row]) {
        let src = rows.as_ptr();
        let dst = out.as_mut_ptr();
        for (b, fb) in blocks.iter().enumerate() {
            let u = update(src, fb);
            // Share::of: anisotropy ln(Γ / max(γ, 1e-12)), at least 0, one library `ln` per lane.
            let ratio = _mm256_div_pd(u.big, _mm256_max_pd(u.small, _mm256_set1_pd(1e-12)));
            let mut r = [0.0; LANES];
            _mm256_storeu_pd(r.as_mut_ptr(), ratio);
            for x in &mut r {
                *x = x.ln().max(0.0);
            }
            let aniso = _mm256_loadu_pd(r.as_ptr());
            let area = _mm256_load_pd(fb.area.as_ptr());
            let v = u.valid;
            let f = [
                _mm256_and_pd(v, area),
                _mm256_and_pd(v, _mm256_mul_pd(area, u.big)),
                _mm256_and_pd(v, _mm256_mul_pd(area, u.small)),
                _mm256_and_pd(v, _mm256_mul_pd(area, aniso)),
                _mm256_and_pd(v, u.dir[0]),
                _mm256_and_pd(v, u.dir[1]),
                _mm256_and_pd(v, u.dir[2]),
                _mm256_and_pd(v, _mm256_set1_pd(1.0)),
            ];
            scatter(dst.add(b * LANES), &f);
        }
    }

    /// See [`super::Blocks::last`].
    ///
    /// # Safety
    /// AVX2, neighbour indices below `rows.len()`.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn last(rows: &[Row], blocks: &[Block], out: &mut [Tensor]) {
        let src = rows.as_ptr();
        let one = _mm256_set1_pd(1.0);
        for (fb, chunk) in blocks.iter().zip(out.chunks_mut(LANES)) {
            let u = update(src, fb);
            let mut a = [[0.0; LANES]; 5];
            _mm256_storeu_pd(a[0].as_mut_ptr(), _mm256_blendv_pd(one, u.big, u.valid));
            _mm256_storeu_pd(a[1].as_mut_ptr(), _mm256_blendv_pd(one, u.small, u.valid));
            for k in 0..3 {
                let d = _mm256_blendv_pd(u.e1[k], u.dir[k], u.valid);
                _mm256_storeu_pd(a[2 + k].as_mut_ptr(), d);
            }
            for (l, t) in chunk.iter_mut().enumerate() {
                *t = Tensor {
                    big: a[0][l],
                    small: a[1][l],
                    dir_big: [a[2][l], a[3][l], a[4][l]],
                };
            }
        }
    }
}
