"""Grey and white matter label maps from the MNI ICBM152 2009 tissue probability maps that
ship inside the nilearn wheel (PyPI), at 1 mm and down-sampled to 1 x 1 x 3 mm by slice
majority, as the papers compare thick-slice surfaces with a high-resolution reference.

    pip download --no-deps nilearn==0.14.1   # the wheel; nothing is installed
    python3 mni.py nilearn-0.14.1-py3-none-any.whl OUT_DIR

Writes OUT_DIR/mni-1mm.nii.gz and OUT_DIR/mni-1x1x3.nii.gz (uint16: 1 grey matter,
2 white matter; a voxel is white matter where its white-matter probability is at least 0.5
and not below the grey's, grey matter where the grey probability is at least 0.5). The thick
map's voxel takes the label most of its three 1 mm slices hold (ties: the lower label), and
its centre is the middle slice's centre, so both maps share world coordinates.
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
nz = labels.shape[2] // 3 * 3
blocks = labels[:, :, :nz].reshape(labels.shape[0], labels.shape[1], nz // 3, 3)
counts = np.stack([(blocks == v).sum(-1) for v in (0, 1, 2)], -1)
thick = counts.argmax(-1).astype(np.uint16)
aff3 = aff.copy()
aff3[:3, 2] *= 3
aff3[:3, 3] = aff[:3, 3] + aff[:3, 2]  # centre of the middle slice of each block
nib.save(nib.Nifti1Image(thick, aff3), f"{out}/mni-1x1x3.nii.gz")
print(labels.shape, thick.shape, [(labels == v).sum() for v in (1, 2)])
