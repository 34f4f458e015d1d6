//! Loading one case: its mesh files read, hashed and decoded (a scattered numbering renumbered
//! once, for every pass to run in), its label maps read, and the key a resumed run compares.

use super::discover::CaseInput;
use super::label_map::{load_label_map, LabelSource, LoadedLabelMap, Place};
use super::plan::{Plan, StructureSettings};
use crate::io::{decode_mesh, extension, with_file_bytes, LoadedMesh, ReadOptions};
use crate::mesh::order::Renumbering;
use crate::mesh::Mesh;

/// One input file, read, hashed and decoded.
#[derive(Debug)]
pub struct LoadedFile {
    pub structure: String,
    pub file: String,
    pub bytes: u64,
    pub blake3: String,
    pub mesh: Result<LoadedMesh, String>,
    /// Where the mesh's coordinates live (world, or a label map grid's frame).
    pub place: Place,
    /// The label map and label the structure was extracted from.
    pub source: Option<LabelSource>,
    /// For a constrained label surface, the binary extraction with the same triangles: the
    /// "before" of its metrics.
    pub binary: Option<Mesh>,
    /// For a file whose numbering is scattered, the scanline order its mesh was renumbered to
    /// after reading (every pass runs in it); outputs go back to the file's numbering.
    pub renumbering: Option<Renumbering>,
    /// For a label surface, the structures of the same label map whose surfaces hold some of
    /// its triangles (they share an interface).
    pub shares_triangles_with: Vec<String>,
}

impl LoadedCase {
    /// Estimated peak bytes of processing the case, now that its label maps' surfaces are
    /// counted: its meshes' estimate and each map's.
    pub fn memory(&self) -> u64 {
        self.label_maps.iter().map(|m| m.memory).fold(
            super::memory::mesh_memory(&self.input.meshes),
            u64::saturating_add,
        )
    }
}

/// A case with its files in memory.
#[derive(Debug)]
pub struct LoadedCase {
    pub input: CaseInput,
    pub files: Vec<LoadedFile>,
    /// The case's label maps, read (their labels become structures when the case is processed).
    pub label_maps: Vec<LoadedLabelMap>,
    /// Key for resuming: the plan's output fingerprint for these structures and the input hashes.
    pub key: String,
}

/// Reads, hashes and decodes the meshes of a case.
pub fn load_case(plan: &Plan, input: CaseInput) -> LoadedCase {
    let options = ReadOptions {
        mode: plan.read_mode,
        ..Default::default()
    };
    // Meshes whose estimate exceeds what this process may use fail with the figures: running
    // them could abort the process (an address-space limit) or have it killed (a cgroup), and
    // every rerun would die at the same case, leaving the cases after it undone. A case beyond
    // the budget but within the limit runs alone.
    let need = super::memory::mesh_memory(&input.meshes);
    let beyond = (need > plan.memory_limit.bytes).then(|| {
        format!(
            "the case's meshes ({} MB) need about {} MB by the estimate (24 bytes per input byte), more than this process may use ({} MB, by {}); raise that limit",
            (need / super::memory::MEMORY_PER_INPUT_BYTE).div_ceil(1 << 20),
            need.div_ceil(1 << 20),
            plan.memory_limit.bytes.div_ceil(1 << 20),
            plan.memory_limit.source
        )
    });
    let files: Vec<LoadedFile> = input
        .meshes
        .iter()
        .map(|(structure, path)| {
            let file = path
                .file_name()
                .map_or_else(String::new, |f| f.to_string_lossy().into_owned());
            let ext = extension(path);
            match with_file_bytes(path, plan.read_mode, |b| {
                let hash = blake3::hash(b).to_hex().to_string();
                let mesh = match &beyond {
                    Some(why) => Err(why.clone()),
                    None => decode_mesh(b, ext.as_deref(), &options).map_err(|e| e.to_string()),
                };
                (b.len() as u64, hash, mesh)
            }) {
                Ok((bytes, blake3, mesh)) => {
                    let mut mesh = mesh.map_err(|e| format!("{}: {e}", plan.display(path)));
                    let renumbering = match &mut mesh {
                        Ok(loaded) => in_working_numbering(plan, structure, loaded),
                        Err(_) => None,
                    };
                    LoadedFile {
                        structure: structure.clone(),
                        file,
                        bytes,
                        blake3,
                        mesh,
                        place: Place::World,
                        source: None,
                        binary: None,
                        renumbering,
                        shares_triangles_with: Vec::new(),
                    }
                }
                Err(e) => LoadedFile {
                    structure: structure.clone(),
                    file,
                    bytes: 0,
                    blake3: String::new(),
                    mesh: Err(format!("{}: cannot read: {e}", plan.display(path))),
                    place: Place::World,
                    source: None,
                    binary: None,
                    renumbering: None,
                    shares_triangles_with: Vec::new(),
                },
            }
        })
        .collect();
    // Each label map within what the budget leaves after the meshes and the maps before it.
    let mut room = plan
        .memory_budget_bytes
        .saturating_sub(super::memory::mesh_memory(&input.meshes));
    let label_maps: Vec<LoadedLabelMap> = input
        .label_maps
        .iter()
        .map(|p| {
            let m = load_label_map(plan, p, room);
            room = room.saturating_sub(m.memory);
            m
        })
        .collect();
    let key = resume_key(plan, &input, &files, &label_maps);
    LoadedCase {
        input,
        files,
        label_maps,
        key,
    }
}

/// Renumbers a mesh file whose numbering is scattered into its working numbering, as
/// `destair smooth` does (so both write the same bytes), unless the structure has the cfd
/// profile, whose outputs are new surfaces. Returns the renumbering, for writing back.
fn in_working_numbering(
    plan: &Plan,
    structure: &str,
    loaded: &mut LoadedMesh,
) -> Option<Renumbering> {
    if plan.settings_for(structure).cfd.is_some() {
        return None;
    }
    let r = crate::mesh::order::working_numbering(&loaded.mesh)?;
    loaded.mesh = r.mesh(&loaded.mesh);
    Some(r)
}

fn resume_key(
    plan: &Plan,
    input: &CaseInput,
    files: &[LoadedFile],
    label_maps: &[LoadedLabelMap],
) -> String {
    let settings: Vec<(String, StructureSettings)> = input
        .meshes
        .iter()
        .map(|(name, _)| (name.clone(), plan.settings_for(name)))
        .collect();
    let mut h = blake3::Hasher::new();
    h.update(plan.output_fingerprint(&settings).as_bytes());
    for f in files {
        h.update(f.structure.as_bytes());
        h.update(&[0]);
        h.update(f.blake3.as_bytes());
        h.update(&[0]);
    }
    if !label_maps.is_empty() {
        // Structure names come from the files, so every settings table may apply to them.
        h.update(plan.settings_fingerprint().as_bytes());
        // The limits decide what is refused; and a map refused for memory is tried again
        // under another budget.
        h.update(format!("{:?}", plan.label_limits).as_bytes());
        if label_maps.iter().any(|m| m.over_budget) {
            h.update(format!("budget {}", plan.memory_budget_bytes).as_bytes());
        }
        for m in label_maps {
            h.update(m.file.as_bytes());
            h.update(&[0]);
            h.update(m.blake3.as_bytes());
            h.update(&[0]);
        }
    }
    h.finalize().to_hex().to_string()
}
