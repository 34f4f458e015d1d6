//! STL, binary and ASCII. STL stores each triangle's corners separately; identical corners are
//! welded into shared vertices (numbered in order of first appearance), so the result is an
//! indexed mesh with real topology. A `SPACE=LPS`/`RAS` tag in the binary header or the ASCII
//! solid name becomes a `SPACE=` comment, and the writer puts it back.

use crate::io::text::{parse_f64, show, TextCursor};
use crate::io::{
    write_atomically, write_rows, DecodeResult, FaceStats, LoadedMesh, MeshMeta, ReadErrorKind,
    SourceFormat, WriteError,
};
use crate::mesh::geometry::{normalize, triangle_area_vector};
use crate::mesh::{check_size, is_valid_coordinate, Mesh};
use rustc_hash::FxHashMap;
use std::io::Write;
use std::path::Path;

const HEADER: usize = 80;
const RECORD: usize = 50;

/// True when the bytes are laid out as a binary STL or start like an ASCII one.
pub(crate) fn looks_like_stl(bytes: &[u8]) -> bool {
    binary_size_matches(bytes) || looks_ascii(bytes)
}

fn binary_size_matches(bytes: &[u8]) -> bool {
    bytes.len() >= HEADER + 4 && {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        (HEADER + 4) as u64 + RECORD as u64 * n == bytes.len() as u64
    }
}

fn looks_ascii(bytes: &[u8]) -> bool {
    let head = &bytes[..bytes.len().min(1024)];
    let trimmed = head.trim_ascii_start();
    trimmed.starts_with(b"solid")
        && head.iter().all(|&b| b.is_ascii())
        && (contains(head, b"facet") || contains(head, b"endsolid"))
}

fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    haystack.windows(needle.len()).any(|w| w == needle)
}

/// Decodes binary or ASCII STL.
pub(crate) fn decode(bytes: &[u8]) -> DecodeResult {
    // Binary files whose header happens to start with "solid" are common, so the size check
    // wins unless the start really reads as ASCII STL.
    if looks_ascii(bytes) {
        decode_ascii(bytes)
    } else if binary_size_matches(bytes) {
        decode_binary(bytes)
    } else if bytes.len() >= HEADER + 4 {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        Err(ReadErrorKind::SizeMismatch {
            message: format!(
                "binary STL declares {n} triangles, which need {} bytes, but the file has {} bytes",
                (HEADER + 4) as u64 + RECORD as u64 * n,
                bytes.len()
            ),
        })
    } else {
        Err(ReadErrorKind::Malformed {
            place: "byte 0".into(),
            message: format!(
                "{} bytes is too short for a binary STL and it does not start like an ASCII STL",
                bytes.len()
            ),
        })
    }
}

/// Welds corners with bit-identical coordinates (+0 and -0 taken as equal) into vertices.
struct Welder {
    index: FxHashMap<[u32; 3], u32>,
    positions: Vec<[f32; 3]>,
}

impl Welder {
    fn with_capacity(n: usize) -> Self {
        Self {
            index: FxHashMap::with_capacity_and_hasher(n, Default::default()),
            positions: Vec::with_capacity(n),
        }
    }

    fn vertex(&mut self, p: [f32; 3]) -> u32 {
        let key = p.map(|v| (v + 0.0).to_bits());
        let next = self.positions.len() as u32;
        *self.index.entry(key).or_insert_with(|| {
            self.positions.push(p);
            next
        })
    }
}

fn space_comment(text: &[u8]) -> Vec<String> {
    let text = String::from_utf8_lossy(text);
    text.split(|c: char| c.is_whitespace() || c == '\0')
        .find(|w| w.starts_with("SPACE=") && w.len() > "SPACE=".len())
        .map(|w| vec![w.to_string()])
        .unwrap_or_default()
}

fn decode_binary(bytes: &[u8]) -> DecodeResult {
    let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
    check_size(n.saturating_mul(3), n)?;
    // Corner c of the file (the size check above guarantees every record is there).
    let offset = |c: usize| HEADER + 4 + RECORD * (c / 3) + 12 + 12 * (c % 3);
    let corner = |c: usize| -> [f32; 3] {
        // One bounds check for the corner's 12 bytes; the reads in it are then known in range.
        let o = offset(c);
        let r = &bytes[o..o + 12];
        std::array::from_fn(|a| {
            f32::from_le_bytes([r[4 * a], r[4 * a + 1], r[4 * a + 2], r[4 * a + 3]])
        })
    };
    let (positions, triangles) = super::weld::weld_triangles(n, corner).map_err(|c| {
        let p = corner(c);
        let a = (0..3).find(|&a| !is_valid_coordinate(p[a])).unwrap_or(0);
        let place = format!(
            "triangle {} corner {} (byte {})",
            c / 3,
            c % 3,
            offset(c) + 4 * a
        );
        ReadErrorKind::bad_coordinate(place, p[a] as f64)
    })?;
    Ok(LoadedMesh {
        mesh: Mesh::from_checked_parts(positions, triangles),
        meta: MeshMeta {
            comments: space_comment(&bytes[..HEADER]),
            obj_info: Vec::new(),
        },
        vertex_properties: Vec::new(),
        warnings: Vec::new(),
        format: SourceFormat::StlBinary,
    })
}

