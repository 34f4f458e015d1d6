//! Named phantom cases modelled on the papers' test data, and a small varied cohort.
//!
//! Each case is a label volume painted from analytic shapes and turned into one mesh per
//! structure by discrete marching cubes; `seed` jitters centres by up to half a voxel so that
//! different seeds give different (but reproducible) staircases.

use super::marching_cubes::{extract_surface, BorderEnds};
use super::volume::{apply, rotation_matrix, LabelVolume, Shape};
use crate::io::ply::write_ply;
use crate::io::{write_atomically, MeshMeta, WriteError};
use crate::mesh::Mesh;
use serde::Serialize;
use std::path::Path;
use thiserror::Error;

/// The named cases `destair phantom` knows.
pub const CASE_NAMES: [&str; 12] = [
    "sphere-iso",
    "sphere-aniso",
    "sphere-aniso-1-16",
    "sphere-aniso-1-8",
    "sphere-aniso-1-4",
    "sphere-aniso-1-2",
    "sphere-aniso-top",
    "cap-cylinder",
    "neck",
    "neck-groove",
    "aneurysm",
    "thin-vessel",
];

/// Smooth-surface variants (marching cubes on a smooth field rather than a binary mask): the
/// paper's sphere, where the only staircase is the removed part of the top slice, and the
/// Gaussian-filtered sphere with smooth staircases ([`super::gaussian`]).
pub const SMOOTH_CASE_NAMES: [&str; 9] = [
    "sphere-smooth",
    "sphere-smooth-1-16",
    "sphere-smooth-1-8",
    "sphere-smooth-1-4",
    "sphere-smooth-1-2",
    "sphere-smooth-top",
    "sphere-gauss",
    "sphere-gauss-cut",
    "blob-gauss",
];

/// Options shared by all phantoms.
#[derive(Debug, Clone, Copy, Default)]
pub struct PhantomOptions {
    /// Rigid rotation of the finished meshes about the volume centre, x first (degrees).
    pub rotate_x_deg: f64,
    /// Then about y (degrees).
    pub rotate_y_deg: f64,
    pub seed: u64,
    /// Where structures leave the volume: flat caps or open rims.
    pub ends: BorderEnds,
}

/// A structure of a phantom case and what it was made from.
#[derive(Debug, Clone, Serialize)]
pub struct StructureInfo {
    pub name: String,
    pub label: u16,
    pub n_voxels: usize,
    pub n_vertices: usize,
    pub n_triangles: usize,
}

/// Description of a generated case, written as `phantom.json` beside its meshes.
#[derive(Debug, Clone, Serialize)]
pub struct CaseInfo {
    pub name: String,
    pub description: String,
    pub seed: u64,
    pub dims: [usize; 3],
    /// Grid spacing in mm (the voxel size `inspect` should reconstruct when not rotated).
    pub spacing_mm: [f64; 3],
    pub origin_mm: [f64; 3],
    pub rotate_x_deg: f64,
    pub rotate_y_deg: f64,
    pub ends: BorderEnds,
    pub structures: Vec<StructureInfo>,
}

/// A generated case: one mesh per structure.
#[derive(Debug, Clone)]
pub struct PhantomCase {
    pub info: CaseInfo,
    pub meshes: Vec<(String, Mesh)>,
}

