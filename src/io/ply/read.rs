//! PLY decoding. Binary elements with a fixed row stride are decoded in parallel straight from
//! the mapped bytes (x, y, z at any offset, either endianness; faces optimistically as
//! triangles with every count checked). Everything else (ASCII, list properties in vertices,
//! polygons, unknown elements) goes through a general row decoder. Both validate indices and
//! coordinates as they go and name the element row and byte offset or line of any problem.

use super::header::{parse_header, ElementDef, Encoding, Header, PropertyType, ScalarType};
use crate::io::text::{parse_f64, parse_i64, show, TextCursor};
use crate::io::{
    DecodeResult, FaceStats, LoadedMesh, MeshMeta, ReadErrorKind, ReadOptions, SourceFormat,
    VertexProperty,
};
use crate::mesh::{check_size, is_valid_coordinate, Mesh};
use rayon::prelude::*;

/// Rows per parallel chunk in the fixed-stride decoders.
const ROWS_PER_CHUNK: usize = 1 << 14;

/// What the decoder does with one property of an element.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    Skip,
    Coord(usize),
    Extra(usize),
    Indices,
}

/// Everything decoded so far.
struct Decoded {
    positions: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
    extras: Vec<Vec<f32>>,
    stats: FaceStats,
}

/// Decodes a whole PLY file.
pub(crate) fn decode(bytes: &[u8], options: &ReadOptions) -> DecodeResult {
    let header = parse_header(bytes)?;
    let vertex = header
        .element("vertex")
        .ok_or_else(|| ReadErrorKind::Header {
            line: header.n_lines,
            message: "header has no 'vertex' element".into(),
        })?;
    let n_vertices = vertex.count;
    let face_count = header.element("face").map_or(0, |f| f.count);
    check_size(
        usize::try_from(n_vertices).unwrap_or(usize::MAX),
        usize::try_from(face_count).unwrap_or(usize::MAX),
    )?;
    let vertex_roles = vertex_roles(vertex, options.keep_vertex_properties)?;
    let extra_names: Vec<String> = vertex
        .properties
        .iter()
        .zip(&vertex_roles)
        .filter(|(_, r)| matches!(r, Role::Extra(_)))
        .map(|(p, _)| p.name.clone())
        .collect();
    let face_roles = match header.element("face") {
        Some(face) => Some(face_roles(face)?),
        None => None,
    };
    let mut out = Decoded {
        positions: Vec::new(),
        triangles: Vec::new(),
        extras: vec![Vec::new(); extra_names.len()],
        stats: FaceStats::default(),
    };
    let mut warnings = Vec::new();
    let data = &bytes[header.data_start..];
    let format = match header.encoding {
        Encoding::Ascii => {
            decode_ascii(
                &header,
                data,
                &vertex_roles,
                face_roles.as_deref(),
                &mut out,
                &mut warnings,
            )?;
            SourceFormat::PlyAscii
        }
        Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => {
            decode_binary(
                &header,
                data,
                &vertex_roles,
                face_roles.as_deref(),
                &mut out,
                &mut warnings,
            )?;
            if header.encoding == Encoding::BinaryBigEndian {
                SourceFormat::PlyBinaryBigEndian
            } else {
                SourceFormat::PlyBinaryLittleEndian
            }
        }
    };
    if header.element("face").is_none() {
        warnings.push("the file has no 'face' element: the mesh has no triangles".into());
    }
    out.stats.warnings(&mut warnings);
    let vertex_properties = extra_names
        .into_iter()
        .zip(out.extras)
        .map(|(name, values)| VertexProperty { name, values })
        .collect();
    Ok(LoadedMesh {
        mesh: Mesh::from_checked_parts(out.positions, out.triangles),
        meta: MeshMeta {
            comments: header.comments,
            obj_info: header.obj_info,
        },
        vertex_properties,
        warnings,
        format,
    })
}

