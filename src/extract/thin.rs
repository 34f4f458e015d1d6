//! Thin parts of a label (thesis §6.3.4): voxels where the label is only one voxel thick, so
//! that constrained smoothing would shrink it onto its voxel centres. Found by a morphological
//! opening (erosion then dilation, 26-neighbourhood) on the dual grid: a corner is set when
//! any of its 8 voxels holds the label, and after the opening a voxel stays only when all 8 of
//! its corners are still set. A plain opening on the voxels would also remove parts two voxels
//! thick; on the dual grid only one-voxel parts go. Decided per voxel from its 7 x 7 x 7
//! neighbourhood, for the few voxels constrained smoothing asks about.

use crate::volume::LabelVolume;

/// Whether voxel `v` (which holds dense label `label`) is thin: not all 8 of its corners survive
/// the opening. Decided from the 7 x 7 x 7 voxels around it (the corners' grid, the erosion and
/// the dilation each reach one voxel further), so it costs the same anywhere and needs no pass
/// over the volume: constrained smoothing asks only about the few voxels whose weight fell low.
pub fn is_thin(volume: &LabelVolume, label: u16, v: [i64; 3]) -> bool {
    let [nx, ny, nz] = volume.dims.map(|d| d as i64);
    // Block voxel (i, j, k) is volume voxel v + (i, j, k) - 3; outside the volume: background.
    let mut set = [[[false; 7]; 7]; 7];
    for (k, plane) in set.iter_mut().enumerate() {
        let z = v[2] + k as i64 - 3;
        for (j, row) in plane.iter_mut().enumerate() {
            let y = v[1] + j as i64 - 3;
            if y < 0 || z < 0 || y >= ny || z >= nz {
                continue;
            }
            for (i, cell) in row.iter_mut().enumerate() {
                let x = v[0] + i as i64 - 3;
                *cell =
                    x >= 0 && x < nx && volume.voxels[(x + nx * (y + ny * z)) as usize] == label;
            }
        }
    }
    // Corner c (1..=6 along each axis) lies between block voxels c - 1 and c.
    let mut corner = [[[false; 7]; 7]; 7];
    for k in 1..7 {
        for j in 1..7 {
            for i in 1..7 {
                corner[k][j][i] =
                    (0..8).any(|o: usize| set[k - (o >> 2 & 1)][j - (o >> 1 & 1)][i - (o & 1)]);
            }
        }
    }
    // Eroded corners (2..=5: their 26 neighbours are all known).
    let mut eroded = [[[false; 7]; 7]; 7];
    for k in 2..6 {
        for j in 2..6 {
            for i in 2..6 {
                eroded[k][j][i] =
                    (0..27).all(|o: usize| corner[k + o / 9 - 1][j + o / 3 % 3 - 1][i + o % 3 - 1]);
            }
        }
    }
    // The voxel's own corners are 3 and 4 along each axis; each survives the dilation when an
    // eroded corner lies next to it.
    let survives = |c: [usize; 3]| {
        (0..27).any(|o: usize| eroded[c[2] + o / 9 - 1][c[1] + o / 3 % 3 - 1][c[0] + o % 3 - 1])
    };
    !(0..8).all(|o: usize| survives([3 + (o & 1), 3 + (o >> 1 & 1), 3 + (o >> 2 & 1)]))
}
