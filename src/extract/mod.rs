//! Surfaces from label volumes, all labels at once (thesis ch. 6.2): every point of a cell
//! belongs to the label whose interpolated indicator is largest, so touching structures share
//! one interface and nothing overlaps or gaps.
//!
//! The cell triangulation is derived, not typed in. Each cube face is decided on its own from
//! its four corner labels by the largest-indicator rule (bilinear on the face): segments join
//! the midpoints of edges whose corners differ, and where three or four labels meet on a face
//! a branching point is placed where their bilinear indicators tie. The one ambiguous face, two
//! labels on diagonal corners, connects the label with the lower index (background before any
//! structure, as the phantoms' binary table does). Because a face is decided only from its own
//! corners, both cells that share it see the same segments and points. Inside a cell, each
//! connected set of face segments bounds a membrane: a simple loop is filled as a polygon (a
//! triangle, a quad, or a fan around its centroid), a set with branching points as a fan from
//! its centroid, where the interior curves of three labels meet. Each triangle separates two
//! labels and belongs, with opposite orientations, to both structures' surfaces. The cell
//! rules live in `cell.rs`; this module scans the volume and assembles the surfaces.

mod cell;
pub mod constrained;
pub mod kernel;
pub mod noise;
pub mod report;

use cell::{Template, KIND_APEX};

use crate::mesh::{is_valid_coordinate, Mesh};
use crate::volume::LabelVolume;
use rustc_hash::FxHashMap;

/// One structure's surface from a label volume.
#[derive(Debug, Clone)]
pub struct LabelSurface {
    /// Dense label index in the volume (1-based).
    pub label: u16,
    pub mesh: Mesh,
}

/// All interfaces of a label volume: one triangle per interface piece, with the labels on its
/// two sides (`inner` is the side its normal points away from; 0 is background).
#[derive(Debug, Clone, Default)]
pub struct Interfaces {
    /// Vertex positions in voxel index coordinates (the volume's grid maps them to mm). f32
    /// keeps 1/30,000 of a voxel at index 512, and halves the memory the scan writes.
    pub positions: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    /// (inner, outer) label per triangle.
    pub sides: Vec<[u16; 2]>,
    /// The third vertex as the outer label's surface uses it: the same as `triangles[t][2]`,
    /// except where a label meets itself at a cell's branching point, which then has a copy
    /// per part of that label so that each surface stays a 2-manifold.
    pub outer_apex: Vec<u32>,
    /// What each vertex lies on: [`VERTEX_EDGE`], [`VERTEX_FACE`] or [`VERTEX_APEX`].
    pub kinds: Vec<u8>,
}

/// A vertex on a cell edge (between two voxel centres of different labels).
pub const VERTEX_EDGE: u8 = 0;
/// A branching point on a cell face, where three or four labels meet on it.
pub const VERTEX_FACE: u8 = 1;
/// A branching point inside a cell (the centre of a membrane's fan).
pub const VERTEX_APEX: u8 = 2;

/// Which voxels of a label form one object: those that share a face (6-connectivity), or also
/// those that touch only by an edge or a corner (26-connectivity, the convention of
/// segmentation tools). The background is always face-connected: it is what lies between.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub enum Connectivity {
    /// Voxels touching by a face, an edge or a corner form one object (the default).
    #[default]
    #[serde(rename = "26")]
    Corners,
    /// Only voxels sharing a face form one object.
    #[serde(rename = "6")]
    Faces,
}

impl Connectivity {
    /// The config number (26 or 6).
    pub fn number(self) -> u8 {
        match self {
            Connectivity::Corners => 26,
            Connectivity::Faces => 6,
        }
    }
}

/// Per dense label, whether its voxels join across edges and corners (`connectivity[l]`;
/// missing entries take the default; the background, entry 0, never does): what the
/// extraction and [`crate::volume::components::label_components`] take.
pub fn joins_of(volume: &LabelVolume, connectivity: &[Connectivity]) -> Vec<bool> {
    (0..=volume.labels.len())
        .map(|l| l > 0 && connectivity.get(l).copied().unwrap_or_default() == Connectivity::Corners)
        .collect()
}

