//! Image-stack orientation from a mesh alone (Moench 2012, §3.1): staircases and terraces put
//! many face normals on the stack axis, which shows as dense clusters on the Gauss map.
//!
//! Face normals are binned on a grid over the unit sphere with n and -n counted together (a
//! terrace facing up and one facing down are the same evidence, the paper's own proposal),
//! each weighted by its face's area; the density of a bin is the weight within radius r (0.1);
//! bins above (mean + max) / 2 are grown into clusters; each cluster's mean is a candidate; the
//! candidate with most area within 4.5 degrees of it wins and is then refined from those faces.
//! Evidence below a minimum share gives a "too weak" result instead of a random axis.
//!
//! Two departures from the paper keep smooth surfaces from producing a wrong axis. Candidates
//! come only from faces that are flat at the mm scale (the normal turns by at most 0.5 degrees
//! per mm, a radius of curvature of 115 mm or more): terraces and caps qualify, the round parts
//! of a structure and the zig-zag slivers marching cubes leaves on an anisotropic grid do not,
//! however finely they are sampled. (With the paper's 5 degree test alone, a sphere surfaced
//! from a smooth field on a 1 x 1 x 3 mm grid gave a 72 degree axis from sliver clusters, and a
//! staircased tumour after 10 Laplace iterations a 90 degree one.) Support and refinement then
//! count faces flat at the mesh's own sampling (normal curvature <= 0.5 degrees): where the
//! surface faces the stack axis marching cubes samples it at the fine in-plane spacing, so such
//! faces surround the axis on all sides, while a smoothed terrace, curved like a dome, lies on
//! one side and alone would pull the axis off by a degree or more.
//!
//! A third departure: the paper assumes the densest cluster is the slices. Off its grid, a
//! tube along the slice axis has no terraces but long flat walls, facing x, y and the
//! diagonals in about equal shares, all 90 degrees from the slices; they outweigh its end
//! discs. So the runner-up is the best direction 10 degrees or more away, from any bin, not
//! only the clusters over the threshold; at 0.9 of the winner's support or more it is a tie and
//! the answer too weak (the report warns from 0.5).
//!
//! Where that finds too little, a second look takes the small flat areas paper 004 (Table 5)
//! estimates from: faces flat at their own sampling by their vertices, or lying in one plane
//! with two of their three edge neighbours (the border faces of a small area, which the vertex
//! test misses: on a sphere with 1/8 of its top slice cut flat, 0.11 % of the area by vertices,
//! 0.49 % with the border). Smoothed binary surfaces keep planar facets in oblique directions
//! of that size (a VTK-smoothed neck tumour: 0.5-1.0 % of its area, in mirror pairs), so such
//! an axis counts only when it has at least twice the support of any other direction, one
//! connected flat area holds the minimum share on its own, and that area is flat (its normals
//! spread by at most 0.25 degrees; smoothed facets by 0.6-2.3); otherwise the answer is too weak.

use crate::mesh::face_neighbours::edge_neighbours;
use crate::mesh::geometry::triangle_area_vector;
use crate::mesh::{Mesh, Topology};
use crate::metrics::normal_curvature::TurnLimits;
use crate::parallel::deterministic_sum;
use rayon::prelude::*;
use serde::Serialize;

/// Parameters of the stack-axis estimation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StackAxisParams {
    /// Neighbourhood radius on the unit sphere for the density (paper: 0.1).
    pub radius: f64,
    /// A face supports an axis when its normal is within this angle of the axis line (degrees).
    pub support_deg: f64,
    /// Least share of the surface area that must support the winning axis; below it the
    /// evidence is too weak.
    pub min_support_share: f64,
    /// Least number of supporting faces.
    pub min_support_faces: usize,
    /// Candidate faces: all three vertices with a normal curvature up to this (degrees; the
    /// paper's flatness test)...
    pub flat_deg: f32,
    /// ...and a normal turning by at most this much per mm (degrees per mm).
    pub flat_deg_per_mm: f32,
    /// Support and refinement count faces whose three vertices have a normal curvature up to
    /// this (degrees).
    pub support_flat_deg: f32,
}

