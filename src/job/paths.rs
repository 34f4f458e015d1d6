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
        // By identity too: a bind mount (or another mount) of the input root is the same
        // folder under a path that no spelling rule relates to it.
        let same_folder = matches!(
            (crate::io::file_id(&r), crate::io::file_id(&out)),
            (Some(a), Some(b)) if a == b
        );
        if r == out || same_folder {
            return Err(format!(
                "the output root {} is the input root {} (the same folder): outputs would overwrite the inputs; choose another [output] root",
                output_root.display(),
                root.display()
            ));
        }
        let holds = crate::io::file_id(&out).is_some_and(|id| identities_up(&r).contains(&id));
        if r.starts_with(&out) || holds {
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

/// The identities (device, inode) of an existing path and of every folder above it, nearest
/// first; empty for a path that does not exist.
fn identities_up(path: &Path) -> Vec<(u64, u64)> {
    let mut out = Vec::new();
    let mut at = Some(path);
    while let Some(p) = at {
        if let Some(id) = crate::io::file_id(p) {
            out.push(id);
        }
        at = p.parent();
    }
    out
}

/// Checks an output root against the case folders: it must not be one, nor lie inside one
/// (compared by identity, so symlinks and bind mounts count), since its outputs would become
/// that case's inputs and its marker would hide the case from every later run. `cases` are the
/// case folders discovery found; `holds_inputs` says whether a folder directly holds files the
/// configuration takes as inputs (for an output root that is a case folder of no root, as
/// `run-case --out` may be given).
pub fn check_output_outside_cases(
    output_root: &Path,
    cases: &[&Path],
    holds_inputs: impl Fn(&Path) -> bool,
) -> Result<(), String> {
    let out = canonical(output_root);
    let up = identities_up(&out);
    for case in cases {
        let Some(id) = crate::io::file_id(case) else {
            continue;
        };
        if let Some(at) = up.iter().position(|u| *u == id) {
            return Err(format!(
                "the output root {} {} the case folder {}: its outputs would be written among that case's inputs; choose an output folder outside every case",
                output_root.display(),
                if at == 0 { "is" } else { "lies inside" },
                case.display()
            ));
        }
    }
    if out.is_dir() && !is_output_root(&out) && holds_inputs(&out) {
        return Err(format!(
            "the output root {} holds input files (meshes or label maps the configuration selects) and is not a destair output folder: choose an empty or new folder",
            output_root.display()
        ));
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
