//! `destair check`: validate a configuration and show the effective settings; touches nothing.

use super::{load_plan, UsageError};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    config: PathBuf,
}

pub fn exec(args: Args) -> anyhow::Result<()> {
    let plan = load_plan(&args.config)?;
    destair::job::paths::check_output_root(&plan.output_root, &plan.roots).map_err(UsageError)?;
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
        args.config.display(),
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
    Ok(())
}