fn vertex_roles(vertex: &ElementDef, keep_extras: bool) -> Result<Vec<Role>, ReadErrorKind> {
    let mut roles = vec![Role::Skip; vertex.properties.len()];
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        let i = vertex.property(axis).ok_or_else(|| ReadErrorKind::Header {
            line: vertex.line,
            message: format!("element vertex has no property {axis:?}"),
        })?;
        if !matches!(vertex.properties[i].ty, PropertyType::Scalar(_)) {
            return Err(ReadErrorKind::Header {
                line: vertex.line,
                message: format!("vertex property {axis:?} is a list, not a number"),
            });
        }
        roles[i] = Role::Coord(k);
    }
    if keep_extras {
        let mut n = 0;
        for (role, p) in roles.iter_mut().zip(&vertex.properties) {
            if *role == Role::Skip && matches!(p.ty, PropertyType::Scalar(_)) {
                *role = Role::Extra(n);
                n += 1;
            }
        }
    }
    Ok(roles)
}

fn face_roles(face: &ElementDef) -> Result<Vec<Role>, ReadErrorKind> {
    let i = face
        .property("vertex_indices")
        .or_else(|| face.property("vertex_index"))
        .ok_or_else(|| ReadErrorKind::Header {
            line: face.line,
            message: "element face has no 'vertex_indices' (or 'vertex_index') list".into(),
        })?;
    match face.properties[i].ty {
        PropertyType::List { item, .. } if item.is_integer() => {}
        _ => {
            return Err(ReadErrorKind::Header {
                line: face.line,
                message: format!(
                    "face property {:?} must be a list of integers",
                    face.properties[i].name
                ),
            })
        }
    }
    let mut roles = vec![Role::Skip; face.properties.len()];
    roles[i] = Role::Indices;
    Ok(roles)
}

// ---------------------------------------------------------------------------------------------
// Binary

#[inline(always)]
fn bytes4(b: &[u8], o: usize) -> [u8; 4] {
    [b[o], b[o + 1], b[o + 2], b[o + 3]]
}

#[inline(always)]
fn read_scalar(b: &[u8], o: usize, t: ScalarType, big_endian: bool) -> f64 {
    macro_rules! num {
        ($ty:ty, $n:expr) => {{
            let mut a = [0u8; $n];
            a.copy_from_slice(&b[o..o + $n]);
            (if big_endian {
                <$ty>::from_be_bytes(a)
            } else {
                <$ty>::from_le_bytes(a)
            }) as f64
        }};
    }
    match t {
        ScalarType::I8 => b[o] as i8 as f64,
        ScalarType::U8 => b[o] as f64,
        ScalarType::I16 => num!(i16, 2),
        ScalarType::U16 => num!(u16, 2),
        ScalarType::I32 => num!(i32, 4),
        ScalarType::U32 => num!(u32, 4),
        ScalarType::F32 => {
            let a = bytes4(b, o);
            (if big_endian {
                f32::from_be_bytes(a)
            } else {
                f32::from_le_bytes(a)
            }) as f64
        }
        ScalarType::F64 => num!(f64, 8),
    }
}

#[inline(always)]
fn read_integer(b: &[u8], o: usize, t: ScalarType, big_endian: bool) -> i64 {
    match t {
        ScalarType::I8 => b[o] as i8 as i64,
        ScalarType::U8 => b[o] as i64,
        ScalarType::I16 | ScalarType::U16 => {
            let a = [b[o], b[o + 1]];
            let v = if big_endian {
                u16::from_be_bytes(a)
            } else {
                u16::from_le_bytes(a)
            };
            if t == ScalarType::I16 {
                v as i16 as i64
            } else {
                v as i64
            }
        }
        ScalarType::I32 | ScalarType::U32 => {
            let a = bytes4(b, o);
            let v = if big_endian {
                u32::from_be_bytes(a)
            } else {
                u32::from_le_bytes(a)
            };
            if t == ScalarType::I32 {
                v as i32 as i64
            } else {
                v as i64
            }
        }
        // Index lists of float type are rejected in the header; counts too.
        ScalarType::F32 | ScalarType::F64 => read_scalar(b, o, t, big_endian) as i64,
    }
}

