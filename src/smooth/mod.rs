//! The base smoothers the papers compare, each scaling its per-step displacement by a
//! per-vertex weight and leaving fixed vertices in place: Laplace (umbrella), Laplace+HC
//! (Vollmer 1999), Taubin lambda|mu (Taubin 1995), mean curvature flow with normalised cotangent
//! weights, Laplace with node-position constraint (Moench 2010), and the cell-size-, cell-edge-
//! and diamond-constrained relaxations of Bade 2007.
//!
//! All are Jacobi-style: every step reads the previous positions and writes a second buffer,
//! in parallel over vertex chunks, so results are bit-identical for any thread count. Buffers
//! are allocated once per call, never inside the iteration loop.

pub mod constraints;
mod hc;
mod laplace;
pub mod mcf;

pub use constraints::cell_edge_axes;

use crate::mesh::order::Renumbering;
use crate::mesh::umbrella::NeighbourLists;
use crate::mesh::{Mesh, Topology};
use crate::weights::VertexWeights;
use rayon::prelude::*;
use serde::Serialize;

/// Vertices per parallel task in the smoothing kernels (the umbrella operator's).
pub const CHUNK: usize = crate::mesh::umbrella::CHUNK;

/// A smoother and its parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "method", rename_all = "snake_case")]
pub enum Method {
    /// Umbrella operator: v += lambda w (mean(neighbours) - v).
    Laplace { lambda: f32 },
    /// Laplace followed by Vollmer's back-correction towards alpha o + (1 - alpha) q.
    Hc { lambda: f32, alpha: f32, beta: f32 },
    /// Alternating lambda and mu (< 0) umbrella steps; one iteration is one pair.
    Taubin { lambda: f32, mu: f32 },
    /// Explicit mean curvature flow with normalised, clamped cotangent weights.
    Mcf { lambda: f32 },
    /// Laplace, then each vertex clamped into the voxel-sized box around its original position.
    Npc { lambda: f32, voxel: [f32; 3] },
    /// Relaxation clipped to +-h/2 per axis around the original position (Bade 2007, §4.1).
    CellSize {
        lambda: f32,
        voxel: [f32; 3],
        threshold: f32,
    },
    /// Relaxation along each vertex's own grid edge only, +-h/2 (Bade 2007, §4.3).
    CellEdge {
        lambda: f32,
        voxel: [f32; 3],
        threshold: f32,
    },
    /// Relaxation clipped to the octahedron |dx|/hx + |dy|/hy + |dz|/hz <= 1/2 (Bade 2007, §4.4).
    Diamond {
        lambda: f32,
        voxel: [f32; 3],
        threshold: f32,
    },
}

impl Method {
    /// Whether the method iterates to convergence (then `iterations` is the maximum).
    pub fn is_relaxation(&self) -> bool {
        matches!(
            self,
            Method::CellSize { .. } | Method::CellEdge { .. } | Method::Diamond { .. }
        )
    }

    /// The method's short name as used on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            Method::Laplace { .. } => "laplace",
            Method::Hc { .. } => "hc",
            Method::Taubin { .. } => "taubin",
            Method::Mcf { .. } => "mcf",
            Method::Npc { .. } => "npc",
            Method::CellSize { .. } => "cell-size",
            Method::CellEdge { .. } => "cell-edge",
            Method::Diamond { .. } => "diamond",
        }
    }
}

/// A smoother by name, before its parameters are filled in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum MethodKind {
    Laplace,
    Hc,
    Taubin,
    Mcf,
    Npc,
    CellSize,
    CellEdge,
    Diamond,
}

impl std::str::FromStr for MethodKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        Ok(match s {
            "laplace" => MethodKind::Laplace,
            "hc" => MethodKind::Hc,
            "taubin" => MethodKind::Taubin,
            "mcf" => MethodKind::Mcf,
            "npc" => MethodKind::Npc,
            "cell-size" => MethodKind::CellSize,
            "cell-edge" => MethodKind::CellEdge,
            "diamond" => MethodKind::Diamond,
            other => {
                return Err(format!(
                    "unknown method {other:?} (laplace, hc, taubin, mcf, npc, cell-size, cell-edge, diamond)"
                ))
            }
        })
    }
}

