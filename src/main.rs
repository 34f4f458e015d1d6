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
        /// Also analyse context: stack axis, staircases, caps, distances, weights.
        #[arg(long)]
        context: bool,
        /// Write the mesh with per-vertex `weight`, `staircase`, `cap` and distance properties (PLY).
        #[arg(long)]
        export: Option<PathBuf>,
        #[command(flatten)]
        ctx: ContextArgs,
    },
    /// Smooth one mesh with one of the papers' smoothers.
    Smooth {
        /// Input mesh (.ply, .stl, .obj).
        input: PathBuf,
        /// Output mesh (.ply or .stl); vertex order is kept.
        #[arg(short, long)]
        output: PathBuf,
        /// laplace, hc, taubin, mcf, npc, cell-size, cell-edge or diamond.
        #[arg(long)]
        method: destair::smooth::MethodKind,
        /// Iterations (the maximum for cell-size, cell-edge and diamond, which stop on convergence).
        #[arg(long)]
        iterations: Option<usize>,
        /// Step factor (default 0.5; 1 for the constrained relaxations).
        #[arg(long)]
        lambda: Option<f32>,
        /// Taubin's negative factor (default -0.53).
        #[arg(long, allow_negative_numbers = true)]
        mu: Option<f32>,
        /// Laplace+HC: pull towards the original (0, default) or previous (1) positions.
        #[arg(long)]
        alpha: Option<f32>,
        /// Laplace+HC: share of a vertex's own correction (default 0.5).
        #[arg(long)]
        beta: Option<f32>,
        /// Voxel size in mm as X,Y,Z (default: reconstructed from the mesh).
        #[arg(long, value_parser = parse_voxel)]
        voxel: Option<[f32; 3]>,
        /// Relaxations stop when no vertex moves more than this in one iteration (mm; default 0.002).
        #[arg(long)]
        threshold: Option<f32>,
        /// PLY file with a per-vertex `weight` property in [0, 1] (same vertices as the input).
        #[arg(long)]
        weights: Option<PathBuf>,
        /// Let vertices on open boundary loops move (by default clipped rims stay in place).
        #[arg(long)]
        move_boundary: bool,
        /// Add `weight` and `displacement` (mm) vertex properties to a PLY output.
        #[arg(long)]
        annotate: bool,
        /// Weight by staircases (Moench): smooth artifacts, keep the rest.
        #[arg(long)]
        staircase: bool,
        #[command(flatten)]
        ctx: ContextArgs,
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
    /// Process a whole cohort described by a configuration file.
    Run {
        config: PathBuf,
        /// Process a share of the cases: I/N (0 <= I < N), or `slurm` for the array task's share.
        #[arg(long)]
        shard: Option<String>,
        /// Redo cases that are already done with the same inputs and settings.
        #[arg(long)]
        force: bool,
    },
    /// Process exactly one case folder (for Snakemake, Nextflow and other workflow engines).
    RunCase {
        case_dir: PathBuf,
        #[arg(long)]
        config: PathBuf,
        /// Output root; the case's outputs go to OUT/<case folder name>/.
        #[arg(long)]
        out: PathBuf,
        #[arg(long)]
        force: bool,
    },
    /// Validate a configuration and print the effective settings per structure; touches nothing.
    Check { config: PathBuf },
    /// Print the cases a configuration finds (TSV, or JSON lines), e.g. for workflow engines.
    List {
        config: PathBuf,
        #[arg(long)]
        jsonl: bool,
        #[arg(long)]
        shard: Option<String>,
    },
    /// Rebuild the cohort summary from the case reports under one or more output folders.
    Summarize {
        #[arg(required = true)]
        out_dirs: Vec<PathBuf>,
        /// The configuration, to report cases that have no report yet.
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Generate a small phantom cohort and run config/demo.toml on it.
    Demo {
        /// Folder for the demo (cases/, demo.toml, out/).
        #[arg(default_value = "destair-demo")]
        dir: PathBuf,
        /// Number of cases.
        #[arg(long, default_value_t = 6)]
        cases: usize,
    },
    /// Generate phantom cases: marching-cubes meshes of analytic shapes with real staircases.
    ///
    /// NAME is one of sphere-iso, sphere-aniso, sphere-aniso-1-16, -1-8, -1-4, -1-2, -top,
    /// sphere-smooth (and the same cut variants), cap-cylinder, neck, aneurysm; `big N`
    /// (about N triangles); or `cohort` (--cases N).
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
    /// Stack axis, staircase weights, caps, and exact distance queries per second.
    Context {
        /// Approximate number of triangles of the `big` phantom (and of query points).
        #[arg(long, default_value_t = 1_000_000)]
        triangles: usize,
        #[arg(long, default_value_t = 3)]
        repeat: usize,
        #[arg(long)]
        json: bool,
    },
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

/// Context options shared by `inspect --context` and `smooth`.
#[derive(clap::Args)]
struct ContextArgs {
    /// Stack axis: `auto` (estimated from the mesh) or X,Y,Z.
    #[arg(long, default_value = "auto", value_parser = parse_axis)]
    axis: AxisArg,
    /// Orientation change above which a vertex is a staircase vertex.
    #[arg(long, default_value_t = 0.7)]
    tau: f32,
    /// Reach of a staircase along the surface (mm).
    #[arg(long, default_value_t = 3.0)]
    tau_max: f32,
    /// Weight floor for artifact-free areas (0 keeps them exactly in place).
    #[arg(long, default_value_t = 0.1)]
    beta_min: f32,
    /// Detected caps: keep them exactly (preserve) or smooth them like the rest.
    #[arg(long, value_enum, default_value_t = CapsArg::Preserve)]
    caps: CapsArg,
    /// Reference structures whose distance must be preserved (repeatable).
    #[arg(long = "reference")]
    references: Vec<PathBuf>,
    /// linear | margin:MM | exp:K | ramp:D0,D1 (mm)
    #[arg(long, default_value = "linear", value_parser = parse_scaling)]
    distance_scaling: destair::weights::DistanceScaling,
    /// How staircase and distance weights combine.
    #[arg(long, value_enum, default_value_t = CombineArg::Product)]
    combine: CombineArg,
}

#[derive(Clone, Copy)]
enum AxisArg {
    Auto,
    Given([f32; 3]),
}

fn parse_axis(s: &str) -> Result<AxisArg, String> {
    if s == "auto" {
        return Ok(AxisArg::Auto);
    }
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected `auto` or X,Y,Z, got {s:?}"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) && (x * x + y * y + z * z) > 0.0 => {
            Ok(AxisArg::Given([*x, *y, *z]))
        }
        _ => Err(format!("expected `auto` or a non-zero X,Y,Z, got {s:?}")),
    }
}

