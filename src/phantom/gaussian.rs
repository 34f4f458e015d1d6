//! Phantoms surfaced from Gaussian-filtered label volumes, as marching cubes sees a smoothed
//! image: the sphere of Moench 2012 Table 3, with parts of some slices deleted before the
//! filter, so its staircases are smooth ramps rather than sharp steps (what most exported
//! surfaces look like, and what a fixed orientation-change threshold of 0.7 misses).

use super::marching_cubes::{extract_surface_interpolated, BorderEnds};
use super::volume::LabelVolume;
use crate::mesh::Mesh;
use rayon::prelude::*;

/// Parts of the sphere deleted slice-wise before filtering: the voxels of the slices whose
/// centres lie `z_mm` (a half-open range, relative to the sphere centre) above the centre,
/// within the sector `sector_deg` (angle about the z axis, from +x towards +y), and deeper than
/// `depth_mm` inside the sphere's outline in their own slice are kept; the rest of the sector
/// (the outer `depth_mm`) is removed. `depth_mm` infinite removes the whole sector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SliceCut {
    pub z_mm: (f64, f64),
    pub sector_deg: (f64, f64),
    pub depth_mm: f64,
}

/// The cuts of `sphere-gauss-cut` (radius 50 mm on 1 x 1 x 3 mm slices): a groove four slices
/// high and 4 mm deep above the equator, a notch two slices high and 3 mm deep below it, and a
/// quarter of the topmost slice (as in Table 5).
pub const SPHERE_CUTS: [SliceCut; 3] = [
    SliceCut {
        z_mm: (12.0, 24.0),
        sector_deg: (0.0, 120.0),
        depth_mm: 4.0,
    },
    SliceCut {
        z_mm: (-27.0, -21.0),
        sector_deg: (180.0, 260.0),
        depth_mm: 3.0,
    },
    SliceCut {
        z_mm: (45.0, 51.0),
        sector_deg: (0.0, 90.0),
        depth_mm: f64::INFINITY,
    },
];

/// Gaussian filter width of `sphere-gauss-cut`, in voxels per axis (1 x 1 x 3 mm).
pub const SPHERE_SIGMA_VOXELS: [f64; 3] = [1.0, 1.0, 1.0];

/// The cut sphere before and after its cuts (label 1), on its 128 x 128 x 43 grid of
/// 1 x 1 x 3 mm voxels, and its centre (mm; jittered by the seed).
pub fn cut_sphere_volumes(seed: u64) -> (LabelVolume, LabelVolume, [f64; 3]) {
    sphere_volumes(seed, &SPHERE_CUTS)
}

fn sphere_volumes(seed: u64, cuts: &[SliceCut]) -> (LabelVolume, LabelVolume, [f64; 3]) {
    let mut rng = fastrand::Rng::with_seed(seed);
    let spacing = [1.0, 1.0, 3.0];
    let mut whole = LabelVolume::new([128, 128, 43], spacing, [0.0; 3]);
    let centre: [f64; 3] = std::array::from_fn(|k| 64.0 + (rng.f64() - 0.5) * spacing[k]);
    let radius = 50.0;
    whole.paint(
        &super::volume::Shape::Sphere {
            center: centre,
            radius,
        },
        1,
    );
    let mut cut = whole.clone();
    for c in cuts {
        let lo = [0.0, 0.0, centre[2] + c.z_mm.0];
        let hi = [128.0, 128.0, centre[2] + c.z_mm.1];
        cut.paint_where(lo, hi, 0, |p, current| {
            let dz = p[2] - centre[2];
            if current != 1 || dz < c.z_mm.0 || dz >= c.z_mm.1 {
                return false;
            }
            let (dx, dy) = (p[0] - centre[0], p[1] - centre[1]);
            let angle = dy.atan2(dx).to_degrees().rem_euclid(360.0);
            let outline = (radius * radius - dz * dz).max(0.0).sqrt();
            angle >= c.sector_deg.0
                && angle < c.sector_deg.1
                && (dx * dx + dy * dy).sqrt() > outline - c.depth_mm
        });
    }
    (whole, cut, centre)
}

