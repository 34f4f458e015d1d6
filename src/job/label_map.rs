//! Label maps as cases: a segmentation in a case folder is read and hashed by the loader, and
//! its labels become the case's structures. All labels of a layer are extracted at once
//! (consistent shared interfaces), each in its grid's own frame, where the voxel size and the
//! stack axis are known exactly from the header instead of being estimated from the mesh.
//! Surfaces go back to world millimetres (LPS or RAS, as the plan says) when written.

use super::plan::Plan;
use crate::extract::constrained::{check_sigma, connectivity_of, LabelSmoothing, Surface};
use crate::extract::report::Extraction;
use crate::io::{with_file_bytes, LoadedMesh, MeshMeta, SourceFormat};
use crate::mesh::{Mesh, MeshError};
pub use crate::report::label_map::{LabelEntry, LabelMapInfo, LabelSource};
use crate::volume::grid::GridFrame;
use crate::volume::LabelMap;
use std::path::Path;

/// Estimated peak bytes per surface triangle of a label-map case (all labels' surfaces
/// together): the extraction, the surfaces with their binary copies, smoothing, metrics, the
/// guard, pictures and encoded outputs. Measured peaks: 224 B (noise, constrained surfaces,
/// defaults) to 470 B (HC with references and three output formats) per triangle; the same
/// as the 24 bytes per input byte of a mesh case (a binary PLY holds about 19 bytes per
/// triangle).
pub const MEMORY_PER_TRIANGLE: u64 = 480;

/// A label map of a case, read and hashed.
#[derive(Debug)]
pub struct LoadedLabelMap {
    /// File name (within the case folder).
    pub file: String,
    /// Bytes read (header and detached data file).
    pub bytes: u64,
    /// BLAKE3 of the file's bytes (and of its detached data file's, when there is one).
    pub blake3: String,
    pub map: Result<LabelMap, String>,
    /// Estimated peak bytes of processing it: reading, and the surfaces counted before any is
    /// made (0 when it could not be read).
    pub memory: u64,
    /// It was refused because it needs more memory than `room` allowed (a larger budget may
    /// admit it, so a rerun with another budget tries it again).
    pub over_budget: bool,
}

/// Where a structure's mesh coordinates live.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Place {
    /// World mm (mesh files, and surfaces of sheared grids).
    World,
    /// The own frame of the grid of the case's label map with this index.
    Frame(usize, GridFrame),
}

impl Place {
    /// Positions of `mesh` (in `self`) expressed in `to`, with triangles turned so that normals
    /// keep pointing the same way when the change mirrors; `None` when the places agree. For
    /// a surface of a label map going to world mm (or back): its grid lies within
    /// [`Grid::check_extent`](crate::volume::grid::Grid::check_extent)'s 1 km, so its
    /// coordinates stay valid in either place and need no second check.
    pub fn mesh_in(&self, mesh: &Mesh, to: &Place) -> Option<Mesh> {
        self.moved(mesh, to, Mesh::from_checked_parts)
    }

    /// [`Place::mesh_in`] for any mesh (a mesh file measured in a grid's frame, which a far
    /// file could put beyond +-1e7 mm): the moved coordinates checked.
    pub fn checked_mesh_in(&self, mesh: &Mesh, to: &Place) -> Result<Option<Mesh>, MeshError> {
        self.moved(mesh, to, Mesh::new).transpose()
    }

    /// The positions and triangles of [`Place::mesh_in`], made into a mesh by `make`.
    fn moved<T>(
        &self,
        mesh: &Mesh,
        to: &Place,
        make: impl FnOnce(Vec<[f32; 3]>, Vec<[u32; 3]>) -> T,
    ) -> Option<T> {
        if self.same(to) {
            return None;
        }
        let mirrored = self.mirrored() != to.mirrored();
        let positions = mesh
            .positions()
            .iter()
            .map(|p| {
                let w = self.world_of(p.map(f64::from));
                to.of_world(w).map(|x| x as f32)
            })
            .collect();
        let triangles = mesh
            .triangles()
            .iter()
            .map(|t| if mirrored { [t[0], t[2], t[1]] } else { *t })
            .collect();
        Some(make(positions, triangles))
    }

    fn same(&self, other: &Place) -> bool {
        match (self, other) {
            (Place::World, Place::World) => true,
            (Place::Frame(a, _), Place::Frame(b, _)) => a == b,
            _ => false,
        }
    }

    fn mirrored(&self) -> bool {
        match self {
            Place::World => false,
            Place::Frame(_, f) => f.mirrored(),
        }
    }

