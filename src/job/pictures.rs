//! A case's pictures: drawn after the guard, so they show the surfaces that are written, for
//! all of the case's structures at once (in parallel; each picture's bytes do not depend on
//! the threads).

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
    /// cfd profile: the patch id of each face of the surface handed over, and the patches'
    /// names by id.
    pub patches: Option<PatchFaces>,
}

/// Per face its patch id, and the patches' (id, name).
pub(super) type PatchFaces = (Vec<u32>, Vec<(u32, String)>);

/// A processed structure to draw: its name, its surfaces before and after (world mm) and
/// what else its pictures need.
pub(super) type PictureJob<'a> = (&'a str, &'a Mesh, &'a Mesh, &'a PictureInput);

/// Draws the picture sheet of every structure given that is ok, adds the PNG files to
/// `files` and the picture to each structure's report and outputs.
pub(super) fn draw_case_pictures(
    jobs: &[PictureJob],
    structures: &mut [StructureReport],
    files: &mut Vec<(String, Vec<u8>)>,
) {
    let ok = |name: &str| {
        structures
            .iter()
            .any(|s| s.name == name && s.status == "ok")
    };
    let jobs: Vec<&PictureJob> = jobs.iter().filter(|(name, ..)| ok(name)).collect();
    let drawn: Vec<_> = jobs
        .par_iter()
        .map(|(name, before, after, p)| {
            let arrays: Vec<(&str, &[f32])> =
                p.arrays.iter().map(|(n, v)| (*n, v.as_slice())).collect();
            let views = StructureViews {
                heading: name.to_string(),
                before: p.start.as_ref().unwrap_or(before),
                after,
                arrays: &arrays,
                patches: p
                    .patches
                    .as_ref()
                    .map(|(ids, names)| (ids.as_slice(), names.as_slice())),
            };
            let (info, png) = structure_picture(&views, format!("{}_views.png", p.stem));
            (name.to_string(), info, png)
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