/// Parameters common to the smoothers; `None` takes each method's default.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct MethodParams {
    /// Step factor (default 0.5; 1 for the constrained relaxations).
    pub lambda: Option<f32>,
    /// Taubin's negative factor (default -0.53).
    pub mu: Option<f32>,
    /// Laplace+HC alpha (default 0) and beta (default 0.5).
    pub alpha: Option<f32>,
    pub beta: Option<f32>,
    /// Relaxation stopping threshold in mm (default 0.002).
    pub threshold: Option<f32>,
}

impl MethodKind {
    /// Whether the method needs the voxel size.
    pub fn needs_voxel(self) -> bool {
        matches!(
            self,
            MethodKind::Npc | MethodKind::CellSize | MethodKind::CellEdge | MethodKind::Diamond
        )
    }

    /// The method with its parameters (defaults where not given); `voxel` in mm.
    pub fn build(self, p: &MethodParams, voxel: [f32; 3]) -> Method {
        let lambda = p.lambda.unwrap_or(0.5);
        let relax = p.lambda.unwrap_or(1.0);
        let threshold = p.threshold.unwrap_or(0.002);
        match self {
            MethodKind::Laplace => Method::Laplace { lambda },
            MethodKind::Hc => Method::Hc {
                lambda,
                alpha: p.alpha.unwrap_or(0.0),
                beta: p.beta.unwrap_or(0.5),
            },
            MethodKind::Taubin => Method::Taubin {
                lambda,
                mu: p.mu.unwrap_or(-0.53),
            },
            MethodKind::Mcf => Method::Mcf { lambda },
            MethodKind::Npc => Method::Npc { lambda, voxel },
            MethodKind::CellSize => Method::CellSize {
                lambda: relax,
                voxel,
                threshold,
            },
            MethodKind::CellEdge => Method::CellEdge {
                lambda: relax,
                voxel,
                threshold,
            },
            MethodKind::Diamond => Method::Diamond {
                lambda: relax,
                voxel,
                threshold,
            },
        }
    }

    /// Checks parameters against their meaningful ranges: lambda in (0, 1]; mu in [-1, 0) and,
    /// for Taubin, below -lambda (Taubin 1995 needs 0 < lambda < -mu); HC's alpha and beta in
    /// [0, 1]; a positive threshold (mm). Outside these the smoothers diverge or do nothing.
    pub fn check(self, p: &MethodParams) -> Result<(), String> {
        use crate::units::readable;
        let r = |x: f32| readable(x as f64);
        let defaults = self.build(&MethodParams::default(), [1.0; 3]);
        let lambda = p.lambda.unwrap_or(match defaults {
            Method::CellSize { lambda, .. }
            | Method::CellEdge { lambda, .. }
            | Method::Diamond { lambda, .. } => lambda,
            _ => 0.5,
        });
        if !(lambda > 0.0 && lambda <= 1.0) {
            return Err(format!("lambda = {} must lie in (0, 1]", r(lambda)));
        }
        // Keys a method does not use are still checked: a NaN or 1e30 is never meant.
        if let Some(mu) = p.mu {
            if !(-1.0..0.0).contains(&mu) {
                return Err(format!("mu = {} must lie in [-1, 0)", r(mu)));
            }
        }
        if self == MethodKind::Taubin {
            let mu = p.mu.unwrap_or(-0.53);
            if mu >= -lambda {
                return Err(format!(
                    "Taubin needs mu < -lambda: mu = {}, lambda = {} (set mu below {})",
                    r(mu),
                    r(lambda),
                    r(-lambda)
                ));
            }
        }
        for (name, v) in [("alpha", p.alpha), ("beta", p.beta)] {
            if let Some(x) = v {
                if !(0.0..=1.0).contains(&x) {
                    return Err(format!("{name} = {} must lie in [0, 1]", r(x)));
                }
            }
        }
        if let Some(t) = p.threshold {
            if !(t.is_finite() && t > 0.0) {
                return Err(format!(
                    "threshold = {} must be a positive size in mm",
                    r(t)
                ));
            }
        }
        Ok(())
    }

