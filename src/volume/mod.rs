//! Label maps in: segmentations as NIfTI-1 (`.nii`, `.nii.gz`) or NRRD (`.nrrd`, `.nhdr` with a
//! detached data file, 3D Slicer's `.seg.nrrd`), with their grid geometry in world millimetres
//! and their label names. Sizes in headers are checked against the data before anything is
//! allocated; every problem names the file and what is wrong.

pub mod components;
pub mod grid;
pub mod nifti;
pub mod nrrd;

pub use grid::{Grid, Space};

use serde::Serialize;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Most voxels a label map may have (2^32, e.g. 2048 x 2048 x 1024): beyond that the header is
/// lying or the volume is not a segmentation.
pub const MAX_VOXELS: u64 = 1 << 32;

/// What a label map may hold: checked against its header before any voxel is inflated, and
/// against its labels before the voxels are mapped to them, so a lying or hostile file fails
/// with the reason instead of filling the memory.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LabelMapLimits {
    /// Most voxels, all layers together (at most [`MAX_VOXELS`]).
    pub max_voxels: u64,
    /// Most distinct labels, all layers together.
    pub max_labels: usize,
    /// Smallest and largest voxel spacing accepted (mm): outside it a header is corrupt or in
    /// other units.
    pub spacing_mm: [f64; 2],
}

impl Default for LabelMapLimits {
    /// 2^30 voxels (1024^3), 255 labels (TotalSegmentator's largest task has 117), spacing
    /// 0.001 to 1000 mm.
    fn default() -> Self {
        LabelMapLimits {
            max_voxels: 1 << 30,
            max_labels: 255,
            spacing_mm: [1e-3, 1e3],
        }
    }
}

impl LabelMapLimits {
    /// Refuses a map of `n_layers` layers of `dims` voxels beyond `max_voxels`.
    pub fn check_voxels(&self, dims: [u64; 3], n_layers: u64) -> Result<(), String> {
        let n = voxel_count(dims)?.saturating_mul(n_layers);
        if n > self.max_voxels {
            return Err(format!(
                "{} is {n} voxels, more than the {} allowed (max_label_voxels)",
                voxels_text(dims, n_layers),
                self.max_voxels
            ));
        }
        Ok(())
    }
}

/// The error for a map holding more labels than `max_labels`: `found` of them when they were
/// all counted, `None` when reading stopped at the first one too many.
pub fn too_many_labels(max_labels: usize, found: Option<usize>) -> String {
    let what = match found {
        Some(n) => format!("{n} distinct values"),
        None => format!("more than {max_labels} distinct values"),
    };
    format!(
        "holds {what}, more than the {max_labels} labels allowed (max_labels): is it an image? Select the label maps with [input] label_maps, or raise [input] max_labels"
    )
}

/// "512 x 512 x 300 voxels" (with " in 3 layers" for several), for messages.
pub fn voxels_text(dims: [u64; 3], n_layers: u64) -> String {
    let layers = if n_layers > 1 {
        format!(" in {n_layers} layers")
    } else {
        String::new()
    };
    format!("{} x {} x {} voxels{layers}", dims[0], dims[1], dims[2])
}

/// What a label map's header declares, read without touching the voxels: for estimating the
/// memory a map needs before it is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LabelMapHeader {
    pub dims: [u64; 3],
    pub n_layers: u64,
    pub voxel_type: VoxelType,
}

impl LabelMapHeader {
    /// Voxels of all layers.
    pub fn n_voxels(&self) -> u64 {
        self.dims
            .iter()
            .product::<u64>()
            .saturating_mul(self.n_layers)
    }

    /// Bytes held while the map is read: the decoded voxels (their type's size) and the dense
    /// label indices (2 bytes) side by side. Measured: 3.0 bytes per voxel for a 512 x 512 x
    /// 300 u8 map read and extracted, 6.0 for the same map as i32.
    pub fn bytes_to_read(&self) -> u64 {
        self.n_voxels()
            .saturating_mul(self.voxel_type.size() as u64 + 2)
    }
}

