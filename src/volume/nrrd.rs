//! NRRD label maps (`.nrrd`, `.nhdr` with a detached data file, 3D Slicer's `.seg.nrrd`). The
//! text header is small and parsed here: type, dimension, sizes, endian, encoding (raw or
//! gzip), space, space directions and origin (or spacings), byte skip, data file, and
//! Slicer's `SegmentN_Name` / `_LabelValue` / `_Layer` fields. A 4D `.seg.nrrd` whose first
//! axis is a list holds one layer of (possibly overlapping) segments per entry.

use super::{
    gunzip_overlapped, voxel_count, Grid, KeyHistogram, LabelMap, LabelMapHeader, LabelMapLimits,
    LabelVolume, Segment, Space, VoxelType,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Longest header read (bytes).
const MAX_HEADER: usize = 1 << 20;

fn voxel_type(t: &str) -> Result<VoxelType, String> {
    Ok(match t {
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => VoxelType::U8,
        "signed char" | "int8" | "int8_t" => VoxelType::I8,
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
            VoxelType::I16
        }
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => {
            VoxelType::U16
        }
        "int" | "signed int" | "int32" | "int32_t" => VoxelType::I32,
        "uint" | "unsigned int" | "uint32" | "uint32_t" => VoxelType::U32,
        other => {
            return Err(format!(
            "type {other:?} is not an integer label type (uchar, char, short, ushort, int, uint)"
        ))
        }
    })
}

/// Parses `(x,y,z)` vectors separated by spaces; `none` entries give `None`.
fn vectors(s: &str) -> Result<Vec<Option<[f64; 3]>>, String> {
    let mut out = Vec::new();
    let mut rest = s.trim();
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("none") {
            out.push(None);
            rest = r.trim_start();
            continue;
        }
        let close = rest
            .find(')')
            .filter(|_| rest.starts_with('('))
            .ok_or_else(|| format!("expected (x,y,z) vectors, got {s:?}"))?;
        let parts: Vec<f64> = rest[1..close]
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("expected numbers in {:?}", &rest[..=close]))?;
        let [x, y, z] = parts[..] else {
            return Err(format!("expected three numbers in {:?}", &rest[..=close]));
        };
        out.push(Some([x, y, z]));
        rest = rest[close + 1..].trim_start();
    }
    Ok(out)
}

/// A NRRD header, parsed and checked: what the voxels are and where they lie, before any is read.
struct Header {
    voxel_type: VoxelType,
    /// Layers (the list axis of a 4D `.seg.nrrd`; 1 for a 3D map).
    n_layers: u64,
    dims: [u64; 3],
    big_endian: bool,
    grid: Grid,
    skip: u64,
    gzip: bool,
    /// The detached data file's name as the header gives it.
    data_file: Option<String>,
    /// Slicer's `key:=value` pairs.
    pairs: BTreeMap<String, String>,
    warnings: Vec<String>,
}

impl Header {
    /// Voxel bytes of all layers.
    fn n_bytes(&self) -> u64 {
        self.dims.iter().product::<u64>() * self.n_layers * self.voxel_type.size() as u64
    }
}

