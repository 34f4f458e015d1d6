//! Context analysis on meshes other tools made (VTK marching cubes and flying edges on numpy
//! label volumes): the shared corpus (`../shared/corpus/`, with what is true of it in its
//! README) and the phantoms of `tests/data/context/` (made by its `make.py`, truth in
//! `truth.json`). The stack axis of a mesh on an axis-aligned grid is the grid's slice axis.

use destair::io::{read_mesh, ReadOptions};
use destair::weights::{context_weights, AxisChoice, AxisSource, ContextParams};
use destair::{Mesh, Topology};
use std::path::{Path, PathBuf};

fn corpus() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!("skipped: the shared corpus is not at {}", dir.display());
        None
    }
}

fn phantoms() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/context")
}

fn read(path: &Path) -> Mesh {
    read_mesh(path, &ReadOptions::default())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .mesh
}

fn analyse(mesh: &Mesh, params: &ContextParams) -> destair::weights::Context {
    context_weights(mesh, &Topology::build(mesh), params, &[])
}

#[test]
fn corpus_neck_stack_axis_is_the_grids_slice_axis_for_all_three() {
    let Some(dir) = corpus() else { return };
    for name in ["tumor", "vein", "trachea"] {
        let ctx = analyse(
            &read(&dir.join(format!("neck/{name}.ply"))),
            &Default::default(),
        );
        // The trachea, a tube along the slice axis, once got y from its in-plane pixel facets.
        assert_eq!(ctx.axis, Some([0.0, 0.0, 1.0]), "{name}");
        assert_eq!(ctx.axis_source, AxisSource::Grid, "{name}");
        let g = ctx.grid_mm.expect("an axis-aligned grid");
        for (k, h) in [0.45, 0.45, 3.0].into_iter().enumerate() {
            assert!(
                (g[k].0 - h).abs() < 1e-5 && g[k].0 == g[k].1,
                "{name}: {g:?}"
            );
        }
        // The estimate is reported beside it, with how far off it is.
        assert!(ctx.estimate_off_deg.is_some(), "{name}");
    }
}

#[derive(serde::Deserialize)]
struct Truth {
    grid_mm: [f64; 3],
    stack_axis: [f32; 3],
    smoothed: Option<usize>,
}

#[test]
fn phantoms_of_other_tools_on_a_grid_take_its_slice_axis() {
    let dir = phantoms();
    let truth: std::collections::BTreeMap<String, Truth> =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    let mut n_on_grid = 0;
    for (name, t) in &truth {
        // Smoothed copies and the distance-field spheres lie on no grid.
        if t.smoothed.is_some_and(|n| n > 0) || name.starts_with("sphere") {
            continue;
        }
        let ctx = analyse(&read(&dir.join(format!("{name}.ply"))), &Default::default());
        let g = ctx.grid_mm.unwrap_or_else(|| panic!("{name}: no grid"));
        for k in 0..3 {
            assert!((g[k].0 - t.grid_mm[k]).abs() < 1e-4, "{name}: {g:?}");
        }
        assert_eq!(ctx.axis, Some(t.stack_axis), "{name}");
        assert_eq!(ctx.axis_source, AxisSource::Grid, "{name}");
        n_on_grid += 1;
    }
    assert!(n_on_grid >= 8, "{n_on_grid} phantoms on a grid");
}

#[test]
fn off_the_grid_the_estimate_is_used_and_says_so() {
    let dir = phantoms();
    // 30 iterations of VTK's Laplace: no grid left, the estimate along z.
    let ctx = analyse(
        &read(&dir.join("cylinder-cuboid-r12-s1.5-l30.ply")),
        &Default::default(),
    );
    assert!(ctx.grid_mm.is_none());
    assert_eq!(ctx.axis_source, AxisSource::Estimated);
    let a = ctx.axis.expect("an axis");
    assert!(a[2].abs() > 0.9999, "{a:?}");
    assert!(ctx.estimate_off_deg.is_none());
}

#[test]
fn a_given_axis_is_used_and_said_to_be_given() {
    let mesh = read(&phantoms().join("tube-along-z.ply"));
    let params = ContextParams {
        axis: AxisChoice::Given([0.0, 2.0, 0.0]),
        ..Default::default()
    };
    let ctx = analyse(&mesh, &params);
    assert_eq!(ctx.axis, Some([0.0, 1.0, 0.0]));
    assert_eq!(ctx.axis_source, AxisSource::Given);
}

#[test]
fn a_known_grid_decides_over_the_mesh() {
    // The same tube with its grid given as isotropic but for y: the given grid's coarse axis.
    let mesh = read(&phantoms().join("tube-along-z.ply"));
    let params = ContextParams {
        grid_mm: Some([0.5, 2.5, 0.5]),
        ..Default::default()
    };
    let ctx = analyse(&mesh, &params);
    assert_eq!(ctx.axis, Some([0.0, 1.0, 0.0]));
    assert_eq!(ctx.axis_source, AxisSource::Grid);
    // Its flat faces say z: 90 degrees off, which the report warns about.
    assert!(
        ctx.estimate_off_deg.is_some_and(|d| d > 89.0),
        "{:?}",
        ctx.estimate_off_deg
    );
    let summary = destair::report::inspect::context_summary(&ctx, mesh.n_vertices());
    assert!(
        summary.warnings.iter().any(|w| w.contains("slice axis")),
        "{:?}",
        summary.warnings
    );
}