/// One label of a label map.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Label {
    /// The value stored in the voxels.
    pub value: i64,
    /// Its name: from Slicer's segment fields or the config, else `label_<value>`.
    pub name: String,
    /// Voxels holding it.
    pub n_voxels: u64,
}

/// A 3D label volume: per voxel (x fastest, then y, then z) a dense label index, 0 for
/// background and `1..=labels.len()` for `labels[index - 1]`.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelVolume {
    pub dims: [usize; 3],
    pub grid: Grid,
    pub voxels: Vec<u16>,
    pub labels: Vec<Label>,
}

impl LabelVolume {
    /// Per label index (0 background, then `labels` in order): whether any of its voxels lies
    /// within `margin` voxels of a face of the volume, i.e. whether the field of view may have
    /// cut the structure there. Only the volume's outer shell is read.
    pub fn near_edge(&self, margin: usize) -> Vec<bool> {
        let mut near = vec![false; self.labels.len() + 1];
        let [nx, ny, nz] = self.dims;
        if self.voxels.len() != nx * ny * nz {
            return near;
        }
        let shell = |i: usize, n: usize| i < margin || i + margin >= n;
        let mut mark = |start: usize, len: usize| {
            for &v in &self.voxels[start..start + len] {
                if let Some(n) = near.get_mut(v as usize) {
                    *n = true;
                }
            }
        };
        for z in 0..nz {
            for y in 0..ny {
                let row = (z * ny + y) * nx;
                if shell(z, nz) || shell(y, ny) {
                    mark(row, nx);
                } else {
                    let m = margin.min(nx);
                    mark(row, m);
                    mark(row + nx - m, m);
                }
            }
        }
        near[0] = false;
        near
    }

    /// Dense label index at voxel (i, j, k).
    pub fn at(&self, i: usize, j: usize, k: usize) -> u16 {
        self.voxels[i + self.dims[0] * (j + self.dims[1] * k)]
    }

    /// Builds a volume from raw label values (any integer type, widened to i64), numbering
    /// the labels in increasing order of value. More than 65 535 labels is an error.
    pub fn from_values(
        dims: [usize; 3],
        grid: Grid,
        values: impl Iterator<Item = i64>,
    ) -> Result<LabelVolume, String> {
        LabelVolume::from_values_limited(dims, grid, values, u16::MAX as usize)
    }

    /// [`LabelVolume::from_values`] refusing more than `max_labels` labels as soon as one more
    /// turns up.
    pub fn from_values_limited(
        dims: [usize; 3],
        grid: Grid,
        values: impl Iterator<Item = i64>,
        max_labels: usize,
    ) -> Result<LabelVolume, String> {
        let max_labels = max_labels.min(u16::MAX as usize);
        // Provisional ids in order of first appearance: a direct table for the usual small
        // non-negative values, a map for the rest.
        const DIRECT: i64 = 1 << 16;
        let mut direct = vec![0u16; DIRECT as usize];
        let mut other: rustc_hash::FxHashMap<i64, u16> = Default::default();
        let mut seen: Vec<i64> = Vec::new();
        let mut voxels = Vec::new();
        voxels
            .try_reserve_exact(dims.iter().product())
            .map_err(|_| cannot_allocate(dims))?;
        for v in values {
            let slot = if (0..DIRECT).contains(&v) {
                &mut direct[v as usize]
            } else {
                other.entry(v).or_insert(0)
            };
            if *slot == 0 && v != 0 {
                if seen.len() >= max_labels {
                    return Err(if max_labels == u16::MAX as usize {
                        "more than 65 535 different labels".into()
                    } else {
                        too_many_labels(max_labels, None)
                    });
                }
                seen.push(v);
                *slot = seen.len() as u16;
            }
            voxels.push(*slot);
        }
        // Renumber in order of value, and count.
        let mut order: Vec<usize> = (0..seen.len()).collect();
        order.sort_by_key(|&i| seen[i]);
        let mut new_id = vec![0u16; seen.len() + 1];
        for (rank, &i) in order.iter().enumerate() {
            new_id[i + 1] = rank as u16 + 1;
        }
        let mut counts = vec![0u64; seen.len() + 1];
        for v in &mut voxels {
            *v = new_id[*v as usize];
            counts[*v as usize] += 1;
        }
        let values: Vec<i64> = order.iter().map(|&i| seen[i]).collect();
        Ok(LabelVolume::labelled(dims, grid, voxels, &values, &counts))
    }

