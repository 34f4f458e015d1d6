//! What `destair extract` writes beside the meshes: `extract.json` with the label map's grid
//! and, per label, its name, voxel count, the volume of its voxels and of its surface (mm³),
//! whether the surface is a closed oriented 2-manifold, and how it was extracted.

use crate::extract::constrained::{LabelCounts, LabelSmoothing, Noise, Surface, Thin};
use crate::extract::Connectivity;
use crate::mesh::{geometry::signed_volume, manifold::is_closed_oriented_manifold, Topology};
use crate::volume::{Grid, Label, LabelVolume};
use serde::Serialize;

/// One extracted structure.
#[derive(Debug, Clone, Serialize)]
pub struct ExtractedLabel {
    pub layer: usize,
    pub value: i64,
    pub name: String,
    /// Output file name (in the output folder).
    pub file: String,
    pub n_voxels: u64,
    pub voxel_volume_mm3: f64,
    pub mesh_volume_mm3: f64,
    pub n_vertices: usize,
    pub n_triangles: usize,
    pub closed_oriented_manifold: bool,
    pub extraction: Extraction,
    /// For constrained surfaces: what the smoothing changed against the binary extraction of
    /// the same label.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub against_binary: Option<AgainstBinary>,
}

/// What is measured of a surface to compare a constrained one with its binary twin: the
/// volume it encloses (mm³) and its mean normal curvature (degrees, as paper 001 measures it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceMeasure {
    pub volume_mm3: f64,
    pub curvature_deg: f64,
}

impl SurfaceMeasure {
    /// Measures `mesh`.
    pub fn of(mesh: &crate::Mesh) -> SurfaceMeasure {
        use crate::metrics::normal_curvature::average_normal_curvature;
        SurfaceMeasure {
            volume_mm3: signed_volume(mesh),
            curvature_deg: average_normal_curvature(mesh, &Topology::build(mesh)),
        }
    }
}

/// A constrained surface against the binary extraction of the same label: volume (mm³, and
/// the change in %) and mean normal curvature (degrees).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AgainstBinary {
    pub binary_mesh_volume_mm3: f64,
    /// 100 (constrained / binary - 1): negative where the surface lost volume.
    pub volume_change_percent: f64,
    pub binary_curvature_deg: f64,
    pub curvature_deg: f64,
}

impl AgainstBinary {
    /// The constrained surface's measures `mesh` against the binary one's.
    pub fn new(mesh: SurfaceMeasure, binary: SurfaceMeasure) -> AgainstBinary {
        let (b, c) = (binary.volume_mm3, mesh.volume_mm3);
        AgainstBinary {
            binary_mesh_volume_mm3: b,
            volume_change_percent: if b != 0.0 { 100.0 * (c / b - 1.0) } else { 0.0 },
            binary_curvature_deg: binary.curvature_deg,
            curvature_deg: mesh.curvature_deg,
        }
    }
}

/// How a label's surface was made, with what the refinements did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Extraction {
    /// "binary" (vertices at cell-edge midpoints) or "constrained" (§6.3).
    pub surface: Surface,
    /// The Gaussian's sigma (mm), for constrained surfaces.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise: Option<Noise>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub thin: Option<Thin>,
    /// Which voxels form one object: 26 (touching by a face, an edge or a corner) or 6.
    pub connectivity: Connectivity,
    /// Objects the label's voxels form by that connectivity.
    pub voxel_objects: u64,
    /// Closed pieces of the surface that enclose an object (a cavity's wall is not counted):
    /// more than `voxel_objects` where the label crosses another diagonally in one cell.
    pub surface_pieces: u64,
    /// Voxels relaxed as surface noise, left pinned, and protected as thin (all 0 for binary).
    #[serde(flatten)]
    pub counts: LabelCounts,
}

impl Extraction {
    /// The settings in effect for a label of `volume`, the objects its voxels form, its
    /// surface `mesh` and the refinements' counts.
    pub fn new(
        volume: &LabelVolume,
        smoothing: &LabelSmoothing,
        voxel_objects: u64,
        mesh: &crate::Mesh,
        counts: LabelCounts,
    ) -> Extraction {
        let constrained = smoothing.surface == Surface::Constrained;
        Extraction {
            surface: smoothing.surface,
            sigma_mm: constrained.then(|| smoothing.sigma_on(volume)),
            noise: constrained.then_some(smoothing.noise),
            thin: constrained.then_some(smoothing.thin),
            connectivity: smoothing.connectivity,
            voxel_objects,
            surface_pieces: outer_shells(mesh),
            counts,
        }
    }

    /// What to say when the surface has more or fewer pieces than the voxels have objects.
    pub fn pieces_warning(&self) -> Option<String> {
        let (pieces, objects) = (self.surface_pieces, self.voxel_objects);
        let c = self.connectivity.number();
        (pieces > objects).then(|| format!(
            "the surface has {pieces} separate pieces where the voxels form {objects} object(s) ({c}-connected): it is cut where it crosses another label diagonally within one voxel cell"
        )).or_else(|| (pieces < objects).then(|| format!(
            "the surface has {pieces} separate pieces where the voxels form {objects} object(s) ({c}-connected): it joins voxels that touch diagonally where two other labels meet them"
        )))
    }
}

/// `extract.json`.
#[derive(Debug, Clone, Serialize)]
pub struct ExtractReport {
    pub source: String,
    /// World convention of the meshes and of `affine` (also in each mesh's `SPACE=` comment).
    pub space: String,
    pub dims: [usize; 3],
    pub spacing_mm: [f64; 3],
    /// Index to world (mm), row by row.
    pub affine: [[f64; 4]; 4],
    pub labels: Vec<ExtractedLabel>,
    pub warnings: Vec<String>,
}

/// The row of one extracted label; `binary` measures the label's binary surface when `mesh`
/// is a constrained one.
pub fn extracted_label(
    layer: usize,
    label: &Label,
    file: String,
    mesh: &crate::Mesh,
    grid: &Grid,
    extraction: Extraction,
    binary: Option<SurfaceMeasure>,
) -> ExtractedLabel {
    ExtractedLabel {
        layer,
        value: label.value,
        name: label.name.clone(),
        file,
        n_voxels: label.n_voxels,
        voxel_volume_mm3: label.n_voxels as f64 * grid.voxel_volume(),
        mesh_volume_mm3: signed_volume(mesh),
        n_vertices: mesh.n_vertices(),
        n_triangles: mesh.n_triangles(),
        closed_oriented_manifold: is_closed_oriented_manifold(mesh),
        extraction,
        against_binary: binary.map(|b| AgainstBinary::new(SurfaceMeasure::of(mesh), b)),
    }
}

/// Closed pieces of a surface that enclose positive volume: one per object (the wall of a
/// cavity inside an object encloses negative volume).
pub fn outer_shells(mesh: &crate::Mesh) -> u64 {
    let topology = Topology::build(mesh);
    let volumes = crate::mesh::geometry::shell_volumes(mesh, &topology);
    volumes.iter().filter(|&&v| v > 0.0).count() as u64
}