/// Why a phantom could not be made or written.
#[derive(Debug, Error)]
pub enum PhantomError {
    #[error("unknown phantom {0:?}; known: {known}, {smooth}, {maps}, big, cohort", known = CASE_NAMES.join(", "), smooth = SMOOTH_CASE_NAMES.join(", "), maps = LABEL_MAP_NAMES.join(", "))]
    UnknownName(String),
    #[error("{0}")]
    Write(#[from] WriteError),
    #[error("{}: {source}", path.display())]
    Io {
        path: std::path::PathBuf,
        source: std::io::Error,
    },
}

/// Sub-voxel jitter in [-0.5, 0.5) voxel per axis, from the seed.
fn jitter(rng: &mut fastrand::Rng, spacing: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|k| (rng.f64() - 0.5) * spacing[k])
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// Generates a named case (see [`CASE_NAMES`]).
pub fn named_case(name: &str, options: &PhantomOptions) -> Result<PhantomCase, PhantomError> {
    if name == "blob-gauss" {
        let (inside, mesh) = super::gaussian::gauss_surface(
            super::gaussian::blob_volume(options.seed),
            options.ends,
        );
        let description = "three overlapping spheres (radii 18, 13, 11 mm) on a 1 x 1 x 3 mm grid, Gaussian-filtered (sigma one voxel) and surfaced at 1/2: rounded, nothing clipped, no caps";
        return Ok(with_mesh(name, description, inside, mesh, options));
    }
    if let Some(suffix) = name.strip_prefix("sphere-gauss") {
        if suffix.is_empty() || suffix == "-cut" {
            return Ok(gauss_sphere(name, suffix == "-cut", options));
        }
    }
    let mut rng = fastrand::Rng::with_seed(options.seed);
    if let Some(fraction) = name.strip_prefix("sphere-smooth").and_then(cut_fraction) {
        return Ok(smooth_sphere(name, fraction, &mut rng, options));
    }
    let (description, volume, structures) = match name {
        "sphere-iso" => {
            let spacing = [1.0; 3];
            let mut v = LabelVolume::new([66, 66, 66], spacing, [0.0; 3]);
            let center = add([32.5; 3], jitter(&mut rng, spacing));
            v.paint(
                &Shape::Sphere {
                    center,
                    radius: 30.0,
                },
                1,
            );
            (
                "binary sphere of diameter 60 voxels on a 1 mm grid (Bade 2007, Fig. 7)",
                v,
                vec![("sphere", 1)],
            )
        }
        n if n.starts_with("sphere-aniso") => {
            let Some(fraction) = cut_fraction(&n["sphere-aniso".len()..]) else {
                return Err(PhantomError::UnknownName(n.to_string()));
            };
            let spacing = [1.0, 1.0, 3.0];
            let mut v = LabelVolume::new([128, 128, 43], spacing, [0.0; 3]);
            let center = add([64.0, 64.0, 64.0], jitter(&mut rng, spacing));
            v.paint(
                &Shape::Sphere {
                    center,
                    radius: 50.0,
                },
                1,
            );
            remove_top_sector(&mut v, 1, center, fraction);
            ("sphere of radius 50 mm on a 1 x 1 x 3 mm grid with part of its top slice removed (Moench 2012, Table 5)", v, vec![("sphere", 1)])
        }
        "cap-cylinder" => {
            let spacing = [1.0, 1.0, 2.0];
            // Large enough (in voxels) that 50 Laplace iterations round the rims but leave the
            // caps flat, as in the paper's experiment.
            let mut v = LabelVolume::new([116, 84, 54], spacing, [0.0; 3]);
            let j = jitter(&mut rng, spacing);
            let cylinder = Shape::Cylinder {
                start: add([38.0, 42.0, 12.0], j),
                end: add([38.0, 42.0, 92.0], j),
                radius: 26.0,
            };
            let cuboid = Shape::Cuboid {
                center: add([76.0, 42.0, 52.0], j),
                half_extent: [24.0, 18.0, 16.0],
                rotation_deg: [8.0, 14.0, 0.0],
            };
            v.paint(&Shape::Union(vec![cylinder, cuboid]), 1);
            ("cylinder with flat caps merged with a tilted cuboid on a 1 x 1 x 2 mm grid (Moench 2012, §4.3)", v, vec![("cap-cylinder", 1)])
        }
        "neck" => {
            let v = neck_volume(
                &mut rng,
                [160, 160, 20],
                [0.45, 0.45, 3.0],
                1.0,
                VeinAt::Apart,
            );
            ("tumor, vein and trachea at 0.45 x 0.45 x 3 mm; the vein passes a few tenths of a mm from the tumor (Moench 2010, distance-aware)", v, vec![("tumor", 1), ("vein", 2), ("trachea", 3)])
        }
        "neck-groove" => {
            let v = neck_volume(
                &mut rng,
                [160, 160, 20],
                [0.45, 0.45, 3.0],
                1.0,
                VeinAt::Groove,
            );
            ("the neck with the vein in a groove of the tumor, one voxel (0.45 mm) apart: smoothing the tumor fills the groove towards the vein", v, vec![("tumor", 1), ("vein", 2), ("trachea", 3)])
        }
        "aneurysm" => {
            let v = aneurysm_volume(&mut rng);
            ("vessel bifurcation with a saccular aneurysm at 0.4 mm isotropic, clipped at the volume border, with a hand-painted block of slices that leaves a staircase (Moench 2012, §5)", v, vec![("aneurysm", 1)])
        }
        "thin-vessel" => {
            let spacing = [0.4; 3];
            let mut v = LabelVolume::new([24, 24, 50], spacing, [0.0; 3]);
            let j = jitter(&mut rng, spacing);
            let tube = Shape::Tube {
                points: vec![add([4.4, 4.6, -1.0], j), add([5.6, 4.6, 21.0], j)],
                radii: vec![0.45, 0.45],
            };
            v.paint(&tube, 1);
            ("a straight vessel two voxels across (0.9 mm at 0.4 mm isotropic), slightly oblique, clipped at both ends: uniform smoothing pinches it", v, vec![("vessel", 1)])
        }
        other => return Err(PhantomError::UnknownName(other.to_string())),
    };
    Ok(finish(name, description, volume, &structures, options))
}

/// The share of the top slice a name suffix removes ("" none, "-1-8" an eighth, "-top" all).
fn cut_fraction(suffix: &str) -> Option<f64> {
    Some(match suffix {
        "" => 0.0,
        "-1-16" => 1.0 / 16.0,
        "-1-8" => 1.0 / 8.0,
        "-1-4" => 0.25,
        "-1-2" => 0.5,
        "-top" => 1.0,
        _ => return None,
    })
}

/// The sphere of `sphere-aniso`, but surfaced from its signed distance field as marching cubes
/// does on a smoothed image (Moench 2012, §4.1): smooth except where part of the top slice was
/// removed, which leaves a staircase.
fn smooth_sphere(
    name: &str,
    fraction: f64,
    rng: &mut fastrand::Rng,
    options: &PhantomOptions,
) -> PhantomCase {
    let spacing = [1.0, 1.0, 3.0];
    let mut v = LabelVolume::new([128, 128, 43], spacing, [0.0; 3]);
    let center = add([64.0, 64.0, 64.0], jitter(rng, spacing));
    let radius = 50.0;
    v.paint(&Shape::Sphere { center, radius }, 1);
    remove_top_sector(&mut v, 1, center, fraction);
    let [nx, ny, nz] = v.dims;
    let mut field = vec![0.0f32; nx * ny * nz];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = v.center(i, j, k);
                let d = (0..3)
                    .map(|a| (p[a] - center[a]).powi(2))
                    .sum::<f64>()
                    .sqrt()
                    - radius;
                let idx = v.index(i, j, k);
                // Removed voxels are outside by half a slice, whatever the sphere says.
                field[idx] = if v.labels[idx] == 1 {
                    d.min(-1e-3) as f32
                } else {
                    d.max(0.5 * spacing[2]) as f32
                };
            }
        }
    }
    let mut case = finish(name, "sphere of radius 50 mm on a 1 x 1 x 3 mm grid surfaced from its distance field (smooth, as after Gaussian filtering), with part of its top slice removed (Moench 2012, Tables 3 and 5)", v.clone(), &[], options);
    let mut mesh = super::marching_cubes::extract_surface_interpolated(&v, 1, options.ends, &field);
    rotate(&mut mesh, &v, options);
    case.info.structures.push(StructureInfo {
        name: "sphere".into(),
        label: 1,
        n_voxels: v.count(1),
        n_vertices: mesh.n_vertices(),
        n_triangles: mesh.n_triangles(),
    });
    case.meshes.push(("sphere".into(), mesh));
    case
}

