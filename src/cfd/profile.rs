//! The cfd profile around the caller's smoothing, in two steps. Before: the patches found and
//! their rims smoothed in their planes unless kept ([`prepare_surface`]); smoothing then holds
//! the patch vertices, so caps stay planar and rims stay put. After ([`finish_surface`]): flow
//! extensions (if asked), open ends closed by flat caps (if asked), the wall remeshed to the
//! target with patch borders kept, the patches measured again on the result, and every check
//! passed, or an error with the reasons.

use super::checks::{check_surface, SurfaceChecks};
use super::close::{close_open_ends, CloseError};
use super::extend::{add_flow_extensions, ExtendError};
use super::patches::{find_patches, remeasure_patches, Inlet, PatchError, PatchKind, Patches};
use super::rims::{smooth_rims, RimSmoothing};
use crate::mesh::{Mesh, Topology};
use crate::metrics::distance::surface_distance;
use crate::remesh::{remesh, EdgeTarget, RemeshError, RemeshParams};
use crate::spatial::TriangleBvh;
use serde::Serialize;
use std::borrow::Cow;
use thiserror::Error;

/// Longest flow extension accepted (equivalent diameters): beyond it a typo, not a choice.
pub const MAX_FLOW_EXTENSION: f64 = 100.0;

/// What the profile does after smoothing.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CfdParams {
    /// Flow extensions of this many equivalent diameters (none when `None`).
    pub flow_extension: Option<f64>,
    /// Patch ids that get a flow extension (every patch when empty).
    pub extend_patches: Vec<u32>,
    /// Close open ends with flat caps (otherwise they stay open patches).
    pub close_open_ends: bool,
    /// Keep the rims as the input has them instead of smoothing them in their patch's plane
    /// ([`super::rims`]).
    pub keep_rims: bool,
    /// Remesh to this target (no remeshing when `None`).
    pub remesh: Option<RemeshParams>,
}

/// The cfd profile of one structure, as a cohort config or the command line gives it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CfdProfile {
    pub inlet: Inlet,
    /// The number of patches the vessel must have; another count fails it.
    pub expect_patches: Option<usize>,
    #[serde(flatten)]
    pub finish: CfdParams,
}

/// The profile's settings as given, before they are checked (`edge_mm` and `edge_per_radius`
/// exclude each other).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CfdOptions {
    pub inlet: Option<Inlet>,
    pub expect_patches: Option<usize>,
    /// Remesh to this edge length (mm).
    pub edge_mm: Option<f64>,
    /// Remesh to this multiple of the local vessel radius.
    pub edge_per_radius: Option<f64>,
    /// Flow extensions of this many equivalent diameters.
    pub flow_extension: Option<f64>,
    /// Patch ids that get an extension (all when empty).
    pub extend: Vec<u32>,
    pub close_open_ends: bool,
    pub keep_rims: bool,
}

impl CfdProfile {
    /// Checks `options`; the message names the setting (by its config key) that is wrong.
    pub fn new(options: CfdOptions) -> Result<CfdProfile, String> {
        let positive = |name: &str, v: Option<f64>| match v {
            Some(x) if !(x.is_finite() && x > 0.0) => {
                Err(format!("{name} = {x} must be a positive number"))
            }
            _ => Ok(()),
        };
        positive("edge_mm", options.edge_mm)?;
        positive("edge_per_radius", options.edge_per_radius)?;
        positive("flow_extension", options.flow_extension)?;
        if let Some(k) = options.flow_extension.filter(|&k| k > MAX_FLOW_EXTENSION) {
            return Err(format!(
                "flow_extension = {k} diameters is longer than {MAX_FLOW_EXTENSION}"
            ));
        }
        let edge = match (options.edge_mm, options.edge_per_radius) {
            (Some(_), Some(_)) => {
                return Err("edge_mm and edge_per_radius exclude each other: give one".into())
            }
            (Some(mm), None) => Some(EdgeTarget::Mm(mm)),
            (None, Some(k)) => Some(EdgeTarget::PerRadius(k)),
            (None, None) => None,
        };
        if !options.extend.is_empty() && options.flow_extension.is_none() {
            return Err("extend names patches for flow extensions: set flow_extension too".into());
        }
        if let Some(&id) = options.extend.iter().find(|&&id| id < 2) {
            return Err(format!(
                "extend: {id} is not a patch id (the wall is 1, patches start at 2)"
            ));
        }
        if options.expect_patches == Some(0) {
            return Err("expect_patches = 0: a vessel has at least one end".into());
        }
        Ok(CfdProfile {
            inlet: options.inlet.unwrap_or(Inlet::Largest),
            expect_patches: options.expect_patches,
            finish: CfdParams {
                flow_extension: options.flow_extension,
                extend_patches: options.extend,
                close_open_ends: options.close_open_ends,
                keep_rims: options.keep_rims,
                remesh: edge.map(|edge| RemeshParams {
                    edge,
                    ..RemeshParams::uniform(1.0)
                }),
            },
        })
    }
}