    fn world_of(&self, p: [f64; 3]) -> [f64; 3] {
        match self {
            Place::World => p,
            Place::Frame(_, f) => f.to_world(p),
        }
    }

    /// A world point (mm) in this place's coordinates.
    pub fn of_world(&self, w: [f64; 3]) -> [f64; 3] {
        match self {
            Place::World => w,
            Place::Frame(_, f) => f.to_frame(w),
        }
    }

    /// A direction given in world, in this place.
    pub fn direction_from_world(&self, d: [f64; 3]) -> [f64; 3] {
        match self {
            Place::World => d,
            Place::Frame(_, f) => f.direction_to_frame(d),
        }
    }

    /// A direction in this place, in world.
    pub fn direction_to_world(&self, d: [f64; 3]) -> [f64; 3] {
        match self {
            Place::World => d,
            Place::Frame(_, f) => f.direction_to_world(d),
        }
    }
}

/// One structure made from a label map.
#[derive(Debug)]
pub struct LabelStructure {
    pub name: String,
    /// The surface, in `place`'s coordinates.
    pub mesh: LoadedMesh,
    /// The plain consistent extraction with the same triangles, when `mesh` is a constrained
    /// surface: what the report measures the extraction's change against.
    pub binary: Option<Mesh>,
    pub place: Place,
    pub source: LabelSource,
    /// The structures of the same layer whose surfaces share interface triangles with this
    /// one's (by name).
    pub shares_triangles_with: Vec<String>,
    /// Why the structure fails although its surface was made (its settings do not fit the
    /// map: a `sigma_mm` beyond the range its spacing allows, extracted with the default so
    /// that its neighbours' interfaces stay as they would be).
    pub refused: Option<String>,
}

/// Reads and hashes a label map (with its detached data file) in `plan.space`, within
/// `plan.label_limits` and `room` bytes of memory: its header says what reading takes, and a
/// count of its surface triangles (one pass over the cells, nothing made) what the surfaces
/// will; a map that would need more than `room` is refused with the figures before that work.
pub fn load_label_map(plan: &Plan, path: &Path, room: u64) -> LoadedLabelMap {
    let file = path
        .file_name()
        .map_or_else(String::new, |f| f.to_string_lossy().into_owned());
    let mut hasher = blake3::Hasher::new();
    let mut bytes = 0;
    let hashed = with_file_bytes(path, plan.read_mode, |b| {
        hasher.update(b);
        bytes += b.len() as u64;
    });
    let shown = plan.display(path);
    let mut memory = 0;
    let mut over_budget = false;
    let budget = |need: u64, what: String| {
        format!(
            "{shown}: {what} needs about {} MB, more than the {} MB left for it of the memory budget ({} MB, {}); raise [run] memory_budget_mb (or the limit behind it) if the machine has the memory",
            mb(need),
            mb(room),
            mb(plan.memory_budget_bytes),
            plan.memory_budget_source
        )
    };
    let map = match hashed {
        Err(e) => Err(format!("{shown}: cannot read: {e}")),
        Ok(()) => (|| {
            // A header that cannot be read is left to the reader, whose error says more (a
            // truncated gzip stream, say) and which checks the same header before any voxel.
            let mut to_read = 0;
            if let Ok(header) = crate::volume::read_header(path) {
                plan.label_limits
                    .check_voxels(header.dims, header.n_layers)
                    .map_err(|e| format!("{shown}: {e}"))?;
                to_read = header.bytes_to_read();
                if to_read > room {
                    over_budget = true;
                    return Err(budget(
                        to_read,
                        format!(
                            "reading its {}",
                            crate::volume::voxels_text(header.dims, header.n_layers)
                        ),
                    ));
                }
            }
            let map = crate::volume::read_label_map_within(path, plan.space, &plan.label_limits)
                .map_err(|e| format!("{shown}: {}", e.message))?;
            if let Some(data) = &map.data_file {
                with_file_bytes(data, plan.read_mode, |b| {
                    hasher.update(b);
                    bytes += b.len() as u64;
                })
                .map_err(|e| format!("{}: cannot read: {e}", plan.display(data)))?;
            }
            let size = (map.layers.iter().enumerate())
                .map(|(layer_index, layer)| {
                    let (_, smoothing) = layer_extraction(plan, layer_index, layer);
                    crate::extract::surface_size(layer, &connectivity_of(&smoothing))
                })
                .fold(crate::extract::SurfaceSize::default(), |a, b| {
                    crate::extract::SurfaceSize {
                        interface_cells: a.interface_cells + b.interface_cells,
                        triangles: a.triangles + b.triangles,
                    }
                });
            let need = to_read.saturating_add(size.triangles.saturating_mul(MEMORY_PER_TRIANGLE));
            if need > room {
                over_budget = true;
                return Err(budget(
                    need,
                    format!(
                        "making its surfaces ({} triangles over {} cells where labels meet; noise or an image rather than a segmentation makes surfaces everywhere)",
                        size.triangles, size.interface_cells
                    ),
                ));
            }
            memory = need;
            Ok(map)
        })(),
    };
    LoadedLabelMap {
        file,
        bytes,
        blake3: hasher.finalize().to_hex().to_string(),
        map,
        memory,
        over_budget,
    }
}

