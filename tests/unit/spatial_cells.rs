//! Tests of `src/spatial/cells.rs`.

use destair::spatial::cells::*;

#[test]
fn near_listed_is_any_listed_cell_of_the_block() {
    let mut rng = fastrand::Rng::with_seed(5);
    for n in [1, 7, 60, 500] {
        let triangles: Vec<[[f32; 3]; 3]> = (0..n)
            .map(|_| {
                let c: [f32; 3] = std::array::from_fn(|_| rng.f32() * 30.0);
                std::array::from_fn(|_| std::array::from_fn(|a| c[a] + rng.f32()))
            })
            .collect();
        let cells = TriangleCells::build(&triangles);
        let [nx, ny, nz] = cells.dims;
        let listed = |i: usize, j: usize, k: usize| !cells.list([i, j, k]).is_empty();
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let range = |x: usize, len: usize| x.saturating_sub(1)..=(x + 1).min(len - 1);
                    let any = range(k, nz)
                        .any(|kk| range(j, ny).any(|jj| range(i, nx).any(|ii| listed(ii, jj, kk))));
                    // The middle of the cell.
                    let p: [f32; 3] = std::array::from_fn(|a| {
                        (cells.origin[a] + ([i, j, k][a] as f64 + 0.5) * cells.cell) as f32
                    });
                    assert_eq!(cells.near_listed(p), any, "n {n}, cell {i} {j} {k}");
                }
            }
        }
        // Far outside the grid: never.
        assert!(!cells.near_listed([-1e4, 0.0, 0.0]));
    }
}

/// Each cell's triangles by hand, indexed x + nx (y + ny z): every triangle whose box
/// overlaps the cell, in ascending order.
fn lists_by_hand(cells: &TriangleCells, triangles: &[[[f32; 3]; 3]]) -> Vec<Vec<u32>> {
    let [nx, ny, nz] = cells.dims;
    let cell_of = |x: f32, a: usize| {
        (((x as f64 - cells.origin[a]) / cells.cell).floor().max(0.0) as usize)
            .min(cells.dims[a] - 1)
    };
    let mut want = vec![Vec::new(); nx * ny * nz];
    for (f, t) in triangles.iter().enumerate() {
        let lo: [usize; 3] = std::array::from_fn(|a| cell_of(t[0][a].min(t[1][a]).min(t[2][a]), a));
        let hi: [usize; 3] = std::array::from_fn(|a| cell_of(t[0][a].max(t[1][a]).max(t[2][a]), a));
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    want[(k * ny + j) * nx + i].push(f as u32);
                }
            }
        }
    }
    want
}

/// Every cell lists exactly the triangles whose box overlaps it, in ascending order, for any
/// number of threads (the lists are counted and filled in stretches side by side).
#[test]
fn cells_list_the_overlapping_triangles_in_order_for_any_thread_count() {
    let mut rng = fastrand::Rng::with_seed(11);
    let triangles: Vec<[[f32; 3]; 3]> = (0..70_000)
        .map(|_| {
            let c: [f32; 3] = std::array::from_fn(|_| rng.f32() * 40.0);
            let size = if rng.u8(..10) == 0 { 3.0 } else { 0.5 };
            std::array::from_fn(|_| std::array::from_fn(|a| c[a] + rng.f32() * size))
        })
        .collect();
    let mut first: Option<Vec<Vec<u32>>> = None;
    for threads in [1, 2, 3, 8] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let cells = pool.install(|| TriangleCells::build(&triangles));
        let [nx, ny, nz] = cells.dims;
        let want = lists_by_hand(&cells, &triangles);
        let mut got = Vec::with_capacity(want.len());
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let p: [f32; 3] = std::array::from_fn(|a| {
                        (cells.origin[a] + ([i, j, k][a] as f64 + 0.5) * cells.cell) as f32
                    });
                    let mut list = Vec::new();
                    cells.visit_ring(p, 0, f64::INFINITY, |ids, _| list.extend_from_slice(ids));
                    got.push(list);
                }
            }
        }
        assert!(
            got == want,
            "{threads} threads: lists differ from the boxes'"
        );
        assert!(want.iter().filter(|l| l.len() > 1).count() > 1000);
        match &first {
            None => first = Some(got),
            Some(f) => assert!(*f == got, "{threads} threads"),
        }
    }
}

/// A few huge slivers across the box among many small triangles would overlap nearly every
/// cell of a grid sized by the small ones (tens of millions of pairs here, billions on a
/// large mesh, past `u32`): the grid is made coarser until the pairs are bounded, and every
/// cell still lists exactly the triangles whose box overlaps it.
#[test]
fn huge_slivers_among_small_triangles_keep_the_lists_bounded_and_exact() {
    let mut rng = fastrand::Rng::with_seed(23);
    let mut triangles: Vec<[[f32; 3]; 3]> = (0..20_000)
        .map(|_| {
            let c: [f32; 3] = std::array::from_fn(|_| rng.f32() * 40.0);
            std::array::from_fn(|_| std::array::from_fn(|a| c[a] + rng.f32() * 0.3))
        })
        .collect();
    for k in 0..100 {
        let s = k as f32 * 0.01;
        triangles.push([[s, 0.0, 0.0], [40.0, 40.0 - s, 40.0], [s, 0.1, 40.0]]);
    }
    let cells = TriangleCells::build(&triangles);
    let [nx, ny, nz] = cells.dims;
    let want = lists_by_hand(&cells, &triangles);
    let mut pairs = 0;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let list = cells.list([i, j, k]);
                assert_eq!(list, want[(k * ny + j) * nx + i], "cell {i} {j} {k}");
                pairs += list.len();
            }
        }
    }
    // At most 32 pairs a triangle and a little room per stretch (at most 8 stretches).
    assert!(
        pairs <= 32 * triangles.len() + 8 * (1 << 16),
        "{pairs} pairs"
    );
    // Still a grid, not one cell.
    assert!(nx * ny * nz > 1000, "{:?}", cells.dims);
}
