//! Label maps in: segmentations as NIfTI-1 (`.nii`, `.nii.gz`) or NRRD (`.nrrd`, `.nhdr` with a
//! detached data file, 3D Slicer's `.seg.nrrd`), with their grid geometry in world millimetres
//! and their label names. Sizes in headers are checked against the data before anything is
//! allocated; every problem names the file and what is wrong.

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
        // Provisional ids in order of first appearance: a direct table for the usual small
        // non-negative values, a map for the rest.
        const DIRECT: i64 = 1 << 16;
        let mut direct = vec![0u16; DIRECT as usize];
        let mut other: rustc_hash::FxHashMap<i64, u16> = Default::default();
        let mut seen: Vec<i64> = Vec::new();
        let mut voxels = Vec::with_capacity(dims.iter().product());
        for v in values {
            let slot = if (0..DIRECT).contains(&v) {
                &mut direct[v as usize]
            } else {
                other.entry(v).or_insert(0)
            };
            if *slot == 0 && v != 0 {
                if seen.len() >= u16::MAX as usize {
                    return Err("more than 65 535 different labels".into());
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
        let labels = order
            .iter()
            .enumerate()
            .map(|(rank, &i)| Label {
                value: seen[i],
                name: format!("label_{}", seen[i]),
                n_voxels: counts[rank + 1],
            })
            .collect();
        Ok(LabelVolume {
            dims,
            grid,
            voxels,
            labels,
        })
    }
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
}

/// A label map that could not be read, with its path.
#[derive(Debug, Error)]
#[error("{}: {message}", path.display())]
pub struct LabelMapError {
    pub path: PathBuf,
    pub message: String,
}

/// Which label-map format a path names, by its ending.
pub fn is_label_map(path: &Path) -> bool {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    [".nii", ".nii.gz", ".nrrd", ".nhdr"]
        .iter()
        .any(|e| name.ends_with(e))
}

/// Reads a label map (NIfTI or NRRD by the file's ending), with world coordinates in `space`.
pub fn read_label_map(path: &Path, space: Space) -> Result<LabelMap, LabelMapError> {
    let err = |message: String| LabelMapError {
        path: path.to_path_buf(),
        message,
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    crate::io::check_regular_file(path).map_err(|e| err(e.to_string()))?;
    let mut map = if name.ends_with(".nii") || name.ends_with(".nii.gz") {
        nifti::read(path).map_err(err)?
    } else if name.ends_with(".nrrd") || name.ends_with(".nhdr") {
        nrrd::read(path).map_err(err)?
    } else {
        return Err(err(
            "not a label map: expected .nii, .nii.gz, .nrrd, .seg.nrrd or .nhdr".into(),
        ));
    };
    for layer in &mut map.layers {
        layer.grid = layer.grid.in_space(space);
    }
    // Slicer's segment names replace the default label names.
    for seg in &map.segments {
        if let Some(layer) = map.layers.get_mut(seg.layer) {
            if let Some(l) = layer.labels.iter_mut().find(|l| l.value == seg.value) {
                l.name = seg.name.clone();
            }
        }
    }
    Ok(map)
}

/// Gzip-decompresses at most `expected` bytes, failing clearly when the stream is truncated,
/// corrupt, or holds more data than the header says. Memory grows with the data actually
/// decoded, never with the header's claim.
pub(crate) fn gunzip_exact(compressed: &[u8], expected: u64) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let mut out = Vec::with_capacity(expected.min(1 << 26) as usize);
    let mut decoder = flate2::read::MultiGzDecoder::new(compressed);
    (&mut decoder)
        .take(expected)
        .read_to_end(&mut out)
        .map_err(|e| format!("the gzip data is corrupt or truncated ({e})"))?;
    if (out.len() as u64) < expected {
        return Err(format!(
            "the gzip data ends after {} bytes; the header says {expected}",
            out.len()
        ));
    }
    let mut probe = [0u8; 1];
    if decoder
        .read(&mut probe)
        .map_err(|e| format!("the gzip data is corrupt or truncated ({e})"))?
        > 0
    {
        return Err(format!(
            "the gzip data holds more than the {expected} bytes the header says"
        ));
    }
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
pub(crate) fn voxel_count(dims: [u64; 3]) -> Result<u64, String> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_are_numbered_by_value_and_counted() {
        let g = Grid::axis_aligned([1.0; 3], [0.0; 3], Space::Lps);
        let v = LabelVolume::from_values([4, 1, 1], g, [5i64, 0, -2, 5].into_iter()).unwrap();
        assert_eq!(v.voxels, vec![2, 0, 1, 2]);
        assert_eq!(v.labels[0].value, -2);
        assert_eq!(v.labels[1].n_voxels, 2);
        assert_eq!(v.labels[1].name, "label_5");
    }

    #[test]
    fn gzip_streams_must_hold_exactly_what_the_header_says() {
        use std::io::Write;
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        e.write_all(&[7u8; 1000]).unwrap();
        let gz = e.finish().unwrap();
        assert_eq!(gunzip_exact(&gz, 1000).unwrap().len(), 1000);
        assert!(gunzip_exact(&gz, 1001)
            .unwrap_err()
            .contains("ends after 1000"));
        assert!(gunzip_exact(&gz, 999).unwrap_err().contains("more than"));
        for cut in [5, gz.len() / 2, gz.len() - 3] {
            assert!(gunzip_exact(&gz[..cut], 1000).is_err(), "cut {cut}");
        }
        // A claim of 2^40 bytes is not allocated up front.
        assert!(gunzip_exact(&gz, 1 << 40).is_err());
    }
}