    /// A volume from dense voxel indices, the label values in index order, and the voxel count
    /// of each index (background first).
    fn labelled(
        dims: [usize; 3],
        grid: Grid,
        voxels: Vec<u16>,
        values: &[i64],
        counts: &[u64],
    ) -> LabelVolume {
        let labels = values
            .iter()
            .zip(&counts[1..])
            .map(|(&value, &n_voxels)| Label {
                value,
                name: format!("label_{value}"),
                n_voxels,
            })
            .collect();
        LabelVolume {
            dims,
            grid,
            voxels,
            labels,
        }
    }
}

impl LabelVolume {
    /// Builds a volume from raw voxel bytes of type `t` (every `stride`-th voxel from `first`,
    /// for one layer of an interleaved 4D file). 8- and 16-bit types go through a direct
    /// value table in two parallel passes (the first skipped when `counted` holds the
    /// histogram of raw keys already, fed while the bytes were being decompressed); 32-bit
    /// types through [`LabelVolume::from_values`]. More than `max_labels` distinct non-zero
    /// values is refused before the voxels are mapped.
    #[allow(clippy::too_many_arguments)]
    pub fn from_raw(
        dims: [usize; 3],
        grid: Grid,
        bytes: &[u8],
        t: VoxelType,
        big_endian: bool,
        (first, stride): (usize, usize),
        counted: Option<KeyHistogram>,
        max_labels: usize,
    ) -> Result<LabelVolume, String> {
        use rayon::prelude::*;
        let size = t.size();
        let n: usize = dims.iter().product();
        if bytes.len() < n * stride * size {
            return Err(format!(
                "{} bytes of voxels; {} expected",
                bytes.len(),
                n * stride * size
            ));
        }
        if size == 4 {
            let values = t
                .values(bytes, big_endian)
                .skip(first)
                .step_by(stride)
                .take(n);
            return LabelVolume::from_values_limited(dims, grid, values, max_labels);
        }
        // The table key of voxel v: its raw bits (u8 or u16, in native order).
        let key = |v: usize| -> usize {
            let at = (first + v * stride) * size;
            if size == 1 {
                bytes[at] as usize
            } else if big_endian {
                u16::from_be_bytes([bytes[at], bytes[at + 1]]) as usize
            } else {
                u16::from_le_bytes([bytes[at], bytes[at + 1]]) as usize
            }
        };
        let signed = matches!(t, VoxelType::I8 | VoxelType::I16);
        let value_of = |k: usize| -> i64 {
            match (size, signed) {
                (1, true) => k as u8 as i8 as i64,
                (2, true) => k as u16 as i16 as i64,
                _ => k as i64,
            }
        };
        let n_keys = 1usize << (8 * size);
        const BLOCK: usize = 1 << 16;
        // Pass 1: a histogram of raw keys, per block in parallel (tight loops per type),
        // unless it was taken already.
        let histogram = |range: std::ops::Range<usize>| {
            if stride == 1 {
                let mut h = KeyHistogram::new(t, big_endian);
                h.add(&bytes[(first + range.start) * size..(first + range.end) * size]);
                return h.counts;
            }
            let mut h = vec![0u64; n_keys];
            for v in range {
                h[key(v)] += 1;
            }
            h
        };
        let counts_by_key = match counted {
            Some(h) if h.counts.len() == n_keys && stride == 1 => h.counts,
            _ => (0..n.div_ceil(BLOCK))
                .into_par_iter()
                .map(|b| histogram(b * BLOCK..((b + 1) * BLOCK).min(n)))
                .reduce(
                    || vec![0u64; n_keys],
                    |mut a, b| {
                        for (x, y) in a.iter_mut().zip(b) {
                            *x += y;
                        }
                        a
                    },
                ),
        };
        let mut keys: Vec<usize> = (0..n_keys)
            .filter(|&k| counts_by_key[k] > 0 && value_of(k) != 0)
            .collect();
        if keys.len() > max_labels {
            return Err(too_many_labels(max_labels, Some(keys.len())));
        }
        keys.sort_unstable_by_key(|&k| value_of(k));
        let values: Vec<i64> = keys.iter().map(|&k| value_of(k)).collect();
        let mut table = vec![0u16; n_keys];
        for (id, &k) in keys.iter().enumerate() {
            table[k] = id as u16 + 1;
        }
        let counts: Vec<u64> = std::iter::once(0)
            .chain(keys.iter().map(|&k| counts_by_key[k]))
            .collect();
        // Pass 2: map every voxel through the table.
        let mut voxels =
            crate::hugepages::try_zeroed_vec::<u16>(n).ok_or_else(|| cannot_allocate(dims))?;
        voxels
            .par_chunks_mut(BLOCK)
            .enumerate()
            .for_each(|(b, out)| {
                let start = b * BLOCK;
                if size == 1 && stride == 1 {
                    let src = &bytes[first + start..first + start + out.len()];
                    for (o, &x) in out.iter_mut().zip(src) {
                        *o = table[x as usize];
                    }
                } else {
                    for (o, v) in out.iter_mut().zip(start..) {
                        *o = table[key(v)];
                    }
                }
            });
        Ok(LabelVolume::labelled(dims, grid, voxels, &values, &counts))
    }
}

