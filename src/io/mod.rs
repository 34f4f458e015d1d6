//! Mesh files in and out: PLY (binary either endianness, ASCII), STL (binary, ASCII), OBJ.
//!
//! Readers decode from a memory map (or a plain read, for network filesystems where a mapped
//! file can vanish) into owned arrays, validate while decoding, and report every problem with
//! the file and the place in it. Writers are atomic: temp file in the target folder, then rename.

pub mod atomic;
pub mod identity;
pub mod mapped;
pub mod obj;
pub mod ply;
pub mod stl;
pub mod text;
pub mod vtp;
pub mod weld;

pub use atomic::{remove_stale_temp_files, write_atomically};
pub use identity::{check_regular_file, file_id, same_file, ProtectedFiles};
pub use mapped::MappedFile;

use crate::mesh::{Mesh, MeshError};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// How a file is brought into memory before decoding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReadMode {
    /// Memory-map the file (fastest on local disks).
    #[default]
    Mmap,
    /// Read the file into a buffer (for NFS/Lustre, where mapped pages of a file replaced by
    /// another client can go stale; a file truncated under a mapping fails its case either way).
    Read,
}

/// Options for [`read_mesh`].
#[derive(Debug, Clone, Default)]
pub struct ReadOptions {
    /// How the file is brought into memory.
    pub mode: ReadMode,
    /// Keep the file's extra per-vertex scalar properties (PLY only), e.g. `weight` or `quality`.
    pub keep_vertex_properties: bool,
}

/// The file dialect a mesh was decoded from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SourceFormat {
    PlyBinaryLittleEndian,
    PlyBinaryBigEndian,
    PlyAscii,
    StlBinary,
    StlAscii,
    Obj,
    /// Not read from a mesh file: extracted from a label map.
    Extracted,
}

impl std::fmt::Display for SourceFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SourceFormat::PlyBinaryLittleEndian => "PLY binary little-endian",
            SourceFormat::PlyBinaryBigEndian => "PLY binary big-endian",
            SourceFormat::PlyAscii => "PLY ASCII",
            SourceFormat::StlBinary => "STL binary",
            SourceFormat::StlAscii => "STL ASCII",
            SourceFormat::Obj => "OBJ",
            SourceFormat::Extracted => "extracted from a label map",
        })
    }
}

/// Header text that travels with a mesh and is written back (e.g. 3D Slicer's `SPACE=LPS`).
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct MeshMeta {
    /// PLY `comment` lines (without the keyword); STL/OBJ readers put a found `SPACE=` tag here.
    pub comments: Vec<String>,
    /// PLY `obj_info` lines (without the keyword).
    pub obj_info: Vec<String>,
}

impl MeshMeta {
    /// The coordinate-space tag (`LPS`, `RAS`) from a `SPACE=` comment, if any.
    pub fn space(&self) -> Option<&str> {
        self.comments.iter().find_map(|c| {
            let rest = &c[c.find("SPACE=")? + "SPACE=".len()..];
            let tag = rest.split_whitespace().next()?;
            (!tag.is_empty()).then_some(tag)
        })
    }
}

/// One extra per-vertex scalar property kept from a PLY file.
#[derive(Debug, Clone, PartialEq)]
pub struct VertexProperty {
    pub name: String,
    pub values: Vec<f32>,
}

/// A decoded mesh with what the file said besides geometry.
#[derive(Debug, Clone)]
pub struct LoadedMesh {
    pub mesh: Mesh,
    pub meta: MeshMeta,
    /// Extra per-vertex scalars (only with [`ReadOptions::keep_vertex_properties`]).
    pub vertex_properties: Vec<VertexProperty>,
    /// Things that were accepted but changed or ignored (polygons fanned, elements skipped).
    pub warnings: Vec<String>,
    pub format: SourceFormat,
}

/// A mesh file that could not be read, with its path.
#[derive(Debug, Error)]
#[error("{}: {kind}", path.display())]
pub struct ReadError {
    pub path: PathBuf,
    pub kind: ReadErrorKind,
}