fn decode_binary(
    header: &Header,
    data: &[u8],
    vertex_roles: &[Role],
    face_roles: Option<&[Role]>,
    out: &mut Decoded,
    warnings: &mut Vec<String>,
) -> Result<(), ReadErrorKind> {
    let big_endian = header.encoding == Encoding::BinaryBigEndian;
    let n_vertices = header.element("vertex").map_or(0, |v| v.count);
    let mut pos = 0usize;
    for e in &header.elements {
        if e.properties.is_empty() {
            continue;
        }
        let start = header.data_start;
        pos = match (e.name.as_str(), e.fixed_stride()) {
            ("vertex", Some(stride)) => {
                fixed_vertices(data, pos, stride, e, vertex_roles, big_endian, start, out)?
            }
            ("face", _) => {
                let roles = face_roles.unwrap_or(&[]);
                match triangle_faces(data, pos, e, roles, big_endian, n_vertices, out) {
                    Some(end) => end,
                    None => {
                        let mut src = BinarySource {
                            data,
                            pos,
                            big_endian,
                            file_offset: start,
                        };
                        decode_rows(&mut src, e, roles, n_vertices, out)?;
                        src.pos
                    }
                }
            }
            ("vertex", None) => {
                let mut src = BinarySource {
                    data,
                    pos,
                    big_endian,
                    file_offset: start,
                };
                decode_rows(&mut src, e, vertex_roles, n_vertices, out)?;
                src.pos
            }
            (_, Some(stride)) => {
                skipped(e, warnings);
                let len = stride as u128 * e.count as u128;
                if len > (data.len() - pos) as u128 {
                    let row = (data.len() - pos) / stride;
                    return Err(ReadErrorKind::Truncated {
                        place: format!("{} {} (byte {})", e.name, row, start + pos + row * stride),
                    });
                }
                pos + len as usize
            }
            (_, None) => {
                skipped(e, warnings);
                let roles = vec![Role::Skip; e.properties.len()];
                let mut src = BinarySource {
                    data,
                    pos,
                    big_endian,
                    file_offset: start,
                };
                decode_rows(&mut src, e, &roles, n_vertices, out)?;
                src.pos
            }
        };
    }
    if pos < data.len() {
        warnings.push(format!(
            "{} bytes after the last element were ignored",
            data.len() - pos
        ));
    }
    Ok(())
}

fn skipped(e: &ElementDef, warnings: &mut Vec<String>) {
    if e.count > 0 {
        warnings.push(format!(
            "element {:?} ({} rows) was skipped",
            e.name, e.count
        ));
    }
}

