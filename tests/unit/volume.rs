//! Tests of `src/volume/mod.rs`.

use destair::volume::grid::{Grid, Space};
use destair::volume::*;

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
fn the_table_path_matches_the_general_one_for_every_type_and_layout() {
    let mut rng = fastrand::Rng::with_seed(1);
    let g = Grid::axis_aligned([1.0; 3], [0.0; 3], Space::Lps);
    for t in [
        VoxelType::U8,
        VoxelType::I8,
        VoxelType::U16,
        VoxelType::I16,
        VoxelType::U32,
        VoxelType::I32,
    ] {
        for big in [false, true] {
            for stride in [1usize, 3] {
                let dims = [rng.usize(1..40), rng.usize(1..40), rng.usize(1..5)];
                let n: usize = dims.iter().product();
                let bytes: Vec<u8> = (0..n * stride * t.size())
                    .map(|_| if rng.bool() { 0 } else { rng.u8(..) & 0x83 })
                    .collect();
                for first in 0..stride {
                    let fast = LabelVolume::from_raw(
                        dims,
                        g,
                        &bytes,
                        t,
                        big,
                        (first, stride),
                        None,
                        u16::MAX as usize,
                    )
                    .unwrap();
                    let values = t.values(&bytes, big).skip(first).step_by(stride).take(n);
                    let slow = LabelVolume::from_values(dims, g, values).unwrap();
                    assert_eq!(fast, slow, "{t:?} big {big} stride {stride}");
                }
            }
        }
    }
}

#[test]
fn gzip_streams_must_hold_exactly_what_the_header_says() {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(&[7u8; 1000]).unwrap();
    let gz = e.finish().unwrap();
    let whole = |skip, n| gunzip_overlapped(&gz, skip, n, |_| {});
    assert_eq!(whole(0, 1000).unwrap(), vec![7u8; 1000]);
    assert_eq!(whole(10, 990).unwrap().len(), 990);
    assert!(whole(0, 1001).unwrap_err().contains("ends after 1000"));
    assert!(whole(1001, 0).unwrap_err().contains("ends after 1000"));
    assert!(whole(0, 999).unwrap_err().contains("more than"));
    for cut in [5, gz.len() / 2, gz.len() - 3] {
        assert!(
            gunzip_overlapped(&gz[..cut], 0, 1000, |_| {}).is_err(),
            "cut {cut}"
        );
    }
    // A claim of 2^40 bytes is refused before anything is allocated.
    assert!(whole(0, 1 << 40).unwrap_err().contains("cannot hold"));
    assert!(whole(u64::MAX, u64::MAX).is_err());
}

#[test]
fn gzip_pieces_arrive_in_order_and_whole() {
    use std::io::Write;
    // Over two 4 MiB pieces, after a 352-byte header as NIfTI has.
    let data: Vec<u8> = (0..9_000_000u32).map(|i| (i / 1000 % 251) as u8).collect();
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(&data).unwrap();
    let gz = e.finish().unwrap();
    let mut seen = Vec::new();
    let mut sizes = Vec::new();
    let out = gunzip_overlapped(&gz, 352, data.len() as u64 - 352, |piece| {
        seen.extend_from_slice(piece);
        sizes.push(piece.len());
    })
    .unwrap();
    assert_eq!(out, &data[352..]);
    assert_eq!(seen, out);
    assert!(sizes.len() >= 3, "{sizes:?}");
    assert!(sizes[..sizes.len() - 1].iter().all(|&s| s % 8 == 0));
    // The histogram fed piece by piece is the one over the whole.
    let mut pieces = KeyHistogram::new(VoxelType::U8, false);
    let mut whole = KeyHistogram::new(VoxelType::U8, false);
    gunzip_overlapped(&gz, 0, data.len() as u64, |piece| pieces.add(piece)).unwrap();
    whole.add(&data);
    assert_eq!(pieces.counts, whole.counts);
    let expect: u64 = data.iter().filter(|&&b| b == 7).count() as u64;
    assert_eq!(whole.counts[7], expect);
}

#[test]
fn near_edge_matches_every_voxel_checked() {
    // Random small volumes of a few labels: the shell walk against a test of every voxel.
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for _ in 0..50 {
        let dims = [
            1 + (next() % 9) as usize,
            1 + (next() % 9) as usize,
            1 + (next() % 9) as usize,
        ];
        let n: usize = dims.iter().product();
        // Mostly background, so that labels inside the volume occur.
        let values: Vec<i64> = (0..n)
            .map(|_| {
                if next() % 5 == 0 {
                    (next() % 4) as i64
                } else {
                    0
                }
            })
            .collect();
        let g = Grid::axis_aligned([1.0; 3], [0.0; 3], Space::Lps);
        let v = LabelVolume::from_values(dims, g, values.into_iter()).unwrap();
        for margin in 0..4 {
            let mut want = vec![false; v.labels.len() + 1];
            for k in 0..dims[2] {
                for j in 0..dims[1] {
                    for i in 0..dims[0] {
                        let near = [i, j, k]
                            .iter()
                            .zip(dims)
                            .any(|(&x, d)| x < margin || x + margin >= d);
                        if near {
                            want[v.at(i, j, k) as usize] = true;
                        }
                    }
                }
            }
            want[0] = false;
            assert_eq!(v.near_edge(margin), want, "{dims:?} margin {margin}");
        }
    }
}
