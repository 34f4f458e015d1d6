//! The cfd profile after smoothing, as one step: flow extensions (if asked), open ends closed
//! by flat caps (if asked), the wall remeshed to the target with patch borders kept, the patches measured again on the
//! result, and every check passed, or an error with the reasons. Smoothing itself is the
//! caller's, with [`patch_vertices`] held fixed so caps stay planar and rims stay put.

use super::checks::{check_surface, SurfaceChecks};
use super::close::{close_open_ends, CloseError};
use super::extend::{add_flow_extensions, ExtendError};
use super::patches::{remeasure_patches, PatchKind, Patches};
use crate::mesh::{Mesh, Topology};
use crate::remesh::{remesh, RemeshError, RemeshParams};
use serde::Serialize;
use thiserror::Error;

/// What the profile does after smoothing.
#[derive(Debug, Clone, PartialEq)]
pub struct CfdParams {
    /// Flow extensions of this many equivalent diameters (none when `None`).
    pub flow_extension: Option<f64>,
    /// Patch ids that get a flow extension (every patch when empty).
    pub extend_patches: Vec<u32>,
    /// Close open ends with flat caps (otherwise they stay open patches).
    pub close_open_ends: bool,
    /// Remesh to this target (no remeshing when `None`).
    pub remesh: Option<RemeshParams>,
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
    #[error("the surface fails the cfd checks: {}", .0.join("; "))]
    Checks(Vec<String>),
}

/// What remeshing did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RemeshSummary {
    pub splits: usize,
    pub collapses: usize,
    pub flips: usize,
    /// Wall-clock time (s).
    pub seconds: f64,
}

/// A surface ready for a flow solver's mesher.
#[derive(Debug, Clone)]
pub struct CfdSurface {
    pub mesh: Mesh,
    /// Measured on `mesh`; `face_ids` are its `CellEntityIds`.
    pub patches: Patches,
    pub checks: SurfaceChecks,
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

/// Extends, closes, remeshes and checks `smoothed` (the vertices of `original`, moved), whose
/// patches `patches` were found on `original` (smoothing moves vertices, not faces, so the
/// face ids still hold). A vessel whose narrowest lumen smoothing halved fails.
pub fn finish_surface(
    original: &Mesh,
    smoothed: &Mesh,
    patches: &Patches,
    params: &CfdParams,
) -> Result<CfdSurface, CfdError> {
    // Measured on the smoothed surface first: open-end planes follow the smoothed rims.
    let topology = Topology::build(smoothed);
    let narrowed = super::checks::narrowing(original, smoothed, &topology);
    let measured = remeasure_patches(smoothed, &topology, patches.face_ids.clone(), patches);
    let (mesh, patches) = match params.flow_extension {
        Some(k) => add_flow_extensions(smoothed, &measured, k, &params.extend_patches)?,
        None => (smoothed.clone(), measured),
    };
    let (mesh, patches) = if params.close_open_ends {
        close_open_ends(&mesh, &patches)?
    } else {
        (mesh, patches)
    };
    let (mesh, patches, target, remeshed) = match &params.remesh {
        Some(rp) => {
            let started = std::time::Instant::now();
            let r = remesh(&mesh, &patches.face_ids, rp)?;
            let summary = RemeshSummary {
                splits: r.splits,
                collapses: r.collapses,
                flips: r.flips,
                seconds: started.elapsed().as_secs_f64(),
            };
            let topology = Topology::build(&r.mesh);
            let again = remeasure_patches(&r.mesh, &topology, r.face_ids, &patches);
            (r.mesh, again, Some(r.target_mm), Some(summary))
        }
        None => (mesh, patches, None, None),
    };
    let topology = Topology::build(&mesh);
    let open = patches.patches.iter().any(|p| p.kind == PatchKind::OpenEnd);
    let mut checks = check_surface(&mesh, &topology, open, target.as_deref());
    checks.narrowing = narrowed;
    let failures = checks.failures();
    if !failures.is_empty() {
        return Err(CfdError::Checks(failures));
    }
    Ok(CfdSurface {
        mesh,
        patches,
        checks,
        remeshed,
    })
}
