//! The pictures of a structure in a case report: one sheet with the input, the smoothed
//! surface, and the surface coloured by displacement (mm), by smoothing weight and by
//! staircase/cap class, each with its legend; and the displacement histogram the HTML report
//! draws. Panels render in parallel, each serially, so the bytes do not depend on threads.

use crate::mesh::Mesh;
use crate::render::colour::{self, Scale};
use crate::render::sheet::{compose_sheet, Legend, Panel};
use crate::render::{rasterise, Camera, Paint, Picture, FRONT_OBLIQUE};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Width and height of each panel (px).
pub const PANEL_PX: u32 = 240;
/// Number of histogram bins.
const HISTOGRAM_BINS: usize = 20;

/// What a structure's sheet shows. `before` and `after` are in world millimetres with the
/// same vertices (the arrays are per vertex of both).
pub struct StructureViews<'a> {
    pub heading: String,
    pub before: &'a Mesh,
    pub after: &'a Mesh,
    /// Per-vertex arrays by name: `displacement` (mm), `weight`, `staircase` and `cap` (1/0).
    pub arrays: &'a [(&'a str, &'a [f32])],
    /// cfd profile: per face of `after` its patch id (`CellEntityIds`) and the patches' names
    /// by id (the wall is id 1).
    pub patches: Option<PatchLabels<'a>>,
}

/// Per face its patch id, and the patches' (id, name).
pub type PatchLabels<'a> = (&'a [u32], &'a [(u32, String)]);

/// Colours of cfd patches: the wall grey, then inlet and outlets in turn.
const PATCH_COLOURS: [[u8; 3]; 7] = [
    [220, 50, 47],
    [38, 139, 210],
    [133, 153, 0],
    [211, 54, 130],
    [42, 161, 152],
    [181, 137, 0],
    [108, 113, 196],
];

