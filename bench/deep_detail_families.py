#!/usr/bin/env python3
"""Offline study: does a nonlinear per-vertex correction on top of `crease deep`'s learned detail filter hold on
a capture family it was not trained on?

Reads a model trained by `crease deep train` (its `detail.npy` and manifest: the filter is re-run here exactly
as `deep/src/detail` runs it), the sleeve-train ground truth and the public sleeve captures. Draws captures of
its own (implicit heat, a smooth spectral cut, lambda|mu sweeps; random strengths and noise), fits a small
multilayer perceptron to what the filter leaves along the capture's normals, once on every family and once
without each family, and prints mean vertex-normal errors (degrees) as capture / filter / filter + correction.

Needs numpy, scipy and scikit-learn (`pip install numpy scipy scikit-learn`). About four minutes on two cores:

    crease deep train --data $T/seed_1 ... $T/seed_6 --out M --cgan-steps 0
    python3 bench/deep_detail_families.py M $D
"""
import glob
import json
import os
import struct
import sys

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from sklearn.neural_network import MLPRegressor

DEGREE = 16
BANDS = [0.0, 16.0, 25.0, 36.0, 50.0, 70.0, 180.0]
FAMILIES = ["heat", "band", "sweeps"]


def read_obj(path):
    v, f = [], []
    for line in open(path):
        if line.startswith("v "):
            v.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            f.append([int(t.split("/")[0]) - 1 for t in line.split()[1:4]])
    return np.array(v), np.array(f, dtype=np.int64)


def load(d):
    """Frames (T x V x 3) and triangles of a `mesh.obj` + `frames.pc2` or `frame_*.obj` directory."""
    if os.path.exists(os.path.join(d, "frames.pc2")):
        _, f = read_obj(os.path.join(d, "mesh.obj"))
        b = open(os.path.join(d, "frames.pc2"), "rb").read()
        n, m = struct.unpack("<i", b[16:20])[0], struct.unpack("<i", b[28:32])[0]
        x = np.frombuffer(b[32:32 + 12 * n * m], dtype="<f4").reshape(m, n, 3)
        return x.astype(np.float64), f
    objs = [read_obj(p) for p in sorted(glob.glob(os.path.join(d, "frame_*.obj")))]
    return np.stack([o[0] for o in objs]), objs[0][1]


def cot_walk(f, p):
    """Row-normalised cotangent weights, negative ones raised to 5 % of the row's mean magnitude."""
    n = len(p)
    rows, cols, vals = [], [], []
    for k in range(3):
        a, b, c = f[:, k], f[:, (k + 1) % 3], f[:, (k + 2) % 3]
        u, v = p[b] - p[a], p[c] - p[a]
        cr = np.linalg.norm(np.cross(u, v), axis=1)
        cot = np.where(cr > 0, (u * v).sum(1) / np.maximum(cr, 1e-300), 0.0)
        rows += [b, c]
        cols += [c, b]
        vals += [0.5 * cot, 0.5 * cot]
    w = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsr()
    w.sum_duplicates()
    w = w.tocoo()
    mean = np.bincount(w.row, weights=np.abs(w.data), minlength=n) / np.maximum(np.bincount(w.row, minlength=n), 1)
    w = sp.coo_matrix((np.maximum(w.data, 0.05 * mean[w.row]), (w.row, w.col)), shape=(n, n)).tocsr()
    return sp.diags(1 / np.asarray(w.sum(1)).ravel()) @ w


def uniform_walk(f, n):
    r = np.concatenate([f[:, 0], f[:, 1], f[:, 2], f[:, 1], f[:, 2], f[:, 0]])
    c = np.concatenate([f[:, 1], f[:, 2], f[:, 0], f[:, 0], f[:, 1], f[:, 2]])
    w = sp.coo_matrix((np.ones(len(r)), (r, c)), shape=(n, n)).tocsr()
    w.data[:] = 1.0
    return sp.diags(1 / np.asarray(w.sum(1)).ravel()) @ w


def normals(f, p):
    fn = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
    n = np.zeros_like(p)
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def edge(f, p):
    e = np.concatenate([p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 1]], p[f[:, 0]] - p[f[:, 2]]])
    return np.linalg.norm(e, axis=1).mean()


def angle(f, a, b):
    return np.degrees(np.arccos(np.clip((normals(f, a) * normals(f, b)).sum(1), -1, 1))).mean()


def chebyshev_features(walk, c, degree):
    out = [walk @ c - c, None]
    out[1] = walk @ out[0]
    for _ in range(2, degree + 1):
        out.append(2 * (walk @ out[-1]) - out[-2])
    return out


