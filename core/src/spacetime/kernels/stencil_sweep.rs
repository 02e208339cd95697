//! The capture stencil's fused sweeps ([`crate::spacetime::shape::deconvolve::CaptureStencil::detail_and_low_pass`]) one vertex's
//! six values at a time with AVX2, bit for bit the scalar sweep.
//!
//! **Why by hand.** The shape projection and the fold restoration spend most of the last stretch pass in
//! these ~90 sweeps, and per vertex a sweep is a sum of its neighbours' six values. Compiled for the baseline
//! x86-64 target, each neighbour costs a bounds check, four loads and four scalar or two-wide additions, and
//! the sweep is bound by the instructions it issues (the field of a 100K-triangle frame is 2.4 MB, in cache).
//! Here a neighbour is one four-wide and one two-wide addition straight from memory at a precomputed byte
//! offset, and the common six-neighbour vertex runs without a loop: about half the instructions per vertex
//! (callgrind, `wide_sweeps_are_the_scalar_sweeps`' mesh and the bench's).
//!
//! **Why the same bits.** Every lane computes what the scalar code computes for that value, with the same
//! operations in the same order: the neighbour sums start at +0.0 and add the neighbours in list order, the
//! mean multiplies by the same reciprocal, the filter step is x + (mean − x) f, the series term 2 mean −
//! T_{j−1} and the series sum acc + T a, each a correctly rounded IEEE operation in either form, none fused
//! into a multiply-add. The lanes the scalar code does not compute (the filter step's fourth lane, the
//! series' first three) are computed anyway and discarded by a blend. `deconvolve`'s tests hold the two to the
//! same bits (`wide_sweeps_are_the_scalar_sweeps`, and `fused_sweeps_are_the_separate_ones_bit_for_bit`,
//! which compares whichever sweep the CPU runs with the separate evaluations).

/// What a sweep computes besides the neighbour means: the filter step (λ or μ; `None` past the filter's
/// steps, where the filter iterate is carried over) and the series term (its weight; `None` past the
/// series, where the series iterate is carried over); `first` for the sweep that makes T_1 = A T_0.
#[derive(Clone, Copy, Debug)]
pub(in crate::spacetime) struct Sweep {
    pub filter: Option<f64>,
    pub term: Option<f64>,
    pub first: bool,
}

/// Whether this CPU runs the AVX2 sweep (detected once); the scalar sweep runs elsewhere, with the same bits.
pub(in crate::spacetime) fn available() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(detected)
}

#[cfg(target_arch = "x86_64")]
pub(in crate::spacetime) fn detected() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

#[cfg(not(target_arch = "x86_64"))]
pub(in crate::spacetime) fn detected() -> bool {
    false
}

/// Bytes of one vertex's slot in the swept field ([f64; 6]).
pub(in crate::spacetime) const SLOT_BYTES: usize = 48;

#[cfg(target_arch = "x86_64")]
pub(in crate::spacetime) mod avx2 {
    use super::Sweep;
    use crate::vec3::V3;
    use std::arch::x86_64::*;

    /// The six values of the slot `byte` bytes into the field at `base`, added to the running sums.
    ///
    /// # Safety
    /// AVX2, and a whole slot at `base + byte`.
    #[inline(always)]
    unsafe fn add_slot(base: *const u8, byte: u32, lo: &mut __m256d, hi: &mut __m128d) {
        let q = base.add(byte as usize) as *const f64;
        *lo = _mm256_add_pd(*lo, _mm256_loadu_pd(q));
        *hi = _mm_add_pd(*hi, _mm_loadu_pd(q.add(4)));
    }