/// The error for a volume whose voxels cannot be allocated.
fn cannot_allocate(dims: [usize; 3]) -> String {
    format!(
        "cannot allocate memory for {} x {} x {} voxels",
        dims[0], dims[1], dims[2]
    )
}

/// A Slicer segment as its `.seg.nrrd` header names it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Segment {
    pub name: String,
    pub value: i64,
    pub layer: usize,
}

/// A label map file: one volume per layer (NIfTI and plain NRRD have one; a `.seg.nrrd` with
/// overlapping segments has several), the segments its header names, and what was odd.
#[derive(Debug, Clone)]
pub struct LabelMap {
    pub layers: Vec<LabelVolume>,
    pub segments: Vec<Segment>,
    pub warnings: Vec<String>,
    /// The detached data file a `.nhdr` names, when there is one (its bytes are input too).
    pub data_file: Option<PathBuf>,
}

/// A label map that could not be read, with its path.
#[derive(Debug, Error)]
#[error("{}: {message}", path.display())]
pub struct LabelMapError {
    pub path: PathBuf,
    pub message: String,
}

/// A label's name made safe as a file stem (path separators and control characters become
/// `_`); `label_<value>` when nothing usable is left.
pub fn label_file_stem(name: &str, value: i64) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c == '/' || c == '\\' || c.is_control() {
                '_'
            } else {
                c
            }
        })
        .collect();
    if s.is_empty() || s == "." || s == ".." {
        format!("label_{value}")
    } else {
        s
    }
}

/// A label-map format, by the file's ending.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    /// `.nii`, or `.nii.gz` when `gz`.
    Nifti { gz: bool },
    /// `.nrrd`, `.seg.nrrd`, `.nhdr`.
    Nrrd,
}

