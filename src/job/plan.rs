//! The validated plan: the configuration resolved into absolute paths, output formats, resource
//! limits and, for any structure name, its effective settings. Built once; everything after
//! consumes it and never sees raw TOML.

use super::config::{Config, ConfigError, Settings};
pub use super::settings::StructureSettings;
use super::settings::{overlay, resolve};
use crate::io::{OutputFormat, ReadMode};
use std::path::{Path, PathBuf};

/// Most cases processed at once: each already uses every thread, so more only adds memory.
pub const MAX_WORKERS: usize = 256;
/// Largest memory budget (MB): 16 TiB, beyond any machine destair runs on.
pub const MAX_MEMORY_BUDGET_MB: u64 = 16 << 20;
/// Deepest case folders below a root.
pub const MAX_CASE_DEPTH: usize = 64;
/// The resolved configuration.
#[derive(Debug, Clone)]
pub struct Plan {
    pub config_path: PathBuf,
    pub roots: Vec<PathBuf>,
    pub case_depth: Option<usize>,
    pub extensions: Vec<String>,
    /// File-name globs that select meshes instead of `extensions`, when given.
    pub patterns: Option<Vec<glob::Pattern>>,
    /// Preference among a structure's files by extension (lower case), when given.
    pub extension_order: Option<Vec<String>>,
    /// File-name globs that select label maps; `None` takes every label-map file.
    pub label_map_patterns: Option<Vec<glob::Pattern>>,
    /// Structure names for label values, from `[labels]`.
    pub label_names: std::collections::BTreeMap<LabelKey, String>,
    /// World convention of surfaces made from label maps.
    pub space: crate::volume::Space,
    pub output_root: PathBuf,
    pub formats: Vec<OutputFormat>,
    pub annotate: bool,
    /// A picture sheet per structure.
    pub pictures: bool,
    /// report.html per case, index.html per cohort.
    pub html: bool,
    /// Output file stem template with `{structure}` and `{case}`.
    pub naming: String,
    pub workers: usize,
    pub memory_budget_bytes: u64,
    /// Where the budget comes from, for the run's first line and messages.
    pub memory_budget_source: String,
    /// What this process may use (the budget never exceeds it; a case that cannot fit in it
    /// fails instead of running alone).
    pub memory_limit: super::memory::MemoryLimit,
    /// What a label map may hold (`[input] max_label_voxels`, `max_labels`,
    /// `spacing_range_mm`).
    pub label_limits: crate::volume::LabelMapLimits,
    pub read_mode: ReadMode,
    /// `[guard]`: the distances between structures smoothing must keep.
    pub guard: crate::guard::GuardPolicy,
    defaults: Settings,
    structures: Vec<(String, glob::Pattern, Settings)>,
}

