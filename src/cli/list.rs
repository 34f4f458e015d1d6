//! `destair list`: the cases a configuration finds, as TSV or JSON lines, for workflow engines.

use super::load_plan;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    config: PathBuf,
    /// One JSON object per line instead of TSV.
    #[arg(long)]
    jsonl: bool,
    /// Only the cases of shard I/N.
    #[arg(long)]
    shard: Option<String>,
}

/// A TSV field: backslash, tab, newline and carriage return escaped as `\\`, `\t`, `\n`, `\r`
/// (the "linear TSV" convention), so every case is one line of exactly three fields.
pub fn tsv_field(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '\t' => out.push_str("\\t"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            c => out.push(c),
        }
    }
    out
}

pub fn exec(args: Args) -> anyhow::Result<()> {
    let plan = load_plan(&args.config)?;
    let shard = match args.shard.as_deref() {
        None => None,
        Some("slurm") => Some(
            destair::job::Shard::from_slurm(|k| std::env::var(k).ok())
                .map_err(super::UsageError)?,
        ),
        Some(s) => Some(destair::job::Shard::parse(s).map_err(super::UsageError)?),
    };
    let found = super::run::discover_all(&plan, &args.config)?;
    for c in found
        .cases
        .iter()
        .filter(|c| shard.is_none_or(|s| s.contains(&c.id)))
    {
        let structures: Vec<&str> = c.meshes.iter().map(|(n, _)| n.as_str()).collect();
        let label_maps: Vec<String> = c
            .label_maps
            .iter()
            .map(|p| {
                p.file_name()
                    .map_or_else(String::new, |f| f.to_string_lossy().into_owned())
            })
            .collect();
        if args.jsonl {
            println!(
                "{}",
                serde_json::json!({ "case": c.id, "dir": c.dir, "structures": structures, "label_maps": label_maps })
            );
        } else {
            // Structure names are joined by commas; a comma inside a name is escaped as `\,`.
            let joined = structures
                .iter()
                .map(|s| tsv_field(s).replace(',', "\\,"))
                .collect::<Vec<_>>()
                .join(",");
            println!(
                "{}\t{}\t{}",
                tsv_field(&c.id),
                tsv_field(&c.dir.to_string_lossy()),
                joined
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::tsv_field;

    #[test]
    fn tsv_fields_never_split_a_line_or_a_column() {
        assert_eq!(tsv_field("a\tb\nc\\d\re"), "a\\tb\\nc\\\\d\\re");
        assert!(!tsv_field("x\ty\nz").contains(['\t', '\n']));
    }
}
