"""VTK's multi-label extraction on the label map of `destair bench extract`, for comparison.

    destair bench extract --keep --dir /tmp/b
    VTK_SMP_BACKEND_IN_USE=STDThread python3 examples/peers/vtk_extract.py /tmp/b/destair-bench.nii

Needs `pip install vtk numpy`. VTK's wheels run their filters on one thread unless
VTK_SMP_BACKEND_IN_USE=STDThread is set. Prints the best and median of 5 runs of
vtkSurfaceNets3D without and with its default smoothing, and the best of 3 of
vtkDiscreteMarchingCubes over all labels. Nothing is written.
"""

import sys
import time

import numpy as np
import vtk
from vtk.util import numpy_support


def read_nifti_u8(path):
    """The u8 voxels, dims and spacing of an uncompressed NIfTI-1 file (as the bench writes it)."""
    header = np.fromfile(path, dtype=np.uint8, count=352)
    dims = np.frombuffer(header[40:56].tobytes(), dtype="<i2")[1:4]
    pixdim = np.frombuffer(header[76:108].tobytes(), dtype="<f4")[1:4]
    offset = int(np.frombuffer(header[108:112].tobytes(), dtype="<f4")[0])
    voxels = np.fromfile(path, dtype=np.uint8, offset=offset)
    assert voxels.size == int(np.prod(dims)), "not a u8 volume of the header's size"
    return voxels, [int(d) for d in dims], [float(s) for s in pixdim]


def timed(make, runs):
    times = []
    for _ in range(runs):
        f = make()
        t = time.perf_counter()
        f.Update()
        times.append(time.perf_counter() - t)
    return sorted(times), f.GetOutput()


def main():
    voxels, dims, spacing = read_nifti_u8(sys.argv[1])
    image = vtk.vtkImageData()
    image.SetDimensions(*dims)
    image.SetSpacing(*spacing)
    scalars = numpy_support.numpy_to_vtk(voxels, deep=1, array_type=vtk.VTK_UNSIGNED_CHAR)
    image.GetPointData().SetScalars(scalars)
    labels = sorted(int(v) for v in np.unique(voxels) if v != 0)
    print(f"VTK {vtk.vtkVersion.GetVTKVersion()}, SMP backend {vtk.vtkSMPTools.GetBackend()}, "
          f"{len(labels)} labels, dims {dims}")

    def filter_of(cls, smoothing=None):
        def make():
            f = cls()
            f.SetInputData(image)
            for i, label in enumerate(labels):
                f.SetValue(i, label)
            if smoothing is not None:
                f.SetSmoothing(smoothing)
            return f
        return make

    for smoothing in (False, True):
        times, out = timed(filter_of(vtk.vtkSurfaceNets3D, smoothing), 5)
        print(f"vtkSurfaceNets3D smoothing={smoothing}: best {times[0]:.3f} s, "
              f"median {times[2]:.3f} s, {out.GetNumberOfPolys()} polygons")
    times, out = timed(filter_of(vtk.vtkDiscreteMarchingCubes), 3)
    print(f"vtkDiscreteMarchingCubes: best {times[0]:.3f} s, {out.GetNumberOfPolys()} polygons")


if __name__ == "__main__":
    main()
