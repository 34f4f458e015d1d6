"""Label maps for issue 62's checks, written with numpy + nibabel (not by destair's code).

Run from this folder: `python3 make.py` (numpy, scipy, nibabel). Every map is 0.8 x 0.8 x 2.5 mm
(x, y, z; z the coarse slice axis) unless its name says otherwise, an identity-rotation
affine, uint16 labels, gzip NIfTI-1. `truth.json` lists per map and label what is true of
the shape the voxels were drawn from (radius, axis, analytic cross-section).

Voxels are set where the voxel *centre* lies inside the analytic shape, as a thresholded
segmentation does.
"""
import json
import numpy as np
import nibabel as nib
from scipy import ndimage

SP = np.array([0.8, 0.8, 2.5])
truth = {}


def grid(dims, spacing=SP):
    idx = np.indices(dims).reshape(3, -1).T.astype(float)
    return idx * spacing, idx


def save(name, vol, spacing=SP, labels=None):
    aff = np.diag(list(spacing) + [1.0])
    img = nib.Nifti1Image(vol.astype(np.uint16), aff)
    img.header.set_xyzt_units("mm")
    nib.save(img, f"{name}.nii.gz")
    labels = labels or {}
    # Objects as scipy counts them: 26-connected (a 3 x 3 x 3 structure) and 6-connected.
    for value in np.unique(vol)[1:]:
        entry = labels.setdefault(str(int(value)), {})
        entry["voxels"] = int((vol == value).sum())
        entry["objects_26"] = int(ndimage.label(vol == value, np.ones((3, 3, 3)))[1])
        entry["objects_6"] = int(ndimage.label(vol == value)[1])
    truth[name] = {"spacing_mm": list(map(float, spacing)), "dims": list(vol.shape),
                   "labels": labels}


def tube_mask(pts, p0, d, r, half):
    """Centres within r of the segment p0 +- half * d (d unit)."""
    rel = pts - p0
    t = rel @ d
    perp = rel - np.outer(t, d)
    return (np.einsum("ij,ij->i", perp, perp) <= r * r) & (np.abs(t) <= half)


def tubes(name, direction, radii=(0.8, 1.0, 1.5, 2.0, 3.0, 4.0), dims=(150, 150, 40)):
    """One straight tube per label, side by side along y', each 30 mm long, centred."""
    d = np.asarray(direction, float)
    d /= np.linalg.norm(d)
    pts, _ = grid(dims)
    vol = np.zeros(len(pts), np.uint16)
    extent = np.asarray(dims) * SP
    # Offsets perpendicular to the tube, in the plane with the least extent used.
    side = np.cross(d, [0.0, 0.0, 1.0])
    if np.linalg.norm(side) < 1e-6:
        side = np.array([1.0, 0.0, 0.0])
    side /= np.linalg.norm(side)
    labels = {}
    n = len(radii)
    for i, r in enumerate(radii):
        centre = extent / 2 + side * (i - (n - 1) / 2) * 18.0
        m = tube_mask(pts, centre, d, r, 15.0)
        vol[m] = i + 1
        labels[str(i + 1)] = {"shape": "tube", "radius_mm": r, "centre_mm": list(centre),
                              "axis": list(d), "half_length_mm": 15.0,
                              "cross_section_mm2": float(np.pi * r * r)}
    save(name, vol.reshape(dims), labels=labels)


tubes("tubes-along-z", [0, 0, 1])
tubes("tubes-along-x", [1, 0, 0])
for deg in (20, 30, 45):
    a = np.radians(deg)
    tubes(f"tubes-z{deg}", [np.sin(a), 0.0, np.cos(a)])
tubes("tubes-xy30", [np.cos(np.radians(30)), np.sin(np.radians(30)), 0.0])

# Vessels one voxel across stepping one voxel per slice: along x (edge contacts) and along
# x and y (corner contacts only), 30 slices; and a 2 x 2 voxel one stepping the same way.
dims = (48, 48, 36)
vol = np.zeros(dims, np.uint16)
for k in range(3, 33):
    vol[5 + k, 6, k] = 1                    # edge steps (x per slice)
    vol[4 + k, 4 + k, k] = 2                # corner steps (x and y per slice)
for k in range(3, 33):
    vol[1 + k, 40 - k, k] = 3               # corner steps, the other diagonal