/// Parses the header text (up to the blank line) and checks everything it says that can be
/// checked without the data: types, sizes against [`super::MAX_VOXELS`], the grid.
fn parse_header(text: &str) -> Result<Header, String> {
    let mut fields: BTreeMap<String, String> = BTreeMap::new();
    let mut pairs: BTreeMap<String, String> = BTreeMap::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        let line = line.trim_end_matches('\r');
        if line.starts_with('#') || line.is_empty() {
            continue;
        }
        if let Some((k, v)) = line.split_once(":=") {
            pairs.insert(k.to_string(), v.to_string());
        } else if let Some((k, v)) = line.split_once(": ") {
            fields.insert(k.trim().to_ascii_lowercase(), v.trim().to_string());
        } else {
            return Err(format!("header line {}: {line:?} is not a field", n + 1));
        }
    }
    let field = |k: &str| {
        fields
            .get(k)
            .map(String::as_str)
            .ok_or_else(|| format!("the header has no {k:?} field"))
    };
    let voxel_type = voxel_type(field("type")?)?;
    let dimension: usize = field("dimension")?
        .parse()
        .map_err(|_| "dimension is not a number".to_string())?;
    let sizes: Vec<u64> = field("sizes")?
        .split_whitespace()
        .map(|x| x.parse::<u64>())
        .collect::<Result<_, _>>()
        .map_err(|_| "sizes are not whole numbers".to_string())?;
    if sizes.len() != dimension || !(dimension == 3 || dimension == 4) {
        return Err(format!(
            "dimension {dimension} with sizes {sizes:?}: a label map is 3D (or 4D with a list of layers)"
        ));
    }
    let (n_layers, dims) = if dimension == 4 {
        (sizes[0], [sizes[1], sizes[2], sizes[3]])
    } else {
        (1, [sizes[0], sizes[1], sizes[2]])
    };
    voxel_count(dims)?;
    if n_layers == 0 || n_layers > 256 {
        return Err(format!("{n_layers} layers: expected 1 to 256"));
    }
    let big_endian = match fields.get("endian").map(String::as_str) {
        None | Some("little") => false,
        Some("big") => true,
        Some(other) => return Err(format!("endian {other:?} is neither little nor big")),
    };
    let space = match fields.get("space").map(String::as_str) {
        Some("left-posterior-superior") | Some("LPS") => Some(Space::Lps),
        Some("right-anterior-superior") | Some("RAS") => Some(Space::Ras),
        None => None,
        Some(other) => return Err(format!("space {other:?}: only LPS and RAS are read")),
    };
    let mut warnings = Vec::new();
    let grid = match fields.get("space directions") {
        Some(d) => {
            let v = vectors(d)?;
            let spatial: Vec<[f64; 3]> = v.iter().flatten().copied().collect();
            let expected_none = if dimension == 4 { 1 } else { 0 };
            if spatial.len() != 3
                || v.len() != dimension
                || v.iter().filter(|x| x.is_none()).count() != expected_none
            {
                return Err(format!(
                    "space directions {d:?} do not give three spatial axes for sizes {sizes:?}"
                ));
            }
            if dimension == 4 && v[0].is_some() {
                return Err(
                    "a 4D label map needs its first axis to be the list of layers (direction none)"
                        .into(),
                );
            }
            let origin = match fields.get("space origin") {
                Some(o) => vectors(o)?
                    .first()
                    .copied()
                    .flatten()
                    .ok_or_else(|| format!("space origin {o:?} is not (x,y,z)"))?,
                None => [0.0; 3],
            };
            let mut matrix = [[0.0; 3]; 3];
            for (c, dir) in spatial.iter().enumerate() {
                for r in 0..3 {
                    matrix[r][c] = dir[r];
                }
            }
            Grid {
                matrix,
                origin,
                space: space.unwrap_or_else(|| {
                    warnings.push("no space field: LPS assumed".into());
                    Space::Lps
                }),
            }
        }
        None => {
            let spacing: Vec<f64> = match fields.get("spacings") {
                Some(s) => s
                    .split_whitespace()
                    .filter(|x| *x != "nan" && *x != "NaN")
                    .map(|x| x.parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| format!("spacings {s:?} are not numbers"))?,
                None => {
                    warnings.push(
                        "no space directions or spacings: 1 mm voxels at the origin assumed".into(),
                    );
                    vec![1.0; 3]
                }
            };
            let [x, y, z] = spacing[..] else {
                return Err(format!("spacings {spacing:?}: expected three"));
            };
            warnings.push("no space directions: an axis-aligned grid in LPS assumed".into());
            Grid::axis_aligned([x, y, z], [0.0; 3], space.unwrap_or(Space::Lps))
        }
    };
    grid.check()?;
    grid.check_extent(dims.map(|d| d as usize))?;
    let skip: u64 = match fields.get("byte skip") {
        None => 0,
        Some(s) => s
            .parse()
            .map_err(|_| format!("byte skip {s:?} is not a whole number (-1 is not read)"))?,
    };
    if fields.get("line skip").is_some_and(|s| s != "0") {
        return Err("line skip is not read; give the data without leading lines".into());
    }
    let gzip = match field("encoding")? {
        "raw" => false,
        "gzip" | "gz" => true,
        other => return Err(format!("encoding {other:?}: only raw and gzip are read")),
    };
    let data_file = fields
        .get("data file")
        .or_else(|| fields.get("datafile"))
        .cloned();
    if let Some(name) = &data_file {
        if name.starts_with("LIST") || name.contains('%') {
            return Err(format!(
                "data file {name:?}: only a single data file is read"
            ));
        }
    }
    Ok(Header {
        voxel_type,
        n_layers,
        dims,
        big_endian,
        grid,
        skip,
        gzip,
        data_file,
        pairs,
        warnings,
    })
}