fn parse_scaling(s: &str) -> Result<destair::weights::DistanceScaling, String> {
    s.parse()
}

#[derive(Clone, Copy, ValueEnum)]
enum CapsArg {
    Preserve,
    Smooth,
}

#[derive(Clone, Copy, ValueEnum)]
enum CombineArg {
    Product,
    Min,
}

impl ContextArgs {
    /// The library parameters; `staircase` turns staircase weighting on.
    fn params(&self, staircase: bool) -> destair::weights::ContextParams {
        use destair::weights::{AxisChoice, CapPolicy, Combine, ContextParams, StaircaseParams};
        ContextParams {
            staircase,
            axis: match self.axis {
                AxisArg::Auto => AxisChoice::Auto,
                AxisArg::Given(a) => AxisChoice::Given(a),
            },
            staircase_params: StaircaseParams {
                tau: self.tau,
                tau_max_mm: self.tau_max,
                beta_min: self.beta_min,
            },
            caps: match self.caps {
                CapsArg::Preserve => CapPolicy::Preserve,
                CapsArg::Smooth => CapPolicy::Smooth,
            },
            cap_params: Default::default(),
            distance_scaling: self.distance_scaling,
            combine: match self.combine {
                CombineArg::Product => Combine::Product,
                CombineArg::Min => Combine::Min,
            },
        }
    }

