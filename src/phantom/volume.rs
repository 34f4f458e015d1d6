//! Label volumes filled from analytic shapes, the input side of a phantom: a regular grid of
//! u16 labels with spacing (mm per axis) and origin, as a segmentation tool would export it.

use rayon::prelude::*;

/// A shape in world coordinates (mm), tested at voxel centres.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    Sphere {
        center: [f64; 3],
        radius: f64,
    },
    Ellipsoid {
        center: [f64; 3],
        radii: [f64; 3],
    },
    /// Axis-aligned box, optionally rotated about its centre by `rotation_deg` (x, then y, then z).
    Cuboid {
        center: [f64; 3],
        half_extent: [f64; 3],
        rotation_deg: [f64; 3],
    },
    /// Cylinder with flat ends from `start` to `end`.
    Cylinder {
        start: [f64; 3],
        end: [f64; 3],
        radius: f64,
    },
    /// Tube along a polyline with a radius per point, linear in between, rounded at joints and ends.
    Tube {
        points: Vec<[f64; 3]>,
        radii: Vec<f64>,
    },
    Union(Vec<Shape>),
    /// Points in the first shape and not in the second.
    Difference(Box<Shape>, Box<Shape>),
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Rotation matrix for angles in degrees about x, then y, then z.
pub fn rotation_matrix(deg: [f64; 3]) -> [[f64; 3]; 3] {
    let [ax, ay, az] = deg.map(f64::to_radians);
    let (sx, cx) = ax.sin_cos();
    let (sy, cy) = ay.sin_cos();
    let (sz, cz) = az.sin_cos();
    let rx = [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]];
    let ry = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
    let rz = [[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]];
    mat_mul(rz, mat_mul(ry, rx))
}

fn mat_mul(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

/// `m` applied to `v`.
pub fn apply(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| dot(m[i], v))
}

impl Shape {
    /// Whether the point (mm) is inside.
    pub fn contains(&self, p: [f64; 3]) -> bool {
        match self {
            Shape::Sphere { center, radius } => {
                let d = sub(p, *center);
                dot(d, d) <= radius * radius
            }
            Shape::Ellipsoid { center, radii } => {
                let d = sub(p, *center);
                (0..3).map(|k| (d[k] / radii[k]).powi(2)).sum::<f64>() <= 1.0
            }
            Shape::Cuboid {
                center,
                half_extent,
                rotation_deg,
            } => {
                let m = rotation_matrix(*rotation_deg);
                let d = sub(p, *center);
                // Inverse rotation = transpose.
                (0..3).all(|k| {
                    let local = m[0][k] * d[0] + m[1][k] * d[1] + m[2][k] * d[2];
                    local.abs() <= half_extent[k]
                })
            }
            Shape::Cylinder { start, end, radius } => {
                let axis = sub(*end, *start);
                let len2 = dot(axis, axis);
                let d = sub(p, *start);
                let t = dot(d, axis);
                if t < 0.0 || t > len2 || len2 == 0.0 {
                    return false;
                }
                dot(d, d) - t * t / len2 <= radius * radius
            }
            Shape::Tube { points, radii } => {
                (0..points.len()).any(|i| {
                    let d = sub(p, points[i]);
                    dot(d, d) <= radii[i] * radii[i]
                }) || points.windows(2).zip(radii.windows(2)).any(|(seg, r)| {
                    let axis = sub(seg[1], seg[0]);
                    let len2 = dot(axis, axis);
                    if len2 == 0.0 {
                        return false;
                    }
                    let d = sub(p, seg[0]);
                    let t = dot(d, axis) / len2;
                    if !(0.0..=1.0).contains(&t) {
                        return false;
                    }
                    let radius = r[0] + t * (r[1] - r[0]);
                    dot(d, d) - t * t * len2 <= radius * radius
                })
            }
            Shape::Union(shapes) => shapes.iter().any(|s| s.contains(p)),
            Shape::Difference(a, b) => a.contains(p) && !b.contains(p),
        }
    }

