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
NOISE mean edge lengths per coordinate (seed 7).

Two more families model what a tracked template does rather than what a low-pass does; both start from the
`heat` low-pass at WAVELENGTH and take NOISE as their amplitude in mean edge lengths instead of white noise:
`slide` moves the vertices along the surface by a smooth field (wavelengths of about 20 edges) that drifts
slowly over the sequence, as a registration slides on cloth it cannot see texture on (the surface is where it
was, the vertices are not: lengths change where nothing stretched); `flicker` adds a smooth field drawn anew
every frame (about 8 edges), as a tracker's per-frame fit jitters. OUT gets `mesh.obj` and `frames.pc2` with the ground truth's
vertices and triangles. Needs numpy, scipy and scikit-learn (the readers it shares with
`deep_detail_families.py` import it).
"""
import os
import struct
import sys

import numpy as np

from deep_detail_families import band_lowpass, cot_walk, edge, heat_lowpass, load, normals


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


def smooth_field(walk, p, rng, wavelength, steps=3):
    """Gaussian vectors per vertex, low-passed `steps` times at `wavelength` edges, scaled to unit rms."""
    x = rng.normal(size=p.shape)
    for _ in range(steps):
        x = heat_lowpass(walk, x, wavelength)
    x -= x.mean(0)
    return x / np.sqrt((x ** 2).sum(1).mean())


def tangential(f, p, u):
    """`u` with its part along the vertex normals of `p` removed."""
    n = normals(f, p)
    return u - (u * n).sum(1, keepdims=True) * n


def capture(f, p, family, wavelength, noise, rng, t=0.0, keys=None):
    walk = cot_walk(f, p)
    if family in ("slide", "flicker"):
        x = heat_lowpass(walk, p, wavelength)
        if family == "slide":
            k = t * (len(keys) - 1)
            i = min(int(k), len(keys) - 2)
            w = 0.5 - 0.5 * np.cos(np.pi * (k - i))
            u = tangential(f, x, (1 - w) * keys[i] + w * keys[i + 1])
        else:
            u = smooth_field(walk, p, rng, 8.0)
        return x + u * noise * edge(f, p)
    if family == "heat":
        x = heat_lowpass(walk, p, wavelength)
    elif family == "band":
        x = band_lowpass(walk, p, wavelength)
    else:
        sys.exit(f"unknown family {family!r}: heat, band, slide or flicker")
    return x + rng.normal(size=x.shape) * noise * edge(f, p)


def main():
    if len(sys.argv) != 6:
        sys.exit(__doc__)
    case, family, wavelength, noise, out = sys.argv[1:]
    data = os.environ.get("D", os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data"))
    frames, triangles = load(os.path.join(data, case, "gt"))
    rng = np.random.default_rng(7)
    keys = None
    if family == "slide":
        walk = cot_walk(triangles, frames[0])
        keys = [smooth_field(walk, frames[0], rng, 20.0) for _ in range(4)]
    last = max(len(frames) - 1, 1)
    captured = np.stack([capture(triangles, p, family, float(wavelength), float(noise), rng, i / last, keys)
                         for i, p in enumerate(frames)])
    write(out, captured, triangles)
    print(f"{out}: {captured.shape[0]} frames x {captured.shape[1]} vertices")


if __name__ == "__main__":
    main()