/// Bytes as whole megabytes (rounded up), for messages.
fn mb(bytes: u64) -> u64 {
    bytes.div_ceil(1 << 20)
}

/// A label's name as a structure: `[labels]` first, then the file's own (Slicer's segment
/// names), made safe as a file stem.
fn structure_name(plan: &Plan, (layer, value): (usize, i64), file_name: &str) -> String {
    let name = plan
        .label_name(layer, value)
        .map_or(file_name, String::as_str);
    crate::volume::label_file_stem(name, value)
}

/// The structure name of each label of a layer, and how each dense label is extracted (entry
/// 0 the background, as [defaults] says).
fn layer_extraction(
    plan: &Plan,
    layer_index: usize,
    layer: &crate::volume::LabelVolume,
) -> (Vec<String>, Vec<LabelSmoothing>) {
    let names: Vec<String> = (layer.labels.iter())
        .map(|l| structure_name(plan, (layer_index, l.value), &l.name))
        .collect();
    let smoothing = std::iter::once(plan.default_settings().extraction)
        .chain(names.iter().map(|n| plan.settings_for(n).extraction))
        .collect();
    (names, smoothing)
}

/// Extracts every label of every layer of a read label map (the `index`-th of its case) as a
/// structure, with the map's report entry.
pub fn label_structures(
    plan: &Plan,
    index: usize,
    loaded: &LoadedLabelMap,
    map: &LabelMap,
) -> (Vec<LabelStructure>, LabelMapInfo) {
    let mut structures = Vec::new();
    let mut entries = Vec::new();
    let mut warnings = map.warnings.clone();
    for (layer_index, layer) in map.layers.iter().enumerate() {
        let grid = layer.grid;
        let (names, mut smoothing) = layer_extraction(plan, layer_index, layer);
        let mut refused: Vec<Option<String>> = vec![None; smoothing.len()];
        for (s, why) in smoothing.iter_mut().zip(&mut refused).skip(1) {
            let checked = s.sigma_mm.map(|sigma| check_sigma(sigma, layer));
            if let Some(Err(e)) = checked {
                *why = Some(e);
                s.sigma_mm = None;
            }
        }
        // The names the file itself gives (Slicer's segments), where [labels] says otherwise.
        let file_names: Vec<Option<String>> = (layer.labels.iter())
            .map(|l| {
                (map.segments.iter())
                    .any(|seg| {
                        seg.layer == layer_index && seg.value == l.value && seg.name == l.name
                    })
                    .then(|| l.name.clone())
            })
            .collect();
        for (l, file_name) in layer.labels.iter().zip(&file_names) {
            if let (Some(given), Some(own)) = (plan.label_name(layer_index, l.value), file_name) {
                if given != own {
                    warnings.push(format!(
                        "[labels] names label {} (layer {layer_index}) of {} {given:?}, but the file names it {own:?}; {given:?} is used",
                        l.value, loaded.file
                    ));
                }
            }
        }
        let connectivity = connectivity_of(&smoothing);
        let mut all = crate::extract::interfaces(layer, &connectivity);
        let joins = crate::extract::joins_of(layer, &connectivity);
        let objects = crate::volume::components::label_components(layer, &joins);
        let binary_positions = smoothing[1..]
            .iter()
            .any(|s| s.surface == Surface::Constrained)
            .then(|| all.positions.clone());
        // Labels that share interface triangles (both sides a label, not background).
        let mut sharing: Vec<std::collections::BTreeSet<u16>> =
            vec![Default::default(); layer.labels.len() + 1];
        for &[inner, outer] in &all.sides {
            if inner != 0 && outer != 0 {
                sharing[inner as usize].insert(outer);
                sharing[outer as usize].insert(inner);
            }
        }
        let counts = crate::extract::constrained::place_on_weights(layer, &mut all, &smoothing);
        let frame = grid.frame();
        if frame.is_none() {
            warnings.push(format!(
                "layer {layer_index}: the grid's axes are not perpendicular (a sheared grid); its surfaces are smoothed in world mm with the voxel size and stack axis estimated from each mesh"
            ));
        }
        let surfaces_of = |all: &crate::extract::Interfaces| match frame {
            Some(_) => crate::extract::label_surfaces_in_frame(layer, all),
            None => crate::extract::label_surfaces(layer, all),
        };
        let place = match frame {
            Some(f) => Place::Frame(index, f),
            None => Place::World,
        };
        let surfaces = surfaces_of(&all);
        let mut binary: Vec<Option<Mesh>> = match binary_positions {
            Some(p) => {
                all.positions = p;
                surfaces_of(&all)
                    .into_iter()
                    .map(|s| Some(s.mesh))
                    .collect()
            }
            None => Vec::new(),
        };
        binary.resize_with(surfaces.len(), || None);
        drop(all);
        let geometry = match place {
            Place::Frame(..) => "the label map's header (smoothed in the grid's own frame, mm along its axes i, j, k; written in world mm)",
            Place::World => "the mesh, estimated (the grid is sheared, so the surface is smoothed in world mm)",
        };
        let near_edge = layer.near_edge(crate::report::label_map::EDGE_MARGIN_VOXELS);
        for (s, binary) in surfaces.into_iter().zip(binary) {
            let label = &layer.labels[s.label as usize - 1];
            let name = names[s.label as usize - 1].clone();
            let own = smoothing[s.label as usize];
            let binary = binary.filter(|_| own.surface == Surface::Constrained);
            let extraction = Extraction::new(
                layer,
                &own,
                objects[s.label as usize],
                &s.mesh,
                counts[s.label as usize],
            );

            entries.push(LabelEntry {
                value: label.value,
                structure: name.clone(),
                file_name: file_names[s.label as usize - 1].clone(),
                layer: layer_index,
                n_voxels: label.n_voxels,
            });
            let meta = MeshMeta {
                comments: vec![
                    format!("SPACE={}", plan.space.tag()),
                    format!("destair: label {} of {}", label.value, loaded.file),
                ],
                obj_info: Vec::new(),
            };
            structures.push(LabelStructure {
                name,
                mesh: LoadedMesh {
                    mesh: s.mesh,
                    meta,
                    vertex_properties: Vec::new(),
                    warnings: Vec::new(),
                    format: SourceFormat::Extracted,
                },
                binary,
                place,
                refused: refused[s.label as usize].clone(),
                shares_triangles_with: sharing[s.label as usize]
                    .iter()
                    .map(|&other| names[other as usize - 1].clone())
                    .collect(),
                source: LabelSource {
                    label_map: loaded.file.clone(),
                    layer: layer_index,
                    label: label.value,
                    n_voxels: label.n_voxels,
                    voxel_volume_mm3: label.n_voxels as f64 * grid.voxel_volume(),
                    voxel_mm: grid.spacing(),
                    stack_axis: grid.stack_axis(),
                    reaches_volume_edge: near_edge.get(s.label as usize).copied().unwrap_or(true),
                    geometry: geometry.into(),
                    extraction,
                },
            });
        }
    }
    for (key, name) in &plan.label_names {
        if !entries.iter().any(|e| key.names(e.layer, e.value)) {
            let layer = key
                .layer
                .map_or(String::new(), |l| format!(" in layer {l}"));
            warnings.push(format!(
                "[labels] names {key} = {name:?}, but no voxel of {}{layer} holds {}",
                loaded.file, key.value
            ));
        }
    }
    let first = map.layers.first();
    let info = LabelMapInfo {
        file: loaded.file.clone(),
        bytes: loaded.bytes,
        blake3: loaded.blake3.clone(),
        space: plan.space,
        dims: first.map_or([0; 3], |l| l.dims),
        spacing_mm: first.map_or([0.0; 3], |l| l.grid.spacing()),
        affine: first.map_or([[0.0; 4]; 4], |l| l.grid.affine()),
        n_layers: map.layers.len(),
        labels: entries,
        warnings,
    };
    (structures, info)
}

/// A structure's voxel size and stack axis in its place, when the header gives them: the
/// grid's spacing and the coordinate axis of the largest spacing, in the grid's frame.
pub fn header_geometry(place: &Place, source: &LabelSource) -> Option<([f32; 3], [f32; 3])> {
    match place {
        Place::World => None,
        Place::Frame(..) => {
            let mut axis = [0.0f32; 3];
            axis[crate::volume::grid::stack_index(source.voxel_mm)] = 1.0;
            Some((source.voxel_mm.map(|x| x as f32), axis))
        }
    }
}
