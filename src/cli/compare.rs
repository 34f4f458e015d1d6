//! `destair compare`: the papers' measures between an original and a smoothed mesh.

use super::read_input;
use destair::io::ReadOptions;
use destair::mesh::order::{working_numbering, Renumbering};
use destair::Mesh;
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
    // A scattered numbering is measured in scanline order, as `smooth` works: the measures do
    // not depend on the numbering (but for the rounding of sums), their speed does. A
    // smoothed copy with the original's faces takes the original's renumbering, so that each
    // vertex is still compared with itself.
    let order_a = working_numbering(&a.mesh);
    let order_b = if a.mesh.triangles() == b.mesh.triangles() {
        order_a.clone()
    } else {
        working_numbering(&b.mesh)
    };
    let (original, smoothed) = (
        in_order(a.mesh, order_a.as_ref()),
        in_order(b.mesh, order_b.as_ref()),
    );
    let refs = args
        .references
        .iter()
        .map(|p| {
            let name = p.file_stem().map_or_else(
                || p.display().to_string(),
                |s| s.to_string_lossy().into_owned(),
            );
            read(p).map(|m| {
                let order = working_numbering(&m.mesh);
                (name, in_order(m.mesh, order.as_ref()))
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let report = destair::report::compare::compare(
        &original,
        &smoothed,
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

/// `mesh` renumbered by `order`, or as it is.
fn in_order(mesh: Mesh, order: Option<&Renumbering>) -> Mesh {
    match order {
        Some(r) => r.mesh(&mesh),
        None => mesh,
    }
}