def heat_lowpass(walk, p, wl):
    """One implicit heat step of the walk that halves wavelength `wl` (edges)."""
    a = (1 + np.cos(2 * np.pi / wl)) / 2
    t = 1 / (1 - a)
    return spla.spsolve(((1 + t) * sp.identity(len(p)) - t * walk).tocsc(), p)


def band_lowpass(walk, p, wl):
    """A smooth spectral cut of the walk: wavelengths under `wl` edges removed, over 1.5 `wl` kept, a raised
    cosine between (a Chebyshev series of degree 80)."""
    lo = np.degrees(np.arccos((1 + np.cos(2 * np.pi / (1.5 * wl))) / 2))
    hi = np.degrees(np.arccos((1 + np.cos(2 * np.pi / wl)) / 2))
    d, nodes = 80, 648
    th = np.pi * (np.arange(nodes) + 0.5) / nodes
    deg = np.degrees(th)
    g = np.where(deg < lo, 1.0, np.where(deg > hi, 0.0, 0.5 * (1 + np.cos(np.pi * (deg - lo) / (hi - lo)))))
    coef = np.array([2 / nodes * (g * np.cos(j * th)).sum() for j in range(d + 1)])
    coef[0] *= 0.5
    t0, t1 = p, walk @ p
    x = coef[0] * t0 + coef[1] * t1
    for j in range(2, d + 1):
        t0, t1 = t1, 2 * (walk @ t1) - t0
        x = x + coef[j] * t1
    return x


def capture(f, p, family, rng):
    """A capture of fine frame `p`: a family's low-pass at a random half-amplitude wavelength, then noise."""
    h = edge(f, p)
    wl = np.exp(rng.uniform(np.log(3.5), np.log(14)))
    sigma = np.exp(rng.uniform(np.log(0.004), np.log(0.08))) if rng.random() < 0.75 else 0.0
    walk = cot_walk(f, p)
    a = (1 + np.cos(2 * np.pi / wl)) / 2
    if family == "heat":
        x = heat_lowpass(walk, p, wl)
    elif family == "band":
        x = band_lowpass(walk, p, wl)
    else:
        lam, band = 0.3 + rng.random() * 0.5, 0.01 + rng.random() * 0.12
        k = 0.5 * (1 - a)
        ks = np.linspace(0, 1, 201)
        while True:
            mu = 1 / (band - 1 / lam)
            per = max(abs((1 - lam * k) * (1 - mu * k)), 1e-6)
            steps = 1 if per >= 1 else int(np.clip(round(np.log(0.5) / np.log(per)), 1, 400))
            if np.abs((1 - lam * ks) * (1 - mu * ks)).max() ** steps <= 1.05 or band < 1e-4:
                break
            band *= 0.5
        if rng.random() < 0.5:
            walk = uniform_walk(f, len(p))
        x = p.copy()
        for _ in range(steps):
            for s in (0.5 * lam, 0.5 * mu):
                x = x + s * (walk @ x - x)
    return x + rng.normal(size=x.shape) * sigma * h


class Filter:
    """`crease deep`'s detail filter, from a model directory."""

    def __init__(self, model, f, n):
        spec = json.load(open(os.path.join(model, "manifest.json")))["detail"]
        w = np.load(os.path.join(model, "detail.npy"))
        self.degree = spec["degree"]
        self.mean, self.std = np.array(spec["signature_mean"]), np.array(spec["signature_std"])
        self.wi, self.wb = w[0].reshape(self.degree + 1, 8), w[1].reshape(self.degree + 1, 8)
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), 1)
        u, cnt = np.unique(e, axis=0, return_counts=True)
        self.boundary = np.zeros(n, bool)
        self.boundary[u[cnt == 1].ravel()] = True

    def signature(self, feats, h):
        inner = ~self.boundary
        g = np.array([[(feats[i][inner] * feats[j][inner]).sum() / inner.sum() for j in range(17)] for i in range(17)])
        total = max(g[0, 0], 1e-300)
        s = [0.5 * np.log(total / h / h)]
        nodes = 8 * 17
        th = np.pi * (np.arange(nodes) + 0.5) / nodes
        a = np.pi / 18
        j = np.arange(17)
        damp = ((17 - j + 1) * np.cos(j * a) + np.sin(j * a) / np.tan(a)) / 18
        for b in range(6):
            m = (np.degrees(th) >= BANDS[b]) & (np.degrees(th) < BANDS[b + 1])
            c = np.array([2 / nodes * np.cos(i * th[m]).sum() for i in range(17)])
            c[0] *= 0.5
            c *= damp
            s.append(0.5 * np.log(max(c @ g @ c, 1e-300 * total) / total))
        return np.array(s)

    def detail(self, f, c):
        h = edge(f, c)
        feats = chebyshev_features(cot_walk(f, c), c, max(self.degree, DEGREE))
        x = np.concatenate([[1.0], np.clip((self.signature(feats, h) - self.mean) / np.maximum(self.std, 1e-12), -3, 3)])
        wi, wb = self.wi @ x, self.wb @ x
        d = sum(np.where(self.boundary[:, None], wb[j], wi[j]) * feats[j] for j in range(self.degree + 1))
        return d, feats, h