fn decode_ascii(bytes: &[u8]) -> DecodeResult {
    let mut c = TextCursor::new(bytes, 1);
    let mut welder = Welder::with_capacity(0);
    let mut triangles = Vec::new();
    let mut comments = Vec::new();
    let mut stats = FaceStats::default();
    let mut warnings = Vec::new();
    let mut polygon: Vec<u32> = Vec::new();
    let malformed = |c: &TextCursor, message: String| ReadErrorKind::Malformed {
        place: format!("line {}", c.line()),
        message,
    };
    let expect = |c: &mut TextCursor, word: &str| -> Result<(), ReadErrorKind> {
        match c.token() {
            Some(t) if t == word.as_bytes() => Ok(()),
            Some(t) => Err(malformed(
                c,
                format!("expected {word:?}, found {:?}", show(t)),
            )),
            None => Err(ReadErrorKind::Truncated {
                place: format!("line {} (expected {word:?})", c.line()),
            }),
        }
    };
    let number = |c: &mut TextCursor| -> Result<f64, ReadErrorKind> {
        match c.token() {
            Some(t) => {
                parse_f64(t).ok_or_else(|| malformed(c, format!("{:?} is not a number", show(t))))
            }
            None => Err(ReadErrorKind::Truncated {
                place: format!("line {} (expected a number)", c.line()),
            }),
        }
    };
    expect(&mut c, "solid")?;
    comments.extend(space_comment(c.rest_of_line()));
    loop {
        let line = c.line();
        match c.token() {
            Some(b"facet") => {
                expect(&mut c, "normal")?;
                for _ in 0..3 {
                    number(&mut c)?;
                }
                expect(&mut c, "outer")?;
                expect(&mut c, "loop")?;
                polygon.clear();
                loop {
                    match c.token() {
                        Some(b"vertex") => {
                            let xyz = [number(&mut c)?, number(&mut c)?, number(&mut c)?];
                            let p = xyz.map(|v| v as f32);
                            if let Some(a) = (0..3).find(|&a| !is_valid_coordinate(p[a])) {
                                return Err(ReadErrorKind::bad_coordinate(
                                    format!("line {}", c.line()),
                                    xyz[a],
                                ));
                            }
                            polygon.push(welder.vertex(p));
                        }
                        Some(b"endloop") => break,
                        Some(t) => {
                            return Err(malformed(
                                &c,
                                format!("expected \"vertex\" or \"endloop\", found {:?}", show(t)),
                            ))
                        }
                        None => {
                            return Err(ReadErrorKind::Truncated {
                                place: format!("line {} (inside a facet)", c.line()),
                            })
                        }
                    }
                }
                expect(&mut c, "endfacet")?;
                stats.push_polygon(&polygon, &mut triangles);
            }
            Some(b"endsolid") => {
                c.rest_of_line();
                match c.token() {
                    None => break,
                    Some(b"solid") => {
                        c.rest_of_line();
                    }
                    Some(t) => {
                        return Err(malformed(
                            &c,
                            format!(
                                "expected \"solid\" or the end of the file, found {:?}",
                                show(t)
                            ),
                        ))
                    }
                }
            }
            Some(t) => {
                return Err(ReadErrorKind::Malformed {
                    place: format!("line {line}"),
                    message: format!("expected \"facet\" or \"endsolid\", found {:?}", show(t)),
                })
            }
            None => {
                warnings.push("the file ends without \"endsolid\"".into());
                break;
            }
        }
    }
    check_size(welder.positions.len(), triangles.len())?;
    stats.warnings(&mut warnings);
    Ok(LoadedMesh {
        mesh: Mesh::from_checked_parts(welder.positions, triangles),
        meta: MeshMeta {
            comments,
            obj_info: Vec::new(),
        },
        vertex_properties: Vec::new(),
        warnings,
        format: SourceFormat::StlAscii,
    })
}