/// The header text of a NRRD's bytes and where its data starts (the end of the bytes for a
/// detached header).
fn split_header(bytes: &[u8]) -> Result<(&str, usize), String> {
    if !bytes.starts_with(b"NRRD000") {
        return Err("not a NRRD file (it does not start with NRRD000x)".into());
    }
    let window = &bytes[..bytes.len().min(MAX_HEADER)];
    // The header ends at the first empty line (or at the end of a detached header).
    let (header_len, data_start) = match find_blank_line(window) {
        Some(x) => x,
        None if bytes.len() <= MAX_HEADER => (bytes.len(), bytes.len()),
        None => {
            return Err(format!(
                "no end of header within the first {MAX_HEADER} bytes"
            ))
        }
    };
    let text = std::str::from_utf8(&bytes[..header_len])
        .map_err(|_| "the header is not text".to_string())?;
    Ok((text, data_start))
}

/// The detached data file a header names, confined to the header's own folder: the name is
/// resolved there (symlinks followed), and what it resolves to must lie in that folder or
/// below it and be a regular file. A header from someone else's case folder cannot make
/// destair read (and so disclose through the surfaces) any other file.
fn confined_data_file(header_path: &Path, name: &str) -> Result<PathBuf, String> {
    let folder = header_path.parent().unwrap_or(Path::new("."));
    let folder = if folder.as_os_str().is_empty() {
        Path::new(".")
    } else {
        folder
    };
    let folder = folder
        .canonicalize()
        .map_err(|e| format!("data file {name:?}: the header's folder cannot be resolved ({e})"))?;
    let named = folder.join(name);
    let resolved = named
        .canonicalize()
        .map_err(|e| format!("data file {name:?}: {e}"))?;
    if !resolved.starts_with(&folder) {
        return Err(format!(
            "data file {name:?} resolves to {}, outside the header's folder {}: a detached data file must lie beside its header (or below it)",
            resolved.display(),
            folder.display()
        ));
    }
    crate::io::check_regular_file(&resolved).map_err(|e| format!("data file {name:?}: {e}"))?;
    Ok(resolved)
}

