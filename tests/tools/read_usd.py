"""Opens a .usda with Pixar's USD (usd-core) and prints, as JSON, the stage's time range, the texture
coordinates (`st` primvar: interpolation, whether indexed, and its value at every face corner) when present,
and, for each time code asked for, the mesh's points and normals counts and its points (as float32 values)."""
import json
import sys

from pxr import Usd, UsdGeom

path, *times = sys.argv[1:]
stage = Usd.Stage.Open(path)
if stage is None:
    sys.exit(f"USD could not open {path}")
mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Garment/mesh"))
if not mesh:
    sys.exit(f"{path} has no Mesh at /Garment/mesh")
out = {
    "start": stage.GetStartTimeCode(),
    "end": stage.GetEndTimeCode(),
    "fps": stage.GetTimeCodesPerSecond(),
    "up": UsdGeom.GetStageUpAxis(stage),
    "samples": len(mesh.GetPointsAttr().GetTimeSamples()),
    "faces": len(mesh.GetFaceVertexCountsAttr().Get()),
    "frames": {},
}
st = UsdGeom.PrimvarsAPI(mesh.GetPrim()).GetPrimvar("st")
if st and st.HasValue():
    out["st"] = {
        "type": str(st.GetTypeName()),
        "interpolation": st.GetInterpolation(),
        "indexed": st.IsIndexed(),
        "corners": [[float(c) for c in uv] for uv in st.ComputeFlattened()],
    }
for t in times:
    pts = mesh.GetPointsAttr().Get(float(t))
    nrm = mesh.GetNormalsAttr().Get(float(t))
    out["frames"][t] = {
        "points": [[float(c) for c in p] for p in pts],
        "normals": len(nrm),
        "normals_interpolation": mesh.GetNormalsInterpolation(),
    }
print(json.dumps(out))
