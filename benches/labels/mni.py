"""Grey and white matter label maps from the MNI ICBM152 2009 tissue probability maps that
ship inside the nilearn wheel (PyPI), at 1 mm and down-sampled by slice majority, as the
papers compare thick-slice surfaces with a high-resolution reference.

    pip download --no-deps nilearn==0.14.1   # the wheel; nothing is installed
    python3 mni.py nilearn-0.14.1-py3-none-any.whl OUT_DIR

Writes OUT_DIR/mni-1mm.nii.gz and the thick maps mni-1x1x3.nii.gz (axial 3 mm),
mni-1x3x1.nii.gz (coronal 3 mm, from the second 1 mm slice on), mni-1x1x4.nii.gz (axial 4 mm,
from the third) and mni-2x1x1.nii.gz (sagittal 2 mm): uint16, 1 grey matter, 2 white matter; a
voxel is white matter where its white-matter probability is at least 0.5 and not below the
grey's, grey matter where the grey probability is at least 0.5. A thick voxel takes the label
most of its 1 mm slices hold (ties: the lower label) and its centre is the mean of their
centres, so all maps share world coordinates. With `vtk` installed it also writes
OUT_DIR/mni-wm-level.ply: the 0 level of min(wm - 0.5, wm - gm) on the 1 mm grid by VTK's
flying edges, in world RAS mm, a smooth reference for white matter that has no staircases.

Measure with `destair extract --space ras` on a thick map and `destair compare` against
`destair extract --space ras --surface binary` of the 1 mm map (or against the level set).
"""
import io
import sys
import zipfile

import nibabel as nib
import numpy as np

wheel, out = sys.argv[1], sys.argv[2]
prefix = "nilearn/datasets/data/mni_icbm152_{}_tal_nlin_sym_09a_converted.nii.gz"
with zipfile.ZipFile(wheel) as z:
    imgs = {t: nib.Nifti1Image.from_bytes(
        __import__("gzip").decompress(z.read(prefix.format(t)))) for t in ("gm", "wm")}
gm = np.asarray(imgs["gm"].dataobj, float)
wm = np.asarray(imgs["wm"].dataobj, float)
aff = imgs["gm"].affine
labels = np.zeros(gm.shape, np.uint16)
labels[gm >= 0.5] = 1
labels[(wm >= 0.5) & (wm >= gm)] = 2
nib.save(nib.Nifti1Image(labels, aff), f"{out}/mni-1mm.nii.gz")


def thick(axis, factor, phase):
    """The map down-sampled along `axis` by `factor` slices, starting at slice `phase`."""
    lab = np.moveaxis(labels, axis, 2)[:, :, phase:]
    nz = lab.shape[2] // factor * factor
    blocks = lab[:, :, :nz].reshape(lab.shape[0], lab.shape[1], nz // factor, factor)
    counts = np.stack([(blocks == v).sum(-1) for v in (0, 1, 2)], -1)
    out = np.moveaxis(counts.argmax(-1).astype(np.uint16), 2, axis)
    a = aff.copy()
    a[:3, 3] = aff[:3, 3] + aff[:3, axis] * (phase + (factor - 1) / 2)
    a[:3, axis] *= factor
    return out, a


for name, axis, factor, phase in [("1x1x3", 2, 3, 0), ("1x3x1", 1, 3, 1),
                                  ("1x1x4", 2, 4, 2), ("2x1x1", 0, 2, 0)]:
    data, a = thick(axis, factor, phase)
    nib.save(nib.Nifti1Image(data, a), f"{out}/mni-{name}.nii.gz")
    print(name, data.shape)
print("1 mm", labels.shape, [(labels == v).sum() for v in (1, 2)])

try:
    import vtk
    from vtk.util import numpy_support
except ImportError:
    print("vtk not installed: mni-wm-level.ply not written")
    sys.exit(0)
field = np.minimum(wm - 0.5, wm - gm).astype(np.float32)
im = vtk.vtkImageData()
im.SetDimensions(*field.shape)
im.GetPointData().SetScalars(numpy_support.numpy_to_vtk(field.ravel(order="F"), deep=True))
fe = vtk.vtkFlyingEdges3D()
fe.SetInputData(im)
fe.SetValue(0, 0.0)
fe.ComputeNormalsOff()
fe.Update()
poly = fe.GetOutput()
pts = numpy_support.vtk_to_numpy(poly.GetPoints().GetData()).astype(float)
poly.GetPoints().SetData(numpy_support.numpy_to_vtk(pts @ aff[:3, :3].T + aff[:3, 3], deep=True))
writer = vtk.vtkPLYWriter()
writer.SetFileName(f"{out}/mni-wm-level.ply")
writer.SetInputData(poly)
writer.Write()
print("mni-wm-level.ply", poly.GetNumberOfPoints(), "points")
