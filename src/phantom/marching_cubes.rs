//! Discrete marching cubes on a label volume: one closed, consistently oriented 2-manifold
//! surface per label, with every vertex exactly at the midpoint of a grid edge between a voxel
//! of the label and one outside it (the assumption Bade 2007 relies on).
//!
//! The case table is not typed in by hand; it is derived for all 256 corner configurations:
//! on each cube face the contour segments are found as in marching squares, with ambiguous
//! faces (two diagonal inside corners) always resolved by separating the inside corners. The
//! rule depends only on the face, so the two cells sharing a face agree and no holes appear.
//! Segments are oriented with the inside on their right seen from outside the cube, chained
//! into loops, and each loop is triangulated without diagonals that lie in a cube face.

use super::volume::LabelVolume;
use crate::mesh::Mesh;
use rayon::prelude::*;
use std::sync::OnceLock;

/// Cube corner `c` sits at (c & 1, (c >> 1) & 1, (c >> 2) & 1).
fn corner(c: usize) -> [f64; 3] {
    [(c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64]
}

/// The 12 cube edges as (lower corner, upper corner); axis = which bit differs.
const EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// The 6 cube faces: corners in cyclic order, outward normal.
const FACES: [([usize; 4], [f64; 3]); 6] = [
    ([0, 2, 6, 4], [-1.0, 0.0, 0.0]),
    ([1, 3, 7, 5], [1.0, 0.0, 0.0]),
    ([0, 1, 5, 4], [0.0, -1.0, 0.0]),
    ([2, 3, 7, 6], [0.0, 1.0, 0.0]),
    ([0, 1, 3, 2], [0.0, 0.0, -1.0]),
    ([4, 5, 7, 6], [0.0, 0.0, 1.0]),
];

fn edge_between(a: usize, b: usize) -> usize {
    EDGES
        .iter()
        .position(|&(p, q)| (p, q) == (a.min(b), a.max(b)))
        .expect("face corners are joined by cube edges")
}

fn midpoint(edge: usize) -> [f64; 3] {
    let (a, b) = EDGES[edge];
    let (p, q) = (corner(a), corner(b));
    std::array::from_fn(|k| 0.5 * (p[k] + q[k]))
}

/// Bit mask of the faces an edge lies on.
pub fn edge_faces(edge: usize) -> u8 {
    let (a, b) = EDGES[edge];
    FACES
        .iter()
        .enumerate()
        .filter(|(_, (c, _))| c.contains(&a) && c.contains(&b))
        .fold(0, |m, (f, _)| m | 1 << f)
}

/// Triangles (as cube-edge triples, outward-oriented) for each of the 256 configurations.
pub fn case_table() -> &'static [Vec<[u8; 3]>; 256] {
    static TABLE: OnceLock<[Vec<[u8; 3]>; 256]> = OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|config| triangulate_case(config as u8)))
}

