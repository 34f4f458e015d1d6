//! The commands of the `destair` binary, one module each (cargo's `commands/` layout). Each
//! module holds its clap arguments and an `exec` function; this module holds what they share:
//! the error kinds that decide the exit code, thread setup, and argument parsers. The cli is
//! the only part of destair that writes to the terminal.

pub mod bench;
pub mod check;
pub mod compare;
pub mod demo;
pub mod extract;
pub mod inspect;
pub mod list;
pub mod phantom;
pub mod run;
pub mod smooth;
pub mod summarize;

use destair::io::{read_mesh, ReadOptions};
use std::path::{Path, PathBuf};

/// A command line or configuration that cannot work as given (exit 2).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

/// Errors in the input data (exit 3) as opposed to internal failures (exit 1).
#[derive(Debug, thiserror::Error)]
#[error(transparent)]
pub struct InputError(pub destair::io::ReadError);

/// A label map that could not be read (exit 3).
#[derive(Debug, thiserror::Error)]
#[error(transparent)]
pub struct LabelMapInputError(pub destair::volume::LabelMapError);

/// A run that stopped early because of a signal (exit 128 + signal).
#[derive(Debug, thiserror::Error)]
#[error("stopped by signal {0}")]
pub struct Interrupted(pub i32);

/// Some cases failed, or a summary found the cohort incomplete (exit 3).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct CasesFailed(pub String);

/// A result that cannot be trusted (a diverged smoothing), so nothing was written (exit 3).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Rejected(pub String);

/// An error with its causes, each said once: a cause whose text its outer error already
/// holds (`x.ply: cannot write: No space left` over `No space left`) is not repeated.
pub fn message(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if out.contains(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    out
}

/// The exit code for an error: 2 usage, 3 bad input, failed cases or files that cannot be read
/// or written, 128 + n signals, else 1.
pub fn exit_code(e: &anyhow::Error) -> u8 {
    if let Some(Interrupted(signal)) = e.downcast_ref::<Interrupted>() {
        128 + *signal as u8
    } else if e.downcast_ref::<UsageError>().is_some()
        || e.downcast_ref::<destair::job::LockError>().is_some()
    {
        2
    } else if e.downcast_ref::<CasesFailed>().is_some()
        || e.downcast_ref::<InputError>().is_some()
        || e.downcast_ref::<LabelMapInputError>().is_some()
        || e.downcast_ref::<Rejected>().is_some()
        || e.chain().any(|c| {
            // Files that cannot be read or written (a full disk, a name too long, no
            // permission) are input and disk problems, not destair's.
            c.downcast_ref::<destair::io::WriteError>().is_some()
                || c.downcast_ref::<destair::volume::LabelMapError>().is_some()
                || c.downcast_ref::<std::io::Error>().is_some()
        })
    {
        3
    } else {
        1
    }
}

/// Most threads `--threads` may ask for, per core this process may use: beyond that, starting
/// the threads costs more than they can give (2000 threads made a 12 KB inspect take 19 s).
const MAX_THREADS_PER_CORE: usize = 4;

/// Sizes the rayon pool: --threads (or DESTAIR_THREADS), then RAYON_NUM_THREADS, then
/// SLURM_CPUS_PER_TASK, then the core count. Every source is checked the same way (rayon
/// would take any RAYON_NUM_THREADS, and 20 000 threads abort the process).
pub fn configure_threads(threads: Option<usize>) -> Result<(), UsageError> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let limit = MAX_THREADS_PER_CORE * cores;
    let check = |n: usize, source: &str| {
        if n == 0 || n > limit {
            return Err(UsageError(format!(
                "{source} = {n}: must be between 1 and {limit} ({MAX_THREADS_PER_CORE} per core; this process may use {cores} cores)"
            )));
        }
        Ok(n)
    };
    let from_env = |name: &str| -> Result<Option<usize>, UsageError> {
        match std::env::var(name) {
            Ok(s) => {
                let n = s
                    .trim()
                    .parse::<usize>()
                    .map_err(|_| UsageError(format!("{name} = {s:?} is not a number")))?;
                Ok(Some(check(n, name)?))
            }
            Err(std::env::VarError::NotPresent) => Ok(None),
            Err(std::env::VarError::NotUnicode(s)) => {
                Err(UsageError(format!("{name} = {s:?} is not a number")))
            }
        }
    };
    let n = match threads {
        Some(n) => Some(check(n, "--threads (or DESTAIR_THREADS)")?),
        // RAYON_NUM_THREADS=0 means rayon's default (every core), as rayon documents it.
        None if std::env::var("RAYON_NUM_THREADS").is_ok_and(|s| s.trim() == "0") => None,
        None => match from_env("RAYON_NUM_THREADS")? {
            Some(n) => Some(n),
            None => from_env("SLURM_CPUS_PER_TASK")?,
        },
    };
    if let Some(n) = n {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| UsageError(format!("cannot start {n} threads: {e}")))?;
    }
    Ok(())
}

