//! The `destair` command line, as a table of contents: parse, run one command from `cli/`,
//! map the outcome to an exit code.
//!
//! Exit codes: 0 success; 2 usage or configuration error; 3 bad input data or failed cases;
//! 1 internal error; 128 + n stopped by signal n. Never 128+n for data errors, since workflow
//! engines retry those.

mod cli;

use clap::{Parser, Subcommand};
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
    Inspect(cli::inspect::Args),
    /// Smooth one mesh with one of the papers' smoothers.
    Smooth(cli::smooth::Args),
    /// Compare a smoothed mesh with its original: distances, volume, curvature, displacement.
    Compare(cli::compare::Args),
    /// Process a whole cohort described by a configuration file.
    Run(cli::run::Args),
    /// Process exactly one case folder (for Snakemake, Nextflow and other workflow engines).
    RunCase(cli::run::CaseArgs),
    /// Validate a configuration and print the effective settings per structure; touches nothing.
    Check(cli::check::Args),
    /// Print the cases a configuration finds (TSV, or JSON lines), e.g. for workflow engines.
    List(cli::list::Args),
    /// Rebuild the cohort summary from the case reports under one or more output folders.
    Summarize(cli::summarize::Args),
    /// Extract one surface per label of a label map (touching structures share their interface).
    Extract(cli::extract::Args),
    /// Generate a small phantom cohort and run config/demo.toml on it.
    Demo(cli::demo::Args),
    /// Generate phantom cases: marching-cubes meshes of analytic shapes with real staircases.
    Phantom(cli::phantom::Args),
    /// Measure destair's throughput on generated meshes.
    Bench {
        #[command(subcommand)]
        what: cli::bench::Args,
    },
}

fn main() -> ExitCode {
    // Like other Unix tools, end quietly when the reader of our output goes away
    // (`destair list ... | head`) instead of failing on every print.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE at startup, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    // glibc keeps freed large blocks in per-thread arenas (its mmap threshold grows with use), so
    // a case processed on one worker stays resident while the next grows on another, and a run
    // would use up to twice what the memory budget allows. Fixing the threshold at glibc's own
    // starting value (128 KiB) hands every larger block back to the system when it is freed.
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets an allocator parameter; called before any thread exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 128 << 10);
    }
    let args = Cli::parse();
    if let Err(e) = cli::configure_threads(args.threads) {
        eprintln!("error: {e}");
        return ExitCode::from(2);
    }
    let outcome = match args.command {
        Command::Inspect(a) => cli::inspect::exec(a),
        Command::Smooth(a) => cli::smooth::exec(a),
        Command::Compare(a) => cli::compare::exec(a),
        Command::Run(a) => cli::run::exec(a),
        Command::RunCase(a) => cli::run::exec_case(a),
        Command::Check(a) => cli::check::exec(a),
        Command::List(a) => cli::list::exec(a),
        Command::Summarize(a) => cli::summarize::exec(a),
        Command::Demo(a) => cli::demo::exec(a),
        Command::Extract(a) => cli::extract::exec(a),
        Command::Phantom(a) => cli::phantom::exec(a),
        Command::Bench { what } => cli::bench::exec(what),
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", cli::message(&e));
            ExitCode::from(cli::exit_code(&e))
        }
    }
}
