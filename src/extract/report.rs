//! What `destair extract` writes beside the meshes: `extract.json` with the label map's grid
//! and, per label, its name, voxel count, the volume of its voxels and of its surface (mm³),
//! and whether the surface is a closed oriented 2-manifold.

use crate::mesh::{geometry::signed_volume, Topology};
use crate::volume::{Grid, Label};
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
    /// "binary" (vertices at cell-edge midpoints) or "constrained" (§6.3.2).
    pub surface: String,
    /// The constrained smoothing's parameters, for `surface = "constrained"`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub constrained: Option<crate::extract::constrained::ConstrainedParams>,
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
) -> ExtractedLabel {
    let topology = Topology::build(mesh);
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
        closed_oriented_manifold: topology.is_closed_oriented_manifold(),
    }
}
