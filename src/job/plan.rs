//! The validated plan: the configuration resolved into absolute paths, output formats, resource
//! limits and, for any structure name, its effective settings. Built once; everything after
//! consumes it and never sees raw TOML.

use super::config::{Config, ConfigError, Settings};
use crate::cfd::{CfdOptions, CfdProfile, Inlet};
use crate::extract::constrained::{LabelSmoothing, Noise, Surface, Thin};
use crate::io::{OutputFormat, ReadMode};
use crate::smooth::{MethodKind, MethodParams};
use crate::weights::{
    AxisChoice, CapPolicy, Combine, ContextParams, DistanceScaling, StaircaseParams,
};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Most cases processed at once: each already uses every thread, so more only adds memory.
pub const MAX_WORKERS: usize = 256;
/// Largest memory budget (MB): 16 TiB, beyond any machine destair runs on.
pub const MAX_MEMORY_BUDGET_MB: u64 = 16 << 20;
/// Deepest case folders below a root.
pub const MAX_CASE_DEPTH: usize = 64;

/// Everything that decides how one structure is processed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StructureSettings {
    pub method: MethodKind,
    pub params: MethodParams,
    pub iterations: usize,
    /// Voxel size (mm); reconstructed from the mesh when not given and the method needs it.
    pub voxel: Option<[f32; 3]>,
    pub context: ContextParams,
    /// Structures of the same case whose distance must be preserved.
    pub references: Vec<String>,
    pub move_boundary: bool,
    /// Copied unchanged (still usable as a reference).
    pub skip: bool,
    /// A structure whose smoothing moved a vertex further than this many voxel diagonals fails.
    pub max_displacement_voxels: f32,
    /// How a structure made from a label map is extracted.
    pub extraction: LabelSmoothing,
    /// Whether `method` was configured: a constrained label surface is already smooth and
    /// true to its voxels, so a mesh smoother runs on it only when asked for.
    pub method_configured: bool,
    /// `profile = "cfd"`: what readies the structure for a flow solver.
    pub cfd: Option<CfdProfile>,
}

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
    pub label_names: std::collections::BTreeMap<i64, String>,
    /// World convention of surfaces made from label maps.
    pub space: crate::volume::Space,
    pub output_root: PathBuf,
    pub formats: Vec<OutputFormat>,
    pub annotate: bool,
    /// Output file stem template with `{structure}` and `{case}`.
    pub naming: String,
    pub workers: usize,
    pub memory_budget_bytes: u64,
    pub read_mode: ReadMode,
    defaults: Settings,
    structures: Vec<(String, glob::Pattern, Settings)>,
}

