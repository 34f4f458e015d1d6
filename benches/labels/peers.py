"""Peer surfaces of a label map for comparison with `destair extract`: 3D Slicer's closed
surface pipeline (per label: discrete marching cubes, then windowed sinc with Slicer's
defaults for smoothing factor 0.5: 20 iterations, pass band 10^(-4 * 0.5), non-manifold
smoothing, normalized coordinates) and VTK's SurfaceNets3D (its own smoothing, box
constraint at one cell, 32 iterations unless given). Needs numpy, nibabel, vtk (PyPI).

    python3 peers.py MAP.nii.gz OUT_DIR [VALUE=NAME ...] [--iterations N]

Writes OUT_DIR/{slicer,surfacenets}/NAME.ply in world RAS mm (the NIfTI's affine), as
`destair extract --space ras` does, so `destair compare` can measure them against a reference.
"""
import os
import sys

import nibabel as nib
import numpy as np
import vtk
from vtk.util import numpy_support

args = [a for a in sys.argv[1:] if not a.startswith("--")]
iterations = 32
if "--iterations" in sys.argv:
    iterations = int(sys.argv[sys.argv.index("--iterations") + 1])
    args = [a for a in args if a != str(iterations)]
path, out = args[0], args[1]
names = dict(a.split("=") for a in args[2:])
img = nib.load(path)
data = np.asarray(img.dataobj).astype(np.int32)
aff = img.affine
values = [int(v) for v in np.unique(data) if v != 0]


def image(labels):
    im = vtk.vtkImageData()
    im.SetDimensions(*labels.shape)
    arr = numpy_support.numpy_to_vtk(labels.ravel(order="F"), deep=True, array_type=vtk.VTK_INT)
    im.GetPointData().SetScalars(arr)
    return im


def to_world(poly):
    t = vtk.vtkTransform()
    m = vtk.vtkMatrix4x4()
    for r in range(4):
        for c in range(4):
            m.SetElement(r, c, aff[r, c])
    t.SetMatrix(m)
    f = vtk.vtkTransformPolyDataFilter()
    f.SetTransform(t)
    f.SetInputData(poly)
    f.Update()
    # A mirroring affine turns the triangles inside out; orient them outward again.
    n = vtk.vtkPolyDataNormals()
    n.SetInputData(f.GetOutput())
    n.ConsistencyOn()
    n.AutoOrientNormalsOn()
    n.SplittingOff()
    n.ComputePointNormalsOff()
    n.Update()
    return n.GetOutput()


def write(poly, folder, name):
    os.makedirs(f"{out}/{folder}", exist_ok=True)
    tri = vtk.vtkTriangleFilter()
    tri.SetInputData(poly)
    tri.Update()
    w = vtk.vtkPLYWriter()
    w.SetFileName(f"{out}/{folder}/{name}.ply")
    w.SetInputData(tri.GetOutput())
    w.SetFileTypeToBinary()
    w.Write()


full = image(data)
for v in values:
    name = names.get(str(v), f"label_{v}")
    # Slicer: a binary image per label, discrete marching cubes, windowed sinc.
    mc = vtk.vtkDiscreteMarchingCubes()
    mc.SetInputData(image((data == v).astype(np.int32)))
    mc.SetValue(0, 1)
    mc.Update()
    ws = vtk.vtkWindowedSincPolyDataFilter()
    ws.SetInputData(mc.GetOutput())
    ws.SetNumberOfIterations(20)
    ws.SetPassBand(10 ** (-4.0 * 0.5))
    ws.BoundarySmoothingOff()
    ws.FeatureEdgeSmoothingOff()
    ws.NonManifoldSmoothingOn()
    ws.NormalizeCoordinatesOn()
    ws.Update()
    write(to_world(ws.GetOutput()), "slicer", name)
    # SurfaceNets3D on all labels at once, this label's surface.
    sn = vtk.vtkSurfaceNets3D()
    sn.SetInputData(full)
    sn.SetValue(0, v)
    sn.SetOutputMeshTypeToTriangles()
    sn.SmoothingOn()
    sn.SetNumberOfIterations(iterations)
    sn.SetConstraintScale(1.0)
    sn.Update()
    write(to_world(sn.GetOutput()), "surfacenets", name)
    print(name, "done", flush=True)