/// What is wrong with a mesh file, and where.
#[derive(Debug, Error)]
pub enum ReadErrorKind {
    #[error("cannot read file: {0}")]
    Io(#[from] std::io::Error),
    #[error("file is empty")]
    Empty,
    #[error(
        "unknown mesh format: expected a .ply, .stl or .obj file (file starts with {start:?})"
    )]
    UnknownFormat { start: String },
    #[error("header line {line}: {message}")]
    Header { line: usize, message: String },
    #[error("header declares more data than the file holds: {message}")]
    SizeMismatch { message: String },
    #[error("{place}: file ends before the data does")]
    Truncated { place: String },
    #[error("{place}: {message}")]
    Malformed { place: String, message: String },
    #[error("{place}: vertex index {index} is out of range (the mesh has {n_vertices} vertices)")]
    IndexOutOfRange {
        place: String,
        index: i64,
        n_vertices: u64,
    },
    #[error("{place}: coordinate is not a finite number ({value})")]
    NonFinite { place: String, value: f64 },
    #[error("{place}: coordinate {} mm lies beyond +-1e7 mm (10 km): not a surface in millimetres (a corrupt file, or one in other units)", crate::units::readable(*value))]
    CoordinateOutOfRange { place: String, value: f64 },
    #[error("the mesh has no vertices")]
    NoVertices,
    #[error("{0}")]
    Mesh(#[from] MeshError),
}

impl ReadErrorKind {
    /// The error for a coordinate `value` (as the file holds it) that is not
    /// [`is_valid_coordinate`](crate::mesh::is_valid_coordinate) at `place`.
    pub(crate) fn bad_coordinate(place: String, value: f64) -> ReadErrorKind {
        if value.is_finite() {
            ReadErrorKind::CoordinateOutOfRange { place, value }
        } else {
            ReadErrorKind::NonFinite { place, value }
        }
    }
}

/// What a format decoder returns before the path is attached.
pub(crate) type DecodeResult = Result<LoadedMesh, ReadErrorKind>;

/// Reads a mesh file, choosing the decoder by content (PLY magic, STL layout) and extension.
pub fn read_mesh(path: &Path, options: &ReadOptions) -> Result<LoadedMesh, ReadError> {
    let err = |kind| ReadError {
        path: path.to_path_buf(),
        kind,
    };
    let bytes = FileBytes::open(path, options.mode).map_err(|e| err(e.into()))?;
    let decoded = decode_mesh(&bytes, extension(path).as_deref(), options);
    bytes.verify().map_err(|e| err(e.into()))?;
    decoded.map_err(err)
}

/// Decodes mesh bytes; `extension` (lower case, no dot) breaks ties the content leaves open.
pub fn decode_mesh(
    bytes: &[u8],
    extension: Option<&str>,
    options: &ReadOptions,
) -> Result<LoadedMesh, ReadErrorKind> {
    if bytes.is_empty() {
        return Err(ReadErrorKind::Empty);
    }
    let loaded = if bytes.starts_with(b"ply") || extension == Some("ply") {
        ply::read::decode(bytes, options)?
    } else if extension == Some("stl") || stl::looks_like_stl(bytes) {
        stl::decode(bytes)?
    } else if extension == Some("obj") {
        obj::decode(bytes)?
    } else {
        let start = String::from_utf8_lossy(&bytes[..bytes.len().min(16)]).into_owned();
        return Err(ReadErrorKind::UnknownFormat { start });
    };
    if loaded.mesh.n_vertices() == 0 {
        return Err(ReadErrorKind::NoVertices);
    }
    Ok(loaded)
}

/// Runs `f` over the bytes of a file, mapped or read as `mode` says; the bytes are released
/// when `f` returns. For callers that need more than a decode (a content hash, say). A file
/// cut short while `f` ran is an error, whatever `f` made of it.
pub fn with_file_bytes<T>(
    path: &Path,
    mode: ReadMode,
    f: impl FnOnce(&[u8]) -> T,
) -> std::io::Result<T> {
    let bytes = FileBytes::open(path, mode)?;
    let out = f(&bytes);
    bytes.verify()?;
    Ok(out)
}

/// Lower-case extension of a path, as `decode_mesh` takes it.
pub fn extension(path: &Path) -> Option<String> {
    Some(path.extension()?.to_str()?.to_ascii_lowercase())
}