impl StructureSettings {
    /// The settings as a `[defaults]`-style TOML table: every key a config can set that this
    /// method uses, with the value that will be used (defaults filled in).
    pub fn config_view(&self) -> String {
        use crate::smooth::Method;
        use toml::Value;
        // Through the shortest f32 text, so 0.1 prints as 0.1 and not 0.10000000149011612.
        let f = |x: f32| Value::Float(x.to_string().parse().unwrap_or(x as f64));
        let mut t: Vec<(&str, Value)> = Vec::new();
        t.push(("method", Value::String(self.method.name().into())));
        t.push(("iterations", Value::Integer(self.iterations as i64)));
        match self
            .method
            .build(&self.params, self.voxel.unwrap_or([1.0; 3]))
        {
            Method::Laplace { lambda } | Method::Mcf { lambda } | Method::Npc { lambda, .. } => {
                t.push(("lambda", f(lambda)));
            }
            Method::Hc {
                lambda,
                alpha,
                beta,
            } => {
                t.push(("lambda", f(lambda)));
                t.push(("alpha", f(alpha)));
                t.push(("beta", f(beta)));
            }
            Method::Taubin { lambda, mu } => {
                t.push(("lambda", f(lambda)));
                t.push(("mu", f(mu)));
            }
            Method::CellSize {
                lambda, threshold, ..
            }
            | Method::CellEdge {
                lambda, threshold, ..
            }
            | Method::Diamond {
                lambda, threshold, ..
            } => {
                t.push(("lambda", f(lambda)));
                t.push(("threshold", f(threshold)));
            }
        }
        if let Some(v) = self.voxel {
            t.push(("voxel", Value::Array(v.iter().map(|&x| f(x)).collect())));
        }
        let c = &self.context;
        t.push(("staircase", Value::Boolean(c.staircase)));
        let axis = match c.axis {
            AxisChoice::Auto => Value::String("auto".into()),
            AxisChoice::Given(a) => Value::Array(a.iter().map(|&x| f(x)).collect()),
        };
        t.push(("axis", axis));
        t.push(("tau", f(c.staircase_params.tau)));
        t.push(("tau_max", f(c.staircase_params.tau_max_mm)));
        t.push(("beta_min", f(c.staircase_params.beta_min)));
        let caps = match c.caps {
            CapPolicy::Preserve => "preserve",
            CapPolicy::Smooth => "smooth",
        };
        t.push(("caps", Value::String(caps.into())));
        let references = self.references.iter().map(|r| Value::String(r.clone()));
        t.push(("references", Value::Array(references.collect())));
        let scaling = match c.distance_scaling {
            DistanceScaling::Linear => "linear".to_string(),
            DistanceScaling::SafetyMargin { margin_mm } => format!("margin:{margin_mm}"),
            DistanceScaling::Exponential { k } => format!("exp:{k}"),
            DistanceScaling::Ramp { d0_mm, d1_mm } => format!("ramp:{d0_mm},{d1_mm}"),
        };
        t.push(("distance_scaling", Value::String(scaling)));
        let combine = match c.combine {
            Combine::Product => "product",
            Combine::Min => "min",
        };
        t.push(("combine", Value::String(combine.into())));
        t.push(("move_boundary", Value::Boolean(self.move_boundary)));
        t.push(("skip", Value::Boolean(self.skip)));
        t.push(("max_displacement_voxels", f(self.max_displacement_voxels)));
        let e = &self.extraction;
        let word = |w: &str| Value::String(w.into());
        t.push(("surface", word(e.surface.name())));
        if let Some(sigma) = e.sigma_mm {
            t.push(("sigma_mm", Value::Float(sigma)));
        }
        t.push(("noise", word(e.noise.name())));
        t.push(("thin", word(e.thin.name())));
        match &self.cfd {
            None => t.push(("profile", word("none"))),
            Some(c) => {
                t.push(("profile", word("cfd")));
                let inlet = match c.inlet {
                    Inlet::Largest => word("largest"),
                    Inlet::Index(i) => Value::Integer(i as i64),
                    Inlet::Point(p) => Value::Array(p.iter().map(|&x| Value::Float(x)).collect()),
                };
                t.push(("inlet", inlet));
                if let Some(n) = c.expect_patches {
                    t.push(("expect_patches", Value::Integer(n as i64)));
                }
                match c.finish.remesh.map(|r| r.edge) {
                    Some(crate::remesh::EdgeTarget::Mm(mm)) => {
                        t.push(("edge_mm", Value::Float(mm)))
                    }
                    Some(crate::remesh::EdgeTarget::PerRadius(k)) => {
                        t.push(("edge_per_radius", Value::Float(k)))
                    }
                    None => {}
                }
                if let Some(k) = c.finish.flow_extension {
                    t.push(("flow_extension", Value::Float(k)));
                    let ids = c
                        .finish
                        .extend_patches
                        .iter()
                        .map(|&i| Value::Integer(i.into()));
                    t.push(("extend", Value::Array(ids.collect())));
                }
                t.push(("close_open_ends", Value::Boolean(c.finish.close_open_ends)));
                t.push(("keep_rims", Value::Boolean(c.finish.keep_rims)));
            }
        }
        let mut text: String = t.iter().map(|(k, v)| format!("{k} = {v}\n")).collect();
        if self.voxel.is_none() {
            text.push_str("# voxel: reconstructed from each mesh where the method needs it\n");
        }
        if e.sigma_mm.is_none() {
            text.push_str("# sigma_mm: twice the label map's smallest voxel spacing\n");
        }
        text.push_str("# surface, sigma_mm, noise, thin: structures made from label maps\n");
        text
    }
}

