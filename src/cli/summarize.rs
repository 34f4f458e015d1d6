//! `destair summarize`: the cohort summary rebuilt from the case reports of output folders.

use super::{load_plan, CasesFailed};
use destair::job::{LockMode, LockScope, OutputLock, Wait};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Output folders to read (default: the configuration's output root).
    out_dirs: Vec<PathBuf>,
    /// The configuration, to report cases that have no report yet (and to find the output).
    #[arg(long)]
    config: Option<PathBuf>,
}

pub fn exec(args: Args) -> anyhow::Result<()> {
    let mut out_dirs = args.out_dirs;
    let (expected, notes, html) = match &args.config {
        Some(c) => {
            let plan = load_plan(c)?;
            if out_dirs.is_empty() {
                out_dirs.push(plan.output_root.clone());
            }
            let found = destair::job::discover(&plan);
            let notes = destair::job::summary::CohortNotes::of(&found);
            let ids: Vec<String> = found.cases.into_iter().map(|c| c.id).collect();
            (Some(ids), notes, plan.html)
        }
        None if out_dirs.is_empty() => {
            return Err(super::UsageError(
                "give the output folders to summarize, or --config COHORT.toml".into(),
            )
            .into())
        }
        None => {
            eprintln!(
                "warning: without --config, summarize cannot know which cases are missing; it summarizes the reports it finds"
            );
            (None, Default::default(), true)
        }
    };
    // The summary is written into the first folder; no run may be writing there meanwhile.
    let lock = OutputLock::open(&out_dirs[0])?;
    lock.lock(&LockScope::Root, LockMode::Exclusive, Wait::No)?;
    let (reports, problems) = destair::job::summary::collect_reports(&out_dirs);
    for p in &problems {
        eprintln!("warning: {p}");
    }
    if let Some(known) = &expected {
        let mut orphans = Vec::new();
        for dir in &out_dirs {
            orphans.extend(
                destair::job::outputs::orphan_case_dirs(dir, known)
                    .into_iter()
                    .map(|(id, _)| id),
            );
        }
        if !orphans.is_empty() {
            eprintln!(
                "warning: output folders of cases no longer in the cohort (left out of the summary; `destair run CONFIG --prune` removes them): {}",
                orphans.join(", ")
            );
        }
    }
    let mut summary = destair::job::summary::summarize(reports, expected.as_deref());
    notes.apply(&mut summary);
    destair::job::summary::write_summary(&out_dirs[0], &summary)?;
    destair::job::index_page::write_index_page(&out_dirs[0], &summary, html)?;
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
        ("not in the cohort", &summary.not_in_cohort),
        ("skipped folders", &summary.skipped_folders),
        (
            "structures with several files",
            &summary.duplicate_structures,
        ),
    ] {
        if !list.is_empty() {
            println!("{what}: {}", list.join(", "));
        }
    }
    let n_failed = summary.failed.len();
    if !(summary.missing.is_empty() && summary.duplicates.is_empty()) {
        return Err(CasesFailed(format!(
            "the cohort is not complete: {} missing, {} duplicated{}",
            summary.missing.len(),
            summary.duplicates.len(),
            if n_failed > 0 {
                format!(", {n_failed} failed")
            } else {
                String::new()
            }
        ))
        .into());
    }
    if n_failed > 0 {
        let complete = if expected.is_some() {
            "complete"
        } else {
            "summarized (completeness unknown without --config)"
        };
        return Err(CasesFailed(format!(
            "the cohort is {complete}, {n_failed} {} failed",
            if n_failed == 1 { "case" } else { "cases" }
        ))
        .into());
    }
    Ok(())
}
