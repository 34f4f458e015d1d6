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
    let review = destair::job::review::review(&plan, &found);
    for w in found.warnings.iter().chain(&review.warnings) {
        println!("warning: {w}");
    }
    for s in &found.skipped_folders {
        println!("warning: skipped folder {s}");
    }
    if !review.errors.is_empty() {
        return Err(UsageError(format!(
            "{}: {}",
            args.config.display(),
            review.errors.join("\n  ")
        ))
        .into());
    }
    let mut names: std::collections::BTreeSet<&str> = found
        .cases
        .iter()
        .flat_map(|c| c.meshes.iter().map(|(n, _)| n.as_str()))
        .collect();
    let n_label_maps: usize = found.cases.iter().map(|c| c.label_maps.len()).sum();
    let label_names = &review.label_names;
    names.extend(label_names.iter().map(String::as_str));
    println!(
        "{}: valid; {} cases, {} structure names{}; output to {}",
        args.config.display(),
        found.cases.len(),
        names.len(),
        if n_label_maps > 0 {
            format!(
                " (from mesh files, [labels] and the segment names of label map headers; {n_label_maps} label maps name the rest of their structures when read)"
            )
        } else {
            String::new()
        },
        plan.output_root.display()
    );
    for n in names {
        let tables = plan.matching_tables(n);
        println!(
            "\n# {n}: [defaults]{}",
            tables
                .iter()
                .map(|t| format!(" + [[structure]] {t:?}"))
                .collect::<String>()
        );
        let settings = plan.settings_for(n);
        if label_names.contains(n) {
            println!("{}", label_note(&settings));
        }
        print!("{}", settings.config_view());
    }
    // Labels no name reaches before the maps are read (label_<value>, a NIfTI's labels).
    if n_label_maps > 0 {
        let settings = plan.default_settings();
        println!(
            "\n# the label maps' other labels (label_<value> or their files' names): [defaults]"
        );
        println!("{}", label_note(&settings));
        print!("{}", settings.config_view());
    }
    Ok(())
}

/// What a structure made from a label map gets with `settings`, as a comment.
fn label_note(settings: &destair::job::StructureSettings) -> String {
    use destair::extract::constrained::Surface;
    match (settings.extraction.surface, settings.method_configured) {
        (Surface::Constrained, false) => "# from a label map: the constrained surface is the result; no mesh smoother runs on it unless `method` is set for it, so the smoothing keys below are unused".into(),
        (Surface::Constrained, true) => "# from a label map: the constrained surface, then the mesh smoother below (from it)".into(),
        (Surface::Binary, _) => "# from a label map: the binary surface, then the mesh smoother below".into(),
    }
}