/// `blob-gauss`: three overlapping spheres (radii 18, 13 and 11 mm) on a 1 x 1 x 3 mm grid,
/// Gaussian-filtered like the sphere: a rounded shape with no clipped surface, so no caps.
pub fn blob_volume(seed: u64) -> LabelVolume {
    let mut rng = fastrand::Rng::with_seed(seed);
    let spacing = [1.0, 1.0, 3.0];
    let mut v = LabelVolume::new([80, 80, 30], spacing, [0.0; 3]);
    let jitter: [f64; 3] = std::array::from_fn(|k| (rng.f64() - 0.5) * spacing[k]);
    let at = |c: [f64; 3]| -> [f64; 3] { std::array::from_fn(|k| c[k] + jitter[k]) };
    v.paint(
        &super::volume::Shape::Union(vec![
            super::volume::Shape::Sphere {
                center: at([40.0, 40.0, 45.0]),
                radius: 18.0,
            },
            super::volume::Shape::Sphere {
                center: at([53.0, 47.0, 56.0]),
                radius: 13.0,
            },
            super::volume::Shape::Sphere {
                center: at([28.0, 50.0, 34.0]),
                radius: 11.0,
            },
        ]),
        1,
    );
    v
}

/// The indicator of `label` filtered with a Gaussian of `sigma_voxels` per axis (separable,
/// truncated at 3 sigma, normalised; background beyond the border), one value per voxel in
/// [0, 1].
pub fn gaussian_indicator(volume: &LabelVolume, label: u16, sigma_voxels: [f64; 3]) -> Vec<f32> {
    let mut field: Vec<f32> = volume
        .labels
        .par_iter()
        .map(|&l| if l == label { 1.0 } else { 0.0 })
        .collect();
    let dims = volume.dims;
    let stride = [1, dims[0], dims[0] * dims[1]];
    for axis in 0..3 {
        let sigma = sigma_voxels[axis];
        if sigma <= 0.0 || !sigma.is_finite() {
            continue;
        }
        let reach = (3.0 * sigma).ceil() as isize;
        let mut kernel: Vec<f32> = (-reach..=reach)
            .map(|d| (-(d * d) as f64 / (2.0 * sigma * sigma)).exp() as f32)
            .collect();
        let sum: f32 = kernel.iter().sum();
        kernel.iter_mut().for_each(|w| *w /= sum);
        let n = dims[axis] as isize;
        let src = field.clone();
        field.par_iter_mut().enumerate().for_each(|(idx, out)| {
            let at = (idx / stride[axis]) as isize % n;
            let mut acc = 0.0;
            for (d, w) in (-reach..=reach).zip(&kernel) {
                let q = at + d;
                if (0..n).contains(&q) {
                    acc += w * src[(idx as isize + d * stride[axis] as isize) as usize];
                }
            }
            *out = acc;
        });
    }
    field
}

/// The surface of `sphere-gauss-cut` (`cut`) or `sphere-gauss` (the whole sphere): the
/// sphere's label volume filtered with a Gaussian of one voxel per axis and surfaced where the
/// filtered indicator crosses 1/2 (Moench 2012, Table 3). Returns the volume of voxels inside
/// (filtered indicator above 1/2) and the mesh.
pub fn gauss_sphere_surface(seed: u64, cut: bool, ends: BorderEnds) -> (LabelVolume, Mesh) {
    let (_, volume, _) = sphere_volumes(seed, if cut { &SPHERE_CUTS } else { &[] });
    gauss_surface(volume, ends)
}

/// The surface where label 1 of `volume`, Gaussian-filtered with one voxel per axis, crosses
/// 1/2, and the volume of voxels inside it.
pub fn gauss_surface(volume: LabelVolume, ends: BorderEnds) -> (LabelVolume, Mesh) {
    let smooth = gaussian_indicator(&volume, 1, SPHERE_SIGMA_VOXELS);
    let mut inside = volume;
    inside
        .labels
        .par_iter_mut()
        .zip(&smooth)
        .for_each(|(l, &g)| *l = u16::from(g > 0.5));
    let field: Vec<f32> = smooth.iter().map(|&g| 0.5 - g).collect();
    let mesh = extract_surface_interpolated(&inside, 1, ends, &field);
    (inside, mesh)
}
