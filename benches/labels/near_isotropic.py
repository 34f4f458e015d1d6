"""Issue 62, item 5: near-isotropic label maps (0.8 x 0.8 x 1.5 mm), destair's constrained
surface against VTK's SurfaceNets3D with its box constraint at one cell (the peer's setting
that keeps voxel centres), at every iteration count, by mean normal curvature and by voxel
centres on the wrong side. Needs numpy, nibabel, vtk (PyPI) and a release build of destair.

    python3 near_isotropic.py DESTAIR_BINARY OUT_DIR

Writes OUT_DIR/near-iso.nii.gz (numpy, not destair: a 12 mm sphere touching an ellipsoid
"organ", a lobed blob, tubes of radius 2-4 mm at 0-60 degrees to the slices; voxels set where
their centre lies inside the analytic shape) and prints per label and setting the curvature
(`destair inspect`), the wrong centres: voxel centres next to another label (26
neighbours), of the label or of its neighbours, that the label's surface encloses wrongly
(vtkSelectEnclosedPoints), and for the sphere and the tubes the vertices' mean distance from
the analytic surface (a low curvature can also mean a tube flattened into a prism).
"""
import json
import os
import subprocess
import sys

import nibabel as nib
import numpy as np
import vtk
from vtk.util import numpy_support

destair, out = sys.argv[1], sys.argv[2]
os.makedirs(out, exist_ok=True)
SP = np.array([0.8, 0.8, 1.5])
dims = (120, 120, 64)
p = np.indices(dims).reshape(3, -1).T * SP
c = np.array(dims) * SP / 2
vol = np.zeros(dims, np.uint16).ravel()


def tube(a, b, r):
    a, b = np.array(a, float), np.array(b, float)
    d = b - a
    t = np.clip(((p - a) @ d) / (d @ d), 0, 1)
    return np.linalg.norm(p - (a + t[:, None] * d), axis=1) < r


# A sphere (label 1) touching an ellipsoid organ (label 2).
SPHERE = (c + [-14, -10, 0], 12.0)
vol[np.linalg.norm(p - SPHERE[0], axis=1) < SPHERE[1]] = 1
e = (p - (c + [12, -10, 4])) / [14, 9, 16]
vol[(np.linalg.norm(e, axis=1) < 1) & (vol == 0)] = 2
# A lobed blob (label 3): a sphere whose radius varies with direction.
q = p - (c + [-22, 16, -4])
rq = np.linalg.norm(q, axis=1) + 1e-9
lobes = 9 + 2.5 * (q[:, 0] / rq) * (q[:, 1] / rq) * 4 + 1.5 * np.cos(3 * np.arctan2(q[:, 1], q[:, 0]))
vol[(rq < lobes) & (vol == 0)] = 3
# Tubes with rounded ends (labels 4-7) at 0, 20, 40 and 60 degrees to the slice axis, each in
# its own row, inside the volume.
TUBES = []
for value, (deg, r, y) in enumerate([(0, 3, 8), (20, 2.5, 16), (40, 2, 24), (60, 4, 34)], start=4):
    t = np.radians(deg)
    base = c + [12, y, 0]
    d = np.array([np.sin(t), 0, np.cos(t)]) * 24
    TUBES.append((value, base - d, base + d, r))
    vol[tube(base - d, base + d, r) & (vol == 0)] = value
vol = vol.reshape(dims)
nib.save(nib.Nifti1Image(vol, np.diag(list(SP) + [1.0])), f"{out}/near-iso.nii.gz")
values = [int(v) for v in np.unique(vol) if v]


def boundary_centres(v):
    """Centres (mm) of voxels next to a different label, with whether they hold `v`."""
    lab = vol
    pad = np.pad(lab, 1, constant_values=0)
    differs = np.zeros(dims, bool)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                sh = pad[1 + dx:1 + dx + dims[0], 1 + dy:1 + dy + dims[1], 1 + dz:1 + dz + dims[2]]
                differs |= sh != lab
    own = lab == v
    # Voxels of v next to anything else, and voxels of others next to v.
    padv = np.pad(own, 1)
    touch = np.zeros(dims, bool)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                touch |= padv[1 + dx:1 + dx + dims[0], 1 + dy:1 + dy + dims[1], 1 + dz:1 + dz + dims[2]]
    near = differs & touch
    idx = np.argwhere(near)
    return idx * SP, own[near]


def read(path):
    r = vtk.vtkPLYReader()
    r.SetFileName(path)
    r.Update()
    return r.GetOutput()