/// `sphere-gauss` and `sphere-gauss-cut` ([`super::gaussian`]) as a case.
fn gauss_sphere(name: &str, cut: bool, options: &PhantomOptions) -> PhantomCase {
    let (inside, mesh) = super::gaussian::gauss_sphere_surface(options.seed, cut, options.ends);
    let description = if cut {
        "sphere of radius 50 mm on a 1 x 1 x 3 mm grid with parts of seven slices deleted (a groove, a notch, a quarter of the top slice), Gaussian-filtered (sigma one voxel) and surfaced at 1/2: smooth staircases (Moench 2012, Table 3)"
    } else {
        "sphere of radius 50 mm on a 1 x 1 x 3 mm grid, Gaussian-filtered (sigma one voxel) and surfaced at 1/2: no staircase but the slices' own faint ripple"
    };
    with_mesh(name, description, inside, mesh, options)
}

/// A case of one structure (label 1, named after the case's first word) whose mesh was made
/// outside [`finish`]; rotated as the options say.
fn with_mesh(
    name: &str,
    description: &str,
    inside: LabelVolume,
    mut mesh: Mesh,
    options: &PhantomOptions,
) -> PhantomCase {
    let structure = name.split('-').next().unwrap_or(name).to_string();
    rotate(&mut mesh, &inside, options);
    let n_voxels = inside.count(1);
    let mut case = finish(name, description, inside, &[], options);
    case.info.structures.push(StructureInfo {
        name: structure.clone(),
        label: 1,
        n_voxels,
        n_vertices: mesh.n_vertices(),
        n_triangles: mesh.n_triangles(),
    });
    case.meshes.push((structure, mesh));
    case
}