/// Decodes a fixed-stride vertex element in parallel; returns the end offset.
#[allow(clippy::too_many_arguments)]
fn fixed_vertices(
    data: &[u8],
    pos: usize,
    stride: usize,
    e: &ElementDef,
    roles: &[Role],
    big_endian: bool,
    file_offset: usize,
    out: &mut Decoded,
) -> Result<usize, ReadErrorKind> {
    let count = e.count as usize;
    let available = data.len() - pos;
    if (stride as u128) * (count as u128) > available as u128 {
        let row = available / stride;
        return Err(ReadErrorKind::Truncated {
            place: format!("vertex {} (byte {})", row, file_offset + pos + row * stride),
        });
    }
    let rows = &data[pos..pos + stride * count];
    let mut offsets = [0usize; 3];
    let mut types = [ScalarType::F32; 3];
    let mut off = 0;
    let mut extras = Vec::new();
    for (p, role) in e.properties.iter().zip(roles) {
        let PropertyType::Scalar(t) = p.ty else {
            unreachable!("fixed stride implies scalars")
        };
        match *role {
            Role::Coord(k) => {
                offsets[k] = off;
                types[k] = t;
            }
            Role::Extra(j) => extras.push((j, off, t)),
            _ => {}
        }
        off += t.size();
    }
    let all_f32 = types == [ScalarType::F32; 3];
    let mut positions: Vec<[f32; 3]> = crate::hugepages::zeroed_vec(count);
    let bad = positions
        .par_chunks_mut(ROWS_PER_CHUNK)
        .enumerate()
        .filter_map(|(c, chunk)| {
            let first = c * ROWS_PER_CHUNK;
            for (i, p) in chunk.iter_mut().enumerate() {
                let base = (first + i) * stride;
                for k in 0..3 {
                    let o = base + offsets[k];
                    let v = if all_f32 {
                        let a = bytes4(rows, o);
                        if big_endian {
                            f32::from_be_bytes(a)
                        } else {
                            f32::from_le_bytes(a)
                        }
                    } else {
                        read_scalar(rows, o, types[k], big_endian) as f32
                    };
                    if !is_valid_coordinate(v) {
                        let exact = read_scalar(rows, o, types[k], big_endian);
                        return Some((first + i, o, exact));
                    }
                    p[k] = v;
                }
            }
            None
        })
        .min_by_key(|&(row, _, _)| row);
    if let Some((row, o, value)) = bad {
        return Err(ReadErrorKind::bad_coordinate(
            format!("vertex {} (byte {})", row, file_offset + pos + o),
            value,
        ));
    }
    out.positions = positions;
    for (j, off, t) in extras {
        out.extras[j] = (0..count)
            .into_par_iter()
            .map(|r| read_scalar(rows, r * stride + off, t, big_endian) as f32)
            .collect();
    }
    Ok(pos + stride * count)
}

/// Decodes a face element in parallel on the assumption that every row is a triangle with the
/// same stride. Returns `None` (nothing decoded) when that assumption or any index check fails,
/// so the general decoder can redo the element row by row and report exactly what is wrong.
fn triangle_faces(
    data: &[u8],
    pos: usize,
    e: &ElementDef,
    roles: &[Role],
    big_endian: bool,
    n_vertices: u64,
    out: &mut Decoded,
) -> Option<usize> {
    let mut before = 0usize;
    let mut after = 0usize;
    let mut list = None;
    for (p, role) in e.properties.iter().zip(roles) {
        match (p.ty, role) {
            (PropertyType::List { count, item }, Role::Indices) => list = Some((count, item)),
            (PropertyType::List { .. }, _) => return None,
            (PropertyType::Scalar(t), _) if list.is_none() => before += t.size(),
            (PropertyType::Scalar(t), _) => after += t.size(),
        }
    }
    let (count_t, item_t) = list?;
    let row = before + count_t.size() + 3 * item_t.size() + after;
    let count = e.count as usize;
    if row as u128 * count as u128 > (data.len() - pos) as u128 {
        return None;
    }
    let rows = &data[pos..pos + row * count];
    let mut triangles: Vec<[u32; 3]> = crate::hugepages::zeroed_vec(count);
    let (cs, is) = (count_t.size(), item_t.size());
    let failed = triangles
        .par_chunks_mut(ROWS_PER_CHUNK)
        .enumerate()
        .any(|(c, chunk)| {
            let first = c * ROWS_PER_CHUNK;
            for (i, t) in chunk.iter_mut().enumerate() {
                let o = (first + i) * row + before;
                if read_integer(rows, o, count_t, big_endian) != 3 {
                    return true;
                }
                for (k, slot) in t.iter_mut().enumerate() {
                    let v = read_integer(rows, o + cs + k * is, item_t, big_endian);
                    if v < 0 || v as u64 >= n_vertices {
                        return true;
                    }
                    *slot = v as u32;
                }
            }
            false
        });
    if failed {
        return None;
    }
    out.triangles = triangles;
    Some(pos + row * count)
}

// ---------------------------------------------------------------------------------------------
// General row decoder