/// What one panel draws.
enum PanelKind<'a> {
    Plain(&'a Mesh),
    Scaled(&'a Mesh, &'a [f32], Scale),
    Classes(&'a Mesh, Vec<[u8; 3]>),
    Faces(&'a Mesh, Vec<[u8; 3]>),
}

/// A structure's picture sheet as the report records it: where each panel is, for pages
/// that show one panel as a thumbnail.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PictureInfo {
    /// File name in the case folder.
    pub file: String,
    /// Sheet size (px).
    pub width: u32,
    pub height: u32,
    /// Panel titles, left to right.
    pub panels: Vec<String>,
    /// Panel size (px).
    pub panel_px: u32,
}

impl PictureInfo {
    /// The box (x, y, width, height in px) of the panel titled `title`.
    pub fn panel_box(&self, title: &str) -> Option<[u32; 4]> {
        let i = self.panels.iter().position(|p| p == title)?;
        let (x, y) = crate::render::sheet::panel_origin(i, self.panel_px);
        Some([x, y, self.panel_px, self.panel_px])
    }
}

/// Renders the sheet of one structure and encodes it as PNG: (info, PNG bytes).
pub fn structure_picture(views: &StructureViews, file: String) -> (PictureInfo, Vec<u8>) {
    let (sheet, panels) = structure_sheet(views);
    let info = PictureInfo {
        file,
        width: sheet.width,
        height: sheet.height,
        panels,
        panel_px: PANEL_PX,
    };
    (info, sheet.encode_png())
}

/// The sheet of one structure (panels for the arrays that are present) and its panel titles.
pub fn structure_sheet(views: &StructureViews) -> (Picture, Vec<String>) {
    let array = |name: &str| {
        views
            .arrays
            .iter()
            .find(|(n, v)| *n == name && v.len() == views.before.n_vertices())
            .map(|(_, v)| *v)
    };
    let mut specs: Vec<(String, PanelKind, Legend)> = vec![
        ("input".into(), PanelKind::Plain(views.before), Legend::None),
        (
            if views.patches.is_some() {
                "handed over (cfd)"
            } else {
                "smoothed"
            }
            .into(),
            PanelKind::Plain(views.after),
            Legend::None,
        ),
    ];
    if let Some(d) = array("displacement") {
        let scale = Scale::zero_to_max(d, 0.01, "mm");
        specs.push((
            "displacement".into(),
            PanelKind::Scaled(views.after, d, scale.clone()),
            Legend::Scale(scale),
        ));
    }
    if let Some(w) = array("weight") {
        let scale = Scale {
            lo: 0.0,
            hi: 1.0,
            unit: "".into(),
        };
        specs.push((
            "smoothing weight".into(),
            PanelKind::Scaled(views.before, w, scale.clone()),
            Legend::Scale(scale),
        ));
    }
    if let (Some(stair), Some(cap)) = (array("staircase"), array("cap")) {
        let colours = stair
            .iter()
            .zip(cap)
            .map(|(&s, &c)| match (s > 0.5, c > 0.5) {
                (_, true) => colour::CLASS_CAP,
                (true, false) => colour::CLASS_STAIRCASE,
                _ => colour::CLASS_OTHER,
            })
            .collect();
        specs.push((
            "staircase / cap".into(),
            PanelKind::Classes(views.before, colours),
            Legend::Classes(vec![
                ("staircase".into(), colour::CLASS_STAIRCASE),
                ("cap".into(), colour::CLASS_CAP),
                ("other".into(), colour::CLASS_OTHER),
            ]),
        ));
    }
    if let Some((ids, names)) = views.patches {
        if ids.len() == views.after.n_triangles() {
            let colour = |id: u32| match names.iter().position(|(i, _)| *i == id) {
                Some(k) => PATCH_COLOURS[k % PATCH_COLOURS.len()],
                None => colour::CLASS_OTHER,
            };
            let mut classes = vec![("wall".to_string(), colour::CLASS_OTHER)];
            classes.extend(names.iter().map(|(id, n)| (n.clone(), colour(*id))));
            specs.push((
                "patches".into(),
                PanelKind::Faces(views.after, ids.iter().map(|&id| colour(id)).collect()),
                Legend::Classes(classes),
            ));
        }
    }
    let camera = Camera::fitted(&[views.before, views.after], FRONT_OBLIQUE, PANEL_PX);
    // Each surface is rasterised once; its panels only shade.
    let (before, after) = rayon::join(
        || rasterise(views.before, &camera),
        || rasterise(views.after, &camera),
    );
    let coverage = |m: &Mesh| {
        if std::ptr::eq(m, views.before) {
            &before
        } else {
            &after
        }
    };
    let panels: Vec<Panel> = specs
        .into_par_iter()
        .map(|(title, kind, legend)| {
            let picture = match &kind {
                PanelKind::Plain(m) => coverage(m).shade(m, Paint::Plain(colour::SURFACE)),
                PanelKind::Scaled(m, values, scale) => {
                    coverage(m).shade(m, Paint::PerVertex(&scale.colours(values)))
                }
                PanelKind::Classes(m, colours) => coverage(m).shade(m, Paint::PerVertex(colours)),
                PanelKind::Faces(m, colours) => coverage(m).shade(m, Paint::PerFace(colours)),
            };
            Panel {
                title,
                picture,
                legend,
            }
        })
        .collect();
    let titles = panels.iter().map(|p| p.title.clone()).collect();
    (compose_sheet(&views.heading, &panels), titles)
}

/// A histogram of non-negative values (mm) over equal bins from 0.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Histogram {
    /// Width of each bin (mm); bin k holds values in [k w, (k+1) w).
    pub bin_mm: f64,
    pub counts: Vec<u64>,
    /// Largest value (mm).
    pub max_mm: f64,
}

/// Histogram of `values` (mm; NaN skipped) in 20 bins whose width is a round number.
pub fn histogram(values: &[f32]) -> Histogram {
    let scale = Scale::zero_to_max(values, 1e-3, "mm");
    let bin = f64::from(scale.hi) / HISTOGRAM_BINS as f64;
    let mut counts = vec![0u64; HISTOGRAM_BINS];
    let mut max = 0.0f64;
    for &v in values.iter().filter(|v| v.is_finite()) {
        let v = f64::from(v.max(0.0));
        max = max.max(v);
        let k = ((v / bin) as usize).min(HISTOGRAM_BINS - 1);
        counts[k] += 1;
    }
    Histogram {
        bin_mm: bin,
        counts,
        max_mm: max,
    }
}