/// Removes the sector of the sphere's topmost slice whose angle about the centre is below
/// `fraction` of a full turn (1/4 removes a quadrant, 1 the whole slice).
fn remove_top_sector(v: &mut LabelVolume, label: u16, center: [f64; 3], fraction: f64) {
    if fraction <= 0.0 {
        return;
    }
    let slice = v.dims[0] * v.dims[1];
    let Some(top) = (0..v.dims[2])
        .rev()
        .find(|&k| v.labels[k * slice..(k + 1) * slice].contains(&label))
    else {
        return;
    };
    let z = v.origin[2] + top as f64 * v.spacing[2];
    let lo = [v.origin[0], v.origin[1], z];
    let hi = [
        v.origin[0] + v.dims[0] as f64 * v.spacing[0],
        v.origin[1] + v.dims[1] as f64 * v.spacing[1],
        z,
    ];
    v.paint_where(lo, hi, 0, |p, current| {
        let angle = (p[1] - center[1])
            .atan2(p[0] - center[0])
            .rem_euclid(std::f64::consts::TAU);
        current == label && angle < fraction * std::f64::consts::TAU
    });
}

/// Where the neck phantom's vein lies against the tumour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum VeinAt {
    /// A few tenths of a mm from the tumour's side, one voxel of background between.
    Apart,
    /// Sharing a face with the tumour, as neighbouring segmentations do.
    Touching,
    /// In a groove of the tumour, one voxel of background between.
    Groove,
}

