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
    /// Write the mesh with per-vertex `weight`, `staircase`, `cap` and distance properties (PLY).
    #[arg(long)]
    export: Option<PathBuf>,
    /// World convention for a label map's coordinates.
    #[arg(long, value_enum, default_value_t = SpaceArg::Lps)]
    space: SpaceArg,
    #[command(flatten)]
    ctx: ContextArgs,
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
        ctx,
    } = args;
    ctx.check()?;
    if destair::volume::is_label_map(&mesh) {
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
    let loaded = read_input(&mesh, &options)?;
    let topology = destair::Topology::build(&loaded.mesh);
    let report = destair::report::inspect::inspect(&mesh, &loaded, &topology);
    let analysis = if context || export.is_some() {
        let grids = ctx.reference_grids()?;
        let refs: Vec<&destair::spatial::TriangleGrid> = grids.iter().collect();
        Some(destair::weights::context_weights(
            &loaded.mesh,
            &topology,
            &ctx.params(true),
            &refs,
        ))
    } else {
        None
    };
    let summary = analysis
        .as_ref()
        .map(|a| destair::report::inspect::context_summary(a, loaded.mesh.n_vertices()));
    if json {
        let mut value = serde_json::to_value(&report)?;
        if let (Some(s), Some(obj)) = (&summary, value.as_object_mut()) {
            obj.insert("context".into(), serde_json::to_value(s)?);
        }
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        print!("{}", report.to_text());
        if let Some(s) = &summary {
            print!("{}", s.to_text());
        }
    }
    if let (Some(path), Some(a)) = (export, &analysis) {
        let n = loaded.mesh.n_vertices();
        let flag = |on: &dyn Fn(usize) -> bool| {
            (0..n)
                .map(|v| if on(v) { 1.0 } else { 0.0 })
                .collect::<Vec<f32>>()
        };
        let staircase = flag(&|v| a.staircase.as_ref().is_some_and(|s| s.is_staircase[v]));
        let caps = a.caps.cap_vertices(n);
        let cap = flag(&|v| caps[v]);
        // -1 where no staircase is within reach.
        let stair_distance: Vec<f32> = (0..n)
            .map(|v| {
                a.staircase.as_ref().map_or(-1.0, |s| {
                    if s.distance_mm[v].is_finite() {
                        s.distance_mm[v]
                    } else {
                        -1.0
                    }
                })
            })
            .collect();
        let mut props: Vec<(&str, &[f32])> = vec![
            ("weight", a.weights.as_slice()),
            ("staircase", &staircase),
            ("cap", &cap),
            ("staircase_distance", &stair_distance),
        ];
        let reference: Vec<f32>;
        if let Some(d) = &a.reference_distance_mm {
            reference = d.iter().map(|&x| x as f32).collect();
            props.push(("reference_distance", &reference));
        }
        destair::io::ply::write_ply(&path, &loaded.mesh, &loaded.meta, &props)?;
    }
    Ok(())
}
