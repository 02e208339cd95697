#!/usr/bin/env python3
"""Inputs that differ from the public captures in ways a real capture does but the public data does not, for
checking that crease holds on them (bench/other_captures.py makes other low-passes and tracking artefacts).

    python3 bench/capture_probes.py KIND CASE CAPTURE OUT
    crease run --input OUT/cap --folds stretch|video [--cameras OUT/cameras.json] --out R
    crease eval --output R --gt OUT/gt --input OUT/cap

CASE is `sleeve` or `drape`, CAPTURE one of its capture directories (read from $D, default ../shared/data).
OUT gets `gt/` and `cap/` (`mesh.obj` + `frames.pc2`), and `cameras.json` (the case's cameras, images read from
$D) where the images still show the sequence. KIND:

- `seam`: the mesh cut in two by the plane through the first frame's mean vertex across its smallest extent
  that is not a thickness (the sleeve lengthwise into two halves, the drape across its middle), the vertices on
  the cut written twice, once for each side's triangles: a garment whose panels are not welded;
- `spikes`: every frame, a random 0.2 % of the vertices moved one mean edge length along their normals, either
  way (reconstruction outliers);
- `rigid`: truth and capture turned 4 degrees about the vertical and moved 3 cm further every frame (no cameras:
  the images do not move);
- `mm`: truth, capture and cameras in millimetres instead of metres;
- `half`: every other frame (half the frame rate), images renumbered to match.

Needs numpy and scipy (the readers it shares with `deep_detail_families.py` import scikit-learn too).
"""
import json
import os
import sys

import numpy as np

from deep_detail_families import edge, load, normals
from other_captures import write


def cameras(data, case, out, scale=1.0, pattern=None):
    c = json.load(open(os.path.join(data, case, "cameras.json")))
    for k in c["cameras"]:
        k["t"] = [x * scale for x in k["t"]]
        if "center" in k:
            k["center"] = [x * scale for x in k["center"]]
    c["image_pattern"] = pattern or os.path.join(os.path.abspath(os.path.join(data, case)), "images", "%s",
                                                 "frame_%04d.png")
    json.dump(c, open(os.path.join(out, "cameras.json"), "w"))


def seam(gt, cap, f):
    p = gt[0]
    # Across the smallest extent that is not a sheet's thickness: lengthwise through a tube, across a sheet.
    extents = p.max(0) - p.min(0)
    axis = [a for a in np.argsort(extents) if extents[a] > 0.1 * extents.max()][0]
    side = p[f].mean(1)[:, axis] > p[:, axis].mean()
    shared = np.intersect1d(np.unique(f[side]), np.unique(f[~side]))
    copy = {v: len(p) + i for i, v in enumerate(shared)}
    f2 = f.copy()
    for t in np.where(side)[0]:
        f2[t] = [copy.get(v, v) for v in f[t]]
    return np.concatenate([gt, gt[:, shared]], 1), np.concatenate([cap, cap[:, shared]], 1), f2, len(shared)


def main():
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    kind, case, capture, out = sys.argv[1:]
    data = os.environ.get("D", os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data"))
    gt, f = load(os.path.join(data, case, "gt"))
    cap, _ = load(os.path.join(data, case, capture))
    os.makedirs(out, exist_ok=True)
    with_cameras = True
    if kind == "seam":
        gt, cap, f, n = seam(gt, cap, f)
        print(f"{n} vertices on the cut, written twice")
    elif kind == "spikes":
        rng = np.random.default_rng(3)
        e = edge(f, cap[0])
        for t in range(len(cap)):
            idx = rng.choice(cap.shape[1], size=max(1, cap.shape[1] // 500), replace=False)
            sign = rng.choice([-1.0, 1.0], size=len(idx))[:, None]
            cap[t, idx] += normals(f, cap[t])[idx] * e * sign
    elif kind == "rigid":
        def move(x):
            out = []
            for t, p in enumerate(x):
                a = np.radians(4.0 * t)
                r = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
                out.append(p @ r.T + np.array([0.03 * t, 0.01 * t, 0.0]))
            return np.array(out)
        gt, cap, with_cameras = move(gt), move(cap), False
    elif kind == "mm":
        gt, cap = gt * 1000.0, cap * 1000.0
        cameras(data, case, out, 1000.0)
        with_cameras = False
    elif kind == "half":
        gt, cap = gt[::2], cap[::2]
        images = os.path.join(out, "images")
        src = os.path.abspath(os.path.join(data, case, "images"))
        for cam in sorted(os.listdir(src)):
            os.makedirs(os.path.join(images, cam), exist_ok=True)
            for i in range(len(gt)):
                link = os.path.join(images, cam, "frame_%04d.png" % (i + 1))
                if not os.path.lexists(link):
                    os.symlink(os.path.join(src, cam, "frame_%04d.png" % (2 * i + 1)), link)
        cameras(data, case, out, pattern="images/%s/frame_%04d.png")
        with_cameras = False
    else:
        sys.exit(f"unknown kind {kind!r}: seam, spikes, rigid, mm or half")
    if with_cameras:
        cameras(data, case, out)
    write(os.path.join(out, "gt"), gt, f)
    write(os.path.join(out, "cap"), cap, f)
    print(f"{out}: {cap.shape[0]} frames x {cap.shape[1]} vertices")


if __name__ == "__main__":
    main()