/// Writes `mesh` as binary STL, atomically.
pub fn write_stl(path: &Path, mesh: &Mesh, meta: &MeshMeta) -> Result<(), WriteError> {
    write_atomically(path, |w| write_stl_to(w, mesh, meta)).map_err(|source| WriteError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes `mesh` as one ASCII STL holding a `solid NAME` per entry of `solids` (its faces), as
/// OpenFOAM's snappyHexMesh takes patches, atomically. The first solid's line carries the
/// `SPACE=` tag when the mesh has one.
pub fn write_stl_solids(
    path: &Path,
    mesh: &Mesh,
    meta: &MeshMeta,
    solids: &[(&str, &[u32])],
) -> Result<(), WriteError> {
    crate::io::write_bytes_atomically(path, &encode_stl_solids(mesh, meta, solids))
}

/// Encodes a multi-solid ASCII STL in memory (see [`write_stl_solids`]). Names keep letters,
/// digits, `_` and `-`; anything else becomes `_`. Numbers are written in their shortest form
/// that reads back to the same `f32`; facets are encoded in parallel chunks, joined in order.
pub fn encode_stl_solids(mesh: &Mesh, meta: &MeshMeta, solids: &[(&str, &[u32])]) -> Vec<u8> {
    use rayon::prelude::*;
    let mut out = Vec::new();
    for (k, (name, faces)) in solids.iter().enumerate() {
        let name: String = name
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        out.extend_from_slice(format!("solid {name}").as_bytes());
        if let (0, Some(space)) = (k, meta.space()) {
            out.extend_from_slice(format!(" SPACE={space}").as_bytes());
        }
        out.push(b'\n');
        let chunks: Vec<Vec<u8>> = faces
            .par_chunks(4096)
            .map(|chunk| ascii_facets(mesh, chunk))
            .collect();
        for chunk in chunks {
            out.extend_from_slice(&chunk);
        }
        out.extend_from_slice(format!("endsolid {name}\n").as_bytes());
    }
    out
}

/// The ASCII `facet` blocks of `faces` (indices into `mesh`).
fn ascii_facets(mesh: &Mesh, faces: &[u32]) -> Vec<u8> {
    let p = mesh.positions();
    let mut out = Vec::with_capacity(faces.len() * 240);
    let mut number = zmij::Buffer::new();
    let mut row = |out: &mut Vec<u8>, head: &[u8], xyz: [f32; 3]| {
        out.extend_from_slice(head);
        for x in xyz {
            out.push(b' ');
            out.extend_from_slice(number.format(x).as_bytes());
        }
        out.push(b'\n');
    };
    for &f in faces {
        let t = mesh.triangles()[f as usize];
        let n = normalize(triangle_area_vector(mesh, t));
        row(&mut out, b"  facet normal", n);
        out.extend_from_slice(b"    outer loop\n");
        for v in t {
            row(&mut out, b"      vertex", p[v as usize]);
        }
        out.extend_from_slice(b"    endloop\n  endfacet\n");
    }
    out
}

/// Encodes binary STL in memory (see [`write_stl`]).
pub fn encode_stl(mesh: &Mesh, meta: &MeshMeta) -> Vec<u8> {
    // The exact size up front: no copies while the buffer grows.
    let mut out = Vec::with_capacity(HEADER + 4 + 50 * mesh.n_triangles());
    write_stl_to(&mut out, mesh, meta).expect("writing to a Vec cannot fail");
    out
}

/// Streams binary STL. The 80-byte header starts with "destair" (never "solid", which makes
/// readers misdetect ASCII) and carries the `SPACE=` tag when the mesh has one.
fn write_stl_to(w: &mut dyn Write, mesh: &Mesh, meta: &MeshMeta) -> std::io::Result<()> {
    let mut text = String::from("destair binary STL");
    if let Some(space) = meta.space() {
        text.push_str(" SPACE=");
        text.push_str(space);
    }
    let mut header = [0u8; HEADER + 4];
    let n = text.len().min(HEADER);
    header[..n].copy_from_slice(&text.as_bytes()[..n]);
    header[HEADER..].copy_from_slice(&(mesh.n_triangles() as u32).to_le_bytes());
    w.write_all(&header)?;
    let p = mesh.positions();
    let triangles = mesh.triangles();
    write_rows(w, triangles.len(), RECORD, |f, record| {
        let t = triangles[f];
        let normal = normalize(triangle_area_vector(mesh, t));
        let values = normal
            .iter()
            .chain(t.iter().flat_map(|&v| p[v as usize].iter()));
        for (slot, v) in record.chunks_exact_mut(4).zip(values) {
            slot.copy_from_slice(&v.to_le_bytes());
        }
    })
}