    /// The method's short name as used on the command line and in configs.
    pub fn name(self) -> &'static str {
        match self {
            MethodKind::Laplace => "laplace",
            MethodKind::Hc => "hc",
            MethodKind::Taubin => "taubin",
            MethodKind::Mcf => "mcf",
            MethodKind::Npc => "npc",
            MethodKind::CellSize => "cell-size",
            MethodKind::CellEdge => "cell-edge",
            MethodKind::Diamond => "diamond",
        }
    }

    /// Default iteration count (the maximum for relaxations).
    pub fn default_iterations(self) -> usize {
        if matches!(
            self,
            MethodKind::CellSize | MethodKind::CellEdge | MethodKind::Diamond
        ) {
            1000
        } else {
            20
        }
    }
}

/// Most iterations a run may ask for: far beyond any useful smoothing (the relaxations converge
/// within a few hundred), and a bound on how long one structure can take.
pub const MAX_ITERATIONS: usize = 100_000;

/// Checks an iteration count against 1..=[`MAX_ITERATIONS`].
pub fn check_iterations(n: usize) -> Result<usize, String> {
    if (1..=MAX_ITERATIONS).contains(&n) {
        Ok(n)
    } else {
        Err(format!(
            "{n} iterations: must be between 1 and {MAX_ITERATIONS}"
        ))
    }
}

/// What a smoothing run did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SmoothStats {
    /// Iterations run (pairs of steps for Taubin).
    pub iterations: usize,
    /// Largest distance a vertex moved in the last iteration (mm).
    pub last_max_step: f32,
    /// For relaxations: whether the last step fell below the threshold.
    pub converged: bool,
    /// Vertices that could not move (fixed mask, weight 0, or no grid edge for cell-edge).
    pub n_fixed: usize,
}

/// Smooths `mesh` with `method` for `iterations` steps (the maximum for relaxations), scaling
/// each vertex's displacement by its weight and keeping `fixed` vertices in place. Returns the
/// new positions (same order as the mesh) and what happened.
pub fn smooth(
    mesh: &Mesh,
    topology: &Topology,
    method: &Method,
    iterations: usize,
    weights: &VertexWeights,
    fixed: &[bool],
) -> (Vec<[f32; 3]>, SmoothStats) {
    let (scale, axes) = step_scales(mesh, topology, method, weights, fixed);
    // A scattered numbering makes every pass wait on memory: the umbrella kernels then run in
    // scanline order and their results are put back. Each vertex keeps its neighbours in
    // the same order, so the results are bit-identical. (Curvature flow reads faces as well and
    // runs in the mesh's own order.)
    let (offsets, neighbors) = topology.neighbor_csr();
    let renumbering = (!matches!(method, Method::Mcf { .. })
        && crate::mesh::order::is_scattered(offsets, neighbors))
    .then(|| crate::mesh::order::scanline(mesh.positions(), offsets, neighbors));
    let (positions, iterations, last_max_step, converged) = match &renumbering {
        Some(r) => {
            let axes = axes.as_deref().map(|a| r.gather(a));
            let (p, i, l, c) = run_method(
                mesh,
                topology,
                method,
                &r.gather(mesh.positions()),
                (offsets, neighbors, Some(r)),
                &r.gather(&scale),
                axes.as_deref(),
                iterations,
            );
            (r.scatter(&p), i, l, c)
        }
        None => run_method(
            mesh,
            topology,
            method,
            mesh.positions(),
            (offsets, neighbors, None),
            &scale,
            axes.as_deref(),
            iterations,
        ),
    };
    let stats = SmoothStats {
        iterations,
        last_max_step,
        converged,
        n_fixed: scale.iter().filter(|&&s| s == 0.0).count(),
    };
    (positions, stats)
}