/// Directed contour segments on the cube faces for one configuration.
pub fn face_segments(config: u8) -> Vec<(usize, usize)> {
    let inside = |c: usize| config >> c & 1 == 1;
    let mut segments = Vec::new();
    for (q, normal) in FACES {
        let changes: Vec<usize> = (0..4)
            .filter(|&k| inside(q[k]) != inside(q[(k + 1) % 4]))
            .collect();
        let edge = |k: usize| edge_between(q[k % 4], q[(k + 1) % 4]);
        let mut add = |e0: usize, e1: usize, reference: usize| {
            // Inside on the right, seen from outside the cube: m . ((b - a) x (c - a)) < 0.
            let (a, b, c) = (midpoint(e0), midpoint(e1), corner(reference));
            let (u, v) = (
                [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
                [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
            );
            let cross = [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ];
            let side = normal[0] * cross[0] + normal[1] * cross[1] + normal[2] * cross[2];
            segments.push(if side < 0.0 { (e0, e1) } else { (e1, e0) });
        };
        match changes.len() {
            2 => {
                let reference = q.iter().copied().find(|&c| inside(c)).unwrap_or(q[0]);
                add(edge(changes[0]), edge(changes[1]), reference);
            }
            4 => {
                // Ambiguous face: cut off each inside corner separately.
                for (k, &c) in q.iter().enumerate() {
                    if inside(c) {
                        add(edge(k + 3), edge(k), c);
                    }
                }
            }
            _ => {}
        }
    }
    segments
}

/// Chains the segments into loops and triangulates each loop.
fn triangulate_case(config: u8) -> Vec<[u8; 3]> {
    let segments = face_segments(config);
    let mut next = [usize::MAX; 12];
    for &(a, b) in &segments {
        next[a] = b;
    }
    let mut used = [false; 12];
    let mut triangles = Vec::new();
    for &(start, _) in &segments {
        if used[start] {
            continue;
        }
        let mut polygon = Vec::new();
        let mut e = start;
        while !used[e] && e != usize::MAX {
            used[e] = true;
            polygon.push(e);
            e = next[e];
        }
        triangulate_loop(&polygon, &mut triangles);
    }
    triangles
}

/// Minimum-weight triangulation of a loop of cube edges (n <= 12) in which a diagonal between
/// two edges on a common cube face costs extra: such a diagonal would lie in the face, where the
/// neighbouring cell could use it too.
#[allow(clippy::needless_range_loop)] // the DP reads cost[i][k] and cost[k][j]
fn triangulate_loop(polygon: &[usize], out: &mut Vec<[u8; 3]>) {
    let n = polygon.len();
    if n < 3 {
        return;
    }
    let weight = |i: usize, j: usize| -> f64 {
        if (i + 1) % n == j || (j + 1) % n == i {
            return 0.0;
        }
        let (a, b) = (midpoint(polygon[i]), midpoint(polygon[j]));
        let len2: f64 = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum();
        let shares_face = edge_faces(polygon[i]) & edge_faces(polygon[j]) != 0;
        len2 + if shares_face { 1000.0 } else { 0.0 }
    };
    // cost[i][j]: best triangulation of the sub-polygon i..=j; split[i][j]: its apex.
    let mut cost = vec![vec![0.0f64; n]; n];
    let mut split = vec![vec![0usize; n]; n];
    for gap in 2..n {
        for i in 0..n - gap {
            let j = i + gap;
            let mut best = f64::INFINITY;
            for k in i + 1..j {
                let c = cost[i][k] + cost[k][j] + weight(i, k) + weight(k, j);
                if c < best {
                    best = c;
                    split[i][j] = k;
                }
            }
            cost[i][j] = best;
        }
    }
    let mut stack = vec![(0, n - 1)];
    while let Some((i, j)) = stack.pop() {
        if j < i + 2 {
            continue;
        }
        let k = split[i][j];
        out.push([polygon[i] as u8, polygon[k] as u8, polygon[j] as u8]);
        stack.push((i, k));
        stack.push((k, j));
    }
}

/// What happens where a label touches the volume border.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BorderEnds {
    /// Closed by a flat cap half a voxel outside the border (as if the volume were padded).
    #[default]
    Capped,
    /// Left open: a clipped end with a boundary loop on the border.
    Open,
}

/// Runs of `label` along x, per row of one slice, in padded x coordinates (voxel i -> i + 1).
struct SliceRuns {
    /// Row j's runs are `runs[offsets[j]..offsets[j + 1]]`.
    offsets: Vec<u32>,
    runs: Vec<(u32, u32)>,
}

fn slice_runs(volume: &LabelVolume, label: u16, k: usize) -> SliceRuns {
    let [nx, ny, _] = volume.dims;
    let mut offsets = Vec::with_capacity(ny + 1);
    let mut runs = Vec::new();
    offsets.push(0);
    for j in 0..ny {
        let row = &volume.labels[volume.index(0, j, k)..volume.index(0, j, k) + nx];
        let mut i = 0;
        while i < nx {
            if row[i] == label {
                let start = i;
                while i < nx && row[i] == label {
                    i += 1;
                }
                runs.push((start as u32 + 1, i as u32 + 1));
            } else {
                i += 1;
            }
        }
        offsets.push(runs.len() as u32);
    }
    SliceRuns { offsets, runs }
}

/// Whether padded x lies in one of the half-open runs.
#[inline]
fn in_runs(runs: &[(u32, u32)], x: u32) -> bool {
    let i = runs.partition_point(|&(a, _)| a <= x);
    i > 0 && x < runs[i - 1].1
}

/// Extracts the surface of `label` with discrete marching cubes. Vertices are numbered in
/// order of their grid edge (slice by slice, like marching-cubes output), so the result is
/// deterministic and has the memory locality real meshes have.
///
/// Work is proportional to the surface, not the volume: each row of the label is reduced to
/// runs, and only cells where the four rows around a cell row differ or change are visited.
pub fn extract_surface(volume: &LabelVolume, label: u16, ends: BorderEnds) -> Mesh {
    extract(volume, label, ends, None)
}

/// Like [`extract_surface`], but each vertex is placed where a scalar field (one value per
/// voxel, negative inside the label, positive outside) crosses zero along its grid edge, as
/// marching cubes does on a smooth (e.g. Gaussian-filtered) image. The topology is the same.
pub fn extract_surface_interpolated(
    volume: &LabelVolume,
    label: u16,
    ends: BorderEnds,
    field: &[f32],
) -> Mesh {
    extract(volume, label, ends, Some(field))
}

fn extract(volume: &LabelVolume, label: u16, ends: BorderEnds, field: Option<&[f32]>) -> Mesh {
    let table = case_table();
    let [nx, ny, nz] = volume.dims;
    // Padded grid: point P = voxel index + 1, with a background layer all round.
    let (px, py) = (nx + 2, ny + 2);
    let slices: Vec<SliceRuns> = (0..nz)
        .into_par_iter()
        .map(|k| slice_runs(volume, label, k))
        .collect();
    let row = |j: usize, k: usize| -> &[(u32, u32)] {
        if j < 1 || k < 1 || j > ny || k > nz {
            return &[];
        }
        let s = &slices[k - 1];
        &s.runs[s.offsets[j - 1] as usize..s.offsets[j] as usize]
    };
    let key =
        |i: usize, j: usize, k: usize, axis: usize| (((k * py + j) * px + i) * 3 + axis) as u64;
    // Cells span padded points c..=c+1; open ends keep only cells inside the real volume.
    let cell_range = |n: usize| match ends {
        BorderEnds::Capped => 0..n + 1,
        BorderEnds::Open => 1..n,
    };
    let (ri, rj) = (cell_range(nx), cell_range(ny));
    let slabs: Vec<Vec<[u64; 3]>> = cell_range(nz)
        .into_par_iter()
        .map(|ck| {
            let mut tris = Vec::new();
            let mut events: Vec<u32> = Vec::new();
            let mut cells: Vec<u32> = Vec::new();
            for cj in rj.clone() {
                // Corner rows in bit order: (dy, dz) = (0,0), (1,0), (0,1), (1,1).
                let rows = [
                    row(cj, ck),
                    row(cj + 1, ck),
                    row(cj, ck + 1),
                    row(cj + 1, ck + 1),
                ];
                events.clear();
                for r in &rows {
                    for &(a, b) in r.iter() {
                        events.extend([a, b]);
                    }
                }
                if events.is_empty() {
                    continue;
                }
                events.sort_unstable();
                events.dedup();
                let status = |x: u32| {
                    rows.iter()
                        .enumerate()
                        .fold(0u8, |s, (r, runs)| s | (in_runs(runs, x) as u8) << r)
                };
                cells.clear();
                for (m, &start) in events.iter().enumerate() {
                    let end = events.get(m + 1).copied().unwrap_or(px as u32);
                    if start > 0 {
                        cells.push(start - 1);
                    }
                    let s = status(start);
                    if s != 0 && s != 15 {
                        cells.extend(start..end);
                    }
                }
                cells.dedup();
                for &ci in cells.iter() {
                    let ci = ci as usize;
                    if !ri.contains(&ci) {
                        continue;
                    }
                    let (lo, hi) = (status(ci as u32), status(ci as u32 + 1));
                    // Corner c = dx + 2 dy + 4 dz; row bit r = dy + 2 dz.
                    let mut config = 0u8;
                    for r in 0..4 {
                        config |= ((lo >> r) & 1) << (2 * r);
                        config |= ((hi >> r) & 1) << (2 * r + 1);
                    }
                    for t in &table[config as usize] {
                        tris.push(t.map(|e| {
                            let (a, b) = EDGES[e as usize];
                            let axis = (a ^ b).trailing_zeros() as usize;
                            key(ci + (a & 1), cj + ((a >> 1) & 1), ck + ((a >> 2) & 1), axis)
                        }));
                    }
                }
            }
            tris
        })
        .collect();
    let mut keys: Vec<u64> = slabs.iter().flatten().flatten().copied().collect();
    keys.par_sort_unstable();
    keys.dedup();
    let positions: Vec<[f32; 3]> = keys
        .par_iter()
        .map(|&k| {
            let axis = (k % 3) as usize;
            let p = k / 3;
            let index = [
                p % px as u64,
                (p / px as u64) % py as u64,
                p / (px * py) as u64,
            ];
            let t = field.map_or(0.5, |f| crossing(volume, f, index, axis));
            std::array::from_fn(|a| {
                let step = if a == axis { t } else { 0.0 };
                (volume.origin[a] + (index[a] as f64 - 1.0 + step) * volume.spacing[a]) as f32
            })
        })
        .collect();
    let triangles: Vec<[u32; 3]> = slabs
        .par_iter()
        .flat_map_iter(|slab| {
            slab.iter()
                .map(|t| t.map(|k| keys.partition_point(|&x| x < k) as u32))
        })
        .collect();
    Mesh::from_checked_parts(positions, triangles)
}

/// Where along the grid edge from padded point `index` in direction `axis` the field crosses
/// zero, as a fraction in [0.02, 0.98] (0.5 if the field does not change sign there).
fn crossing(volume: &LabelVolume, field: &[f32], index: [u64; 3], axis: usize) -> f64 {
    // The padding layer counts as outside by half a voxel.
    let value = |q: [u64; 3]| -> f64 {
        if (0..3).all(|a| q[a] >= 1 && q[a] as usize <= volume.dims[a]) {
            field[volume.index(q[0] as usize - 1, q[1] as usize - 1, q[2] as usize - 1)] as f64
        } else {
            0.5 * volume.spacing[axis]
        }
    };
    let mut upper = index;
    upper[axis] += 1;
    let (fa, fb) = (value(index), value(upper));
    if (fa < 0.0) != (fb < 0.0) && fa != fb {
        (fa / (fa - fb)).clamp(0.02, 0.98)
    } else {
        0.5
    }
}
