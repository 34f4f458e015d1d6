//! `destair run` and `destair run-case`: cases through the pipeline, with the output folder
//! locked, inputs protected, progress on stderr, signals and the exit policy.

use super::{clock, load_plan, CasesFailed, Interrupted, UsageError};
use destair::job::discover::protected_inputs;
use destair::job::outputs::{orphan_case_dirs, prune_case_dir};
use destair::job::paths::{check_output_outside_cases, check_output_root};
use destair::job::pipeline::{Event, RunOptions};
use destair::job::summary::CohortNotes;
use destair::job::{CaseInput, Discovery, LockMode, LockScope, OutputLock, Plan, Shard, Wait};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

#[derive(clap::Args)]
pub struct Args {
    config: PathBuf,
    /// Process a share of the cases: I/N (0 <= I < N), or `slurm` for the array task's share.
    #[arg(long)]
    shard: Option<String>,
    /// Redo cases that are already done with the same inputs and settings.
    #[arg(long)]
    force: bool,
    /// Remove the output folders of cases that are no longer in the cohort.
    #[arg(long)]
    prune: bool,
    /// Wait for another run that holds the output folder instead of exiting.
    #[arg(long)]
    wait: bool,
}

/// `run-case`: one case folder (for Snakemake, Nextflow and other workflow engines).
#[derive(clap::Args)]
pub struct CaseArgs {
    case_dir: PathBuf,
    #[arg(long)]
    config: PathBuf,
    /// Output root; the case's outputs go to OUT/<case folder name>/.
    #[arg(long)]
    out: PathBuf,
    #[arg(long)]
    force: bool,
    /// Wait for another run that holds the case instead of exiting.
    #[arg(long)]
    wait: bool,
}

/// SIGTERM and SIGINT flags, and `stop`, which either sets.
pub struct Signals {
    term: Arc<AtomicBool>,
    int: Arc<AtomicBool>,
    pub stop: Arc<AtomicBool>,
}

impl Signals {
    pub fn install() -> anyhow::Result<Signals> {
        let s = Signals {
            term: Arc::new(AtomicBool::new(false)),
            int: Arc::new(AtomicBool::new(false)),
            stop: Arc::new(AtomicBool::new(false)),
        };
        use signal_hook::consts::{SIGINT, SIGTERM};
        signal_hook::flag::register(SIGTERM, s.term.clone())?;
        signal_hook::flag::register(SIGINT, s.int.clone())?;
        signal_hook::flag::register(SIGTERM, s.stop.clone())?;
        signal_hook::flag::register(SIGINT, s.stop.clone())?;
        Ok(s)
    }

    /// The error for a stop by signal, if one came.
    fn interrupted(&self) -> Option<Interrupted> {
        if self.term.load(Ordering::Relaxed) {
            Some(Interrupted(15))
        } else if self.int.load(Ordering::Relaxed) {
            Some(Interrupted(2))
        } else {
            None
        }
    }
}

fn shard_of(arg: &Option<String>) -> anyhow::Result<Option<Shard>> {
    match arg.as_deref() {
        None => Ok(None),
        Some("slurm") => Shard::from_slurm(|k| std::env::var(k).ok())
            .map(Some)
            .map_err(|e| UsageError(e).into()),
        Some(s) => Shard::parse(s).map(Some).map_err(|e| UsageError(e).into()),
    }
}

/// Discovers and reviews the plan's cases: discovery warnings, skipped folders and review
/// warnings go to stderr; review errors (no cases, a missing root, a reference no case has)
/// are a usage error.
pub fn discover_all(plan: &Plan, config: &std::path::Path) -> anyhow::Result<Discovery> {
    let found = destair::job::discover(plan);
    for w in &found.warnings {
        eprintln!("warning: {w}");
    }
    for s in &found.skipped_folders {
        eprintln!("warning: skipped folder {s}");
    }
    let review = destair::job::review::review(plan, &found);
    for w in &review.warnings {
        eprintln!("warning: {w}");
    }
    if !review.errors.is_empty() {
        return Err(UsageError(format!(
            "{}: {}",
            config.display(),
            review.errors.join("\n  ")
        ))
        .into());
    }
    Ok(found)
}

