//! Inter-structure guard: after a case's structures are smoothed, every pair of structures that
//! comes near another (configured as a reference or not, skipped ones included) is measured
//! before and after: the minimum distance, and whether the surfaces touch or cross (exact
//! triangle-triangle tests); each structure's self-intersections too. The table shows in the
//! report whether smoothing made a new contact or ate into a margin.

use crate::mesh::geometry::bounding_box;
use crate::mesh::Mesh;
use crate::metrics::minimum_distance;
use crate::spatial::intersect::{mesh_intersections, meshes_touch, self_intersections};
use crate::spatial::TriangleBvh;
use rayon::prelude::*;
use serde::Serialize;

/// Pairs whose bounding boxes stay further apart than this (mm), before and after, are not
/// measured: smoothing moves surfaces by a voxel or so, and margins that wide are not at risk.
pub const NEAR_MM: f64 = 10.0;

/// One structure as it came in and as it goes out, in the same (world) coordinates.
pub struct Surface<'a> {
    pub name: &'a str,
    pub before: &'a Mesh,
    pub after: &'a Mesh,
    /// Structures whose "before" surface holds triangles of this one's (labels of one label
    /// map sharing an interface): they touch before by construction, so the pair is not
    /// measured. A case of many labels has many such pairs, and measuring each costs the size
    /// of both surfaces.
    pub shares_triangles_with: &'a [String],
}

impl Surface<'_> {
    /// Whether this structure's input holds triangles of `other`'s.
    fn shares_triangles(&self, other: &Surface) -> bool {
        self.shares_triangles_with.iter().any(|n| n == other.name)
            || other.shares_triangles_with.iter().any(|n| n == self.name)
    }
}

/// Two structures before and after smoothing.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairRow {
    pub a: String,
    pub b: String,
    /// Smallest vertex-to-surface distance in either direction (mm); 0 where they touch or
    /// cross. "After" is not measured (null) for a pair that touched before.
    pub min_distance_before_mm: f64,
    pub min_distance_after_mm: Option<f64>,
    /// After minus before (mm): negative when smoothing brought them closer; 0 for a pair that
    /// touched before.
    pub change_mm: f64,
    /// The surfaces touch or cross (some pair of closed triangles meets); after: null for a
    /// pair that touched before.
    pub contact_before: bool,
    pub contact_after: Option<bool>,
    /// Triangle pairs that meet, for a new contact (else 0).
    pub new_contact_triangle_pairs: usize,
    /// A contact after smoothing that was not there before (an overlap already in the input is
    /// reported by `contact_before`, not counted as new).
    pub new_contact: bool,
}

/// Self-intersections of one structure (pairs of its own triangles that cross beyond what they
/// share). The input is examined only when the output has some; `before` is 0 otherwise.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SelfRow {
    pub structure: String,
    pub self_intersections_before: usize,
    pub self_intersections_after: usize,
}

/// The guard's measurements for a case.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairTable {
    /// Pairs within [`NEAR_MM`] of each other, in name order.
    pub pairs: Vec<PairRow>,
    /// Pairs further apart, not measured.
    pub n_far_pairs: usize,
    /// Self-intersections per structure (empty with `self_intersections = false`).
    pub structures: Vec<SelfRow>,
    /// Rounds of repair `[guard]` needed (0: none was).
    pub repair_rounds: usize,
    /// Vertices held back per repaired structure.
    pub held: Vec<HeldRow>,
    /// What still breaks `[guard]` after the repairs (the case fails).
    pub violations: Vec<String>,
}

/// How many vertices of a structure the guard held in place.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeldRow {
    pub structure: String,
    pub n_vertices: usize,
}

/// What smoothing may do to the distances between a case's structures (`[guard]`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GuardPolicy {
    /// Largest loss of minimum distance a pair may suffer (mm).
    pub max_gap_loss_mm: f64,
    /// A pair that does not touch before smoothing must not touch after.
    pub forbid_new_contacts: bool,
    /// Repair rounds before the case fails; 0 checks without repairing.
    pub max_repairs: usize,
    /// Whether each smoothed structure is checked for self-intersections (exact; about 2-8
    /// microseconds per triangle on 2 cores).
    pub self_intersections: bool,
    /// Other limits for named pairs: (a, b, max_gap_loss_mm, forbid_new_contacts).
    pub pairs: Vec<(String, String, f64, bool)>,
}

impl Default for GuardPolicy {
    fn default() -> Self {
        Self {
            max_gap_loss_mm: 0.05,
            forbid_new_contacts: true,
            max_repairs: 4,
            self_intersections: true,
            pairs: Vec::new(),
        }
    }
}

