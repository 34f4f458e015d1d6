//! Cap detection (Moench 2012, §3.3, Algorithm 3.1): flat regions where a structure was clipped
//! (vessel inlets and outlets, volume-of-interest borders), told apart from staircase terraces
//! by how the surface leaves them: around a cap it turns the same way everywhere, around a
//! terrace it goes up on one side and down on the other.
//!
//! Flat faces (all three vertices with normal curvature <= 5 degrees, or coplanar with two
//! edge neighbours: a cut a few slices tall has no vertex away from a chamfer) form regions,
//! each filled from the flattest face not yet taken over flat faces within the growth limits
//! of it (on a smoothed mesh nearly every face is flat at its sampling, and an unlimited fill
//! joins discs, walls and the rims between); regions under 10 faces are dropped; the rest grow
//! over neighbours of nearly the same orientation; then each region's border vertices are
//! checked for the sign of the largest offset of their outside neighbours along the region
//! normal, or, where the surface within reach beyond rises above them, up: one direction (up
//! to a small minority, for smoothed meshes) makes a cap, and on a closed oriented mesh it must
//! be inwards (a region the surface leaves outwards all round is a dent). That test alone also
//! accepts every flat facet of a convex surface and the top of every lobe, so checks go beyond
//! the paper: following the surface outwards from the border (up to half the region's width)
//! it must turn sharply, as the wall at a cut does (75 degrees or more); the region must be a
//! clipped end (compact, the wall behind it running on along the normal at least as far as the
//! region is long, with the region's cross-section: a lobe's top steps outward into the next
//! terrace, the side of a tube lying across the normal ends within the tube's width); and,
//! when staircase reach is known, most of the border must lie within reach of a staircase,
//! since a cap only matters where staircase smoothing would otherwise reach it (§4.3). A
//! clipped end that cuts the grid obliquely is terraced on a binary surface, with no flat face
//! to grow from; it is found by looking again on a copy smoothed by 10 Laplace iterations,
//! where it is flat (the faces, not the positions, are what the copy contributes).

mod region;

use crate::mesh::face_neighbours::FaceNeighbours;
use crate::mesh::geometry::{dot64, signed_volume, triangle_area_vector};
use crate::mesh::umbrella::{padded, umbrella_pass, unpadded, written_before_read, NeighbourLists};
use crate::mesh::{Mesh, Topology};
use crate::metrics::normal_curvature::TurnLimits;
use rayon::prelude::*;
use region::{examine_region, RegionScratch, Verdict};
use serde::Serialize;

