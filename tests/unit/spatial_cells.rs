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
        let listed = |i: usize, j: usize, k: usize| {
            let c = (k * ny + j) * nx + i;
            cells.offsets[c] < cells.offsets[c + 1]
        };
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
