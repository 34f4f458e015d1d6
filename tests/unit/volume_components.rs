//! Objects per label (run-based union-find) against a plain union-find over every voxel and
//! its 6 or 26 neighbours, on random volumes.

use destair::volume::components::label_components;
use destair::volume::{Grid, LabelVolume, Space};

fn brute_force(volume: &LabelVolume, joins: &[bool]) -> Vec<u64> {
    let [nx, ny, nz] = volume.dims;
    let n = nx * ny * nz;
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    let at = |i: usize, j: usize, k: usize| i + nx * (j + ny * k);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let l = volume.voxels[at(i, j, k)];
                if l == 0 {
                    continue;
                }
                let diagonal = joins.get(l as usize).copied().unwrap_or(true);
                for d in 0..27usize {
                    let o = [d % 3, d / 3 % 3, d / 9].map(|x| x as i64 - 1);
                    let steps = o.iter().filter(|&&x| x != 0).count();
                    if steps == 0 || (steps > 1 && !diagonal) {
                        continue;
                    }
                    let q = [i as i64 + o[0], j as i64 + o[1], k as i64 + o[2]];
                    if q.iter()
                        .zip([nx, ny, nz])
                        .any(|(&x, n)| x < 0 || x >= n as i64)
                    {
                        continue;
                    }
                    let b = at(q[0] as usize, q[1] as usize, q[2] as usize);
                    if volume.voxels[b] == l {
                        let (ra, rb) = (find(&mut parent, at(i, j, k)), find(&mut parent, b));
                        parent[ra.max(rb)] = ra.min(rb);
                    }
                }
            }
        }
    }
    let mut counts = vec![0u64; volume.labels.len() + 1];
    for v in 0..n {
        if volume.voxels[v] != 0 && find(&mut parent, v) == v {
            counts[volume.voxels[v] as usize] += 1;
        }
    }
    counts
}

#[test]
fn objects_match_a_union_find_over_every_voxel() {
    let mut rng = fastrand::Rng::with_seed(62);
    let mut diagonal_only = 0;
    for _ in 0..400 {
        let dims = [rng.usize(1..9), rng.usize(1..9), rng.usize(1..7)];
        let n_labels = rng.i64(1..4);
        let fill = rng.f64();
        let values = (0..dims.iter().product::<usize>()).map(|_| {
            if rng.f64() < fill * 0.6 {
                rng.i64(1..=n_labels)
            } else {
                0
            }
        });
        let volume = LabelVolume::from_values(
            dims,
            Grid::axis_aligned([1.0; 3], [0.0; 3], Space::Lps),
            values,
        )
        .unwrap();
        let joins: Vec<bool> = (0..=volume.labels.len()).map(|_| rng.bool()).collect();
        let fast = label_components(&volume, &joins);
        assert_eq!(fast, brute_force(&volume, &joins), "{dims:?} {joins:?}");
        let faces = label_components(&volume, &[false; 8]);
        let corners = label_components(&volume, &[]);
        diagonal_only += faces.iter().zip(&corners).filter(|(f, c)| f > c).count();
    }
    // The volumes did have objects that only diagonal contacts join.
    assert!(diagonal_only > 100, "{diagonal_only}");
}
