//! Tests of `src/mesh/umbrella.rs`.

use destair::mesh::order::Renumbering;
use destair::mesh::umbrella::*;

/// A random adjacency: degrees 0-20 (a sixth of them longer than a row), any neighbours.
fn random_csr(n: usize, seed: u64) -> (Vec<u32>, Vec<u32>) {
    let mut rng = fastrand::Rng::with_seed(seed);
    let (mut offsets, mut neighbors) = (vec![0u32], Vec::new());
    for _ in 0..n {
        let degree = if rng.u8(0..6) == 0 {
            rng.usize(WINDOW + 1..=20)
        } else {
            rng.usize(0..=WINDOW)
        };
        neighbors.extend((0..degree).map(|_| rng.u32(0..n as u32)));
        offsets.push(neighbors.len() as u32);
    }
    (offsets, neighbors)
}

fn random_values(n: usize, rng: &mut fastrand::Rng) -> Vec<[f32; 3]> {
    (0..n)
        .map(|_| std::array::from_fn(|_| (rng.f32() - 0.5) * 200.0))
        .collect()
}

/// The old numbering's list of new vertex i, renamed.
fn renamed_list(
    (offsets, neighbors): (&[u32], &[u32]),
    r: Option<&Renumbering>,
    i: usize,
) -> Vec<u32> {
    let v = r.map_or(i, |r| r.old[i] as usize);
    neighbors[offsets[v] as usize..offsets[v + 1] as usize]
        .iter()
        .map(|&w| r.map_or(w, |r| r.new[w as usize]))
        .collect()
}

/// Rows give every vertex's mean with the bits of a plain loop over its CSR list, in the
/// mesh's numbering and in a renumbering, short and long lists alike.
#[test]
fn row_means_have_the_bits_of_the_plain_loop() {
    let n = 3000;
    let (offsets, neighbors) = random_csr(n, 1);
    let mut rng = fastrand::Rng::with_seed(2);
    let values = random_values(n, &mut rng);
    let mut old: Vec<u32> = (0..n as u32).collect();
    rng.shuffle(&mut old);
    let mut new = vec![0u32; n];
    for (i, &v) in old.iter().enumerate() {
        new[v as usize] = i as u32;
    }
    let shuffle = Renumbering {
        old,
        new,
        faces: None,
    };
    for r in [None, Some(&shuffle)] {
        let rows = NeighbourLists::new(&offsets, &neighbors, r);
        assert_eq!(rows.len(), n);
        let in_rows: Vec<[f32; 3]> = r.map_or(values.clone(), |r| r.gather(&values));
        let padded_values = padded(&in_rows);
        let (mut long, mut checked) = (0, 0);
        for i in 0..n {
            let list = renamed_list((&offsets, &neighbors), r, i);
            if list.is_empty() {
                continue;
            }
            long += usize::from(list.len() > WINDOW);
            checked += 1;
            let want = neighbour_mean(&in_rows, &list);
            let got = rows.mean(&padded_values, i);
            assert_eq!(
                got.to_array().map(f32::to_bits)[..3],
                want.map(f32::to_bits)
            );
            assert_eq!(got.w, 0.0);
        }
        assert!(long > 300 && checked > 2500, "{long} long of {checked}");
    }
}

/// A pass equals the scalar umbrella step vertex by vertex, bit for bit, with fixed
/// vertices, with and without the node-position clamp; the sentinel stays zero.
#[test]
fn a_pass_has_the_bits_of_the_scalar_step() {
    let n = 2000;
    let (offsets, neighbors) = random_csr(n, 3);
    let mut rng = fastrand::Rng::with_seed(4);
    let original = random_values(n, &mut rng);
    let scale: Vec<f32> = (0..n)
        .map(|v| {
            if offsets[v] == offsets[v + 1] || rng.u8(0..5) == 0 {
                0.0
            } else {
                rng.f32()
            }
        })
        .collect();
    let rows = NeighbourLists::new(&offsets, &neighbors, None);
    for clamp in [None, Some([0.7f32, 0.9, 2.1])] {
        let src = padded(&original);
        let mut dst = copied(&src);
        umbrella_pass(
            &src,
            &mut dst,
            &rows,
            &scale,
            0.5,
            clamp.map(|v| (&original[..], v)),
        );
        assert_eq!(dst[n], Padded::ZERO);
        let got = unpadded(&dst);
        for v in 0..n {
            let (p, s) = (original[v], 0.5 * scale[v]);
            let want = if s == 0.0 {
                p
            } else {
                let list = &neighbors[offsets[v] as usize..offsets[v + 1] as usize];
                let m = neighbour_mean(&original, list);
                std::array::from_fn(|k| {
                    let r = p[k] + s * (m[k] - p[k]);
                    match clamp {
                        Some(voxel) => {
                            let h = 0.5 * voxel[k];
                            p[k] + (r - p[k]).clamp(-h, h)
                        }
                        None => r,
                    }
                })
            };
            assert_eq!(
                got[v].map(f32::to_bits),
                want.map(f32::to_bits),
                "vertex {v}"
            );
        }
    }
}