    /// Reads the reference meshes and indexes their triangles.
    fn reference_grids(&self) -> anyhow::Result<Vec<destair::spatial::TriangleGrid>> {
        self.references
            .iter()
            .map(|p| {
                let r = read_mesh(p, &ReadOptions::default()).map_err(InputError)?;
                Ok(destair::spatial::TriangleGrid::build(&r.mesh))
            })
            .collect()
    }

    /// Validates value ranges clap cannot express.
    fn check(&self) -> Result<(), UsageError> {
        let valid = (0.0..=1.0).contains(&self.tau)
            && (0.0..=1.0).contains(&self.beta_min)
            && self.tau_max.is_finite()
            && self.tau_max > 0.0;
        if !valid {
            return Err(UsageError(
                "--tau and --beta-min must lie in [0, 1] and --tau-max above 0".into(),
            ));
        }
        Ok(())
    }
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
    // Like other Unix tools, end quietly when the reader of our output goes away
    // (`destair list ... | head`) instead of failing on every print.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE at startup, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    if let Err(e) = configure_threads(cli.threads) {
        eprintln!("error: {e:#}");
        return ExitCode::from(2);
    }
    match run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            if let Some(Interrupted(signal)) = e.downcast_ref::<Interrupted>() {
                ExitCode::from(128 + *signal as u8)
            } else if e.downcast_ref::<UsageError>().is_some() {
                ExitCode::from(2)
            } else if e.downcast_ref::<CasesFailed>().is_some()
                || e.downcast_ref::<InputError>().is_some()
            {
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

/// A run that stopped early because of a signal (exit 128 + signal, so engines may retry).
#[derive(Debug, thiserror::Error)]
#[error("stopped by signal {0}")]
struct Interrupted(i32);

/// Some cases failed (exit 3).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
struct CasesFailed(String);

fn load_plan(config: &std::path::Path) -> anyhow::Result<destair::job::Plan> {
    destair::job::Plan::load(config).map_err(|e| UsageError(e.to_string()).into())
}

fn shard_of(arg: &Option<String>) -> anyhow::Result<Option<destair::job::Shard>> {
    use destair::job::Shard;
    match arg.as_deref() {
        None => Ok(None),
        Some("slurm") => Shard::from_slurm(|k| std::env::var(k).ok())
            .map(Some)
            .map_err(|e| UsageError(e).into()),
        Some(s) => Shard::parse(s).map(Some).map_err(|e| UsageError(e).into()),
    }
}

/// UTC wall-clock time of day, for log lines on clusters.
fn clock() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    format!(
        "{:02}:{:02}:{:02}",
        secs / 3600 % 24,
        secs / 60 % 60,
        secs % 60
    )
}

