//! How many objects each label's voxels form: voxels of one label that share a face (6), or
//! also an edge or a corner (26), are one object. The extraction promises one closed surface
//! per object; the report compares the two counts. Works on runs of voxels along x joined by
//! union-find, so memory grows with the runs (about the labels' surface), not with the volume.

use super::LabelVolume;

/// A run of voxels of one label along x: `[start, end)` in its row.
#[derive(Clone, Copy)]
struct Run {
    start: u32,
    end: u32,
    label: u16,
}

/// Objects per dense label (entry 0, the background, is 0): `joins[l]` says whether label
/// `l`'s voxels touching only by an edge or a corner are one object (26-connectivity; missing
/// entries are).
pub fn label_components(volume: &LabelVolume, joins: &[bool]) -> Vec<u64> {
    let [nx, ny, nz] = volume.dims;
    let n_labels = volume.labels.len() + 1;
    let mut counts = vec![0u64; n_labels];
    if nx == 0 || ny == 0 || nz == 0 {
        return counts;
    }
    // Runs of every row (y + ny * z), in row order, with each row's first run.
    let mut runs: Vec<Run> = Vec::new();
    let mut row_start: Vec<u32> = Vec::with_capacity(ny * nz + 1);
    for row in volume.voxels.chunks_exact(nx) {
        row_start.push(runs.len() as u32);
        let mut x = 0;
        while x < nx {
            let label = row[x];
            let start = x;
            while x < nx && row[x] == label {
                x += 1;
            }
            if label != 0 {
                runs.push(Run {
                    start: start as u32,
                    end: x as u32,
                    label,
                });
            }
        }
    }
    row_start.push(runs.len() as u32);
    let mut parent: Vec<u32> = (0..runs.len() as u32).collect();
    let joins_at = |l: u16| joins.get(l as usize).copied().unwrap_or(true);
    let rows_of = |r: usize| row_start[r] as usize..row_start[r + 1] as usize;
    for z in 0..nz {
        for y in 0..ny {
            let here = y + ny * z;
            // Rows before this one that touch it: by a face (y - 1; z - 1), or by an edge only
            // (y -+ 1 at z - 1), whose runs join only labels that join diagonally.
            let mut before: [(Option<usize>, bool); 4] = [(None, false); 4];
            if y > 0 {
                before[0] = (Some(here - 1), false);
            }
            if z > 0 {
                before[1] = (Some(here - ny), false);
                if y > 0 {
                    before[2] = (Some(here - ny - 1), true);
                }
                if y + 1 < ny {
                    before[3] = (Some(here - ny + 1), true);
                }
            }
            for (other, edge_only) in before {
                let Some(other) = other else { continue };
                let b = rows_of(other);
                // Runs are sorted by x in both rows: `first` is the other row's first run that
                // can still reach this row's next run (a corner's reach is one voxel).
                let mut first = b.start;
                for a in rows_of(here) {
                    let ra = runs[a];
                    while first < b.end && runs[first].end < ra.start {
                        first += 1;
                    }
                    let diagonal = joins_at(ra.label);
                    if edge_only && !diagonal {
                        continue;
                    }
                    // Touching by a face: overlapping x; by an edge or a corner: x within one.
                    let reach = diagonal as u32;
                    for (o, rb) in runs[first..b.end].iter().enumerate() {
                        if rb.start >= ra.end + reach {
                            break;
                        }
                        if rb.label == ra.label && ra.start < rb.end + reach {
                            union(&mut parent, a as u32, (first + o) as u32);
                        }
                    }
                }
            }
        }
    }
    for r in 0..runs.len() as u32 {
        if find(&mut parent, r) == r {
            counts[runs[r as usize].label as usize] += 1;
        }
    }
    counts
}

fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let up = parent[parent[x as usize] as usize];
        parent[x as usize] = up;
        x = up;
    }
    x
}

fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra.max(rb) as usize] = ra.min(rb);
    }
}