/// Reads a NRRD label map within `limits`.
pub fn read(path: &Path, limits: &LabelMapLimits) -> Result<LabelMap, String> {
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read: {e}"))?;
    let map = crate::io::MappedFile::map(&file).map_err(|e| format!("cannot read: {e}"))?;
    let bytes: &[u8] = map.bytes();
    let (text, data_start) = split_header(bytes)?;
    let h = parse_header(text)?;
    limits.check_voxels(h.dims, h.n_layers)?;
    h.grid.check_spacing(limits.spacing_mm)?;
    let n_bytes = h.n_bytes();
    // The data: after the header, or in a detached file next to it, whose size is checked
    // against the header before a byte of it is read.
    let mut data_file = None;
    let mut detached = None;
    if let Some(name) = &h.data_file {
        let p = confined_data_file(path, name)?;
        let f = std::fs::File::open(&p).map_err(|e| format!("data file {name:?}: {e}"))?;
        let len = f
            .metadata()
            .map_err(|e| format!("data file {name:?}: {e}"))?
            .len();
        let expected = h.skip.saturating_add(n_bytes);
        if !h.gzip && len != expected {
            return Err(format!(
                    "data file {name:?} holds {len} bytes; the header says {expected} (byte skip {} + {n_bytes} bytes of voxels)",
                    h.skip
                ));
        }
        if h.gzip && expected > len.saturating_mul(super::MAX_GZIP_RATIO) + 4096 {
            return Err(format!(
                    "data file {name:?} holds {len} bytes of gzip data, which cannot inflate to the {expected} bytes the header says"
                ));
        }
        detached =
            Some(crate::io::MappedFile::map(&f).map_err(|e| format!("data file {name:?}: {e}"))?);
        data_file = Some(p);
    }
    let data: &[u8] = match &detached {
        Some(m) => m.bytes(),
        None => &bytes[data_start..],
    };
    let t = h.voxel_type;
    // One layer's histogram of values is taken while the rest is still being inflated.
    let mut counted = (h.n_layers == 1).then(|| KeyHistogram::new(t, h.big_endian));
    let raw: std::borrow::Cow<[u8]> = if h.gzip {
        std::borrow::Cow::Owned(gunzip_overlapped(data, h.skip, n_bytes, |piece| {
            if let Some(counts) = &mut counted {
                counts.add(piece);
            }
        })?)
    } else {
        counted = None;
        std::borrow::Cow::Borrowed(super::exact_slice(data, h.skip, n_bytes)?)
    };
    let dims_usize = h.dims.map(|d| d as usize);
    let mut layers = Vec::new();
    layers
        .try_reserve_exact(h.n_layers as usize)
        .map_err(|_| "cannot allocate the layers".to_string())?;
    let mut n_labels = 0;
    for layer in 0..h.n_layers as usize {
        let volume = LabelVolume::from_raw(
            dims_usize,
            h.grid,
            &raw,
            t,
            h.big_endian,
            (layer, h.n_layers as usize),
            counted.take(),
            limits.max_labels,
        )?;
        n_labels += volume.labels.len();
        if n_labels > limits.max_labels {
            // Labels of all layers together: "its first 3 layers hold 300 distinct values, ...".
            return Err(format!(
                "its first {} layers hold{}",
                layer + 1,
                super::too_many_labels(limits.max_labels, Some(n_labels))
                    .trim_start_matches("holds")
            ));
        }
        layers.push(volume);
    }
    drop(raw);
    // A file that changed size while it was mapped was read in part as zeros: refuse it.
    map.verify().map_err(|e| format!("cannot read: {e}"))?;
    if let Some(m) = &detached {
        m.verify().map_err(|e| format!("data file: {e}"))?;
    }
    let mut warnings = h.warnings;
    let segments = segments(&h.pairs, &mut warnings);
    Ok(LabelMap {
        layers,
        segments,
        warnings,
        data_file,
    })
}

/// The header text alone, read in growing chunks (a header is small; the data after it is not
/// read).
fn header_text(path: &Path) -> Option<String> {
    use std::io::Read;
    // Opening a FIFO would block, and /dev/zero never ends.
    crate::io::check_regular_file(path).ok()?;
    let mut file = std::fs::File::open(path).ok()?;
    let mut head = Vec::new();
    let mut chunk = 64 << 10;
    loop {
        let before = head.len();
        (&mut file).take(chunk).read_to_end(&mut head).ok()?;
        if let Some((end, _)) = find_blank_line(&head) {
            head.truncate(end);
            break;
        }
        if head.len() == before || head.len() >= MAX_HEADER {
            break;
        }
        chunk *= 2;
    }
    Some(String::from_utf8_lossy(&head).into_owned())
}

/// What the header of the NRRD at `path` declares, read from the header alone (the data is not
/// touched).
pub(super) fn peek(path: &Path) -> Result<LabelMapHeader, String> {
    let text = header_text(path).ok_or("cannot read the header")?;
    let mut bytes = text.into_bytes();
    bytes.extend_from_slice(b"\n\n");
    let (text, _) = split_header(&bytes)?;
    let h = parse_header(text)?;
    Ok(LabelMapHeader {
        dims: h.dims,
        n_layers: h.n_layers,
        voxel_type: h.voxel_type,
    })
}

/// The segments a header names (3D Slicer's fields), read from the header alone.
pub(super) fn declared_segments(path: &Path) -> Vec<Segment> {
    let Some(text) = header_text(path) else {
        return Vec::new();
    };
    let pairs: BTreeMap<String, String> = text
        .lines()
        .filter_map(|l| l.trim_end_matches('\r').split_once(":="))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    segments(&pairs, &mut Vec::new())
}

