//! `destair compare`: the papers' measures between an original and a smoothed mesh.

use super::read_input;
use destair::io::ReadOptions;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    original: PathBuf,
    smoothed: PathBuf,
    /// Reference structures whose minimum distance is reported before and after.
    #[arg(long = "reference")]
    references: Vec<PathBuf>,
    /// Voxel size in mm as X,Y,Z for maxD (default: reconstructed from the original).
    #[arg(long, value_parser = super::parse_voxel)]
    voxel: Option<[f32; 3]>,
    #[arg(long)]
    json: bool,
}

pub fn exec(args: Args) -> anyhow::Result<()> {
    let read = |p: &PathBuf| read_input(p, &ReadOptions::default());
    // Both read side by side (each parse has serial stretches); the original's error first.
    let (a, b) = rayon::join(|| read(&args.original), || read(&args.smoothed));
    let (a, b) = (a?, b?);
    let refs = args
        .references
        .iter()
        .map(|p| {
            let name = p.file_stem().map_or_else(
                || p.display().to_string(),
                |s| s.to_string_lossy().into_owned(),
            );
            read(p).map(|m| (name, m.mesh))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let report = destair::report::compare::compare(
        &a.mesh,
        &b.mesh,
        &refs,
        args.voxel.map(|v| v.map(f64::from)),
    );
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", report.to_text());
    }
    Ok(())
}
