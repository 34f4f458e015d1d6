//! `destair demo`: a small phantom cohort and config/demo.toml run on it.

use super::{clock, load_plan};
use destair::job::{LockMode, LockScope, OutputLock, Wait};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Folder for the demo (cases/, demo.toml, out/).
    #[arg(default_value = "destair-demo")]
    dir: PathBuf,
    /// Number of mesh cases (one label-map case is added).
    #[arg(long, default_value_t = 6)]
    cases: usize,
}

pub fn exec(args: Args) -> anyhow::Result<()> {
    let cases_dir = args.dir.join("cases");
    for i in 0..args.cases {
        let case = destair::phantom::cohort_case(i, 0);
        destair::phantom::write_case(&case, &cases_dir.join(&case.info.name))?;
    }
    // One case arrives as a segmentation instead: an oblique NIfTI label map.
    let options = destair::phantom::PhantomOptions {
        rotate_x_deg: 20.0,
        ..Default::default()
    };
    destair::phantom::cases::write_label_map_case(
        "labelmap-neck",
        &options,
        &cases_dir.join("case-labelmap"),
    )?;
    let config = args.dir.join("demo.toml");
    destair::io::write_atomically(&config, |w| {
        w.write_all(include_str!("../../config/demo.toml").as_bytes())
    })?;
    eprintln!(
        "[{}] demo cohort of {} mesh cases and 1 label-map case in {}; running {}",
        clock(),
        args.cases,
        cases_dir.display(),
        config.display()
    );
    let plan = load_plan(&config)?;
    let found = super::run::discover_all(&plan, &config)?;
    let notes = destair::job::summary::CohortNotes::of(&found);
    let cases = found.cases;
    let signals = super::run::Signals::install()?;
    let lock = std::sync::Arc::new(OutputLock::open(&plan.output_root)?);
    lock.lock(&LockScope::Root, LockMode::Exclusive, Wait::No)?;
    let options = destair::job::pipeline::RunOptions {
        force: false,
        protected: destair::job::discover::protected_inputs(&cases, &plan.roots),
    };
    super::run::run_cases(&plan, cases, &options, Some(&notes), &lock, &signals)?;
    println!("outputs and reports: {}", plan.output_root.display());
    Ok(())
}
