//! Same-process A/B of the positioning system's kernels at paper scale (100K triangles by default): the
//! numeric Cholesky factorisation under a few supernode-relaxation settings, and the 3-RHS triangular solves —
//! faer's general solve, the previous column-by-column interleaved sweep (kept here as the "before"), and
//! [`factor_solve::solve3_supernodal`]. Alternates the contenders run by run so that machine load hits all
//! of them alike; prints min / median seconds of thread CPU time and the largest difference to faer's solution.
//!
//! `cargo run --release -p crease-research --example position_solve_ab -- [triangles] [runs]`

use crease_core::spacetime::position::factor_solve;
use crease_core::spacetime::position::PositionSystem;
use crease_core::spacetime::DeformParams;
use crease_core::synth::{self, DemoSpec};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::SymbolicSupernodalParams;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Mat, MatMut, Par, Side};

/// faer's supernode relaxation table: (supernode size, allowed fill fraction) pairs.
type Relaxation<'a> = &'a [(usize, f64)];

/// This thread's CPU time in seconds (CLOCK_THREAD_CPUTIME_ID): on a loaded machine, time slices given to
/// other processes are not counted, which wall time would add at random.
fn cpu_now() -> f64 {
    #[repr(C)]
    struct Timespec {
        sec: i64,
        nsec: i64,
    }
    extern "C" {
        fn clock_gettime(clock: i32, ts: *mut Timespec) -> i32;
    }
    let mut ts = Timespec { sec: 0, nsec: 0 };
    // SAFETY: clock_gettime writes one timespec into the valid, exclusively borrowed `ts`.
    let rc = unsafe { clock_gettime(3, &mut ts) };
    assert_eq!(rc, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID)");
    ts.sec as f64 + ts.nsec as f64 * 1e-9
}

struct Clock(f64);
impl Clock {
    fn start() -> Self {
        Clock(cpu_now())
    }
    fn secs(&self) -> f64 {
        cpu_now() - self.0
    }
}

fn stats(mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[0], v[v.len() / 2])
}

fn main() -> crease_core::Result<()> {
    let arg = |i: usize, d: usize| {
        std::env::args()
            .nth(i)
            .and_then(|s| s.parse().ok())
            .unwrap_or(d)
    };
    let (size, runs) = (arg(1, 100_000), arg(2, 11));
    let (seq, _) = synth::demo(&DemoSpec {
        triangles: size,
        frames: 1,
        ..Default::default()
    })?;
    let params = DeformParams::default();
    let edge = crease_core::shape::mean_edge_length(&seq.topology, &seq.frames[0]);
    let sys = PositionSystem::new(
        seq.topology.clone(),
        params.pinning,
        params.scales(edge).screen,
    )?;
    let (vals, _, _, _) = sys.assemble(&seq.frames[0])?;
    let (cp, ri) = sys.pattern();
    let n = cp.len() - 1;
    let pattern = SymbolicSparseColMatRef::new_checked(n, n, cp, None, ri);
    let relaxations: [(&str, Option<Relaxation>); 4] = [
        ("faer default", None),
        ("none", Some(&[])),
        (
            "<=8 any, <=32 50%",
            Some(&[(8, 1.0), (32, 0.5), (usize::MAX, 0.05)]),
        ),
        (
            "<=16 any, <=64 30%",
            Some(&[(16, 1.0), (64, 0.3), (usize::MAX, 0.05)]),
        ),
    ];
    let b = Mat::<f64>::from_fn(n, 3, |i, j| ((i * 7 + j * 13) % 17) as f64 - 8.0);
    println!("{size} triangles: positioning system of {n} unknowns; {runs} runs, alternating");
    for (name, relax) in relaxations {
        let mut sp = SymbolicSupernodalParams::default();
        if let Some(r) = relax {
            sp.relax = Some(r);
        }
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Lower,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams {
                supernodal_params: sp,
                ..Default::default()
            },
        )
        .expect("symbolic");
        let SymbolicCholeskyRaw::Supernodal(snr) = symbolic.raw() else {
            println!("{name}: simplicial");
            continue;
        };
        let widths: Vec<usize> = (0..snr.n_supernodes())
            .map(|s| snr.supernode_end()[s] - snr.supernode_begin()[s])
            .collect();
        let hist = [1, 2, 3, 4]
            .map(|w| widths.iter().filter(|&&x| x == w).count())
            .to_vec();
        let wide = widths.iter().filter(|&&x| x > 4).count();
        let mut l = vec![0.0; symbolic.len_val()];
        let mut buf = MemBuffer::new(
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        );
        let mut t_factor = Vec::new();
        for _ in 0..runs.min(5) {
            let t = Clock::start();
            symbolic
                .factorize_numeric_llt::<f64>(
                    &mut l,
                    SparseColMatRef::new(pattern, &vals),
                    Side::Lower,
                    Default::default(),
                    Par::Seq,
                    MemStack::new(&mut buf),
                    Default::default(),
                )
                .expect("numeric");
            t_factor.push(t.secs());
        }
        let (mut t_faer, mut t_old, mut t_new) = (Vec::new(), Vec::new(), Vec::new());
        let mut faer_x = b.clone();
        let mut worst = [0.0f64; 2];
        for _ in 0..runs {
            let mut x = b.clone();
            let t = Clock::start();
            let mut sbuf = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(3, Par::Seq));
            LltRef::<usize, f64>::new(&symbolic, &l).solve_in_place_with_conj(
                Conj::No,
                x.as_mut(),
                Par::Seq,
                MemStack::new(&mut sbuf),
            );
            t_faer.push(t.secs());
            faer_x = x;
            let mut x = b.clone();
            let t = Clock::start();
            old_solve3(&symbolic, &l, &mut x);
            t_old.push(t.secs());
            worst[0] = worst[0].max(max_diff(&x, &faer_x));
            let mut x = b.clone();
            let t = Clock::start();
            assert!(factor_solve::solve3_supernodal(&symbolic, &l, &mut x));
            t_new.push(t.secs());
            worst[1] = worst[1].max(max_diff(&x, &faer_x));
        }
        let scale = max_diff(&faer_x, &Mat::zeros(n, 3));
        let (f, o, nw, fa) = (stats(t_factor), stats(t_old), stats(t_new), stats(t_faer));
        println!(
            "relax {name}: {} supernodes (widths 1-4: {hist:?}, wider: {wide}), L nnz {}",
            widths.len(),
            symbolic.len_val()
        );
        println!(
            "  factor {:.5} / {:.5}   solve faer {:.5} / {:.5}   previous sweep {:.5} / {:.5}   new {:.5} / {:.5}  (min / median s)",
            f.0, f.1, fa.0, fa.1, o.0, o.1, nw.0, nw.1
        );
        println!(
            "  max |x - faer| / max |faer|: previous {:.1e}, new {:.1e}",
            worst[0] / scale,
            worst[1] / scale
        );
    }
    Ok(())
}

