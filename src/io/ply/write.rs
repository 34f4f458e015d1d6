//! Binary little-endian PLY writer. Vertex order is kept; faces are written as
//! `list uchar int vertex_indices`, the layout MeshLab and every other reader accept; extra
//! per-vertex scalars (weights, displacements) go out as float properties so ParaView and
//! MeshLab can colour by them. Header comments and obj_info are written back.

use crate::io::{write_atomically, MeshMeta, WriteError};
use crate::mesh::Mesh;
use rayon::prelude::*;
use std::path::Path;

/// Rows per parallel encoding chunk.
const ROWS_PER_CHUNK: usize = 1 << 14;

/// Writes `mesh` as binary little-endian PLY, atomically.
pub fn write_ply(
    path: &Path,
    mesh: &Mesh,
    meta: &MeshMeta,
    vertex_properties: &[(&str, &[f32])],
) -> Result<(), WriteError> {
    let bytes = encode_ply(mesh, meta, vertex_properties)?;
    write_atomically(path, |w| w.write_all(&bytes)).map_err(|source| WriteError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Encodes `mesh` as a binary little-endian PLY file in memory.
pub fn encode_ply(
    mesh: &Mesh,
    meta: &MeshMeta,
    vertex_properties: &[(&str, &[f32])],
) -> Result<Vec<u8>, WriteError> {
    check_properties(mesh, vertex_properties)?;
    let mut header = String::from("ply\nformat binary_little_endian 1.0\n");
    for c in &meta.comments {
        header.push_str(&format!("comment {}\n", one_line(c)));
    }
    for c in &meta.obj_info {
        header.push_str(&format!("obj_info {}\n", one_line(c)));
    }
    header.push_str(&format!(
        "element vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        mesh.n_vertices()
    ));
    for (name, _) in vertex_properties {
        header.push_str(&format!("property float {name}\n"));
    }
    // `int` is what MeshLab expects; only meshes beyond 2^31 vertices need `uint` (same bytes).
    let index_type = if mesh.n_vertices() > i32::MAX as usize {
        "uint"
    } else {
        "int"
    };
    header.push_str(&format!(
        "element face {}\nproperty list uchar {index_type} vertex_indices\nend_header\n",
        mesh.n_triangles()
    ));

    let vertex_row = 12 + 4 * vertex_properties.len();
    let face_row = 13;
    let n_v = mesh.n_vertices();
    let n_f = mesh.n_triangles();
    let body = header.len() + vertex_row * n_v + face_row * n_f;
    let mut out = vec![0u8; body];
    out[..header.len()].copy_from_slice(header.as_bytes());
    let (vertex_bytes, face_bytes) = out[header.len()..].split_at_mut(vertex_row * n_v);
    let positions = mesh.positions();
    vertex_bytes
        .par_chunks_mut(vertex_row * ROWS_PER_CHUNK)
        .enumerate()
        .for_each(|(c, chunk)| {
            for (i, row) in chunk.chunks_exact_mut(vertex_row).enumerate() {
                let v = c * ROWS_PER_CHUNK + i;
                for k in 0..3 {
                    row[4 * k..4 * k + 4].copy_from_slice(&positions[v][k].to_le_bytes());
                }
                for (j, (_, values)) in vertex_properties.iter().enumerate() {
                    row[12 + 4 * j..16 + 4 * j].copy_from_slice(&values[v].to_le_bytes());
                }
            }
        });
    let triangles = mesh.triangles();
    face_bytes
        .par_chunks_mut(face_row * ROWS_PER_CHUNK)
        .enumerate()
        .for_each(|(c, chunk)| {
            for (i, row) in chunk.chunks_exact_mut(face_row).enumerate() {
                let t = triangles[c * ROWS_PER_CHUNK + i];
                row[0] = 3;
                for k in 0..3 {
                    row[1 + 4 * k..5 + 4 * k].copy_from_slice(&t[k].to_le_bytes());
                }
            }
        });
    Ok(out)
}

fn one_line(s: &str) -> String {
    s.replace(['\n', '\r'], " ")
}

fn check_properties(mesh: &Mesh, props: &[(&str, &[f32])]) -> Result<(), WriteError> {
    for (i, (name, values)) in props.iter().enumerate() {
        let bad = |message: String| WriteError::InvalidProperty {
            name: name.to_string(),
            message,
        };
        if name.is_empty() || name.chars().any(|c| c.is_whitespace() || c.is_control()) {
            return Err(bad("names must be non-empty and without spaces".into()));
        }
        if ["x", "y", "z"].contains(name) || props[..i].iter().any(|(n, _)| n == name) {
            return Err(bad("name is used twice".into()));
        }
        if values.len() != mesh.n_vertices() {
            return Err(bad(format!(
                "has {} values but the mesh has {} vertices",
                values.len(),
                mesh.n_vertices()
            )));
        }
    }
    Ok(())
}