/// Parameters of cap detection.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CapParams {
    /// Largest vertex normal curvature of a flat face (degrees; paper: 5).
    pub flat_deg: f32,
    /// A face whose normal is within this angle (degrees) of two of its edge neighbours' is
    /// flat too: a cut a few slices tall holds no vertex that touches no chamfer.
    pub coplanar_deg: f32,
    /// Smallest flat region considered (faces; paper: 10).
    pub min_faces: usize,
    /// Growth: largest angle between a face and the region face it is reached from (degrees).
    pub grow_step_deg: f32,
    /// Growth: largest angle between a face and the region's initial mean normal (degrees).
    pub grow_total_deg: f32,
    /// How far beyond its border the surface is followed to see it turn, as a share of the
    /// region's width (its smallest extent within its plane).
    pub turn_reach: f32,
    /// Angle (degrees) the surface must turn to, relative to the region normal, within that
    /// reach for a border vertex to count as the rim of a cut.
    pub turn_deg: f32,
    /// Least share of border vertices that must see that turn (a cut's rim all round; on a
    /// smoothed mesh, whose rim is rounded and whose border ragged, fewer border vertices are
    /// nearest to where the wall has turned).
    pub min_turning_border: f32,
    /// Least share of border vertices within staircase reach (when that is given; 0 disables).
    pub min_staircase_border: f32,
    /// Share of border vertices that may see the surface leave the other way (noise on
    /// smoothed meshes); a terrace shows far more.
    pub max_minority: f32,
    /// Slope (offset along the normal over edge length) below which a border vertex shows no
    /// direction.
    pub min_slope: f32,
    /// Caps are also looked for on a copy smoothed by this many uniform Laplace iterations
    /// (lambda 0.5, rims fixed), and one found there that overlaps none found on the mesh
    /// itself is added: a clipped end that cuts the grid obliquely is terraced, with no flat
    /// face to grow from, until smoothed. 0 turns the second look off.
    pub smoothed_copy_iterations: usize,
    /// On the smoothed copy a flat face must also be flat at the mm scale: the normal turns by
    /// at most this much per mm (degrees per mm), so rounded parts, flat at a fine sampling,
    /// are not examined.
    pub smoothed_copy_flat_deg_per_mm: f32,
    /// Largest ratio of a region's length to its width (its largest to smallest extent in its
    /// plane): a tube cut at 70 degrees to its axis gives 2.9.
    pub max_aspect: f32,
    /// A clipped end's wall runs on along the normal with the cut's cross-section: the
    /// cross-section is measured down to this share of the region's width (its smallest
    /// in-plane extent)...
    pub section_depth_share: f32,
    /// ...and the wall must run on to this share of its length (largest extent)...
    pub run_depth_share: f32,
    /// ...both at least this many voxels along the normal when the grid is known.
    pub runs_on_slices: f32,
    /// Largest growth (and, inverted, shrinkage) of the cross-section from half the section
    /// depth to all of it.
    pub max_section_growth: f32,
    /// Largest cross-section at half the section depth, as a multiple of the region's area
    /// (the rim's chamfers or rounding lie between).
    pub max_section_span: f32,
    /// The voxel grid the mesh was made on, when known or found.
    #[serde(skip)]
    pub grid: Option<crate::analysis::grid_frame::Grid>,
}

impl Default for CapParams {
    fn default() -> Self {
        Self {
            flat_deg: 5.0,
            coplanar_deg: 0.5,
            min_faces: 10,
            grow_step_deg: 10.0,
            grow_total_deg: 25.0,
            turn_reach: 0.5,
            turn_deg: 75.0,
            min_turning_border: 0.2,
            min_staircase_border: 0.0,
            max_minority: 0.1,
            min_slope: 0.05,
            smoothed_copy_iterations: 10,
            smoothed_copy_flat_deg_per_mm: 0.5,
            max_aspect: 3.5,
            section_depth_share: 0.25,
            run_depth_share: 1.0,
            runs_on_slices: 2.0,
            max_section_growth: 1.3,
            max_section_span: 2.0,
            grid: None,
        }
    }
}

/// One detected cap.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Cap {
    /// The cap's faces, ascending.
    pub faces: Vec<u32>,
    /// The cap's vertices, each once, in the order detection met them (no order is promised:
    /// its users test membership or take the rim from the faces).
    pub vertices: Vec<u32>,
    /// Area-weighted unit normal (outward for outward-oriented meshes).
    pub normal: [f32; 3],
    pub area_mm2: f64,
    /// Why it is a cap: the figures of the clipped-end test.
    pub evidence: CapEvidence,
}

/// The figures that made a flat region a cap (a clipped end): its size and how the surface
/// behind it runs on.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CapEvidence {
    /// Smallest and largest extent within its plane (mm).
    pub width_mm: f32,
    pub length_mm: f32,
    /// Depth (mm) down to which the cross-section was measured, and to which the wall runs on.
    pub section_depth_mm: f32,
    pub run_depth_mm: f32,
    /// Cross-section at half the section depth over the region's area (the rim's chamfers or
    /// rounding make it exceed 1).
    pub span: f64,
    /// Cross-section at the section depth over that at half of it (1 for a straight tube).
    pub growth: f64,
}

