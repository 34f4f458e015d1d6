//! Finding the cases of a cohort: sorted and deterministic, following symlinks (workflow engines
//! stage inputs as links), with loops and unreadable folders reported rather than fatal.

use super::lock::is_output_root;
use super::plan::Plan;
use crate::io::ProtectedFiles;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// One case: a folder and its structure meshes.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct CaseInput {
    /// Path of the case folder relative to its root, with `/` separators (the root's own folder
    /// name when the root is itself a case).
    pub id: String,
    pub dir: PathBuf,
    /// (structure name = file stem, file), sorted by name.
    pub meshes: Vec<(String, PathBuf)>,
    /// Label maps, sorted by name: their labels become structures once read.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub label_maps: Vec<PathBuf>,
    /// Problems found while listing (duplicate structure names).
    pub problems: Vec<String>,
    /// Why the case cannot be processed (its folder cannot be read); such a case fails.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub errors: Vec<String>,
    /// Structures with more than one file, as "name (file, file)".
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub duplicates: Vec<String>,
}

/// The cases of a plan, and what could not be read while looking for them.
#[derive(Debug, Clone, Default)]
pub struct Discovery {
    pub cases: Vec<CaseInput>,
    pub warnings: Vec<String>,
    /// Folders that look like cases but hold no mesh (with case_depth: every folder at that
    /// depth; without: folders with files but no subfolders), with the reason.
    pub skipped_folders: Vec<String>,
}

/// What a folder directly holds.
struct Listing {
    meshes: Vec<PathBuf>,
    label_maps: Vec<PathBuf>,
    n_subfolders: usize,
    n_other_files: usize,
}

fn is_mesh(plan: &Plan, path: &Path) -> bool {
    if let Some(patterns) = &plan.patterns {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy())
            .unwrap_or_default();
        return patterns.iter().any(|p| p.matches(&name));
    }
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| plan.extensions.iter().any(|x| x.eq_ignore_ascii_case(e)))
}

/// Mesh files directly in `dir`, sorted by name, and what else is there; an unreadable folder
/// is an error.
fn case_meshes(plan: &Plan, dir: &Path, warnings: &mut Vec<String>) -> Result<Listing, String> {
    let mut listing = Listing {
        meshes: Vec::new(),
        label_maps: Vec::new(),
        n_subfolders: 0,
        n_other_files: 0,
    };
    for entry in walkdir::WalkDir::new(dir)
        .min_depth(0)
        .max_depth(1)
        .follow_links(true)
        .sort_by_file_name()
    {
        match entry {
            Ok(e) if e.depth() == 0 => {}
            Ok(e) if e.file_type().is_file() && plan.is_label_map(e.path()) => {
                listing.label_maps.push(e.path().to_path_buf())
            }
            Ok(e) if e.file_type().is_file() && is_mesh(plan, e.path()) => {
                listing.meshes.push(e.path().to_path_buf())
            }
            Ok(e) if e.file_type().is_dir() => listing.n_subfolders += 1,
            Ok(_) => listing.n_other_files += 1,
            // The folder itself cannot be listed: the case cannot be processed.
            Err(e) if e.depth() == 0 || e.path() == Some(dir) => {
                return Err(format!(
                    "cannot read the case folder {}: {}",
                    plan.display(dir),
                    io_reason(&e)
                ))
            }
            Err(e) => warnings.push(format!("{}: {e}", plan.display(dir))),
        }
    }
    Ok(listing)
}

/// The OS reason of a walk error, without walkdir's repetition of the path.
fn io_reason(e: &walkdir::Error) -> String {
    e.io_error()
        .map_or_else(|| e.to_string(), |io| io.to_string())
}

/// The case in `dir` with the given id, or `None` if the folder holds no meshes. Two files for
/// one structure (`tumor.ply`, `tumor.stl`) fail the case, unless `[input] extension_order`
/// says which to take.
pub fn case_at(
    plan: &Plan,
    dir: &Path,
    id: String,
    warnings: &mut Vec<String>,
) -> Option<CaseInput> {
    case_listing(plan, dir, id, warnings).0
}