/// Opens and locks an output root for a run; a busy folder is a usage error naming the holder.
fn lock_output(
    root: &std::path::Path,
    scopes: &[(LockScope, LockMode)],
    wait: bool,
    signals: &Signals,
) -> anyhow::Result<Arc<OutputLock>> {
    let lock = OutputLock::open(root)?;
    let wait = if wait {
        Wait::Until(&signals.stop)
    } else {
        Wait::No
    };
    for (scope, mode) in scopes {
        if let Err(e) = lock.lock(scope, *mode, wait) {
            if let Some(i) = signals.interrupted() {
                return Err(i.into());
            }
            return Err(e.into());
        }
    }
    Ok(Arc::new(lock))
}

pub fn exec(args: Args) -> anyhow::Result<()> {
    let plan = load_plan(&args.config)?;
    check_output_root(&plan.output_root, &plan.roots).map_err(UsageError)?;
    let shard = shard_of(&args.shard)?;
    if args.prune && shard.is_some() {
        return Err(UsageError(
            "--prune looks at the whole cohort; run it without --shard (or after the shards, alone)"
                .into(),
        )
        .into());
    }
    let signals = Signals::install()?;
    let found = discover_all(&plan, &args.config)?;
    let case_dirs: Vec<&std::path::Path> = found.cases.iter().map(|c| c.dir.as_path()).collect();
    check_output_outside_cases(&plan.output_root, &case_dirs, |d| holds_inputs(&plan, d))
        .map_err(UsageError)?;
    let notes = CohortNotes::of(&found);
    let all = found.cases;
    let protected = protected_inputs(&all, &plan.roots);
    let ids: Vec<String> = all.iter().map(|c| c.id.clone()).collect();
    let cases: Vec<CaseInput> = all
        .into_iter()
        .filter(|c| shard.is_none_or(|s| s.contains(&c.id)))
        .collect();
    let scopes = match shard {
        None => vec![(LockScope::Root, LockMode::Exclusive)],
        Some(s) => vec![
            (LockScope::Root, LockMode::Shared),
            (
                LockScope::Shard {
                    index: s.index,
                    count: s.count,
                },
                LockMode::Exclusive,
            ),
        ],
    };
    let lock = lock_output(&plan.output_root, &scopes, args.wait, &signals)?;
    if shard.is_none() {
        let orphans = orphan_case_dirs(&plan.output_root, &ids);
        if args.prune {
            for (id, dir) in &orphans {
                let left = prune_case_dir(dir, &plan.output_root, &protected)
                    .map_err(|e| anyhow::anyhow!("{}: cannot prune: {e}", dir.display()))?;
                if left.is_empty() {
                    eprintln!("pruned {id} (no longer in the cohort)");
                } else {
                    eprintln!(
                        "pruned destair's files of {id}; kept files it did not write: {}",
                        left.join(", ")
                    );
                }
            }
        } else if !orphans.is_empty() {
            let names: Vec<&str> = orphans.iter().map(|(id, _)| id.as_str()).collect();
            eprintln!(
                "warning: {} output folder{} of cases no longer in the cohort: {}; `destair run {} --prune` removes them",
                names.len(),
                if names.len() == 1 { "" } else { "s" },
                names.join(", "),
                args.config.display()
            );
        }
    }
    if let Some(s) = shard {
        eprintln!(
            "shard {}/{}: {} of {} cases; when all shards are done: destair summarize {} --config {}",
            s.index,
            s.count,
            cases.len(),
            ids.len(),
            plan.output_root.display(),
            args.config.display()
        );
    }
    let options = RunOptions {
        force: args.force,
        protected,
    };
    let summary = shard.is_none().then_some(&notes);
    run_cases(&plan, cases, &options, summary, &lock, &signals)
}