/// Slabs of cells (along z) per parallel task. Fixed, so results do not depend on the thread
/// count.
const SLAB: i64 = 4;

/// What one slab of cells produced: its vertices (first-seen order) and triangles over them,
/// and the vertices on its bottom and top planes, which it shares with the slabs next to it.
struct SlabOutput {
    positions: Vec<[f32; 3]>,
    kinds: Vec<u8>,
    triangles: Vec<[u32; 3]>,
    outer_apex: Vec<u32>,
    sides: Vec<[u16; 2]>,
    /// (local vertex, key) of vertices on the bottom plane, in local order.
    bottom: Vec<(u32, u64)>,
    /// (key, local vertex) of vertices on the top plane, sorted by key.
    top: Vec<(u64, u32)>,
}

/// Extracts every interface of `volume` (labels outside the volume count as background, so
/// structures that reach the border are closed there by a flat cap). `connectivity[l]` is
/// how dense label `l`'s voxels join (missing entries: 26). Slabs of cells run in parallel;
/// slabs are fixed and merged in order, so the output does not depend on the thread count.
pub fn interfaces(volume: &LabelVolume, connectivity: &[Connectivity]) -> Interfaces {
    let joins = joins_of(volume, connectivity);
    use rayon::prelude::*;
    let nz = volume.dims[2] as i64;
    let n_slabs = (nz + 1 + SLAB - 1) / SLAB;
    // Per worker thread: the cell templates (derived on first use), the vertex tables and the
    // size of its last slab (neighbouring slabs are alike: reserving that much saves growing
    // the outputs). Each thread only ever locks its own entry.
    let pool: Vec<std::sync::Mutex<SlabScratch>> = (0..rayon::current_num_threads().max(1))
        .map(|_| std::sync::Mutex::new(SlabScratch::default()))
        .collect();
    let slabs: Vec<SlabOutput> = (0..n_slabs)
        .into_par_iter()
        .map(|s| {
            let slot = rayon::current_thread_index().unwrap_or(0) % pool.len();
            let mut scratch = pool[slot].lock().unwrap_or_else(|e| e.into_inner());
            let k0 = -1 + s * SLAB;
            slab(volume, &joins, k0..(k0 + SLAB).min(nz), &mut scratch)
        })
        .collect();
    // Vertex numbers: a slab's vertices in its own order, except those on its bottom plane,
    // which are the previous slab's top-plane vertices (the same grid elements). Per slab in
    // parallel: which local vertices are the previous slab's (by their local number there),
    // then the new ones numbered from the slab's first, then the shared ones looked up (a
    // top-plane vertex is always new in its own slab).
    let links: Vec<Vec<(u32, u32)>> = slabs
        .par_iter()
        .enumerate()
        .map(|(s, slab)| {
            let Some(prev) = s.checked_sub(1).map(|p| &slabs[p]) else {
                return Vec::new();
            };
            slab.bottom
                .iter()
                .filter_map(|&(local, key)| {
                    let at = prev.top.binary_search_by_key(&key, |&(k, _)| k).ok()?;
                    Some((local, prev.top[at].1))
                })
                .collect()
        })
        .collect();
    let new_counts: Vec<usize> = slabs
        .iter()
        .zip(&links)
        .map(|(slab, links)| slab.positions.len() - links.len())
        .collect();
    let first_new: Vec<u32> = new_counts
        .iter()
        .scan(0u32, |next, &n| {
            let first = *next;
            *next += n as u32;
            Some(first)
        })
        .collect();
    let mut maps: Vec<Vec<u32>> = slabs
        .par_iter()
        .zip(&links)
        .zip(&first_new)
        .map(|((slab, links), &first)| {
            let mut map = vec![0u32; slab.positions.len()];
            for &(local, _) in links {
                map[local as usize] = u32::MAX;
            }
            let mut next = first;
            for m in &mut map {
                if *m != u32::MAX {
                    *m = next;
                    next += 1;
                }
            }
            map
        })
        .collect();
    let shared: Vec<Vec<(u32, u32)>> = links
        .par_iter()
        .enumerate()
        .map(|(s, links)| {
            let prev = maps.get(s.wrapping_sub(1));
            links
                .iter()
                .filter_map(|&(local, there)| Some((local, *prev?.get(there as usize)?)))
                .collect()
        })
        .collect();
    maps.par_iter_mut().zip(shared).for_each(|(map, shared)| {
        for (local, global) in shared {
            map[local as usize] = global;
        }
    });
    // Concatenated in parallel: every slab writes its own stretch of the outputs.
    let tri_counts: Vec<usize> = slabs.iter().map(|s| s.triangles.len()).collect();
    let positions = concat(&new_counts, |s, out: &mut [[f32; 3]]| {
        let first = first_new[s];
        let new = slabs[s]
            .positions
            .iter()
            .zip(&maps[s])
            .filter(|(_, &g)| g >= first);
        for (dst, (p, _)) in out.iter_mut().zip(new) {
            *dst = *p;
        }
    });
    let triangles = concat(&tri_counts, |s, out: &mut [[u32; 3]]| {
        for (dst, t) in out.iter_mut().zip(&slabs[s].triangles) {
            *dst = t.map(|v| maps[s][v as usize]);
        }
    });
    let outer_apex = concat(&tri_counts, |s, out: &mut [u32]| {
        for (dst, &v) in out.iter_mut().zip(&slabs[s].outer_apex) {
            *dst = maps[s][v as usize];
        }
    });
    let kinds = concat(&new_counts, |s, out: &mut [u8]| {
        let first = first_new[s];
        let new = slabs[s]
            .kinds
            .iter()
            .zip(&maps[s])
            .filter(|(_, &g)| g >= first);
        for (dst, (k, _)) in out.iter_mut().zip(new) {
            *dst = *k;
        }
    });
    let sides = concat(&tri_counts, |s, out: &mut [[u16; 2]]| {
        out.copy_from_slice(&slabs[s].sides);
    });
    Interfaces {
        positions,
        triangles,
        sides,
        outer_apex,
        kinds,
    }
}