/// Per-vertex step scale (the weight; 0 where fixed, isolated, or, for cell-edge, on no grid
/// edge) and, for cell-edge, each vertex's grid-edge axis.
pub fn step_scales(
    mesh: &Mesh,
    topology: &Topology,
    method: &Method,
    weights: &VertexWeights,
    fixed: &[bool],
) -> (Vec<f32>, Option<Vec<Option<u8>>>) {
    let n = mesh.n_vertices();
    let (offsets, _) = topology.neighbor_csr();
    let mut scale: Vec<f32> = crate::hugepages::with_capacity(n);
    (0..n)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|v| {
            let isolated = offsets[v] == offsets[v + 1];
            if fixed.get(v).copied().unwrap_or(false) || isolated {
                0.0
            } else {
                weights.as_slice()[v]
            }
        })
        .collect_into_vec(&mut scale);
    // Cell-edge moves each vertex along its own grid edge; vertices on none stay put.
    let axes = match *method {
        Method::CellEdge { voxel, .. } => {
            let axes = cell_edge_axes(mesh, voxel);
            for (s, a) in scale.iter_mut().zip(&axes) {
                if a.is_none() {
                    *s = 0.0;
                }
            }
            Some(axes)
        }
        _ => None,
    };
    (scale, axes)
}

/// Runs `method` on positions `original` and step scales `scale`, both in one numbering: the
/// mesh's own, or for every method but curvature flow (which reads the mesh's faces) the
/// renumbering given with the mesh's adjacency (CSR offsets and neighbours). Returns positions,
/// iterations run, the last largest step and whether a relaxation converged.
#[allow(clippy::too_many_arguments)]
pub fn run_method(
    mesh: &Mesh,
    topology: &Topology,
    method: &Method,
    original: &[[f32; 3]],
    (offsets, neighbors, renumbering): (&[u32], &[u32], Option<&Renumbering>),
    scale: &[f32],
    edge_axes: Option<&[Option<u8>]>,
    iterations: usize,
) -> (Vec<[f32; 3]>, usize, f32, bool) {
    // The umbrella kernels' adjacency, in the numbering of `original`.
    let rows = || NeighbourLists::new(offsets, neighbors, renumbering);
    match *method {
        Method::Laplace { lambda } => {
            let (p, s) = laplace::laplace(original, &rows(), scale, &[lambda], iterations, None);
            (p, iterations, s, false)
        }
        Method::Taubin { lambda, mu } => {
            let (p, s) =
                laplace::laplace(original, &rows(), scale, &[lambda, mu], iterations, None);
            (p, iterations, s, false)
        }
        Method::Npc { lambda, voxel } => {
            let (p, s) =
                laplace::laplace(original, &rows(), scale, &[lambda], iterations, Some(voxel));
            (p, iterations, s, false)
        }
        Method::Hc {
            lambda,
            alpha,
            beta,
        } => {
            let (p, s) = hc::hc(original, &rows(), scale, lambda, alpha, beta, iterations);
            (p, iterations, s, false)
        }
        Method::Mcf { lambda } => {
            let (p, s) = mcf::mcf(mesh, topology, scale, lambda, iterations);
            (p, iterations, s, false)
        }
        Method::CellSize {
            lambda,
            voxel,
            threshold,
        }
        | Method::CellEdge {
            lambda,
            voxel,
            threshold,
        }
        | Method::Diamond {
            lambda,
            voxel,
            threshold,
        } => {
            let region = match method {
                Method::Diamond { .. } => constraints::Region::Diamond(voxel),
                _ => constraints::Region::Box(voxel),
            };
            constraints::relax(
                original,
                &rows(),
                scale,
                lambda,
                region,
                edge_axes,
                threshold,
                iterations,
            )
        }
    }
}

/// The default fixed mask: vertices on open boundary loops (clipped vessel ends keep their rims).
pub fn boundary_vertices(topology: &Topology) -> Vec<bool> {
    let mut fixed = vec![false; topology.n_vertices()];
    for l in topology.boundary_loops() {
        for &v in &l.vertices {
            fixed[v as usize] = true;
        }
    }
    fixed
}