/// [`case_at`] with the folder's listing, for telling skipped folders apart.
fn case_listing(
    plan: &Plan,
    dir: &Path,
    id: String,
    warnings: &mut Vec<String>,
) -> (Option<CaseInput>, Option<Listing>) {
    let listing = match case_meshes(plan, dir, warnings) {
        Ok(listing) => listing,
        Err(error) => return (Some(unreadable_case(dir, id, error)), None),
    };
    if listing.meshes.is_empty() && listing.label_maps.is_empty() {
        return (None, Some(listing));
    }
    let mut by_name: std::collections::BTreeMap<String, Vec<PathBuf>> = Default::default();
    for f in &listing.meshes {
        let name = f
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        by_name.entry(name).or_default().push(f.clone());
    }
    let mut meshes = Vec::new();
    let mut problems = Vec::new();
    let mut errors = Vec::new();
    let mut duplicates = Vec::new();
    for (name, mut files) in by_name {
        if files.len() > 1 {
            let names: Vec<String> = files
                .iter()
                .map(|f| {
                    f.file_name()
                        .unwrap_or_default()
                        .to_string_lossy()
                        .into_owned()
                })
                .collect();
            duplicates.push(format!("{name} ({})", names.join(", ")));
            match &plan.extension_order {
                Some(order) => {
                    let rank = |f: &PathBuf| {
                        let ext = crate::io::extension(f).unwrap_or_default();
                        order.iter().position(|o| *o == ext).unwrap_or(order.len())
                    };
                    files.sort_by_key(rank);
                    problems.push(format!(
                        "structure {name:?} has {} files ({}); {} is used ([input] extension_order)",
                        files.len(),
                        names.join(", "),
                        files[0].file_name().unwrap_or_default().to_string_lossy()
                    ));
                }
                None => errors.push(format!(
                    "structure {name:?} has {} files ({}): keep one, or set [input] extension_order to choose",
                    files.len(),
                    names.join(", ")
                )),
            }
        }
        meshes.push((name, files.swap_remove(0)));
    }
    let case = CaseInput {
        id,
        dir: dir.to_path_buf(),
        meshes,
        label_maps: listing.label_maps,
        problems,
        errors,
        duplicates,
    };
    (Some(case), None)
}

/// A case whose folder cannot be read: it fails with the reason, rather than vanishing.
fn unreadable_case(dir: &Path, id: String, error: String) -> CaseInput {
    CaseInput {
        id,
        dir: dir.to_path_buf(),
        meshes: Vec::new(),
        label_maps: Vec::new(),
        problems: Vec::new(),
        errors: vec![error],
        duplicates: Vec::new(),
    }
}

/// Case id of a folder below a root: its relative path with `/` separators. A root that is
/// itself a case is named after its own folder, as it would be one level up (its outputs go to
/// their own folder, not among the cohort's summary files).
fn case_id(root: &Path, dir: &Path) -> String {
    let rel = dir.strip_prefix(root).unwrap_or(dir);
    if rel.as_os_str().is_empty() {
        super::paths::canonical(root)
            .file_name()
            .map_or_else(|| "root".to_string(), |n| n.to_string_lossy().into_owned())
    } else {
        rel.components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .collect::<Vec<_>>()
            .join("/")
    }
}

/// Lists the cases of all roots. Never below an output root (a folder holding the
/// [`MARKER`](super::lock::MARKER)), whatever the path spelling; a folder that cannot be read
/// becomes a failed case rather than vanishing.
pub fn discover(plan: &Plan) -> Discovery {
    let mut out = Discovery::default();
    let mut seen = std::collections::BTreeSet::new();
    let output_root = super::paths::canonical(&plan.output_root);
    for root in &plan.roots {
        // A missing root is an error of the configuration (see `review`).
        if !root.is_dir() {
            continue;
        }
        let mut walker = walkdir::WalkDir::new(root)
            .follow_links(true)
            .sort_by_file_name();
        if let Some(depth) = plan.case_depth {
            walker = walker.min_depth(depth).max_depth(depth);
        }
        let mut skipped_outputs = Vec::new();
        let walker = walker.into_iter().filter_entry(|e| {
            let output = e.file_type().is_dir()
                && (is_output_root(e.path()) || super::paths::canonical(e.path()) == output_root);
            if output {
                skipped_outputs.push(e.path().to_path_buf());
            }
            !output
        });
        for entry in walker {
            let (dir, case) = match entry {
                Ok(e) if e.file_type().is_dir() => {
                    let id = case_id(root, e.path());
                    let (case, listing) = case_listing(plan, e.path(), id, &mut out.warnings);
                    let Some(case) = case else {
                        // A folder that should be a case, or a leaf folder with files: say so.
                        let what = match listing {
                            Some(l)
                                if l.n_other_files > 0
                                    && (plan.case_depth.is_some() || l.n_subfolders == 0) =>
                            {
                                Some(format!("{} files, none of them a mesh", l.n_other_files))
                            }
                            Some(_) if plan.case_depth.is_some() => Some("empty".to_string()),
                            _ => None,
                        };
                        if let Some(what) = what {
                            out.skipped_folders.push(format!(
                                "{}: {what} ({})",
                                plan.display(e.path()),
                                plan.mesh_selection()
                            ));
                        }
                        continue;
                    };
                    (e.path().to_path_buf(), case)
                }
                Ok(_) => continue,
                // A folder the walk cannot enter: with case_depth only folders above the cases
                // are entered, so it is a case only without case_depth.
                Err(e) => {
                    let dir = e.path().map(Path::to_path_buf);
                    match dir {
                        Some(d) if plan.case_depth.is_none() && d.is_dir() => {
                            let error = format!(
                                "cannot read the folder {}: {}",
                                plan.display(&d),
                                io_reason(&e)
                            );
                            let case = unreadable_case(&d, case_id(root, &d), error);
                            (d, case)
                        }
                        _ => {
                            out.warnings.push(format!("{}: {e}", root.display()));
                            continue;
                        }
                    }
                }
            };
            if !seen.insert(case.id.clone()) {
                out.warnings.push(format!(
                    "{}: case {:?} also exists under another root; skipped",
                    dir.display(),
                    case.id
                ));
                continue;
            }
            out.cases.push(case);
        }
        for d in skipped_outputs {
            if d != plan.output_root && super::paths::canonical(&d) != output_root {
                out.warnings.push(format!(
                    "{}: a destair output folder; not searched for cases",
                    d.display()
                ));
            }
        }
    }
    out
}