/// One vector made of parts of the given lengths, each filled by `fill(part, stretch)` in
/// parallel. Zeroed allocation costs nothing extra: fresh pages are zero already.
fn concat<T: Copy + Default + Send + Sync>(
    lens: &[usize],
    fill: impl Fn(usize, &mut [T]) + Sync,
) -> Vec<T> {
    use rayon::prelude::*;
    let mut out = crate::hugepages::zeroed_vec(lens.iter().sum());
    crate::parallel::split_lengths(lens.iter().copied(), &mut out)
        .into_par_iter()
        .enumerate()
        .for_each(|(s, stretch)| fill(s, stretch));
    out
}

/// Cell templates derived so far, by configuration key, with a direct table for the
/// configurations of two labels (by the mask of corners holding the larger one).
#[derive(Default)]
struct Templates {
    by_key: FxHashMap<u32, Template>,
    two_labels: Vec<Option<Template>>,
}

impl Templates {
    fn of(&mut self, key: u32) -> &Template {
        self.by_key.entry(key).or_insert_with(|| Template::of(key))
    }

    /// `mask`: the corners holding the larger label in bits 0..8, which of the two labels
    /// join diagonally in bits 8 (the smaller) and 9.
    fn two_labels(&mut self, mask: usize) -> &Template {
        if self.two_labels.is_empty() {
            self.two_labels.resize_with(1024, || None);
        }
        self.two_labels[mask & 1023].get_or_insert_with(|| {
            // Corner 0's rank in the key's highest bits.
            let key = (0..8).fold(0u32, |acc, c| acc << 3 | ((mask >> c) & 1) as u32);
            Template::of(key | ((mask >> 8) as u32) << 24)
        })
    }
}

