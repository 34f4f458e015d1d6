//! Context-aware weights: staircase weights along the (estimated or given) stack axis, caps
//! preserved or smoothed, and distance weights from reference structures, combined into one
//! weight per vertex (Moench 2010, 2012; Moench et al. 2010).

use super::staircase::{slice_step_change, staircase_weights_with};
use super::{
    distance_weights, Combine, DistanceScaling, StaircaseParams, StaircaseWeights, VertexWeights,
};
use crate::analysis::{
    stack_axis_with, turned_grid, CapCandidates, CapDetection, CapParams, CapSearch, Grid,
    StackAxis, StackAxisParams,
};
use crate::mesh::geometry::dot64;
use crate::mesh::order::{is_scattered, scanline, with_working_faces, Renumbering};
use crate::mesh::{Mesh, Topology};
use crate::metrics::normal_curvature::TurnLimits;
use crate::spatial::TriangleBvh;
use serde::{Deserialize, Serialize};

/// Where the stack axis comes from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisChoice {
    /// Estimated from the mesh (Moench 2012, §3.1).
    Auto,
    /// Given (need not be normalised).
    Given([f32; 3]),
}

/// Where the stack axis used came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisSource {
    /// Given in the configuration or on the command line.
    Given,
    /// The coarse axis of the voxel grid, known (a label map's header) or reconstructed from
    /// the mesh on an axis-aligned grid (Bade 2007, §3.2).
    Grid,
    /// The Gauss-map estimate (Moench 2012, §3.1) on an isotropic grid, set to the grid axis
    /// nearest to it: on a grid, staircases only ever face its axes.
    EstimateOnGrid,
    /// The Gauss-map estimate: the grid is unknown or rotated.
    Estimated,
    /// No grid to read it from and too little flat area to estimate it.
    TooWeak,
    /// Staircase weighting is off.
    Off,
}

impl AxisSource {
    /// The name reports use.
    pub fn name(self) -> &'static str {
        match self {
            AxisSource::Given => "given",
            AxisSource::Grid => "grid",
            AxisSource::EstimateOnGrid => "estimate_on_grid",
            AxisSource::Estimated => "estimated",
            AxisSource::TooWeak => "too_weak",
            AxisSource::Off => "off",
        }
    }
}

/// What happens to detected caps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CapPolicy {
    /// Weight 0: caps (CFD inlets and outlets) keep their exact shape.
    #[default]
    Preserve,
    /// Caps are weighted like the rest of the surface.
    Smooth,
}

/// Everything that decides the weights.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContextParams {
    /// Weight by staircases (off: staircases play no part).
    pub staircase: bool,
    pub axis: AxisChoice,
    pub staircase_params: StaircaseParams,
    pub caps: CapPolicy,
    /// Look for caps when `caps` is [`CapPolicy::Smooth`] too, for reports and pictures (on by
    /// default). `smooth` turns it off: caps smoothed like the rest change nothing it writes.
    #[serde(skip)]
    pub find_smoothed_caps: bool,
    /// Also find the mesh's average normal curvature ([`Context::average_normal_curvature_deg`])
    /// in the walk the flat-vertex tests make, for an inspect report (off by default: it costs
    /// visiting every face of every vertex).
    #[serde(skip)]
    pub measure_curvature: bool,
    pub cap_params: CapParams,
    /// The voxel size (mm along the mesh's x, y, z) when it is known from elsewhere (a label
    /// map's header, with the mesh in its grid's frame); otherwise it is reconstructed from
    /// the mesh where the mesh lies on an axis-aligned grid.
    #[serde(skip)]
    pub grid_mm: Option<[f32; 3]>,
    /// Scaling of the distances to the reference structures (used when references are given).
    pub distance_scaling: DistanceScaling,
    pub combine: Combine,
}

impl Default for ContextParams {
    fn default() -> Self {
        Self {
            staircase: true,
            axis: AxisChoice::Auto,
            staircase_params: StaircaseParams::default(),
            caps: CapPolicy::Preserve,
            find_smoothed_caps: true,
            measure_curvature: false,
            cap_params: CapParams::default(),
            grid_mm: None,
            distance_scaling: DistanceScaling::Linear,
            combine: Combine::Product,
        }
    }
}

