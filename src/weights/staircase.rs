//! Staircase weights (Moench 2010 §3, Moench 2012 §3.2): faces rated by orientation to the
//! stack axis, vertices by the change of that rating around them, staircase vertices above a
//! threshold, and every vertex weighted by its distance to the nearest staircase vertex measured
//! through the surface, so a part of the surface that merely passes close by gets nothing.

use super::VertexWeights;
use crate::mesh::geometry::face_normals;
use crate::mesh::{Mesh, Topology};
use rayon::prelude::*;
use serde::Serialize;

/// The orientation-change threshold above which a vertex is a staircase vertex.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Tau {
    /// This value (paper: 0.7).
    Fixed(f32),
    /// Chosen from the mesh's own distribution ([`auto_tau`]).
    Auto,
}

impl Serialize for Tau {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Tau::Fixed(t) => s.serialize_f32(*t),
            Tau::Auto => s.serialize_str("auto"),
        }
    }
}

impl std::str::FromStr for Tau {
    type Err = String;
    /// `auto` or a number in [0, 1].
    fn from_str(text: &str) -> Result<Tau, String> {
        if text.trim() == "auto" {
            return Ok(Tau::Auto);
        }
        match text.trim().parse::<f32>() {
            Ok(t) if (0.0..=1.0).contains(&t) => Ok(Tau::Fixed(t)),
            _ => Err(format!(
                "tau = {text:?} must be \"auto\" or a number in [0, 1]"
            )),
        }
    }
}

/// Lowest and highest threshold [`auto_tau`] chooses: 0.2 is the lowest the paper uses (for
/// caps rounded by 50 Laplace iterations), 0.7 its default for marching-cubes surfaces.
pub const AUTO_TAU_RANGE: (f32, f32) = (0.2, 0.7);

/// Standard deviations above the mean orientation change where [`auto_tau`] puts the threshold.
pub const AUTO_TAU_SIGMAS: f64 = 3.5;

/// The threshold for `tau = "auto"`: the mean orientation change of the mesh plus 3.5 standard
/// deviations, within [0.2, 0.7]. On a binary marching-cubes surface staircases make up a large
/// share of the vertices, the spread is wide and the rule gives the paper's 0.7 (every binary
/// phantom of `destair phantom` measured); on a surface from a smoothed image (or smoothed at export) the
/// bulk is the surface's own gentle variation and the threshold lands just above it, where
/// softened staircases stand out (Gaussian-filtered cut sphere: 0.42, the uncut one 0.37 with
/// no vertex above it). Summed in order, so the same for any thread count.
pub fn auto_tau(change: &[f32]) -> f32 {
    if change.is_empty() {
        return AUTO_TAU_RANGE.1;
    }
    let n = change.len() as f64;
    let mean = change.iter().map(|&c| c as f64).sum::<f64>() / n;
    let var = change
        .iter()
        .map(|&c| (c as f64 - mean).powi(2))
        .sum::<f64>()
        / n;
    let tau = (mean + AUTO_TAU_SIGMAS * var.sqrt()) as f32;
    tau.clamp(AUTO_TAU_RANGE.0, AUTO_TAU_RANGE.1)
}

/// The orientation change (theta, 0-1) at the vertices where a one-slice step leaves its
/// terrace, on a grid whose slice spacing is `ratio` times its in-plane spacing. Marching cubes
/// on a binary volume never meets a terrace with a wall at one vertex: the step's edge is a
/// chamfer across one voxel, with normal (1, 0, ratio) in voxel units, so the change there is
/// 1 - 1/sqrt(ratio^2 + 1): 0.85 on 0.45 x 0.45 x 3 mm slices, but 0.68 at ratio 3 and 0.55 at
/// ratio 2, below the paper's 0.7, where no staircase would be found at all.
pub fn slice_step_change(ratio: f64) -> f32 {
    (1.0 - 1.0 / (ratio * ratio + 1.0).sqrt()) as f32
}

/// How far below [`slice_step_change`] `auto` puts tau on a grid: the changes marching cubes
/// makes on a grid are a few discrete values, and this keeps the step's own clear of rounding.
pub const SLICE_STEP_MARGIN: f32 = 0.02;

