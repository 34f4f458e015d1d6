"""Context-analysis phantoms made by other tools (numpy label volumes, VTK surfaces), not by destair.

Run from this folder with numpy and vtk installed (pip install numpy vtk; made with VTK 9.7.2):
    python3 make.py
Every mesh is written by VTK's PLY writer; `truth.json` says what is true of each (grid in mm,
slice axis, the caps as outward normals). Shapes and grids differ from ../../../../shared/corpus on
purpose: these check that the rules generalise, the corpus that they hold on the reference meshes.
"""
import json
import numpy as np
import vtk
from vtk.util import numpy_support

truth = {}


def image(labels, spacing, origin=(0.0, 0.0, 0.0)):
    """vtkImageData of a (z, y, x) array."""
    img = vtk.vtkImageData()
    nz, ny, nx = labels.shape
    img.SetDimensions(nx, ny, nz)
    img.SetSpacing(*spacing)
    img.SetOrigin(*origin)
    arr = numpy_support.numpy_to_vtk(labels.ravel(order="C"), deep=True)
    img.GetPointData().SetScalars(arr)
    return img


def grid(shape, spacing):
    """World coordinates (x, y, z) of the voxel centres of a (z, y, x) volume."""
    nz, ny, nx = shape
    z, y, x = np.meshgrid(
        np.arange(nz) * spacing[2], np.arange(ny) * spacing[1], np.arange(nx) * spacing[0], indexing="ij"
    )
    return x, y, z


def smoothed(smoother, poly, iterations):
    """`poly` after `iterations` of a VTK smoothing filter (features and boundary smoothed too)."""
    smoother.SetInputData(poly)
    smoother.SetNumberOfIterations(iterations)
    smoother.FeatureEdgeSmoothingOff()
    smoother.BoundarySmoothingOn()
    smoother.Update()
    return smoother.GetOutput()


def surface(img, discrete=True, flying=False, smooth_iterations=0, sinc_iterations=0):
    if discrete:
        mc = vtk.vtkDiscreteFlyingEdges3D() if flying else vtk.vtkDiscreteMarchingCubes()
        mc.SetValue(0, 1)
    else:
        mc = vtk.vtkFlyingEdges3D()
        mc.SetValue(0, 0.0)
        mc.ComputeNormalsOff()
    mc.SetInputData(img)
    mc.Update()
    out = mc.GetOutput()
    if smooth_iterations:
        # Uniform Laplace, lambda 0.5: another implementation than destair's.
        s = vtk.vtkSmoothPolyDataFilter()
        s.SetRelaxationFactor(0.5)
        s.SetConvergence(0.0)
        out = smoothed(s, out, smooth_iterations)
    if sinc_iterations:
        # Windowed sinc (pass band 0.1), the smoothing segmentation tools apply at export.
        s = vtk.vtkWindowedSincPolyDataFilter()
        s.SetPassBand(0.1)
        s.NormalizeCoordinatesOn()
        out = smoothed(s, out, sinc_iterations)
    clean = vtk.vtkPolyDataNormals()  # outward, consistent orientation
    clean.SetInputData(out)
    clean.ConsistencyOn()
    clean.AutoOrientNormalsOn()
    clean.SplittingOff()
    clean.ComputePointNormalsOff()
    clean.Update()
    return clean.GetOutput()


def write(name, poly, **facts):
    w = vtk.vtkPLYWriter()
    w.SetFileName(name + ".ply")
    w.SetInputData(poly)
    w.SetFileTypeToBinary()
    w.Write()
    facts["n_triangles"] = poly.GetNumberOfCells()
    truth[name] = facts


def blob(name, seed, spacing, n=12, flying=True, axes_mm=(3.0, 8.0), smooth_iterations=0):
    """A union of rotated ellipsoids (one object): no cap, stack axis z."""
    rng = np.random.default_rng(seed)
    size = (40.0, 40.0, 40.0)
    shape = tuple(int(size[k] / spacing[2 - k]) + 1 for k in range(3))
    x, y, z = grid(shape, spacing)
    inside = np.zeros(shape, bool)
    centre = np.array([20.0, 20.0, 20.0])
    for i in range(n):
        c = centre + (rng.uniform(-7, 7, 3) if i else 0)
        axes = rng.uniform(*axes_mm, 3)
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        d = np.stack([x - c[0], y - c[1], z - c[2]], -1) @ q
        inside |= ((d / axes) ** 2).sum(-1) <= 1.0
    inside[[0, -1], :, :] = inside[:, [0, -1], :] = inside[:, :, [0, -1]] = False
    poly = surface(
        image(inside.astype(np.uint8), spacing), flying=flying, smooth_iterations=smooth_iterations
    )
    write(
        name, poly, grid_mm=list(spacing), stack_axis=[0, 0, 1], caps=[],
        smoothed=smooth_iterations,
    )