pub fn exec_case(args: CaseArgs) -> anyhow::Result<()> {
    let mut plan = load_plan(&args.config)?;
    plan.output_root = args.out.clone();
    let dir = args
        .case_dir
        .canonicalize()
        .map_err(|e| UsageError(format!("{}: {e}", args.case_dir.display())))?;
    if !dir.is_dir() {
        return Err(UsageError(format!("{}: not a folder", args.case_dir.display())).into());
    }
    let mut roots = plan.roots.clone();
    roots.push(dir.clone());
    check_output_root(&args.out, &roots).map_err(UsageError)?;
    // The output root must not be (or lie in) this case, nor a case folder of the config's
    // roots (the folders between a root and the output root are looked at), nor hold inputs.
    let out = destair::job::paths::canonical(&args.out);
    let mut case_dirs: Vec<std::path::PathBuf> = vec![dir.clone()];
    for root in &plan.roots {
        let root = destair::job::paths::canonical(root);
        let mut at = out.as_path();
        while at.starts_with(&root) && at != root {
            if holds_inputs(&plan, at) && !destair::job::lock::is_output_root(at) {
                case_dirs.push(at.to_path_buf());
            }
            match at.parent() {
                Some(p) => at = p,
                None => break,
            }
        }
    }
    let case_refs: Vec<&std::path::Path> = case_dirs.iter().map(|d| d.as_path()).collect();
    check_output_outside_cases(&args.out, &case_refs, |d| holds_inputs(&plan, d))
        .map_err(UsageError)?;
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    destair::job::paths::check_case_output(&args.out.join(&name), &dir).map_err(UsageError)?;
    let mut warnings = Vec::new();
    let case = destair::job::discover::case_at(&plan, &dir, name.clone(), &mut warnings)
        .ok_or_else(|| {
            UsageError(format!(
                "{}: no meshes or label maps in this folder",
                args.case_dir.display()
            ))
        })?;
    for w in warnings {
        eprintln!("warning: {w}");
    }
    let signals = Signals::install()?;
    let scopes = [
        (LockScope::Root, LockMode::Shared),
        (LockScope::Case(name), LockMode::Exclusive),
    ];
    let lock = lock_output(&args.out, &scopes, args.wait, &signals)?;
    let options = RunOptions {
        force: args.force,
        protected: protected_inputs([&case], std::slice::from_ref(&dir)),
    };
    run_cases(&plan, vec![case], &options, None, &lock, &signals)
}

/// Whether a folder directly holds files the plan takes as inputs (meshes or label maps).
fn holds_inputs(plan: &Plan, dir: &std::path::Path) -> bool {
    destair::job::discover::case_at(plan, dir, String::new(), &mut Vec::new())
        .is_some_and(|c| !c.meshes.is_empty() || !c.label_maps.is_empty())
}