/// Largest per-vertex distance between two position buffers (mm); order-independent.
pub fn max_step<P: Xyz>(a: &[P], b: &[P]) -> f32 {
    a.par_chunks(CHUNK)
        .zip(b.par_chunks(CHUNK))
        .map(|(x, y)| {
            x.iter()
                .zip(y)
                .map(|(p, q)| {
                    let (p, q) = (p.xyz(), q.xyz());
                    let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
                    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
                })
                .fold(0.0f32, f32::max)
        })
        .reduce(|| 0.0, f32::max)
        .sqrt()
}

/// A position buffer's element: plain or padded (mm).
pub trait Xyz: Copy + Sync {
    fn xyz(self) -> [f32; 3];
}

impl Xyz for [f32; 3] {
    fn xyz(self) -> [f32; 3] {
        self
    }
}

impl Xyz for crate::mesh::umbrella::Padded {
    fn xyz(self) -> [f32; 3] {
        self.truncate().to_array()
    }
}

/// Default bound on how far smoothing may move a vertex, in voxel diagonals: staircase removal
/// moves vertices by a fraction of a voxel, so ten diagonals means the smoothing diverged.
pub const DEFAULT_MAX_DISPLACEMENT_VOXELS: f32 = 10.0;

/// The length (mm) that [`check_result`]'s bound is counted in: the voxel diagonal when the
/// voxel size is known, else two mean edge lengths (marching-cubes edges are h/2 to h long).
pub fn displacement_unit(
    mesh: &Mesh,
    topology: &Topology,
    voxel: Option<[f32; 3]>,
) -> (f64, &'static str) {
    if let Some(v) = voxel {
        let d = v.iter().map(|&x| (x as f64).powi(2)).sum::<f64>().sqrt();
        return (d, "voxel diagonals");
    }
    let p = mesh.positions();
    let edges = topology.edges();
    let total: f64 = crate::parallel::deterministic_sum(edges.len(), |i| {
        let [a, b] = edges[i];
        let (a, b) = (p[a as usize], p[b as usize]);
        (0..3)
            .map(|k| ((a[k] - b[k]) as f64).powi(2))
            .sum::<f64>()
            .sqrt()
    });
    let mean = if edges.is_empty() {
        1.0
    } else {
        total / edges.len() as f64
    };
    (
        2.0 * mean,
        "x 2 mean edge lengths (the voxel size is unknown)",
    )
}

/// Rejects a smoothing result that cannot be trusted: a non-finite coordinate, or a vertex moved
/// further than `max_units` times `unit` mm (see [`displacement_unit`]). The message names the
/// first such vertex (by its number in the file, for a mesh worked in a `renumbering`) and what
/// to change.
pub fn check_result(
    original: &[[f32; 3]],
    smoothed: &[[f32; 3]],
    max_units: f32,
    (unit_mm, unit_name): (f64, &str),
    renumbering: Option<&Renumbering>,
) -> Result<(), String> {
    use crate::units::readable;
    let limit = max_units as f64 * unit_mm;
    for (i, (a, b)) in original.iter().zip(smoothed).enumerate() {
        // Messages name the vertex as the file numbers it.
        let v = renumbering
            .and_then(|r| r.old.get(i))
            .map_or(i, |&o| o as usize);
        if b.iter().any(|c| !c.is_finite()) {
            return Err(format!(
                "smoothing diverged: vertex {v} has a non-finite coordinate; lower lambda or the iterations"
            ));
        }
        let d = (0..3)
            .map(|k| ((a[k] - b[k]) as f64).powi(2))
            .sum::<f64>()
            .sqrt();
        if d > limit {
            return Err(format!(
                "smoothing moved vertex {v} by {} mm, more than {} {unit_name} ({} mm): the result is not a smoothed surface; lower lambda or the iterations (or raise max_displacement_voxels)",
                readable(d),
                readable(max_units as f64),
                readable(limit)
            ));
        }
    }
    Ok(())
}