def tube(name, spacing, radius, axis, length, smooth_iterations=0, sinc_iterations=0):
    """A straight tube with both ends cut flat inside the volume: two caps along its axis."""
    size = [length + 10.0, 2 * radius + 10.0, 2 * radius + 10.0]
    order = {"x": (0, 1, 2), "y": (1, 0, 2), "z": (2, 1, 0)}[axis]
    ext = [0.0, 0.0, 0.0]
    for k, o in enumerate(order):
        ext[o] = size[k]
    shape = tuple(int(ext[2 - k] / spacing[2 - k]) + 1 for k in range(3))
    x, y, z = grid(shape, spacing)
    p = [x, y, z]
    a, b, c = (p[o] - ext[o] / 2 for o in order)
    inside = (b**2 + c**2 <= radius**2) & (np.abs(a) <= length / 2)
    poly = surface(
        image(inside.astype(np.uint8), spacing),
        smooth_iterations=smooth_iterations,
        sinc_iterations=sinc_iterations,
    )
    n = [0, 0, 0]
    n[order[0]] = 1
    write(
        name, poly, grid_mm=list(spacing), stack_axis=[0, 0, 1],
        caps=[n, [-v for v in n]], smoothed=smooth_iterations + sinc_iterations,
    )


def cylinder_cuboid(name, spacing, radius, smooth_iterations):
    """Paper 004 section 4.3: a cylinder along z merged with a cuboid protruding along +x."""
    cx = cy = radius + 6.0
    size = (2 * radius + 6.0 + radius + 14.0, 2 * radius + 12.0, 3.4 * radius + 12.0)
    shape = tuple(int(size[2 - k] / spacing[2 - k]) + 1 for k in range(3))
    x, y, z = grid(shape, spacing)
    z0, z1 = 6.0, 6.0 + 3.4 * radius
    cyl = ((x - cx) ** 2 + (y - cy) ** 2 <= radius**2) & (z >= z0) & (z <= z1)
    zm = 0.5 * (z0 + z1)
    box = (x >= cx) & (x <= cx + radius + 10.0) & (np.abs(y - cy) <= 0.65 * radius) & (
        np.abs(z - zm) <= 0.8 * radius
    )
    inside = cyl | box
    poly = surface(image(inside.astype(np.uint8), spacing), smooth_iterations=smooth_iterations)
    write(
        name, poly, grid_mm=list(spacing), stack_axis=[0, 0, 1],
        caps=[[0, 0, 1], [0, 0, -1], [1, 0, 0]], smoothed=smooth_iterations, tau=0.2,
    )


