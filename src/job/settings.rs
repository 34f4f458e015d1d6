//! One structure's effective settings: a `[defaults]` table with every matching `[[structure]]`
//! laid over it key by key, checked and resolved into [`StructureSettings`] with defaults
//! filled in, and shown back in the config's own syntax (`destair check`).

use super::config::Settings;
use crate::cfd::{CfdOptions, CfdProfile, Inlet};
use crate::extract::constrained::{LabelSmoothing, Noise, Surface, Thin};
use crate::extract::Connectivity;
use crate::smooth::{MethodKind, MethodParams};
use crate::weights::{
    AxisChoice, CapPolicy, Combine, ContextParams, DistanceScaling, StaircaseParams, Tau,
};
use serde::Serialize;

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
        let tau = match c.staircase_params.tau {
            Tau::Auto => Value::String("auto".into()),
            Tau::Fixed(x) => f(x),
        };
        t.push(("tau", tau));
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
        t.push((
            "connectivity",
            Value::Integer(e.connectivity.number().into()),
        ));
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
        text.push_str(
            "# surface, sigma_mm, noise, thin, connectivity: structures made from label maps\n",
        );
        text
    }
}

/// Later settings override earlier ones key by key.
pub fn overlay(base: &Settings, over: &Settings) -> Settings {
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
        connectivity,
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
pub fn resolve(s: &Settings) -> Result<StructureSettings, String> {
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
        tau: match &s.tau {
            None => defaults.tau,
            Some(toml::Value::String(text)) => text.parse()?,
            Some(v) => match v.as_float().or(v.as_integer().map(|i| i as f64)) {
                Some(x) => Tau::Fixed(unit("tau", Some(x as f32))?.unwrap_or(0.0)),
                None => return Err(format!("tau = {v} must be \"auto\" or a number in [0, 1]")),
            },
        },
        tau_max_mm: positive("tau_max", s.tau_max)?.unwrap_or(defaults.tau_max_mm),
        beta_min: unit("beta_min", s.beta_min)?.unwrap_or(defaults.beta_min),
        slice_step_change: None,
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
        connectivity: match &s.connectivity {
            None => Connectivity::Corners,
            Some(v) => match (v.as_integer(), v.as_str()) {
                (Some(26), _) | (_, Some("26")) => Connectivity::Corners,
                (Some(6), _) | (_, Some("6")) => Connectivity::Faces,
                _ => {
                    return Err(format!(
                        "connectivity = {v} must be 26 (voxels touching by a face, an edge or a corner are one object) or 6 (by a face only)"
                    ))
                }
            },
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
            find_smoothed_caps: true,
            measure_curvature: false,
            cap_params: Default::default(),
            grid_mm: None,
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
