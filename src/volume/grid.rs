//! Grid geometry of a label map: the affine from voxel indices to world millimetres (spacing,
//! origin and the full direction matrix, so oblique acquisitions stay oblique), and the
//! world convention it is in (LPS, Slicer's and DICOM's; or RAS, NIfTI's).

use serde::Serialize;

/// How far from the world origin a label map's voxels may lie (mm): 1 km. A scanner's grid
/// lies within a metre or two of it; a surface of a grid within this bound stays within
/// [`MAX_COORDINATE_MM`](crate::mesh::MAX_COORDINATE_MM) in world mm and in the grid's frame.
pub const MAX_GRID_EXTENT_MM: f64 = 1e6;

/// Patient coordinate convention of world millimetres.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "UPPERCASE")]
pub enum Space {
    /// x to the patient's left, y posterior, z superior (DICOM, ITK, 3D Slicer since 4.11).
    Lps,
    /// x to the patient's right, y anterior, z superior (NIfTI's scanner space).
    Ras,
}

impl Space {
    /// The tag written into mesh headers (`SPACE=LPS`).
    pub fn tag(self) -> &'static str {
        match self {
            Space::Lps => "LPS",
            Space::Ras => "RAS",
        }
    }
}

/// Voxel index (i, j, k) to world mm: `world = origin + matrix * (i, j, k)`. The columns of
/// `matrix` are the grid steps along i, j and k (spacing times direction).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Grid {
    pub matrix: [[f64; 3]; 3],
    pub origin: [f64; 3],
    pub space: Space,
}

impl Grid {
    /// An axis-aligned grid with the given spacing (mm) and origin, in `space`.
    pub fn axis_aligned(spacing: [f64; 3], origin: [f64; 3], space: Space) -> Grid {
        let mut matrix = [[0.0; 3]; 3];
        for (k, s) in spacing.iter().enumerate() {
            matrix[k][k] = *s;
        }
        Grid {
            matrix,
            origin,
            space,
        }
    }

    /// Checks what a grid must be: finite, every step longer than zero, not singular.
    pub fn check(&self) -> Result<(), String> {
        let finite = self
            .matrix
            .iter()
            .flatten()
            .chain(&self.origin)
            .all(|x| x.is_finite());
        if !finite {
            return Err("the grid's directions or origin are not finite numbers".into());
        }
        let spacing = self.spacing();
        if let Some(k) = spacing.iter().position(|s| s.is_nan() || *s <= 0.0) {
            return Err(format!(
                "the voxel spacing along axis {k} is {} mm; it must be positive",
                crate::units::readable(spacing[k])
            ));
        }
        // Singular when the unit directions span (almost) no volume.
        let d = self.directions();
        let det = det3(&d);
        if det.abs() < 1e-6 {
            return Err(format!(
                "the direction matrix is singular (determinant {})",
                crate::units::readable(det)
            ));
        }
        Ok(())
    }

    /// Checks that a volume of `dims` voxels on this grid lies within +-[`MAX_GRID_EXTENT_MM`]
    /// of the world origin (with a voxel's margin around it), so that its surfaces, in world
    /// mm or in the grid's own frame, hold valid mesh coordinates
    /// ([`is_valid_coordinate`](crate::mesh::is_valid_coordinate)).
    pub fn check_extent(&self, dims: [usize; 3]) -> Result<(), String> {
        let far = (0..8)
            .flat_map(|c: usize| {
                let corner = [0, 1, 2].map(|k| {
                    if c >> k & 1 == 0 {
                        -1.0
                    } else {
                        dims[k] as f64
                    }
                });
                self.world(corner)
            })
            // NaN (huge steps of both signs in one row) counts as infinitely far: `max`
            // alone would pass over it.
            .map(|x| if x.is_nan() { f64::INFINITY } else { x.abs() })
            .fold(0.0f64, f64::max);
        if far > MAX_GRID_EXTENT_MM {
            return Err(format!(
                "the grid places voxels {} mm from the origin, beyond +-1e6 mm (1 km): not a scan in millimetres (a corrupt header, or one in other units)",
                crate::units::readable(far)
            ));
        }
        Ok(())
    }

    /// Checks every voxel spacing against `[smallest, largest]` (mm): outside it the header is
    /// corrupt or in other units (1e-40 mm or 75 mm voxels are no scan).
    pub fn check_spacing(&self, [smallest, largest]: [f64; 2]) -> Result<(), String> {
        let spacing = self.spacing();
        match (0..3).find(|&k| !(smallest..=largest).contains(&spacing[k])) {
            Some(k) => Err(format!(
                "the voxel spacing along axis {k} is {} mm, outside the {} to {} mm a scan has (a corrupt header, or one in other units; [input] spacing_range_mm widens it)",
                crate::units::readable(spacing[k]),
                crate::units::readable(smallest),
                crate::units::readable(largest)
            )),
            None => Ok(()),
        }
    }

    /// Step length (mm) along each index axis.
    pub fn spacing(&self) -> [f64; 3] {
        let m = &self.matrix;
        [0, 1, 2].map(|c| (m[0][c] * m[0][c] + m[1][c] * m[1][c] + m[2][c] * m[2][c]).sqrt())
    }

    /// Unit direction of each index axis, as the columns of a matrix.
    pub fn directions(&self) -> [[f64; 3]; 3] {
        let s = self.spacing();
        let mut d = self.matrix;
        for row in &mut d {
            for c in 0..3 {
                row[c] /= if s[c] > 0.0 { s[c] } else { 1.0 };
            }
        }
        d
    }

