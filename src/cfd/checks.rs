//! The checks a surface passes before it goes to a flow solver's mesher, all exact where a
//! yes/no answer is given: a closed (or, with open ends kept, only open at its patches)
//! 2-manifold, consistently oriented with normals out of the fluid, no self-intersection
//! (exact triangle-triangle tests), no triangle with collinear corners; and the quality
//! figures meshers report (angles, aspect ratios, edge lengths against the target).

use crate::mesh::geometry::signed_volume;
use crate::mesh::{Mesh, Topology};
use crate::metrics::quality::{
    edge_length_stats, triangle_quality, EdgeLengthStats, TriangleQuality,
};
use crate::spatial::intersect::{exactly_degenerate_triangles, self_intersections};
use serde::Serialize;

/// What the checks found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SurfaceChecks {
    /// Edges with one face (allowed only where open ends are kept).
    pub border_edges: usize,
    pub open_ends_allowed: bool,
    pub non_manifold_edges: usize,
    pub non_manifold_vertices: usize,
    /// Edges both faces run the same way (inconsistent orientation).
    pub inconsistent_edges: usize,
    pub components: usize,
    /// Enclosed volume with the faces' orientation (mm³); negative when normals point in.
    pub signed_volume_mm3: f64,
    /// The volume the wall encloses with its open ends closed by flat fans (mm³), and the
    /// wall's area (mm²): a surface that encloses nothing (a sheet, a single triangle) is no
    /// vessel, whatever its patches.
    pub lumen_volume_mm3: f64,
    pub area_mm2: f64,
    /// Pairs of faces that cross or touch beyond shared corners and edges.
    pub self_intersections: usize,
    /// Where the first one is (the centre of its first face, mm).
    pub first_self_intersection_mm: Option<[f32; 3]>,
    /// Faces whose corners are exactly collinear (or repeat a vertex).
    pub degenerate_triangles: usize,
    pub quality: TriangleQuality,
    /// Edge lengths against the remeshing target, when there was one.
    pub edges: Option<EdgeLengthStats>,
    /// How smoothing changed the narrowest lumen, when measured.
    pub narrowing: Option<Narrowing>,
}

/// Smoothing fails a vessel when its narrowest lumen (the distance from the wall to the
/// opposite wall) falls below this share of what it was.
pub const MIN_LUMEN_RATIO: f64 = 0.5;

/// How smoothing changed the vessel's narrowest lumen.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Narrowing {
    /// Narrowest distance to the opposite wall after / before smoothing (1 = unchanged).
    pub ratio: f64,
    pub before_mm: f64,
    pub after_mm: f64,
    /// Where the narrowest lumen is after smoothing (mm).
    pub at_mm: [f32; 3],
}

/// What finding a vertex's opposite wall needs: the faces in a tree, face and vertex normals.
struct OppositeWall<'a> {
    mesh: &'a Mesh,
    tree: crate::spatial::TriangleBvh,
    faces: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    /// -1 when the faces' normals point out of the fluid (as they should), else 1.
    inward: f64,
}