/// What cap detection found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CapDetection {
    pub caps: Vec<Cap>,
    /// Flat regions large enough to examine.
    pub n_regions: usize,
    /// Regions rejected because the surface leaves them both ways (staircase terraces).
    pub n_terraces: usize,
    /// Caps found only on the smoothed copy (terraced oblique ends), included in `caps`.
    pub n_from_smoothed_copy: usize,
    /// False when caps were not looked for (see [`CapDetection::not_searched`]).
    #[serde(skip)]
    pub searched: bool,
}

impl CapDetection {
    /// No caps because none were looked for: `smooth` with caps smoothed like the rest, where
    /// they would change nothing.
    pub fn not_searched() -> CapDetection {
        CapDetection {
            caps: Vec::new(),
            n_regions: 0,
            n_terraces: 0,
            n_from_smoothed_copy: 0,
            searched: false,
        }
    }

    /// Per-vertex flag: the vertex belongs to a cap.
    pub fn cap_vertices(&self, n_vertices: usize) -> Vec<bool> {
        let mut on = vec![false; n_vertices];
        for c in &self.caps {
            for &v in &c.vertices {
                on[v as usize] = true;
            }
        }
        on
    }
}

fn angle_deg(a: [f32; 3], b: [f32; 3]) -> f32 {
    (a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

const NONE: u32 = u32::MAX;

/// Detects caps. `staircase_reach` (one flag per vertex: within tau_max of a staircase vertex
/// along the surface) enables the staircase-border check.
pub fn detect_caps(
    mesh: &Mesh,
    topology: &Topology,
    staircase_reach: Option<&[bool]>,
    params: &CapParams,
) -> CapDetection {
    cap_candidates(mesh, topology, params).settle(mesh, staircase_reach, params)
}

/// Caps found before the staircase-border check, from both looks: what [`detect_caps`] finds
/// without needing the staircase reach, so that the search can run while the staircases are
/// still being measured.
#[derive(Debug, Clone)]
pub struct CapCandidates {
    plain: Look,
    smoothed: Option<Look>,
}

/// What one look found: the regions that passed every check but the staircase border.
#[derive(Debug, Clone)]
struct Look {
    candidates: Vec<Candidate>,
    n_regions: usize,
    n_terraces: usize,
}

/// A cap with its border vertices (sorted), kept for the staircase-border check.
#[derive(Debug, Clone)]
struct Candidate {
    cap: Cap,
    border: Vec<u32>,
}

/// [`CapCandidates`] of a mesh: both looks, side by side.
pub fn cap_candidates(mesh: &Mesh, topology: &Topology, params: &CapParams) -> CapCandidates {
    let search = CapSearch::new(mesh, topology);
    // The two looks are independent and mostly serial (flood fills, growth): they run side by
    // side, and their results are merged in the same order as ever.
    let (plain, smoothed) = rayon::join(
        || search.on_mesh(&TurnLimits::new(mesh, topology), topology, params),
        || search.on_smoothed_copy(mesh, topology, params),
    );
    CapCandidates::new(plain, smoothed)
}

/// What both looks of cap detection share (the faces' edge neighbours), so that each look can
/// run beside other analyses of the mesh.
pub struct CapSearch {
    adjacency: FaceNeighbours,
    /// Whether the faces face out of the structure (its signed volume is positive), where the
    /// mesh is a closed, consistently oriented manifold; unknown otherwise.
    outward: Option<bool>,
    /// Per-vertex scratch for examining regions, shared by both looks (one per worker busy at
    /// a time, not one per worker and look).
    scratch: std::sync::Mutex<Vec<RegionScratch>>,
}

/// What one look of cap detection found, for [`CapCandidates::new`].
#[derive(Debug, Clone)]
pub struct CapLook(Look);

impl CapSearch {
    /// Finds the faces' edge neighbours of `mesh` (whose topology is `topology`).
    pub fn new(mesh: &Mesh, topology: &Topology) -> CapSearch {
        let volume = topology
            .is_closed_oriented_manifold()
            .then(|| signed_volume(mesh));
        CapSearch {
            adjacency: FaceNeighbours::build(mesh, topology),
            outward: volume
                .filter(|v| *v != 0.0 && v.is_finite())
                .map(|v| v > 0.0),
            scratch: std::sync::Mutex::new(Vec::new()),
        }
    }

    /// The look at the mesh whose normals `turns` holds (computed once for every analysis of
    /// the mesh), as it is.
    pub fn on_mesh(&self, turns: &TurnLimits, topology: &Topology, params: &CapParams) -> CapLook {
        CapLook(caps_of(turns, topology, self, params, f32::INFINITY))
    }

    /// The look at a copy of `mesh` smoothed by `params.smoothed_copy_iterations` Laplace
    /// iterations (none when that is 0): mostly serial, so it is best started first.
    pub fn on_smoothed_copy(
        &self,
        mesh: &Mesh,
        topology: &Topology,
        params: &CapParams,
    ) -> Option<CapLook> {
        (params.smoothed_copy_iterations > 0).then(|| {
            let copy = mesh.with_checked_positions(low_pass(
                mesh,
                topology,
                params.smoothed_copy_iterations,
            ));
            CapLook(caps_of(
                &TurnLimits::new(&copy, topology),
                topology,
                self,
                params,
                params.smoothed_copy_flat_deg_per_mm,
            ))
        })
    }
}

impl CapCandidates {
    /// The candidates of the two looks of [`CapSearch`].
    pub fn new(plain: CapLook, smoothed: Option<CapLook>) -> CapCandidates {
        CapCandidates {
            plain: plain.0,
            smoothed: smoothed.map(|look| look.0),
        }
    }

    /// The caps: candidates with enough of their border within `staircase_reach` (when given),
    /// those of the smoothed copy added where they overlap none of the mesh's own. `mesh` is
    /// the one the candidates were found on.
    pub fn settle(
        self,
        mesh: &Mesh,
        staircase_reach: Option<&[bool]>,
        params: &CapParams,
    ) -> CapDetection {
        let near_staircases = |c: &Candidate| {
            staircase_reach.is_none_or(|reach| {
                let on = c.border.iter().filter(|&&v| reach[v as usize]).count();
                (on as f32) >= params.min_staircase_border * c.border.len() as f32
            })
        };
        let mut detection = CapDetection {
            caps: (self.plain.candidates.into_iter())
                .filter(|c| near_staircases(c))
                .map(|c| c.cap)
                .collect(),
            n_regions: self.plain.n_regions,
            n_terraces: self.plain.n_terraces,
            n_from_smoothed_copy: 0,
            searched: true,
        };
        let Some(found) = self.smoothed else {
            return detection;
        };
        let mut taken = vec![false; mesh.n_triangles()];
        for c in &detection.caps {
            for &f in &c.faces {
                taken[f as usize] = true;
            }
        }
        for candidate in found.candidates {
            if !near_staircases(&candidate) {
                continue;
            }
            let mut cap = candidate.cap;
            if cap.faces.iter().any(|&f| taken[f as usize]) {
                continue;
            }
            for &f in &cap.faces {
                taken[f as usize] = true;
            }
            // Normal and area of the mesh itself (the terraced plane's mean normal).
            cap.normal = region_normal(mesh, &cap.faces);
            cap.area_mm2 = region_area(mesh, &cap.faces);
            detection.caps.push(cap);
            detection.n_from_smoothed_copy += 1;
        }
        detection
    }
}

/// Positions after `iterations` uniform umbrella steps (lambda 0.5) with rim and non-manifold
/// vertices fixed: a low-pass copy on which a terraced plane is flat.
fn low_pass(mesh: &Mesh, topology: &Topology, iterations: usize) -> Vec<[f32; 3]> {
    let (offsets, neighbors) = topology.neighbor_csr();
    // Step scale 1, or 0 where a vertex stays: on a rim or non-manifold edge, or isolated.
    let irregular = topology.on_irregular_edge();
    let scale: Vec<f32> = (offsets.windows(2).zip(irregular))
        .map(|(w, stays)| if w[0] == w[1] || stays { 0.0 } else { 1.0 })
        .collect();
    let rows = NeighbourLists::new(offsets, neighbors, None);
    let mut a = padded(mesh.positions());
    let mut b = written_before_read(&a);
    for _ in 0..iterations {
        umbrella_pass(&a, &mut b, &rows, &scale, 0.5, None);
        std::mem::swap(&mut a, &mut b);
    }
    unpadded(&a)
}

/// Caps of the mesh whose normals `turns` holds, as it is (Algorithm 3.1 with the checks
/// above); flat faces turn by at most `flat_deg_per_mm` too (infinite: no limit, and faces
/// coplanar with two neighbours count as flat).
fn caps_of(
    turns: &TurnLimits,
    topology: &Topology,
    search: &CapSearch,
    params: &CapParams,
    flat_deg_per_mm: f32,
) -> Look {
    let (adjacency, scratch_pool) = (&search.adjacency, &search.scratch);
    let mesh = turns.mesh();
    let n_faces = mesh.n_triangles();
    let tris = mesh.triangles();
    let flat_vertex = turns.within(params.flat_deg, flat_deg_per_mm);
    let normals = turns.face_normals();
    let degenerate = |f: usize| normals[f] == [0.0; 3];
    // Per face: how far its edge neighbours turn from it (the sum of 1 - cos, to pick seeds
    // from the flattest faces first), and whether at least two of them are coplanar with it.
    let cos_coplanar = params.coplanar_deg.to_radians().cos();
    let roughness: Vec<(f32, bool)> = (0..n_faces as u32)
        .into_par_iter()
        .map_init(Vec::new, |scratch, f| {
            let n = normals[f as usize];
            if n == [0.0; 3] {
                return (f32::INFINITY, false);
            }
            let (mut turn, mut coplanar) = (0.0f32, 0);
            adjacency.each((mesh, topology), f, scratch, |g| {
                let c = dot(n, normals[g as usize]);
                turn += 1.0 - c;
                coplanar += usize::from(c >= cos_coplanar);
            });
            (turn, coplanar >= 2)
        })
        .collect();
    // Flat: every vertex flat (the paper), or coplanar with two neighbours (the rows of a cut
    // a few slices tall, whose every vertex touches a chamfer); not on the smoothed copy,
    // where a flat face must be flat at the mm scale, which two neighbours do not show.
    let coplanar_is_flat = flat_deg_per_mm == f32::INFINITY;
    let flat: Vec<bool> = (0..n_faces)
        .map(|f| {
            !degenerate(f)
                && ((coplanar_is_flat && roughness[f].1)
                    || tris[f].iter().all(|&v| flat_vertex[v as usize]))
        })
        .collect();
    // Growth limits as cosines (no acos per visited face).
    let cos_step = params.grow_step_deg.to_radians().cos();
    let cos_total = params.grow_total_deg.to_radians().cos();
    // Flat regions, each filled from the flattest face not yet taken over flat faces within
    // the growth limits of it: on a smoothed mesh, flat at a fine sampling almost everywhere,
    // a flood fill without them would join the discs, the walls and the rounded rims between.
    let seeds = flattest_first(&flat, &roughness);
    let mut region = vec![NONE; n_faces];
    let mut regions: Vec<Vec<u32>> = Vec::new();
    let mut scratch = Vec::new();
    for &start in &seeds {
        if region[start as usize] != NONE {
            continue;
        }
        let id = regions.len() as u32;
        let mut members = vec![start];
        region[start as usize] = id;
        let seed_normal = normals[start as usize];
        let mut i = 0;
        while let Some(&f) = members.get(i) {
            adjacency.each((mesh, topology), f, &mut scratch, |g| {
                let n = normals[g as usize];
                if flat[g as usize]
                    && region[g as usize] == NONE
                    && dot(n, normals[f as usize]) >= cos_step
                    && dot(n, seed_normal) >= cos_total
                {
                    region[g as usize] = id;
                    members.push(g);
                }
            });
            i += 1;
        }
        regions.push(members);
    }
    // Drop small regions (their faces become free for growth).
    let mut kept: Vec<Vec<u32>> = Vec::new();
    for r in regions {
        if r.len() >= params.min_faces {
            let id = kept.len() as u32;
            for &f in &r {
                region[f as usize] = id;
            }
            kept.push(r);
        } else {
            for &f in &r {
                region[f as usize] = NONE;
            }
        }
    }
    for (id, faces) in kept.iter_mut().enumerate() {
        let id = id as u32;
        let mean = region_normal(mesh, faces);
        // Grow over neighbours of nearly the same orientation, breadth first: the faces not
        // yet visited are the queue.
        let mut next = 0;
        while let Some(&f) = faces.get(next) {
            next += 1;
            adjacency.each((mesh, topology), f, &mut scratch, |g| {
                let gi = g as usize;
                if region[gi] == NONE
                    && !degenerate(gi)
                    && dot(normals[gi], normals[f as usize]) >= cos_step
                    && dot(normals[gi], mean) >= cos_total
                {
                    region[gi] = id;
                    faces.push(g);
                }
            });
        }
    }
    // A grown region's verdict depends only on its faces (a face goes to the first region
    // that reaches it), so all regions are grown first, then examined side by side (a large
    // one with its large steps in parallel too) and counted in order.
    let planes = TerracePlanes::of(mesh, &kept);
    let verdicts: Vec<Verdict> = (kept.par_iter().enumerate())
        .map(|(i, faces)| {
            let gap = || planes.gap(i);
            let taken = scratch_pool.lock().map(|mut pool| pool.pop());
            let mut scratch = taken
                .ok()
                .flatten()
                .filter(|s| s.fits(mesh.n_vertices(), n_faces))
                .unwrap_or_else(|| RegionScratch::new(mesh.n_vertices(), n_faces));
            let verdict = examine_region(
                mesh,
                topology,
                (normals, search.outward),
                (faces, gap),
                &mut scratch,
                params,
            );
            if let Ok(mut pool) = scratch_pool.lock() {
                pool.push(scratch);
            }
            verdict
        })
        .collect();
    let mut look = Look {
        candidates: Vec::new(),
        n_regions: kept.len(),
        n_terraces: 0,
    };
    for verdict in verdicts {
        match verdict {
            Verdict::Cap(candidate) => look.candidates.push(candidate),
            Verdict::Terrace => look.n_terraces += 1,
            Verdict::Other => {}
        }
    }
    look
}

/// The flat faces, flattest first: by how far their neighbours turn from them, in buckets (a
/// counting sort, in face order within a bucket; the order only has to start each region
/// well inside a flat area rather than on a rounded rim).
fn flattest_first(flat: &[bool], roughness: &[(f32, bool)]) -> Vec<u32> {
    const BUCKETS: usize = 64;
    // sqrt(sum of 1 - cos) is about the neighbours' turn in radians over sqrt(2): buckets of
    // about a quarter of a degree, the last holding every turn from 16 degrees.
    let bucket = |f: usize| ((roughness[f].0.max(0.0).sqrt() * 320.0) as usize).min(BUCKETS - 1);
    let mut counts = [0usize; BUCKETS + 1];
    for f in (0..flat.len()).filter(|&f| flat[f]) {
        counts[bucket(f) + 1] += 1;
    }
    for b in 0..BUCKETS {
        counts[b + 1] += counts[b];
    }
    let mut seeds = vec![0u32; counts[BUCKETS]];
    for f in (0..flat.len()).filter(|&f| flat[f]) {
        let slot = &mut counts[bucket(f)];
        seeds[*slot] = f as u32;
        *slot += 1;
    }
    seeds
}

/// Each flat region's plane: its normal, a point of it (the mean of its faces' first corners)
/// and its area; to find, for the few regions that need it, the spacing of the terraces
/// facing the same way (a pass over every region per region asked).
struct TerracePlanes(Vec<([f32; 3], [f64; 3], f64)>);

impl TerracePlanes {
    fn of(mesh: &Mesh, regions: &[Vec<u32>]) -> Self {
        let (tris, p) = (mesh.triangles(), mesh.positions());
        TerracePlanes(
            regions
                .par_iter()
                .map(|faces| {
                    let mut point = [0.0f64; 3];
                    for &f in faces {
                        let q = p[tris[f as usize][0] as usize];
                        (0..3).for_each(|k| point[k] += f64::from(q[k]));
                    }
                    let n_faces = faces.len().max(1) as f64;
                    let point = point.map(|x| x / n_faces);
                    (region_normal(mesh, faces), point, region_area(mesh, faces))
                })
                .collect(),
        )
    }

    /// The spacing (mm) of the terraces facing the way region `i` faces (within 2 degrees):
    /// on a mesh from slices whose grid is unknown (rotated), how deep to look behind a flat
    /// region for the next terrace. It is the smallest gap between the planes of consecutive
    /// such regions that another gap repeats (within 5 %): slices repeat, a vessel's far end
    /// or a side branch does not. Infinite where there is none.
    fn gap(&self, i: usize) -> f32 {
        let cos_parallel = 2.0f32.to_radians().cos();
        let n = self.0[i].0;
        let parallel: Vec<&([f32; 3], [f64; 3], f64)> = (self.0.iter())
            .filter(|&&(m, _, _)| dot(n, m) >= cos_parallel)
            .collect();
        // The levels along the regions' common normal (their area-weighted mean): one
        // region's own normal, off by a tenth of a degree, would shift planes 100 mm apart by
        // 0.2 mm. Differences of levels do not depend on where the mesh lies.
        let mut common = [0.0f64; 3];
        for &&(m, _, area) in &parallel {
            (0..3).for_each(|k| common[k] += area * f64::from(m[k]));
        }
        let len = dot64(common, common).sqrt();
        if !(len > 0.0 && len.is_finite()) {
            return f32::INFINITY;
        }
        let common = common.map(|x| x / len);
        let mut levels: Vec<f64> = (parallel.iter())
            .map(|&&(_, point, _)| dot64(point, common))
            .collect();
        levels.sort_unstable_by(f64::total_cmp);
        // Gaps between distinct planes (regions of one terrace split in two are one).
        let mut gaps: Vec<f64> = levels
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|&g| g > 1e-3)
            .collect();
        gaps.sort_unstable_by(f64::total_cmp);
        gaps.windows(2)
            .find(|w| w[1] <= 1.05 * w[0])
            .map_or(f32::INFINITY, |w| w[0] as f32)
    }
}

/// Area of a set of faces (mm²).
fn region_area(mesh: &Mesh, faces: &[u32]) -> f64 {
    faces
        .iter()
        .map(|&f| {
            let a = triangle_area_vector(mesh, mesh.triangles()[f as usize]);
            0.5 * (a.iter().map(|x| (*x as f64).powi(2)).sum::<f64>()).sqrt()
        })
        .sum()
}

/// Area-weighted unit normal of a set of faces. The area vectors of a large region are computed
/// side by side, then summed in face order as for a small one: the same bits either way.
fn region_normal(mesh: &Mesh, faces: &[u32]) -> [f32; 3] {
    let area_vector = |f: u32| triangle_area_vector(mesh, mesh.triangles()[f as usize]);
    let mut sum = [0.0f64; 3];
    let mut add = |a: [f32; 3]| {
        for k in 0..3 {
            sum[k] += a[k] as f64;
        }
    };
    if faces.len() < 1 << 16 {
        faces.iter().for_each(|&f| add(area_vector(f)));
    } else {
        let vectors: Vec<[f32; 3]> = faces.par_iter().map(|&f| area_vector(f)).collect();
        vectors.into_iter().for_each(add);
    }
    unit_f32(sum)
}

/// `v` scaled to unit length, in f32; zero for a zero vector.
fn unit_f32(v: [f64; 3]) -> [f32; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if len > 0.0 {
        v.map(|x| (x / len) as f32)
    } else {
        [0.0; 3]
    }
}
