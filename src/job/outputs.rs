//! A case's output folder: its manifest (the resume key and the list of outputs, written last),
//! writing a processed case into it without ever touching an input, removing outputs a rerun no
//! longer makes, and pruning folders of cases that left the cohort.

use super::case::CaseOutput;
use super::plan::Plan;
use crate::io::{remove_stale_temp_files, write_atomically, ProtectedFiles};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Files every case folder holds besides its meshes; written by destair, removed by a prune.
pub const CASE_FILES: [&str; 5] = [
    "report.json",
    "report.md",
    "report.html",
    "timings.json",
    "manifest.json",
];

/// `manifest.json` of a case: written last, so its presence means every output is complete.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Manifest {
    pub key: String,
    pub status: String,
    pub outputs: Vec<String>,
}

/// A case's outputs could not be written.
#[derive(Debug, Error)]
pub enum WriteCaseError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: is an input of this run; refusing to write there", path.display())]
    WouldOverwriteInput { path: PathBuf },
}

impl WriteCaseError {
    /// Whether the device is full (or the quota used up): every later write will fail too.
    pub fn is_disk_full(&self) -> bool {
        matches!(self, WriteCaseError::Io { source, .. }
            if matches!(source.raw_os_error(), Some(libc::ENOSPC) | Some(libc::EDQUOT)))
    }
}

/// Output folder of a case.
pub fn case_dir(plan: &Plan, id: &str) -> PathBuf {
    if id == "." {
        plan.output_root.clone()
    } else {
        plan.output_root.join(id)
    }
}

/// The manifest in a case folder, if there is a readable one.
pub fn read_manifest(dir: &Path) -> Option<Manifest> {
    let text = std::fs::read(dir.join("manifest.json")).ok()?;
    serde_json::from_slice(&text).ok()
}

/// Whether a case's outputs are complete and were made from the same inputs and settings.
pub fn is_done(dir: &Path, key: &str) -> bool {
    read_manifest(dir).is_some_and(|m| {
        m.key == key
            && dir.join("report.json").is_file()
            && m.outputs
                .iter()
                .all(|o| is_plain_name(o) && dir.join(o).is_file())
    })
}

/// A file name without folders, so a manifest can never point outside its case folder.
pub fn is_plain_name(name: &str) -> bool {
    !name.is_empty()
        && name != "."
        && name != ".."
        && !name.contains(['/', '\\', '\0'])
        && !CASE_FILES.contains(&name)
}

/// Writes one case's outputs, reports and (last) its manifest, each atomically, into its
/// folder; removes outputs the previous manifest listed that this run no longer makes.
/// Nothing is written onto a protected file or into a protected folder.
pub fn write_case_output(
    plan: &Plan,
    out: &CaseOutput,
    protected: &ProtectedFiles,
) -> Result<(), WriteCaseError> {
    let dir = case_dir(plan, &out.id);
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| WriteCaseError::Io { path, source }
    };
    std::fs::create_dir_all(&dir).map_err(io(&dir))?;
    if protected.contains(&dir) {
        return Err(WriteCaseError::WouldOverwriteInput { path: dir });
    }
    remove_stale_temp_files(&dir).map_err(io(&dir))?;
    let previous = read_manifest(&dir);
    let put = |name: &str, bytes: &[u8]| -> Result<(), WriteCaseError> {
        let path = dir.join(name);
        if protected.contains(&path) {
            return Err(WriteCaseError::WouldOverwriteInput { path });
        }
        write_atomically(&path, |w| w.write_all(bytes)).map_err(io(&path))
    };
    for (name, bytes) in &out.files {
        put(name, bytes)?;
    }
    let report = serde_json::to_vec_pretty(&out.report).map_err(|e| io(&dir)(e.into()))?;
    put("report.json", &report)?;
    let markdown = out.report.to_markdown();
    put("report.md", markdown.as_bytes())?;
    let html_path = dir.join("report.html");
    if plan.html {
        put(
            "report.html",
            crate::report::html::case::case_page(&out.report, &markdown).as_bytes(),
        )?;
    } else if html_path.is_file() && !protected.contains(&html_path) {
        // Turned off since the last run: a stale page would show old results.
        std::fs::remove_file(&html_path).map_err(io(&html_path))?;
    }
    let timings = serde_json::to_vec_pretty(&out.timings).map_err(|e| io(&dir)(e.into()))?;
    put("timings.json", &timings)?;
    let outputs: Vec<String> = out.files.iter().map(|(n, _)| n.clone()).collect();
    // Before the new manifest: if this is cut short, the old manifest no longer matches and a
    // rerun redoes the case (and this cleanup).
    if let Some(previous) = previous {
        for old in previous.outputs.iter().filter(|o| !outputs.contains(o)) {
            let path = dir.join(old);
            if is_plain_name(old) && !protected.contains(&path) && path.is_file() {
                std::fs::remove_file(&path).map_err(io(&path))?;
            }
        }
    }
    let manifest = Manifest {
        key: out.key.clone(),
        status: out.report.status.clone(),
        outputs,
    };
    let manifest = serde_json::to_vec_pretty(&manifest).map_err(|e| io(&dir)(e.into()))?;
    put("manifest.json", &manifest)
}

/// Case output folders under `output_root` (those holding a manifest) whose case id is not in
/// `known`: outputs of cases that left the cohort. Sorted by id.
pub fn orphan_case_dirs(output_root: &Path, known: &[String]) -> Vec<(String, PathBuf)> {
    let known: std::collections::HashSet<&str> = known.iter().map(String::as_str).collect();
    let mut out = Vec::new();
    for entry in walkdir::WalkDir::new(output_root)
        .min_depth(1)
        .sort_by_file_name()
        .into_iter()
        .flatten()
    {
        if !(entry.file_type().is_dir() && entry.path().join("manifest.json").is_file()) {
            continue;
        }
        let Ok(rel) = entry.path().strip_prefix(output_root) else {
            continue;
        };
        let id = rel
            .components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .collect::<Vec<_>>()
            .join("/");
        if !known.contains(id.as_str()) {
            out.push((id, entry.path().to_path_buf()));
        }
    }
    out
}

/// Removes what destair wrote in a case folder (its manifest first, then the outputs it lists,
/// the reports and temp files), then the folder and its parents up to `output_root` if empty.
/// Files destair did not write stay; their names are returned.
pub fn prune_case_dir(
    dir: &Path,
    output_root: &Path,
    protected: &ProtectedFiles,
) -> std::io::Result<Vec<String>> {
    let listed = read_manifest(dir).map(|m| m.outputs).unwrap_or_default();
    let remove = |name: &str| -> std::io::Result<()> {
        let path = dir.join(name);
        if path.is_file() && !protected.contains(&path) {
            std::fs::remove_file(&path)?;
        }
        Ok(())
    };
    remove("manifest.json")?;
    for name in listed.iter().filter(|n| is_plain_name(n)) {
        remove(name)?;
    }
    for name in CASE_FILES {
        remove(name)?;
    }
    remove_stale_temp_files(dir)?;
    let mut left: Vec<String> = std::fs::read_dir(dir)?
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    if left.is_empty() {
        let mut d = dir.to_path_buf();
        while d.starts_with(output_root) && d != output_root && std::fs::remove_dir(&d).is_ok() {
            if !d.pop() {
                break;
            }
        }
    }
    Ok(left)
}