/// Later settings override earlier ones key by key.
fn overlay(base: &Settings, over: &Settings) -> Settings {
    macro_rules! pick {
        ($($f:ident),*) => { Settings { $($f: over.$f.clone().or_else(|| base.$f.clone()),)* } };
    }
    pick!(
        method,
        iterations,
        lambda,
        mu,
        alpha,
        beta,
        threshold,
        voxel,
        staircase,
        axis,
        tau,
        tau_max,
        beta_min,
        caps,
        references,
        distance_scaling,
        combine,
        move_boundary,
        skip,
        max_displacement_voxels,
        surface,
        sigma_mm,
        noise,
        thin,
        profile,
        edge_mm,
        edge_per_radius,
        flow_extension,
        extend,
        close_open_ends,
        keep_rims,
        inlet,
        expect_patches
    )
}

/// The `inlet` key: "largest", a patch index (by decreasing area) or [x, y, z] (mm).
fn parse_inlet(v: &toml::Value) -> Result<Inlet, String> {
    let bad = || format!("inlet = {v} must be \"largest\", a patch index or [x, y, z] in mm");
    match v {
        toml::Value::String(s) => s.parse().map_err(|_| bad()),
        toml::Value::Integer(i) => usize::try_from(*i).map(Inlet::Index).map_err(|_| bad()),
        toml::Value::Array(a) if a.len() == 3 => {
            let p: Vec<f64> = a
                .iter()
                .map(|x| x.as_float().or_else(|| x.as_integer().map(|i| i as f64)))
                .collect::<Option<_>>()
                .filter(|p: &Vec<f64>| p.iter().all(|x| x.is_finite()))
                .ok_or_else(bad)?;
            Ok(Inlet::Point([p[0], p[1], p[2]]))
        }
        _ => Err(bad()),
    }
}

/// The cfd profile of merged settings, when `profile = "cfd"`.
fn resolve_cfd(s: &Settings) -> Result<Option<CfdProfile>, String> {
    match s.profile.as_deref() {
        None | Some("none") => Ok(None),
        Some("cfd") => CfdProfile::new(CfdOptions {
            inlet: s.inlet.as_ref().map(parse_inlet).transpose()?,
            expect_patches: s.expect_patches,
            edge_mm: s.edge_mm,
            edge_per_radius: s.edge_per_radius,
            flow_extension: s.flow_extension,
            extend: s.extend.clone().unwrap_or_default(),
            close_open_ends: s.close_open_ends.unwrap_or(false),
            keep_rims: s.keep_rims.unwrap_or(false),
        })
        .map(Some),
        Some(other) => Err(format!("profile = {other:?} must be \"cfd\" or \"none\"")),
    }
}