impl Plan {
    /// Validates a configuration (read from `path`) into a plan.
    pub fn new(config: Config, path: &Path) -> Result<Plan, ConfigError> {
        let invalid = |message: String| ConfigError::Invalid {
            path: path.to_path_buf(),
            message,
        };
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let absolute = |p: &Path| {
            if p.is_absolute() {
                p.to_path_buf()
            } else {
                base.join(p)
            }
        };
        if config.input.roots.is_empty() {
            return Err(invalid("[input] roots is empty".into()));
        }
        if config.input.case_depth == Some(0) {
            return Err(invalid("[input] case_depth must be at least 1".into()));
        }
        let formats = config
            .output
            .formats
            .iter()
            .map(|f| match f.as_str() {
                "ply" => Ok(OutputFormat::Ply),
                "stl" => Ok(OutputFormat::Stl),
                "vtp" => Ok(OutputFormat::Vtp),
                other => Err(invalid(format!(
                    "[output] formats: unknown format {other:?} (ply, stl, vtp)"
                ))),
            })
            .collect::<Result<Vec<_>, _>>()?;
        if formats.is_empty() {
            return Err(invalid("[output] formats is empty".into()));
        }
        if config.output.annotate && !formats.contains(&OutputFormat::Ply) {
            return Err(invalid(
                "[output] annotate adds vertex properties to PLY outputs: add \"ply\" to formats (VTP outputs always have them)"
                    .into(),
            ));
        }
        resolve(&config.defaults).map_err(|m| invalid(format!("[defaults]: {m}")))?;
        let cfd_anywhere = std::iter::once(&config.defaults)
            .chain(config.structures.iter().map(|s| &s.settings))
            .any(|s| s.profile.as_deref() == Some("cfd"));
        let stray = std::iter::once(("[defaults]".to_string(), &config.defaults))
            .chain(
                config
                    .structures
                    .iter()
                    .map(|s| (format!("[[structure]] {:?}", s.pattern), &s.settings)),
            )
            .find(|(_, s)| !s.cfd_keys().is_empty());
        if let (false, Some((table, s))) = (cfd_anywhere, stray) {
            return Err(invalid(format!(
                "{table}: {} only apply with profile = \"cfd\", which no table sets",
                s.cfd_keys().join(", ")
            )));
        }
        let mut structures = Vec::new();
        for (i, s) in config.structures.into_iter().enumerate() {
            let pattern = glob::Pattern::new(&s.pattern).map_err(|e| {
                invalid(format!(
                    "[[structure]] #{} pattern {:?}: {e}",
                    i + 1,
                    s.pattern
                ))
            })?;
            resolve(&overlay(&config.defaults, &s.settings))
                .map_err(|m| invalid(format!("[[structure]] {:?}: {m}", s.pattern)))?;
            structures.push((s.pattern, pattern, s.settings));
        }
        let patterns = match &config.input.patterns {
            None => None,
            Some(list) => Some(
                list.iter()
                    .map(|p| {
                        glob::Pattern::new(p)
                            .map_err(|e| invalid(format!("[input] patterns: {p:?}: {e}")))
                    })
                    .collect::<Result<Vec<_>, _>>()?,
            ),
        };
        let label_map_patterns = match &config.input.label_maps {
            None => None,
            Some(list) => Some(
                list.iter()
                    .map(|p| {
                        glob::Pattern::new(p)
                            .map_err(|e| invalid(format!("[input] label_maps: {p:?}: {e}")))
                    })
                    .collect::<Result<Vec<_>, _>>()?,
            ),
        };
        let mut label_names = std::collections::BTreeMap::new();
        for (value, name) in &config.labels {
            let v = LabelKey::parse(value).ok_or_else(|| {
                invalid(format!(
                    "[labels] {value:?} = {name:?}: the key must be a label value (a whole number), or a layer and a value as \"1:2\" (layer 1, counted from 0, value 2)"
                ))
            })?;
            if v.value == 0 {
                return Err(invalid(format!(
                    "[labels] {v} = {name:?}: label 0 is background and has no surface"
                )));
            }
            if name.is_empty()
                || name == "."
                || name == ".."
                || name.contains(['/', '\\'])
                || name.chars().any(char::is_control)
            {
                return Err(invalid(format!(
                    "[labels] {value} = {name:?}: a structure name must be non-empty, without path separators or control characters"
                )));
            }
            if let Some((other, _)) = label_names.iter().find(|(_, n)| *n == name) {
                return Err(invalid(format!(
                    "[labels] {other} and {v} are both named {name:?}; structure names must differ"
                )));
            }
            label_names.insert(v, name.clone());
        }
        let space = match config.output.space.as_deref() {
            None | Some("lps") | Some("LPS") => crate::volume::Space::Lps,
            Some("ras") | Some("RAS") => crate::volume::Space::Ras,
            Some(other) => {
                return Err(invalid(format!(
                    "[output] space = {other:?}: expected \"lps\" or \"ras\""
                )))
            }
        };
        let naming = config.output.naming.clone();
        if !naming.contains("{structure}") || naming.contains(['/', '\\']) {
            return Err(invalid(format!(
                "[output] naming = {naming:?} must contain {{structure}} and no path separators"
            )));
        }
        let workers = config.run.workers.unwrap_or(1);
        if !(1..=MAX_WORKERS).contains(&workers) {
            return Err(invalid(format!(
                "[run] workers = {workers}: must be between 1 and {MAX_WORKERS} (cases processed at once; each already uses every thread)"
            )));
        }
        let memory_limit = super::memory::process_memory_limit();
        let (memory_budget_bytes, memory_budget_source) =
            memory_budget(config.run.memory_budget_mb, &memory_limit).map_err(invalid)?;
        let label_limits = label_limits(&config.input).map_err(invalid)?;
        if let Some(d) = config.input.case_depth {
            if d > MAX_CASE_DEPTH {
                return Err(invalid(format!(
                    "[input] case_depth = {d}: must be between 1 and {MAX_CASE_DEPTH}"
                )));
            }
        }
        let guard = guard_policy(&config.guard).map_err(invalid)?;
        Ok(Plan {
            config_path: path.to_path_buf(),
            roots: config.input.roots.iter().map(|r| absolute(r)).collect(),
            case_depth: config.input.case_depth,
            extensions: config
                .input
                .extensions
                .iter()
                .map(|e| e.to_ascii_lowercase())
                .collect(),
            patterns,
            extension_order: config.input.extension_order.as_ref().map(|l| {
                l.iter()
                    .map(|e| e.trim_start_matches('.').to_ascii_lowercase())
                    .collect()
            }),
            label_map_patterns,
            label_names,
            space,
            output_root: absolute(&config.output.root),
            formats,
            annotate: config.output.annotate,
            pictures: config.output.pictures,
            html: config.output.html,
            naming,
            workers,
            memory_budget_bytes,
            memory_budget_source,
            memory_limit,
            label_limits,
            read_mode: if config.run.plain_read {
                ReadMode::Read
            } else {
                ReadMode::Mmap
            },
            guard,
            defaults: config.defaults,
            structures,
        })
    }

