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
fn phantoms_of_other_tools_on_a_turned_grid_take_its_slice_axis() {
    // The phantoms on a grid in 8 random poses, far from the origin: the grid is found turned,
    // with its spacing, and its slice axis is the stack axis. Smoothed ones lie on no grid.
    let dir = phantoms();
    let truth: std::collections::BTreeMap<String, Truth> =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    let poses = rotations(8, 71);
    let mut n_turned = 0;
    for (name, t) in &truth {
        if name.starts_with("sphere") {
            continue;
        }
        let mesh = read(&dir.join(format!("{name}.ply")));
        let smoothed = t.smoothed.is_some_and(|n| n > 0);
        for (i, &r) in poses.iter().enumerate() {
            let ctx = analyse(&placed(&mesh, r, shift(i)), &Default::default());
            let what = format!("{name}, pose {i}");
            if smoothed {
                assert!(ctx.grid_mm.is_none(), "{what}: {:?}", ctx.grid_mm);
                continue;
            }
            let (g, axes) = (ctx.grid_mm, ctx.grid_axes);
            let (g, axes) = g
                .zip(axes)
                .unwrap_or_else(|| panic!("{what}: no turned grid"));
            // Each true grid axis is one of the found axes, with its spacing.
            for k in 0..3 {
                let mut e = [0.0f32; 3];
                e[k] = 1.0;
                let true_axis = turn(r, e);
                let j = (0..3)
                    .find(|&j| off_deg(axes[j].map(|x| x as f32), true_axis) < 0.01)
                    .unwrap_or_else(|| panic!("{what}: axis {k} {true_axis:?} not among {axes:?}"));
                assert!((g[j].0 - t.grid_mm[k]).abs() < 1e-3, "{what}: {g:?}");
            }
            assert_eq!(ctx.axis_source, AxisSource::Grid, "{what}");
            let a = ctx.axis.expect("an axis");
            assert!(off_deg(a, turn(r, t.stack_axis)) < 0.01, "{what}: {a:?}");
            n_turned += 1;
        }
    }
    assert!(n_turned >= 8 * 8, "{n_turned} turned phantoms on a grid");
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

#[test]
fn on_an_isotropic_grid_the_estimate_picks_an_axis_without_a_warning() {
    // The tube turned 30 degrees about x, with an isotropic grid given: the estimate (30
    // degrees from z) only picks the grid axis nearest it, so there is nothing to warn about.
    let (s, c) = 30f64.to_radians().sin_cos();
    let mesh = rotated(
        &read(&phantoms().join("tube-along-z.ply")),
        [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
    );
    let params = ContextParams {
        grid_mm: Some([0.5, 0.5, 0.5]),
        ..Default::default()
    };
    let ctx = analyse(&mesh, &params);
    assert_eq!(ctx.axis_source, AxisSource::EstimateOnGrid);
    assert_eq!(ctx.axis, Some(Z));
    let off = ctx
        .estimate_off_deg
        .expect("the estimate beside the grid axis");
    assert!((off - 30.0).abs() < 0.1, "{off}");
    let summary = destair::report::inspect::context_summary(&ctx, mesh.n_vertices());
    assert!(
        !summary.warnings.iter().any(|w| w.contains("slice axis")),
        "{:?}",
        summary.warnings
    );
}

/// The context analysis with the defaults, tau given when `tau` is.
fn analyse_tau(mesh: &Mesh, tau: Option<f32>) -> destair::weights::Context {
    let mut params = ContextParams::default();
    if let Some(t) = tau {
        params.staircase_params.tau = destair::weights::Tau::Fixed(t);
    }
    analyse(mesh, &params)
}

fn near(a: [f32; 3], b: [f32; 3]) -> bool {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f32>() < 0.0025
}

/// The caps' normals are exactly `want` (each within about 3 degrees of one found, as many).
fn assert_caps(name: &str, ctx: &destair::weights::Context, want: &[[f32; 3]]) {
    let got: Vec<[f32; 3]> = ctx.caps.caps.iter().map(|c| c.normal).collect();
    assert!(
        got.len() == want.len() && want.iter().all(|w| got.iter().any(|g| near(*g, *w))),
        "{name}: caps {got:?}, true {want:?}"
    );
}

const Z: [f32; 3] = [0.0, 0.0, 1.0];
const MINUS_Z: [f32; 3] = [0.0, 0.0, -1.0];

#[test]
fn corpus_caps_only_where_a_structure_was_cut() {
    let Some(dir) = corpus() else { return };
    for (file, caps) in [
        // Its top and bottom slices (67 mm^2) and a 45-degree facet were caps.
        ("neck/tumor.ply", vec![]),
        ("neck/vein.ply", vec![Z, MINUS_Z]),
        ("neck/trachea.ply", vec![Z, MINUS_Z]),
        // 15 lobe tops and bottoms were caps.
        ("blob-ellipsoids/blob.ply", vec![]),
    ] {
        let ctx = analyse_tau(&read(&dir.join(file)), None);
        assert_caps(file, &ctx, &caps);
        for cap in &ctx.caps.caps {
            let e = cap.evidence;
            assert!(e.growth <= 1.3 && e.span <= 2.0, "{file}: {e:?}");
        }
    }
}

/// A mesh turned by `r` (row-major rotation matrix).
fn rotated(mesh: &Mesh, r: [[f64; 3]; 3]) -> Mesh {
    placed(mesh, r, [0.0; 3])
}

/// A mesh turned by `r` (row-major rotation matrix), then moved by `t` (mm).
fn placed(mesh: &Mesh, r: [[f64; 3]; 3], t: [f64; 3]) -> Mesh {
    let mut m = mesh.clone();
    for p in m.positions_mut() {
        let q = p.map(f64::from);
        *p = std::array::from_fn(|i| ((0..3).map(|k| r[i][k] * q[k]).sum::<f64>() + t[i]) as f32);
    }
    m
}

/// Where pose `i` moves a mesh to (mm): up to 300 mm from the origin, as scanner
/// coordinates are.
fn shift(i: usize) -> [f64; 3] {
    let s = [-1.0, 0.5, 1.0, -0.5, 0.25, -1.0, 0.75, 0.0];
    [
        300.0 * s[i % 8],
        -150.0 * s[(i + 3) % 8],
        200.0 * s[(i + 5) % 8],
    ]
}

/// `n` random rotations (the same numbers everywhere: xorshift64* and Box-Muller, rows
/// orthonormalised, the third their cross product).
fn rotations(n: usize, seed: u64) -> Vec<[[f64; 3]; 3]> {
    let mut state = seed;
    let mut gauss = move || {
        let mut uniform = || {
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            ((state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let (u, v) = (uniform(), uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    };
    let unit = |v: [f64; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|x| x / l)
    };
    (0..n)
        .map(|_| {
            let a = unit([gauss(), gauss(), gauss()]);
            let r1 = [gauss(), gauss(), gauss()];
            let d = (0..3).map(|k| r1[k] * a[k]).sum::<f64>();
            let b = unit(std::array::from_fn(|k| r1[k] - d * a[k]));
            let c = [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ];
            [a, b, c]
        })
        .collect()
}

fn turn(r: [[f64; 3]; 3], v: [f32; 3]) -> [f32; 3] {
    std::array::from_fn(|i| (0..3).map(|k| r[i][k] * f64::from(v[k])).sum::<f64>() as f32)
}

#[test]
fn corpus_caps_and_axis_in_eight_random_poses() {
    let Some(dir) = corpus() else { return };
    for (file, tau, caps) in [
        ("neck/vein.ply", None, vec![Z, MINUS_Z]),
        // A tube along the slice axis: its in-plane pixel walls are the largest flat parts.
        ("neck/trachea.ply", None, vec![Z, MINUS_Z]),
        // Off the grid the terraces' spacing tells how deep to look behind a lobe's top.
        ("neck/tumor.ply", None, vec![]),
        ("blob-ellipsoids/blob.ply", None, vec![]),
        // Paper 004 section 4.3 after 50 Laplace iterations by VTK, tau 0.2 as the paper.
        (
            "cylinder-cuboid-50/cylinder_cuboid.ply",
            Some(0.2),
            vec![Z, MINUS_Z, [1.0, 0.0, 0.0]],
        ),
    ] {
        let mesh = read(&dir.join(file));
        assert_caps(file, &analyse_tau(&mesh, tau), &caps);
        let smoothed = file.starts_with("cylinder-cuboid-50");
        for (i, r) in rotations(8, 61).into_iter().enumerate() {
            let ctx = analyse_tau(&placed(&mesh, r, shift(i)), tau);
            let want: Vec<[f32; 3]> = caps.iter().map(|&c| turn(r, c)).collect();
            assert_caps(&format!("{file}, pose {i}"), &ctx, &want);
            // The turned grid's slice axis; the estimate where smoothing left no grid.
            let source = if smoothed {
                AxisSource::Estimated
            } else {
                AxisSource::Grid
            };
            assert_eq!(ctx.axis_source, source, "{file}, pose {i}");
            let (a, t) = (ctx.axis.expect("an axis"), turn(r, Z));
            assert!(
                off_deg(a, t) < 0.2,
                "{file}, pose {i}: axis {a:?}, true {t:?}"
            );
        }
    }
}

#[derive(serde::Deserialize)]
struct CapTruth {
    caps: Option<Vec<[f32; 3]>>,
    tau: Option<f32>,
}

/// The phantoms of `tests/data/context` with caps stated in `truth.json`: blobs of other
/// seeds and grids (one with dents at its inner corners), tubes along and across the slice
/// axis (ends three slices tall), the paper's cylinder with other radii, slices and smoothing.
const CAP_PHANTOMS: [&str; 13] = [
    "blob-s7",
    "blob-s11",
    "blob-s30",
    "cylinder-cuboid-r12-s1.5-l30",
    "cylinder-cuboid-r15-s2-l0",
    "cylinder-cuboid-r18-s2.4-l20",
    "cylinder-cuboid-r18-s2.4-l40",
    "cylinder-cuboid-r24-s3-l50",
    "tube-along-x",
    "tube-along-y",
    "tube-along-z",
    "tube-along-z-thin",
    "tube-along-z-diamond",
];

fn cap_truth() -> std::collections::BTreeMap<String, CapTruth> {
    serde_json::from_str(&std::fs::read_to_string(phantoms().join("truth.json")).unwrap()).unwrap()
}

#[test]
fn phantoms_of_other_tools_caps_at_cut_ends_and_nowhere_else() {
    let truth = cap_truth();
    for name in CAP_PHANTOMS {
        let t = &truth[name];
        let ctx = analyse_tau(&read(&phantoms().join(format!("{name}.ply"))), t.tau);
        assert_caps(name, &ctx, t.caps.as_deref().unwrap_or(&[]));
    }
}

#[test]
fn phantoms_of_other_tools_caps_in_four_random_poses() {
    // Rotated and moved up to 300 mm: nothing of the answer may depend on the pose.
    let truth = cap_truth();
    let poses = rotations(4, 67);
    for name in CAP_PHANTOMS {
        let t = &truth[name];
        let mesh = read(&phantoms().join(format!("{name}.ply")));
        let caps = t.caps.as_deref().unwrap_or(&[]);
        for (i, &r) in poses.iter().enumerate() {
            let ctx = analyse_tau(&placed(&mesh, r, shift(i + 3)), t.tau);
            let want: Vec<[f32; 3]> = caps.iter().map(|&c| turn(r, c)).collect();
            assert_caps(&format!("{name}, pose {i}"), &ctx, &want);
        }
    }
}

/// Angle (degrees) between an axis line and a direction (from the sine too: precise at
/// small angles).
fn off_deg(a: [f32; 3], t: [f32; 3]) -> f64 {
    let (a, t) = (a.map(f64::from), t.map(f64::from));
    let cos = (0..3).map(|k| a[k] * t[k]).sum::<f64>().abs();
    let sin = [
        a[1] * t[2] - a[2] * t[1],
        a[2] * t[0] - a[0] * t[2],
        a[0] * t[1] - a[1] * t[0],
    ]
    .iter()
    .map(|x| x * x)
    .sum::<f64>()
    .sqrt();
    sin.atan2(cos).to_degrees()
}

/// The stack axis of `mesh` turned by each pose: `Some(degrees off the turned z)` or `None`
/// when too weak.
fn axis_errors(mesh: &Mesh, poses: &[[[f64; 3]; 3]]) -> Vec<Option<f64>> {
    poses
        .iter()
        .map(|&r| {
            let ctx = analyse(&rotated(mesh, r), &Default::default());
            match ctx.axis {
                Some(a) => Some(off_deg(a, turn(r, Z))),
                None => {
                    assert_eq!(ctx.axis_source, AxisSource::TooWeak);
                    None
                }
            }
        })
        .collect()
}

#[test]
fn weak_axes_from_one_small_flat_area_in_eight_random_poses() {
    // Paper 004 Table 5's protocol: spheres from distance fields (nothing flat) with 1/8 and
    // 1/4 of the top slice cut off flat; the paper estimates them within 1.6 degrees. Before
    // the second look, 1/8 was too weak: its border faces, flat but next to the cut's rim,
    // failed the flat-vertex test (0.11 % of the area left of 0.49 %).
    let mut poses = vec![[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]];
    poses.extend(rotations(8, 63));
    for name in ["sphere-cut-eighth", "sphere-cut-quarter"] {
        let mesh = read(&phantoms().join(format!("{name}.ply")));
        let errors = axis_errors(&mesh, &poses);
        assert!(
            errors.iter().all(|e| e.is_some_and(|d| d <= 1.6)),
            "{name}: {errors:?}"
        );
    }
    let ctx = analyse(
        &read(&phantoms().join("sphere-cut-eighth.ply")),
        &Default::default(),
    );
    let summary = destair::report::inspect::context_summary(&ctx, 0);
    assert_eq!(
        summary.axis_evidence,
        Some(destair::analysis::AxisEvidence::SmallFlatArea)
    );
    assert_eq!(summary.axis_source, "estimated");
}

#[test]
fn off_the_grid_a_tube_along_the_slices_is_never_wrong_without_a_warning() {
    // Smoothed at export (VTK windowed sinc, 5 and 10 iterations), a tube along the slice axis
    // lies on no grid, and its long flat walls (facing x, y and the diagonals, all 90 degrees
    // from the slice axis) outweigh its end discs: the Gauss map names a wall. The answer
    // must then say that another direction comes close, or decline; never wrong and sure.
    let mut poses = vec![[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]];
    poses.extend(rotations(8, 73));
    let mut n_warned = 0;
    for name in ["tube-along-z-sinc5", "tube-along-z-sinc10"] {
        let mesh = read(&phantoms().join(format!("{name}.ply")));
        for (i, &r) in poses.iter().enumerate() {
            let m = placed(&mesh, r, shift(i));
            let ctx = analyse(&m, &Default::default());
            assert!(ctx.grid_mm.is_none(), "{name}, pose {i}: on a grid");
            let Some(a) = ctx.axis else { continue };
            if off_deg(a, turn(r, Z)) < 1.0 {
                continue;
            }
            let summary = destair::report::inspect::context_summary(&ctx, m.n_vertices());
            assert!(
                summary
                    .warnings
                    .iter()
                    .any(|w| w.contains("running along the slices")),
                "{name}, pose {i}: axis {a:?}, {:.1} degrees off, without a warning: {:?}",
                off_deg(a, turn(r, Z)),
                summary.warnings
            );
            n_warned += 1;
        }
    }
    // The case the warning is for occurs (else this test would test nothing).
    assert!(n_warned > 0);
}

#[test]
fn never_a_wrong_axis_where_the_evidence_is_weak() {
    // Too weak or right (within 2 degrees), in any pose: 1/16 of a slice cut flat (the paper
    // fails there too, 10 degrees off); removals that slope down to the slice below (no flat
    // area at all); binary surfaces smoothed until their terraces are rounded off, which keep
    // planar oblique facets of 0.3-1 % of their area: VTK's Laplace on a blob (one facet 71
    // degrees off z, alone in its direction, told from a cut only by its bent normals) and
    // destair's on the neck tumour of the corpus (facets in mirror pairs 34-48 degrees off z).
    let poses = rotations(8, 67);
    let mut meshes: Vec<(String, Mesh)> = [
        "sphere-cut-sixteenth",
        "sphere-eighth",
        "sphere-quarter",
        "blob-s4-l80",
    ]
    .iter()
    .map(|n| (n.to_string(), read(&phantoms().join(format!("{n}.ply")))))
    .collect();
    if let Some(dir) = corpus() {
        let tumour = read(&dir.join("neck/tumor.ply"));
        let t = Topology::build(&tumour);
        for iterations in [10, 20, 50] {
            let w = destair::weights::VertexWeights::uniform(tumour.n_vertices());
            let method = destair::smooth::Method::Laplace { lambda: 0.5 };
            let fixed = destair::smooth::boundary_vertices(&t);
            let (p, _) = destair::smooth::smooth(&tumour, &t, &method, iterations, &w, &fixed);
            let mut m = tumour.clone();
            m.positions_mut().copy_from_slice(&p);
            meshes.push((
                format!("neck tumour after {iterations} Laplace iterations"),
                m,
            ));
        }
    }
    for (name, mesh) in &meshes {
        let errors = axis_errors(mesh, &poses);
        assert!(
            errors.iter().all(|e| e.is_none_or(|d| d <= 2.0)),
            "{name}: {errors:?}"
        );
    }
}

#[derive(serde::Deserialize)]
struct VesselTruth {
    radius_mm: f64,
    direction: [f64; 3],
    centre_mm: [f64; 3],
    length_mm: f64,
}

/// Mean distance (mm) of the vertices of a straight vessel's middle (its cut ends left out)
/// from its true wall.
fn lumen_error(mesh: &Mesh, t: &VesselTruth) -> f64 {
    let mut sum = 0.0;
    let mut n = 0;
    for p in mesh.positions() {
        let q: [f64; 3] = std::array::from_fn(|k| f64::from(p[k]) - t.centre_mm[k]);
        let along = (0..3).map(|k| q[k] * t.direction[k]).sum::<f64>();
        if along.abs() > t.length_mm / 2.0 - 3.0 * t.radius_mm {
            continue;
        }
        let across = (0..3)
            .map(|k| (q[k] - along * t.direction[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        sum += (across - t.radius_mm).abs();
        n += 1;
    }
    sum / n as f64
}

#[test]
fn vessels_lying_in_the_slice_plane_have_staircases_that_get_smoothed() {
    // VTK marching cubes on 0.4 x 0.4 x 0.8 mm: a one-slice step changes the orientation by
    // 0.553 there, below the paper's 0.7, so no staircase was found on any of these vessels and
    // only the weight floor smoothed them. Context-aware HC (20 iterations) must take the
    // terraces down about as far as HC unweighted does.
    use destair::smooth::{boundary_vertices, smooth, MethodKind, MethodParams};
    use destair::weights::VertexWeights;
    let dir = phantoms();
    let truth: std::collections::BTreeMap<String, VesselTruth> =
        serde_json::from_str::<std::collections::BTreeMap<String, serde_json::Value>>(
            &std::fs::read_to_string(dir.join("truth.json")).unwrap(),
        )
        .unwrap()
        .into_iter()
        .filter(|(name, _)| name.starts_with("vessel-"))
        .map(|(name, v)| (name, serde_json::from_value(v).unwrap()))
        .collect();
    assert_eq!(truth.len(), 3);
    let hc = MethodKind::Hc.build(&MethodParams::default(), [0.4, 0.4, 0.8]);
    for (name, t) in &truth {
        let mesh = read(&dir.join(format!("{name}.ply")));
        let topology = Topology::build(&mesh);
        let ctx = analyse(&mesh, &Default::default());
        let st = ctx.staircase.as_ref().expect("staircase weights");
        let share = st.n_staircase() as f64 / mesh.n_vertices() as f64;
        assert!(
            share > 0.1,
            "{name}: {:.1} % staircase vertices",
            100.0 * share
        );
        let fixed = boundary_vertices(&topology);
        let smoothed = |w: &VertexWeights| {
            let (p, _) = smooth(&mesh, &topology, &hc, 20, w, &fixed);
            let mut m = mesh.clone();
            m.positions_mut().copy_from_slice(&p);
            lumen_error(&m, t)
        };
        let before = lumen_error(&mesh, t);
        let aware = smoothed(&ctx.weights);
        let uniform = smoothed(&VertexWeights::uniform(mesh.n_vertices()));
        eprintln!(
            "{name}: {:.1} % staircase vertices (tau {:.3}); mean distance to the true lumen {before:.3} mm, context-aware HC {aware:.3}, uniform HC {uniform:.3}",
            100.0 * share,
            st.tau
        );
        assert!(
            before - aware >= 0.7 * (before - uniform) && aware < 0.85 * before,
            "{name}: {before:.3} -> {aware:.3} (uniform {uniform:.3})"
        );
    }
}