def weak_sphere(name, spacing, removed, radius=15.0, cut="slice"):
    """Paper 004 Table 5: a sphere from a signed distance field (no flat part), with a share of
    its topmost slice removed. cut="flat": the removed part ends at the plane halfway between
    the top two slices (a flat area facing +z, as a binary cut gives); cut="slice": its values
    are set to one slice thickness, so the surface slopes down to the slice below (no flat
    area: nothing to estimate from, and the answer must not be a wrong axis)."""
    size = 2 * radius + 8.0
    shape = tuple(int(size / spacing[2 - k]) + 1 for k in range(3))
    x, y, z = grid(shape, spacing)
    c = size / 2
    sdf = np.sqrt((x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2) - radius
    # The topmost slice holding the sphere, and the sector of it removed (angle from +x).
    top = max(k for k in range(shape[0]) if (sdf[k] < 0).any())
    angle = np.mod(np.arctan2(y - c, x - c), 2 * np.pi)
    sector = angle < 2 * np.pi * removed
    field = sdf.copy()
    if cut == "flat":
        plane = (top - 0.5) * spacing[2]
        field = np.where(sector, np.maximum(sdf, z - plane), sdf)
    else:
        field[top][sector[top]] = np.maximum(field[top][sector[top]], spacing[2])
    poly = surface(image(field.astype(np.float32), spacing), discrete=False)
    write(name, poly, grid_mm=list(spacing), stack_axis=[0, 0, 1], removed=removed, cut=cut)


def inplane_vessel(name, spacing, radius, direction_deg, length=30.0):
    """A vessel lying in the slice plane (its axis at `direction_deg` from x, in x-y), ends cut."""
    size = (length + 12.0, length + 12.0, 2 * radius + 8.0)
    shape = tuple(int(size[2 - k] / spacing[2 - k]) + 1 for k in range(3))
    x, y, z = grid(shape, spacing)
    t = np.radians(direction_deg)
    d = np.array([np.cos(t), np.sin(t)])
    px, py, pz = x - size[0] / 2, y - size[1] / 2, z - size[2] / 2
    along = px * d[0] + py * d[1]
    across = -px * d[1] + py * d[0]
    inside = (across**2 + pz**2 <= radius**2) & (np.abs(along) <= length / 2)
    poly = surface(image(inside.astype(np.uint8), spacing))
    write(name, poly, grid_mm=list(spacing), stack_axis=[0, 0, 1], radius_mm=radius,
          direction=[float(d[0]), float(d[1]), 0.0], centre_mm=[float(v / 2) for v in size],
          length_mm=length)


def crossing_vessel(name, spacing, radius, azimuth_deg, elevation_deg, length=30.0):
    """A straight vessel crossing the slices (its axis `elevation_deg` out of the slice plane,
    at `azimuth_deg` from x within it), ends cut: the comparison for the in-plane vessels."""
    e, a = np.radians(elevation_deg), np.radians(azimuth_deg)
    d = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    size = (length + 12.0, length + 12.0, length * np.sin(e) + 2 * radius + 8.0)
    shape = tuple(int(size[2 - k] / spacing[2 - k]) + 1 for k in range(3))
    x, y, z = grid(shape, spacing)
    px, py, pz = x - size[0] / 2, y - size[1] / 2, z - size[2] / 2
    along = px * d[0] + py * d[1] + pz * d[2]
    inside = (px**2 + py**2 + pz**2 - along**2 <= radius**2) & (np.abs(along) <= length / 2)
    poly = surface(image(inside.astype(np.uint8), spacing))
    write(name, poly, grid_mm=list(spacing), stack_axis=[0, 0, 1], radius_mm=radius,
          direction=[float(v) for v in d], centre_mm=[float(v / 2) for v in size],
          length_mm=length)


blob("blob-s7", 7, (0.6, 0.6, 2.0))
blob("blob-s11", 11, (0.4, 0.4, 1.2), flying=False)
# Its inner corners hold chamfer strips the surface leaves outwards all round: dents, no caps.
blob("blob-s30", 30, (0.45, 0.45, 3.0), flying=False)
# A tumour-like blob on the neck's grid after 80 Laplace iterations by VTK: its terraces are
# rounded off, while an oblique planar facet of the binary surface stays nearly flat (0.44 %
# of the area, 71 degrees from z, alone in its direction, its normals spread by 0.65 degrees):
# weak evidence that must not give a wrong axis.
blob("blob-s4-l80", 4, (0.45, 0.45, 3.0), n=6, flying=False, axes_mm=(5.0, 12.0), smooth_iterations=80)
tube("tube-along-z", (0.5, 0.5, 2.5), 4.0, "z", 40.0)
tube("tube-along-x", (0.5, 0.5, 2.5), 4.0, "x", 30.0)
tube("tube-along-z-thin", (0.4, 0.4, 2.0), 2.0, "z", 30.0)
# Two pixels across: its section is a diamond of corner facets, with no wall facing a grid axis.
tube("tube-along-z-diamond", (0.5, 0.5, 2.5), 1.0, "z", 20.0)
# Along the slices, smoothed at export: off its grid, its long flat walls outweigh the end discs.
tube("tube-along-z-sinc5", (0.45, 0.45, 3.0), 7.0, "z", 60.0, sinc_iterations=5)
tube("tube-along-z-sinc10", (0.45, 0.45, 3.0), 7.0, "z", 60.0, sinc_iterations=10)
# Across the slices: its end discs, three slices tall, hold no vertex away from a chamfer.
tube("tube-along-y", (0.8, 0.8, 2.5), 4.0, "y", 24.0)
cylinder_cuboid("cylinder-cuboid-r12-s1.5-l30", (1.0, 1.0, 1.5), 12.0, 30)
cylinder_cuboid("cylinder-cuboid-r24-s3-l50", (1.0, 1.0, 3.0), 24.0, 50)
cylinder_cuboid("cylinder-cuboid-r15-s2-l0", (1.0, 1.0, 2.0), 15.0, 0)
# The paper's radius on a finer grid, smoothed less and more.
cylinder_cuboid("cylinder-cuboid-r18-s2.4-l20", (0.8, 0.8, 2.4), 18.0, 20)
cylinder_cuboid("cylinder-cuboid-r18-s2.4-l40", (0.8, 0.8, 2.4), 18.0, 40)
weak_sphere("sphere-quarter", (1.0, 1.0, 3.0), 0.25)
weak_sphere("sphere-eighth", (1.0, 1.0, 3.0), 0.125)
weak_sphere("sphere-cut-eighth", (1.0, 1.0, 3.0), 0.125, cut="flat")
weak_sphere("sphere-cut-quarter", (0.8, 0.8, 2.4), 0.25, radius=20.0, cut="flat")
weak_sphere("sphere-cut-sixteenth", (1.0, 1.0, 3.0), 0.0625, cut="flat")
inplane_vessel("vessel-inplane-x", (0.4, 0.4, 0.8), 1.2, 0.0)
inplane_vessel("vessel-inplane-30", (0.4, 0.4, 0.8), 1.5, 30.0)
crossing_vessel("vessel-crossing-45", (0.4, 0.4, 0.8), 1.5, 20.0, 45.0)

with open("truth.json", "w") as f:
    json.dump(truth, f, indent=1, sort_keys=True)