    /// Loads and validates a configuration file.
    pub fn load(path: &Path) -> Result<Plan, ConfigError> {
        let config = Config::load(path)?;
        // Absolute, so roots and output compare as paths whatever the working directory.
        let absolute = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
        Plan::new(config, &absolute)
    }

    /// A path as reports and messages show it: relative to the config file's folder, so reports
    /// stay true when a cohort moves.
    pub fn display(&self, path: &Path) -> String {
        let base = self.config_path.parent().unwrap_or(Path::new(""));
        super::paths::relative_to(base, path).display().to_string()
    }

    /// Whether a file (by name) is a label map of the cohort.
    pub fn is_label_map(&self, path: &Path) -> bool {
        if !crate::volume::is_label_map(path) {
            return false;
        }
        match &self.label_map_patterns {
            None => true,
            Some(patterns) => {
                let name = path
                    .file_name()
                    .map(|n| n.to_string_lossy())
                    .unwrap_or_default();
                patterns.iter().any(|p| p.matches(&name))
            }
        }
    }

    /// Which files count as meshes, in words.
    pub fn mesh_selection(&self) -> String {
        match &self.patterns {
            Some(p) => format!(
                "meshes are files matching {}",
                p.iter().map(|p| p.as_str()).collect::<Vec<_>>().join(", ")
            ),
            None => format!("meshes are .{} files", self.extensions.join(", .")),
        }
    }

    /// Names of the `[[structure]]` patterns, in file order.
    pub fn structure_patterns(&self) -> impl Iterator<Item = &str> {
        self.structures.iter().map(|(s, _, _)| s.as_str())
    }

    /// Effective settings for a structure: defaults, then every matching `[[structure]]` in order.
    pub fn settings_for(&self, structure: &str) -> StructureSettings {
        let merged = self
            .structures
            .iter()
            .filter(|(_, p, _)| p.matches(structure))
            .fold(self.defaults.clone(), |acc, (_, _, s)| overlay(&acc, s));
        // Every table was resolved in `new`, and overlays of valid tables stay valid.
        resolve(&merged)
            .unwrap_or_else(|_| resolve(&Settings::default()).expect("built-in defaults are valid"))
    }

    /// The `[defaults]` table's settings (what a structure no `[[structure]]` matches gets).
    pub fn default_settings(&self) -> StructureSettings {
        resolve(&self.defaults)
            .unwrap_or_else(|_| resolve(&Settings::default()).expect("built-in defaults are valid"))
    }

    /// Output file stem for a structure of a case (the case id's last part for `{case}`).
    pub fn output_stem(&self, case_id: &str, structure: &str) -> String {
        let case = case_id.rsplit('/').next().unwrap_or(case_id);
        self.naming
            .replace("{structure}", structure)
            .replace("{case}", case)
    }

