//! The cohort configuration file (TOML): where the cases are, where outputs go, and the smoothing
//! settings per structure. Unknown keys are rejected with their line and column; the file is
//! turned once into a [`Plan`](super::plan::Plan) that the rest of the runner consumes.

use serde::Deserialize;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Largest configuration file read (bytes).
const MAX_CONFIG_BYTES: u64 = 16 << 20;

/// A configuration file that cannot be used.
#[derive(Debug, Error)]
pub enum ConfigError {
    #[error("{}: cannot read: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}:{line}:{column}: {message}", path.display())]
    Syntax {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
    #[error("{}: {message}", path.display())]
    Invalid { path: PathBuf, message: String },
}

/// `[input]`: where the cases are and how a case is recognised.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputConfig {
    /// Folders holding the cases, relative to the config file.
    pub roots: Vec<PathBuf>,
    /// Cases are the folders at this depth below a root (1 = its subfolders); without it,
    /// every folder that directly contains mesh files is a case.
    pub case_depth: Option<usize>,
    /// File extensions of meshes (lower case, no dot).
    #[serde(default = "default_extensions")]
    pub extensions: Vec<String>,
    /// Globs on file names that select meshes (e.g. "*_seg.stl"); when given, they replace
    /// `extensions`. The structure name is still the file stem.
    pub patterns: Option<Vec<String>>,
    /// Which file to take when a structure has several (`tumor.ply`, `tumor.stl`): the first
    /// extension in this list. Without it such a case fails.
    pub extension_order: Option<Vec<String>>,
    /// Globs on file names that select label maps (segmentations whose labels become the
    /// case's structures). Default: every .nii, .nii.gz, .nrrd, .seg.nrrd and .nhdr file;
    /// `[]` reads none. Narrow it when case folders also hold images (`["*seg*.nii.gz"]`).
    pub label_maps: Option<Vec<String>>,
    /// Most voxels a label map may declare, all layers together (default 2^30).
    pub max_label_voxels: Option<u64>,
    /// Most distinct labels a label map may hold (default 255).
    pub max_labels: Option<usize>,
    /// Smallest and largest voxel spacing a label map may have, in mm (default [0.001, 1000]).
    pub spacing_range_mm: Option<[f64; 2]>,
}

fn default_extensions() -> Vec<String> {
    vec!["ply".into(), "stl".into(), "obj".into()]
}

/// `[output]`: where results go.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputConfig {
    /// Output folder, relative to the config file.
    pub root: PathBuf,
    /// Mesh formats to write for every structure: "ply", "stl", "vtp".
    #[serde(default = "default_formats")]
    pub formats: Vec<String>,
    /// Add the per-vertex arrays (`weight`, `displacement`, ...) to PLY outputs (VTP always
    /// has them).
    #[serde(default)]
    pub annotate: bool,
    /// A picture sheet per structure (PNG next to the report).
    #[serde(default = "default_true")]
    pub pictures: bool,
    /// `report.html` per case and `index.html` for the cohort.
    #[serde(default = "default_true")]
    pub html: bool,
    /// Output mesh file name without extension; `{structure}` and `{case}` are replaced.
    #[serde(default = "default_naming")]
    pub naming: String,
    /// World convention of surfaces made from label maps: "lps" (3D Slicer's, the default) or
    /// "ras" (NIfTI's). Written into each mesh's header as `SPACE=...`.
    pub space: Option<String>,
}

fn default_true() -> bool {
    true
}

fn default_naming() -> String {
    "{structure}".into()
}

fn default_formats() -> Vec<String> {
    vec!["ply".into()]
}

/// `[run]`: resources.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunConfig {
    /// Cases processed at the same time (default 1; each uses all threads inside).
    pub workers: Option<usize>,
    /// Upper bound on the estimated memory of the cases in flight, in MB (default: half of
    /// what this process may use; never more than that).
    pub memory_budget_mb: Option<u64>,
    /// Read with plain reads instead of memory maps (network filesystems).
    #[serde(default)]
    pub plain_read: bool,
}