/// Turns merged settings into effective ones, with defaults for what is unset.
fn resolve(s: &Settings) -> Result<StructureSettings, String> {
    let method: MethodKind = s.method.as_deref().unwrap_or("hc").parse()?;
    let r = |x: f32| crate::units::readable(x as f64);
    let unit = |name: &str, v: Option<f32>| -> Result<Option<f32>, String> {
        match v {
            Some(x) if !(0.0..=1.0).contains(&x) => {
                Err(format!("{name} = {} must lie in [0, 1]", r(x)))
            }
            other => Ok(other),
        }
    };
    let positive = |name: &str, v: Option<f32>| -> Result<Option<f32>, String> {
        match v {
            Some(x) if !(x.is_finite() && x > 0.0) => {
                Err(format!("{name} = {} must be a positive number", r(x)))
            }
            other => Ok(other),
        }
    };
    let axis = match &s.axis {
        None => AxisChoice::Auto,
        Some(toml::Value::String(a)) if a == "auto" => AxisChoice::Auto,
        Some(toml::Value::Array(a)) if a.len() == 3 => {
            let v: Vec<f32> = a
                .iter()
                .map(|x| {
                    x.as_float()
                        .or_else(|| x.as_integer().map(|i| i as f64))
                        .map(|f| f as f32)
                })
                .collect::<Option<_>>()
                .ok_or("axis must be \"auto\" or three numbers")?;
            if v.iter().all(|x| *x == 0.0) || v.iter().any(|x| !x.is_finite()) {
                return Err("axis must not be zero".into());
            }
            AxisChoice::Given([v[0], v[1], v[2]])
        }
        Some(other) => return Err(format!("axis must be \"auto\" or [x, y, z], got {other}")),
    };
    if let Some(v) = s.voxel {
        if v.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            let shown: Vec<String> = v.iter().map(|&x| r(x)).collect();
            return Err(format!(
                "voxel = [{}] must be three positive sizes in mm",
                shown.join(", ")
            ));
        }
    }
    let caps = match s.caps.as_deref() {
        None | Some("preserve") => CapPolicy::Preserve,
        Some("smooth") => CapPolicy::Smooth,
        Some(other) => {
            return Err(format!(
                "caps = {other:?} must be \"preserve\" or \"smooth\""
            ))
        }
    };
    let combine = match s.combine.as_deref() {
        None | Some("product") => Combine::Product,
        Some("min") => Combine::Min,
        Some(other) => {
            return Err(format!(
                "combine = {other:?} must be \"product\" or \"min\""
            ))
        }
    };
    let distance_scaling: DistanceScaling =
        s.distance_scaling.as_deref().unwrap_or("linear").parse()?;
    let defaults = StaircaseParams::default();
    let staircase_params = StaircaseParams {
        tau: unit("tau", s.tau)?.unwrap_or(defaults.tau),
        tau_max_mm: positive("tau_max", s.tau_max)?.unwrap_or(defaults.tau_max_mm),
        beta_min: unit("beta_min", s.beta_min)?.unwrap_or(defaults.beta_min),
    };
    let params = MethodParams {
        lambda: s.lambda,
        mu: s.mu,
        alpha: s.alpha,
        beta: s.beta,
        threshold: s.threshold,
    };
    method.check(&params)?;
    let extraction = LabelSmoothing {
        surface: match s.surface.as_deref() {
            None | Some("constrained") => Surface::Constrained,
            Some("binary") => Surface::Binary,
            Some(other) => {
                return Err(format!(
                    "surface = {other:?} must be \"constrained\" or \"binary\""
                ))
            }
        },
        sigma_mm: match s.sigma_mm {
            Some(x) if !(x.is_finite() && x > 0.0) => {
                return Err(format!(
                    "sigma_mm = {} must be a positive number of mm",
                    crate::units::readable(x)
                ))
            }
            other => other,
        },
        noise: match s.noise.as_deref() {
            None | Some("smooth") => Noise::Smooth,
            Some("keep") => Noise::Keep,
            Some(other) => return Err(format!("noise = {other:?} must be \"smooth\" or \"keep\"")),
        },
        thin: match s.thin.as_deref() {
            None | Some("protect") => Thin::Protect,
            Some("off") => Thin::Off,
            Some(other) => return Err(format!("thin = {other:?} must be \"protect\" or \"off\"")),
        },
    };
    Ok(StructureSettings {
        method,
        params,
        iterations: match s.iterations {
            Some(n) => {
                crate::smooth::check_iterations(n).map_err(|m| format!("iterations: {m}"))?
            }
            None => method.default_iterations(),
        },
        voxel: s.voxel,
        context: ContextParams {
            staircase: s.staircase.unwrap_or(true),
            axis,
            staircase_params,
            caps,
            cap_params: Default::default(),
            distance_scaling,
            combine,
        },
        references: s.references.clone().unwrap_or_default(),
        move_boundary: s.move_boundary.unwrap_or(false),
        skip: s.skip.unwrap_or(false),
        max_displacement_voxels: positive("max_displacement_voxels", s.max_displacement_voxels)?
            .unwrap_or(crate::smooth::DEFAULT_MAX_DISPLACEMENT_VOXELS),
        extraction,
        method_configured: s.method.is_some(),
        cfd: resolve_cfd(s)?,
    })
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
                other => Err(invalid(format!(
                    "[output] formats: unknown format {other:?} (ply, stl)"
                ))),
            })
            .collect::<Result<Vec<_>, _>>()?;
        if formats.is_empty() {
            return Err(invalid("[output] formats is empty".into()));
        }
        if config.output.annotate && !formats.contains(&OutputFormat::Ply) {
            return Err(invalid(
                "[output] annotate adds vertex properties, which only PLY holds: add \"ply\" to formats"
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
            let v: i64 = value.trim().parse().map_err(|_| {
                invalid(format!(
                    "[labels] {value:?} = {name:?}: the key must be a label value (a whole number)"
                ))
            })?;
            if v == 0 {
                return Err(invalid(format!(
                    "[labels] 0 = {name:?}: label 0 is background and has no surface"
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
        let memory_budget_mb = config.run.memory_budget_mb.unwrap_or(1024);
        if !(1..=MAX_MEMORY_BUDGET_MB).contains(&memory_budget_mb) {
            return Err(invalid(format!(
                "[run] memory_budget_mb = {memory_budget_mb}: must be between 1 and {MAX_MEMORY_BUDGET_MB} (MB)"
            )));
        }
        if let Some(d) = config.input.case_depth {
            if d > MAX_CASE_DEPTH {
                return Err(invalid(format!(
                    "[input] case_depth = {d}: must be between 1 and {MAX_CASE_DEPTH}"
                )));
            }
        }
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
            naming,
            workers,
            memory_budget_bytes: memory_budget_mb << 20,
            read_mode: if config.run.plain_read {
                ReadMode::Read
            } else {
                ReadMode::Mmap
            },
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

    /// Hash of everything in the plan that changes outputs for given settings, with the
    /// program version: part of each case's resume key.
    pub fn output_fingerprint(&self, settings: &[(String, StructureSettings)]) -> String {
        let value = serde_json::json!({
            "version": env!("CARGO_PKG_VERSION"),
            "formats": self.formats,
            "annotate": self.annotate,
            "naming": self.naming,
            "structures": settings,
            "space": self.space,
            "labels": self.label_names,
        });
        blake3::hash(value.to_string().as_bytes())
            .to_hex()
            .to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(text: &str) -> Result<Plan, ConfigError> {
        Plan::new(
            Config::parse(text, Path::new("/c/cohort.toml"))?,
            Path::new("/c/cohort.toml"),
        )
    }

    #[test]
    fn settings_merge_in_order_and_paths_resolve() {
        let p = plan(
            r#"
[input]
roots = ["cases"]
[output]
root = "/abs/out"
[defaults]
method = "laplace"
lambda = 0.4
[[structure]]
pattern = "ve*"
method = "taubin"
[[structure]]
pattern = "vein"
references = ["tumor"]
skip = false
"#,
        )
        .unwrap();
        assert_eq!(p.roots, vec![PathBuf::from("/c/cases")]);
        assert_eq!(p.output_root, PathBuf::from("/abs/out"));
        let vein = p.settings_for("vein");
        assert_eq!(vein.method, MethodKind::Taubin);
        assert_eq!(vein.params.lambda, Some(0.4));
        assert_eq!(vein.references, vec!["tumor"]);
        let tumor = p.settings_for("tumor");
        assert_eq!(tumor.method, MethodKind::Laplace);
        assert!(tumor.references.is_empty());
        assert_eq!(p.matching_tables("vessel"), vec!["ve*"]);
    }

    #[test]
    fn bad_values_name_their_table() {
        let base = "[input]\nroots = [\"c\"]\n[output]\nroot = \"o\"\n";
        let cases = [
            ("[defaults]\nmethod = \"smoothest\"\n", "[defaults]"),
            (
                "[[structure]]\npattern = \"v*\"\ncaps = \"keep\"\n",
                "\"v*\"",
            ),
            ("[defaults]\ntau = 1.5\n", "tau"),
            ("[defaults]\ndistance_scaling = \"ramp:3,1\"\n", "ramp"),
            ("[defaults]\naxis = [0, 0, 0]\n", "axis"),
        ];
        for (extra, needle) in cases {
            let err = plan(&format!("{base}{extra}")).unwrap_err().to_string();
            assert!(err.contains(needle), "{err}");
        }
        let err = plan("[input]\nroots = [\"c\"]\n[output]\nroot = \"o\"\nformats = [\"stl\"]\nannotate = true\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("only PLY"), "{err}");
        let err = plan("[input]\nroots = [\"c\"]\n[output]\nroot = \"o\"\nformats = [\"vtk\"]\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("vtk"));
    }

    #[test]
    fn the_cfd_profile_is_set_per_structure_and_checked() {
        let base = "[input]\nroots = [\"c\"]\n[output]\nroot = \"o\"\n";
        let p = plan(&format!(
            "{base}[defaults]\nedge_mm = 0.3\n[[structure]]\npattern = \"vessel*\"\nprofile = \"cfd\"\ninlet = [1, 2.5, 3]\nflow_extension = 5\nextend = [2]\nexpect_patches = 3\n"
        ))
        .unwrap();
        assert!(p.settings_for("tumor").cfd.is_none());
        let c = p.settings_for("vessel_a").cfd.unwrap();
        assert_eq!(c.inlet, Inlet::Point([1.0, 2.5, 3.0]));
        assert_eq!(c.expect_patches, Some(3));
        assert_eq!(c.finish.flow_extension, Some(5.0));
        assert_eq!(c.finish.extend_patches, vec![2]);
        assert_eq!(
            c.finish.remesh.map(|r| r.edge),
            Some(crate::remesh::EdgeTarget::Mm(0.3))
        );
        let view = p.settings_for("vessel_a").config_view();
        assert!(
            view.contains("profile = \"cfd\"") && view.contains("edge_mm = 0.3"),
            "{view}"
        );
        // The view parses back into the same settings.
        let again = plan(&format!("{base}[defaults]\n{view}")).unwrap();
        assert_eq!(again.settings_for("x").cfd, Some(c));
        for inlet in ["\"largest\"", "1", "\"2\""] {
            let text = format!("{base}[defaults]\nprofile = \"cfd\"\ninlet = {inlet}\n");
            assert!(plan(&text).is_ok(), "{inlet}");
        }
        let cases = [
            ("edge_mm = 0.3\n", "no table sets"),
            ("profile = \"cdf\"\n", "\"cfd\" or \"none\""),
            (
                "profile = \"cfd\"\nedge_mm = 0.3\nedge_per_radius = 0.5\n",
                "exclude",
            ),
            ("profile = \"cfd\"\nedge_mm = -1.0\n", "edge_mm"),
            ("profile = \"cfd\"\nextend = [2]\n", "set flow_extension"),
            (
                "profile = \"cfd\"\nflow_extension = 5\nextend = [1]\n",
                "wall is 1",
            ),
            ("profile = \"cfd\"\nflow_extension = 1000\n", "longer than"),
            ("profile = \"cfd\"\ninlet = [1, 2]\n", "inlet"),
            ("profile = \"cfd\"\ninlet = -1\n", "inlet"),
            ("profile = \"cfd\"\nexpect_patches = 0\n", "expect_patches"),
        ];
        for (extra, needle) in cases {
            let err = plan(&format!("{base}[defaults]\n{extra}"))
                .unwrap_err()
                .to_string();
            assert!(err.contains(needle), "{extra}: {err}");
        }
    }
}