def per_vertex(f, flt, c, fine=None):
    """Inputs of the correction (normal parts of the features, tangential sizes, the filter's own detail and
    the frame's log feature sizes), the filter's detail, and the target left along the normals."""
    d, feats, h = flt.detail(f, c)
    n = normals(f, c)
    along = lambda v: (v * n).sum(1)
    across = lambda v: np.linalg.norm(v - along(v)[:, None] * n, axis=1)
    x = [along(v) / h for v in feats] + [across(v) / h for v in feats[:4]] + [along(d) / h, across(d) / h]
    ctx = np.log(np.sqrt(np.stack([(v ** 2).sum(1) for v in feats], 1).mean(0)) / h + 1e-12)
    x = np.concatenate([np.stack(x, 1), np.tile(ctx, (len(c), 1))], 1)
    target = None if fine is None else along(fine - c - d) / h
    return x, d, h, n, target


def main():
    model, data = sys.argv[1], sys.argv[2]
    train = [load(os.path.join(data, "sleeve-train", f"seed_{s}", "gt")) for s in range(1, 7)]
    f = train[0][1]
    flt = Filter(model, f, train[0][0].shape[1])
    rng = np.random.default_rng(2)
    xs, ts, fams = [], [], []
    for frames, _ in train:
        for i in range(0, len(frames), 2):
            fam = i // 4 % 3
            x, _, _, _, t = per_vertex(f, flt, capture(f, frames[i], FAMILIES[fam], rng), frames[i])
            xs.append(x)
            ts.append(t)
            fams.append(np.full(len(t), fam))
    x, t, fam = np.concatenate(xs), np.concatenate(ts), np.concatenate(fams)
    mu, sd = x.mean(0), x.std(0) + 1e-9
    held = load(os.path.join(data, "sleeve-train", "seed_7", "gt"))[0]
    tests = [
        ("seed_7 captured", held, load(os.path.join(data, "sleeve-train", "seed_7", "captured"))[0]),
        ("sleeve captured", load(os.path.join(data, "sleeve", "gt"))[0], load(os.path.join(data, "sleeve", "captured"))[0]),
        ("sleeve captured-spectral", load(os.path.join(data, "sleeve", "gt"))[0],
         load(os.path.join(data, "sleeve", "captured-spectral"))[0]),
    ]
    for out in [None, 0, 1, 2]:
        keep = np.flatnonzero(fam != out) if out is not None else np.arange(len(t))
        pick = np.random.default_rng(0).choice(keep, 300000, replace=False)
        net = MLPRegressor(hidden_layer_sizes=(32, 32), activation="tanh", max_iter=40, batch_size=512,
                           learning_rate_init=1e-3, alpha=1e-5, random_state=0)
        net.fit((x[pick] - mu) / sd, t[pick])

        def score(fines, caps):
            e = np.zeros(3)
            for fine, c in zip(fines, caps):
                xi, d, h, n, _ = per_vertex(f, flt, c)
                r = net.predict((xi - mu) / sd)
                e += [angle(f, c, fine), angle(f, c + d, fine), angle(f, c + d + (r * h)[:, None] * n, fine)]
            return e / len(caps)

        line = [f"trained without {FAMILIES[out]}" if out is not None else "trained on every family"]
        for k, name in enumerate(FAMILIES):
            r2 = np.random.default_rng(10 + k)
            idx = range(1, len(held), 10)
            e = score([held[i] for i in idx], [capture(f, held[i], name, r2) for i in idx])
            line.append(f"seed_7 {name} {e[0]:.2f}/{e[1]:.2f}/{e[2]:.2f}")
        for name, fines, caps in tests:
            idx = range(0, len(fines), 6)
            e = score([fines[i] for i in idx], [caps[i] for i in idx])
            line.append(f"{name} {e[0]:.2f}/{e[1]:.2f}/{e[2]:.2f}")
        print(" | ".join(line), flush=True)


if __name__ == "__main__":
    main()