/// The label-map format a path names by its ending (any case), if any.
fn format_of(path: &Path) -> Option<Format> {
    let name = path.file_name()?.to_string_lossy().to_ascii_lowercase();
    if name.ends_with(".nii") {
        Some(Format::Nifti { gz: false })
    } else if name.ends_with(".nii.gz") {
        Some(Format::Nifti { gz: true })
    } else if name.ends_with(".nrrd") || name.ends_with(".nhdr") {
        Some(Format::Nrrd)
    } else {
        None
    }
}

/// The format of a label map that can be read as a file (a regular file: opening a FIFO would
/// block, and /dev/zero never ends), or why not.
fn readable_format(path: &Path) -> Result<Format, LabelMapError> {
    let err = |message: String| LabelMapError {
        path: path.to_path_buf(),
        message,
    };
    crate::io::check_regular_file(path).map_err(|e| err(e.to_string()))?;
    format_of(path).ok_or_else(|| {
        err("not a label map: expected .nii, .nii.gz, .nrrd, .seg.nrrd or .nhdr".into())
    })
}

/// Which label-map format a path names, by its ending.
pub fn is_label_map(path: &Path) -> bool {
    format_of(path).is_some()
}

/// Reads a label map (NIfTI or NRRD by the file's ending), with world coordinates in `space`,
/// within the default [`LabelMapLimits`].
pub fn read_label_map(path: &Path, space: Space) -> Result<LabelMap, LabelMapError> {
    read_label_map_within(path, space, &LabelMapLimits::default())
}

/// [`read_label_map`] within the given limits.
pub fn read_label_map_within(
    path: &Path,
    space: Space,
    limits: &LabelMapLimits,
) -> Result<LabelMap, LabelMapError> {
    let err = |message: String| LabelMapError {
        path: path.to_path_buf(),
        message,
    };
    let mut map = match readable_format(path)? {
        Format::Nifti { gz } => nifti::read(path, gz, limits).map_err(err)?,
        Format::Nrrd => nrrd::read(path, limits).map_err(err)?,
    };
    for layer in &mut map.layers {
        layer.grid = layer.grid.in_space(space);
    }
    name_segments(&mut map);
    Ok(map)
}

/// Gives labels Slicer's segment names. Two segments that name one label differently leave it
/// with its neutral name `label_<value>` and a warning: which name is right cannot be known,
/// and a structure under a wrong name gets another's settings and references.
fn name_segments(map: &mut LabelMap) {
    let mut names: std::collections::BTreeMap<(usize, i64), Vec<&str>> = Default::default();
    for seg in &map.segments {
        let e = names.entry((seg.layer, seg.value)).or_default();
        if !e.contains(&seg.name.as_str()) {
            e.push(&seg.name);
        }
    }
    let mut warnings = Vec::new();
    for ((layer_index, value), names) in names {
        let Some(layer) = map.layers.get_mut(layer_index) else {
            warnings.push(format!(
                "segment {:?} is in layer {layer_index}, which the file does not have; not named",
                names[0]
            ));
            continue;
        };
        let Some(label) = layer.labels.iter_mut().find(|l| l.value == value) else {
            continue;
        };
        if let [name] = names[..] {
            label.name = name.to_string();
        } else {
            warnings.push(format!(
                "label {value} (layer {layer_index}) is named by {} segments ({}): left as label_{value}; name it in [labels]",
                names.len(),
                names.iter().map(|n| format!("{n:?}")).collect::<Vec<_>>().join(", ")
            ));
        }
    }
    map.warnings.extend(warnings);
}

/// What a label map's header declares (read from the header alone, the voxels untouched), for
/// estimating memory before the map is read.
pub fn read_header(path: &Path) -> Result<LabelMapHeader, LabelMapError> {
    let err = |message: String| LabelMapError {
        path: path.to_path_buf(),
        message,
    };
    match readable_format(path)? {
        Format::Nifti { gz } => nifti::peek(path, gz).map_err(err),
        Format::Nrrd => nrrd::peek(path).map_err(err),
    }
}