    /// A box (mm) that contains the shape, for painting only the voxels that can be inside.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let around = |c: [f64; 3], r: [f64; 3]| {
            (
                std::array::from_fn(|k| c[k] - r[k]),
                std::array::from_fn(|k| c[k] + r[k]),
            )
        };
        let merge = |a: ([f64; 3], [f64; 3]), b: ([f64; 3], [f64; 3])| {
            (
                std::array::from_fn(|k| a.0[k].min(b.0[k])),
                std::array::from_fn(|k| a.1[k].max(b.1[k])),
            )
        };
        match self {
            Shape::Sphere { center, radius } => around(*center, [*radius; 3]),
            Shape::Ellipsoid { center, radii } => around(*center, *radii),
            Shape::Cuboid {
                center,
                half_extent,
                ..
            } => around(
                *center,
                [half_extent.iter().map(|h| h * h).sum::<f64>().sqrt(); 3],
            ),
            Shape::Cylinder { start, end, radius } => {
                merge(around(*start, [*radius; 3]), around(*end, [*radius; 3]))
            }
            Shape::Tube { points, radii } => points
                .iter()
                .zip(radii)
                .map(|(p, r)| around(*p, [*r; 3]))
                .reduce(merge)
                .unwrap_or(([0.0; 3], [0.0; 3])),
            Shape::Union(shapes) => shapes
                .iter()
                .map(Shape::bounds)
                .reduce(merge)
                .unwrap_or(([0.0; 3], [0.0; 3])),
            Shape::Difference(a, _) => a.bounds(),
        }
    }
}

/// A label volume: `dims` voxels with `spacing` (mm) per axis; voxel (i, j, k) has its centre
/// at `origin + (i, j, k) * spacing`. Labels are stored x fastest, then y, then z.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelVolume {
    pub dims: [usize; 3],
    pub spacing: [f64; 3],
    pub origin: [f64; 3],
    pub labels: Vec<u16>,
}

impl LabelVolume {
    /// An all-background (label 0) volume.
    pub fn new(dims: [usize; 3], spacing: [f64; 3], origin: [f64; 3]) -> Self {
        Self {
            dims,
            spacing,
            origin,
            labels: vec![0; dims[0] * dims[1] * dims[2]],
        }
    }

    /// Linear index of voxel (i, j, k).
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        (k * self.dims[1] + j) * self.dims[0] + i
    }

    /// Centre of voxel (i, j, k) in mm.
    #[inline]
    pub fn center(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        [
            self.origin[0] + i as f64 * self.spacing[0],
            self.origin[1] + j as f64 * self.spacing[1],
            self.origin[2] + k as f64 * self.spacing[2],
        ]
    }

    /// Voxel index range (per axis) whose centres can lie inside the box `lo..=hi` (mm).
    fn index_range(&self, lo: [f64; 3], hi: [f64; 3]) -> [std::ops::Range<usize>; 3] {
        std::array::from_fn(|k| {
            let a = ((lo[k] - self.origin[k]) / self.spacing[k])
                .floor()
                .max(0.0) as usize;
            let b = (((hi[k] - self.origin[k]) / self.spacing[k]).ceil() + 1.0)
                .clamp(0.0, self.dims[k] as f64) as usize;
            a.min(b)..b
        })
    }

    /// Sets every voxel whose centre is inside `shape` to `label` (0 erases).
    pub fn paint(&mut self, shape: &Shape, label: u16) {
        // A union paints member by member, each over its own bounds only.
        if let Shape::Union(shapes) = shape {
            for s in shapes {
                self.paint(s, label);
            }
            return;
        }
        let (lo, hi) = shape.bounds();
        self.paint_where(lo, hi, label, |p, _| shape.contains(p));
    }

    /// Sets voxels with centres in the box `lo..=hi` (mm) to `label` where `inside(centre,
    /// current label)` holds.
    pub fn paint_where<F>(&mut self, lo: [f64; 3], hi: [f64; 3], label: u16, inside: F)
    where
        F: Fn([f64; 3], u16) -> bool + Sync,
    {
        let [ri, rj, rk] = self.index_range(lo, hi);
        let slice = self.dims[0] * self.dims[1];
        let (nx, origin, spacing) = (self.dims[0], self.origin, self.spacing);
        self.labels
            .par_chunks_mut(slice.max(1))
            .enumerate()
            .filter(|(k, _)| rk.contains(k))
            .for_each(|(k, plane)| {
                for j in rj.clone() {
                    for i in ri.clone() {
                        let p = [
                            origin[0] + i as f64 * spacing[0],
                            origin[1] + j as f64 * spacing[1],
                            origin[2] + k as f64 * spacing[2],
                        ];
                        let v = &mut plane[j * nx + i];
                        if inside(p, *v) {
                            *v = label;
                        }
                    }
                }
            });
    }

    /// Number of voxels with this label.
    pub fn count(&self, label: u16) -> usize {
        self.labels.par_iter().filter(|&&l| l == label).count()
    }
}
