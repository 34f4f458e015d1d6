//! Tests of `src/volume/grid.rs`.

use destair::volume::grid::*;

#[test]
fn oblique_grids_map_indices_and_convert_spaces() {
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let g = Grid {
        matrix: [
            [0.8 * c, -0.8 * s, 0.0],
            [0.8 * s, 0.8 * c, 0.0],
            [0.0, 0.0, 1.5],
        ],
        origin: [10.0, -20.0, 5.0],
        space: Space::Ras,
    };
    g.check().unwrap();
    let sp = g.spacing();
    assert!((sp[0] - 0.8).abs() < 1e-12 && (sp[2] - 1.5).abs() < 1e-12);
    let w = g.world([1.0, 0.0, 2.0]);
    assert!((w[0] - (10.0 + 0.8 * c)).abs() < 1e-12 && (w[2] - 8.0).abs() < 1e-12);
    let lps = g.in_space(Space::Lps);
    let wl = lps.world([1.0, 0.0, 2.0]);
    assert_eq!([wl[0], wl[1], wl[2]], [-w[0], -w[1], w[2]]);
    assert_eq!(lps.in_space(Space::Ras), g);
    assert_eq!(g.stack_axis(), [0.0, 0.0, 1.0]);
    let mut bad = g;
    bad.matrix[2][2] = 0.0;
    assert!(bad.check().unwrap_err().contains("axis 2"));
    let mut singular = g;
    singular.matrix = [[1.0, 1.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
    assert!(singular.check().unwrap_err().contains("singular"));
}