/// A worker's reusable state for [`slab`].
#[derive(Default)]
struct SlabScratch {
    templates: Templates,
    /// Vertex ids by grid element: per grid plane of the slab and row parity, per padded grid
    /// point of the row, 6 slots (edges along x, y, z; faces normal to x, y, z). An entry is
    /// `stamp + id + 1`; it is valid only when above its row's threshold, so the table is never
    /// cleared between rows or slabs (0 is never valid). About 120 KB for 512 columns: it stays
    /// in a core's L2.
    table: Vec<u32>,
    /// Added to every id stored by the current slab; grows by each slab's vertex count.
    stamp: u32,
    /// Vertices and triangles of the worker's last slab.
    last: [usize; 2],
}

/// What [`visit_mixed_cells`] hands its visitor.
enum Visit<'a> {
    /// A new row of cells starts at y index `j` (all z layers of the slab follow).
    Row(i64),
    /// A cell whose eight corners do not all hold one label: its lower corner (i, j, k), its
    /// template, and the cell's distinct labels in increasing order (the ranks the template
    /// uses; the rest of the array is unused).
    Cell {
        ijk: [i64; 3],
        template: &'a Template,
        distinct: &'a [u16; 8],
    },
}

/// Visits every cell with more than one label among its corners whose lower corner lies in
/// the z range `ks` (from -1: the pad below the volume; labels outside the volume are
/// background), row by row (y), all layers of `ks` for each row, then along x. Cells whose
/// corners hold one label are skipped in runs; templates are derived on first use.
fn visit_mixed_cells(
    volume: &LabelVolume,
    joins: &[bool],
    ks: std::ops::Range<i64>,
    templates: &mut Templates,
    mut visit: impl FnMut(Visit),
) {
    let [nx, ny, nz] = volume.dims.map(|d| d as i64);
    // A row of voxels along x, or none outside the volume (background).
    let row = |j: i64, k: i64| -> Option<&[u16]> {
        if j < 0 || k < 0 || j >= ny || k >= nz {
            None
        } else {
            let at = (nx * (j + ny * k)) as usize;
            Some(&volume.voxels[at..at + nx as usize])
        }
    };
    let at = |r: Option<&[u16]>, i: i64| -> u16 {
        match r {
            Some(r) if i >= 0 && i < nx => r[i as usize],
            _ => 0,
        }
    };
    let mut flags: Vec<u8> = vec![0; (nx.max(1) - 1) as usize];
    let mut columns: Vec<u16> = vec![0; nx.max(1) as usize];
    for j in -1..ny {
        visit(Visit::Row(j));
        for k in ks.clone() {
            let rows = [row(j, k), row(j + 1, k), row(j, k + 1), row(j + 1, k + 1)];
            if rows.iter().all(Option::is_none) {
                continue;
            }
            // Inside the volume, cells whose eight corners hold one label are skipped: a
            // flag per cell, computed over the four rows in one vectorisable pass, and runs of
            // unflagged cells passed eight at a time.
            let full = match rows {
                [Some(a), Some(b), Some(c), Some(d)] => Some([a, b, c, d]),
                _ => None,
            };
            if let Some(r) = full {
                mixed_cells(r, &mut columns, &mut flags);
            }
            let mut next_i = -1;
            while next_i < nx {
                let i = next_i;
                next_i += 1;
                if full.is_some() && i >= 0 && i + 1 < nx {
                    let x = i as usize;
                    if flags[x] == 0 {
                        // Skip to the next flagged cell.
                        let mut y = x + 1;
                        while y + 8 <= flags.len()
                            && u64::from_ne_bytes(flags[y..y + 8].try_into().unwrap_or([1; 8])) == 0
                        {
                            y += 8;
                        }
                        while y < flags.len() && flags[y] == 0 {
                            y += 1;
                        }
                        next_i = y as i64;
                        continue;
                    }
                }
                // Corner c = dx + 2 dy + 4 dz: row dy + 2 dz, position i + dx.
                let labels: [u16; 8] =
                    std::array::from_fn(|c| at(rows[c >> 1], i + (c & 1) as i64));
                if labels.iter().all(|&l| l == labels[0]) {
                    continue;
                }
                // The configuration up to the labels' values: each corner's rank among the
                // cell's distinct labels (the order decides the diagonal faces). Most mixed
                // cells hold two labels: their configuration is the mask of corners holding
                // the larger one, looked up directly.
                let mut distinct = labels;
                let (lo, hi) = labels
                    .iter()
                    .fold((u16::MAX, 0), |(lo, hi), &l| (lo.min(l), hi.max(l)));
                let joins = |l: u16| joins.get(l as usize).copied().unwrap_or(false);
                let template = if labels.iter().all(|&l| l == lo || l == hi) {
                    distinct[..2].copy_from_slice(&[lo, hi]);
                    let mask = labels
                        .iter()
                        .enumerate()
                        .fold(0usize, |m, (c, &l)| m | ((l == hi) as usize) << c);
                    let flags = joins(lo) as usize | (joins(hi) as usize) << 1;
                    templates.two_labels(mask | flags << 8)
                } else {
                    distinct.sort_unstable();
                    let n = dedup_sorted(&mut distinct);
                    let key = labels.iter().fold(0u32, |acc, l| {
                        acc << 3 | distinct.iter().position(|d| d == l).unwrap_or(0) as u32
                    });
                    let flags = (0..n).fold(0u32, |f, r| f | (joins(distinct[r]) as u32) << r);
                    templates.of(key | flags << 24)
                };
                visit(Visit::Cell {
                    ijk: [i, j, k],
                    template,
                    distinct: &distinct,
                });
            }
        }
    }
}