/// Parameters of staircase weighting.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StaircaseParams {
    /// Orientation change above which a vertex is a staircase vertex (paper: 0.7; default
    /// `auto`, see [`auto_tau`]).
    pub tau: Tau,
    /// Reach of a staircase into its surroundings, along the surface (mm; paper: 3).
    pub tau_max_mm: f32,
    /// Weight floor, so artifact-free areas are still smoothed a little (paper: 0.1; 0 keeps them fixed).
    pub beta_min: f32,
    /// The orientation change where a one-slice step leaves its terrace, when the mesh lies on
    /// a grid with a slice axis ([`slice_step_change`]): `auto` keeps tau below it.
    #[serde(skip)]
    pub slice_step_change: Option<f32>,
}

impl Default for StaircaseParams {
    fn default() -> Self {
        Self {
            tau: Tau::Auto,
            tau_max_mm: 3.0,
            beta_min: 0.1,
            slice_step_change: None,
        }
    }
}

/// Staircase analysis of a mesh.
#[derive(Debug, Clone)]
pub struct StaircaseWeights {
    /// Final weights w' in [beta_min, 1].
    pub weights: VertexWeights,
    /// Vertices above the orientation-change threshold.
    pub is_staircase: Vec<bool>,
    /// Geodesic distance to the nearest staircase vertex (mm), infinite beyond tau_max.
    pub distance_mm: Vec<f32>,
    /// The threshold used (the given one, or the one [`auto_tau`] chose).
    pub tau: f32,
    /// Whether [`auto_tau`] chose it.
    pub tau_auto: bool,
}

impl StaircaseWeights {
    /// Number of staircase vertices.
    pub fn n_staircase(&self) -> usize {
        self.is_staircase.iter().filter(|&&s| s).count()
    }
}

/// Face orientation theta_f = 1 - |n_f . axis|: 1 for walls along the axis, 0 for terraces
/// across it; degenerate faces get 1 - 0 = 1 but are excluded from every vertex by topology.
pub fn face_orientation(mesh: &Mesh, axis: [f32; 3]) -> Vec<f32> {
    orientation_of(&face_normals(mesh), axis)
}

/// [`face_orientation`] from the unit face normals.
fn orientation_of(face_normals: &[[f32; 3]], axis: [f32; 3]) -> Vec<f32> {
    face_normals
        .par_iter()
        .map(|n| 1.0 - (n[0] * axis[0] + n[1] * axis[1] + n[2] * axis[2]).abs())
        .collect()
}

/// Orientation change per vertex: max - min of theta over its incident faces (0 if none).
pub fn orientation_change(topology: &Topology, theta: &[f32]) -> Vec<f32> {
    (0..topology.n_vertices())
        .into_par_iter()
        .map(|v| {
            let faces = topology.vertex_faces(v);
            if faces.is_empty() {
                return 0.0;
            }
            let (lo, hi) = faces
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &f| {
                    let t = theta[f as usize];
                    (lo.min(t), hi.max(t))
                });
            hi - lo
        })
        .collect()
}