/// The segment names a label map's header gives (3D Slicer's `.seg.nrrd` fields), read from
/// the header alone; empty for NIfTI, which names no labels.
pub fn declared_segments(path: &Path) -> Vec<Segment> {
    match format_of(path) {
        Some(Format::Nrrd) => nrrd::declared_segments(path),
        _ => Vec::new(),
    }
}

/// The `n` bytes of voxels at `offset`, or what the header claims against what there is.
pub fn exact_slice(data: &[u8], offset: u64, n: u64) -> Result<&[u8], String> {
    match offset.checked_add(n) {
        Some(end) if end <= data.len() as u64 => Ok(&data[offset as usize..end as usize]),
        _ => Err(format!(
            "the header says {n} bytes of voxels from byte {offset}; the data holds {} bytes",
            data.len()
        )),
    }
}

/// How often each raw key (the bits of an 8- or 16-bit voxel, in native order) occurs, fed
/// piece by piece; pieces must hold whole voxels.
pub struct KeyHistogram {
    size: usize,
    big_endian: bool,
    /// Occurrences per key.
    pub counts: Vec<u64>,
}

impl KeyHistogram {
    /// An empty histogram for voxels of type `t` (32-bit types keep none).
    pub fn new(t: VoxelType, big_endian: bool) -> KeyHistogram {
        let size = t.size();
        let n_keys = if size <= 2 { 1usize << (8 * size) } else { 0 };
        KeyHistogram {
            size,
            big_endian,
            counts: vec![0; n_keys],
        }
    }

    /// Counts the voxels of `bytes`.
    pub fn add(&mut self, bytes: &[u8]) {
        match self.size {
            1 => {
                // Four tables in turn: labels come in long runs, and one table would make
                // every voxel of a run wait on the same counter.
                let mut four = [[0u32; 256]; 4];
                for block in bytes.chunks(1 << 30) {
                    let mut quads = block.chunks_exact(4);
                    for q in &mut quads {
                        for (table, &b) in four.iter_mut().zip(q) {
                            table[b as usize] += 1;
                        }
                    }
                    for &b in quads.remainder() {
                        four[0][b as usize] += 1;
                    }
                    for table in &mut four {
                        for (total, c) in self.counts.iter_mut().zip(table.iter_mut()) {
                            *total += *c as u64;
                            *c = 0;
                        }
                    }
                }
            }
            2 => {
                for pair in bytes.chunks_exact(2) {
                    let key = if self.big_endian {
                        u16::from_be_bytes([pair[0], pair[1]])
                    } else {
                        u16::from_le_bytes([pair[0], pair[1]])
                    };
                    self.counts[key as usize] += 1;
                }
            }
            _ => {}
        }
    }
}

/// Largest ratio of decompressed to compressed size DEFLATE can reach (about 1032:1), with
/// room for the gzip framing: a header that claims more data than this is lying.
pub(super) const MAX_GZIP_RATIO: u64 = 1040;