/// Runs cases through the pipeline with progress lines, signal handling and the exit policy.
fn run_cases(
    plan: &destair::job::Plan,
    cases: Vec<destair::job::CaseInput>,
    force: bool,
    write_summary: bool,
) -> anyhow::Result<()> {
    use destair::job::pipeline::{run, Event, RunOptions};
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let term = Arc::new(AtomicBool::new(false));
    let int = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGTERM, term.clone())?;
    signal_hook::flag::register(signal_hook::consts::SIGINT, int.clone())?;
    // The loader polls `stop` between cases; either signal sets it.
    let stop = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGTERM, stop.clone())?;
    signal_hook::flag::register(signal_hook::consts::SIGINT, stop.clone())?;
    let total = cases.len();
    let ids: Vec<String> = cases.iter().map(|c| c.id.clone()).collect();
    let started = std::time::Instant::now();
    let mut last_log = std::time::Instant::now();
    let (mut done, mut failed, mut skipped, mut n_structures) = (0usize, 0usize, 0usize, 0usize);
    eprintln!(
        "[{}] destair: {total} cases, {} worker(s), {} threads",
        clock(),
        plan.workers,
        rayon::current_num_threads()
    );
    // A live bar on a terminal; off a terminal (cluster logs) indicatif draws nothing, so
    // plain timestamped lines every few seconds instead.
    let bar = std::io::IsTerminal::is_terminal(&std::io::stderr()).then(|| {
        let bar = indicatif::ProgressBar::new(total as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{elapsed_precise} [{bar:30}] {pos}/{len} cases {msg} ({per_sec}, ETA {eta})",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let mut on_event = |e: Event| {
        match e {
            Event::CaseDone {
                id,
                failed: f,
                skipped: s,
                structures,
            } => {
                done += 1;
                n_structures += structures;
                failed += f as usize;
                skipped += s as usize;
                if f {
                    let line = format!("[{}] case {id} failed (see its report.json)", clock());
                    match &bar {
                        Some(b) => b.println(line),
                        None => eprintln!("{line}"),
                    }
                }
            }
            Event::WriteFailed { id, error } => {
                done += 1;
                failed += 1;
                eprintln!("[{}] case {id}: cannot write outputs: {error}", clock());
            }
        }
        if let Some(b) = &bar {
            b.set_position(done as u64);
            b.set_message(format!(
                "{n_structures} structures, {failed} failed, {skipped} already done"
            ));
            return;
        }
        if last_log.elapsed().as_secs_f64() >= 5.0 || done == total {
            let rate = done as f64 / started.elapsed().as_secs_f64().max(1e-9);
            let eta = (total - done) as f64 / rate.max(1e-9);
            eprintln!(
                "[{}] {done}/{total} cases, {n_structures} structures ({failed} failed, {skipped} already done), {:.1} cases/min, ETA {:.0} s",
                clock(),
                60.0 * rate,
                eta
            );
            last_log = std::time::Instant::now();
        }
    };
    let result = run(plan, cases, &RunOptions { force }, &stop, &mut on_event);
    if let Some(b) = &bar {
        b.finish();
    }
    if write_summary && result.not_started == 0 {
        let reports: Vec<_> = ids
            .iter()
            .filter_map(|id| {
                let path = destair::job::pipeline::case_dir(plan, id).join("report.json");
                destair::job::summary::read_case_rows(&path).ok()
            })
            .collect();
        let summary = destair::job::summary::summarize(reports, Some(&ids));
        destair::job::summary::write_summary(&plan.output_root, &summary)?;
        eprintln!(
            "[{}] summary: {}",
            clock(),
            plan.output_root.join("summary.csv").display()
        );
    }
    if term.load(Ordering::Relaxed) {
        eprintln!(
            "[{}] stopped by SIGTERM: {} cases not started; rerun to continue",
            clock(),
            result.not_started
        );
        return Err(Interrupted(15).into());
    }
    if int.load(Ordering::Relaxed) {
        eprintln!(
            "[{}] stopped by SIGINT: {} cases not started; rerun to continue",
            clock(),
            result.not_started
        );
        return Err(Interrupted(2).into());
    }
    if !result.failed.is_empty() {
        return Err(CasesFailed(format!(
            "{} of {total} cases failed: {}",
            result.failed.len(),
            result.failed.join(", ")
        ))
        .into());
    }
    Ok(())
}

/// The plan's cases in a shard (all without one); discovery warnings go to stderr.
fn discover_cases(
    plan: &destair::job::Plan,
    shard: Option<destair::job::Shard>,
) -> Vec<destair::job::CaseInput> {
    let found = destair::job::discover(plan);
    for w in &found.warnings {
        eprintln!("warning: {w}");
    }
    found
        .cases
        .into_iter()
        .filter(|c| shard.is_none_or(|s| s.contains(&c.id)))
        .collect()
}

fn run(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Run {
            config,
            shard,
            force,
        } => {
            let plan = load_plan(&config)?;
            let shard = shard_of(&shard)?;
            let cases = discover_cases(&plan, shard);
            if cases.is_empty() && shard.is_none() {
                return Err(UsageError(format!(
                    "{}: no cases found under {} (check [input] roots and case_depth)",
                    config.display(),
                    plan.roots
                        .iter()
                        .map(|r| r.display().to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
                .into());
            }
            if let Some(s) = shard {
                eprintln!(
                    "shard {}/{}: {} cases; run `destair summarize {}` when all shards are done",
                    s.index,
                    s.count,
                    cases.len(),
                    plan.output_root.display()
                );
            }
            run_cases(&plan, cases, force, shard.is_none())?;
        }
        Command::RunCase {
            case_dir,
            config,
            out,
            force,
        } => {
            let mut plan = load_plan(&config)?;
            plan.output_root = out;
            let dir = case_dir
                .canonicalize()
                .map_err(|e| UsageError(format!("{}: {e}", case_dir.display())))?;
            let name = dir
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let mut warnings = Vec::new();
            let case = destair::job::discover::case_at(&plan, &dir, name, &mut warnings)
                .ok_or_else(|| {
                    UsageError(format!("{}: no meshes in this folder", case_dir.display()))
                })?;
            for w in warnings {
                eprintln!("warning: {w}");
            }
            run_cases(&plan, vec![case], force, false)?;
        }
        Command::Check { config } => {
            let plan = load_plan(&config)?;
            let found = destair::job::discover(&plan);
            for w in &found.warnings {
                println!("warning: {w}");
            }
            let names: std::collections::BTreeSet<&str> = found
                .cases
                .iter()
                .flat_map(|c| c.meshes.iter().map(|(n, _)| n.as_str()))
                .collect();
            println!(
                "{}: valid; {} cases, {} structure names; output to {}",
                config.display(),
                found.cases.len(),
                names.len(),
                plan.output_root.display()
            );
            for n in names {
                let tables = plan.matching_tables(n);
                println!(
                    "\n[{n}] (from [defaults]{})",
                    tables
                        .iter()
                        .map(|t| format!(" + [[structure]] {t:?}"))
                        .collect::<String>()
                );
                println!("{}", serde_json::to_string_pretty(&plan.settings_for(n))?);
            }
        }
        Command::List {
            config,
            jsonl,
            shard,
        } => {
            let plan = load_plan(&config)?;
            let shard = shard_of(&shard)?;
            for c in discover_cases(&plan, shard) {
                let structures: Vec<&str> = c.meshes.iter().map(|(n, _)| n.as_str()).collect();
                if jsonl {
                    println!(
                        "{}",
                        serde_json::json!({ "case": c.id, "dir": c.dir, "structures": structures })
                    );
                } else {
                    println!("{}\t{}\t{}", c.id, c.dir.display(), structures.join(","));
                }
            }
        }
        Command::Summarize { out_dirs, config } => {
            let expected = match &config {
                Some(c) => Some(
                    destair::job::discover(&load_plan(c)?)
                        .cases
                        .into_iter()
                        .map(|c| c.id)
                        .collect::<Vec<_>>(),
                ),
                None => None,
            };
            let (reports, problems) = destair::job::summary::collect_reports(&out_dirs);
            for p in &problems {
                eprintln!("warning: {p}");
            }
            let summary = destair::job::summary::summarize(reports, expected.as_deref());
            destair::job::summary::write_summary(&out_dirs[0], &summary)?;
            println!(
                "{} cases: {} ok, {} failed, {} missing, {} duplicated -> {}",
                summary.n_cases,
                summary.n_ok,
                summary.failed.len(),
                summary.missing.len(),
                summary.duplicates.len(),
                out_dirs[0].join("summary.csv").display()
            );
            for (what, list) in [
                ("failed", &summary.failed),
                ("missing", &summary.missing),
                ("duplicated", &summary.duplicates),
            ] {
                if !list.is_empty() {
                    println!("{what}: {}", list.join(", "));
                }
            }
            if !(summary.failed.is_empty()
                && summary.missing.is_empty()
                && summary.duplicates.is_empty())
            {
                return Err(CasesFailed("the cohort is not complete".into()).into());
            }
        }
        Command::Demo { dir, cases } => {
            let cases_dir = dir.join("cases");
            for i in 0..cases {
                let case = destair::phantom::cohort_case(i, 0);
                destair::phantom::write_case(&case, &cases_dir.join(&case.info.name))?;
            }
            let config = dir.join("demo.toml");
            destair::io::write_atomically(&config, |w| {
                w.write_all(include_str!("../config/demo.toml").as_bytes())
            })?;
            eprintln!(
                "[{}] demo cohort of {cases} cases in {}; running {}",
                clock(),
                cases_dir.display(),
                config.display()
            );
            let plan = load_plan(&config)?;
            let found = destair::job::discover(&plan);
            run_cases(&plan, found.cases, false, true)?;
            println!("outputs and reports: {}", plan.output_root.display());
        }
        Command::Inspect {
            mesh,
            json,
            read_mode,
            context,
            export,
            ctx,
        } => {
            ctx.check()?;
            let options = ReadOptions {
                mode: match read_mode {
                    ModeArg::Mmap => ReadMode::Mmap,
                    ModeArg::Read => ReadMode::Read,
                },
                ..Default::default()
            };
            let loaded = read_mesh(&mesh, &options).map_err(InputError)?;
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
            staircase,
            ctx,
        } => {
            use destair::smooth::{boundary_vertices, smooth};
            ctx.check()?;
            let loaded = read_mesh(&input, &ReadOptions::default()).map_err(InputError)?;
            let mesh = &loaded.mesh;
            let topology = destair::Topology::build(mesh);
            let voxel = match (voxel, method.needs_voxel()) {
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
            let params = destair::smooth::MethodParams {
                lambda,
                mu,
                alpha,
                beta,
                threshold,
            };
            let kind = method;
            let method = kind.build(&params, voxel);
            let iterations = iterations.unwrap_or(kind.default_iterations());
            let context_on = staircase || !ctx.references.is_empty();
            let weights = match weights {
                None if context_on => {
                    let grids = ctx.reference_grids()?;
                    let refs: Vec<&destair::spatial::TriangleGrid> = grids.iter().collect();
                    let analysis = destair::weights::context_weights(
                        mesh,
                        &topology,
                        &ctx.params(staircase),
                        &refs,
                    );
                    let summary =
                        destair::report::inspect::context_summary(&analysis, mesh.n_vertices());
                    eprint!("{}", summary.to_text());
                    analysis.weights
                }
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
        }
        Command::Bench {
            what:
                BenchCommand::Context {
                    triangles,
                    repeat,
                    json,
                },
        } => {
            let r = destair::bench::context(triangles, repeat);
            if json {
                println!("{}", serde_json::to_string_pretty(&r)?);
            } else {
                println!(
                    "bench context: {} vertices, {} triangles, {} threads, best of {repeat}",
                    r.n_vertices, r.n_triangles, r.threads
                );
                println!("  topology           {:.4} s", r.topology_s);
                println!("  stack axis         {:.4} s", r.stack_axis_s);
                println!("  staircase weights  {:.4} s", r.staircase_weights_s);
                println!("  caps               {:.4} s", r.caps_s);
                println!("  triangle grid      {:.4} s", r.grid_build_s);
                println!(
                    "  {} exact queries  {:.4} s  ({:.2} M queries/s)",
                    r.n_queries,
                    r.queries_s,
                    r.queries_per_s / 1e6
                );
            }
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