/// The identities of every input file and case folder of `cases` (and of the roots).
pub fn protected_inputs<'a>(
    cases: impl IntoIterator<Item = &'a CaseInput>,
    roots: &[PathBuf],
) -> ProtectedFiles {
    let mut p = ProtectedFiles::default();
    for r in roots {
        p.insert(r);
    }
    for c in cases {
        p.insert(&c.dir);
        for (_, f) in &c.meshes {
            p.insert(f);
        }
    }
    p
}

/// A share of the cases for one of `count` parallel runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// 0-based index.
    pub index: u64,
    pub count: u64,
}

impl Shard {
    /// Whether a case belongs to this shard. The choice depends only on the case id (a hash),
    /// so adding cases to a cohort never moves existing ones to another shard.
    pub fn contains(&self, case_id: &str) -> bool {
        let h = blake3::hash(case_id.as_bytes());
        let v = u64::from_le_bytes(h.as_bytes()[..8].try_into().unwrap_or([0; 8]));
        v % self.count == self.index
    }

    /// Parses `I/N` (0 <= I < N).
    pub fn parse(s: &str) -> Result<Shard, String> {
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| format!("expected I/N or `slurm`, got {s:?}"))?;
        let index: u64 = i
            .trim()
            .parse()
            .map_err(|_| format!("shard index {i:?} is not a number"))?;
        let count: u64 = n
            .trim()
            .parse()
            .map_err(|_| format!("shard count {n:?} is not a number"))?;
        if count == 0 || index >= count {
            return Err(format!("shard {s:?}: need 0 <= I < N"));
        }
        Ok(Shard { index, count })
    }

    /// The shard of a Slurm array task, from SLURM_ARRAY_TASK_ID/MIN/MAX/STEP/COUNT (read through
    /// `var`). Index (ID - MIN) / STEP of COUNT. List-form arrays (`--array=1,4,10`) report STEP 1
    /// and would give wrong indexes, so inconsistent values are refused rather than guessed.
    pub fn from_slurm(var: impl Fn(&str) -> Option<String>) -> Result<Shard, String> {
        let get = |name: &str| -> Result<u64, String> {
            let v = var(name)
                .ok_or_else(|| format!("{name} is not set (not inside a Slurm job array?)"))?;
            v.trim()
                .parse()
                .map_err(|_| format!("{name}={v:?} is not a number"))
        };
        let (id, min, max, count) = (
            get("SLURM_ARRAY_TASK_ID")?,
            get("SLURM_ARRAY_TASK_MIN")?,
            get("SLURM_ARRAY_TASK_MAX")?,
            get("SLURM_ARRAY_TASK_COUNT")?,
        );
        let step = match var("SLURM_ARRAY_TASK_STEP") {
            Some(_) => get("SLURM_ARRAY_TASK_STEP")?,
            None => 1,
        };
        if id < min || id > max {
            return Err(format!(
                "SLURM_ARRAY_TASK_ID={id} lies outside SLURM_ARRAY_TASK_MIN..MAX = {min}..{max}"
            ));
        }
        if step == 0
            || (id - min) % step != 0
            || max < min
            || (max - min) % step != 0
            || (max - min) / step + 1 != count
        {
            return Err(format!(
                "Slurm array ID={id} MIN={min} MAX={max} STEP={step} COUNT={count} is not a range a-b:s \
                 (list forms like --array=1,4,10 cannot be mapped to shards); use --shard I/N"
            ));
        }
        Ok(Shard {
            index: (id - min) / step,
            count,
        })
    }
}
