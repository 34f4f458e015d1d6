//! A case's pictures: drawn after the guard, so they show the surfaces that are written, for
//! all of the case's structures at once (in parallel; each picture's bytes do not depend on
//! the threads).

use super::guard::{Files, Kept};
use crate::mesh::Mesh;
use crate::report::case::StructureReport;
use crate::report::pictures::{structure_picture, StructureViews};
use rayon::prelude::*;

/// What a structure's pictures need besides its surfaces before and after.
pub(super) struct PictureInput {
    /// Output file stem of the structure.
    pub stem: String,
    /// The surface displacements are measured from, when it is not the one smoothing started
    /// from (a label surface's binary extraction), in world mm.
    pub start: Option<Mesh>,
    /// Per-vertex arrays (weight, staircase, cap, displacement, ...).
    pub arrays: Vec<(&'static str, Vec<f32>)>,
}

/// Draws the picture sheet of every kept structure that is ok, adds the PNG files to `files`
/// and the picture to each structure's report and outputs.
pub(super) fn draw_case_pictures(
    kept: &[Kept],
    structures: &mut [StructureReport],
    files: &mut Files,
) {
    let ok = |name: &str| {
        structures
            .iter()
            .any(|s| s.name == name && s.status == "ok")
    };
    let jobs: Vec<(&Kept, &PictureInput)> = kept
        .iter()
        .filter_map(|k| k.picture.as_ref().map(|p| (k, p)))
        .filter(|(k, _)| ok(&k.name))
        .collect();
    let drawn: Vec<_> = jobs
        .par_iter()
        .map(|(k, p)| {
            let arrays: Vec<(&str, &[f32])> =
                p.arrays.iter().map(|(n, v)| (*n, v.as_slice())).collect();
            let views = StructureViews {
                heading: k.name.clone(),
                before: p.start.as_ref().unwrap_or(&k.before),
                after: &k.after,
                arrays: &arrays,
            };
            let (info, png) = structure_picture(&views, format!("{}_views.png", p.stem));
            (k.name.clone(), info, png)
        })
        .collect();
    for (name, info, png) in drawn {
        if let Some(s) = structures.iter_mut().find(|s| s.name == name) {
            s.outputs.push(info.file.clone());
            files.push((info.file.clone(), png));
            s.picture = Some(info);
        }
    }
}
