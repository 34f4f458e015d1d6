//! Wavefront OBJ reader: `v` and `f` statements (indices as `i`, `i/t`, `i/t/n`, `i//n`,
//! negative = relative to the last vertex), polygons fan-triangulated. Normals, texture
//! coordinates, groups and materials are ignored; lines and points are skipped with a warning.

use crate::io::text::{parse_f64, parse_i64, show, TextCursor};
use crate::io::{DecodeResult, FaceStats, LoadedMesh, MeshMeta, ReadErrorKind, SourceFormat};
use crate::mesh::{check_size, is_valid_coordinate, Mesh};

/// Decodes an OBJ file.
pub(crate) fn decode(bytes: &[u8]) -> DecodeResult {
    let mut c = TextCursor::new(bytes, 1);
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut triangles = Vec::new();
    let mut stats = FaceStats::default();
    let mut polygon: Vec<u32> = Vec::new();
    let mut skipped_elements = 0u64;
    loop {
        c.skip_space();
        let line = c.line();
        let Some(keyword) = c.inline_token() else {
            break;
        };
        let malformed = |message: String| ReadErrorKind::Malformed {
            place: format!("line {line}"),
            message,
        };
        match keyword {
            b"v" => {
                let mut xyz = [0.0f64; 3];
                for v in &mut xyz {
                    let t = c
                        .inline_token()
                        .ok_or_else(|| malformed("vertex needs 3 coordinates".into()))?;
                    *v = parse_f64(t)
                        .ok_or_else(|| malformed(format!("{:?} is not a number", show(t))))?;
                }
                let p = xyz.map(|v| v as f32);
                if let Some(k) = (0..3).find(|&k| !is_valid_coordinate(p[k])) {
                    return Err(ReadErrorKind::bad_coordinate(
                        format!("line {line}"),
                        xyz[k],
                    ));
                }
                positions.push(p);
                // Optional w and vertex colours follow; they are ignored.
                c.rest_of_line();
            }
            b"f" => {
                polygon.clear();
                while let Some(t) = c.inline_token() {
                    let first = t.split(|&b| b == b'/').next().unwrap_or(t);
                    let raw = parse_i64(first).ok_or_else(|| {
                        malformed(format!("face corner {:?} is not a vertex index", show(t)))
                    })?;
                    let n = positions.len() as i64;
                    // OBJ indices count from 1; negative ones count back from the last vertex.
                    let index = if raw > 0 { raw - 1 } else { n + raw };
                    if raw == 0 || index < 0 || index >= n {
                        return Err(ReadErrorKind::IndexOutOfRange {
                            place: format!("line {line} (face corner {raw})"),
                            index: raw,
                            n_vertices: n as u64,
                        });
                    }
                    polygon.push(index as u32);
                }
                stats.push_polygon(&polygon, &mut triangles);
            }
            b"l" | b"p" => {
                skipped_elements += 1;
                c.rest_of_line();
            }
            _ => {
                // Comments, normals, texture coordinates, groups, materials, smoothing groups.
                c.rest_of_line();
            }
        }
    }
    check_size(positions.len(), triangles.len())?;
    let mut warnings = Vec::new();
    stats.warnings(&mut warnings);
    if skipped_elements > 0 {
        warnings.push(format!(
            "{skipped_elements} line and point statements were skipped"
        ));
    }
    Ok(LoadedMesh {
        mesh: Mesh::from_checked_parts(positions, triangles),
        meta: MeshMeta::default(),
        vertex_properties: Vec::new(),
        warnings,
        format: SourceFormat::Obj,
    })
}
