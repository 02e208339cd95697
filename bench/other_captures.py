#!/usr/bin/env python3
"""Captures of the public ground truth made in ways the public data was not, for checking that a figure holds
on a capture crease knows nothing about.

    python3 bench/other_captures.py CASE FAMILY WAVELENGTH NOISE OUT
    crease run --input OUT --folds stretch|video [--cameras $D/CASE/cameras.json --images $D/CASE/images] --out R
    crease eval --output R --gt $D/CASE/gt --input OUT

CASE is `sleeve` or `drape` (read from $D, default ../shared/data). FAMILY is `heat` (an implicit cotangent
low-pass: one backward-Euler step of heat flow that halves WAVELENGTH, in mean edge lengths) or `band` (a
smooth spectral cut of the cotangent walk: everything shorter than WAVELENGTH edges removed, everything longer
than 1.5 x WAVELENGTH kept, a raised cosine between; a Chebyshev series of degree 80). Then Gaussian noise of
NOISE mean edge lengths per coordinate (seed 7). OUT gets `mesh.obj` and `frames.pc2` with the ground truth's
vertices and triangles. Needs numpy, scipy and scikit-learn (the readers it shares with
`deep_detail_families.py` import it).
"""
import os
import struct
import sys

import numpy as np

from deep_detail_families import band_lowpass, cot_walk, edge, heat_lowpass, load


def write(out, frames, triangles):
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, "mesh.obj"), "w") as o:
        for v in frames[0]:
            o.write("v %.6f %.6f %.6f\n" % tuple(v))
        for t in triangles:
            o.write("f %d %d %d\n" % tuple(t + 1))
    with open(os.path.join(out, "frames.pc2"), "wb") as o:
        o.write(b"POINTCACHE2\0" + struct.pack("<iiffi", 1, frames.shape[1], 0.0, 1.0, frames.shape[0]))
        o.write(frames.astype("<f4").tobytes())


def capture(f, p, family, wavelength, noise, rng):
    walk = cot_walk(f, p)
    if family == "heat":
        x = heat_lowpass(walk, p, wavelength)
    elif family == "band":
        x = band_lowpass(walk, p, wavelength)
    else:
        sys.exit(f"unknown family {family!r}: heat or band")
    return x + rng.normal(size=x.shape) * noise * edge(f, p)


def main():
    if len(sys.argv) != 6:
        sys.exit(__doc__)
    case, family, wavelength, noise, out = sys.argv[1:]
    data = os.environ.get("D", os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data"))
    frames, triangles = load(os.path.join(data, case, "gt"))
    rng = np.random.default_rng(7)
    captured = np.stack([capture(triangles, p, family, float(wavelength), float(noise), rng) for p in frames])
    write(out, captured, triangles)
    print(f"{out}: {captured.shape[0]} frames x {captured.shape[1]} vertices")


if __name__ == "__main__":
    main()
