#!/usr/bin/env python3
"""Writes the seed inputs of every fuzz target into fuzz/corpus/<target>/ (small files, named seed-*).

Seeds are small valid (and a few nearly valid) files of each format: hand-written meshes in every face and
encoding form the readers accept, a cut-down piece of the repository's sleeve fixture, and the job spec,
anchors and cameras examples of the README. Run from anywhere: python3 fuzz/seeds.py
"""
import json
import os
import struct

ROOT = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(ROOT)
SEP = b"\n#--next-frame--\n"  # harness::SEPARATOR: splits an input into two frames


def put(target, name, data):
    d = os.path.join(ROOT, "corpus", target)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(d, "seed-" + name), "wb") as f:
        f.write(data)


def sleeve_piece(n_vertices=120):
    """The first vertices of a fixture frame and the faces that use only them."""
    path = os.path.join(REPO, "tests/fixtures/sleeve/frame_0020.obj")
    vs, fs = [], []
    with open(path) as f:
        for line in f:
            t = line.split()
            if not t:
                continue
            if t[0] == "v" and len(vs) < n_vertices:
                vs.append(line)
            elif t[0] == "f":
                idx = [int(x.split("/")[0]) for x in t[1:]]
                if all(0 < i <= n_vertices for i in idx):
                    fs.append(line)
    return "".join(vs) + "".join(fs)


# ---- OBJ ----
QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n"
GRID = "".join(f"v {x} {y} {0.1 * x * y}\n" for y in range(3) for x in range(3))
GRID_F = "".join(
    f"f {1 + x + 3 * y} {2 + x + 3 * y} {5 + x + 3 * y}\nf {1 + x + 3 * y} {5 + x + 3 * y} {4 + x + 3 * y}\n"
    for y in range(2) for x in range(2))
put("obj", "quad", QUAD)
put("obj", "grid", "# grid\no grid\n" + GRID + "vt 0 0\nvt 1 0\nvn 0 0 1\n" + GRID_F)
put("obj", "forms", "mtllib a.mtl\nv 0 0 0 1\nv 1 0 0 0.5 0.5 0.5\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n"
    "usemtl m\ns 1\nf 1/1/1 2//1 3/1 -1 # quad\n")