/// How large the surfaces of a label volume will be, counted in one pass over its cells
/// without making them: for bounding the memory of an extraction before it starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct SurfaceSize {
    /// Cells whose eight corners hold more than one label.
    pub interface_cells: u64,
    /// Triangles of all the labels' surfaces together (an interface between two labels counts
    /// once for each; towards the background once).
    pub triangles: u64,
}

/// Counts the cells and surface triangles [`interfaces`] and [`label_surfaces`] would make,
/// exactly, without making them (slabs in parallel; integer sums, so the same for any thread
/// count). Costs about what the scan of [`interfaces`] costs without its outputs.
pub fn surface_size(volume: &LabelVolume, connectivity: &[Connectivity]) -> SurfaceSize {
    let joins = joins_of(volume, connectivity);
    use rayon::prelude::*;
    let nz = volume.dims[2] as i64;
    let n_slabs = (nz + 1 + SLAB - 1) / SLAB;
    (0..n_slabs)
        .into_par_iter()
        .map_init(Templates::default, |templates, s| {
            let k0 = -1 + s * SLAB;
            let mut size = SurfaceSize::default();
            visit_mixed_cells(volume, &joins, k0..(k0 + SLAB).min(nz), templates, |v| {
                if let Visit::Cell {
                    template, distinct, ..
                } = v
                {
                    size.interface_cells += 1;
                    for t in &template.triangles {
                        size.triangles += t
                            .sides
                            .iter()
                            .filter(|&&r| distinct[r as usize] != 0)
                            .count() as u64;
                    }
                }
            });
            size
        })
        .reduce(SurfaceSize::default, |a, b| SurfaceSize {
            interface_cells: a.interface_cells + b.interface_cells,
            triangles: a.triangles + b.triangles,
        })
}

