//! The `destair` command line: parse -> run the subcommand -> exit code.
//!
//! Exit codes: 0 success; 2 usage error; 3 an input could not be processed (bad mesh file);
//! 1 internal error. Never 128+n for data errors, since workflow engines retry those.

use anyhow::Context;
use clap::{Parser, Subcommand, ValueEnum};
use destair::io::{read_mesh, ReadMode, ReadOptions};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "destair",
    version,
    about = "Removes staircase artifacts from medical surface meshes"
)]
struct Cli {
    /// Worker threads (default: RAYON_NUM_THREADS, else SLURM_CPUS_PER_TASK, else all cores).
    #[arg(long, global = true, env = "DESTAIR_THREADS")]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print what a mesh file holds: counts, size, volume, topology findings, curvature, voxel size.
    Inspect {
        /// Mesh file (.ply, .stl, .obj).
        mesh: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
        /// How to read the file: mmap (local disks) or read (network filesystems).
        #[arg(long, value_enum, default_value_t = ModeArg::Mmap)]
        read_mode: ModeArg,
    },
    /// Generate phantom cases: marching-cubes meshes of analytic shapes with real staircases.
    ///
    /// NAME is one of sphere-iso, sphere-aniso, sphere-aniso-1-16, -1-8, -1-4, -1-2, -top,
    /// cap-cylinder, neck, aneurysm; `big N` (about N triangles); or `cohort` (--cases N).
    Phantom {
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
    },
    /// Measure destair's throughput on generated meshes.
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// PLY read+validate, write and topology build on a generated closed mesh.
    Io {
        /// Approximate number of triangles.
        #[arg(long, default_value_t = 5_000_000)]
        triangles: usize,
        /// Folder for the temporary PLY file (default: the system temp folder).
        #[arg(long)]
        dir: Option<PathBuf>,
        /// Mesh to run on: the `big` phantom (marching-cubes blob) or a regular torus.
        #[arg(long, value_enum, default_value_t = MeshArg::Phantom)]
        mesh: MeshArg,
        /// Permute vertex numbering (worst-case memory locality).
        #[arg(long)]
        shuffle: bool,
        /// Runs per measurement; the best is reported.
        #[arg(long, default_value_t = 5)]
        repeat: usize,
        /// Print the results as JSON.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Clone, Copy, ValueEnum)]
enum MeshArg {
    Phantom,
    Torus,
}

#[derive(Clone, Copy, ValueEnum)]
enum ModeArg {
    Mmap,
    Read,
}

/// A command line that names something that does not exist (exit 2).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
struct UsageError(String);

/// Errors in the input data (exit 3) as opposed to internal failures (exit 1).
#[derive(Debug, thiserror::Error)]
#[error(transparent)]
struct InputError(destair::io::ReadError);

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Err(e) = configure_threads(cli.threads) {
        eprintln!("error: {e:#}");
        return ExitCode::from(2);
    }
    match run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            if e.downcast_ref::<UsageError>().is_some() {
                ExitCode::from(2)
            } else if e.downcast_ref::<InputError>().is_some() {
                ExitCode::from(3)
            } else {
                ExitCode::from(1)
            }
        }
    }
}

/// Sizes the rayon pool: --threads (or DESTAIR_THREADS), then RAYON_NUM_THREADS (which rayon
/// reads itself), then SLURM_CPUS_PER_TASK, then the core count.
fn configure_threads(threads: Option<usize>) -> anyhow::Result<()> {
    let from_env = |name| {
        std::env::var(name)
            .ok()
            .and_then(|s: String| s.trim().parse::<usize>().ok())
    };
    let slurm = if from_env("RAYON_NUM_THREADS").is_some() {
        None
    } else {
        from_env("SLURM_CPUS_PER_TASK")
    };
    if let Some(n) = threads.or(slurm) {
        anyhow::ensure!(n > 0, "--threads must be at least 1");
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .context("cannot start the thread pool")?;
    }
    Ok(())
}

fn run(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Inspect {
            mesh,
            json,
            read_mode,
        } => {
            let options = ReadOptions {
                mode: match read_mode {
                    ModeArg::Mmap => ReadMode::Mmap,
                    ModeArg::Read => ReadMode::Read,
                },
                ..Default::default()
            };
            let loaded = read_mesh(&mesh, &options).map_err(InputError)?;
            let report = destair::report::inspect::inspect(&mesh, &loaded);
            if json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                print!("{}", report.to_text());
            }
        }
        Command::Phantom {
            name,
            size,
            out,
            rotate_x,
            rotate_y,
            seed,
            open_ends,
            cases,
        } => {
            use destair::phantom::{
                big_case, cohort_case, named_case, write_case, BorderEnds, PhantomOptions,
            };
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
            if !["big", "cohort"].contains(&name.as_str())
                && !destair::phantom::cases::CASE_NAMES.contains(&name.as_str())
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
        }
        Command::Bench {
            what:
                BenchCommand::Io {
                    triangles,
                    dir,
                    mesh,
                    shuffle,
                    repeat,
                    json,
                },
        } => {
            let dir = dir.unwrap_or_else(std::env::temp_dir);
            let kind = match mesh {
                MeshArg::Phantom => destair::bench::BenchMesh::Phantom,
                MeshArg::Torus => destair::bench::BenchMesh::Torus,
            };
            let r = destair::bench::io(&dir, triangles, kind, shuffle, repeat)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&r)?);
            } else {
                println!(
                    "bench io: {:?} mesh, {} vertices, {} triangles{}, binary PLY {:.1} MB, {} threads, best of {repeat}",
                    r.mesh,
                    r.n_vertices,
                    r.n_triangles,
                    if r.shuffled { " (shuffled numbering)" } else { "" },
                    r.file_bytes as f64 / 1e6,
                    r.threads
                );
                println!(
                    "  read+validate (mmap)  {:.4} s  {:.0} MB/s",
                    r.read_mmap_s, r.read_mmap_mb_per_s
                );
                println!("  read+validate (read)  {:.4} s", r.read_plain_s);
                println!(
                    "  write (atomic)        {:.4} s  {:.0} MB/s",
                    r.write_s, r.write_mb_per_s
                );
                println!("  topology build        {:.4} s", r.topology_s);
                println!(
                    "  STL ({:.1} MB) write  {:.4} s, read+weld {:.4} s",
                    r.stl_file_bytes as f64 / 1e6,
                    r.stl_write_s,
                    r.stl_read_s
                );
            }
        }
    }
    Ok(())
}