/// Tumor (1), vein (2) and trachea (3); `scale` shrinks the anatomy for small cohort cases.
fn neck_volume(
    rng: &mut fastrand::Rng,
    dims: [usize; 3],
    spacing: [f64; 3],
    scale: f64,
    vein_at: VeinAt,
) -> LabelVolume {
    let mut v = LabelVolume::new(dims, spacing, [0.0; 3]);
    let size: [f64; 3] = std::array::from_fn(|k| dims[k] as f64 * spacing[k]);
    let c = add(
        [0.45 * size[0], 0.5 * size[1], 0.5 * size[2]],
        jitter(rng, spacing),
    );
    let r = [9.0 * scale, 7.5 * scale, 0.3 * size[2].min(40.0 * scale)];
    let tumor = Shape::Union(vec![
        Shape::Ellipsoid {
            center: c,
            radii: r,
        },
        Shape::Ellipsoid {
            center: add(c, [-0.4 * r[0], 0.5 * r[1], 0.2 * r[2]]),
            radii: [0.6 * r[0], 0.6 * r[1], 0.7 * r[2]],
        },
    ]);
    v.paint(&tumor, 1);
    // The vein runs along z just past the tumor's +x side, bending slightly towards it.
    let vein_r = 3.5 * scale;
    // In a groove, the vein's axis lies inside the tumour's outline and the tumour wraps round it.
    let x0 = match vein_at {
        VeinAt::Groove => c[0] + r[0] + 0.2 * vein_r,
        _ => c[0] + r[0] + vein_r + 0.3,
    };
    let vein = Shape::Tube {
        points: vec![
            [x0 + 2.0 * scale, c[1] - 2.0 * scale, -5.0],
            [x0, c[1], c[2]],
            [x0 + 3.0 * scale, c[1] + 1.0 * scale, size[2] + 5.0],
        ],
        radii: vec![vein_r, vein_r, vein_r * 1.1],
    };
    let groove = vein_at == VeinAt::Groove;
    v.paint_where(vein.bounds().0, vein.bounds().1, 2, |p, current| {
        (current == 0 || (groove && current == 1)) && vein.contains(p)
    });
    if vein_at == VeinAt::Touching {
        // Segmentations of neighbours share a face where they touch: grow the vein into it.
        let x_touch = c[0] + r[0] + 0.5 * vein_r;
        let wider = Shape::Tube {
            points: vec![[x_touch, c[1], -5.0], [x_touch, c[1], size[2] + 5.0]],
            radii: vec![vein_r, vein_r],
        };
        v.paint_where(wider.bounds().0, wider.bounds().1, 2, |p, current| {
            current == 0 && wider.contains(p)
        });
    } else {
        separate_labels(&mut v, 2, 1);
    }
    let trachea_r = 8.0 * scale;
    let tx = c[0] - r[0] - trachea_r - 6.0 * scale;
    let trachea = Shape::Tube {
        points: vec![
            [tx, c[1] + 3.0 * scale, -5.0],
            [tx - 2.0 * scale, c[1] + 2.0 * scale, size[2] + 5.0],
        ],
        radii: vec![trachea_r, trachea_r],
    };
    v.paint_where(trachea.bounds().0, trachea.bounds().1, 3, |p, current| {
        current == 0 && trachea.contains(p)
    });
    v
}

/// Clears voxels of `label` that share a face with a voxel of `other`, so the two surfaces stay
/// apart (as separately segmented neighbours do) instead of meeting in a shared face.
fn separate_labels(v: &mut LabelVolume, label: u16, other: u16) {
    let [nx, ny, nz] = v.dims;
    let mut clear = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                if v.labels[v.index(i, j, k)] != label {
                    continue;
                }
                let neighbours = [
                    (i.wrapping_sub(1), j, k),
                    (i + 1, j, k),
                    (i, j.wrapping_sub(1), k),
                    (i, j + 1, k),
                    (i, j, k.wrapping_sub(1)),
                    (i, j, k + 1),
                ];
                if neighbours.iter().any(|&(a, b, c)| {
                    a < nx && b < ny && c < nz && v.labels[v.index(a, b, c)] == other
                }) {
                    clear.push(v.index(i, j, k));
                }
            }
        }
    }
    for idx in clear {
        v.labels[idx] = 0;
    }
}