/// File contents, mapped (guarded against truncation) or read; dropped as soon as decoding
/// is done.
struct FileBytes(MappedFile);

impl FileBytes {
    fn open(path: &Path, mode: ReadMode) -> std::io::Result<FileBytes> {
        // Checked before opening: opening a FIFO blocks, and /dev/zero never ends.
        check_regular_file(path)?;
        let file = std::fs::File::open(path)?;
        if mode == ReadMode::Read {
            let len = file.metadata()?.len();
            let mut buf = Vec::new();
            buf.try_reserve_exact(usize::try_from(len).unwrap_or(usize::MAX))
                .map_err(|_| {
                    std::io::Error::new(
                        std::io::ErrorKind::OutOfMemory,
                        format!("cannot allocate {len} bytes to read the file"),
                    )
                })?;
            std::io::Read::read_to_end(&mut &file, &mut buf)?;
            return Ok(FileBytes(MappedFile::from_bytes(buf)));
        }
        Ok(FileBytes(MappedFile::map_with(&file, true)?))
    }

    /// Fails when the file was cut short while it was mapped.
    fn verify(&self) -> std::io::Result<()> {
        self.0.verify()
    }
}

impl std::ops::Deref for FileBytes {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        self.0.bytes()
    }
}

/// Mesh output formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OutputFormat {
    Ply,
    Stl,
    /// VTK XML PolyData with the per-vertex arrays (ParaView, 3D Slicer, VMTK, pyvista).
    Vtp,
}

impl OutputFormat {
    /// The format an output path's extension names (`.ply`, `.stl`, `.vtp`).
    pub fn of_path(path: &Path) -> Option<OutputFormat> {
        match extension(path).as_deref() {
            Some("ply") => Some(OutputFormat::Ply),
            Some("stl") => Some(OutputFormat::Stl),
            Some("vtp") => Some(OutputFormat::Vtp),
            _ => None,
        }
    }

    /// The file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            OutputFormat::Ply => "ply",
            OutputFormat::Stl => "stl",
            OutputFormat::Vtp => "vtp",
        }
    }

    /// Whether the format holds per-vertex arrays.
    pub fn holds_arrays(self) -> bool {
        !matches!(self, OutputFormat::Stl)
    }
}

/// Encodes a mesh with per-vertex arrays. PLY gets them as float properties plus `quality`,
/// a copy of the array named `main` (MeshLab shows only that one); VTP gets them as point data
/// with `main` the active scalars; STL holds none and drops them.
pub fn encode_annotated(
    format: OutputFormat,
    mesh: &Mesh,
    meta: &MeshMeta,
    arrays: &[(&str, &[f32])],
    main: &str,
) -> Result<Vec<u8>, WriteError> {
    let main_first = || {
        let mut sorted: Vec<(&str, &[f32])> = arrays.to_vec();
        sorted.sort_by_key(|(n, _)| *n != main);
        sorted
    };
    match format {
        OutputFormat::Ply => ply::encode_ply(mesh, meta, &ply_properties(arrays, main)),
        OutputFormat::Stl => Ok(stl::encode_stl(mesh, meta)),
        OutputFormat::Vtp => {
            let point_data: Vec<vtp::VtpArray> = main_first()
                .into_iter()
                .map(|(n, v)| vtp::VtpArray::Float32(n, v))
                .collect();
            vtp::encode_vtp(mesh, meta, &point_data, &[])
        }
    }
}

/// [`encode_annotated`] into the file at `path` (format from its extension), atomically.
pub fn write_annotated(
    path: &Path,
    mesh: &Mesh,
    meta: &MeshMeta,
    arrays: &[(&str, &[f32])],
    main: &str,
) -> Result<(), WriteError> {
    let format = OutputFormat::of_path(path).ok_or_else(|| WriteError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the output must end in .ply, .stl or .vtp",
        ),
    })?;
    // PLY and STL are streamed: no copy of the whole file in memory.
    match format {
        OutputFormat::Ply => {
            return ply::write_ply(path, mesh, meta, &ply_properties(arrays, main))
        }
        OutputFormat::Stl => return stl::write_stl(path, mesh, meta),
        OutputFormat::Vtp => {}
    }
    let bytes = encode_annotated(format, mesh, meta, arrays, main)?;
    write_bytes_atomically(path, &bytes)
}

