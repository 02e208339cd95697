#!/usr/bin/env python3
"""Reference solvers on crease's own matrices, timed in the same run.

Reads what `crease bench --export DIR` wrote (the first time window's space-time weight matrix and right-hand
sides, frame 0's positioning matrix and right-hand side, and crease's timings of exactly those solves in
ours.json) and solves the same systems with SciPy:

* weights, fused: SciPy CG (Jacobi preconditioner, rtol = crease's tolerance) on the 3 right-hand sides;
* weights, per anchor: SciPy CG on single anchor columns c_a e_a (a sample), per column;
* positioning: SciPy SuperLU (splu) factorisation of the stiffness matrix + the 3-RHS solve.

Prints the times and ratios crease / SciPy (below 1 means crease is faster).
"""
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import scipy
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def timed(f, repeats):
    times = []
    out = None
    for _ in range(repeats):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def cg(a, b, m, tol):
    try:
        return spla.cg(a, b, rtol=tol, M=m, maxiter=10000)
    except TypeError:  # SciPy < 1.12 calls it `tol`
        return spla.cg(a, b, tol=tol, M=m, maxiter=10000)


def main():
    d = Path(sys.argv[1] if len(sys.argv) > 1 else "bench-out/export")
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    ours = json.loads((d / "ours.json").read_text())
    tol = ours["cg_tolerance"]

    indptr = np.load(d / "weights_indptr.npy")
    indices = np.load(d / "weights_indices.npy")
    data = np.load(d / "weights_data.npy")
    n = len(indptr) - 1
    m = sp.csr_matrix((data, indices.astype(np.int64), indptr.astype(np.int64)), shape=(n, n))
    rhs = np.load(d / "weights_rhs.npy")
    jacobi = sp.diags(1.0 / m.diagonal())

    def fused():
        return [cg(m, rhs[:, c], jacobi, tol)[0] if np.any(rhs[:, c]) else np.zeros(n) for c in range(3)]

    t_fused, cols = timed(fused, repeats)
    res = max(
        np.linalg.norm(m @ x - rhs[:, c]) / max(np.linalg.norm(rhs[:, c]), 1e-300) for c, x in enumerate(cols)
    )

    anchors = np.load(d / "weights_anchor_nodes.npy")
    sample = anchors[: min(20, len(anchors))]
    c_a = ours["c_a"]

    def per_column():
        for node in sample:
            b = np.zeros(n)
            b[node] = c_a
            cg(m, b, jacobi, tol)

    t_cols, _ = timed(per_column, 1)
    t_col = t_cols / len(sample)

    colptr = np.load(d / "position_colptr.npy").astype(np.int64)
    rowidx = np.load(d / "position_rowidx.npy").astype(np.int64)
    lower_vals = np.load(d / "position_lower.npy")
    k = len(colptr) - 1
    lower = sp.csc_matrix((lower_vals, rowidx, colptr), shape=(k, k))
    full = (lower + lower.T - sp.diags(lower.diagonal())).tocsc()
    prhs = np.load(d / "position_rhs.npy")
    t_factor, lu = timed(lambda: spla.splu(full, permc_spec="COLAMD"), repeats)
    t_solve, x = timed(lambda: lu.solve(prhs), repeats)
    pres = np.linalg.norm(full @ x - prhs) / max(np.linalg.norm(prhs), 1e-300)

    print(f"SciPy {scipy.__version__}, NumPy {np.__version__}; crease used {ours['threads']} threads")
    print(f"weight window: {n} unknowns, {ours['window_anchors']} anchors; positioning: {k} unknowns")
    rows = [
        ("weights fused, 3 RHS (CG)", ours["weights_fused_seconds"], t_fused),
        ("weights, one anchor column (CG)", ours["weights_per_column_seconds"], t_col),
        ("weights per-anchor, whole window", ours["weights_per_anchor_window_seconds"], t_col * ours["window_anchors"]),
        ("positioning factor (Cholesky vs SuperLU)", ours["position_factor_seconds"], t_factor),
        ("positioning solve, 3 RHS", ours["position_solve3_seconds"], t_solve),
    ]
    print(f"{'stage':<44} {'crease s':>11} {'SciPy s':>11} {'crease/SciPy':>13}")
    for name, a, b in rows:
        print(f"{name:<44} {a:>11.5f} {b:>11.5f} {a / b:>13.4f}")
    print("(per-anchor whole-window SciPy time is extrapolated from the sampled columns)")
    print(f"SciPy residuals: weights {res:.2e} (tolerance {tol:g}), positioning {pres:.2e}")


if __name__ == "__main__":
    main()