/// A bifurcation with a saccular aneurysm, clipped at the volume border, and a block of slices
/// around one outlet repainted by hand: every 4 slices share one contour, leaving a staircase.
fn aneurysm_volume(rng: &mut fastrand::Rng) -> LabelVolume {
    let spacing = [0.4; 3];
    let mut v = LabelVolume::new([100, 100, 100], spacing, [0.0; 3]);
    let j = jitter(rng, spacing);
    let parent = Shape::Tube {
        points: vec![add([20.0, 20.0, -3.0], j), add([20.0, 20.0, 18.0], j)],
        radii: vec![2.2, 2.0],
    };
    let left = Shape::Tube {
        points: vec![
            add([20.0, 20.0, 18.0], j),
            add([12.0, 18.0, 30.0], j),
            add([6.0, 16.0, 43.0], j),
        ],
        radii: vec![2.0, 1.7, 1.6],
    };
    let right = Shape::Tube {
        points: vec![
            add([20.0, 20.0, 18.0], j),
            add([28.0, 22.0, 28.0], j),
            add([31.0, 24.0, 43.0], j),
        ],
        radii: vec![2.0, 1.8, 1.7],
    };
    let sac = Shape::Sphere {
        center: add([20.5, 20.0, 24.5], j),
        radius: 5.0,
    };
    let neck = Shape::Cylinder {
        start: add([20.0, 20.0, 18.0], j),
        end: add([20.4, 20.0, 21.0], j),
        radius: 2.5,
    };
    v.paint(
        &Shape::Union(vec![parent, left, right.clone(), sac, neck]),
        1,
    );
    // Hand-painted block along the right outlet: slices 75..87, in groups of 4.
    let (k0, k1, group) = (75usize, 87usize, 4usize);
    let z = |k: usize| v.origin[2] + k as f64 * spacing[2];
    let lo = [20.0, 10.0, z(k0)];
    let hi = [40.0, 40.0, z(k1 - 1)];
    v.paint_where(lo, hi, 0, |_, current| current == 1);
    let origin_z = v.origin[2];
    v.paint_where(lo, hi, 1, |p, _| {
        let k = ((p[2] - origin_z) / spacing[2]).round() as usize;
        let middle = k0 + k.saturating_sub(k0) / group * group + group / 2;
        right.contains([p[0], p[1], origin_z + middle as f64 * spacing[2]])
    });
    v
}

/// A stair-stepped blob of about `n_triangles` triangles on a 1 x 1 x 3 mm grid, for benchmarks.
pub fn big_case(n_triangles: u64, options: &PhantomOptions) -> PhantomCase {
    let blob = |radius: f64, rng: &mut fastrand::Rng| {
        let spacing = [1.0, 1.0, 3.0];
        let dims = [
            (2.3 * radius) as usize + 4,
            (2.1 * radius) as usize + 4,
            (2.0 * radius / 3.0) as usize + 4,
        ];
        let mut v = LabelVolume::new(dims, spacing, [0.0; 3]);
        let c = add(
            [1.15 * radius + 2.0, 1.05 * radius + 2.0, radius + 3.0],
            jitter(rng, spacing),
        );
        v.paint(
            &Shape::Union(vec![
                Shape::Ellipsoid {
                    center: c,
                    radii: [radius, 0.8 * radius, 0.75 * radius],
                },
                Shape::Ellipsoid {
                    center: add(c, [0.45 * radius, 0.3 * radius, 0.1 * radius]),
                    radii: [0.6 * radius, 0.7 * radius, 0.9 * radius],
                },
                Shape::Sphere {
                    center: add(c, [-0.5 * radius, -0.35 * radius, -0.2 * radius]),
                    radius: 0.5 * radius,
                },
            ]),
            1,
        );
        v
    };
    // Triangle count grows with the square of the radius: calibrate on a small blob.
    let probe_radius = 40.0;
    let probe = extract_surface(
        &blob(probe_radius, &mut fastrand::Rng::with_seed(options.seed)),
        1,
        options.ends,
    );
    let radius = probe_radius * (n_triangles as f64 / probe.n_triangles().max(1) as f64).sqrt();
    let mut rng = fastrand::Rng::with_seed(options.seed);
    let volume = blob(radius.max(2.0), &mut rng);
    finish(
        "big",
        "stair-stepped blob on a 1 x 1 x 3 mm grid for benchmarks",
        volume,
        &[("blob", 1)],
        options,
    )
}

/// Extracts each structure, applies the rotation and records what was made.
/// Rotates a finished mesh about the volume centre (x first, then y).
fn rotate(mesh: &mut Mesh, volume: &LabelVolume, options: &PhantomOptions) {
    if options.rotate_x_deg == 0.0 && options.rotate_y_deg == 0.0 {
        return;
    }
    let rotation = rotation_matrix([options.rotate_x_deg, options.rotate_y_deg, 0.0]);
    let center: [f64; 3] = std::array::from_fn(|k| {
        volume.origin[k] + 0.5 * (volume.dims[k] as f64 - 1.0) * volume.spacing[k]
    });
    for p in mesh.positions_mut() {
        let d = [
            p[0] as f64 - center[0],
            p[1] as f64 - center[1],
            p[2] as f64 - center[2],
        ];
        let r = apply(&rotation, d);
        *p = std::array::from_fn(|k| (center[k] + r[k]) as f32);
    }
}

