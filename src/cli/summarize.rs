//! `destair summarize`: the cohort summary rebuilt from the case reports of output folders.

use super::{load_plan, CasesFailed};
use destair::job::{LockMode, LockScope, OutputLock, Wait};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    #[arg(required = true)]
    out_dirs: Vec<PathBuf>,
    /// The configuration, to report cases that have no report yet.
    #[arg(long)]
    config: Option<PathBuf>,
}

pub fn exec(args: Args) -> anyhow::Result<()> {
    let expected = match &args.config {
        Some(c) => Some(
            destair::job::discover(&load_plan(c)?)
                .cases
                .into_iter()
                .map(|c| c.id)
                .collect::<Vec<_>>(),
        ),
        None => None,
    };
    // The summary is written into the first folder; no run may be writing there meanwhile.
    let lock = OutputLock::open(&args.out_dirs[0])?;
    lock.lock(&LockScope::Root, LockMode::Exclusive, Wait::No)?;
    let (reports, problems) = destair::job::summary::collect_reports(&args.out_dirs);
    for p in &problems {
        eprintln!("warning: {p}");
    }
    if let Some(known) = &expected {
        let mut orphans = Vec::new();
        for dir in &args.out_dirs {
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
    let summary = destair::job::summary::summarize(reports, expected.as_deref());
    destair::job::summary::write_summary(&args.out_dirs[0], &summary)?;
    println!(
        "{} cases: {} ok, {} failed, {} missing, {} duplicated -> {}",
        summary.n_cases,
        summary.n_ok,
        summary.failed.len(),
        summary.missing.len(),
        summary.duplicates.len(),
        args.out_dirs[0].join("summary.csv").display()
    );
    for (what, list) in [
        ("failed", &summary.failed),
        ("missing", &summary.missing),
        ("duplicated", &summary.duplicates),
        ("not in the cohort", &summary.not_in_cohort),
    ] {
        if !list.is_empty() {
            println!("{what}: {}", list.join(", "));
        }
    }
    if !(summary.failed.is_empty() && summary.missing.is_empty() && summary.duplicates.is_empty()) {
        return Err(CasesFailed("the cohort is not complete".into()).into());
    }
    Ok(())
}
