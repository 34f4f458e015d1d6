//! NIfTI-1 label maps (`.nii`, `.nii.gz`). The 348-byte header is decoded by the `nifti` crate
//! (both byte orders); the voxels are read here, from a memory map or a gzip stream, after the
//! header's sizes are checked against the data. Geometry from the sform when its code is set
//! (with a warning when a set qform places the grid elsewhere), else the qform, else the plain
//! pixdim scaling (with a warning); NIfTI's world is RAS.

use super::{
    gunzip_overlapped, voxel_count, Grid, KeyHistogram, LabelMap, LabelMapHeader, LabelMapLimits,
    LabelVolume, Space, VoxelType,
};
use std::path::Path;

/// Size of the NIfTI-1 header (bytes).
const HEADER: usize = 348;

fn voxel_type(code: i16) -> Result<VoxelType, String> {
    Ok(match code {
        2 => VoxelType::U8,
        256 => VoxelType::I8,
        4 => VoxelType::I16,
        512 => VoxelType::U16,
        8 => VoxelType::I32,
        768 => VoxelType::U32,
        16 | 64 | 1536 => {
            return Err(format!(
                "datatype {code} is floating point; a label map holds integers (u8, i8, u16, i16, u32, i32)"
            ))
        }
        other => return Err(format!("datatype {other} is not an integer label type")),
    })
}

/// Largest amount by which the qform's (b, c, d) may exceed unit length: float32 rounding of a
/// unit quaternion (nibabel refuses beyond 3 float32 epsilons; this is a little wider).
const QUATERNION_SLACK: f64 = 1e-6;

/// The grid of a NIfTI header (RAS), and a warning when it had to be guessed or when the
/// sform and qform place it differently. A qform whose quaternion is longer than 1 is no
/// rotation (its grid would scale every voxel), and voxel sizes (pixdim) are positive in NIfTI
/// (the mirror goes in qfac): both are refused.
fn grid_of(h: &nifti::NiftiHeader) -> Result<(Grid, Option<String>), String> {
    if h.sform_code > 0 {
        let r = [h.srow_x, h.srow_y, h.srow_z].map(|row| row.map(|x| x as f64));
        let grid = Grid {
            matrix: [
                [r[0][0], r[0][1], r[0][2]],
                [r[1][0], r[1][1], r[1][2]],
                [r[2][0], r[2][1], r[2][2]],
            ],
            origin: [r[0][3], r[1][3], r[2][3]],
            space: Space::Ras,
        };
        // Readers differ in which form they take (nibabel the sform; ITK, and so 3D Slicer,
        // may take the qform): a disagreement places the surfaces elsewhere there.
        let warning = match (h.qform_code > 0).then(|| qform_grid(h)) {
            Some(Ok(q)) => disagreement(&grid, &q, dims_of(h)),
            _ => None,
        };
        return Ok((grid, warning));
    }
    if h.qform_code > 0 {
        return Ok((qform_grid(h)?, None));
    }
    positive_pixdims(h)?;
    let p = |k: usize| h.pixdim[k] as f64;
    Ok((
        Grid::axis_aligned([p(1), p(2), p(3)], [0.0; 3], Space::Ras),
        Some("neither sform nor qform is set: the grid is pixdim-scaled at the origin, orientation unknown".into()),
    ))
}

/// Voxel sizes (pixdim 1-3) must be positive.
fn positive_pixdims(h: &nifti::NiftiHeader) -> Result<(), String> {
    let p = |k: usize| h.pixdim[k] as f64;
    match (1..=3).find(|&k| p(k).is_nan() || p(k) <= 0.0) {
        Some(k) => Err(format!(
            "pixdim[{k}] = {}: NIfTI voxel sizes must be positive (a mirrored axis is qfac, pixdim[0])",
            crate::units::readable(p(k))
        )),
        None => Ok(()),
    }
}

/// The grid the qform gives (quaternion, pixdim, qfac, offset).
fn qform_grid(h: &nifti::NiftiHeader) -> Result<Grid, String> {
    let p = |k: usize| h.pixdim[k] as f64;
    let (b, c, d) = (h.quatern_b as f64, h.quatern_c as f64, h.quatern_d as f64);
    let length2 = b * b + c * c + d * d;
    if length2.is_nan() || length2 > 1.0 + QUATERNION_SLACK {
        return Err(format!(
            "the qform quaternion (b, c, d) = ({}, {}, {}) is longer than 1 (|q|^2 = {}): not a rotation, so the voxel grid cannot be placed",
            crate::units::readable(b),
            crate::units::readable(c),
            crate::units::readable(d),
            crate::units::readable(length2)
        ));
    }
    positive_pixdims(h)?;
    let a = (1.0 - length2).max(0.0).sqrt();
    let rot = super::grid::quaternion_rotation(a, b, c, d);
    let qfac = if h.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
    let scale = [p(1), p(2), qfac * p(3)];
    let mut matrix = [[0.0; 3]; 3];
    for r in 0..3 {
        for col in 0..3 {
            matrix[r][col] = rot[r][col] * scale[col];
        }
    }
    Ok(Grid {
        matrix,
        origin: [h.quatern_x as f64, h.quatern_y as f64, h.quatern_z as f64],
        space: Space::Ras,
    })
}