fn finish(
    name: &str,
    description: &str,
    volume: LabelVolume,
    structures: &[(&str, u16)],
    options: &PhantomOptions,
) -> PhantomCase {
    let mut meshes = Vec::new();
    let mut infos = Vec::new();
    for &(structure, label) in structures {
        let mut mesh = extract_surface(&volume, label, options.ends);
        rotate(&mut mesh, &volume, options);
        infos.push(StructureInfo {
            name: structure.to_string(),
            label,
            n_voxels: volume.count(label),
            n_vertices: mesh.n_vertices(),
            n_triangles: mesh.n_triangles(),
        });
        meshes.push((structure.to_string(), mesh));
    }
    PhantomCase {
        info: CaseInfo {
            name: name.to_string(),
            description: description.to_string(),
            seed: options.seed,
            dims: volume.dims,
            spacing_mm: volume.spacing,
            origin_mm: volume.origin,
            rotate_x_deg: options.rotate_x_deg,
            rotate_y_deg: options.rotate_y_deg,
            ends: options.ends,
            structures: infos,
        },
        meshes,
    }
}

/// A small cohort of neck-like cases varying in size, position, spacing and rotation; case `i`
/// depends only on `seed` and `i`.
pub fn cohort_case(index: usize, seed: u64) -> PhantomCase {
    let mut rng = fastrand::Rng::with_seed(
        seed.wrapping_mul(0x9e37_79b9_7f4a_7c15)
            .wrapping_add(index as u64),
    );
    let spacings = [
        [0.45, 0.45, 3.0],
        [0.8, 0.8, 2.0],
        [1.0, 1.0, 3.0],
        [0.6, 0.6, 1.5],
    ];
    let spacing = spacings[rng.usize(..spacings.len())];
    let scale = 0.6 + 0.5 * rng.f64();
    let extent = 52.0 * scale;
    let dims = [
        (extent / spacing[0]) as usize,
        (extent / spacing[1]) as usize,
        ((30.0 + 20.0 * rng.f64()) / spacing[2]) as usize,
    ];
    let volume = neck_volume(&mut rng, dims, spacing, scale, VeinAt::Apart);
    let options = PhantomOptions {
        rotate_x_deg: if rng.bool() {
            0.0
        } else {
            rng.f64() * 40.0 - 20.0
        },
        rotate_y_deg: if rng.bool() {
            0.0
        } else {
            rng.f64() * 40.0 - 20.0
        },
        seed,
        ends: BorderEnds::Capped,
    };
    let name = format!("case-{index:03}");
    finish(
        &name,
        "neck-like cohort case: tumor, vein, trachea",
        volume,
        &[("tumor", 1), ("vein", 2), ("trachea", 3)],
        &options,
    )
}

/// Names of the label-map phantoms (`destair phantom NAME`), written as label maps, not meshes.
pub const LABEL_MAP_NAMES: [&str; 1] = ["labelmap-neck"];