    /// Patterns of the `[[structure]]` tables that match a name, for `destair check`.
    pub fn matching_tables(&self, structure: &str) -> Vec<&str> {
        self.structures
            .iter()
            .filter(|(_, p, _)| p.matches(structure))
            .map(|(s, _, _)| s.as_str())
            .collect()
    }

    /// Hash of every settings table (defaults and `[[structure]]`s): for cases whose structure
    /// names are known only once their label maps are read.
    pub fn settings_fingerprint(&self) -> String {
        let tables = format!("{:?} {:?}", self.defaults, self.structures);
        blake3::hash(tables.as_bytes()).to_hex().to_string()
    }

    /// The structure name `[labels]` gives label `value` of layer `layer`: a key naming that
    /// layer first, then one naming the value in every layer.
    pub fn label_name(&self, layer: usize, value: i64) -> Option<&String> {
        (self.label_names.get(&LabelKey {
            layer: Some(layer),
            value,
        }))
        .or_else(|| self.label_names.get(&LabelKey { layer: None, value }))
    }

    /// Hash of everything in the plan that changes outputs for given settings, with the
    /// program version and [`OUTPUT_REVISION`]: part of each case's resume key.
    pub fn output_fingerprint(&self, settings: &[(String, StructureSettings)]) -> String {
        let value = serde_json::json!({
            "version": env!("CARGO_PKG_VERSION"),
            "revision": OUTPUT_REVISION,
            "formats": self.formats,
            "annotate": self.annotate,
            "pictures": self.pictures,
            "html": self.html,
            "naming": self.naming,
            "structures": settings,
            "space": self.space,
            "labels": self.label_names,
            "guard": self.guard,
        });
        blake3::hash(value.to_string().as_bytes())
            .to_hex()
            .to_string()
    }
}

/// A `[labels]` key: a label value in every layer (`"2"`), or in one layer (`"1:2"`: layer 1,
/// counted from 0 as the report's `layer` and Slicer's `Segment<N>_Layer` are, value 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct LabelKey {
    pub layer: Option<usize>,
    pub value: i64,
}

impl LabelKey {
    /// The key as written in `[labels]`, or None when it is neither form.
    pub fn parse(key: &str) -> Option<LabelKey> {
        let (layer, value) = match key.split_once(':') {
            Some((layer, value)) => (Some(layer.trim().parse().ok()?), value),
            None => (None, key),
        };
        Some(LabelKey {
            layer,
            value: value.trim().parse().ok()?,
        })
    }

    /// Whether the key names `value` of layer `layer`.
    pub fn names(&self, layer: usize, value: i64) -> bool {
        self.value == value && self.layer.is_none_or(|l| l == layer)
    }
}

impl std::fmt::Display for LabelKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.layer {
            Some(layer) => write!(f, "{layer}:{}", self.value),
            None => write!(f, "{}", self.value),
        }
    }
}

