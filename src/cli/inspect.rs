//! `destair inspect`: what a mesh file holds, and optionally its context analysis.

use super::{read_input, refuse_overwriting_inputs, ContextArgs, SpaceArg};
use destair::io::{ReadMode, ReadOptions};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Mesh file (.ply, .stl, .obj) or label map (.nii, .nii.gz, .nrrd, .seg.nrrd, .nhdr).
    mesh: PathBuf,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// How to read the file: mmap (local disks) or read (network filesystems).
    #[arg(long, value_enum, default_value_t = ModeArg::Mmap)]
    read_mode: ModeArg,
    /// Also analyse context: stack axis, staircases, caps, distances, weights.
    #[arg(long)]
    context: bool,
    /// Write the mesh with per-vertex `weight`, `staircase`, `cap` and distance arrays (.ply or
    /// .vtp).
    #[arg(long)]
    export: Option<PathBuf>,
    /// World convention for a label map's coordinates.
    #[arg(long, value_enum, default_value_t = SpaceArg::Lps)]
    space: SpaceArg,
    /// Also find the vessel's boundary patches for flow solvers (caps and open ends: inlet,
    /// outlets, wall); a surface that is not one 2-manifold vessel is an error with the reason.
    #[arg(long)]
    patches: bool,
    /// Which patch is the inlet: `largest`, a patch index in order of decreasing area (0 is
    /// the largest), or the point X,Y,Z (mm) nearest to its centre.
    #[arg(long, default_value = "largest", value_parser = parse_inlet, requires = "patches")]
    inlet: destair::cfd::Inlet,
    /// Patches the vessel must have; another count is an error.
    #[arg(long, requires = "patches")]
    expect_patches: Option<usize>,
    /// Close open ends with flat caps (rim moved onto the loop's plane, a fan from its centre)
    /// before writing patch files.
    #[arg(long, requires = "patch_files")]
    close_open_ends: bool,
    /// Write the files solvers' meshers take into this folder: STEM_solids.stl (one solid per
    /// patch), STEM_NAME.stl per patch, STEM.vtp with CellEntityIds, STEM_patches.json.
    #[arg(long, requires = "patches")]
    patch_files: Option<PathBuf>,
    #[command(flatten)]
    ctx: ContextArgs,
}