impl GuardPolicy {
    /// The limits for the pair `a`, `b` (either order): (max gap loss in mm, forbid contact).
    pub fn limits(&self, a: &str, b: &str) -> (f64, bool) {
        self.pairs
            .iter()
            .find(|(x, y, _, _)| (x == a && y == b) || (x == b && y == a))
            .map_or((self.max_gap_loss_mm, self.forbid_new_contacts), |p| {
                (p.2, p.3)
            })
    }

    /// The pairs of `table` that break the policy, each with what it broke.
    pub fn violations<'t>(&self, table: &'t PairTable) -> Vec<(&'t PairRow, String)> {
        table
            .pairs
            .iter()
            .filter_map(|p| {
                let (max_loss, forbid) = self.limits(&p.a, &p.b);
                if forbid && p.new_contact {
                    Some((
                        p,
                        format!(
                            "`{}` and `{}` touch after smoothing ({} triangle pairs meet) and did not before",
                            p.a, p.b, p.new_contact_triangle_pairs
                        ),
                    ))
                } else if !p.contact_before && -p.change_mm > max_loss {
                    Some((
                        p,
                        format!(
                            "the distance between `{}` and `{}` fell from {:.4} to {:.4} mm, more than the {max_loss} mm allowed",
                            p.a, p.b, p.min_distance_before_mm, p.min_distance_after_mm.unwrap_or(0.0)
                        ),
                    ))
                } else {
                    None
                }
            })
            .collect()
    }
}

/// Vertices of `mesh` closer than `within` (mm) to the surface of `other`, widened by `rings`
/// rings of neighbours: where a repair holds a structure back.
pub fn vertices_near(
    mesh: &Mesh,
    topology: &crate::mesh::Topology,
    other: &TriangleBvh,
    within: f64,
    rings: usize,
) -> Vec<bool> {
    let mut near: Vec<bool> = mesh
        .positions()
        .par_iter()
        .map(|&p| other.nearest_matching_within(p, within, |_| true).is_some())
        .collect();
    for _ in 0..rings {
        let grown: Vec<bool> = (0..near.len())
            .into_par_iter()
            .map(|v| near[v] || topology.neighbors(v).iter().any(|&u| near[u as usize]))
            .collect();
        near = grown;
    }
    near
}

/// Gap between two bounding boxes (mm); infinite when either mesh has no vertex.
fn box_gap(a: &Mesh, b: &Mesh) -> f64 {
    let (Some(a), Some(b)) = (bounding_box(a), bounding_box(b)) else {
        return f64::INFINITY;
    };
    (0..3)
        .map(|k| {
            let gap = (a.min[k] - b.max[k]).max(b.min[k] - a.max[k]).max(0.0) as f64;
            gap * gap
        })
        .sum::<f64>()
        .sqrt()
}

/// The structure left smoothing unchanged (skipped, or nothing moved).
fn unchanged(s: &Surface) -> bool {
    s.before.positions() == s.after.positions() && s.before.triangles() == s.after.triangles()
}

/// Minimum distance of two meshes, 0 when they touch or cross.
fn measure(a: &Mesh, tree_a: &TriangleBvh, b: &Mesh, tree_b: &TriangleBvh) -> f64 {
    if meshes_touch(a, b) {
        0.0
    } else {
        minimum_distance(a, tree_a, b, tree_b)
    }
}

/// Measures every near pair of `surfaces` and each one's self-intersections.
pub fn pair_table(surfaces: &[Surface], check_self: bool) -> PairTable {
    table_reusing(surfaces, None, check_self)
}

/// As [`pair_table`] after only the structures named in `changed` were smoothed again: the
/// other pairs' rows, every pair's "before" figures and the unchanged structures'
/// self-intersections are taken from `previous`.
pub fn update_pair_table(
    surfaces: &[Surface],
    previous: &PairTable,
    changed: &[&str],
    check_self: bool,
) -> PairTable {
    table_reusing(surfaces, Some((previous, changed)), check_self)
}