/// The analysis behind the weights, for reports.
#[derive(Debug, Clone)]
pub struct Context {
    /// The Gauss-map estimate of the axis (None when the axis was given or staircases are off).
    pub estimated_axis: Option<StackAxis>,
    /// Where the axis used came from.
    pub axis_source: AxisSource,
    /// Bounds (smallest, largest; mm) on the voxel size along x, y, z (or along `grid_axes`):
    /// known, or reconstructed from the mesh; None when the mesh lies on no grid found.
    pub grid_mm: Option<[(f64, f64); 3]>,
    /// The unit axes (rows) of the grid the mesh lies on when they are not x, y, z: a grid
    /// turned off the axes, found from the mesh's flat faces.
    pub grid_axes: Option<[[f64; 3]; 3]>,
    /// Angle (degrees) between the axis used and the Gauss-map estimate, when the axis came
    /// from the grid and the estimate found one.
    pub estimate_off_deg: Option<f64>,
    /// The axis used for staircase weighting, if any.
    pub axis: Option<[f32; 3]>,
    pub staircase: Option<StaircaseWeights>,
    pub caps: CapDetection,
    /// Minimum distance per vertex to the references (mm), when references were given.
    pub reference_distance_mm: Option<Vec<f64>>,
    /// The final weights.
    pub weights: VertexWeights,
    /// The mesh's average normal curvature (degrees) as
    /// [`average_normal_curvature`](crate::metrics::average_normal_curvature) gives it to the
    /// bit, found in the walk over every vertex's angles that the flat-vertex tests make, when
    /// [`ContextParams::measure_curvature`] asks for it; None otherwise, when caps were not
    /// looked for, or when the mesh was analysed in another numbering (whose sum would round
    /// differently).
    pub average_normal_curvature_deg: Option<f64>,
}

impl Context {
    /// The context of a mesh renumbered by `order`, in the mesh's own numbering of vertices
    /// and faces.
    fn numbered_back(mut self, order: &Renumbering) -> Context {
        self.average_normal_curvature_deg = None;
        self.weights = self.weights.scattered(order);
        if let Some(s) = &mut self.staircase {
            s.weights = s.weights.scattered(order);
            s.is_staircase = order.scatter(&s.is_staircase);
            s.distance_mm = order.scatter(&s.distance_mm);
        }
        for cap in &mut self.caps.caps {
            for v in &mut cap.vertices {
                *v = order.old[*v as usize];
            }
            if let Some(faces) = &order.faces {
                for f in &mut cap.faces {
                    *f = faces.file_index[*f as usize];
                }
                // Ascending, as detection lists them in the order it ran in.
                cap.faces.sort_unstable();
            }
        }
        if let Some(d) = &mut self.reference_distance_mm {
            *d = order.scatter(d);
        }
        self
    }

    /// Per-vertex arrays for viewers and pictures: `weight`, `staircase` and `cap` (1 on, 0
    /// off), `staircase_distance` (mm, -1 where no staircase is within reach) and, with
    /// references, `reference_distance` (mm).
    pub fn vertex_arrays(&self, n_vertices: usize) -> Vec<(&'static str, Vec<f32>)> {
        let flag = |on: bool| if on { 1.0 } else { 0.0 };
        let staircase: Vec<f32> = (0..n_vertices)
            .map(|v| flag(self.staircase.as_ref().is_some_and(|s| s.is_staircase[v])))
            .collect();
        let cap: Vec<f32> = self
            .caps
            .cap_vertices(n_vertices)
            .into_iter()
            .map(flag)
            .collect();
        let stair_distance: Vec<f32> = (0..n_vertices)
            .map(|v| match &self.staircase {
                Some(s) if s.distance_mm[v].is_finite() => s.distance_mm[v],
                _ => -1.0,
            })
            .collect();
        let mut out = vec![
            ("weight", self.weights.as_slice().to_vec()),
            ("staircase", staircase),
            ("cap", cap),
            ("staircase_distance", stair_distance),
        ];
        if let Some(d) = &self.reference_distance_mm {
            out.push(("reference_distance", d.iter().map(|&x| x as f32).collect()));
        }
        out
    }
}

/// Computes context-aware weights for a mesh; `references` are the structures whose distance
/// must be preserved (empty for none). A mesh whose numbering is scattered (see
/// [`is_scattered`]) is analysed in scanline order, about twice as fast, and one whose faces
/// are listed in a scattered order with its faces sorted by vertex ([`with_working_faces`]);
/// the results are put back in its own numbering. They then match an analysis in its own order
/// to float rounding (sums over neighbours run in another order), not bit for bit.
pub fn context_weights(
    mesh: &Mesh,
    topology: &Topology,
    params: &ContextParams,
    references: &[&TriangleBvh],
) -> Context {
    let (offsets, neighbors) = topology.neighbor_csr();
    let vertices =
        is_scattered(offsets, neighbors).then(|| scanline(mesh.positions(), offsets, neighbors));
    let Some(order) = with_working_faces(mesh, vertices) else {
        return context_in_mesh_order(mesh, topology, params, references);
    };
    let local = order.mesh(mesh);
    let local_topology = Topology::build(&local);
    context_in_mesh_order(&local, &local_topology, params, references).numbered_back(&order)
}