impl Default for StackAxisParams {
    fn default() -> Self {
        Self {
            radius: 0.1,
            support_deg: 4.5,
            // A uniform Gauss map puts 0.31 % of the area within 4.5 degrees of any axis, even
            // if every face passed the flatness test; ask for more than that (a direction
            // needs candidate faces, flat at the mm scale, before it is considered at all).
            min_support_share: 0.004,
            min_support_faces: 10,
            flat_deg: 5.0,
            flat_deg_per_mm: 0.5,
            support_flat_deg: 0.5,
        }
    }
}

/// Result of the estimation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StackAxis {
    /// A unit axis (sign chosen so its largest component is positive) and the share of the
    /// surface area whose normals lie within the support angle of it.
    Found {
        axis: [f64; 3],
        confidence: f64,
        n_candidates: usize,
        /// Support share of the best other direction at least 10 degrees from the axis (0 if
        /// none): how clearly the axis stands out.
        runner_up: f64,
        /// Angle (degrees) between the axis and that direction (0 if none).
        runner_up_deg: f64,
        /// What the axis was found from.
        evidence: AxisEvidence,
    },
    /// No direction stands out: the mesh shows no staircases to estimate from.
    TooWeak { best_share: f64 },
}

/// What a stack axis was found from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisEvidence {
    /// Terraces and caps flat at the mm scale (the paper's clusters).
    Terraces,
    /// One small flat area, alone in its direction (paper 004 Table 5's weak case).
    SmallFlatArea,
}

impl AxisEvidence {
    /// How reports name it.
    pub fn describe(self) -> &'static str {
        match self {
            AxisEvidence::Terraces => "terraces",
            AxisEvidence::SmallFlatArea => "one small flat area",
        }
    }
}

impl StackAxis {
    /// The axis, if one was found.
    pub fn axis(&self) -> Option<[f64; 3]> {
        match self {
            StackAxis::Found { axis, .. } => Some(*axis),
            StackAxis::TooWeak { .. } => None,
        }
    }
}