fn table_reusing(
    surfaces: &[Surface],
    reuse: Option<(&PairTable, &[&str])>,
    check_self: bool,
) -> PairTable {
    let changed = |name: &str| reuse.is_none_or(|(_, c)| c.contains(&name));
    let old_row =
        |a: &str, b: &str| reuse.and_then(|(t, _)| t.pairs.iter().find(|p| p.a == a && p.b == b));
    let mut order: Vec<usize> = (0..surfaces.len()).collect();
    order.sort_by(|&i, &j| surfaces[i].name.cmp(surfaces[j].name));
    let mut near = Vec::new();
    let mut n_far_pairs = 0;
    for (x, &i) in order.iter().enumerate() {
        for &j in &order[x + 1..] {
            let (s, t) = (&surfaces[i], &surfaces[j]);
            if box_gap(s.before, t.before).min(box_gap(s.after, t.after)) <= NEAR_MM {
                near.push((i, j));
            } else {
                n_far_pairs += 1;
            }
        }
    }
    // Pairs that must be measured again (a side changed, or no row to reuse), and trees only
    // for their structures (after = before for skipped ones, one tree).
    let remeasure = |i: usize, j: usize| {
        let (a, b) = (surfaces[i].name, surfaces[j].name);
        changed(a) || changed(b) || old_row(a, b).is_none()
    };
    // Pairs known to touch before (shared triangles) need nothing measured at all.
    let shared = |i: usize, j: usize| surfaces[i].shares_triangles(&surfaces[j]);
    let mut needed = vec![false; surfaces.len()];
    for &(i, j) in &near {
        if remeasure(i, j) && !shared(i, j) {
            needed[i] = true;
            needed[j] = true;
        }
    }
    let trees: Vec<Option<(TriangleBvh, Option<TriangleBvh>)>> = surfaces
        .par_iter()
        .zip(&needed)
        .map(|(s, &need)| {
            need.then(|| {
                let before = TriangleBvh::build(s.before);
                (before, (!unchanged(s)).then(|| TriangleBvh::build(s.after)))
            })
        })
        .collect();
    let tree = |i: usize, after: bool| {
        let (before, moved) = trees[i].as_ref().expect("tree built for near pairs");
        if after {
            moved.as_ref().unwrap_or(before)
        } else {
            before
        }
    };
    // Pairs in parallel (rows in pair order whatever the threads): a case with many small
    // structures has many pairs, each too small to keep the threads busy on its own.
    let pairs = near
        .par_iter()
        .map(|&(i, j)| {
            let (s, t) = (&surfaces[i], &surfaces[j]);
            let old = old_row(s.name, t.name);
            if let (Some(row), false) = (old, remeasure(i, j)) {
                return row.clone();
            }
            let before = match old {
                Some(row) => row.min_distance_before_mm,
                None if shared(i, j) => 0.0,
                None => measure(s.before, tree(i, false), t.before, tree(j, false)),
            };
            // Structures that touch already (labels sharing an interface) cannot touch anew
            // nor lose a gap: their "after" is not measured.
            if before == 0.0 {
                return PairRow {
                    a: s.name.to_string(),
                    b: t.name.to_string(),
                    min_distance_before_mm: 0.0,
                    min_distance_after_mm: None,
                    change_mm: 0.0,
                    contact_before: true,
                    contact_after: None,
                    new_contact_triangle_pairs: 0,
                    new_contact: false,
                };
            }
            let after = measure(s.after, tree(i, true), t.after, tree(j, true));
            // A new contact: how many triangle pairs meet, for the message.
            let new_pairs = if after == 0.0 {
                mesh_intersections(s.after, t.after).len()
            } else {
                0
            };
            PairRow {
                a: s.name.to_string(),
                b: t.name.to_string(),
                min_distance_before_mm: before,
                min_distance_after_mm: Some(after),
                change_mm: after - before,
                contact_before: false,
                contact_after: Some(after == 0.0),
                new_contact_triangle_pairs: new_pairs,
                new_contact: after == 0.0,
            }
        })
        .collect();
    // The input is examined only where the output intersects itself (to tell whether it did
    // already): the exact tests on the many coplanar neighbours of a staircase are not cheap.
    let structures = order
        .iter()
        .filter(|_| check_self)
        .map(|&i| {
            let s = &surfaces[i];
            let kept = reuse.and_then(|(t, _)| t.structures.iter().find(|r| r.structure == s.name));
            if let (Some(row), false) = (kept, changed(s.name)) {
                return row.clone();
            }
            let after = self_intersections(s.after).len();
            let before = if after == 0 {
                0
            } else if unchanged(s) {
                after
            } else {
                self_intersections(s.before).len()
            };
            SelfRow {
                structure: s.name.to_string(),
                self_intersections_before: before,
                self_intersections_after: after,
            }
        })
        .collect();
    PairTable {
        pairs,
        n_far_pairs,
        structures,
        repair_rounds: 0,
        held: Vec::new(),
        violations: Vec::new(),
    }
}
