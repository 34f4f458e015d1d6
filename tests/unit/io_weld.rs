//! Tests of `src/io/weld.rs`.

use destair::io::weld::*;
use rustc_hash::FxHashMap;

/// The sequential reference: one hash map over all corners in file order.
fn weld_sequential(corners: &[[f32; 3]]) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut index: FxHashMap<[u32; 3], u32> = FxHashMap::default();
    let mut positions = Vec::new();
    let numbers = corners
        .iter()
        .map(|&p| {
            *index.entry(Key::of(p).0).or_insert_with(|| {
                positions.push(p);
                positions.len() as u32 - 1
            })
        })
        .collect();
    (positions, numbers)
}

/// Welds corners given as a flat list (a multiple of three).
fn weld(corners: &[[f32; 3]]) -> Result<(Vec<[f32; 3]>, Vec<u32>), usize> {
    let (p, t) = weld_triangles(corners.len() / 3, |c| corners[c])?;
    Ok((p, t.into_iter().flatten().collect()))
}

#[test]
fn parallel_welding_matches_the_sequential_pass_on_random_soups() {
    let mut rng = fastrand::Rng::with_seed(11);
    for round in 0..40 {
        // From a handful to a few hundred thousand corners (several chunks), drawn from a
        // small pool so most repeat; some coordinates are -0. Odd rounds draw from a
        // window that slides along the pool, as files list neighbouring triangles
        // together, so chunks weld most of their corners locally.
        let n = [0, 3, 6, 21, 1002, 70_002, 250_002][round % 7];
        let pool: Vec<[f32; 3]> = (0..(n / 5).max(1))
            .map(|_| {
                std::array::from_fn(|_| match rng.u8(..10) {
                    0 => 0.0,
                    1 => -0.0,
                    _ => rng.f32() * 100.0 - 50.0,
                })
            })
            .collect();
        let corners: Vec<[f32; 3]> = (0..n)
            .map(|c| {
                let i = if round % 2 == 1 {
                    (c / 5 + rng.usize(..50)).min(pool.len() - 1)
                } else {
                    rng.usize(..pool.len())
                };
                pool[i]
            })
            .collect();
        let (p, v) = weld(&corners).unwrap();
        let (q, w) = weld_sequential(&corners);
        assert_eq!(v, w, "round {round}: vertex numbers");
        assert_eq!(
            p.iter().map(|x| Key::of(*x).0).collect::<Vec<_>>(),
            q.iter().map(|x| Key::of(*x).0).collect::<Vec<_>>(),
            "round {round}: positions"
        );
    }
}

#[test]
fn the_first_non_finite_corner_is_named() {
    let mut rng = fastrand::Rng::with_seed(3);
    let clean: Vec<[f32; 3]> = (0..200_001)
        .map(|_| std::array::from_fn(|_| rng.u8(..30) as f32))
        .collect();
    assert!(weld(&clean).is_ok());
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        for _ in 0..6 {
            // One to three bad corners, anywhere (often in different chunks).
            let mut corners = clean.clone();
            let at: Vec<usize> = (0..rng.usize(1..4))
                .map(|_| rng.usize(..corners.len()))
                .collect();
            for &c in &at {
                corners[c][rng.usize(..3)] = bad;
            }
            assert_eq!(weld(&corners), Err(*at.iter().min().unwrap()));
        }
    }
}

#[test]
fn welding_does_not_depend_on_the_thread_count() {
    let mut rng = fastrand::Rng::with_seed(5);
    let corners: Vec<[f32; 3]> = (0..200_001)
        .map(|_| std::array::from_fn(|_| rng.u8(..20) as f32))
        .collect();
    let [one, three] = [1, 3].map(|threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| weld(&corners))
    });
    assert_eq!(one, three);
}
