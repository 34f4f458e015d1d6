//! Files a flow solver's mesher takes directly, written atomically next to each other:
//! `STEM_solids.stl` (ASCII, one `solid` per patch named `wall`, `inlet`, `outlet_1`, ..., as
//! OpenFOAM's snappyHexMesh expects), `STEM_NAME.stl` (binary, one per patch), `STEM.vtp` (the
//! surface with VMTK's `CellEntityIds` cell array) and `STEM_patches.json` (the patch table).
//! Open ends that were not closed have no faces and appear only in the JSON.

use super::patches::{Patches, WALL_ID};
use crate::io::vtp::{encode_vtp, VtpArray};
use crate::io::{MeshMeta, WriteError};
use crate::mesh::Mesh;
use std::path::{Path, PathBuf};

/// The paths [`write_patch_files`] writes for `patches`, in its order (to check before
/// writing that none is an input).
pub fn planned_files(dir: &Path, stem: &str, patches: &Patches) -> Vec<PathBuf> {
    let mut names = vec![format!("{stem}_solids.stl"), format!("{stem}_wall.stl")];
    for p in patches.patches.iter().filter(|p| !p.faces.is_empty()) {
        names.push(format!("{stem}_{}.stl", p.name));
    }
    names.push(format!("{stem}.vtp"));
    names.push(format!("{stem}_patches.json"));
    names.into_iter().map(|n| dir.join(n)).collect()
}

/// Writes the patch files of `mesh` (whose patches are `patches`) into `dir`, each
/// atomically; returns their paths, in the order above.
pub fn write_patch_files(
    dir: &Path,
    stem: &str,
    mesh: &Mesh,
    meta: &MeshMeta,
    patches: &Patches,
) -> Result<Vec<PathBuf>, WriteError> {
    let files = encode_patch_files(stem, mesh, meta, patches)?;
    let mut written = Vec::with_capacity(files.len());
    for (name, bytes) in files {
        let path = dir.join(name);
        crate::io::write_bytes_atomically(&path, &bytes)?;
        written.push(path);
    }
    Ok(written)
}

/// The patch files of `mesh` in memory: (file name, bytes) in the order of
/// [`planned_files`], for a writer that writes a case's outputs together.
pub fn encode_patch_files(
    stem: &str,
    mesh: &Mesh,
    meta: &MeshMeta,
    patches: &Patches,
) -> Result<Vec<(String, Vec<u8>)>, WriteError> {
    let n = mesh.n_triangles();
    if patches.face_ids.len() != n
        || patches
            .patches
            .iter()
            .flat_map(|p| &p.faces)
            .any(|&f| f as usize >= n)
    {
        return Err(WriteError::InvalidArray {
            name: "CellEntityIds".into(),
            message: "the patches were not found on this mesh".into(),
        });
    }
    let mut files = Vec::new();
    let wall: Vec<u32> = (0..n as u32)
        .filter(|&f| patches.face_ids.get(f as usize) == Some(&WALL_ID))
        .collect();
    let mut solids: Vec<(&str, &[u32])> = vec![("wall", &wall)];
    for p in patches.patches.iter().filter(|p| !p.faces.is_empty()) {
        solids.push((p.name.as_str(), &p.faces));
    }
    files.push((
        format!("{stem}_solids.stl"),
        crate::io::stl::encode_stl_solids(mesh, meta, &solids),
    ));
    for (name, faces) in &solids {
        files.push((
            format!("{stem}_{name}.stl"),
            crate::io::stl::encode_stl(&mesh.select_faces(faces), meta),
        ));
    }
    let ids: Vec<i32> = patches.face_ids.iter().map(|&id| id as i32).collect();
    files.push((
        format!("{stem}.vtp"),
        encode_vtp(mesh, meta, &[], &[VtpArray::Int32("CellEntityIds", &ids)])?,
    ));
    let table = serde_json::json!({
        "space": meta.space(),
        "cell_entity_ids": "wall 1, then each patch's id",
        "patches": patches.patches,
        "wall_faces": patches.wall_faces,
    });
    let text = serde_json::to_vec_pretty(&table).map_err(|e| WriteError::InvalidArray {
        name: "patches".into(),
        message: e.to_string(),
    })?;
    files.push((format!("{stem}_patches.json"), text));
    Ok(files)
}