/// Shortest distance along mesh edges from any source vertex, searched up to `limit` mm
/// (multi-source); vertices beyond stay infinite.
///
/// Label-correcting search over distance buckets about one mean edge long (delta-stepping,
/// sequential): a vertex is expanded again whenever its distance drops, and the search ends
/// when no edge can shorten a distance. Every such fixed point is the same (the least float sum
/// along any path, sums rounded step by step as here), so the result is bit for bit the one
/// Dijkstra's search gives, without a heap (which took most of the time, serial, on large meshes).
pub fn geodesic_distance(
    mesh: &Mesh,
    topology: &Topology,
    sources: &[bool],
    limit: f64,
) -> Vec<f32> {
    let p = mesh.positions();
    let n = mesh.n_vertices();
    let edge = |v: usize, u: usize| {
        let (pv, pu) = (p[v], p[u]);
        (0..3)
            .map(|k| (pu[k] as f64 - pv[k] as f64).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let (offsets, neighbors) = topology.neighbor_csr();
    let width = crate::mesh::order::sampled_mean_edge(p, offsets, neighbors);
    // Bucket of a distance; the last one takes everything beyond (still correct, only slower).
    const MAX_BUCKETS: usize = 1 << 16;
    let bucket_of = |d: f64| ((d / width) as usize).min(MAX_BUCKETS - 1);
    let mut dist = vec![f64::INFINITY; n];
    // The distance each vertex was last expanded at: a vertex queued twice at one distance is
    // expanded once.
    let mut expanded = vec![f64::NAN; n];
    let mut buckets: Vec<Vec<u32>> = vec![Vec::new()];
    for (v, _) in sources.iter().enumerate().filter(|(_, &s)| s) {
        dist[v] = 0.0;
        buckets[0].push(v as u32);
    }
    let mut current = 0;
    let mut queue = Vec::new();
    while current < buckets.len() {
        // Expanding may queue vertices in this bucket again: drain it until it stays empty.
        std::mem::swap(&mut queue, &mut buckets[current]);
        if queue.is_empty() {
            current += 1;
            continue;
        }
        for &v in &queue {
            let d = dist[v as usize];
            // Queued again since, at a shorter distance (in an earlier or this bucket).
            if bucket_of(d) != current || expanded[v as usize] == d {
                continue;
            }
            expanded[v as usize] = d;
            for &u in topology.neighbors(v as usize) {
                let nd = d + edge(v as usize, u as usize);
                if nd <= limit && nd < dist[u as usize] {
                    dist[u as usize] = nd;
                    let b = bucket_of(nd);
                    if b >= buckets.len() {
                        buckets.resize_with(b + 1, Vec::new);
                    }
                    buckets[b].push(u);
                }
            }
        }
        queue.clear();
    }
    dist.into_iter().map(|d| d as f32).collect()
}

/// Staircase weights for a mesh whose stack axis is `axis` (unit vector).
pub fn staircase_weights(
    mesh: &Mesh,
    topology: &Topology,
    axis: [f32; 3],
    params: &StaircaseParams,
) -> StaircaseWeights {
    staircase_weights_with(mesh, topology, &face_normals(mesh), axis, params)
}

/// [`staircase_weights`] from the mesh's unit face normals ([`face_normals`], computed once for
/// every analysis of the mesh).
pub fn staircase_weights_with(
    mesh: &Mesh,
    topology: &Topology,
    face_normals: &[[f32; 3]],
    axis: [f32; 3],
    params: &StaircaseParams,
) -> StaircaseWeights {
    let theta = orientation_of(face_normals, axis);
    let change = orientation_change(topology, &theta);
    let tau = match (params.tau, params.slice_step_change) {
        (Tau::Fixed(t), _) => t,
        (Tau::Auto, None) => auto_tau(&change),
        // On a grid: low enough to find the steps (but not below auto's floor).
        (Tau::Auto, Some(step)) => auto_tau(&change)
            .min(step - SLICE_STEP_MARGIN)
            .max(AUTO_TAU_RANGE.0),
    };
    let is_staircase: Vec<bool> = change.iter().map(|&c| c > tau).collect();
    let distance_mm = geodesic_distance(mesh, topology, &is_staircase, params.tau_max_mm as f64);
    // Scale by the largest distance reached (at most tau_max).
    let max_d = distance_mm
        .iter()
        .filter(|d| d.is_finite())
        .fold(0.0f32, |a, &d| a.max(d));
    let scale = params.tau_max_mm.min(max_d);
    let beta = params.beta_min.clamp(0.0, 1.0);
    let values: Vec<f32> = distance_mm
        .iter()
        .map(|&d| {
            let w = if !d.is_finite() {
                0.0
            } else if scale > 0.0 {
                (1.0 - d / scale).clamp(0.0, 1.0)
            } else {
                1.0
            };
            w * (1.0 - beta) + beta
        })
        .collect();
    StaircaseWeights {
        weights: VertexWeights::new(values, mesh.n_vertices())
            .unwrap_or_else(|_| VertexWeights::uniform(mesh.n_vertices())),
        is_staircase,
        distance_mm,
        tau,
        tau_auto: params.tau == Tau::Auto,
    }
}