put("obj", "crlf-bom", b"\xef\xbb\xbfv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n")
put("obj", "relative", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 1 1 0\nf 2 4 3\n")
put("obj", "nan", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
put("obj", "two-frames", QUAD + SEP.decode() + QUAD.replace("v 1 1 0", "v 1 1 0.5"))
put("obj", "other-faces", QUAD + SEP.decode() + QUAD.replace("f 1 2 3 4", "f 1 2 3\nf 1 3 4"))
put("obj", "degenerate", QUAD + SEP.decode() + QUAD.replace("v 1 1 0", "v 1 0 0"))
put("obj", "nonmanifold", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 2 5\n")
put("obj", "sleeve-piece", sleeve_piece())


# ---- PLY ----
def ply(fmt, verts, faces, normals=False, extra=""):
    head = f"ply\nformat {fmt} 1.0\ncomment fuzz seed\n{extra}element vertex {len(verts)}\n" \
           "property float x\nproperty float y\nproperty float z\n"
    if normals:
        head += "property float nx\nproperty float ny\nproperty float nz\n"
    head += f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    out = head.encode()
    if fmt == "ascii":
        for v in verts:
            out += (" ".join(str(c) for c in v) + (" 0 0 1" if normals else "") + "\n").encode()
        for f in faces:
            out += (" ".join(str(i) for i in [len(f)] + list(f)) + "\n").encode()
        return out
    e = "<" if fmt == "binary_little_endian" else ">"
    for v in verts:
        out += struct.pack(e + "3f", *v) + (struct.pack(e + "3f", 0, 0, 1) if normals else b"")
    for f in faces:
        out += struct.pack(e + "B" + "i" * len(f), len(f), *f)
    return out


QV = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
put("ply", "ascii-quad", ply("ascii", QV, [(0, 1, 2, 3)]))
put("ply", "ascii-tris-normals", ply("ascii", QV, [(0, 1, 2), (0, 2, 3)], normals=True))
put("ply", "binle", ply("binary_little_endian", QV, [(0, 1, 2), (0, 2, 3)]))
put("ply", "binbe-normals", ply("binary_big_endian", QV, [(0, 1, 2, 3)], normals=True))
put("ply", "extra-element",
    "ply\nformat ascii 1.0\ncomment x\nelement material 1\nproperty list uchar float c\n"
    "element vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n"
    "element face 1\nproperty list uchar int vertex_index\nend_header\n2 0.5 0.5\n"
    "0 0 0 1\n1 0 0 2\n1 1 0 3\n0 1 0 4\n4 0 1 2 3\n")
put("ply", "double-ushort",
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\n"
    "element face 1\nproperty list ushort uint vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
put("ply", "two-frames-binle", ply("binary_little_endian", QV, [(0, 1, 2, 3)]) + SEP
    + ply("binary_little_endian", [(0, 0, 0), (1, 0, 0), (1, 1, 0.5), (0, 1, 0)], [(0, 1, 2, 3)]))
put("ply", "two-frames-other", ply("ascii", QV, [(0, 1, 2, 3)]) + SEP + ply("ascii", QV, [(0, 1, 2), (0, 2, 3)]))


# ---- PC2 ----
def pc2(samples, start=1.0, rate=1.0):
    n = len(samples[0])
    out = b"POINTCACHE2\0" + struct.pack("<iiffi", 1, n, start, rate, len(samples))
    for s in samples:
        for p in s:
            out += struct.pack("<3f", *p)
    return out


put("pc2", "quad-2", pc2([QV, [(0, 0, 0), (1, 0, 0), (1, 1, 0.5), (0, 1, 0)]]))
put("pc2", "quad-1", pc2([QV], start=10.0, rate=0.5))
put("pc2", "quad-degenerate", pc2([QV, [(0, 0, 0)] * 4]))
put("pc2", "with-obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n" + pc2([[(0, 0, 0), (1, 0, 0), (0, 1, 0)]] * 3))
put("pc2", "with-grid-obj", (GRID + GRID_F).encode()
    + pc2([[(x, y, 0.0) for y in range(3) for x in range(3)]] * 2))
put("pc2", "truncated", pc2([QV, QV])[:-5])

# ---- anchors JSON ----
put("anchors", "readme", json.dumps({"version": 1, "frames": [
    {"frame": 0, "anchors": [{"triangle": 12, "axis": [0, 0, 1], "angle": 0.8}],
     "control_lines": [[[0, 0, 0], [1, 0, 0], [1, 1, 0.5]]]}]}, indent=1))
put("anchors", "several", json.dumps({"version": 1, "frames": [
    {"frame": f, "anchors": [{"triangle": t, "axis": [1, 2, 3], "angle": -0.5 + 0.1 * t} for t in range(f, 20, 7)]}
    for f in range(0, 8, 3)]}))
put("anchors", "empty", '{"version":1,"frames":[]}')
put("anchors", "twice", '{"version":1,"frames":[{"frame":1},{"frame":1}]}')
put("anchors", "bad-angle", '{"version":1,"frames":[{"frame":0,"anchors":[{"triangle":1,"axis":[1,0,0],"angle":4}]}]}')

# ---- cameras JSON ----
CAM = {"name": "a", "width": 64, "height": 48, "fx": 50, "fy": 50, "cx": 31.5, "cy": 23.5,
       "R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "t": [0, 0, 2], "center": [0, 0, -2]}
CAM_B = dict(CAM, name="b", R=[[0, 0, -1], [0, 1, 0], [1, 0, 0]], t=[0, 0, 2], center=[2, 0, 0])
put("cameras", "one", json.dumps({"image_pattern": "images/%s/frame_%04d.png", "cameras": [CAM]}, indent=1))
put("cameras", "two-convention", json.dumps({"convention": "OpenCV pinhole", "cameras": [CAM, CAM_B]}))
put("cameras", "array", json.dumps([{k: v for k, v in CAM.items() if k != "center"}]))
put("cameras", "pattern", json.dumps({"image_pattern": "%s/%d_%3d%%.png", "cameras": [CAM]}))
put("cameras", "reflection", json.dumps({"cameras": [dict(CAM, R=[[1, 0, 0], [0, 0, 1], [0, 1, 0]])]}))

# ---- job specs ----
TOML_ANCHORS = '''name = "sleeve take 3"
input = "/data/capture/sleeve"
output = "file:///data/out/sleeve"
priority = 10
client_token = "sleeve-take-3"
max_task_attempts = 3
max_task_failures_per_job = 10

[folds]
kind = "anchors"
uri = "/data/capture/sleeve-anchors.json"

[deform]
mode = "per-anchor"
window = 10
shift = 7
cg_tolerance = 1e-3
stretch_passes = 2

[partition]
anchor_block = 256
frames_per_chunk = 4
fold_frames_per_chunk = 8

[preview]
frames = [5, 20]
size = 384
'''
TOML_STRETCH = '''input = "s3://bucket/capture/sleeve"
output = "memory://out/sleeve"
[folds]
kind = "stretch"
subdivide = 1
[folds.params]
min_shrink = 0.02
theta0_deg = 30.0
'''
TOML_VIDEO = '''input = "/data/capture/sleeve/take.pc2"
output = "/data/out"
[folds]
kind = "video"
cameras = "/data/capture/sleeve/cameras.json"
images = "/data/capture/sleeve/images"
front_vertex = 10
back_vertex = 200
first_image_number = 1
overlay_frames = [0, 3]
[folds.params]
radii = [2.0, 4.0]
canny_low = 10.0
'''
put("spec_toml", "anchors", TOML_ANCHORS)
put("spec_toml", "stretch", TOML_STRETCH)
put("spec_toml", "video", TOML_VIDEO)
put("spec_toml", "minimal", 'input = "in"\noutput = "out"\n')
put("spec_toml", "bad-field", 'input = "in"\noutput = "out"\n[partition]\nframes_per_chunk = 0\n')
SPECS_JSON = [
    {"input": "/in", "output": "/out"},
    {"name": "j", "input": "file:///in", "output": "s3://b/out", "priority": -3, "client_token": "t",
     "folds": {"kind": "anchors", "uri": "/a.json"}, "deform": {"mode": "fused", "window": 10},
     "partition": {"anchor_block": 64, "frames_per_chunk": 2, "fold_frames_per_chunk": 4},
     "preview": {"frames": [1, 2], "size": 128}},
    {"input": "/in", "output": "/out", "folds": {"kind": "stretch", "subdivide": 2,
                                                "params": {"min_shrink": 0.05}}},
    {"input": "/in", "output": "/out", "folds": {"kind": "video", "cameras": "/c.json", "front_vertex": 1,
                                                "back_vertex": 2, "overlay_frames": [0],
                                                "params": {"radii": [3.0]}}},
    {"input": "/in", "output": "/out", "folds": {"kind": "none"}, "max_task_attempts": 0},
]
for i, s in enumerate(SPECS_JSON):
    put("spec_json", f"spec{i}", json.dumps(s, indent=1 if i % 2 else None))
