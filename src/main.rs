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
    /// Smooth one mesh with one of the papers' smoothers.
    Smooth {
        /// Input mesh (.ply, .stl, .obj).
        input: PathBuf,
        /// Output mesh (.ply or .stl); vertex order is kept.
        #[arg(short, long)]
        output: PathBuf,
        #[arg(long, value_enum)]
        method: MethodArg,
        /// Iterations (the maximum for cell-size, cell-edge and diamond, which stop on convergence).
        #[arg(long)]
        iterations: Option<usize>,
        /// Step factor (default 0.5; 1 for the constrained relaxations).
        #[arg(long)]
        lambda: Option<f32>,
        /// Taubin's negative factor.
        #[arg(long, default_value_t = -0.53, allow_negative_numbers = true)]
        mu: f32,
        /// Laplace+HC: pull towards the original (0) or previous (1) positions.
        #[arg(long, default_value_t = 0.0)]
        alpha: f32,
        /// Laplace+HC: share of a vertex's own correction.
        #[arg(long, default_value_t = 0.5)]
        beta: f32,
        /// Voxel size in mm as X,Y,Z (default: reconstructed from the mesh).
        #[arg(long, value_parser = parse_voxel)]
        voxel: Option<[f32; 3]>,
        /// Relaxations stop when no vertex moves more than this in one iteration (mm).
        #[arg(long, default_value_t = 0.002)]
        threshold: f32,
        /// PLY file with a per-vertex `weight` property in [0, 1] (same vertices as the input).
        #[arg(long)]
        weights: Option<PathBuf>,
        /// Let vertices on open boundary loops move (by default clipped rims stay in place).
        #[arg(long)]
        move_boundary: bool,
        /// Add `weight` and `displacement` (mm) vertex properties to a PLY output.
        #[arg(long)]
        annotate: bool,
    },
    /// Compare a smoothed mesh with its original: distances, volume, curvature, displacement.
    Compare {
        original: PathBuf,
        smoothed: PathBuf,
        /// Reference structures whose minimum distance is reported before and after.
        #[arg(long = "reference")]
        references: Vec<PathBuf>,
        /// Voxel size in mm as X,Y,Z for maxD (default: reconstructed from the original).
        #[arg(long, value_parser = parse_voxel)]
        voxel: Option<[f32; 3]>,
        #[arg(long)]
        json: bool,
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
    /// Every smoother (seconds per run, vertex updates per second) and the Hausdorff metric.
    Smooth {
        /// Approximate number of triangles of the `big` phantom.
        #[arg(long, default_value_t = 1_000_000)]
        triangles: usize,
        #[arg(long, default_value_t = 20)]
        iterations: usize,
        /// Runs per measurement; the best is reported.
        #[arg(long, default_value_t = 3)]
        repeat: usize,
        #[arg(long)]
        json: bool,
    },
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

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum MethodArg {
    Laplace,
    Hc,
    Taubin,
    Mcf,
    Npc,
    CellSize,
    CellEdge,
    Diamond,
}

fn parse_voxel(s: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let values: Vec<f32> = parts
        .iter()
        .map(|p| p.parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected three numbers X,Y,Z in mm, got {s:?}"))?;
    match values.as_slice() {
        [x, y, z] if values.iter().all(|v| v.is_finite() && *v > 0.0) => Ok([*x, *y, *z]),
        _ => Err(format!(
            "expected three positive numbers X,Y,Z in mm, got {s:?}"
        )),
    }
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
        Command::Smooth {
            input,
            output,
            method,
            iterations,
            lambda,
            mu,
            alpha,
            beta,
            voxel,
            threshold,
            weights,
            move_boundary,
            annotate,
        } => {
            use destair::smooth::{boundary_vertices, smooth, Method};
            let loaded = read_mesh(&input, &ReadOptions::default()).map_err(InputError)?;
            let mesh = &loaded.mesh;
            let topology = destair::Topology::build(mesh);
            let needs_voxel = matches!(
                method,
                MethodArg::Npc | MethodArg::CellSize | MethodArg::CellEdge | MethodArg::Diamond
            );
            let voxel = match (voxel, needs_voxel) {
                (Some(v), _) => v,
                (None, false) => [1.0; 3],
                (None, true) => {
                    let est = destair::analysis::voxel_size(mesh, &topology);
                    let s = est.spacing().ok_or_else(|| {
                        UsageError(format!(
                            "{}: cannot reconstruct the voxel size from the mesh ({est:?}); pass --voxel X,Y,Z",
                            input.display()
                        ))
                    })?;
                    s.map(|x| x as f32)
                }
            };
            let relax_lambda = lambda.unwrap_or(1.0);
            let lambda = lambda.unwrap_or(0.5);
            let method = match method {
                MethodArg::Laplace => Method::Laplace { lambda },
                MethodArg::Hc => Method::Hc {
                    lambda,
                    alpha,
                    beta,
                },
                MethodArg::Taubin => Method::Taubin { lambda, mu },
                MethodArg::Mcf => Method::Mcf { lambda },
                MethodArg::Npc => Method::Npc { lambda, voxel },
                MethodArg::CellSize => Method::CellSize {
                    lambda: relax_lambda,
                    voxel,
                    threshold,
                },
                MethodArg::CellEdge => Method::CellEdge {
                    lambda: relax_lambda,
                    voxel,
                    threshold,
                },
                MethodArg::Diamond => Method::Diamond {
                    lambda: relax_lambda,
                    voxel,
                    threshold,
                },
            };
            let iterations = iterations.unwrap_or(if method.is_relaxation() { 1000 } else { 20 });
            let weights = match weights {
                None => destair::weights::VertexWeights::uniform(mesh.n_vertices()),
                Some(path) => {
                    let options = ReadOptions {
                        keep_vertex_properties: true,
                        ..Default::default()
                    };
                    let w = read_mesh(&path, &options).map_err(InputError)?;
                    let values = w
                        .vertex_properties
                        .into_iter()
                        .find(|p| p.name == "weight")
                        .ok_or_else(|| {
                            UsageError(format!("{}: no vertex property 'weight'", path.display()))
                        })?
                        .values;
                    destair::weights::VertexWeights::new(values, mesh.n_vertices())
                        .map_err(|e| UsageError(format!("{}: {e}", path.display())))?
                }
            };
            let fixed = if move_boundary {
                vec![false; mesh.n_vertices()]
            } else {
                boundary_vertices(&topology)
            };
            let started = std::time::Instant::now();
            let (positions, stats) = smooth(mesh, &topology, &method, iterations, &weights, &fixed);
            let seconds = started.elapsed().as_secs_f64();
            let mut smoothed = mesh.clone();
            smoothed.positions_mut().copy_from_slice(&positions);
            let lengths: Vec<f32> = destair::metrics::displacements(mesh.positions(), &positions)
                .into_iter()
                .map(|d| d as f32)
                .collect();
            match output
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase)
                .as_deref()
            {
                Some("ply") => {
                    let props: Vec<(&str, &[f32])> = if annotate {
                        vec![("weight", weights.as_slice()), ("displacement", &lengths)]
                    } else {
                        Vec::new()
                    };
                    destair::io::ply::write_ply(&output, &smoothed, &loaded.meta, &props)?
                }
                Some("stl") => destair::io::stl::write_stl(&output, &smoothed, &loaded.meta)?,
                _ => {
                    return Err(UsageError(format!(
                        "{}: output must end in .ply or .stl",
                        output.display()
                    ))
                    .into())
                }
            }
            println!(
                "{} {}: {} iterations{} in {:.3} s, last step {:.5} mm, {} vertices fixed -> {}",
                method.name(),
                input.display(),
                stats.iterations,
                if method.is_relaxation() {
                    if stats.converged {
                        " (converged)"
                    } else {
                        " (not converged)"
                    }
                } else {
                    ""
                },
                seconds,
                stats.last_max_step,
                stats.n_fixed,
                output.display()
            );
        }
        Command::Compare {
            original,
            smoothed,
            references,
            voxel,
            json,
        } => {
            let read = |p: &PathBuf| read_mesh(p, &ReadOptions::default()).map_err(InputError);
            let a = read(&original)?;
            let b = read(&smoothed)?;
            let refs = references
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
                voxel.map(|v| v.map(f64::from)),
            );
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
                BenchCommand::Smooth {
                    triangles,
                    iterations,
                    repeat,
                    json,
                },
        } => {
            let r = destair::bench::smooth(triangles, iterations, repeat);
            if json {
                println!("{}", serde_json::to_string_pretty(&r)?);
            } else {
                println!(
                    "bench smooth: {} vertices, {} triangles, {} iterations, {} threads, best of {repeat}",
                    r.n_vertices, r.n_triangles, r.iterations, r.threads
                );
                for t in &r.smoothers {
                    println!(
                        "  {:<10} {:.4} s  {:.1} M vertex-updates/s",
                        t.method,
                        t.seconds,
                        t.vertex_updates_per_s / 1e6
                    );
                }
                println!(
                    "  hausdorff  {:.4} s  ({:.2} M point-to-surface queries/s, grids included)",
                    r.hausdorff_s,
                    r.hausdorff_queries_per_s / 1e6
                );
            }
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