/// UTC wall-clock time of day, for log lines on clusters.
pub fn clock() -> String {
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

/// Loads and validates a cohort configuration (errors are usage errors).
pub fn load_plan(config: &Path) -> anyhow::Result<destair::job::Plan> {
    destair::job::Plan::load(config).map_err(|e| UsageError(e.to_string()).into())
}

/// Reads a mesh named on the command line (errors are input errors, exit 3).
pub fn read_input(
    path: &Path,
    options: &ReadOptions,
) -> Result<destair::io::LoadedMesh, InputError> {
    read_mesh(path, options).map_err(InputError)
}

/// Refuses to write `output` when it is the same file as one of `inputs` (by device and
/// inode, whatever the spelling), unless `force`.
pub fn refuse_overwriting_inputs(
    output: &Path,
    inputs: &[&Path],
    force: bool,
) -> Result<(), UsageError> {
    if force {
        return Ok(());
    }
    for input in inputs {
        if destair::io::same_file(output, input) {
            return Err(UsageError(format!(
                "{}: this is the input {}; refusing to overwrite an input (write elsewhere, or pass --force)",
                output.display(),
                input.display()
            )));
        }
    }
    Ok(())
}

/// Parses `X,Y,Z` voxel sizes in mm (each finite and positive).
pub fn parse_voxel(s: &str) -> Result<[f32; 3], String> {
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

#[derive(Clone, Copy)]
pub enum AxisArg {
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

/// World convention of label-map coordinates on the command line.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum SpaceArg {
    Lps,
    Ras,
}

impl SpaceArg {
    pub fn space(self) -> destair::volume::Space {
        match self {
            SpaceArg::Lps => destair::volume::Space::Lps,
            SpaceArg::Ras => destair::volume::Space::Ras,
        }
    }
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum CapsArg {
    Preserve,
    Smooth,
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum CombineArg {
    Product,
    Min,
}

/// Context options shared by `inspect --context` and `smooth`.
#[derive(clap::Args)]
pub struct ContextArgs {
    /// Stack axis: `auto` (estimated from the mesh) or X,Y,Z.
    #[arg(long, default_value = "auto", value_parser = parse_axis)]
    pub axis: AxisArg,
    /// Orientation change above which a vertex is a staircase vertex: a number in [0, 1] (the
    /// paper's 0.7) or `auto` (chosen from the mesh's own orientation changes).
    #[arg(long, default_value = "auto")]
    pub tau: destair::weights::Tau,
    /// Reach of a staircase along the surface (mm).
    #[arg(long, default_value_t = 3.0)]
    pub tau_max: f32,
    /// Weight floor for artifact-free areas (0 keeps them exactly in place).
    #[arg(long, default_value_t = 0.1)]
    pub beta_min: f32,
    /// Detected caps: keep them exactly (preserve) or smooth them like the rest.
    #[arg(long, value_enum, default_value_t = CapsArg::Preserve)]
    pub caps: CapsArg,
    /// Reference structures whose distance must be preserved (repeatable).
    #[arg(long = "reference")]
    pub references: Vec<PathBuf>,
    /// linear | margin:MM | exp:K | ramp:D0,D1 (mm)
    #[arg(long, default_value = "linear", value_parser = parse_scaling)]
    pub distance_scaling: destair::weights::DistanceScaling,
    /// How staircase and distance weights combine.
    #[arg(long, value_enum, default_value_t = CombineArg::Product)]
    pub combine: CombineArg,
}

impl ContextArgs {
    /// The library parameters; `staircase` turns staircase weighting on.
    pub fn params(&self, staircase: bool) -> destair::weights::ContextParams {
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
                slice_step_change: None,
            },
            caps: match self.caps {
                CapsArg::Preserve => CapPolicy::Preserve,
                CapsArg::Smooth => CapPolicy::Smooth,
            },
            find_smoothed_caps: true,
            measure_curvature: false,
            cap_params: Default::default(),
            grid_mm: None,
            distance_scaling: self.distance_scaling,
            combine: match self.combine {
                CombineArg::Product => Combine::Product,
                CombineArg::Min => Combine::Min,
            },
        }
    }

    /// Reads the reference meshes and indexes their triangles.
    pub fn reference_trees(&self) -> anyhow::Result<Vec<destair::spatial::TriangleBvh>> {
        self.references
            .iter()
            .map(|p| {
                let r = read_input(p, &ReadOptions::default())?;
                Ok(destair::spatial::TriangleBvh::build(&r.mesh))
            })
            .collect()
    }

    /// Validates value ranges clap cannot express.
    pub fn check(&self) -> Result<(), UsageError> {
        let valid =
            (0.0..=1.0).contains(&self.beta_min) && self.tau_max.is_finite() && self.tau_max > 0.0;
        if !valid {
            return Err(UsageError(
                "--beta-min must lie in [0, 1] and --tau-max above 0".into(),
            ));
        }
        Ok(())
    }
}