impl<'a> OppositeWall<'a> {
    fn new(mesh: &'a Mesh, topology: &Topology) -> OppositeWall<'a> {
        use crate::mesh::geometry::{face_normals, vertex_normals};
        OppositeWall {
            mesh,
            tree: crate::spatial::TriangleBvh::build(mesh),
            faces: face_normals(mesh),
            normals: vertex_normals(mesh, topology),
            inward: if signed_volume(mesh) < 0.0 { 1.0 } else { -1.0 },
        }
    }

    /// The distance from vertex `v` to its opposite wall if that is at most `within` (mm).
    fn distance(&self, v: usize, within: f64) -> Option<f64> {
        let n = self.normals[v].map(|x| self.inward * x as f64);
        if n == [0.0; 3] {
            return None;
        }
        let p = self.mesh.positions()[v];
        let x = p.map(f64::from);
        let facing_back = |f: u32| {
            let m = self.faces[f as usize];
            // n is inward; a face of the opposite wall has its outward normal along n.
            let d = n[0] * m[0] as f64 + n[1] * m[1] as f64 + n[2] * m[2] as f64;
            if d <= 0.5 {
                return false;
            }
            let t = self.tree.triangle(f);
            t.iter().any(|c| {
                (c[0] as f64 - x[0]) * n[0]
                    + (c[1] as f64 - x[1]) * n[1]
                    + (c[2] as f64 - x[2]) * n[2]
                    > 0.0
            })
        };
        self.tree
            .nearest_matching_within(p, within, facing_back)
            .map(|near| near.distance)
    }
}

/// Distance (mm) from each vertex to the opposite wall: the nearest face that faces back
/// (its normal against the vertex normal by more than 60 degrees) on the inner side of the
/// vertex. Infinite where there is none. Neighbouring faces on the same side (a tube's wall
/// along its axis, a staircase's steps) do not count, so on a tube this is its diameter.
pub fn opposite_wall_distance(mesh: &Mesh, topology: &Topology) -> Vec<f64> {
    use rayon::prelude::*;
    let wall = OppositeWall::new(mesh, topology);
    (0..mesh.n_vertices())
        .into_par_iter()
        .map(|v| wall.distance(v, f64::INFINITY).unwrap_or(f64::INFINITY))
        .collect()
}

/// The vertex with the smallest [`opposite_wall_distance`] (the lowest index among equals) and
/// that distance (mm); `None` when no vertex has an opposite wall. A sample of the vertices
/// bounds the search for the others, so wide parts of the vessel cost little.
pub fn narrowest_lumen(mesh: &Mesh, topology: &Topology) -> Option<(usize, f64)> {
    use rayon::prelude::*;
    const SAMPLE_EVERY: usize = 16;
    let wall = OppositeWall::new(mesh, topology);
    let n = mesh.n_vertices();
    let bound = (0..n)
        .into_par_iter()
        .step_by(SAMPLE_EVERY)
        .filter_map(|v| wall.distance(v, f64::INFINITY))
        .reduce(|| f64::INFINITY, f64::min);
    // Every vertex at or below the bound is found, with its exact distance.
    (0..n)
        .into_par_iter()
        .filter_map(|v| wall.distance(v, bound).map(|d| (v, d)))
        .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
}

/// The narrowest lumen of `after` against the narrowest of `before` (the same vertices,
/// moved): per vertex the distance would follow whichever staircase face happens to face back,
/// so the vessel's narrowest point is compared instead. `None` when no vertex has an opposite
/// wall in both.
pub fn narrowing(before: &Mesh, after: &Mesh, topology: &Topology) -> Option<Narrowing> {
    let (_, b) = narrowest_lumen(before, topology)?;
    let (v, a) = narrowest_lumen(after, topology)?;
    (b > 0.0).then(|| Narrowing {
        ratio: a / b,
        before_mm: b,
        after_mm: a,
        at_mm: after.positions()[v],
    })
}

/// Smallest enclosed volume over area^1.5 a vessel may have: a sphere has 0.094, a tube 1000
/// diameters long 0.0045; a flat sheet 0.
const MIN_ENCLOSED_RATIO: f64 = 1e-5;

impl SurfaceChecks {
    /// Why the surface must not be handed over; empty when it passes.
    pub fn failures(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.border_edges > 0 && !self.open_ends_allowed {
            out.push(format!(
                "not watertight: {} border edges (close the open ends)",
                self.border_edges
            ));
        }
        if self.non_manifold_edges > 0 || self.non_manifold_vertices > 0 {
            out.push(format!(
                "not a 2-manifold: {} edges with more than two faces, {} pinched vertices",
                self.non_manifold_edges, self.non_manifold_vertices
            ));
        }
        if self.inconsistent_edges > 0 {
            out.push(format!(
                "inconsistently oriented: {} edges",
                self.inconsistent_edges
            ));
        }
        if self.components != 1 {
            out.push(format!("{} separate components", self.components));
        }
        // A tube a thousand diameters long still has V / A^1.5 = 0.0045.
        let enough = self.lumen_volume_mm3.abs() > MIN_ENCLOSED_RATIO * self.area_mm2.powf(1.5);
        if !enough {
            out.push(format!(
                "it encloses no lumen ({:.3e} mm³ for {:.3} mm² of wall, its open ends closed): a sheet, not a vessel",
                self.lumen_volume_mm3, self.area_mm2
            ));
        }
        if self.signed_volume_mm3 <= 0.0 && self.border_edges == 0 {
            out.push(format!(
                "normals point into the fluid (enclosed volume {:.3} mm³)",
                self.signed_volume_mm3
            ));
        }
        if self.self_intersections > 0 {
            let at = self
                .first_self_intersection_mm
                .map(|p| format!(" (first near {:.2}, {:.2}, {:.2} mm)", p[0], p[1], p[2]))
                .unwrap_or_default();
            out.push(format!(
                "{} pairs of faces intersect{at}",
                self.self_intersections
            ));
        }
        if let Some(n) = self.narrowing.filter(|n| n.ratio < MIN_LUMEN_RATIO) {
            out.push(format!(
                "smoothing pinched the vessel: its narrowest lumen went from {:.3} to {:.3} mm, near ({:.2}, {:.2}, {:.2}) mm (use fewer iterations or a volume-keeping method such as taubin or hc)",
                n.before_mm, n.after_mm, n.at_mm[0], n.at_mm[1], n.at_mm[2]
            ));
        }
        if self.degenerate_triangles > 0 {
            out.push(format!(
                "{} degenerate triangles (collinear corners)",
                self.degenerate_triangles
            ));
        }
        out
    }
}

/// Runs every check on `mesh`; `target_mm` (per vertex) adds the edge-length figures.
pub fn check_surface(
    mesh: &Mesh,
    topology: &Topology,
    open_ends_allowed: bool,
    target_mm: Option<&[f32]>,
) -> SurfaceChecks {
    let border_edges = topology.edge_n_faces().iter().filter(|&&n| n == 1).count();
    let intersections = self_intersections(mesh);
    let first_self_intersection_mm = intersections.first().map(|&[f, _]| {
        let p = mesh.positions();
        let t = mesh.triangles()[f as usize];
        std::array::from_fn(|k| {
            (p[t[0] as usize][k] + p[t[1] as usize][k] + p[t[2] as usize][k]) / 3.0
        })
    });
    SurfaceChecks {
        border_edges,
        open_ends_allowed,
        non_manifold_edges: topology.non_manifold_edges().len(),
        non_manifold_vertices: topology.non_manifold_vertices().len(),
        inconsistent_edges: topology.inconsistent_edges().len(),
        components: topology.n_components(),
        signed_volume_mm3: signed_volume(mesh),
        lumen_volume_mm3: crate::metrics::volume::enclosed_volume(mesh, topology).mm3,
        area_mm2: crate::mesh::geometry::area(mesh),
        self_intersections: intersections.len(),
        first_self_intersection_mm,
        degenerate_triangles: exactly_degenerate_triangles(mesh).len(),
        quality: triangle_quality(mesh),
        edges: target_mm.map(|t| edge_length_stats(mesh, topology.edges(), t)),
        narrowing: None,
    }
}
