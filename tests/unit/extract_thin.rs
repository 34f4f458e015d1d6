//! Tests of `src/extract/thin.rs`.

use destair::extract::thin::*;
use destair::volume::{Grid, LabelVolume};

fn volume(dims: [usize; 3], set: impl Fn(usize, usize, usize) -> bool) -> LabelVolume {
    let mut values = Vec::new();
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                values.push(i64::from(set(x, y, z)));
            }
        }
    }
    LabelVolume::from_values(
        dims,
        Grid::axis_aligned([1.0; 3], [0.0; 3], destair::volume::Space::Lps),
        values.into_iter(),
    )
    .unwrap()
}

/// Every thin voxel of label 1, in scan order.
fn thin_of(v: &LabelVolume) -> Vec<[i64; 3]> {
    let d = v.dims.map(|x| x as i64);
    let mut thin = Vec::new();
    for z in 0..d[2] {
        for y in 0..d[1] {
            for x in 0..d[0] {
                if v.at(x as usize, y as usize, z as usize) == 1 && is_thin(v, 1, [x, y, z]) {
                    thin.push([x, y, z]);
                }
            }
        }
    }
    thin
}

/// Brute force of the same definition, straight from the chapter's steps.
fn brute(v: &LabelVolume) -> Vec<[i64; 3]> {
    let d = v.dims.map(|x| x as i64);
    let set = |p: [i64; 3]| {
        (0..3).all(|a| p[a] >= 0 && p[a] < d[a])
            && v.at(p[0] as usize, p[1] as usize, p[2] as usize) == 1
    };
    let cube = |r: std::ops::RangeInclusive<i64>| {
        let r2 = r.clone();
        let r3 = r.clone();
        r.flat_map(move |x| {
            let r3 = r3.clone();
            r2.clone()
                .flat_map(move |y| r3.clone().map(move |z| [x, y, z]))
        })
        .collect::<Vec<_>>()
    };
    let corner = |c: [i64; 3]| {
        cube(-1..=0)
            .iter()
            .any(|o| set([c[0] + o[0], c[1] + o[1], c[2] + o[2]]))
    };
    let eroded = |c: [i64; 3]| {
        cube(-1..=1)
            .iter()
            .all(|o| corner([c[0] + o[0], c[1] + o[1], c[2] + o[2]]))
    };
    let opened = |c: [i64; 3]| {
        cube(-1..=1)
            .iter()
            .any(|o| eroded([c[0] + o[0], c[1] + o[1], c[2] + o[2]]))
    };
    let mut thin = Vec::new();
    for z in 0..d[2] {
        for y in 0..d[1] {
            for x in 0..d[0] {
                let p = [x, y, z];
                if set(p)
                    && !cube(0..=1)
                        .iter()
                        .all(|o| opened([x + o[0], y + o[1], z + o[2]]))
                {
                    thin.push(p);
                }
            }
        }
    }
    thin
}

#[test]
fn one_voxel_parts_are_thin_and_two_voxel_parts_are_not() {
    // A plate 2 voxels thick with a one-voxel sheet and a one-voxel rod sticking out.
    let v = volume([24, 24, 16], |x, y, z| {
        let plate = (3..=20).contains(&x) && (3..=20).contains(&y) && (3..=4).contains(&z);
        let sheet = (3..=20).contains(&x) && y == 10 && (5..=12).contains(&z);
        let rod = x == 16 && y == 16 && (5..=12).contains(&z);
        plate || sheet || rod
    });
    let thin = thin_of(&v);
    assert!(!thin.contains(&[10, 5, 3]) && !thin.contains(&[10, 5, 4]));
    assert!(thin.contains(&[10, 10, 9]) && thin.contains(&[16, 16, 9]));
}

#[test]
fn local_opening_matches_brute_force() {
    let mut rng = fastrand::Rng::with_seed(11);
    for round in 0..40 {
        let dims = [rng.usize(1..70), rng.usize(1..9), rng.usize(1..9)];
        let density = rng.f64() * 0.8 + 0.1;
        let cells: Vec<bool> = (0..dims.iter().product::<usize>())
            .map(|_| rng.f64() < density)
            .collect();
        let v = volume(dims, |x, y, z| cells[x + dims[0] * (y + dims[1] * z)]);
        if v.labels.is_empty() {
            continue;
        }
        let got = thin_of(&v);
        let mut expected = brute(&v);
        expected.sort_by_key(|p| (p[2], p[1], p[0]));
        assert_eq!(got, expected, "round {round}, dims {dims:?}");
    }
}
