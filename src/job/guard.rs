//! The inter-structure guard in a case: the pair table of the processed structures and the
//! repair rounds that hold back, and smooth again, structures that broke `[guard]`.

use crate::guard::{
    pair_table, update_pair_table, vertices_near, GuardPolicy, HeldRow, PairTable, Surface,
};
use crate::mesh::{Mesh, Topology};
use crate::report::case::StructureReport;
use crate::spatial::TriangleBvh;
use std::collections::BTreeMap;

/// Output files of a case: (name within its folder, bytes).
pub(super) type Files = Vec<(String, Vec<u8>)>;

/// Processes a structure again with vertices held in place (see [`guard_case`]).
pub(super) type Rerun<'a> =
    dyn FnMut(usize, &[bool], &mut Files, &mut Vec<Kept>) -> StructureReport + 'a;

/// A processed structure as the guard sees it.
pub(super) struct Kept {
    /// Index of its input in the case's list.
    pub input: usize,
    pub name: String,
    pub before: Mesh,
    pub after: Mesh,
    /// A smoother ran and the surface kept its vertices (not the cfd profile's new surface):
    /// a repair can hold vertices back and smooth again.
    pub repairable: bool,
    /// What its pictures need besides the surfaces (none for structures copied unchanged).
    pub picture: Option<super::pictures::PictureInput>,
    /// Structures whose input holds triangles of this one's input (labels of one map that
    /// share an interface): in contact before by construction.
    pub shares_triangles_with: Vec<String>,
}

/// The pair table of the kept structures; after a repair, only what involves the structures
/// smoothed again (`changed`) is measured again.
fn measure_pairs(
    kept: &[Kept],
    previous: Option<(&PairTable, &[&str])>,
    check_self: bool,
) -> PairTable {
    let list: Vec<Surface> = kept
        .iter()
        .map(|k| Surface {
            name: &k.name,
            before: &k.before,
            after: &k.after,
            shares_triangles_with: &k.shares_triangles_with,
        })
        .collect();
    match previous {
        Some((table, changed)) => update_pair_table(&list, table, changed, check_self),
        None => pair_table(&list, check_self),
    }
}

/// Measures the pairs and, while some pair breaks `[guard]`, holds back the vertices of the
/// structures that moved where they came closer than the pair's old gap (and two rings round
/// them) and smooths those structures again; a pair still broken after the last round fails
/// the structures that moved, with the reason, and their outputs are not written.
/// `rerun(input, held, files, kept)` processes input `input` again with `held` vertices in
/// place, adding its outputs to `files` and its surfaces to `kept`, and returns its report.
pub(super) fn guard_case(
    policy: &GuardPolicy,
    names: &[String],
    files: &mut Files,
    structures: &mut [StructureReport],
    kept: &mut Vec<Kept>,
    rerun: &mut Rerun,
) -> PairTable {
    let mut held: BTreeMap<usize, Vec<bool>> = BTreeMap::new();
    let mut table = measure_pairs(kept, None, policy.self_intersections);
    let mut rounds = 0;
    while rounds < policy.max_repairs {
        let broken: Vec<(String, String, f64)> = policy
            .violations(&table)
            .iter()
            .map(|(p, _)| (p.a.clone(), p.b.clone(), p.min_distance_before_mm))
            .collect();
        if broken.is_empty() {
            break;
        }
        let mut again = std::collections::BTreeSet::new();
        for (a, b, gap) in &broken {
            for (me, other) in [(a, b), (b, a)] {
                let (Some(i), Some(j)) = (
                    kept.iter().position(|k| &k.name == me),
                    kept.iter().position(|k| &k.name == other),
                ) else {
                    continue;
                };
                if !kept[i].repairable {
                    continue;
                }
                let tree = TriangleBvh::build(&kept[j].after);
                let topology = Topology::build(&kept[i].after);
                let near = vertices_near(&kept[i].after, &topology, &tree, *gap, 2);
                let mask = held
                    .entry(kept[i].input)
                    .or_insert_with(|| vec![false; near.len()]);
                for (h, n) in mask.iter_mut().zip(&near) {
                    *h |= *n;
                }
                again.insert(kept[i].input);
            }
        }
        if again.is_empty() {
            break;
        }
        rounds += 1;
        let changed: Vec<&str> = again.iter().map(|&i| names[i].as_str()).collect();
        for &input in &again {
            let Some(at) = structures.iter().position(|r| r.name == names[input]) else {
                continue;
            };
            let old: Vec<String> = std::mem::take(&mut structures[at].outputs);
            files.retain(|(n, _)| !old.contains(n));
            let held_here = held.get(&input).cloned().unwrap_or_default();
            structures[at] = rerun(input, &held_here, files, kept);
        }
        table = measure_pairs(kept, Some((&table, &changed)), policy.self_intersections);
    }
    table.repair_rounds = rounds;
    table.held = held
        .iter()
        .map(|(&input, mask)| HeldRow {
            structure: names[input].clone(),
            n_vertices: mask.iter().filter(|&&h| h).count(),
        })
        .collect();
    let broken: Vec<(String, String, String)> = policy
        .violations(&table)
        .iter()
        .map(|(p, why)| (p.a.clone(), p.b.clone(), why.clone()))
        .collect();
    for (a, b, why) in broken {
        let place = match (
            kept.iter().find(|k| k.name == a),
            kept.iter().find(|k| k.name == b),
        ) {
            (Some(x), Some(y)) => {
                let p = closest_place(&x.after, &y.after);
                format!("; closest at ({:.2}, {:.2}, {:.2}) mm", p[0], p[1], p[2])
            }
            _ => String::new(),
        };
        let why = format!("{why}{place}");
        table.violations.push(why.clone());
        // The structures that moved carry the failure; their outputs are not written.
        for name in [&a, &b] {
            let moved = kept
                .iter()
                .any(|k| &k.name == name && k.before.positions() != k.after.positions());
            if let Some(r) = structures.iter_mut().find(|r| &r.name == name && moved) {
                let message = format!(
                    "guard: {why} (after {rounds} repair round(s); see the report's pair table)"
                );
                r.error = Some(match r.error.take() {
                    Some(e) => format!("{e}; {message}"),
                    None => message,
                });
                r.status = "failed".into();
                files.retain(|(n, _)| !r.outputs.contains(n));
                r.outputs.clear();
            }
        }
    }
    table
}

/// Where `a` comes closest to `b` (world mm): a meeting triangle of `a` (its centroid) when
/// they touch, else the vertex of `a` nearest to `b`.
fn closest_place(a: &Mesh, b: &Mesh) -> [f32; 3] {
    let p = a.positions();
    if let Some(&[f, _]) = crate::spatial::intersect::mesh_intersections(a, b).first() {
        let t = a.triangles()[f as usize];
        return std::array::from_fn(|k| t.iter().map(|&v| p[v as usize][k]).sum::<f32>() / 3.0);
    }
    let d = TriangleBvh::build(b).distances(p);
    (0..p.len())
        .min_by(|&i, &j| d[i].total_cmp(&d[j]))
        .map_or([f32::NAN; 3], |i| p[i])
}
