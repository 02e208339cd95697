#!/usr/bin/env python3
"""A public case on an irregular mesh, for checking that crease's figures do not depend on the public data's
regular grids (garments cut from sewing patterns rarely are).

    python3 bench/irregular_mesh.py CASE SHARE SEED OUT [CAPTURE ...]
    crease run --input OUT/CAPTURE --folds stretch|video [--cameras $D/CASE/cameras.json --images $D/CASE/images] --out R
    crease eval --output R --gt OUT/gt --input OUT/CAPTURE

SHARE `all` splits every triangle in four at its edges' midpoints instead (the same garment meshed twice as
finely, regularly). Otherwise it bisects a random SHARE of the mesh's edges at their midpoints (no two in one triangle; each splits both of its
triangles in two), so edge lengths vary by 2x and valences by 2 across the surface, and writes the ground truth
(`OUT/gt`) and each named capture of the case (`captured`, `captured-spectral`, ...: `OUT/<name>`) with the same
splits, as `mesh.obj` + `frames.pc2`. A midpoint lies on the straight edge in every sequence, so the ground truth
gains no detail and the calibrated images of the case still show it. Needs numpy and scipy.
"""
import os
import sys

import numpy as np

from deep_detail_families import load
from other_captures import write


def bisect(triangles, share, rng):
    """New triangles and, per new vertex, the two old vertices it is the midpoint of."""
    n = triangles.max() + 1
    edges = {}
    for t, tri in enumerate(triangles):
        for k in range(3):
            a, b = sorted((tri[k], tri[(k + 1) % 3]))
            edges.setdefault((a, b), []).append(t)
    keys = list(edges)
    order = rng.permutation(len(keys))
    taken = np.zeros(len(triangles), dtype=bool)
    split = {}
    want = int(share * len(keys))
    for i in order:
        if len(split) >= want:
            break
        e = keys[i]
        ts = edges[e]
        if taken[ts].any():
            continue
        taken[ts] = True
        split[e] = n + len(split)
    out = []
    for tri in triangles:
        done = False
        for k in range(3):
            a, b, c = tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]
            m = split.get(tuple(sorted((a, b))))
            if m is not None:
                out += [(a, m, c), (m, b, c)]
                done = True
                break
        if not done:
            out.append(tuple(tri))
    mids = np.array(sorted(split, key=split.get), dtype=np.int64).reshape(-1, 2)
    return np.array(out, dtype=np.int64), mids


def quadrisect(triangles):
    """Every triangle split in four at its edges' midpoints (the same garment meshed twice as finely)."""
    n = triangles.max() + 1
    mid = {}
    out = []
    for tri in triangles:
        m = []
        for k in range(3):
            e = tuple(sorted((tri[k], tri[(k + 1) % 3])))
            if e not in mid:
                mid[e] = n + len(mid)
            m.append(mid[e])
        a, b, c = tri
        out += [(a, m[0], m[2]), (m[0], b, m[1]), (m[2], m[1], c), (m[0], m[1], m[2])]
    mids = np.array(sorted(mid, key=mid.get), dtype=np.int64).reshape(-1, 2)
    return np.array(out, dtype=np.int64), mids


def main():
    if len(sys.argv) < 5:
        sys.exit(__doc__)
    case, share, seed, out = sys.argv[1:5]
    captures = sys.argv[5:]
    data = os.environ.get("D", os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data"))
    gt, triangles = load(os.path.join(data, case, "gt"))
    if share == "all":
        new_tris, mids = quadrisect(triangles)
    else:
        new_tris, mids = bisect(triangles, float(share), np.random.default_rng(int(seed)))
    for name, src in [("gt", "gt")] + [(c, c) for c in captures]:
        frames = gt if name == "gt" else load(os.path.join(data, case, src))[0]
        frames = np.concatenate([frames, 0.5 * (frames[:, mids[:, 0]] + frames[:, mids[:, 1]])], axis=1)
        write(os.path.join(out, name), frames, new_tris)
    print(f"{out}: {len(mids)} edges bisected, {gt.shape[1] + len(mids)} vertices, {len(new_tris)} triangles")


if __name__ == "__main__":
    main()
