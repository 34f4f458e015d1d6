//! Paths compared by what they are, not how they are spelled: `cases/../cases`, `./cases/` and
//! a symlink to `cases` are one folder. Used to refuse output roots that would write over the
//! inputs, and to name files in reports relative to the config.

use super::lock::is_output_root;
use std::path::{Component, Path, PathBuf};

/// The canonical form of a path that may not exist yet: the longest existing prefix resolved
/// (symlinks, `..`), the rest appended with `.` and `..` applied lexically.
pub fn canonical(path: &Path) -> PathBuf {
    let absolute = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir().unwrap_or_default().join(path)
    };
    let mut existing = absolute.as_path();
    let mut tail: Vec<&std::ffi::OsStr> = Vec::new();
    loop {
        if let Ok(c) = existing.canonicalize() {
            let mut out = c;
            for part in tail.iter().rev() {
                match Path::new(part).components().next() {
                    Some(Component::ParentDir) => {
                        out.pop();
                    }
                    Some(Component::CurDir) | None => {}
                    _ => out.push(part),
                }
            }
            return out;
        }
        match (existing.parent(), existing.file_name()) {
            (Some(parent), Some(name)) => {
                tail.push(name);
                existing = parent;
            }
            // `..` or `.` as the last component of a missing path: keep it for the lexical pass.
            (Some(parent), None) => {
                tail.push(
                    existing
                        .components()
                        .next_back()
                        .map_or(std::ffi::OsStr::new("."), |c| c.as_os_str()),
                );
                existing = parent;
            }
            (None, _) => return absolute,
        }
    }
}

/// `path` relative to `base` (both made canonical), with `..` where it lies outside; `path`
/// itself when they share nothing (another drive).
pub fn relative_to(base: &Path, path: &Path) -> PathBuf {
    let (b, p) = (canonical(base), canonical(path));
    let common = b
        .components()
        .zip(p.components())
        .take_while(|(x, y)| x == y)
        .count();
    if common == 0 {
        return p;
    }
    let mut out = PathBuf::new();
    for _ in b.components().skip(common) {
        out.push("..");
    }
    for c in p.components().skip(common) {
        out.push(c);
    }
    if out.as_os_str().is_empty() {
        out.push(".");
    }
    out
}

/// Checks an output root against the input roots: it must not be a file, must not be an input
/// root or hold one (its marker would hide the cases), and no input root may be an earlier
/// run's output root.
pub fn check_output_root(output_root: &Path, roots: &[PathBuf]) -> Result<(), String> {
    if output_root.exists() && !output_root.is_dir() {
        return Err(format!(
            "{}: the output root exists and is not a folder",
            output_root.display()
        ));
    }
    let out = canonical(output_root);
    for root in roots {
        let r = canonical(root);
        if r == out {
            return Err(format!(
                "the output root {} is the input root {} (the same folder): outputs would overwrite the inputs; choose another [output] root",
                output_root.display(),
                root.display()
            ));
        }
        if r.starts_with(&out) {
            return Err(format!(
                "the output root {} holds the input root {}: choose an output folder that does not contain the inputs",
                output_root.display(),
                root.display()
            ));
        }
        if is_output_root(&r) {
            return Err(format!(
                "the input root {} is a destair output folder; its files are outputs, not cases",
                root.display()
            ));
        }
    }
    Ok(())
}

/// Refuses an output folder for one case that is the case's own input folder.
pub fn check_case_output(case_out: &Path, case_dir: &Path) -> Result<(), String> {
    if canonical(case_out) == canonical(case_dir) {
        return Err(format!(
            "the outputs of {} would go into that same folder ({}): choose an output root elsewhere",
            case_dir.display(),
            case_out.display()
        ));
    }
    Ok(())
}