/// Gzip-decompresses the `n_bytes` that follow the first `skip` bytes of the stream (which
/// must end there), handing them to `each` piece by piece on the calling thread while a
/// second thread decompresses the rest: work on the data overlaps the serial inflate. Pieces
/// hold whole multiples of 8 bytes except the last. Fails clearly when the stream is
/// truncated, corrupt, or longer than that.
pub fn gunzip_overlapped(
    compressed: &[u8],
    skip: u64,
    n_bytes: u64,
    mut each: impl FnMut(&[u8]),
) -> Result<Vec<u8>, String> {
    use std::io::Read;
    const PIECE: usize = 4 << 20;
    let corrupt = |e: std::io::Error| format!("the gzip data is corrupt or truncated ({e})");
    let expected = skip.saturating_add(n_bytes);
    if expected > (compressed.len() as u64).saturating_mul(MAX_GZIP_RATIO) + 4096 {
        return Err(format!(
            "the header says {expected} bytes; {} bytes of gzip data cannot hold that many",
            compressed.len()
        ));
    }
    let n =
        usize::try_from(n_bytes).map_err(|_| format!("{n_bytes} bytes do not fit in memory"))?;
    let mut out: Vec<u8> = Vec::new();
    out.try_reserve_exact(n)
        .map_err(|_| format!("cannot allocate {n} bytes for the voxels"))?;
    crate::hugepages::advise(out.spare_capacity_mut());
    out.resize(n, 0);
    let mut decoder = flate2::read::MultiGzDecoder::new(compressed);
    let skipped =
        std::io::copy(&mut (&mut decoder).take(skip), &mut std::io::sink()).map_err(corrupt)?;
    if skipped < skip {
        return Err(format!(
            "the gzip data ends after {skipped} bytes; the header says {expected}"
        ));
    }
    let filled: &mut [u8] = &mut out;
    std::thread::scope(|scope| {
        let (send, receive) = crossbeam_channel::bounded::<&[u8]>(4);
        let inflate = scope.spawn(move || -> Result<(), String> {
            let mut done = skip;
            for piece in filled.chunks_mut(PIECE) {
                let mut at = 0;
                while at < piece.len() {
                    match decoder.read(&mut piece[at..]).map_err(corrupt)? {
                        0 => {
                            return Err(format!(
                                "the gzip data ends after {} bytes; the header says {expected}",
                                done + at as u64
                            ))
                        }
                        k => at += k,
                    }
                }
                done += at as u64;
                if send.send(&*piece).is_err() {
                    return Ok(());
                }
            }
            drop(send);
            let mut probe = [0u8; 1];
            if decoder.read(&mut probe).map_err(corrupt)? > 0 {
                return Err(format!(
                    "the gzip data holds more than the {expected} bytes the header says"
                ));
            }
            Ok(())
        });
        for piece in receive {
            each(piece);
        }
        inflate
            .join()
            .unwrap_or_else(|_| Err("decompression failed".into()))
    })?;
    Ok(out)
}

/// Integer voxel types of label maps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VoxelType {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
}

impl VoxelType {
    /// Bytes per voxel.
    pub fn size(self) -> usize {
        match self {
            VoxelType::U8 | VoxelType::I8 => 1,
            VoxelType::U16 | VoxelType::I16 => 2,
            VoxelType::U32 | VoxelType::I32 => 4,
        }
    }

    /// The voxel values of `bytes` (`big_endian` for their byte order), widened to i64.
    pub fn values(self, bytes: &[u8], big_endian: bool) -> impl Iterator<Item = i64> + '_ {
        let size = self.size();
        bytes.chunks_exact(size).map(move |c| {
            let mut b = [0u8; 4];
            b[..size].copy_from_slice(c);
            if big_endian {
                b[..size].reverse();
            }
            match self {
                VoxelType::U8 => b[0] as i64,
                VoxelType::I8 => b[0] as i8 as i64,
                VoxelType::U16 => u16::from_le_bytes([b[0], b[1]]) as i64,
                VoxelType::I16 => i16::from_le_bytes([b[0], b[1]]) as i64,
                VoxelType::U32 => u32::from_le_bytes(b) as i64,
                VoxelType::I32 => i32::from_le_bytes(b) as i64,
            }
        })
    }
}

/// Checks dimensions against [`MAX_VOXELS`] and returns the voxel count.
pub fn voxel_count(dims: [u64; 3]) -> Result<u64, String> {
    if dims.contains(&0) {
        return Err(format!("a dimension is zero ({dims:?})"));
    }
    let n = dims.iter().try_fold(1u64, |a, &d| a.checked_mul(d));
    match n {
        Some(n) if n <= MAX_VOXELS => Ok(n),
        _ => Err(format!(
            "{} x {} x {} voxels is more than the {MAX_VOXELS} a label map may have",
            dims[0], dims[1], dims[2]
        )),
    }
}
