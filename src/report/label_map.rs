//! What a label map holds, as `destair inspect` shows it: grid, geometry in the chosen space,
//! and per label its value, name, voxel count and voxel volume (mm³).

use crate::volume::{LabelMap, Space};
use serde::Serialize;
use std::fmt::Write;

/// How close (voxels) to a face of the volume a label must come to count as reaching its edge:
/// a structure that leaves the field of view is segmented up to the last slice or one short of
/// it (the neck corpus's tubes end one slice inside their volume).
pub const EDGE_MARGIN_VOXELS: usize = 2;

/// Where a structure made from a label map comes from, for its report.
#[derive(Debug, Clone, Serialize)]
pub struct LabelSource {
    /// The label map's file name.
    pub label_map: String,
    /// Layer of a `.seg.nrrd` with overlapping segments (0 otherwise).
    pub layer: usize,
    /// The label value in the voxels.
    pub label: i64,
    pub n_voxels: u64,
    /// Volume of the label's voxels (mm³).
    pub voxel_volume_mm3: f64,
    /// Voxel size along the grid's axes i, j, k (mm), from the header.
    pub voxel_mm: [f64; 3],
    /// The thick-slice axis (largest spacing; k on ties) as a unit world direction.
    pub stack_axis: [f64; 3],
    /// Whether the label reaches the volume's edge (a voxel within [`EDGE_MARGIN_VOXELS`] of a
    /// face): only there can the field of view have clipped it.
    pub reaches_volume_edge: bool,
    /// Where the voxel size and stack axis used for smoothing came from: the header (smoothed in
    /// the grid's frame) or, for sheared grids, estimates from the mesh (smoothed in world).
    pub geometry: String,
    /// How the surface was extracted (binary or constrained, with its settings and counts).
    pub extraction: crate::extract::report::Extraction,
}

/// What a case's label map held, for the case report.
#[derive(Debug, Clone, Serialize)]
pub struct LabelMapInfo {
    pub file: String,
    pub bytes: u64,
    pub blake3: String,
    /// World convention of the surfaces.
    pub space: Space,
    pub dims: [usize; 3],
    pub spacing_mm: [f64; 3],
    /// Voxel index to world mm, in `space`.
    pub affine: [[f64; 4]; 4],
    pub n_layers: usize,
    /// (value, structure name, layer, voxels) per label.
    pub labels: Vec<LabelEntry>,
    pub warnings: Vec<String>,
}

/// One label of a label map and the structure it became.
#[derive(Debug, Clone, Serialize)]
pub struct LabelEntry {
    pub value: i64,
    pub structure: String,
    /// The name the file gives the label (Slicer's segment name), when it gives one.
    pub file_name: Option<String>,
    pub layer: usize,
    pub n_voxels: u64,
}

/// One label of a layer.
#[derive(Debug, Clone, Serialize)]
pub struct LabelRow {
    pub layer: usize,
    pub value: i64,
    pub name: String,
    pub n_voxels: u64,
    pub volume_mm3: f64,
}

/// The summary of a label map.
#[derive(Debug, Clone, Serialize)]
pub struct LabelMapReport {
    pub path: String,
    pub dims: [usize; 3],
    pub n_layers: usize,
    /// World convention of `affine` and `origin_mm`.
    pub space: Space,
    pub spacing_mm: [f64; 3],
    pub origin_mm: [f64; 3],
    /// Index to world, row by row.
    pub affine: [[f64; 4]; 4],
    /// Slice normal: the world direction of the index axis with the largest spacing.
    pub stack_axis: [f64; 3],
    pub labels: Vec<LabelRow>,
    pub warnings: Vec<String>,
}

/// Summarises a label map read in `space`.
pub fn label_map_report(path: &str, map: &LabelMap) -> LabelMapReport {
    let first = &map.layers[0];
    let g = first.grid;
    let voxel_mm3 = g.voxel_volume();
    let labels = map
        .layers
        .iter()
        .enumerate()
        .flat_map(|(layer, v)| {
            v.labels.iter().map(move |l| LabelRow {
                layer,
                value: l.value,
                name: l.name.clone(),
                n_voxels: l.n_voxels,
                volume_mm3: l.n_voxels as f64 * voxel_mm3,
            })
        })
        .collect();
    LabelMapReport {
        path: path.to_string(),
        dims: first.dims,
        n_layers: map.layers.len(),
        space: g.space,
        spacing_mm: g.spacing(),
        origin_mm: g.origin,
        affine: g.affine(),
        stack_axis: g.stack_axis(),
        labels,
        warnings: map.warnings.clone(),
    }
}

impl LabelMapReport {
    /// The report as text.
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        let r = |x: f64| crate::units::readable(x);
        let _ = writeln!(s, "{}", self.path);
        let _ = writeln!(
            s,
            "  label map {} x {} x {} voxels{}, spacing {} x {} x {} mm",
            self.dims[0],
            self.dims[1],
            self.dims[2],
            if self.n_layers > 1 {
                format!(", {} layers", self.n_layers)
            } else {
                String::new()
            },
            r(self.spacing_mm[0]),
            r(self.spacing_mm[1]),
            r(self.spacing_mm[2])
        );
        let _ = writeln!(s, "  affine (index to {} mm):", self.space.tag());
        for row in &self.affine[..3] {
            let _ = writeln!(
                s,
                "    {:>10} {:>10} {:>10} {:>10}",
                r(row[0]),
                r(row[1]),
                r(row[2]),
                r(row[3])
            );
        }
        let a = self.stack_axis;
        let _ = writeln!(s, "  stack axis ({}, {}, {})", r(a[0]), r(a[1]), r(a[2]));
        let _ = writeln!(s, "  {} labels:", self.labels.len());
        for l in &self.labels {
            let _ = writeln!(
                s,
                "    {:>6}  {:<24} {:>10} voxels  {:>12} mm³{}",
                l.value,
                l.name,
                l.n_voxels,
                r(l.volume_mm3),
                if self.n_layers > 1 {
                    format!("  (layer {})", l.layer)
                } else {
                    String::new()
                }
            );
        }
        for w in &self.warnings {
            let _ = writeln!(s, "  warning: {w}");
        }
        s
    }
}