/// Smoothing settings; every key optional so `[[structure]]` tables override only what they name.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Settings {
    /// laplace, hc, taubin, mcf, npc, cell-size, cell-edge, diamond.
    pub method: Option<String>,
    pub iterations: Option<usize>,
    pub lambda: Option<f32>,
    pub mu: Option<f32>,
    pub alpha: Option<f32>,
    pub beta: Option<f32>,
    /// Relaxation stopping threshold (mm).
    pub threshold: Option<f32>,
    /// Voxel size [x, y, z] in mm (default: reconstructed from the mesh when needed).
    pub voxel: Option<[f32; 3]>,
    /// Staircase-aware weighting.
    pub staircase: Option<bool>,
    /// "auto" or [x, y, z].
    pub axis: Option<toml::Value>,
    /// "auto" or a number in [0, 1].
    pub tau: Option<toml::Value>,
    pub tau_max: Option<f32>,
    pub beta_min: Option<f32>,
    /// "preserve" or "smooth".
    pub caps: Option<String>,
    /// Structure names (in the same case) whose distance must be preserved.
    pub references: Option<Vec<String>>,
    /// "linear", "margin:MM", "exp:K", "ramp:D0,D1".
    pub distance_scaling: Option<String>,
    /// "product" or "min".
    pub combine: Option<String>,
    /// Let open-boundary vertices move.
    pub move_boundary: Option<bool>,
    /// Copy the structure unchanged (it can still be a reference).
    pub skip: Option<bool>,
    /// Fail a structure whose smoothing moved a vertex further than this many voxel diagonals.
    pub max_displacement_voxels: Option<f32>,
    /// Label-map structures: "constrained" (default) or "binary".
    pub surface: Option<String>,
    /// Label-map structures: Gaussian sigma of constrained surfaces (mm).
    pub sigma_mm: Option<f64>,
    /// Label-map structures: "smooth" (default) or "keep" one- and two-voxel bumps and pits.
    pub noise: Option<String>,
    /// Label-map structures: "protect" (default) or "off" for parts one voxel thick.
    pub thin: Option<String>,
    /// Label-map structures: 26 (default; voxels touching by a face, an edge or a corner are
    /// one object) or 6 (by a face only).
    pub connectivity: Option<toml::Value>,
    /// "cfd": ready the structure for a flow solver (patches held while smoothing, then
    /// extended, closed, remeshed and checked; patch files written); "none" (default).
    pub profile: Option<String>,
    /// cfd profile: remesh to this edge length (mm).
    pub edge_mm: Option<f64>,
    /// cfd profile: remesh to this multiple of the local vessel radius.
    pub edge_per_radius: Option<f64>,
    /// cfd profile: flow extensions of this many equivalent diameters.
    pub flow_extension: Option<f64>,
    /// cfd profile: patch ids that get a flow extension (default all).
    pub extend: Option<Vec<u32>>,
    /// cfd profile: close open ends with flat caps.
    pub close_open_ends: Option<bool>,
    /// cfd profile: keep patch rims as they are instead of smoothing them in their plane.
    pub keep_rims: Option<bool>,
    /// cfd profile: "largest", a patch index by decreasing area, or [x, y, z] (mm).
    pub inlet: Option<toml::Value>,
    /// cfd profile: the number of patches each matching structure has; another count fails.
    pub expect_patches: Option<usize>,
}

impl Settings {
    /// The cfd profile's keys that this table sets, for the check that some table turns the
    /// profile on.
    pub fn cfd_keys(&self) -> Vec<&'static str> {
        let set = [
            ("edge_mm", self.edge_mm.is_some()),
            ("edge_per_radius", self.edge_per_radius.is_some()),
            ("flow_extension", self.flow_extension.is_some()),
            ("extend", self.extend.is_some()),
            ("close_open_ends", self.close_open_ends.is_some()),
            ("keep_rims", self.keep_rims.is_some()),
            ("inlet", self.inlet.is_some()),
            ("expect_patches", self.expect_patches.is_some()),
        ];
        set.iter().filter(|(_, on)| *on).map(|(k, _)| *k).collect()
    }
}

/// One `[[structure]]` table: settings for structures whose name matches `pattern`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StructureConfig {
    /// Glob on the structure name (the mesh file stem), e.g. "vein*".
    pub pattern: String,
    #[serde(flatten)]
    pub settings: Settings,
}

/// `[guard]`: what smoothing may do to the distances between a case's structures.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GuardConfig {
    /// Largest loss of minimum distance a pair may suffer (mm; default 0.05).
    pub max_gap_loss_mm: Option<f64>,
    /// A pair that does not touch before smoothing must not touch after (default true).
    pub forbid_new_contacts: Option<bool>,
    /// Repair rounds before a case fails (default 4; 0 checks without repairing).
    pub max_repairs: Option<usize>,
    /// Check each smoothed structure for self-intersections (default true).
    pub self_intersections: Option<bool>,
    /// `[[guard.pair]]`: other limits for one pair of structures.
    #[serde(default, rename = "pair")]
    pub pairs: Vec<GuardPairConfig>,
}

/// `[[guard.pair]]`: limits for the pair of structures named `a` and `b` (either order).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GuardPairConfig {
    pub a: String,
    pub b: String,
    pub max_gap_loss_mm: Option<f64>,
    pub forbid_new_contacts: Option<bool>,
}

/// The whole configuration file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    pub input: InputConfig,
    pub output: OutputConfig,
    #[serde(default)]
    pub run: RunConfig,
    #[serde(default)]
    pub defaults: Settings,
    #[serde(default, rename = "structure")]
    pub structures: Vec<StructureConfig>,
    /// `[labels]`: structure names for label values of label maps (`1 = "tumor"`); they win
    /// over names in the files.
    #[serde(default)]
    pub labels: std::collections::BTreeMap<String, String>,
    #[serde(default)]
    pub guard: GuardConfig,
}

impl Config {
    /// Reads and parses a configuration file.
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let io = |source| ConfigError::Io {
            path: path.to_path_buf(),
            source,
        };
        // A device or FIFO would block or never end; a huge file is not a configuration.
        let meta = crate::io::check_regular_file(path).map_err(io)?;
        if meta.len() > MAX_CONFIG_BYTES {
            return Err(io(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("{} bytes is too large for a configuration file", meta.len()),
            )));
        }
        let text = std::fs::read_to_string(path).map_err(io)?;
        Self::parse(&text, path)
    }

    /// Parses configuration text; `path` is used in messages.
    pub fn parse(text: &str, path: &Path) -> Result<Config, ConfigError> {
        toml::from_str(text).map_err(|e| {
            let (line, column) = e.span().map_or((0, 0), |s| line_column(text, s.start));
            ConfigError::Syntax {
                path: path.to_path_buf(),
                line,
                column,
                message: e.message().to_string(),
            }
        })
    }
}

/// 1-based line and column of a byte offset.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    (line, column)
}