    /// The sweep over the vertices `first_vertex ..` `first_vertex + out.len()`: reads `src` (every vertex:
    /// neighbours may be anywhere), writes each vertex's next [filter iterate | series iterate] over its
    /// previous-but-one in `out`, and adds the series term to `acc` (the scalar
    /// `CaptureStencil::sweep_vertex`, vertex by vertex). Vertex v's neighbours are the slots at the byte
    /// offsets `bytes[offsets[v] .. offsets[v + 1]]` of `src`.
    ///
    /// # Safety
    /// AVX2 present; `offsets` and `inv_count` cover the swept vertices (`offsets` one past them), the
    /// offsets index `bytes`, and every byte offset there is that of a slot of `src`; `acc.len() ==
    /// out.len()`.
    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx2")]
    pub(in crate::spacetime) unsafe fn sweep(
        offsets: &[u32],
        bytes: &[u32],
        inv_count: &[f64],
        src: &[[f64; 6]],
        first_vertex: usize,
        out: &mut [[f64; 6]],
        acc: &mut [V3],
        s: Sweep,
    ) {
        let sp = src.as_ptr() as *const f64;
        let sb = src.as_ptr() as *const u8;
        let two = _mm256_set1_pd(2.0);
        let factor = _mm256_set1_pd(s.filter.unwrap_or(0.0));
        let weight = _mm_set1_pd(s.term.unwrap_or(0.0));
        for (k, (ov, av)) in out.iter_mut().zip(acc.iter_mut()).enumerate() {
            let v = first_vertex + k;
            let me = sp.add(6 * v);
            let (me_lo, me_hi) = (_mm256_loadu_pd(me), _mm_loadu_pd(me.add(4)));
            let nb = bytes.get_unchecked(
                *offsets.get_unchecked(v) as usize..*offsets.get_unchecked(v + 1) as usize,
            );
            // Neighbour means (lanes 0–2: the filter iterate's, 3–5: the series iterate's), summed from +0.0
            // in list order, and the filter step x + (mean − x) f; a vertex without neighbours keeps its
            // values.
            let (mean_lo, mean_hi, x_lo) = if nb.is_empty() {
                (me_lo, me_hi, me_lo)
            } else {
                let (mut lo, mut hi) = (_mm256_setzero_pd(), _mm_setzero_pd());
                if let Ok(six) = <&[u32; 6]>::try_from(nb) {
                    for &b in six {
                        add_slot(sb, b, &mut lo, &mut hi);
                    }
                } else {
                    for &b in nb {
                        add_slot(sb, b, &mut lo, &mut hi);
                    }
                }
                let inv = _mm256_set1_pd(*inv_count.get_unchecked(v));
                let mean_lo = _mm256_mul_pd(lo, inv);
                let mean_hi = _mm_mul_pd(hi, _mm256_castpd256_pd128(inv));
                let x_lo = if s.filter.is_some() {
                    _mm256_add_pd(me_lo, _mm256_mul_pd(_mm256_sub_pd(mean_lo, me_lo), factor))
                } else {
                    me_lo
                };
                (mean_lo, mean_hi, x_lo)
            };
            let op = ov.as_mut_ptr();
            // The series iterate: T_1 = mean, T_{j+1} = 2 mean − T_{j−1} (the latter in `out` at this vertex).
            let (t_lo, t_hi) = match s.term {
                Some(_) if s.first => (mean_lo, mean_hi),
                Some(_) => (
                    _mm256_sub_pd(_mm256_mul_pd(mean_lo, two), _mm256_loadu_pd(op)),
                    _mm_sub_pd(
                        _mm_mul_pd(mean_hi, _mm256_castpd256_pd128(two)),
                        _mm_loadu_pd(op.add(4)),
                    ),
                ),
                None => (me_lo, me_hi),
            };
            _mm256_storeu_pd(op, _mm256_blend_pd::<0b1000>(x_lo, t_lo));
            _mm_storeu_pd(op.add(4), t_hi);
            if s.term.is_some() {
                // acc + T a, T's first component from lane 3.
                let upper = _mm256_extractf128_pd::<1>(t_lo);
                let ap = av.as_mut_ptr();
                let t0 = _mm_unpackhi_pd(upper, upper);
                _mm_store_sd(ap, _mm_add_sd(_mm_load_sd(ap), _mm_mul_sd(t0, weight)));
                _mm_storeu_pd(
                    ap.add(1),
                    _mm_add_pd(_mm_loadu_pd(ap.add(1)), _mm_mul_pd(t_hi, weight)),
                );
            }
        }
    }
}