/// Refuses flow extensions of `diameters` equivalent diameters whose walls alone would make
/// more than `budget` faces: each extension's wall (circumference times length) over an
/// equilateral triangle of the finer of the target edge there and the input's mean edge (an
/// extension is built at the rim's own edge before any remeshing).
fn check_extension_size(
    original: &Mesh,
    patches: &Patches,
    diameters: f64,
    params: &CfdParams,
    budget: u64,
) -> Result<(), CfdError> {
    let area = crate::mesh::geometry::area(original);
    let input_edge = (4.0 * area / (3f64.sqrt() * original.n_triangles().max(1) as f64)).sqrt();
    let mut estimated = 0.0;
    let mut smallest = f64::INFINITY;
    for p in patches
        .patches
        .iter()
        .filter(|p| params.extend_patches.is_empty() || params.extend_patches.contains(&p.id))
    {
        let target = match params.remesh.as_ref().map(|r| (&r.edge, r.clamp_mm)) {
            Some((crate::remesh::EdgeTarget::Mm(e), _)) => *e,
            Some((crate::remesh::EdgeTarget::PerRadius(f), (lo, hi))) => {
                (f * p.diameter_mm / 2.0).clamp(lo, hi)
            }
            None => input_edge,
        };
        let edge = target.min(input_edge);
        smallest = smallest.min(edge);
        let wall = std::f64::consts::PI * p.diameter_mm * diameters * p.diameter_mm;
        estimated += wall / (3f64.sqrt() / 4.0 * edge * edge);
    }
    let within = estimated <= budget as f64;
    if !within {
        return Err(CfdError::ExtensionTooLarge {
            diameters,
            estimated: if estimated.is_finite() {
                estimated.round() as u64
            } else {
                u64::MAX
            },
            edge_mm: smallest,
            input: original.n_triangles(),
            limit: budget,
        });
    }
    Ok(())
}

/// Why a surface was not made ready for a solver.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CfdError {
    #[error(transparent)]
    Close(#[from] CloseError),
    #[error(transparent)]
    Extend(#[from] ExtendError),
    #[error(transparent)]
    Remesh(#[from] RemeshError),
    #[error(
        "flow extensions of {diameters} diameters would make about {estimated} faces (edges down \
         to {edge_mm:.3} mm) for a surface of {input}, more than the {limit} allowed ({} times \
         its faces, at least {}): shorten them, or ask for longer edges",
        crate::remesh::sizing::GROWTH_BUDGET,
        crate::remesh::sizing::MIN_BUDGET
    )]
    ExtensionTooLarge {
        diameters: f64,
        estimated: u64,
        edge_mm: f64,
        input: usize,
        limit: u64,
    },
    #[error("the surface fails the cfd checks: {}", .0.join("; "))]
    Checks(Vec<String>),
}

/// What remeshing did, and how far the remeshed surface lies from the one it remeshed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RemeshSummary {
    pub splits: usize,
    pub collapses: usize,
    pub flips: usize,
    /// Vertices put onto dimples and bumps the remeshed surface would otherwise stand off.
    pub covered: usize,
    /// Hausdorff distance between the surface before and after remeshing (mm).
    pub hausdorff_mm: f64,
    /// Mean vertex-to-surface distance between them, both ways (mm).
    pub mean_distance_mm: f64,
    /// Wall-clock time of the remeshing alone (s); not serialized, as reports are
    /// deterministic.
    #[serde(skip)]
    pub seconds: f64,
}

/// A surface ready for a flow solver's mesher.
#[derive(Debug, Clone)]
pub struct CfdSurface {
    pub mesh: Mesh,
    /// Measured on `mesh`; `face_ids` are its `CellEntityIds`.
    pub patches: Patches,
    pub checks: SurfaceChecks,
    /// What smoothing the rims did (`None` with `keep_rims`).
    pub rims: Option<RimSmoothing>,
    pub remeshed: Option<RemeshSummary>,
}

/// Vertices the smoother must hold for the profile: every cap's vertices and every open end's
/// rim.
pub fn patch_vertices(patches: &Patches, n_vertices: usize) -> Vec<bool> {
    let mut fixed = vec![false; n_vertices];
    for p in &patches.patches {
        for &v in &p.vertices {
            if let Some(f) = fixed.get_mut(v as usize) {
                *f = true;
            }
        }
    }
    fixed
}