for k in range(3, 20):
    vol[20 + k:22 + k, 20 - k // 2:22 - k // 2, k] = 4   # 2 x 2 voxels, a step every slice
save("stepping-vessels", vol, labels={
    "1": {"shape": "one-voxel vessel, one voxel along x per slice"},
    "2": {"shape": "one-voxel vessel, one voxel along x and y per slice"},
    "3": {"shape": "one-voxel vessel, one voxel along x and -y per slice"},
    "4": {"shape": "2 x 2 voxel vessel, a step every slice"}})

# One-voxel sheets and walls: the voxels nearest a plane along each column.
dims = (60, 60, 30)
pts, idx = grid(dims)
vol = np.zeros(dims, np.uint16)
# A sheet across the coarse axis, tilted 30 degrees: per (i, j) column the k nearest it.
for i in range(5, 55):
    for j in range(5, 25):
        z = 30.0 + np.tan(np.radians(30)) * (i * 0.8 - 24.0)
        k = int(round(z / 2.5))
        if 0 <= k < dims[2]:
            vol[i, j, k] = 1
# A wall (plane containing z) at 30 degrees to x: per (j, k) row the i nearest it.
for j in range(30, 58):
    for k in range(3, 27):
        x = 10.0 + (j * 0.8 - 24.0) / np.tan(np.radians(30)) * 0.25
        i = int(round(x / 0.8))
        if 0 <= i < dims[0]:
            vol[i, j, k] = 2
save("sheets", vol, labels={
    "1": {"shape": "one-voxel sheet across z, 30 degrees"},
    "2": {"shape": "one-voxel wall containing z, 30 degrees to x"}})

# A helix of radius 8 mm, pitch 20 mm, tube radius 1.2 mm, axis along y (across slices).
dims = (40, 80, 14)
pts, _ = grid(dims)
c = np.asarray(dims) * SP / 2
s = np.linspace(0, 3 * 2 * np.pi, 4000)
curve = np.stack([c[0] + 8 * np.cos(s), c[1] - 30 + 20 * s / (2 * np.pi), c[2] + 8 * np.sin(s)], 1)
m = np.zeros(len(pts), bool)
for p in curve[::4]:
    m |= np.einsum("ij,ij->i", pts - p, pts - p) <= 1.2 ** 2
vol = np.zeros(len(pts), np.uint16)
vol[m] = 1
save("helix", vol.reshape(dims), labels={"1": {"shape": "helix tube r 1.2 mm", "radius_mm": 1.2}})

# Small labels: single voxels and 2 x 2 x 1 blocks, apart from each other.
dims = (30, 30, 10)
vol = np.zeros(dims, np.uint16)
vol[5, 5, 4] = 1
vol[15, 5, 5] = 2
vol[5, 15, 4:6] = 3
vol[15:17, 15:17, 4] = 4
vol[22:24, 22:24, 5] = 5
save("small", vol)

# A septum: label 3 one voxel thick between labels 1 and 2, on a plane at 35 degrees to the
# slices (across the coarse axis) and another at 25 degrees to x containing z.
dims = (36, 24, 16)
pts, idx = grid(dims)
n1 = np.array([np.sin(np.radians(35)), 0.0, np.cos(np.radians(35))])
dist = (pts - np.asarray(dims) * SP / 2) @ n1
vol = np.where(dist < 0, 1, 2).astype(np.uint16)
# The septum: voxels of label 2 with a label-1 face neighbour become 3 (one voxel thick).
v = vol.reshape(dims)
sep = np.zeros(dims, bool)
for ax in range(3):
    for sh in (1, -1):
        sep |= (v == 2) & (np.roll(v, sh, ax) == 1)
v[sep] = 3
keep = np.zeros(dims, bool)
keep[3:33, 3:21, 2:14] = True
v[~keep] = 0
save("septum", v, labels={"3": {"shape": "one-voxel septum at 35 degrees to the slices"}})

# A sphere of radius 12 mm.
dims = (40, 40, 16)
pts, _ = grid(dims)
c = np.asarray(dims) * SP / 2
m = np.einsum("ij,ij->i", pts - c, pts - c) <= 144.0
vol = np.zeros(len(pts), np.uint16)
vol[m] = 1
save("sphere", vol.reshape(dims), labels={"1": {"shape": "sphere r 12 mm",
                                                "volume_mm3": float(4 / 3 * np.pi * 12 ** 3)}})

with open("truth.json", "w") as f:
    json.dump(truth, f, indent=1)