fn max_diff(a: &Mat<f64>, b: &Mat<f64>) -> f64 {
    let mut w = 0.0f64;
    for j in 0..a.ncols() {
        for i in 0..a.nrows() {
            w = w.max((a[(i, j)] - b[(i, j)]).abs());
        }
    }
    w
}

/// The column-by-column interleaved sweep that preceded the grouped row sweep (one update of each pattern row per
/// supernode column), kept as the "before" of this A/B.
fn old_solve3(symbolic: &SymbolicCholesky<usize>, l_values: &[f64], rhs: &mut Mat<f64>) -> bool {
    let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
        return false;
    };
    let n = sn.nrows();
    if rhs.nrows() != n || rhs.ncols() != 3 || l_values.len() != sn.len_val() {
        return false;
    }
    // Permute into row-interleaved storage: x[i] = rhs[fwd[i]].
    let mut x: Vec<[f64; 3]> = match symbolic.perm() {
        Some(p) => p
            .arrays()
            .0
            .iter()
            .map(|&f| [rhs[(f, 0)], rhs[(f, 1)], rhs[(f, 2)]])
            .collect(),
        None => (0..n)
            .map(|i| [rhs[(i, 0)], rhs[(i, 1)], rhs[(i, 2)]])
            .collect(),
    };
    let begin = sn.supernode_begin();
    let end = sn.supernode_end();
    let val_ptr = sn.col_ptr_for_val();
    let row_ptr = sn.col_ptr_for_row_idx();
    let rows = sn.row_idx();
    let ns = sn.n_supernodes();
    // Supernode s: columns start..end, a dense column-major block of (size + |pattern|) rows; the first `size`
    // rows are the lower-triangular diagonal block, the rest the rows listed in `pattern`.
    let block = |s: usize| {
        let (start, size) = (begin[s], end[s] - begin[s]);
        let vals = &l_values[val_ptr[s]..val_ptr[s + 1]];
        let m = vals.len() / size - size;
        let pattern = &rows[row_ptr[s]..row_ptr[s] + m];
        (start, size, vals, pattern)
    };
    // Forward: L y = b.
    for s in 0..ns {
        let (start, size, vals, pattern) = block(s);
        let ld = size + pattern.len();
        for c in 0..size {
            let col = &vals[c * ld..(c + 1) * ld];
            let d = col[c];
            let yc = x[start + c];
            let yc = [yc[0] / d, yc[1] / d, yc[2] / d];
            x[start + c] = yc;
            for r in c + 1..size {
                let l = col[r];
                let xr = &mut x[start + r];
                xr[0] -= l * yc[0];
                xr[1] -= l * yc[1];
                xr[2] -= l * yc[2];
            }
            for (k, &i) in pattern.iter().enumerate() {
                let l = col[size + k];
                let xi = &mut x[i];
                xi[0] -= l * yc[0];
                xi[1] -= l * yc[1];
                xi[2] -= l * yc[2];
            }
        }
    }
    // Backward: Lᵀ x = y.
    for s in (0..ns).rev() {
        let (start, size, vals, pattern) = block(s);
        let ld = size + pattern.len();
        for c in (0..size).rev() {
            let col = &vals[c * ld..(c + 1) * ld];
            let mut acc = x[start + c];
            for r in c + 1..size {
                let l = col[r];
                let xr = x[start + r];
                acc[0] -= l * xr[0];
                acc[1] -= l * xr[1];
                acc[2] -= l * xr[2];
            }
            for (k, &i) in pattern.iter().enumerate() {
                let l = col[size + k];
                let xi = x[i];
                acc[0] -= l * xi[0];
                acc[1] -= l * xi[1];
                acc[2] -= l * xi[2];
            }
            let d = col[c];
            x[start + c] = [acc[0] / d, acc[1] / d, acc[2] / d];
        }
    }
    // Back to the original ordering: rhs[i] = x[inv[i]].
    let mut out: MatMut<'_, f64> = rhs.as_mut();
    match symbolic.perm() {
        Some(p) => {
            for (i, &v) in p.arrays().1.iter().enumerate() {
                for c in 0..3 {
                    out[(i, c)] = x[v][c];
                }
            }
        }
        None => {
            for (i, xi) in x.iter().enumerate() {
                for c in 0..3 {
                    out[(i, c)] = xi[c];
                }
            }
        }
    }
    true
}
