#!/usr/bin/env python3
"""A sheet whose capture erased one fold, for checking what `crease run` makes of the lost length.

    python3 bench/erased_fold.py make DIR          # writes DIR/gt and DIR/captured (16 OBJ frames each)
    crease run --input DIR/captured --folds stretch --out OUT --quiet [--set KEY=VALUE ...]
    python3 bench/erased_fold.py measure DIR OUT   # the middle row's height above the capture, in edges

The sheet is 48 x 32 edges of 1 cm, flat but for a gentle 2 mm bow across it. One ridge runs along it: a
raised cosine 8 edges wide whose steepest slope rises to 35 degrees and falls back over the 16 frames, made
without stretching the cloth (the rest length is kept by pulling the sheet in across the ridge). The capture
keeps every vertex where the cloth put it across the sheet and none of the ridge's height: a flat sheet that
lost length in a band 8 edges wide.
"""
import glob
import os
import sys

import numpy as np

NX, NY, EDGE = 49, 33, 0.01
WIDTH, CENTRE, FRAMES = 8.0, 24.0, 16
PEAK = np.tan(np.radians(35.0)) * WIDTH / np.pi  # a raised cosine of width W and height A is steepest at pi A / W


def frame(amplitude):
    """Ground truth and capture of one frame: the ridge laid out by arc length, so that no edge stretches."""
    x = np.linspace(-30.0, 30.0, 60001)
    z = np.where(np.abs(x) < WIDTH / 2, amplitude * (1 + np.cos(2 * np.pi * x / WIDTH)) / 2, 0.0)
    arc = np.concatenate([[0.0], np.cumsum(np.sqrt(1 + np.gradient(z, x)[1:] ** 2) * np.diff(x))])
    arc -= np.interp(0.0, x, arc)
    gt = np.zeros((NY, NX, 3))
    for i in range(NX):
        u = i - CENTRE
        gt[:, i, 0] = (np.interp(u, arc, x) + CENTRE) * EDGE
        gt[:, i, 2] = np.interp(u, arc, z) * EDGE
    gt[:, :, 1] = (np.arange(NY) * EDGE)[:, None]
    cap = gt.copy()
    cap[:, :, 2] = 0.0
    bow = 0.002 * np.sin(np.pi * gt[:, :, 1] / (NY * EDGE))
    gt[:, :, 2] += bow
    cap[:, :, 2] += bow
    return gt.reshape(-1, 3), cap.reshape(-1, 3)


def triangles():
    out = []
    for j in range(NY - 1):
        for i in range(NX - 1):
            a = j * NX + i
            b, c, d = a + 1, a + NX, a + NX + 1
            out += [(a, b, d), (a, d, c)] if (i + j) % 2 == 0 else [(a, b, c), (b, d, c)]
    return out


def write(folder, frames):
    os.makedirs(folder, exist_ok=True)
    tris = triangles()
    for t, p in enumerate(frames):
        with open(os.path.join(folder, f"frame_{t + 1:04d}.obj"), "w") as f:
            f.writelines("v %.7f %.7f %.7f\n" % tuple(v) for v in p)
            f.writelines("f %d %d %d\n" % (a + 1, b + 1, c + 1) for a, b, c in tris)


def read(folder):
    frames = []
    for path in sorted(glob.glob(os.path.join(folder, "frame_*.obj"))):
        frames.append(np.array([[float(x) for x in l.split()[1:4]] for l in open(path) if l.startswith("v ")]))
    return frames


def main():
    if sys.argv[1] == "make":
        pairs = [frame(PEAK * np.sin(np.pi * t / (FRAMES - 1)) ** 2) for t in range(FRAMES)]
        write(os.path.join(sys.argv[2], "gt"), [g for g, _ in pairs])
        write(os.path.join(sys.argv[2], "captured"), [c for _, c in pairs])
        print(f"ridge {WIDTH:.0f} edges wide, {PEAK:.2f} edges high at its peak")
        return
    gt, cap, out = (read(os.path.join(sys.argv[2], "gt")), read(os.path.join(sys.argv[2], "captured")),
                    read(sys.argv[3]))
    row = NY // 2
    for t in (4, 6, 8, 10):
        height = lambda p: (p[t].reshape(NY, NX, 3)[row, :, 2] - cap[t].reshape(NY, NX, 3)[row, :, 2]) / EDGE
        g, o = height(gt), height(out)
        print(f"frame {t + 1}: truth peak {g.max():.2f} at column {g.argmax()}, output {o.min():.2f}..{o.max():.2f}; "
              "columns 16-32: " + " ".join(f"{v:.2f}" for v in o[16:33]))


if __name__ == "__main__":
    main()