/// Voxel centres the two forms may place apart by float32 storage alone (a share of the
/// smallest voxel spacing): beyond it they are two placements.
const FORMS_AGREE_VOXELS: f64 = 0.01;

/// A warning naming both forms when the sform and qform put a corner voxel of the `dims`
/// volume more than [`FORMS_AGREE_VOXELS`] apart.
fn disagreement(sform: &Grid, qform: &Grid, dims: [usize; 3]) -> Option<String> {
    let corners = (0..8).map(|c: usize| {
        std::array::from_fn(|k| {
            if c >> k & 1 == 1 {
                dims[k].saturating_sub(1) as f64
            } else {
                0.0
            }
        })
    });
    let (apart, corner) = corners
        .map(|ijk: [f64; 3]| {
            let (a, b) = (sform.world(ijk), qform.world(ijk));
            (
                (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt(),
                ijk,
            )
        })
        .fold((0.0, [0.0; 3]), |m, x| if x.0 > m.0 { x } else { m });
    let smallest = (sform.spacing().into_iter()).fold(f64::INFINITY, f64::min);
    if apart.is_nan() || apart <= FORMS_AGREE_VOXELS * smallest {
        return None;
    }
    let mm = |v: [f64; 3]| format!("({:.3}, {:.3}, {:.3})", v[0], v[1], v[2]);
    Some(format!(
        "the sform and the qform place the grid differently: voxel ({}, {}, {}) at {} mm by the sform, {} mm by the qform ({apart:.3} mm apart, RAS); the sform is used (as nibabel does; ITK-based tools such as 3D Slicer may take the qform)",
        corner[0], corner[1], corner[2],
        mm(sform.world(corner)),
        mm(qform.world(corner))
    ))
}

/// Reads a NIfTI-1 label map (gzip-compressed when `gz`) within `limits`.
pub fn read(path: &Path, gz: bool, limits: &LabelMapLimits) -> Result<LabelMap, String> {
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read: {e}"))?;
    let map = crate::io::MappedFile::map(&file).map_err(|e| format!("cannot read: {e}"))?;
    let bytes: &[u8] = map.bytes();
    let read = if gz {
        // Header first, from the start of the stream, to know how much data to expect.
        use std::io::Read;
        let mut head = Vec::new();
        flate2::read::MultiGzDecoder::new(bytes)
            .take(HEADER as u64)
            .read_to_end(&mut head)
            .map_err(|e| format!("not a gzip file, or a corrupt one ({e})"))?;
        let (h, offset, n_bytes) = header(&head)?;
        let grid = checked_grid(&h, limits)?;
        // The histogram of voxel values is taken while the rest is still being inflated.
        let mut counted = KeyHistogram::new(voxel_type(h.datatype)?, big_endian(&h));
        let data = gunzip_overlapped(bytes, offset, n_bytes, |piece| counted.add(piece))?;
        decode(&h, grid, &data, Some(counted), limits)
    } else {
        let (h, offset, n_bytes) = header(bytes)?;
        let grid = checked_grid(&h, limits)?;
        decode(
            &h,
            grid,
            super::exact_slice(bytes, offset, n_bytes)?,
            None,
            limits,
        )
    };
    // A file that changed size while it was mapped was read in part as zeros: refuse it.
    map.verify().map_err(|e| format!("cannot read: {e}"))?;
    read
}

/// The header's grid, checked (before any voxel is read) with the voxel count against
/// `limits`.
fn checked_grid(
    h: &nifti::NiftiHeader,
    limits: &LabelMapLimits,
) -> Result<(Grid, Option<String>), String> {
    let dims = dims_of(h);
    limits.check_voxels(dims.map(|d| d as u64), 1)?;
    let (grid, warning) = grid_of(h)?;
    grid.check()?;
    grid.check_extent(dims)?;
    grid.check_spacing(limits.spacing_mm)?;
    Ok((grid, warning))
}

/// The three spatial dimensions of a header (1 for those it does not have).
fn dims_of(h: &nifti::NiftiHeader) -> [usize; 3] {
    let n_dims = h.dim[0] as usize;
    let d = |k: usize| if k <= n_dims { h.dim[k] as usize } else { 1 };
    [d(1), d(2), d(3)]
}

fn big_endian(h: &nifti::NiftiHeader) -> bool {
    h.endianness == nifti::Endianness::Big
}

/// What the header declares, read from the first 348 bytes (inflated ones for `.nii.gz`).
pub(super) fn peek(path: &Path, gz: bool) -> Result<LabelMapHeader, String> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read: {e}"))?;
    let mut head = Vec::with_capacity(HEADER);
    let read = if gz {
        flate2::read::MultiGzDecoder::new(file)
            .take(HEADER as u64)
            .read_to_end(&mut head)
    } else {
        file.take(HEADER as u64).read_to_end(&mut head)
    };
    read.map_err(|e| format!("cannot read the header: {e}"))?;
    let (h, _, _) = header(&head)?;
    Ok(LabelMapHeader {
        dims: dims_of(&h).map(|d| d as u64),
        n_layers: 1,
        voxel_type: voxel_type(h.datatype)?,
    })
}

