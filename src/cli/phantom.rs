//! `destair phantom`: marching-cubes meshes of analytic shapes with real staircases.

use super::UsageError;
use std::path::PathBuf;

/// NAME is one of sphere-iso, sphere-aniso, sphere-aniso-1-16, -1-8, -1-4, -1-2, -top,
/// sphere-smooth (and the same cut variants), cap-cylinder, neck, aneurysm; `big N`
/// (about N triangles); `cohort` (--cases N); or the label map `labelmap-neck`.
#[derive(clap::Args)]
pub struct Args {
    /// Which phantom.
    name: String,
    /// Triangle count for `big`.
    size: Option<u64>,
    /// Output folder (one PLY per structure plus phantom.json; for `cohort` one folder per case).
    #[arg(long)]
    out: PathBuf,
    /// Rotate the meshes about the volume centre around x (degrees).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    rotate_x: f64,
    /// Then around y (degrees).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    rotate_y: f64,
    /// Seed for the sub-voxel placement of the shapes.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Leave structures open where they leave the volume (default: flat caps).
    #[arg(long)]
    open_ends: bool,
    /// Number of cases for `cohort`.
    #[arg(long, default_value_t = 6)]
    cases: usize,
}

pub fn exec(args: Args) -> anyhow::Result<()> {
    use destair::phantom::{
        big_case, cohort_case, named_case, write_case, BorderEnds, PhantomOptions,
    };
    let Args {
        name,
        size,
        out,
        rotate_x,
        rotate_y,
        seed,
        open_ends,
        cases,
    } = args;
    let options = PhantomOptions {
        rotate_x_deg: rotate_x,
        rotate_y_deg: rotate_y,
        seed,
        ends: if open_ends {
            BorderEnds::Open
        } else {
            BorderEnds::Capped
        },
    };
    if destair::phantom::cases::LABEL_MAP_NAMES.contains(&name.as_str()) {
        let (volume, names) = destair::phantom::cases::write_label_map_case(&name, &options, &out)?;
        for l in &volume.labels {
            let label = names
                .iter()
                .find(|(v, _)| *v == l.value)
                .map_or("", |(_, n)| n.as_str());
            println!(
                "{}: label {} {label}: {} voxels",
                out.join("segmentation.nii.gz").display(),
                l.value,
                l.n_voxels
            );
        }
        return Ok(());
    }
    if !["big", "cohort"].contains(&name.as_str())
        && !destair::phantom::cases::CASE_NAMES.contains(&name.as_str())
        && !destair::phantom::cases::SMOOTH_CASE_NAMES.contains(&name.as_str())
    {
        return Err(UsageError(
            destair::phantom::cases::PhantomError::UnknownName(name).to_string(),
        )
        .into());
    }
    let started = std::time::Instant::now();
    let written: Vec<_> = match name.as_str() {
        "cohort" => (0..cases)
            .map(|i| {
                let case = cohort_case(i, seed);
                let dir = out.join(&case.info.name);
                write_case(&case, &dir).map(|()| (case, dir))
            })
            .collect::<Result<_, _>>()?,
        "big" => {
            let case = big_case(size.unwrap_or(1_000_000), &options);
            write_case(&case, &out)?;
            vec![(case, out.clone())]
        }
        _ => {
            let case = named_case(&name, &options)?;
            write_case(&case, &out)?;
            vec![(case, out.clone())]
        }
    };
    for (case, dir) in &written {
        for s in &case.info.structures {
            println!(
                "{}: {} vertices, {} triangles",
                dir.join(format!("{}.ply", s.name)).display(),
                s.n_vertices,
                s.n_triangles
            );
        }
    }
    eprintln!("generated in {:.2} s", started.elapsed().as_secs_f64());
    Ok(())
}