/// Why a value could not be read.
enum SourceError {
    Truncated,
    Malformed(String),
}

/// A place values are read from, one row at a time.
trait RowSource {
    fn begin_row(&mut self);
    fn scalar(&mut self, t: ScalarType) -> Result<f64, SourceError>;
    fn integer(&mut self, t: ScalarType) -> Result<i64, SourceError>;
    fn skip_list(&mut self, n: u64, t: ScalarType) -> Result<(), SourceError>;
    fn end_row(&mut self) -> Result<(), SourceError>;
    /// Where the cursor is, for messages: "byte N" or "line N".
    fn location(&self) -> String;
}

struct BinarySource<'a> {
    data: &'a [u8],
    pos: usize,
    big_endian: bool,
    file_offset: usize,
}

impl BinarySource<'_> {
    fn take(&mut self, n: usize) -> Result<usize, SourceError> {
        if self.data.len() - self.pos < n {
            return Err(SourceError::Truncated);
        }
        let at = self.pos;
        self.pos += n;
        Ok(at)
    }
}

impl RowSource for BinarySource<'_> {
    fn begin_row(&mut self) {}

    fn scalar(&mut self, t: ScalarType) -> Result<f64, SourceError> {
        let at = self.take(t.size())?;
        Ok(read_scalar(self.data, at, t, self.big_endian))
    }

    fn integer(&mut self, t: ScalarType) -> Result<i64, SourceError> {
        let at = self.take(t.size())?;
        Ok(read_integer(self.data, at, t, self.big_endian))
    }

    fn skip_list(&mut self, n: u64, t: ScalarType) -> Result<(), SourceError> {
        let len = n as u128 * t.size() as u128;
        if len > (self.data.len() - self.pos) as u128 {
            return Err(SourceError::Truncated);
        }
        self.pos += len as usize;
        Ok(())
    }

    fn end_row(&mut self) -> Result<(), SourceError> {
        Ok(())
    }

    fn location(&self) -> String {
        format!("byte {}", self.file_offset + self.pos)
    }
}

struct AsciiSource<'a> {
    cursor: TextCursor<'a>,
}

impl AsciiSource<'_> {
    fn token(&mut self) -> Result<&[u8], SourceError> {
        match self.cursor.inline_token() {
            Some(t) => Ok(t),
            None if self.cursor.at_end() => Err(SourceError::Truncated),
            None => Err(SourceError::Malformed(
                "row has fewer values than the header declares".into(),
            )),
        }
    }
}

impl RowSource for AsciiSource<'_> {
    fn begin_row(&mut self) {
        self.cursor.skip_space();
    }

    fn scalar(&mut self, t: ScalarType) -> Result<f64, SourceError> {
        if t.is_integer() {
            return self.integer(t).map(|v| v as f64);
        }
        let token = self.token()?;
        parse_f64(token)
            .ok_or_else(|| SourceError::Malformed(format!("{:?} is not a number", show(token))))
    }

    fn integer(&mut self, t: ScalarType) -> Result<i64, SourceError> {
        let token = self.token()?;
        let v = parse_i64(token).ok_or_else(|| {
            SourceError::Malformed(format!("{:?} is not an integer", show(token)))
        })?;
        let (lo, hi) = t.integer_range();
        if v < lo || v > hi {
            return Err(SourceError::Malformed(format!(
                "{v} does not fit the declared type {t:?}"
            )));
        }
        Ok(v)
    }

    fn skip_list(&mut self, n: u64, t: ScalarType) -> Result<(), SourceError> {
        for _ in 0..n {
            self.scalar(t)?;
        }
        Ok(())
    }

    fn end_row(&mut self) -> Result<(), SourceError> {
        if self.cursor.finish_line() {
            Ok(())
        } else {
            Err(SourceError::Malformed(
                "row has more values than the header declares".into(),
            ))
        }
    }

    fn location(&self) -> String {
        format!("line {}", self.cursor.line())
    }
}

