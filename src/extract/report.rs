//! What `destair extract` writes beside the meshes: `extract.json` with the label map's grid
//! and, per label, its name, voxel count, the volume of its voxels and of its surface (mm³),
//! whether the surface is a closed oriented 2-manifold, and how it was extracted.

use crate::extract::constrained::{LabelCounts, LabelSmoothing, Noise, Surface, Thin};
use crate::mesh::{geometry::signed_volume, manifold::is_closed_oriented_manifold};
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
    /// Voxels relaxed as surface noise, left pinned, and protected as thin (all 0 for binary).
    #[serde(flatten)]
    pub counts: LabelCounts,
}

impl Extraction {
    /// The settings in effect for a label of `volume` and their counts.
    pub fn new(
        volume: &LabelVolume,
        smoothing: &LabelSmoothing,
        counts: LabelCounts,
    ) -> Extraction {
        let constrained = smoothing.surface == Surface::Constrained;
        Extraction {
            surface: smoothing.surface,
            sigma_mm: constrained.then(|| smoothing.sigma_on(volume)),
            noise: constrained.then_some(smoothing.noise),
            thin: constrained.then_some(smoothing.thin),
            counts,
        }
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

/// The row of one extracted label.
pub fn extracted_label(
    layer: usize,
    label: &Label,
    file: String,
    mesh: &crate::Mesh,
    grid: &Grid,
    extraction: Extraction,
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
    }
}