/// Parses and checks the header: (header, voxel offset, voxel bytes).
fn header(bytes: &[u8]) -> Result<(nifti::NiftiHeader, u64, u64), String> {
    if bytes.len() < HEADER {
        return Err(format!(
            "{} bytes is shorter than a NIfTI-1 header ({HEADER} bytes)",
            bytes.len()
        ));
    }
    let h = nifti::NiftiHeader::from_reader(&bytes[..HEADER])
        .map_err(|e| format!("not a NIfTI-1 header: {e}"))?;
    if h.sizeof_hdr != HEADER as i32 {
        return Err(format!(
            "header size is {}, not {HEADER}: not a NIfTI-1 file (NIfTI-2 is not read)",
            h.sizeof_hdr
        ));
    }
    if &h.magic != b"n+1\0" && &h.magic != b"ni1\0" {
        return Err(format!("magic {:?} is not NIfTI-1's \"n+1\"", h.magic));
    }
    if &h.magic == b"ni1\0" {
        return Err("a header-only .hdr/.img pair; give the single-file .nii".into());
    }
    let n_dims = h.dim[0];
    if !(1..=7).contains(&n_dims) {
        return Err(format!(
            "dim[0] = {n_dims} is not a number of dimensions (1..7)"
        ));
    }
    if (4..=n_dims as usize).any(|k| h.dim[k] > 1) {
        return Err(format!(
            "a {n_dims}-dimensional image ({:?}); a label map is 3D",
            &h.dim[1..=n_dims as usize]
        ));
    }
    let d = |k: usize| {
        if k <= n_dims as usize {
            h.dim[k] as u64
        } else {
            1
        }
    };
    let n = voxel_count([d(1), d(2), d(3)])?;
    let t = voxel_type(h.datatype)?;
    if h.vox_offset < HEADER as f32 || !h.vox_offset.is_finite() {
        return Err(format!(
            "vox_offset {} lies inside the header",
            h.vox_offset
        ));
    }
    if h.scl_slope != 0.0 && (h.scl_slope != 1.0 || h.scl_inter != 0.0) {
        return Err(format!(
            "scl_slope {} and scl_inter {} rescale the voxels; labels must be stored as they are",
            h.scl_slope, h.scl_inter
        ));
    }
    Ok((h.clone(), h.vox_offset as u64, n * t.size() as u64))
}

fn decode(
    h: &nifti::NiftiHeader,
    (grid, warning): (Grid, Option<String>),
    data: &[u8],
    counted: Option<KeyHistogram>,
    limits: &LabelMapLimits,
) -> Result<LabelMap, String> {
    let dims = dims_of(h);
    let t = voxel_type(h.datatype)?;
    let volume = LabelVolume::from_raw(
        dims,
        grid,
        data,
        t,
        big_endian(h),
        (0, 1),
        counted,
        limits.max_labels,
    )?;
    Ok(LabelMap {
        layers: vec![volume],
        segments: Vec::new(),
        warnings: warning.into_iter().collect(),
        data_file: None,
    })
}