/// (end of the header text, start of the data): the first empty line.
fn find_blank_line(b: &[u8]) -> Option<(usize, usize)> {
    let mut i = 0;
    while let Some(p) = b[i..].iter().position(|&c| c == b'\n') {
        let at = i + p;
        if b[at + 1..].starts_with(b"\n") {
            return Some((at, at + 2));
        }
        if b[at + 1..].starts_with(b"\r\n") {
            return Some((at, at + 3));
        }
        i = at + 1;
    }
    None
}

/// Slicer's segments from `SegmentN_Name:=`, `SegmentN_LabelValue:=`, `SegmentN_Layer:=`.
fn segments(pairs: &BTreeMap<String, String>, warnings: &mut Vec<String>) -> Vec<Segment> {
    let mut by_index: BTreeMap<usize, (Option<String>, Option<i64>, usize)> = BTreeMap::new();
    for (k, v) in pairs {
        let Some(rest) = k.strip_prefix("Segment") else {
            continue;
        };
        let Some((n, what)) = rest.split_once('_') else {
            continue;
        };
        let Ok(n) = n.parse::<usize>() else {
            continue;
        };
        let e = by_index.entry(n).or_insert((None, None, 0));
        match what {
            "Name" => e.0 = Some(v.trim().to_string()),
            "LabelValue" => e.1 = v.trim().parse().ok(),
            "Layer" => e.2 = v.trim().parse().unwrap_or(0),
            _ => {}
        }
    }
    by_index
        .into_iter()
        .filter_map(|(n, (name, value, layer))| match (name, value) {
            (Some(name), Some(value)) => Some(Segment { name, value, layer }),
            _ => {
                warnings.push(format!("Segment{n} lacks a name or label value; not named"));
                None
            }
        })
        .collect()
}

/// Encodes label volumes as a NRRD (one layer: 3D; several: 4D with a list axis first, as
/// Slicer writes overlapping segments), with `segments` as Slicer's header fields.
pub fn encode(layers: &[LabelVolume], segments: &[Segment], gz: bool) -> Result<Vec<u8>, String> {
    let first = layers.first().ok_or("no layers")?;
    let g = first.grid;
    g.check()?;
    let mut h = String::from("NRRD0004\n# written by destair\ntype: int\n");
    let d = first.dims;
    let col = |c: usize| format!("({},{},{})", g.matrix[0][c], g.matrix[1][c], g.matrix[2][c]);
    if layers.len() == 1 {
        h += &format!("dimension: 3\nsizes: {} {} {}\n", d[0], d[1], d[2]);
        h += &format!(
            "space directions: {} {} {}\nkinds: domain domain domain\n",
            col(0),
            col(1),
            col(2)
        );
    } else {
        h += &format!(
            "dimension: 4\nsizes: {} {} {} {}\n",
            layers.len(),
            d[0],
            d[1],
            d[2]
        );
        h += &format!(
            "space directions: none {} {} {}\nkinds: list domain domain domain\n",
            col(0),
            col(1),
            col(2)
        );
    }
    let space = match g.space {
        Space::Lps => "left-posterior-superior",
        Space::Ras => "right-anterior-superior",
    };
    h += &format!(
        "space: {space}\nspace origin: ({},{},{})\nendian: little\nencoding: {}\n",
        g.origin[0],
        g.origin[1],
        g.origin[2],
        if gz { "gzip" } else { "raw" }
    );
    for (n, s) in segments.iter().enumerate() {
        h += &format!(
            "Segment{n}_Name:={}\nSegment{n}_LabelValue:={}\nSegment{n}_Layer:={}\n",
            s.name, s.value, s.layer
        );
    }
    h += "\n";
    let n = first.voxels.len();
    let mut data = Vec::with_capacity(n * layers.len() * 4);
    for v in 0..n {
        for layer in layers {
            let id = layer.voxels[v];
            let value = if id == 0 {
                0
            } else {
                layer.labels[id as usize - 1].value
            };
            data.extend_from_slice(&(value as i32).to_le_bytes());
        }
    }
    let mut out = h.into_bytes();
    if gz {
        use std::io::Write;
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        e.write_all(&data).map_err(|e| e.to_string())?;
        out.extend(e.finish().map_err(|e| e.to_string())?);
    } else {
        out.extend(data);
    }
    Ok(out)
}
