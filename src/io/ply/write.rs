//! Binary little-endian PLY writer. Vertex order is kept; faces are written as
//! `list uchar int vertex_indices`, the layout MeshLab and every other reader accept; extra
//! per-vertex scalars (weights, displacements) go out as float properties so ParaView and
//! MeshLab can colour by them; per-face integers (the two labels an interface separates) go
//! after the face list. Header comments and obj_info are written back.

use crate::io::{write_atomically, write_rows, MeshMeta, WriteError};
use crate::mesh::Mesh;
use std::io::Write;
use std::path::Path;

/// Writes `mesh` as binary little-endian PLY, atomically.
pub fn write_ply(
    path: &Path,
    mesh: &Mesh,
    meta: &MeshMeta,
    vertex_properties: &[(&str, &[f32])],
) -> Result<(), WriteError> {
    write_ply_with_faces(path, mesh, meta, vertex_properties, &[])
}

/// [`write_ply`] with per-face integer properties (written as `int` after the vertex list).
pub fn write_ply_with_faces(
    path: &Path,
    mesh: &Mesh,
    meta: &MeshMeta,
    vertex_properties: &[(&str, &[f32])],
    face_properties: &[(&str, &[i32])],
) -> Result<(), WriteError> {
    check_properties(mesh, vertex_properties)?;
    check_face_properties(mesh, face_properties)?;
    write_atomically(path, |w| {
        write_ply_to(w, mesh, meta, vertex_properties, face_properties)
    })
    .map_err(|source| WriteError::Io {
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
    // Room for the whole file up front (the header is short): growing a buffer of a few
    // hundred MB by doubling copies it several times and faults in every copy's pages.
    let rows = mesh.n_vertices() * (12 + 4 * vertex_properties.len()) + mesh.n_triangles() * 13;
    let mut out = Vec::with_capacity(rows + 4096);
    write_ply_to(&mut out, mesh, meta, vertex_properties, &[])
        .expect("writing to a Vec cannot fail");
    Ok(out)
}

/// Streams the PLY file; properties must have passed `check_properties`.
fn write_ply_to(
    w: &mut dyn Write,
    mesh: &Mesh,
    meta: &MeshMeta,
    vertex_properties: &[(&str, &[f32])],
    face_properties: &[(&str, &[i32])],
) -> std::io::Result<()> {
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
        "element face {}\nproperty list uchar {index_type} vertex_indices\n",
        mesh.n_triangles()
    ));
    for (name, _) in face_properties {
        header.push_str(&format!("property int {name}\n"));
    }
    header.push_str("end_header\n");
    w.write_all(header.as_bytes())?;
    let positions = mesh.positions();
    write_rows(
        w,
        mesh.n_vertices(),
        12 + 4 * vertex_properties.len(),
        |v, row| {
            for k in 0..3 {
                row[4 * k..4 * k + 4].copy_from_slice(&positions[v][k].to_le_bytes());
            }
            for (j, (_, values)) in vertex_properties.iter().enumerate() {
                row[12 + 4 * j..16 + 4 * j].copy_from_slice(&values[v].to_le_bytes());
            }
        },
    )?;
    let triangles = mesh.triangles();
    write_rows(
        w,
        mesh.n_triangles(),
        13 + 4 * face_properties.len(),
        |f, row| {
            row[0] = 3;
            for k in 0..3 {
                row[1 + 4 * k..5 + 4 * k].copy_from_slice(&triangles[f][k].to_le_bytes());
            }
            for (j, (_, values)) in face_properties.iter().enumerate() {
                row[13 + 4 * j..17 + 4 * j].copy_from_slice(&values[f].to_le_bytes());
            }
        },
    )
}

fn one_line(s: &str) -> String {
    s.replace(['\n', '\r'], " ")
}

fn check_properties(mesh: &Mesh, props: &[(&str, &[f32])]) -> Result<(), WriteError> {
    let named: Vec<(&str, usize)> = props.iter().map(|(n, v)| (*n, v.len())).collect();
    check_named(&named, &["x", "y", "z"], mesh.n_vertices(), "vertices")
}

fn check_face_properties(mesh: &Mesh, props: &[(&str, &[i32])]) -> Result<(), WriteError> {
    let named: Vec<(&str, usize)> = props.iter().map(|(n, v)| (*n, v.len())).collect();
    check_named(&named, &["vertex_indices"], mesh.n_triangles(), "faces")
}

/// Property names usable in a header (no spaces, not taken) and one value per element.
fn check_named(
    props: &[(&str, usize)],
    taken: &[&str],
    n: usize,
    elements: &str,
) -> Result<(), WriteError> {
    for (i, &(name, len)) in props.iter().enumerate() {
        let bad = |message: String| WriteError::InvalidProperty {
            name: name.to_string(),
            message,
        };
        if name.is_empty() || name.chars().any(|c| c.is_whitespace() || c.is_control()) {
            return Err(bad("names must be non-empty and without spaces".into()));
        }
        if taken.contains(&name) || props[..i].iter().any(|(n, _)| *n == name) {
            return Err(bad("name is used twice".into()));
        }
        if len != n {
            return Err(bad(format!(
                "has {len} values but the mesh has {n} {elements}"
            )));
        }
    }
    Ok(())
}