/// The estimated stack axis (none when given or without staircase weighting), where the axis
/// used came from, the axis used (unit) and the staircase weights along it.
type Staircases = (
    Option<StackAxis>,
    AxisSource,
    Option<[f32; 3]>,
    Option<StaircaseWeights>,
);

/// The stack axis (from the grid, estimated, or given and normalised; none without staircase
/// weighting) and the staircase weights along it. `grid` is the voxel grid the mesh lies on,
/// when known or found.
fn staircases(
    mesh: &Mesh,
    topology: &Topology,
    turns: &TurnLimits,
    params: &ContextParams,
    axis_params: &StackAxisParams,
    grid: Option<Grid>,
) -> Staircases {
    let (estimated_axis, source, axis) = if !params.staircase {
        (None, AxisSource::Off, None)
    } else {
        match params.axis {
            AxisChoice::Given(a) => {
                let len = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
                (
                    None,
                    AxisSource::Given,
                    (len > 0.0 && len.is_finite()).then(|| a.map(|x| x / len)),
                )
            }
            AxisChoice::Auto => {
                let est = stack_axis_with(turns, axis_params);
                let (source, axis) = axis_on_grid(est.axis(), grid);
                (Some(est), source, axis)
            }
        }
    };
    let staircase = axis.map(|a| {
        let normals = turns.face_normals();
        staircase_weights_with(mesh, topology, normals, a, &params.staircase_params)
    });
    (estimated_axis, source, axis, staircase)
}

/// The stack axis a grid and an estimate give together: the grid's coarse axis when it has
/// one; on an isotropic grid the grid axis nearest to the estimate; off any grid the estimate.
fn axis_on_grid(estimate: Option<[f64; 3]>, grid: Option<Grid>) -> (AxisSource, Option<[f32; 3]>) {
    let along = |g: Grid, k: usize| g.axes[k].map(|x| x as f32);
    if let Some(g) = grid {
        if let Some(k) = crate::analysis::coarse_axis(g.spacing_mm) {
            return (AxisSource::Grid, Some(along(g, k)));
        }
    }
    match (grid, estimate) {
        (Some(g), Some(e)) => {
            let cos = |k: usize| dot64(g.axes[k], e).abs();
            let k = (0..3)
                .max_by(|&i, &j| cos(i).total_cmp(&cos(j)))
                .unwrap_or(2);
            (AxisSource::EstimateOnGrid, Some(along(g, k)))
        }
        (None, Some(e)) => (AxisSource::Estimated, Some(e.map(|x| x as f32))),
        (_, None) => (AxisSource::TooWeak, None),
    }
}

/// How many times its in-plane spacing a grid's slice spacing is at least (the smallest the
/// spacing bounds allow), when it has a slice axis.
fn slice_ratio(grid: Grid) -> Option<f64> {
    let k = crate::analysis::coarse_axis(grid.spacing_mm)?;
    let in_plane = (0..3)
        .filter(|&j| j != k)
        .map(|j| grid.spacing_mm[j].1)
        .fold(0.0, f64::max);
    (in_plane > 0.0).then(|| grid.spacing_mm[k].0 / in_plane)
}