/// A label-map phantom: the volume (grid rotated by the options' angles about its centre, so
/// oblique acquisitions can be made) and its label names.
pub fn label_map_case(
    name: &str,
    options: &PhantomOptions,
) -> Result<(crate::volume::LabelVolume, Vec<(i64, String)>), PhantomError> {
    use crate::volume::{Grid, Space};
    let mut rng = fastrand::Rng::with_seed(options.seed);
    let v = match name {
        "labelmap-neck" => neck_volume(
            &mut rng,
            [160, 160, 20],
            [0.45, 0.45, 3.0],
            1.0,
            VeinAt::Touching,
        ),
        other => return Err(PhantomError::UnknownName(other.to_string())),
    };
    let rotation = rotation_matrix([options.rotate_x_deg, options.rotate_y_deg, 0.0]);
    let center: [f64; 3] =
        std::array::from_fn(|k| v.origin[k] + 0.5 * (v.dims[k] as f64 - 1.0) * v.spacing[k]);
    let mut matrix = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            matrix[r][c] = rotation[r][c] * v.spacing[c];
        }
    }
    // world(ijk) = center + R (origin + S ijk - center)
    let shifted = apply(&rotation, std::array::from_fn(|k| v.origin[k] - center[k]));
    let grid = Grid {
        matrix,
        origin: std::array::from_fn(|k| center[k] + shifted[k]),
        space: Space::Lps,
    };
    let volume =
        crate::volume::LabelVolume::from_values(v.dims, grid, v.labels.iter().map(|&l| l as i64))
            .map_err(|e| PhantomError::Io {
            path: name.into(),
            source: std::io::Error::other(e),
        })?;
    let names = vec![
        (1, "tumor".to_string()),
        (2, "vein".to_string()),
        (3, "trachea".to_string()),
    ];
    Ok((volume, names))
}

/// Writes a label-map phantom as `DIR/segmentation.nii.gz` and `DIR/phantom.json` (grid,
/// affine, label values, names and voxel counts).
pub fn write_label_map_case(
    name: &str,
    options: &PhantomOptions,
    dir: &Path,
) -> Result<(crate::volume::LabelVolume, Vec<(i64, String)>), PhantomError> {
    let (volume, names) = label_map_case(name, options)?;
    let io = |path: std::path::PathBuf| move |source| PhantomError::Io { path, source };
    std::fs::create_dir_all(dir).map_err(io(dir.to_path_buf()))?;
    let bytes = crate::volume::nifti::encode(&volume, true)
        .map_err(|e| io(dir.to_path_buf())(std::io::Error::other(e)))?;
    let path = dir.join("segmentation.nii.gz");
    write_atomically(&path, |w| w.write_all(&bytes)).map_err(io(path.clone()))?;
    let labels: Vec<serde_json::Value> = volume
        .labels
        .iter()
        .map(|l| {
            let name = names
                .iter()
                .find(|(v, _)| *v == l.value)
                .map(|(_, n)| n.as_str());
            serde_json::json!({ "value": l.value, "name": name, "n_voxels": l.n_voxels })
        })
        .collect();
    let info = serde_json::json!({
        "name": name,
        "description": "tumor touching a vein, trachea apart, at 0.45 x 0.45 x 3 mm, as a NIfTI label map (LPS world written as NIfTI's RAS)",
        "seed": options.seed,
        "dims": volume.dims,
        "spacing_mm": volume.grid.spacing(),
        "affine_lps": volume.grid.affine(),
        "rotate_x_deg": options.rotate_x_deg,
        "rotate_y_deg": options.rotate_y_deg,
        "labels": labels,
    });
    let json = serde_json::to_vec_pretty(&info).expect("label map info serialises");
    let path = dir.join("phantom.json");
    write_atomically(&path, |w| w.write_all(&json)).map_err(io(path.clone()))?;
    Ok((volume, names))
}

/// Writes each structure as `DIR/<structure>.ply` and the description as `DIR/phantom.json`.
pub fn write_case(case: &PhantomCase, dir: &Path) -> Result<(), PhantomError> {
    std::fs::create_dir_all(dir).map_err(|source| PhantomError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let s = case.info.spacing_mm;
    let meta = MeshMeta {
        comments: vec![format!(
            "destair phantom {} seed {} spacing {} {} {} mm",
            case.info.name, case.info.seed, s[0], s[1], s[2]
        )],
        obj_info: Vec::new(),
    };
    for (name, mesh) in &case.meshes {
        write_ply(&dir.join(format!("{name}.ply")), mesh, &meta, &[])?;
    }
    let json = serde_json::to_vec_pretty(&case.info).expect("case info serialises");
    let path = dir.join("phantom.json");
    write_atomically(&path, |w| w.write_all(&json))
        .map_err(|source| PhantomError::Io { path, source })
}
