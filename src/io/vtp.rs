//! VTK XML PolyData (`.vtp`), the surface format ParaView, 3D Slicer, VMTK and pyvista read
//! with every per-vertex and per-face array (VTK's PLY reader drops extra properties). Written
//! with the arrays in raw appended binary (little endian, 64-bit headers), points as Float32,
//! triangles as Int64 connectivity and offsets. The coordinate convention goes into an XML
//! comment and a `SPACE` field-data string.

use crate::io::{MeshMeta, WriteError};
use crate::mesh::Mesh;
use std::path::Path;

/// One named array: a value per vertex (point data) or per face (cell data).
#[derive(Debug, Clone, Copy)]
pub enum VtpArray<'a> {
    Float32(&'a str, &'a [f32]),
    Int32(&'a str, &'a [i32]),
}

impl VtpArray<'_> {
    fn name(&self) -> &str {
        match self {
            VtpArray::Float32(name, _) | VtpArray::Int32(name, _) => name,
        }
    }

    fn len(&self) -> usize {
        match self {
            VtpArray::Float32(_, v) => v.len(),
            VtpArray::Int32(_, v) => v.len(),
        }
    }

    fn type_name(&self) -> &'static str {
        match self {
            VtpArray::Float32(..) => "Float32",
            VtpArray::Int32(..) => "Int32",
        }
    }

    fn bytes(&self) -> Vec<u8> {
        match self {
            VtpArray::Float32(_, v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            VtpArray::Int32(_, v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
        }
    }
}

/// Writes `mesh` as `.vtp` with the given point and cell arrays, atomically. Arrays whose
/// length is not the vertex (point) or face (cell) count are refused before anything is
/// written.
pub fn write_vtp(
    path: &Path,
    mesh: &Mesh,
    meta: &MeshMeta,
    point_data: &[VtpArray],
    cell_data: &[VtpArray],
) -> Result<(), WriteError> {
    let bytes = encode_vtp(mesh, meta, point_data, cell_data)?;
    crate::io::write_bytes_atomically(path, &bytes)
}

/// Encodes `.vtp` in memory (see [`write_vtp`]).
pub fn encode_vtp(
    mesh: &Mesh,
    meta: &MeshMeta,
    point_data: &[VtpArray],
    cell_data: &[VtpArray],
) -> Result<Vec<u8>, WriteError> {
    let (n_points, n_cells) = (mesh.n_vertices(), mesh.n_triangles());
    for (arrays, n, what) in [
        (point_data, n_points, "vertices"),
        (cell_data, n_cells, "faces"),
    ] {
        if let Some(a) = arrays.iter().find(|a| a.len() != n) {
            return Err(WriteError::InvalidArray {
                name: a.name().to_string(),
                message: format!("{} values for {n} {what}", a.len()),
            });
        }
    }
    // The appended blocks, in the order their headers name them.
    let mut blocks: Vec<Vec<u8>> = Vec::new();
    let mut offset = 0u64;
    let mut add = |data: Vec<u8>| {
        let at = offset;
        offset += 8 + data.len() as u64;
        blocks.push(data);
        at
    };
    let mut xml = String::new();
    let space = meta.space().unwrap_or("unknown").to_string();
    xml.push_str("<?xml version=\"1.0\"?>\n");
    xml.push_str(&format!(
        "<!-- destair SPACE={} -->\n",
        escape(&space).replace('-', "_")
    ));
    xml.push_str(
        "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n  <PolyData>\n",
    );
    // VTK's string arrays: each string ends with a zero byte.
    let at = add(space.bytes().chain(std::iter::once(0)).collect());
    xml.push_str(&format!(
        "    <FieldData>\n      <Array type=\"String\" Name=\"SPACE\" NumberOfTuples=\"1\" format=\"appended\" offset=\"{at}\"/>\n    </FieldData>\n"
    ));
    xml.push_str(&format!(
        "    <Piece NumberOfPoints=\"{n_points}\" NumberOfVerts=\"0\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"{n_cells}\">\n"
    ));
    for (tag, arrays) in [("PointData", point_data), ("CellData", cell_data)] {
        match arrays.first() {
            Some(first) => xml.push_str(&format!(
                "      <{tag} Scalars=\"{}\">\n",
                escape(first.name())
            )),
            None => xml.push_str(&format!("      <{tag}>\n")),
        }
        for a in arrays {
            let at = add(a.bytes());
            xml.push_str(&format!(
                "        <DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"1\" format=\"appended\" offset=\"{at}\"/>\n",
                a.type_name(),
                escape(a.name())
            ));
        }
        xml.push_str(&format!("      </{tag}>\n"));
    }
    let points: Vec<u8> = mesh
        .positions()
        .iter()
        .flat_map(|p| p.iter().flat_map(|x| x.to_le_bytes()))
        .collect();
    let at = add(points);
    xml.push_str(&format!(
        "      <Points>\n        <DataArray type=\"Float32\" Name=\"Points\" NumberOfComponents=\"3\" format=\"appended\" offset=\"{at}\"/>\n      </Points>\n"
    ));
    let connectivity: Vec<u8> = mesh
        .triangles()
        .iter()
        .flat_map(|t| t.iter().flat_map(|&v| (v as i64).to_le_bytes()))
        .collect();
    let offsets: Vec<u8> = (1..=n_cells as i64)
        .flat_map(|k| (3 * k).to_le_bytes())
        .collect();
    let (c, o) = (add(connectivity), add(offsets));
    xml.push_str(&format!(
        "      <Polys>\n        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"appended\" offset=\"{c}\"/>\n        <DataArray type=\"Int64\" Name=\"offsets\" format=\"appended\" offset=\"{o}\"/>\n      </Polys>\n"
    ));
    xml.push_str("    </Piece>\n  </PolyData>\n  <AppendedData encoding=\"raw\">\n   _");
    let mut out = xml.into_bytes();
    out.reserve(offset as usize + 64);
    for block in blocks {
        out.extend_from_slice(&(block.len() as u64).to_le_bytes());
        out.extend_from_slice(&block);
    }
    out.extend_from_slice(b"\n  </AppendedData>\n</VTKFile>\n");
    Ok(out)
}

/// Text safe inside an XML attribute or comment.
fn escape(s: &str) -> String {
    s.chars()
        .map(|c| match c {
            '<' | '>' | '&' | '"' | '\'' => '_',
            c if c.is_control() => '_',
            c => c,
        })
        .collect()
}
