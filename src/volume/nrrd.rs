//! NRRD label maps (`.nrrd`, `.nhdr` with a detached data file, 3D Slicer's `.seg.nrrd`). The
//! text header is small and parsed here: type, dimension, sizes, endian, encoding (raw or
//! gzip), space, space directions and origin (or spacings), byte skip, data file, and
//! Slicer's `SegmentN_Name` / `_LabelValue` / `_Layer` fields. A 4D `.seg.nrrd` whose first
//! axis is a list holds one layer of (possibly overlapping) segments per entry.

use super::{
    gunzip_overlapped, voxel_count, Grid, KeyHistogram, LabelMap, LabelVolume, Segment, Space,
    VoxelType,
};
use std::collections::BTreeMap;
use std::path::Path;

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

/// Reads a NRRD label map.
pub fn read(path: &Path) -> Result<LabelMap, String> {
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read: {e}"))?;
    // SAFETY: read-only map, dropped before returning.
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| format!("cannot read: {e}"))?;
    let bytes: &[u8] = &map;
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
    let t = voxel_type(field("type")?)?;
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
    let n_voxels = voxel_count(dims)?;
    if n_layers == 0 || n_layers > 256 {
        return Err(format!("{n_layers} layers: expected 1 to 256"));
    }
    let n_bytes = n_voxels * n_layers * t.size() as u64;
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
    // The data: after the header, or in a detached file next to it.
    let detached;
    let mut data_file = None;
    let data: &[u8] = match fields.get("data file").or_else(|| fields.get("datafile")) {
        Some(name) => {
            if name.starts_with("LIST") || name.contains('%') {
                return Err(format!(
                    "data file {name:?}: only a single data file is read"
                ));
            }
            let p = path.parent().unwrap_or(Path::new(".")).join(name);
            crate::io::check_regular_file(&p)
                .map_err(|e| format!("data file {}: {e}", p.display()))?;
            detached = std::fs::read(&p).map_err(|e| format!("data file {}: {e}", p.display()))?;
            data_file = Some(p);
            &detached
        }
        None => &bytes[data_start..],
    };
    // One layer's histogram of values is taken while the rest is still being inflated.
    let mut counted = (n_layers == 1).then(|| KeyHistogram::new(t, big_endian));
    let raw: std::borrow::Cow<[u8]> = match field("encoding")? {
        "raw" => std::borrow::Cow::Borrowed(super::exact_slice(data, skip, n_bytes)?),
        "gzip" | "gz" => {
            std::borrow::Cow::Owned(gunzip_overlapped(data, skip, n_bytes, |piece| {
                if let Some(h) = &mut counted {
                    h.add(piece);
                }
            })?)
        }
        other => return Err(format!("encoding {other:?}: only raw and gzip are read")),
    };
    if matches!(raw, std::borrow::Cow::Borrowed(_)) {
        counted = None;
    }
    let dims_usize = dims.map(|d| d as usize);
    let mut layers = Vec::with_capacity(n_layers as usize);
    for layer in 0..n_layers as usize {
        layers.push(LabelVolume::from_raw(
            dims_usize,
            grid,
            &raw,
            t,
            big_endian,
            (layer, n_layers as usize),
            counted.take(),
        )?);
    }
    let segments = segments(&pairs, &mut warnings);
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

/// Voxels the header declares, all layers (see [`super::declared_voxels`]).
pub(super) fn declared_voxels(path: &Path) -> Option<u64> {
    let text = header_text(path)?;
    let sizes = text
        .lines()
        .find_map(|l| l.trim_end_matches('\r').strip_prefix("sizes:"))?;
    sizes
        .split_whitespace()
        .map(|s| s.parse::<u64>().ok())
        .try_fold(1u64, |n, s| n.checked_mul(s?))
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