/// The cells whose lower corner lies in the z range `ks` (from -1: the pad below the volume).
fn slab(
    volume: &LabelVolume,
    joins: &[bool],
    ks: std::ops::Range<i64>,
    scratch: &mut SlabScratch,
) -> SlabOutput {
    let SlabScratch {
        templates,
        table,
        stamp,
        last: [n_vertices, n_triangles],
    } = scratch;
    let (n_vertices, n_triangles) = (*n_vertices, *n_triangles);
    let [nx, ny] = [volume.dims[0] as i64, volume.dims[1] as i64];
    // Grid points with a one-voxel pad, numbered for vertex keys.
    let (px, py) = (nx + 2, ny + 2);
    let point_id =
        |i: i64, j: i64, k: i64| -> u64 { ((i + 1) + px * ((j + 1) + py * (k + 1))) as u64 };
    let (bottom, top) = (ks.start as f64, ks.end as f64);
    // Vertices on grid edges and faces: ids in a dense table over the two grid rows a row of
    // cells spans, for every plane of the slab (cells are visited row by row, all layers of
    // the slab for each row, so a vertex is found again while its row is in cache; a hash map
    // by key, and tables over whole planes, measured 1.2-1.5x slower over the whole scan).
    let table_len = (SLAB as usize + 1) * 2 * px as usize * 6;
    if table.len() != table_len || *stamp > u32::MAX / 2 {
        *table = vec![0; table_len];
        *stamp = 0;
    }
    let base = *stamp;
    let mut out = SlabOutput {
        positions: Vec::with_capacity(n_vertices),
        kinds: Vec::with_capacity(n_vertices),
        triangles: Vec::with_capacity(n_triangles),
        outer_apex: Vec::with_capacity(n_triangles),
        sides: Vec::with_capacity(n_triangles),
        bottom: Vec::new(),
        top: Vec::new(),
    };
    let mut ids: Vec<u32> = Vec::with_capacity(32);
    // Vertices at the start of the previous and the current row of cells: a table entry of
    // grid row r is this slab's when created during cell row r - 1 or r.
    let mut row_start = [0u32; 2];
    let mut valid_above = [0u32; 2];
    let k_start = ks.start;
    visit_mixed_cells(volume, joins, ks, templates, |v| {
        let (i, j, k, template, distinct) = match v {
            Visit::Row(j) => {
                let count = out.positions.len() as u32;
                row_start = if j == -1 {
                    [count; 2]
                } else {
                    [row_start[1], count]
                };
                // Entries valid in the table's rows j and j + 1.
                valid_above = [base + row_start[0], base + row_start[1]];
                return;
            }
            Visit::Cell {
                ijk: [i, j, k],
                template,
                distinct,
            } => (i, j, k, template, distinct),
        };
        let gid = |c: u64| {
            point_id(
                i + (c & 1) as i64,
                j + ((c >> 1) & 1) as i64,
                k + ((c >> 2) & 1) as i64,
            )
        };
        ids.clear();
        for &(local, p) in &template.vertices {
            let at = [p[0] + i as f64, p[1] + j as f64, p[2] + k as f64];
            if local & 3 == KIND_APEX {
                // A cell's own branching point: no other cell has it.
                ids.push(out.positions.len() as u32);
                out.positions.push(at.map(|x| x as f32));
                out.kinds.push(VERTEX_APEX);
                continue;
            }
            let v = local >> 2;
            let (c, axis) = (v / 3, v % 3);
            let (dz, dy, dx) = ((c >> 2) as i64 & 1, (c >> 1) as i64 & 1, c as i64 & 1);
            let point = ((k + dz - k_start) * 2 + ((j + dy + 1) & 1)) * px + (i + dx + 1);
            let entry = &mut table[point as usize * 6 + ((local & 3) * 3 + axis) as usize];
            let next = out.positions.len() as u32;
            let id = if *entry > valid_above[dy as usize] {
                *entry - base - 1
            } else {
                *entry = base + next + 1;
                next
            };
            if id == next {
                let global = (((gid(c) * 3) + axis) << 2) | (local & 3);
                out.positions.push(at.map(|x| x as f32));
                out.kinds.push(if local & 3 == KIND_APEX {
                    VERTEX_APEX
                } else if local & 3 == cell::KIND_FACE {
                    VERTEX_FACE
                } else {
                    VERTEX_EDGE
                });
                // On the slab's bottom or top plane: shared with the next slab.
                if at[2] == bottom {
                    out.bottom.push((id, global));
                } else if at[2] == top {
                    out.top.push((global, id));
                }
            }
            ids.push(id);
        }
        for t in &template.triangles {
            out.triangles.push(t.corners.map(|x| ids[x as usize]));
            out.outer_apex.push(ids[t.outer_apex as usize]);
            out.sides.push(t.sides.map(|r| distinct[r as usize]));
        }
    });
    out.top.sort_unstable();
    *stamp = base + out.positions.len() as u32 + 1;
    scratch.last = [out.positions.len(), out.triangles.len()];
    out
}

