"""Issue 62's speed check: a 12-label 512 x 512 x 300 map (0.8 x 0.8 x 2.5 mm, organ-like
ellipsoids written by numpy, some touching), file to written meshes with `destair extract`
(binary and constrained) against VTK SurfaceNets3D with its smoothing on all labels at once
(its compute alone, the image already in memory), side by side in one run. Needs numpy,
nibabel, vtk (PyPI) and a release build of destair.

    python3 speed.py DESTAIR_BINARY OUT_DIR [--runs N]

Prints the best of N runs (default 3) of each, in seconds, and the ratios.
"""
import os
import subprocess
import sys
import time

import nibabel as nib
import numpy as np
import vtk
from vtk.util import numpy_support

destair, out = sys.argv[1], sys.argv[2]
runs = int(sys.argv[sys.argv.index("--runs") + 1]) if "--runs" in sys.argv else 3
os.makedirs(out, exist_ok=True)
dims = (512, 512, 300)
SP = np.array([0.8, 0.8, 2.5])
path = f"{out}/twelve.nii.gz"
if not os.path.exists(path):
    rng = np.random.default_rng(62)
    vol = np.zeros(dims, np.uint16)
    x, y, z = np.ogrid[: dims[0], : dims[1], : dims[2]]
    x, y, z = x * SP[0], y * SP[1], z * SP[2]
    ext = np.array(dims) * SP
    for label in range(1, 13):
        c = ext * rng.uniform(0.25, 0.75, 3)
        r = rng.uniform(25, 70, 3)
        inside = ((x - c[0]) / r[0]) ** 2 + ((y - c[1]) / r[1]) ** 2 + ((z - c[2]) / r[2]) ** 2 < 1
        vol[inside & (vol == 0)] = label
    nib.save(nib.Nifti1Image(vol, np.diag(list(SP) + [1.0])), path)
vol = np.asarray(nib.load(path).dataobj)
print("labels", [int((vol == v).sum()) for v in range(1, 13)])


def best(f):
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return min(times)


def extract(surface):
    subprocess.run([destair, "extract", "--surface", surface, "--out", f"{out}/{surface}", path],
                   check=True, capture_output=True)


img = vtk.vtkImageData()
img.SetDimensions(*dims)
img.SetSpacing(*SP)
img.GetPointData().SetScalars(numpy_support.numpy_to_vtk(vol.ravel(order="F"), deep=True))


def surfacenets():
    sn = vtk.vtkSurfaceNets3D()
    sn.SetInputData(img)
    sn.GenerateLabels(12, 1, 12)
    sn.SmoothingOn()
    sn.Update()


t_sn = best(surfacenets)
t_bin = best(lambda: extract("binary"))
t_con = best(lambda: extract("constrained"))
print(f"SurfaceNets3D with smoothing (compute): {t_sn:.2f} s")
print(f"destair extract binary (file to meshes): {t_bin:.2f} s ({t_bin / t_sn:.2f}x)")
print(f"destair extract constrained (file to meshes): {t_con:.2f} s ({t_con / t_sn:.2f}x)")