// Keys are written as in the configuration (a plain value as before, so a resume key made
// before layers could be addressed is unchanged).
impl serde::Serialize for LabelKey {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

/// Raised whenever a change makes destair write something else for the same input and
/// settings (an analysis or a default changed), so that a rerun redoes the cases an earlier
/// build finished instead of mixing its results with the new ones in one cohort. The package
/// version alone does not change between such builds. 1: turned grids, the grid-aware
/// automatic tau and `reaches_volume_edge` (issue 61). 2: flat regions filled from their
/// flattest face within the growth limits, coplanar faces, rises and dents (issue 61's caps).
/// 3: turned grids of tubes with only corner facets, ties in the axis estimate, the file's
/// label names in reports, the NIfTI sform/qform warning and the label volume warning.
/// 4: label voxels touching by an edge or a corner are one object (26-connectivity), objects
/// and surface pieces in reports (issue 62). 5: constrained label surfaces with the
/// shrink-free kernel and the Gaussian narrowed where a label is thin (issue 62). 6: default
/// sigma 1.5 smallest spacings, noise only one- and two-voxel bumps and pits, thin parts stay
/// narrowed beside relaxed noise (issue 62).
pub const OUTPUT_REVISION: u32 = 6;

/// Largest number of guard repair rounds.
const MAX_GUARD_REPAIRS: usize = 20;

/// Validates `[guard]`.
fn guard_policy(c: &super::config::GuardConfig) -> Result<crate::guard::GuardPolicy, String> {
    let defaults = crate::guard::GuardPolicy::default();
    let loss = |v: Option<f64>, what: &str| match v {
        None => Ok(defaults.max_gap_loss_mm),
        Some(x) if x.is_finite() && x >= 0.0 => Ok(x),
        Some(x) => Err(format!(
            "{what} max_gap_loss_mm = {x}: must be a distance of 0 mm or more"
        )),
    };
    let max_gap_loss_mm = loss(c.max_gap_loss_mm, "[guard]")?;
    let forbid_new_contacts = c
        .forbid_new_contacts
        .unwrap_or(defaults.forbid_new_contacts);
    let max_repairs = c.max_repairs.unwrap_or(defaults.max_repairs);
    if max_repairs > MAX_GUARD_REPAIRS {
        return Err(format!(
            "[guard] max_repairs = {max_repairs}: must be between 0 and {MAX_GUARD_REPAIRS}"
        ));
    }
    let mut pairs = Vec::new();
    for p in &c.pairs {
        if p.a == p.b || p.a.is_empty() || p.b.is_empty() {
            return Err(format!(
                "[[guard.pair]] a = {:?}, b = {:?}: two different structure names",
                p.a, p.b
            ));
        }
        pairs.push((
            p.a.clone(),
            p.b.clone(),
            match p.max_gap_loss_mm {
                None => max_gap_loss_mm,
                given => loss(given, "[[guard.pair]]")?,
            },
            p.forbid_new_contacts.unwrap_or(forbid_new_contacts),
        ));
    }
    Ok(crate::guard::GuardPolicy {
        max_gap_loss_mm,
        forbid_new_contacts,
        max_repairs,
        self_intersections: c.self_intersections.unwrap_or(defaults.self_intersections),
        pairs,
    })
}

/// The memory budget (bytes) and where it comes from: `[run] memory_budget_mb`, held to what
/// this process may use, or by default half of that.
fn memory_budget(
    configured_mb: Option<u64>,
    limit: &super::memory::MemoryLimit,
) -> Result<(u64, String), String> {
    let mib = |b: u64| crate::units::readable(b as f64 / f64::from(1 << 20));
    match configured_mb {
        Some(mb) if !(1..=MAX_MEMORY_BUDGET_MB).contains(&mb) => Err(format!(
            "[run] memory_budget_mb = {mb}: must be between 1 and {MAX_MEMORY_BUDGET_MB} (MB)"
        )),
        Some(mb) if (mb << 20) > limit.bytes => Ok((
            limit.bytes,
            format!(
                "[run] memory_budget_mb = {mb} held to what this process may use, by {}",
                limit.source
            ),
        )),
        Some(mb) => Ok((mb << 20, "[run] memory_budget_mb".into())),
        None => Ok((
            limit.bytes / 2,
            format!(
                "half of the {} MB this process may use, by {}",
                mib(limit.bytes),
                limit.source
            ),
        )),
    }
}

/// `[input]`'s limits on label maps, checked.
fn label_limits(
    input: &super::config::InputConfig,
) -> Result<crate::volume::LabelMapLimits, String> {
    let mut limits = crate::volume::LabelMapLimits::default();
    if let Some(n) = input.max_label_voxels {
        if !(1..=crate::volume::MAX_VOXELS).contains(&n) {
            return Err(format!(
                "[input] max_label_voxels = {n}: must be between 1 and {}",
                crate::volume::MAX_VOXELS
            ));
        }
        limits.max_voxels = n;
    }
    if let Some(n) = input.max_labels {
        if !(1..=u16::MAX as usize).contains(&n) {
            return Err(format!(
                "[input] max_labels = {n}: must be between 1 and {}",
                u16::MAX
            ));
        }
        limits.max_labels = n;
    }
    if let Some([lo, hi]) = input.spacing_range_mm {
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo < hi) {
            return Err(format!(
                "[input] spacing_range_mm = [{lo}, {hi}]: expected two positive numbers, the smaller first (mm)"
            ));
        }
        limits.spacing_mm = [lo, hi];
    }
    Ok(limits)
}