/// For the cells between four full rows (x from 0 to nx - 2), 1 where the cell's eight
/// corners do not all hold one label. Two branch-free passes over the row (the columns that
/// differ within themselves, then the cells), so the compiler vectorises both; `columns` is
/// scratch of at least nx entries.
fn mixed_cells(rows: [&[u16]; 4], columns: &mut [u16], flags: &mut [u8]) {
    let [a, b, c, d] = rows;
    let n = flags.len();
    // Column x: nonzero where its four voxels differ.
    let columns = &mut columns[..n + 1];
    for ((((col, &a), &b), &c), &d) in columns.iter_mut().zip(a).zip(b).zip(c).zip(d) {
        *col = (a ^ b) | (a ^ c) | (a ^ d);
    }
    // Cell x: column x or x + 1 differs, or the columns differ from each other (in row a;
    // the columns cover the other rows).
    for (x, flag) in flags.iter_mut().enumerate() {
        *flag = ((columns[x] | columns[x + 1] | (a[x] ^ a[x + 1])) != 0) as u8;
    }
}

/// Moves the distinct values of a sorted array to its front; returns how many there are.
fn dedup_sorted(a: &mut [u16; 8]) -> usize {
    let mut n = 1;
    for x in 1..8 {
        if a[x] != a[n - 1] {
            a[n] = a[x];
            n += 1;
        }
    }
    n
}

/// One closed surface per label (normals outward, vertices in world mm through the volume's
/// grid), made of the shared interface triangles; labels are assembled in parallel.
pub fn label_surfaces(volume: &LabelVolume, all: &Interfaces) -> Vec<LabelSurface> {
    let grid = volume.grid;
    // A grid that mirrors (negative determinant, e.g. NIfTI's qfac = -1) turns every triangle
    // inside out in world space; swapping two corners turns it back.
    let mirrored = crate::volume::grid::det3(&grid.matrix) < 0.0;
    assemble(volume, all, |p| grid.world(p), mirrored)
}

/// [`label_surfaces`] in the grid's own frame (index times spacing, mm; see
/// [`GridFrame`](crate::volume::grid::GridFrame)): grid axes are the coordinate axes there.
pub fn label_surfaces_in_frame(volume: &LabelVolume, all: &Interfaces) -> Vec<LabelSurface> {
    let s = volume.grid.spacing();
    assemble(
        volume,
        all,
        |p| [p[0] * s[0], p[1] * s[1], p[2] * s[2]],
        false,
    )
}

/// All interfaces as one mesh in world mm (non-manifold where three labels meet), with the
/// label values on the two sides of each triangle: (inner, outer), the normal pointing from
/// inner to outer, 0 for background. This is what tetrahedral meshers with regions take.
pub fn combined_surface(volume: &LabelVolume, all: &Interfaces) -> (Mesh, Vec<[i64; 2]>) {
    let grid = volume.grid;
    let mirrored = crate::volume::grid::det3(&grid.matrix) < 0.0;
    let mut local = vec![u32::MAX; all.positions.len()];
    let mut positions = Vec::new();
    let mut triangles = Vec::with_capacity(all.triangles.len());
    for tri in &all.triangles {
        let tri = if mirrored {
            [tri[0], tri[2], tri[1]]
        } else {
            *tri
        };
        triangles.push(tri.map(|v| {
            if local[v as usize] == u32::MAX {
                local[v as usize] = positions.len() as u32;
                let p = all.positions[v as usize].map(f64::from);
                positions.push(grid.world(p).map(|x| x as f32));
            }
            local[v as usize]
        }));
    }
    let value = |l: u16| {
        if l == 0 {
            0
        } else {
            volume.labels[l as usize - 1].value
        }
    };
    let sides = all
        .sides
        .iter()
        .map(|s| [value(s[0]), value(s[1])])
        .collect();
    (Mesh::new(positions, triangles).unwrap_or_default(), sides)
}