def wrong(poly, v):
    pts, inside = boundary_centres(v)
    vp = vtk.vtkPoints()
    vp.SetData(numpy_support.numpy_to_vtk(pts, deep=True))
    pd = vtk.vtkPolyData()
    pd.SetPoints(vp)
    sel = vtk.vtkSelectEnclosedPoints()
    sel.SetInputData(pd)
    sel.SetSurfaceData(poly)
    sel.SetTolerance(1e-6)
    sel.Update()
    got = numpy_support.vtk_to_numpy(sel.GetOutput().GetPointData().GetArray("SelectedPoints"))
    return int((got.astype(bool) != inside).sum()), len(pts)


def to_truth(poly, v):
    """Mean distance (mm) of the surface's vertices from the analytic shape of label `v`
    (the sphere and the tubes; None for the others)."""
    x = numpy_support.vtk_to_numpy(poly.GetPoints().GetData()).astype(float)
    if v == 1:
        return float(np.abs(np.linalg.norm(x - SPHERE[0], axis=1) - SPHERE[1]).mean())
    for value, a, b, r in TUBES:
        if value == v:
            d = b - a
            t = np.clip(((x - a) @ d) / (d @ d), 0, 1)
            return float(np.abs(np.linalg.norm(x - (a + t[:, None] * d), axis=1) - r).mean())
    return None


def curvature(path):
    o = subprocess.run([destair, "inspect", "--json", path], capture_output=True, text=True)
    return json.loads(o.stdout).get("average_normal_curvature_deg")


def write(poly, path):
    # SurfaceNets3D's triangles of one label face either way where it meets another label:
    # orient them outward.
    n = vtk.vtkPolyDataNormals()
    n.SetInputData(poly)
    n.ConsistencyOn()
    n.AutoOrientNormalsOn()
    n.SplittingOff()
    n.ComputePointNormalsOff()
    n.Update()
    tri = vtk.vtkTriangleFilter()
    tri.SetInputData(n.GetOutput())
    tri.Update()
    w = vtk.vtkPLYWriter()
    w.SetFileName(path)
    w.SetInputData(tri.GetOutput())
    w.SetFileTypeToBinary()
    w.Write()


rows = {}
img = vtk.vtkImageData()
img.SetDimensions(*dims)
img.SetSpacing(*SP)
img.GetPointData().SetScalars(numpy_support.numpy_to_vtk(vol.ravel(order="F").astype(np.int32), deep=True))
for it in [int(a) for a in os.environ.get("ITERATIONS", "0,8,16,32,64,128").split(",")]:
    for v in values:
        sn = vtk.vtkSurfaceNets3D()
        sn.SetInputData(img)
        sn.SetValue(0, v)
        sn.SetOutputMeshTypeToTriangles()
        sn.SetSmoothing(it > 0)
        sn.SetNumberOfIterations(max(it, 1))
        sn.SetConstraintStrategyToConstraintBox()
        sn.SetConstraintScale(float(os.environ.get("SCALE", "1")))
        sn.Update()
        path = f"{out}/sn{it}_{v}.ply"
        write(sn.GetOutput(), path)
        poly = read(path)
        rows.setdefault(v, []).append((f"SurfaceNets3D {it}", curvature(path), to_truth(poly, v), *wrong(poly, v)))
for name, args in [("destair default", []), ("destair sigma 1.6", ["--sigma-mm", "1.6"]),
                   ("destair sigma 1.2 keep", ["--noise", "keep"])]:
    d = f"{out}/{name.replace(' ', '_')}"
    subprocess.run([destair, "extract", "--out", d, f"{out}/near-iso.nii.gz", *args],
                   check=True, capture_output=True)
    for v in values:
        path = f"{d}/label_{v}.ply"
        # destair writes LPS by default: x and y negated; the centres are in the grid's mm.
        poly = read(path)
        pts = numpy_support.vtk_to_numpy(poly.GetPoints().GetData()).copy()
        pts[:, :2] *= -1
        poly.GetPoints().SetData(numpy_support.numpy_to_vtk(pts, deep=True))
        rows[v].append((name, curvature(path), to_truth(poly, v), *wrong(poly, v)))
for v in values:
    print(f"label {v}:")
    for name, curv, truth, bad, n in rows[v]:
        away = "" if truth is None else f"{truth:6.3f} mm from the shape"
        print(f"  {name:26s} {curv:6.2f} deg  {bad:6d} of {n} centres wrong  {away}")