fn plural(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// "no failures", "3 structures failed in 2 cases", or "2 cases failed" (cases that failed as a
/// whole or in an earlier run).
fn failures(cases: usize, structures: usize) -> String {
    match (cases, structures) {
        (0, _) => "no failures".into(),
        (c, 0) => format!("{} failed", plural(c, "case", "cases")),
        (c, s) => format!(
            "{} failed in {}",
            plural(s, "structure", "structures"),
            plural(c, "case", "cases")
        ),
    }
}

/// Runs cases through the pipeline with progress lines, signal handling and the exit policy.
pub fn run_cases(
    plan: &Plan,
    cases: Vec<CaseInput>,
    options: &RunOptions,
    summary_notes: Option<&CohortNotes>,
    lock: &Arc<OutputLock>,
    signals: &Signals,
) -> anyhow::Result<()> {
    let total = cases.len();
    let ids: Vec<String> = cases.iter().map(|c| c.id.clone()).collect();
    let started = std::time::Instant::now();
    let mut last_log = std::time::Instant::now();
    let (mut done, mut failed, mut skipped, mut n_structures) = (0usize, 0usize, 0usize, 0usize);
    let mut failed_structures = 0usize;
    let mut disk_full_told = false;
    eprintln!(
        "[{}] destair: {}, {} worker{}, {} threads, memory budget {} MB ({})",
        clock(),
        plural(total, "case", "cases"),
        plan.workers,
        if plan.workers == 1 { "" } else { "s" },
        rayon::current_num_threads(),
        plan.memory_budget_bytes.div_ceil(1 << 20),
        plan.memory_budget_source
    );
    // A live bar on a terminal; off a terminal (cluster logs) indicatif draws nothing, so
    // plain timestamped lines every few seconds instead.
    let bar = std::io::IsTerminal::is_terminal(&std::io::stderr()).then(|| {
        let bar = indicatif::ProgressBar::new(total as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{elapsed_precise} [{bar:30}] {pos}/{len} cases {msg} (ETA {eta})",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let say = |line: String| match &bar {
        Some(b) => b.println(line),
        None => eprintln!("{line}"),
    };
    let mut on_event = |e: Event| {
        match e {
            Event::CaseDone {
                id,
                failed: f,
                skipped: s,
                structures,
                failed_structures: n_failed,
                errors,
            } => {
                done += 1;
                n_structures += structures;
                failed += f as usize;
                skipped += s as usize;
                failed_structures += n_failed;
                if f && !s {
                    say(format!("[{}] case {id} failed:", clock()));
                    for e in errors {
                        say(format!("    {e}"));
                    }
                } else if f {
                    say(format!(
                        "[{}] case {id}: failed in an earlier run with the same inputs and settings (see its report.json)",
                        clock()
                    ));
                }
            }
            Event::WriteFailed {
                id,
                error,
                disk_full,
            } => {
                done += 1;
                failed += 1;
                if disk_full && disk_full_told {
                    // Said once; the count at the end says how many more it hit.
                } else if disk_full {
                    disk_full_told = true;
                    say(format!(
                        "[{}] error: the output device is full: {error}\n    case {id} and every further case that cannot be written fail; free space and rerun to redo them",
                        clock()
                    ));
                } else {
                    say(format!(
                        "[{}] case {id}: cannot write its outputs: {error}",
                        clock()
                    ));
                }
            }
        }
        if let Some(b) = &bar {
            b.set_position(done as u64);
            b.set_message(format!(
                "({skipped} already done), {}, {}",
                plural(n_structures, "structure", "structures"),
                failures(failed, failed_structures)
            ));
            return;
        }
        if last_log.elapsed().as_secs_f64() >= 5.0 || done == total {
            let per_min = 60.0 * done as f64 / started.elapsed().as_secs_f64().max(1e-9);
            let eta = (total - done) as f64 * 60.0 / per_min.max(1e-9);
            eprintln!(
                "[{}] {done}/{total} cases done ({skipped} already done), {}, {}, {:.0} cases/min, ETA {:.0} s",
                clock(),
                plural(n_structures, "structure", "structures"),
                failures(failed, failed_structures),
                per_min,
                eta
            );
            last_log = std::time::Instant::now();
        }
    };
    let result =
        destair::job::pipeline::run(plan, cases, options, lock, &signals.stop, &mut on_event)?;
    if let Some(b) = &bar {
        b.finish();
    }
    if let Some(stop) = signals.interrupted() {
        let name = if stop.0 == 15 { "SIGTERM" } else { "SIGINT" };
        eprintln!(
            "[{}] stopped by {name}: {} not started, {} abandoned unwritten; rerun to continue",
            clock(),
            plural(result.not_started, "case", "cases"),
            plural(result.unfinished, "case", "cases"),
        );
        return Err(stop.into());
    }
    if let Some(notes) = summary_notes {
        let reports: Vec<_> = ids
            .iter()
            .filter_map(|id| {
                let path = destair::job::outputs::case_dir(plan, id).join("report.json");
                destair::job::summary::read_case_rows(&path).ok()
            })
            .collect();
        let mut summary = destair::job::summary::summarize(reports, Some(&ids));
        notes.apply(&mut summary);
        let root = &plan.output_root;
        let written = destair::job::summary::write_summary(root, &summary)
            .and_then(|()| destair::job::index_page::write_index_page(root, &summary, plan.html));
        if let Err(e) = written {
            return Err(CasesFailed(format!(
                "cannot write the cohort summary in {}: {e}",
                plan.output_root.display()
            ))
            .into());
        }
        eprintln!(
            "[{}] summary: {}",
            clock(),
            plan.output_root.join("summary.csv").display()
        );
    }
    if !result.failed.is_empty() {
        return Err(CasesFailed(format!(
            "{} of {total} failed: {}",
            plural(result.failed.len(), "case", "cases"),
            result.failed.join(", ")
        ))
        .into());
    }
    Ok(())
}