/// The vertex properties a PLY output carries: `arrays`, and `main` once more as `quality`
/// (the name MeshLab colours by) unless an array has that name.
fn ply_properties<'a>(arrays: &[(&'a str, &'a [f32])], main: &str) -> Vec<(&'a str, &'a [f32])> {
    let mut props = arrays.to_vec();
    if let Some(&(_, v)) = arrays.iter().find(|(n, _)| *n == main) {
        if !arrays.iter().any(|(n, _)| *n == "quality") {
            props.push(("quality", v));
        }
    }
    props
}

/// A mesh file that could not be written.
#[derive(Debug, Error)]
pub enum WriteError {
    #[error("{}: cannot write: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("vertex property {name:?}: {message}")]
    InvalidProperty { name: String, message: String },
    #[error("array {name:?}: {message}")]
    InvalidArray { name: String, message: String },
}

/// Writes `bytes` to `path` atomically (temp file + rename), the error naming the path.
pub(crate) fn write_bytes_atomically(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    write_atomically(path, |w| w.write_all(bytes)).map_err(|source| WriteError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Rows encoded per batch by [`write_rows`]; bounds the writer's buffer to a few MB.
const WRITE_BATCH_ROWS: usize = 1 << 18;
/// Rows per parallel task within a batch.
const WRITE_TASK_ROWS: usize = 1 << 12;

/// Writes `n_rows` fixed-size binary rows: each batch is encoded in parallel into one reusable
/// buffer by `encode(row_index, row_bytes)` and then written, so memory stays bounded and the
/// bytes do not depend on the thread count.
pub(crate) fn write_rows<F>(
    w: &mut dyn std::io::Write,
    n_rows: usize,
    row_size: usize,
    encode: F,
) -> std::io::Result<()>
where
    F: Fn(usize, &mut [u8]) + Sync,
{
    use rayon::prelude::*;
    let mut buf = vec![0u8; WRITE_BATCH_ROWS.min(n_rows) * row_size];
    let mut start = 0;
    while start < n_rows {
        let n = WRITE_BATCH_ROWS.min(n_rows - start);
        let batch = &mut buf[..n * row_size];
        batch
            .par_chunks_mut(WRITE_TASK_ROWS * row_size)
            .enumerate()
            .for_each(|(task, part)| {
                let first = start + task * WRITE_TASK_ROWS;
                for (i, row) in part.chunks_exact_mut(row_size).enumerate() {
                    encode(first + i, row);
                }
            });
        w.write_all(batch)?;
        start += n;
    }
    Ok(())
}

/// Counts of polygons fanned and faces dropped, turned into load warnings at the end.
#[derive(Debug, Default)]
pub(crate) struct FaceStats {
    pub fanned_polygons: u64,
    pub fan_triangles: u64,
    pub dropped_faces: u64,
}

impl FaceStats {
    pub(crate) fn warnings(&self, out: &mut Vec<String>) {
        if self.fanned_polygons > 0 {
            out.push(format!(
                "{} polygons with more than 3 vertices were fan-triangulated into {} triangles",
                self.fanned_polygons, self.fan_triangles
            ));
        }
        if self.dropped_faces > 0 {
            out.push(format!(
                "{} faces with fewer than 3 vertices were dropped",
                self.dropped_faces
            ));
        }
    }

    /// Appends a polygon (already index-checked) as a triangle fan around its first vertex.
    pub(crate) fn push_polygon(&mut self, polygon: &[u32], triangles: &mut Vec<[u32; 3]>) {
        match polygon.len() {
            0..=2 => self.dropped_faces += 1,
            3 => triangles.push([polygon[0], polygon[1], polygon[2]]),
            n => {
                self.fanned_polygons += 1;
                self.fan_triangles += (n - 2) as u64;
                for k in 1..n - 1 {
                    triangles.push([polygon[0], polygon[k], polygon[k + 1]]);
                }
            }
        }
    }
}