/// A vessel ready to be smoothed for the profile.
#[derive(Debug, Clone)]
pub struct PreparedSurface {
    /// Found on the input, with the inlet and count the profile asks for.
    pub patches: Patches,
    /// The input with its rims smoothed in their planes (unless the profile keeps them): what
    /// smoothing starts from, so the wall next to a rim follows the smoothed rim.
    pub start: Mesh,
    /// The vertices smoothing must hold ([`patch_vertices`]).
    pub held: Vec<bool>,
    pub rims: Option<RimSmoothing>,
}

/// Finds the patches of `mesh` (`topology` built from it) and smooths their rims in their
/// planes: the first step of the profile, before the caller's smoothing.
pub fn prepare_surface(
    mesh: &Mesh,
    topology: &Topology,
    profile: &CfdProfile,
) -> Result<PreparedSurface, PatchError> {
    let patches = find_patches(mesh, topology, profile.inlet, profile.expect_patches)?;
    let held = patch_vertices(&patches, mesh.n_vertices());
    let (start, rims) = if profile.finish.keep_rims {
        (mesh.clone(), None)
    } else {
        let (m, r) = smooth_rims(mesh, &patches);
        (m, Some(r))
    };
    Ok(PreparedSurface {
        patches,
        start,
        held,
        rims,
    })
}

/// Extends, closes, remeshes and checks `smoothed` (the vertices of `original`, moved, from
/// `prepared.start`), whose patches were found on `original` (smoothing moves vertices, not
/// faces, so the face ids still hold). A vessel whose narrowest lumen smoothing halved fails.
pub fn finish_surface(
    original: &Mesh,
    smoothed: &Mesh,
    prepared: &PreparedSurface,
    params: &CfdParams,
) -> Result<CfdSurface, CfdError> {
    // Measured on the smoothed surface first: open-end planes follow the smoothed rims.
    let patches = &prepared.patches;
    let topology = Topology::build(smoothed);
    let narrowed = super::checks::narrowing(original, smoothed, &topology);
    let measured = remeasure_patches(smoothed, &topology, patches.face_ids.clone(), patches);
    // Work is bounded by the structure as it came in: every step together may make at most
    // `face_budget` of its faces, which flow extensions count against before they are built.
    let budget = crate::remesh::sizing::face_budget(original.n_triangles());
    if let Some(k) = params.flow_extension {
        check_extension_size(original, &measured, k, params, budget)?;
    }
    let remesh_params = params.remesh.map(|mut rp| {
        rp.max_faces.get_or_insert(budget);
        rp
    });
    // Borrowed until a step makes a new mesh; the topology is built once per mesh.
    let (mesh, patches): (Cow<Mesh>, Patches) = match params.flow_extension {
        Some(k) => {
            let (m, p) = add_flow_extensions(smoothed, &measured, k, &params.extend_patches)?;
            (Cow::Owned(m), p)
        }
        None => (Cow::Borrowed(smoothed), measured),
    };
    let (mesh, patches) = if params.close_open_ends {
        let (m, p) = close_open_ends(&mesh, &patches)?;
        (Cow::Owned(m), p)
    } else {
        (mesh, patches)
    };
    let (mesh, patches, topology, target, remeshed) = match &remesh_params {
        Some(rp) => {
            let started = std::time::Instant::now();
            let r = remesh(&mesh, &patches.face_ids, rp)?;
            let seconds = started.elapsed().as_secs_f64();
            let distance = surface_distance(
                &r.mesh,
                &TriangleBvh::build(&r.mesh),
                &mesh,
                &TriangleBvh::build(&mesh),
            );
            let summary = RemeshSummary {
                splits: r.splits,
                collapses: r.collapses,
                flips: r.flips,
                covered: r.covered,
                hausdorff_mm: distance.hausdorff_mm,
                mean_distance_mm: distance.mean_mm,
                seconds,
            };
            let topology = Topology::build(&r.mesh);
            let again = remeasure_patches(&r.mesh, &topology, r.face_ids, &patches);
            let target = Some(r.target_mm);
            (Cow::Owned(r.mesh), again, topology, target, Some(summary))
        }
        None => {
            let topology = match mesh {
                Cow::Borrowed(_) => topology,
                Cow::Owned(ref m) => Topology::build(m),
            };
            (mesh, patches, topology, None, None)
        }
    };
    let open = patches.patches.iter().any(|p| p.kind == PatchKind::OpenEnd);
    let mut checks = check_surface(&mesh, &topology, open, target.as_deref());
    checks.narrowing = narrowed;
    let failures = checks.failures();
    if !failures.is_empty() {
        return Err(CfdError::Checks(failures));
    }
    Ok(CfdSurface {
        mesh: mesh.into_owned(),
        patches,
        checks,
        rims: prepared.rims.clone(),
        remeshed,
    })
}