    /// World position (mm) of a (possibly fractional) voxel index.
    pub fn world(&self, ijk: [f64; 3]) -> [f64; 3] {
        let m = &self.matrix;
        [0, 1, 2].map(|r| self.origin[r] + m[r][0] * ijk[0] + m[r][1] * ijk[1] + m[r][2] * ijk[2])
    }

    /// The same grid in the other convention (x and y negated).
    pub fn in_space(&self, space: Space) -> Grid {
        if space == self.space {
            return *self;
        }
        let mut g = *self;
        for r in 0..2 {
            g.origin[r] = -g.origin[r];
            for c in 0..3 {
                g.matrix[r][c] = -g.matrix[r][c];
            }
        }
        g.space = space;
        g
    }

    /// The index axis that runs closest to `axis` (a unit world direction), and the cosine.
    pub fn nearest_index_axis(&self, axis: [f64; 3]) -> (usize, f64) {
        let d = self.directions();
        (0..3)
            .map(|c| {
                (
                    c,
                    (d[0][c] * axis[0] + d[1][c] * axis[1] + d[2][c] * axis[2]).abs(),
                )
            })
            .fold((0, -1.0), |best, x| if x.1 > best.1 { x } else { best })
    }

    /// The slice normal: the world direction across the slices, taken as the index axis with
    /// the largest spacing (the thick-slice axis), in unit length.
    pub fn stack_axis(&self) -> [f64; 3] {
        let k = self.stack_index_axis();
        let d = self.directions();
        [d[0][k], d[1][k], d[2][k]]
    }

    /// Volume of one voxel (mm³).
    pub fn voxel_volume(&self) -> f64 {
        det3(&self.matrix).abs()
    }

    /// The 4 x 4 affine, row by row, for reports.
    pub fn affine(&self) -> [[f64; 4]; 4] {
        let m = &self.matrix;
        let o = &self.origin;
        [
            [m[0][0], m[0][1], m[0][2], o[0]],
            [m[1][0], m[1][1], m[1][2], o[1]],
            [m[2][0], m[2][1], m[2][2], o[2]],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }
}

/// A grid's own frame: millimetres along the grid axes from voxel (0, 0, 0), i.e. index times
/// spacing. It differs from world mm by a rigid motion (rotation, possibly a mirror, and the
/// origin), so distances, volumes and curvature are the same in both, while a voxel is an
/// axis-aligned box and the stack axis a coordinate axis: grid-aware smoothing holds exactly for
/// oblique acquisitions there.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GridFrame {
    /// Unit grid directions as columns (world = rotation * frame + origin).
    pub rotation: [[f64; 3]; 3],
    pub origin: [f64; 3],
}

impl GridFrame {
    /// World mm of a point in the frame.
    pub fn to_world(&self, p: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        [0, 1, 2].map(|i| self.origin[i] + r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2])
    }

    /// The frame's coordinates of a world point.
    pub fn to_frame(&self, w: [f64; 3]) -> [f64; 3] {
        let d = [0, 1, 2].map(|i| w[i] - self.origin[i]);
        self.direction_to_frame(d)
    }

    /// A world direction (or offset) in the frame.
    pub fn direction_to_frame(&self, d: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        [0, 1, 2].map(|c| r[0][c] * d[0] + r[1][c] * d[1] + r[2][c] * d[2])
    }

    /// A frame direction in world.
    pub fn direction_to_world(&self, d: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        [0, 1, 2].map(|i| r[i][0] * d[0] + r[i][1] * d[1] + r[i][2] * d[2])
    }

    /// Whether the frame mirrors world (orientation of triangles flips between them).
    pub fn mirrored(&self) -> bool {
        det3(&self.rotation) < 0.0
    }
}

impl Grid {
    /// The grid's own frame, or `None` when its axes are not perpendicular (a sheared grid,
    /// where no rigid motion makes voxels axis-aligned boxes).
    pub fn frame(&self) -> Option<GridFrame> {
        let d = self.directions();
        let dot = |a: usize, b: usize| (0..3).map(|r| d[r][a] * d[r][b]).sum::<f64>();
        let orthogonal = dot(0, 1).abs() < 1e-5 && dot(0, 2).abs() < 1e-5 && dot(1, 2).abs() < 1e-5;
        orthogonal.then_some(GridFrame {
            rotation: d,
            origin: self.origin,
        })
    }

    /// Index of the stack axis (see [`stack_index`]).
    pub fn stack_index_axis(&self) -> usize {
        stack_index(self.spacing())
    }
}

/// The index axis across the slices: the one with the largest spacing, and the last one (the
/// slice axis by convention) on ties.
pub fn stack_index(spacing: [f64; 3]) -> usize {
    (0..3).fold(
        2,
        |best, c| {
            if spacing[c] > spacing[best] {
                c
            } else {
                best
            }
        },
    )
}

/// The rotation matrix of the unit quaternion (a, b, c, d) (NIfTI's qform convention).
pub fn quaternion_rotation(a: f64, b: f64, c: f64, d: f64) -> [[f64; 3]; 3] {
    [
        [
            a * a + b * b - c * c - d * d,
            2.0 * (b * c - a * d),
            2.0 * (b * d + a * c),
        ],
        [
            2.0 * (b * c + a * d),
            a * a + c * c - b * b - d * d,
            2.0 * (c * d - a * b),
        ],
        [
            2.0 * (b * d - a * c),
            2.0 * (c * d + a * b),
            a * a + d * d - c * c - b * b,
        ],
    ]
}

/// Determinant of a 3 x 3 matrix.
pub fn det3(m: &[[f64; 3]; 3]) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}