/// [`context_weights`] in the mesh's own numbering, whatever it is.
pub fn context_in_mesh_order(
    mesh: &Mesh,
    topology: &Topology,
    params: &ContextParams,
    references: &[&TriangleBvh],
) -> Context {
    let axis_params = StackAxisParams::default();
    let axis_limits = [
        (axis_params.flat_deg, axis_params.flat_deg_per_mm),
        (axis_params.support_flat_deg, f32::INFINITY),
    ];
    let estimates_axis = params.staircase && params.axis == AxisChoice::Auto;
    let caps_only_smoothed = params.caps == CapPolicy::Smooth && !params.find_smoothed_caps;
    // The grid: known, reconstructed where the mesh lies on an axis-aligned one, or found
    // turned off the axes (for the stack axis and the caps' slices: not looked for when
    // neither is).
    let grid: Option<Grid> = match params.grid_mm {
        Some(g) => Some(g.map(|h| (f64::from(h), f64::from(h)))),
        None => crate::analysis::voxel_size(mesh, topology).spacing_bounds(),
    }
    .map(Grid::along_mesh_axes)
    .or_else(|| {
        (params.staircase || !caps_only_smoothed)
            .then(|| turned_grid(mesh, topology))
            .flatten()
    });
    // Where the mesh itself lies on a grid with a slice axis (and the axis is the grid's), its
    // steps make a known orientation change, which an automatic tau stays below.
    let slice_step_change = match (params.grid_mm, params.axis, grid) {
        (None, AxisChoice::Auto, Some(g)) => slice_ratio(g).map(slice_step_change),
        _ => None,
    };
    let params = &ContextParams {
        cap_params: CapParams {
            grid,
            ..params.cap_params
        },
        staircase_params: StaircaseParams {
            slice_step_change,
            ..params.staircase_params
        },
        ..params.clone()
    };
    if caps_only_smoothed {
        // The staircases alone (caps are not looked for).
        let stairs = if params.staircase {
            let mut turns = TurnLimits::new(mesh, topology);
            if estimates_axis {
                turns.remember(&axis_limits);
            }
            staircases(mesh, topology, &turns, params, &axis_params, grid)
        } else {
            (None, AxisSource::Off, None, None)
        };
        return weighted(
            mesh,
            params,
            references,
            stairs,
            CapDetection::not_searched(),
            grid,
        );
    }
    // Cap detection's look at a smoothed copy is mostly serial (flood fills, growth): it starts
    // first, and the stack axis, the staircases and cap detection's look at the mesh itself
    // (which need nothing from it) fill the other cores meanwhile.
    let search = CapSearch::new(mesh, topology);
    let (smoothed_look, (curvature, (stairs, plain_look))) = rayon::join(
        || search.on_smoothed_copy(mesh, topology, &params.cap_params),
        || {
            // Face and vertex normals once, for the stack axis, the staircases and the caps;
            // the flat-vertex tests of the stack axis and of the caps' look in one walk.
            let mut turns = TurnLimits::new(mesh, topology);
            let mut limits = vec![(params.cap_params.flat_deg, f32::INFINITY)];
            if estimates_axis {
                limits.extend_from_slice(&axis_limits);
            }
            let curvature = if params.measure_curvature {
                Some(turns.remember_with_curvature(&limits))
            } else {
                turns.remember(&limits);
                None
            };
            // Cap candidates need nothing from the staircases but their reach, applied at
            // the end.
            let found = rayon::join(
                || staircases(mesh, topology, &turns, params, &axis_params, grid),
                || search.on_mesh(&turns, topology, &params.cap_params),
            );
            (curvature, found)
        },
    );
    drop(search);
    let candidates = CapCandidates::new(plain_look, smoothed_look);
    let reach: Option<Vec<bool>> = stairs
        .3
        .as_ref()
        .map(|s| s.distance_mm.iter().map(|d| d.is_finite()).collect());
    let caps = candidates.settle(mesh, reach.as_deref(), &params.cap_params);
    let mut context = weighted(mesh, params, references, stairs, caps, grid);
    context.average_normal_curvature_deg = curvature;
    context
}

/// The weights from the staircases (estimated axis, axis used, staircase weights), the caps
/// and the distances to `references`, with the analysis behind them.
fn weighted(
    mesh: &Mesh,
    params: &ContextParams,
    references: &[&TriangleBvh],
    (estimated_axis, axis_source, axis, staircase): Staircases,
    caps: CapDetection,
    grid: Option<Grid>,
) -> Context {
    let n = mesh.n_vertices();
    let reference_distance_mm =
        (!references.is_empty()).then(|| super::distance::reference_distances(mesh, references));
    // Staircase weighting without a found axis: no staircases, so only the floor beta_min.
    let stair_weights = match (&staircase, params.staircase) {
        (Some(s), _) => Some(s.weights.clone()),
        (None, true) => Some(
            VertexWeights::new(vec![params.staircase_params.beta_min.clamp(0.0, 1.0); n], n)
                .unwrap_or_else(|_| VertexWeights::uniform(n)),
        ),
        (None, false) => None,
    };
    let dist_weights = reference_distance_mm
        .as_ref()
        .map(|d| distance_weights(d, params.distance_scaling));
    let mut weights = match (stair_weights, dist_weights) {
        (Some(s), Some(d)) => s.combine(&d, params.combine),
        (Some(w), None) | (None, Some(w)) => w,
        (None, None) => VertexWeights::uniform(n),
    };
    if params.caps == CapPolicy::Preserve {
        for c in &caps.caps {
            weights.zero(c.vertices.iter().copied());
        }
    }
    let estimate_off_deg = match (axis_source, estimated_axis.and_then(|e| e.axis()), axis) {
        (AxisSource::Grid | AxisSource::EstimateOnGrid, Some(e), Some(a)) => Some(
            (0..3)
                .map(|k| e[k] * f64::from(a[k]))
                .sum::<f64>()
                .abs()
                .min(1.0)
                .acos()
                .to_degrees(),
        ),
        _ => None,
    };
    Context {
        estimated_axis,
        axis_source,
        grid_mm: grid.map(|g| g.spacing_mm),
        grid_axes: grid.filter(Grid::is_turned).map(|g| g.axes),
        estimate_off_deg,
        axis,
        staircase,
        caps,
        reference_distance_mm,
        weights,
        average_normal_curvature_deg: None,
    }
}