/// `largest`, an index, or X,Y,Z in mm.
fn parse_inlet(s: &str) -> Result<destair::cfd::Inlet, String> {
    s.parse()
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum ModeArg {
    Mmap,
    Read,
}

pub fn exec(args: Args) -> anyhow::Result<()> {
    let Args {
        mesh,
        json,
        read_mode,
        context,
        export,
        space,
        patches,
        inlet,
        expect_patches,
        close_open_ends,
        patch_files,
        ctx,
    } = args;
    if let Some(dir) = &patch_files {
        if !dir.is_dir() {
            return Err(super::UsageError(format!(
                "{}: the folder for patch files does not exist",
                dir.display()
            ))
            .into());
        }
    }
    ctx.check()?;
    if destair::volume::is_label_map(&mesh) {
        if patches {
            return Err(super::UsageError(format!(
                "{}: --patches takes a vessel mesh; extract the label map's surfaces first (destair extract)",
                mesh.display()
            ))
            .into());
        }
        let space = space.space();
        let map =
            destair::volume::read_label_map(&mesh, space).map_err(super::LabelMapInputError)?;
        let report =
            destair::report::label_map::label_map_report(&mesh.display().to_string(), &map);
        if json {
            println!("{}", serde_json::to_string_pretty(&report)?);
        } else {
            print!("{}", report.to_text());
        }
        return Ok(());
    }
    if let Some(path) = &export {
        let folder = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => std::path::Path::new("."),
        };
        if !folder.is_dir() {
            return Err(super::UsageError(format!(
                "{}: the output folder does not exist",
                folder.display()
            ))
            .into());
        }
        if !destair::io::OutputFormat::of_path(path).is_some_and(|f| f.holds_arrays()) {
            return Err(super::UsageError(format!(
                "{}: --export writes per-vertex arrays: name a .ply or .vtp file",
                path.display()
            ))
            .into());
        }
        let mut inputs = vec![mesh.as_path()];
        inputs.extend(ctx.references.iter().map(PathBuf::as_path));
        refuse_overwriting_inputs(path, &inputs, false)?;
    }
    let options = ReadOptions {
        mode: match read_mode {
            ModeArg::Mmap => ReadMode::Mmap,
            ModeArg::Read => ReadMode::Read,
        },
        ..Default::default()
    };
    let mut loaded = read_input(&mesh, &options)?;
    // A scattered file is inspected in its working order, as `smooth` works it (the report's
    // figures are sums and counts; --export goes back to the file's numbering), but for
    // --patches, whose patch files are new surfaces in the file's order.
    let renumbering = if patches || patch_files.is_some() {
        None
    } else {
        destair::mesh::order::working_numbering(&loaded.mesh)
    };
    if let Some(r) = &renumbering {
        loaded.mesh = r.mesh(&loaded.mesh);
    }
    let topology = destair::Topology::build(&loaded.mesh);
    let trees = if context || export.is_some() {
        Some(ctx.reference_trees()?)
    } else {
        None
    };
    // The report and the context analysis side by side: both only read the mesh, and each
    // has serial stretches the other fills. The context finds the report's average normal
    // curvature on its way (measured after when there is no context).
    let (report, analysis) = rayon::join(
        || destair::report::inspect::inspect_but_curvature(&mesh, &loaded, &topology),
        || {
            trees.as_ref().map(|trees| {
                let refs: Vec<&destair::spatial::TriangleBvh> = trees.iter().collect();
                let params = destair::weights::ContextParams {
                    measure_curvature: true,
                    ..ctx.params(true)
                };
                destair::weights::context_weights(&loaded.mesh, &topology, &params, &refs)
            })
        },
    );
    let report = report.with_curvature(
        (analysis.as_ref())
            .and_then(|a| a.average_normal_curvature_deg)
            .unwrap_or_else(|| destair::metrics::average_normal_curvature(&loaded.mesh, &topology)),
    );
    let summary = analysis
        .as_ref()
        .map(|a| destair::report::inspect::context_summary(a, loaded.mesh.n_vertices()));
    let found = patches.then(|| {
        destair::cfd::find_patches(&loaded.mesh, &topology, inlet, expect_patches)
            .map_err(|e| anyhow::anyhow!("{}: no patches: {e}", mesh.display()))
    });
    if json {
        let mut value = serde_json::to_value(&report)?;
        if let (Some(s), Some(obj)) = (&summary, value.as_object_mut()) {
            obj.insert("context".into(), serde_json::to_value(s)?);
        }
        if let (Some(Ok(p)), Some(obj)) = (&found, value.as_object_mut()) {
            obj.insert("patches".into(), serde_json::to_value(p)?);
        }
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        print!("{}", report.to_text());
        if let Some(s) = &summary {
            print!("{}", s.to_text());
        }
        if let Some(Ok(p)) = &found {
            print!("{}", destair::report::inspect::patches_text(p));
        }
    }
    let found = match found {
        Some(Err(e)) => return Err(e),
        Some(Ok(p)) => Some(p),
        None => None,
    };
    if let (Some(dir), Some(found)) = (&patch_files, &found) {
        let (closed, found) = if close_open_ends {
            let (m, p) = destair::cfd::close_open_ends(&loaded.mesh, found)
                .map_err(|e| anyhow::anyhow!("{}: {e}", mesh.display()))?;
            (std::borrow::Cow::Owned(m), std::borrow::Cow::Owned(p))
        } else {
            (
                std::borrow::Cow::Borrowed(&loaded.mesh),
                std::borrow::Cow::Borrowed(found),
            )
        };
        let stem = mesh
            .file_stem()
            .map_or_else(|| "vessel".into(), |s| s.to_string_lossy().into_owned());
        let planned = destair::cfd::outputs::planned_files(dir, &stem, &found);
        for path in &planned {
            refuse_overwriting_inputs(path, &[mesh.as_path()], false)?;
        }
        let written = destair::cfd::write_patch_files(dir, &stem, &closed, &loaded.meta, &found)?;
        if !json {
            for path in written {
                println!("  wrote {}", path.display());
            }
        }
    }
    if let (Some(path), Some(a)) = (export, &analysis) {
        let mut arrays = a.vertex_arrays(loaded.mesh.n_vertices());
        let written = match &renumbering {
            Some(r) => {
                for (_, values) in &mut arrays {
                    *values = r.scatter(values);
                }
                std::borrow::Cow::Owned(r.restore(&loaded.mesh))
            }
            None => std::borrow::Cow::Borrowed(&loaded.mesh),
        };
        let props: Vec<(&str, &[f32])> = arrays.iter().map(|(n, v)| (*n, v.as_slice())).collect();
        destair::io::write_annotated(&path, &written, &loaded.meta, &props, "weight")?;
    }
    Ok(())
}