fn decode_ascii(
    header: &Header,
    data: &[u8],
    vertex_roles: &[Role],
    face_roles: Option<&[Role]>,
    out: &mut Decoded,
    warnings: &mut Vec<String>,
) -> Result<(), ReadErrorKind> {
    let n_vertices = header.element("vertex").map_or(0, |v| v.count);
    let mut src = AsciiSource {
        cursor: TextCursor::new(data, header.n_lines + 1),
    };
    for e in &header.elements {
        if e.properties.is_empty() {
            continue;
        }
        let skip_roles;
        let roles = match e.name.as_str() {
            "vertex" => vertex_roles,
            "face" => face_roles.unwrap_or(&[]),
            _ => {
                skipped(e, warnings);
                skip_roles = vec![Role::Skip; e.properties.len()];
                &skip_roles
            }
        };
        decode_rows(&mut src, e, roles, n_vertices, out)?;
    }
    if !src.cursor.at_end() {
        warnings.push(format!(
            "data after the last element (from line {}) was ignored",
            src.cursor.line()
        ));
    }
    Ok(())
}

/// Decodes every row of one element from any source, validating as it goes.
fn decode_rows<S: RowSource>(
    src: &mut S,
    e: &ElementDef,
    roles: &[Role],
    n_vertices: u64,
    out: &mut Decoded,
) -> Result<(), ReadErrorKind> {
    let is_vertex = e.name == "vertex";
    let is_face = e.name == "face";
    // Counts were checked against the file size, so these reservations are bounded by it.
    if is_vertex {
        out.positions.reserve(e.count as usize);
        for x in out.extras.iter_mut() {
            x.reserve(e.count as usize);
        }
    }
    if is_face {
        out.triangles.reserve(e.count as usize);
    }
    let mut polygon: Vec<u32> = Vec::new();
    for row in 0..e.count {
        src.begin_row();
        let place = |src: &S| format!("{} {} ({})", e.name, row, src.location());
        let fail = |src: &S, err: SourceError| match err {
            SourceError::Truncated => ReadErrorKind::Truncated { place: place(src) },
            SourceError::Malformed(message) => ReadErrorKind::Malformed {
                place: place(src),
                message,
            },
        };
        let mut xyz = [0.0f64; 3];
        for (p, &role) in e.properties.iter().zip(roles) {
            match p.ty {
                PropertyType::Scalar(t) => {
                    let v = src.scalar(t).map_err(|err| fail(src, err))?;
                    match role {
                        Role::Coord(k) => xyz[k] = v,
                        Role::Extra(j) => out.extras[j].push(v as f32),
                        _ => {}
                    }
                }
                PropertyType::List { count, item } => {
                    let n = src.integer(count).map_err(|err| fail(src, err))?;
                    if n < 0 {
                        return Err(fail(
                            src,
                            SourceError::Malformed(format!("list {:?} has length {n}", p.name)),
                        ));
                    }
                    if role == Role::Indices {
                        polygon.clear();
                        for _ in 0..n {
                            let index = src.integer(item).map_err(|err| fail(src, err))?;
                            if index < 0 || index as u64 >= n_vertices {
                                return Err(ReadErrorKind::IndexOutOfRange {
                                    place: place(src),
                                    index,
                                    n_vertices,
                                });
                            }
                            polygon.push(index as u32);
                        }
                    } else {
                        src.skip_list(n as u64, item)
                            .map_err(|err| fail(src, err))?;
                    }
                }
            }
        }
        src.end_row().map_err(|err| fail(src, err))?;
        if is_vertex {
            let p = xyz.map(|v| v as f32);
            if let Some(k) = (0..3).find(|&k| !is_valid_coordinate(p[k])) {
                return Err(ReadErrorKind::bad_coordinate(place(src), xyz[k]));
            }
            out.positions.push(p);
        }
        if is_face {
            out.stats.push_polygon(&polygon, &mut out.triangles);
        }
    }
    Ok(())
}