/// Encodes a label volume as NIfTI-1 (u8 if every label value fits, else i16 or i32) with its
/// grid as sform and qform (in RAS, as NIfTI requires); gzip-compressed when `gz`.
pub fn encode(volume: &LabelVolume, gz: bool) -> Result<Vec<u8>, String> {
    let values: Vec<i64> = volume
        .voxels
        .iter()
        .map(|&v| {
            if v == 0 {
                0
            } else {
                volume.labels[v as usize - 1].value
            }
        })
        .collect();
    let (lo, hi) = values
        .iter()
        .fold((0i64, 0i64), |(a, b), &v| (a.min(v), b.max(v)));
    let (code, bits, t) = if lo >= 0 && hi <= 255 {
        (2i16, 8i16, VoxelType::U8)
    } else if lo >= i16::MIN as i64 && hi <= i16::MAX as i64 {
        (4, 16, VoxelType::I16)
    } else {
        (8, 32, VoxelType::I32)
    };
    let g = volume.grid.in_space(Space::Ras);
    g.check()?;
    let mut h = vec![0u8; HEADER + 4];
    let put = |h: &mut Vec<u8>, at: usize, b: &[u8]| h[at..at + b.len()].copy_from_slice(b);
    put(&mut h, 0, &(HEADER as i32).to_le_bytes());
    h[38] = b'r';
    let dims = [
        3i16,
        volume.dims[0] as i16,
        volume.dims[1] as i16,
        volume.dims[2] as i16,
        1,
        1,
        1,
        1,
    ];
    if volume.dims.iter().any(|&d| d > i16::MAX as usize) {
        return Err("a dimension above 32767 voxels does not fit NIfTI-1".into());
    }
    for (k, d) in dims.iter().enumerate() {
        put(&mut h, 40 + 2 * k, &d.to_le_bytes());
    }
    put(&mut h, 70, &code.to_le_bytes());
    put(&mut h, 72, &bits.to_le_bytes());
    let spacing = g.spacing();
    let dir = g.directions();
    let det = super::grid::det3(&dir);
    let qfac: f32 = if det < 0.0 { -1.0 } else { 1.0 };
    let pixdim = [
        qfac,
        spacing[0] as f32,
        spacing[1] as f32,
        spacing[2] as f32,
        1.0,
        1.0,
        1.0,
        1.0,
    ];
    for (k, p) in pixdim.iter().enumerate() {
        put(&mut h, 76 + 4 * k, &p.to_le_bytes());
    }
    put(&mut h, 108, &((HEADER + 4) as f32).to_le_bytes());
    h[123] = 2; // xyzt_units: mm
    put(&mut h, 148, b"destair label map");
    put(&mut h, 252, &1i16.to_le_bytes()); // qform_code: scanner
    put(&mut h, 254, &1i16.to_le_bytes()); // sform_code: scanner
                                           // The qform quaternion of the rotation part (third column flipped when qfac is -1).
    let mut r = dir;
    if qfac < 0.0 {
        for row in &mut r {
            row[2] = -row[2];
        }
    }
    let (b, c, d) = quaternion(&r);
    for (k, q) in [b, c, d, g.origin[0], g.origin[1], g.origin[2]]
        .iter()
        .enumerate()
    {
        put(&mut h, 256 + 4 * k, &(*q as f32).to_le_bytes());
    }
    for row in 0..3 {
        let srow = [
            g.matrix[row][0],
            g.matrix[row][1],
            g.matrix[row][2],
            g.origin[row],
        ];
        for (k, x) in srow.iter().enumerate() {
            put(&mut h, 280 + 16 * row + 4 * k, &(*x as f32).to_le_bytes());
        }
    }
    put(&mut h, 344, b"n+1\0");
    let mut out = h;
    out.reserve(values.len() * t.size());
    for v in values {
        match t {
            VoxelType::U8 => out.push(v as u8),
            VoxelType::I16 => out.extend_from_slice(&(v as i16).to_le_bytes()),
            _ => out.extend_from_slice(&(v as i32).to_le_bytes()),
        }
    }
    if !gz {
        return Ok(out);
    }
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(&out).map_err(|e| e.to_string())?;
    e.finish().map_err(|e| e.to_string())
}

/// Quaternion (b, c, d) of a proper rotation matrix, with a >= 0 (NIfTI's convention).
fn quaternion(r: &[[f64; 3]; 3]) -> (f64, f64, f64) {
    let trace = r[0][0] + r[1][1] + r[2][2];
    let (a, b, c, d);
    if trace > 0.0 {
        let s = 0.5 / (trace + 1.0).sqrt();
        a = 0.25 / s;
        b = (r[2][1] - r[1][2]) * s;
        c = (r[0][2] - r[2][0]) * s;
        d = (r[1][0] - r[0][1]) * s;
    } else if r[0][0] > r[1][1] && r[0][0] > r[2][2] {
        let s = 2.0 * (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt();
        a = (r[2][1] - r[1][2]) / s;
        b = 0.25 * s;
        c = (r[0][1] + r[1][0]) / s;
        d = (r[0][2] + r[2][0]) / s;
    } else if r[1][1] > r[2][2] {
        let s = 2.0 * (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt();
        a = (r[0][2] - r[2][0]) / s;
        b = (r[0][1] + r[1][0]) / s;
        c = 0.25 * s;
        d = (r[1][2] + r[2][1]) / s;
    } else {
        let s = 2.0 * (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt();
        a = (r[1][0] - r[0][1]) / s;
        b = (r[0][2] + r[2][0]) / s;
        c = (r[1][2] + r[2][1]) / s;
        d = 0.25 * s;
    }
    if a < 0.0 {
        (-b, -c, -d)
    } else {
        (b, c, d)
    }
}