fn normalize(v: [f64; 3]) -> Option<[f64; 3]> {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    (len > 1e-12 && len.is_finite()).then(|| v.map(|x| x / len))
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Sign convention: the largest component positive.
fn canonical(a: [f64; 3]) -> [f64; 3] {
    let k = (0..3)
        .max_by(|&i, &j| a[i].abs().total_cmp(&a[j].abs()))
        .unwrap_or(2);
    if a[k] < 0.0 {
        a.map(|x| -x)
    } else {
        a
    }
}

/// Estimates the stack axis of a mesh from its face normals.
pub fn stack_axis(mesh: &Mesh, topology: &Topology, params: &StackAxisParams) -> StackAxis {
    stack_axis_with(&TurnLimits::new(mesh, topology), params)
}

/// [`stack_axis`] of the mesh whose normals `turns` holds (computed once for every analysis
/// of the mesh).
pub fn stack_axis_with(turns: &TurnLimits, params: &StackAxisParams) -> StackAxis {
    let flat = turns.within(params.flat_deg, params.flat_deg_per_mm);
    let support = turns.within(params.support_flat_deg, f32::INFINITY);
    let all_flat = |flags: &[bool], t: [u32; 3]| t.iter().all(|&v| flags[v as usize]);
    // Shares are of the whole surface, so a mesh with little flat area gives little evidence.
    let mesh = turns.mesh();
    let total_area = deterministic_sum(mesh.n_triangles(), |f| {
        let v = triangle_area_vector(mesh, mesh.triangles()[f]);
        0.5 * (v.iter().map(|&x| (x as f64).powi(2)).sum::<f64>()).sqrt()
    });
    if total_area <= 0.0 || !total_area.is_finite() {
        return StackAxis::TooWeak { best_share: 0.0 };
    }
    let first = estimate(
        turns,
        (&|_, t| all_flat(&flat, t), &|_, t| all_flat(&support, t)),
        total_area,
        params,
    );
    let first_share = match first {
        StackAxis::Found { .. } => return first,
        StackAxis::TooWeak { best_share } => best_share,
    };
    // The second look: faces flat by their vertices or lying in one plane with two of their
    // edge neighbours (the border faces of a small flat area, which the vertex test misses).
    let coplanar = coplanar_faces(turns, params.support_flat_deg, 2);
    let tris = mesh.triangles();
    let small: Vec<bool> = (0..tris.len())
        .into_par_iter()
        .map(|f| coplanar[f] || all_flat(&support, tris[f]))
        .collect();
    let second = estimate(
        turns,
        (&|f, _| small[f], &|f, _| small[f]),
        total_area,
        params,
    );
    let StackAxis::Found {
        axis,
        confidence,
        n_candidates,
        runner_up,
        runner_up_deg,
        ..
    } = second
    else {
        return StackAxis::TooWeak {
            best_share: first_share,
        };
    };
    let area = largest_flat_area(turns, &small, axis, (params.support_deg, total_area));
    // Alone in its direction, one connected area rather than scattered facets, and flat
    // rather than a facet smoothing has bent.
    if confidence < SMALL_AREA_LEAD * runner_up
        || area.share < params.min_support_share
        || area.spread_deg > SMALL_AREA_SPREAD_DEG
    {
        return StackAxis::TooWeak {
            best_share: first_share,
        };
    }
    StackAxis::Found {
        axis,
        confidence,
        n_candidates,
        runner_up,
        runner_up_deg,
        evidence: AxisEvidence::SmallFlatArea,
    }
}

/// A small flat area names the axis only when it has at least this many times the support of
/// any other direction: a smoothed surface keeps planar facets in several directions at once.
const SMALL_AREA_LEAD: f64 = 2.0;

/// ...and when its normals spread by at most this much (degrees, root mean square): a cut is
/// flat to the bit, while the planar facets smoothing leaves are bent (0.58-2.3 degrees measured
/// on blobs and the corpus tumour after 10-80 Laplace iterations).
const SMALL_AREA_SPREAD_DEG: f64 = 0.25;

/// The largest edge-connected set of admitted faces whose normals lie within a given angle of
/// an axis line: its share of the surface area, and how far its normals spread.
struct FlatArea {
    share: f64,
    /// Area-weighted root mean square angle between its face normals and their mean (degrees).
    spread_deg: f64,
}

fn largest_flat_area(
    turns: &TurnLimits,
    admitted: &[bool],
    axis: [f64; 3],
    (within_deg, total_area): (f64, f64),
) -> FlatArea {
    let mesh = turns.mesh();
    let topology = turns.topology();
    let tris = mesh.triangles();
    let normals = turns.face_normals();
    let cos_within = within_deg.to_radians().cos();
    let axis32 = axis.map(|x| x as f32);
    let member: Vec<bool> = (0..tris.len())
        .map(|f| admitted[f] && dot32(normals[f], axis32).abs() >= cos_within)
        .collect();
    let area = |f: usize| {
        let v = triangle_area_vector(mesh, tris[f]).map(f64::from);
        0.5 * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
    };
    // A face's normal turned to the axis' side, as f64.
    let aligned = |f: usize| {
        let n = normals[f].map(f64::from);
        if dot(n, axis) < 0.0 {
            n.map(|x| -x)
        } else {
            n
        }
    };
    let mut seen = vec![false; tris.len()];
    let mut best: (f64, Vec<usize>) = (0.0, Vec::new());
    let (mut stack, mut neighbours) = (Vec::new(), Vec::new());
    for start in 0..tris.len() {
        if !member[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut faces = Vec::new();
        while let Some(f) = stack.pop() {
            faces.push(f);
            edge_neighbours(mesh, topology, f as u32, &mut neighbours);
            for &g in &neighbours {
                let g = g as usize;
                if member[g] && !seen[g] {
                    seen[g] = true;
                    stack.push(g);
                }
            }
        }
        let sum: f64 = faces.iter().map(|&f| area(f)).sum();
        if sum > best.0 {
            best = (sum, faces);
        }
    }
    let (region_area, faces) = best;
    let mean = faces.iter().fold([0.0; 3], |m, &f| {
        let (a, n) = (area(f), aligned(f));
        std::array::from_fn(|k| m[k] + a * n[k])
    });
    let spread_deg = match normalize(mean) {
        Some(mean) if region_area > 0.0 => {
            let square_sum: f64 = faces
                .iter()
                .map(|&f| area(f) * dot(aligned(f), mean).clamp(-1.0, 1.0).acos().powi(2))
                .sum();
            (square_sum / region_area).sqrt().to_degrees()
        }
        _ => 0.0,
    };
    FlatArea {
        share: region_area / total_area,
        spread_deg,
    }
}

/// Per face: whether its normal lies within `max_deg` of the normals of at least `min_agree`
/// of its edge neighbours (faces without area never agree).
fn coplanar_faces(turns: &TurnLimits, max_deg: f32, min_agree: usize) -> Vec<bool> {
    let (mesh, topology) = (turns.mesh(), turns.topology());
    let normals = turns.face_normals();
    let cos_max = f64::from(max_deg).to_radians().cos();
    (0..mesh.n_triangles() as u32)
        .into_par_iter()
        .map_init(Vec::new, |neighbours, f| {
            let n = normals[f as usize];
            if n == [0.0; 3] {
                return false;
            }
            edge_neighbours(mesh, topology, f, neighbours);
            let agree = neighbours
                .iter()
                .filter(|&&g| dot32(n, normals[g as usize]) >= cos_max)
                .count();
            agree >= min_agree
        })
        .collect()
}

fn dot32(a: [f32; 3], b: [f32; 3]) -> f64 {
    (0..3).map(|k| f64::from(a[k]) * f64::from(b[k])).sum()
}

/// A face test, given the face's index and corners.
type FaceTest<'a> = &'a (dyn Fn(usize, [u32; 3]) -> bool + Sync);

/// One look: the clusters of the normals of the faces `candidate` admits give the candidate
/// axes; the faces `support` admits give each its share of `total_area` (mm^2) and refine the
/// winner.
fn estimate(
    turns: &TurnLimits,
    (candidate, support): (FaceTest, FaceTest),
    total_area: f64,
    params: &StackAxisParams,
) -> StackAxis {
    let mesh = turns.mesh();
    // Evidence is the area of flat faces, not a face count: slivers (which marching cubes makes
    // wherever the surface passes close to a grid point) then cannot outvote real terraces.
    // Unit normal and area of every face `admit` admits, in face order: fixed blocks of faces
    // in parallel, each a plain loop, joined in block order.
    let unit_normals = |admit: FaceTest| -> (Vec<[f64; 3]>, Vec<f64>) {
        const BLOCK: usize = 1 << 16;
        let blocks: Vec<(Vec<[f64; 3]>, Vec<f64>)> = mesh
            .triangles()
            .par_chunks(BLOCK)
            .enumerate()
            .map(|(b, block)| {
                let mut out = (Vec::new(), Vec::new());
                for (i, &t) in block.iter().enumerate() {
                    if !admit(b * BLOCK + i, t) {
                        continue;
                    }
                    let v = triangle_area_vector(mesh, t).map(f64::from);
                    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                    if len > 0.0 && len.is_finite() {
                        out.0.push(v.map(|x| x / len));
                        out.1.push(0.5 * len);
                    }
                }
                out
            })
            .collect();
        let n = blocks.iter().map(|b| b.0.len()).sum();
        let mut all = (Vec::with_capacity(n), Vec::with_capacity(n));
        for (normals, areas) in blocks {
            all.0.extend_from_slice(&normals);
            all.1.extend_from_slice(&areas);
        }
        all
    };
    let (normals, areas) = unit_normals(candidate);
    let (support_normals, support_areas) = unit_normals(support);
    if normals.is_empty() {
        return StackAxis::TooWeak { best_share: 0.0 };
    }
    // Bins of half the radius over [-1, 1]^3; each normal counts at n and -n.
    let bin = params.radius / 2.0;
    let per_axis = (2.0 / bin).ceil() as usize + 1;
    let index = |v: [f64; 3]| -> usize {
        let c = v.map(|x| (((x + 1.0) / bin).floor() as usize).min(per_axis - 1));
        (c[2] * per_axis + c[1]) * per_axis + c[0]
    };
    let n_bins = per_axis * per_axis * per_axis;
    // Area per bin, summed per fixed chunk and then in chunk order (same bits for any thread count).
    let partial: Vec<Vec<f64>> = normals
        .par_chunks(65_536)
        .zip(areas.par_chunks(65_536))
        .map(|(chunk, area)| {
            let mut c = vec![0.0f64; n_bins];
            for (&n, &a) in chunk.iter().zip(area) {
                c[index(n)] += a;
                c[index(n.map(|x| -x))] += a;
            }
            c
        })
        .collect();
    let mut counts = vec![0.0f64; n_bins];
    for p in &partial {
        for (x, y) in counts.iter_mut().zip(p) {
            *x += y;
        }
    }
    drop(partial);
    let occupied: Vec<usize> = (0..n_bins).filter(|&b| counts[b] > 0.0).collect();
    let centre = |b: usize| -> [f64; 3] {
        let (i, j, k) = (
            b % per_axis,
            (b / per_axis) % per_axis,
            b / (per_axis * per_axis),
        );
        [i, j, k].map(|c| -1.0 + (c as f64 + 0.5) * bin)
    };
    let reach = (params.radius / bin).ceil() as isize;
    let neighbours = |b: usize| -> Vec<usize> {
        let (i, j, k) = (
            (b % per_axis) as isize,
            ((b / per_axis) % per_axis) as isize,
            (b / (per_axis * per_axis)) as isize,
        );
        let c = centre(b);
        let mut out = Vec::new();
        for dk in -reach..=reach {
            for dj in -reach..=reach {
                for di in -reach..=reach {
                    let (x, y, z) = (i + di, j + dj, k + dk);
                    let n = per_axis as isize;
                    if x < 0 || y < 0 || z < 0 || x >= n || y >= n || z >= n {
                        continue;
                    }
                    let o = ((z * n + y) * n + x) as usize;
                    let d = centre(o);
                    if counts[o] > 0.0
                        && (0..3).map(|a| (c[a] - d[a]).powi(2)).sum::<f64>()
                            <= params.radius * params.radius
                    {
                        out.push(o);
                    }
                }
            }
        }
        out
    };
    // Density of a bin: samples within the radius of its centre.
    let density: Vec<(usize, f64)> = occupied
        .par_iter()
        .map(|&b| (b, neighbours(b).iter().map(|&o| counts[o]).sum()))
        .collect();
    // Mean density as seen by the samples (area-weighted), and the maximum.
    let total: f64 = density.iter().map(|&(b, _)| counts[b]).sum();
    let mean = density.iter().map(|&(b, d)| d * counts[b]).sum::<f64>() / total;
    let max = density.iter().map(|&(_, d)| d).fold(0.0, f64::max);
    let threshold = 0.5 * (mean + max);
    let dense: std::collections::BTreeSet<usize> = density
        .iter()
        .filter(|&&(_, d)| d >= threshold)
        .map(|&(b, _)| b)
        .collect();
    // Region growing among dense bins; candidate = count-weighted mean of bin centres.
    let mut seen = std::collections::BTreeSet::new();
    let mut candidates: Vec<[f64; 3]> = Vec::new();
    for &start in &dense {
        if !seen.insert(start) {
            continue;
        }
        let mut stack = vec![start];
        let mut sum = [0.0f64; 3];
        while let Some(b) = stack.pop() {
            let c = centre(b);
            for a in 0..3 {
                sum[a] += c[a] * counts[b];
            }
            for o in neighbours(b) {
                if dense.contains(&o) && seen.insert(o) {
                    stack.push(o);
                }
            }
        }
        if let Some(axis) = normalize(sum) {
            let axis = canonical(axis);
            // n and -n clusters give the same line: keep one.
            if !candidates.iter().any(|c| dot(*c, axis).abs() > 0.999) {
                candidates.push(axis);
            }
        }
    }
    let cos_support = params.support_deg.to_radians().cos();
    // Supporting area for an axis, as a share of the total.
    let support = |a: [f64; 3]| {
        deterministic_sum(support_normals.len(), |i| {
            if dot(support_normals[i], a).abs() >= cos_support {
                support_areas[i]
            } else {
                0.0
            }
        }) / total_area
    };
    let shares: Vec<([f64; 3], f64)> = candidates.iter().map(|&c| (c, support(c))).collect();
    let Some(&(best, best_share)) = shares.iter().max_by(|x, y| x.1.total_cmp(&y.1)) else {
        return StackAxis::TooWeak { best_share: 0.0 };
    };
    // Refined from the supporting faces (area-weighted, sign-aligned mean), a few rounds.
    let refined = |mut axis: [f64; 3], rounds: usize| {
        for _ in 0..rounds {
            let sum: [f64; 3] = std::array::from_fn(|k| {
                deterministic_sum(support_normals.len(), |i| {
                    let d = dot(support_normals[i], axis);
                    if d.abs() >= cos_support {
                        support_areas[i] * d.signum() * support_normals[i][k]
                    } else {
                        0.0
                    }
                })
            });
            match normalize(sum) {
                Some(a) => axis = canonical(a),
                None => break,
            }
        }
        axis
    };
    let axis = refined(best, 3);
    let share = support(axis).max(best_share);
    let count = normals
        .par_iter()
        .filter(|&&n| dot(n, axis).abs() >= cos_support)
        .count();
    if share < params.min_support_share || count < params.min_support_faces {
        return StackAxis::TooWeak { best_share: share };
    }
    // The best other direction clearly apart from the axis: a candidate, or the densest bin
    // that did not make the clusters' threshold (the walls of a tube along the slices come in
    // two perpendicular pairs of about equal area; only one may reach it).
    let cos_apart = RUNNER_UP_APART_DEG.to_radians().cos();
    let apart = |d: [f64; 3]| dot(d, axis).abs() < cos_apart;
    let densest_other = density
        .iter()
        .filter_map(|&(b, d)| Some((normalize(centre(b)).filter(|&c| apart(c))?, d, b)))
        .max_by(|x, y| x.1.total_cmp(&y.1).then(y.2.cmp(&x.2)))
        .map(|(c, _, _)| refined(c, 2))
        .filter(|&c| apart(c));
    let (runner_up_axis, runner_up) = shares
        .iter()
        .filter(|(c, _)| apart(*c))
        .copied()
        .chain(densest_other.map(|c| (c, support(c))))
        .fold(
            ([0.0; 3], 0.0),
            |best, x| if x.1 > best.1 { x } else { best },
        );
    // Two directions with about equal flat area name no axis: the larger may be a wall.
    if runner_up >= TIE_SHARE * share {
        return StackAxis::TooWeak { best_share: share };
    }
    StackAxis::Found {
        axis,
        confidence: share,
        n_candidates: candidates.len(),
        runner_up,
        runner_up_deg: if runner_up > 0.0 {
            dot(runner_up_axis, axis).abs().min(1.0).acos().to_degrees()
        } else {
            0.0
        },
        evidence: AxisEvidence::Terraces,
    }
}

/// A direction with at least this share of the winner's support ties with it (the flat walls
/// of a tube along the slice axis: +x/-x against +y/-y, 0.9-1.0 on VTK tubes off their grid).
const TIE_SHARE: f64 = 0.9;

/// Candidates at least this far from the winner count as other directions (degrees).
const RUNNER_UP_APART_DEG: f64 = 10.0;