fn assemble(
    volume: &LabelVolume,
    all: &Interfaces,
    to_mm: impl Fn([f64; 3]) -> [f64; 3] + Sync,
    mirrored: bool,
) -> Vec<LabelSurface> {
    use rayon::prelude::*;
    let n_labels = volume.labels.len();
    // Each triangle goes to the labels on its two sides (background has no surface): per
    // fixed stretch of triangles, in parallel, the triangles of each label in order.
    const STRETCH: usize = 1 << 15;
    let members: Vec<Vec<Vec<u32>>> = all
        .sides
        .par_chunks(STRETCH)
        .enumerate()
        .map(|(c, sides)| {
            let mut own: Vec<Vec<u32>> = vec![Vec::new(); n_labels + 1];
            for (t, s) in sides.iter().enumerate() {
                let t = (c * STRETCH + t) as u32;
                for l in *s {
                    if l != 0 {
                        own[l as usize].push(t);
                    }
                }
            }
            own
        })
        .collect();
    // One vertex map per thread, reset after each label (only the entries it set), instead of
    // a fresh one per label.
    let pool: Vec<std::sync::Mutex<Vec<u32>>> = (0..rayon::current_num_threads().max(1))
        .map(|_| std::sync::Mutex::new(Vec::new()))
        .collect();
    (1..=n_labels as u16)
        .into_par_iter()
        .map(|label| {
            let slot = rayon::current_thread_index().unwrap_or(0) % pool.len();
            let mut local = pool[slot].lock().unwrap_or_else(|e| e.into_inner());
            if local.len() != all.positions.len() {
                *local = vec![u32::MAX; all.positions.len()];
            }
            let own = members.iter().flat_map(|m| &m[label as usize]);
            let n_own: usize = members.iter().map(|m| m[label as usize].len()).sum();
            // A closed surface has about half as many vertices as triangles (Euler).
            let mut used: Vec<u32> = Vec::with_capacity(n_own / 2 + 64);
            let mut positions = Vec::with_capacity(n_own / 2 + 64);
            let mut triangles = Vec::with_capacity(n_own);
            for &t in own {
                let (tri, sides) = (all.triangles[t as usize], all.sides[t as usize]);
                let tri = if sides[0] == label {
                    tri
                } else {
                    [tri[0], all.outer_apex[t as usize], tri[1]]
                };
                let tri = if mirrored {
                    [tri[0], tri[2], tri[1]]
                } else {
                    tri
                };
                triangles.push(tri.map(|v| {
                    if local[v as usize] == u32::MAX {
                        local[v as usize] = positions.len() as u32;
                        used.push(v);
                        // In mm as the label first uses it (about twice per vertex in all:
                        // cheaper than a shared array of every vertex in mm).
                        let p = to_mm(all.positions[v as usize].map(f64::from));
                        positions.push(p.map(|x| x as f32));
                    }
                    local[v as usize]
                }));
            }
            // Indices are in range by construction; only the coordinates are checked.
            let valid = positions.iter().flatten().all(|&x| is_valid_coordinate(x));
            for v in used {
                local[v as usize] = u32::MAX;
            }
            // A grid that maps voxels beyond +-1e7 mm leaves the surface empty (readers refuse
            // such grids with a message first).
            let mesh = if valid {
                Mesh::from_checked_parts(positions, triangles)
            } else {
                Mesh::new(positions, triangles).unwrap_or_default()
            };
            LabelSurface { label, mesh }
        })
        .collect()
}
