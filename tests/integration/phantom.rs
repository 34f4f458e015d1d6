//! Discrete marching cubes on random and analytic label volumes: closed, consistently oriented
//! 2-manifolds, every vertex at a grid-edge midpoint between the label and the outside.

use destair::analysis::voxel_size;
use destair::mesh::geometry::signed_volume;
use destair::phantom::{extract_surface, BorderEnds, LabelVolume, Shape};
use destair::Topology;

/// Checks that every vertex is the midpoint of a grid edge joining a voxel of `label` and a
/// voxel (or the padding outside the volume) that is not.
fn assert_midpoints(v: &LabelVolume, label: u16, mesh: &destair::Mesh) {
    let inside = |idx: [i64; 3]| {
        (0..3).all(|a| idx[a] >= 0 && (idx[a] as usize) < v.dims[a])
            && v.labels[v.index(idx[0] as usize, idx[1] as usize, idx[2] as usize)] == label
    };
    for p in mesh.positions() {
        let g: [f64; 3] = std::array::from_fn(|a| (p[a] as f64 - v.origin[a]) / v.spacing[a]);
        let half: Vec<usize> = (0..3)
            .filter(|&a| (g[a] - g[a].floor() - 0.5).abs() < 1e-4)
            .collect();
        assert_eq!(half.len(), 1, "vertex {p:?} is not on a grid-edge midpoint");
        let a = half[0];
        let lo: [i64; 3] = std::array::from_fn(|k| {
            if k == a {
                g[k].floor() as i64
            } else {
                g[k].round() as i64
            }
        });
        let mut hi = lo;
        hi[a] += 1;
        assert_ne!(
            inside(lo),
            inside(hi),
            "vertex {p:?} is not between inside and outside"
        );
    }
}

fn random_volume(
    rng: &mut fastrand::Rng,
    dims: [usize; 3],
    density: f64,
    checker: bool,
) -> LabelVolume {
    let mut v = LabelVolume::new(dims, [1.0, 0.7, 2.5], [-3.0, 5.0, 11.0]);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let border = i == 0
                    || j == 0
                    || k == 0
                    || i + 1 == dims[0]
                    || j + 1 == dims[1]
                    || k + 1 == dims[2];
                let on = if checker {
                    (i + j + k) % 2 == 0
                } else {
                    rng.f64() < density
                };
                let idx = v.index(i, j, k);
                v.labels[idx] = if border || !on {
                    0
                } else {
                    1 + (rng.u8(..3) == 0) as u16
                };
            }
        }
    }
    v
}

#[test]
fn random_label_volumes_give_closed_oriented_manifolds() {
    let mut rng = fastrand::Rng::with_seed(2026);
    for round in 0..400 {
        let dims = [rng.usize(3..9), rng.usize(3..9), rng.usize(3..9)];
        let checker = round % 10 == 0;
        let density = rng.f64();
        let v = random_volume(&mut rng, dims, density, checker);
        for label in [1u16, 2] {
            let mesh = extract_surface(&v, label, BorderEnds::Capped);
            let t = Topology::build(&mesh);
            assert!(
                t.is_closed_oriented_manifold(),
                "round {round} label {label}: {:?} {:?} {:?} {:?}",
                t.boundary_loops().len(),
                t.non_manifold_edges().len(),
                t.non_manifold_vertices().len(),
                t.inconsistent_edges().len()
            );
            assert!(t.degenerate_triangles().is_empty() && t.unreferenced_vertices().is_empty());
            assert_midpoints(&v, label, &mesh);
            // Outward orientation: enclosed volume is positive and bounded by the voxel volume.
            let n_vox = v.count(label) as f64 * 1.0 * 0.7 * 2.5;
            let vol = signed_volume(&mesh);
            assert!(
                n_vox == 0.0 && vol == 0.0 || vol > 0.0 && vol <= n_vox + 1e-6,
                "{vol} vs {n_vox}"
            );
        }
    }
}

#[test]
fn labels_touching_the_border_are_capped_or_open() {
    let mut v = LabelVolume::new([6, 6, 5], [1.0, 1.0, 2.0], [0.0; 3]);
    // A column through the whole volume along z: touches the bottom and top.
    for k in 0..5 {
        for (i, j) in [(2, 2), (3, 2), (2, 3), (3, 3)] {
            let idx = v.index(i, j, k);
            v.labels[idx] = 1;
        }
    }
    let capped = extract_surface(&v, 1, BorderEnds::Capped);
    let t = Topology::build(&capped);
    assert!(t.is_closed_oriented_manifold());
    assert_eq!(t.euler_characteristic(), 2);
    assert_midpoints(&v, 1, &capped);
    let open = extract_surface(&v, 1, BorderEnds::Open);
    let t = Topology::build(&open);
    assert_eq!(t.boundary_loops().len(), 2);
    assert!(t.boundary_loops().iter().all(|l| l.closed));
    assert!(t.non_manifold_edges().is_empty() && t.inconsistent_edges().is_empty());
    assert_midpoints(&v, 1, &open);
    // The rims lie on the first and last slice.
    let z: std::collections::BTreeSet<u32> = t
        .boundary_loops()
        .iter()
        .flat_map(|l| &l.vertices)
        .map(|&i| open.positions()[i as usize][2].to_bits())
        .collect();
    assert_eq!(z.len(), 2);
}

#[test]
fn sphere_volume_euler_and_voxel_size() {
    let spacing = [1.0, 1.0, 1.0];
    let mut v = LabelVolume::new([64, 64, 64], spacing, [0.0; 3]);
    v.paint(
        &Shape::Sphere {
            center: [32.0; 3],
            radius: 30.0,
        },
        1,
    );
    let mesh = extract_surface(&v, 1, BorderEnds::Capped);
    let t = Topology::build(&mesh);
    assert!(t.is_closed_oriented_manifold());
    assert_eq!(t.euler_characteristic(), 2);
    assert_eq!(t.n_components(), 1);
    let exact = 4.0 / 3.0 * std::f64::consts::PI * 30f64.powi(3);
    let vol = signed_volume(&mesh);
    assert!((vol - exact).abs() / exact < 0.03, "{vol} vs {exact}");
    let est = voxel_size(&mesh, &t);
    assert_eq!(est.spacing(), Some(spacing), "{est:?}");

    let spacing = [0.45, 0.45, 3.0];
    let mut v = LabelVolume::new([120, 120, 20], spacing, [-20.0, 7.5, 100.0]);
    v.paint(
        &Shape::Ellipsoid {
            center: [7.0, 34.0, 128.0],
            radii: [20.0, 18.0, 24.0],
        },
        1,
    );
    let mesh = extract_surface(&v, 1, BorderEnds::Capped);
    let t = Topology::build(&mesh);
    let got = voxel_size(&mesh, &t).spacing().expect("axis-aligned grid");
    for a in 0..3 {
        assert!((got[a] - spacing[a]).abs() < 1e-4 * spacing[a], "{got:?}");
    }
}

use destair::phantom::{cohort_case, named_case, PhantomOptions};

/// Every vertex has exactly one coordinate on a half-voxel position of the case's grid.
fn assert_on_grid_edges(case: &destair::phantom::PhantomCase) {
    let (s, o) = (case.info.spacing_mm, case.info.origin_mm);
    for (name, mesh) in &case.meshes {
        for p in mesh.positions() {
            let halves = (0..3)
                .filter(|&a| {
                    let g = (p[a] as f64 - o[a]) / s[a];
                    (g - g.floor() - 0.5).abs() < 1e-4
                })
                .count();
            assert_eq!(
                halves, 1,
                "{}/{name}: vertex {p:?} is off the grid edges",
                case.info.name
            );
        }
    }
}

#[test]
fn named_cases_are_closed_manifolds_on_their_grid() {
    for name in destair::phantom::cases::CASE_NAMES {
        let case = named_case(name, &PhantomOptions::default()).unwrap();
        assert_on_grid_edges(&case);
        for (structure, mesh) in &case.meshes {
            let t = Topology::build(mesh);
            assert!(t.is_closed_oriented_manifold(), "{name}/{structure}");
            assert_eq!(t.n_components(), 1, "{name}/{structure}");
            assert_eq!(t.euler_characteristic(), 2, "{name}/{structure}");
            assert!(signed_volume(mesh) > 0.0);
            let got = voxel_size(mesh, &t)
                .spacing()
                .unwrap_or_else(|| panic!("{name}/{structure}"));
            for a in 0..3 {
                assert!(
                    (got[a] - case.info.spacing_mm[a]).abs() < 1e-4,
                    "{name}: {got:?}"
                );
            }
        }
    }
    let iso = named_case(
        "sphere-iso",
        &PhantomOptions {
            seed: 9,
            ..Default::default()
        },
    )
    .unwrap();
    let exact = 4.0 / 3.0 * std::f64::consts::PI * 30f64.powi(3);
    let vol = signed_volume(&iso.meshes[0].1);
    assert!((vol - exact).abs() / exact < 0.02, "{vol}");
    // Paper 000, Fig. 7: the MC sphere of diameter 60 has about 35k triangles and 17k vertices.
    let n = iso.meshes[0].1.n_triangles();
    assert!((30_000..40_000).contains(&n), "{n}");
}

#[test]
fn removing_more_of_the_top_slice_removes_more_voxels() {
    let voxels = |name: &str| {
        named_case(name, &PhantomOptions::default())
            .unwrap()
            .info
            .structures[0]
            .n_voxels
    };
    let counts: Vec<usize> = [
        "sphere-aniso",
        "sphere-aniso-1-16",
        "sphere-aniso-1-8",
        "sphere-aniso-1-4",
        "sphere-aniso-1-2",
        "sphere-aniso-top",
    ]
    .iter()
    .map(|n| voxels(n))
    .collect();
    assert!(counts.windows(2).all(|w| w[0] > w[1]), "{counts:?}");
    // A quarter of the slice is about a quarter of what the whole slice removes.
    let whole = (counts[0] - counts[5]) as f64;
    let quarter = (counts[0] - counts[3]) as f64;
    assert!(
        (quarter / whole - 0.25).abs() < 0.05,
        "{quarter} of {whole}"
    );
}

#[test]
fn rotated_cases_are_not_taken_for_a_grid() {
    for (rx, ry) in [(30.0, 0.0), (0.0, 60.0)] {
        let case = named_case(
            "cap-cylinder",
            &PhantomOptions {
                rotate_x_deg: rx,
                rotate_y_deg: ry,
                ..Default::default()
            },
        )
        .unwrap();
        let mesh = &case.meshes[0].1;
        let t = Topology::build(mesh);
        assert!(t.is_closed_oriented_manifold());
        let est = voxel_size(mesh, &t);
        assert!(est.spacing().is_none() && est.is_irregular(), "{est:?}");
    }
    // A quarter turn keeps the grid axis-aligned: y and z spacings swap.
    let case = named_case(
        "cap-cylinder",
        &PhantomOptions {
            rotate_x_deg: 90.0,
            ..Default::default()
        },
    )
    .unwrap();
    let mesh = &case.meshes[0].1;
    let got = voxel_size(mesh, &Topology::build(mesh)).spacing().unwrap();
    assert!(
        (got[1] - 2.0).abs() < 1e-3 && (got[2] - 1.0).abs() < 1e-3,
        "{got:?}"
    );
}

#[test]
fn aneurysm_ends_are_capped_or_open() {
    let open = named_case(
        "aneurysm",
        &PhantomOptions {
            ends: BorderEnds::Open,
            ..Default::default()
        },
    )
    .unwrap();
    let t = Topology::build(&open.meshes[0].1);
    assert_eq!(t.boundary_loops().len(), 3, "one inlet, two outlets");
    assert!(t.non_manifold_edges().is_empty() && t.inconsistent_edges().is_empty());
}

fn min_vertex_distance(a: &destair::Mesh, b: &destair::Mesh) -> f64 {
    a.positions()
        .iter()
        .flat_map(|p| {
            b.positions().iter().map(move |q| {
                (0..3)
                    .map(|k| (p[k] as f64 - q[k] as f64).powi(2))
                    .sum::<f64>()
            })
        })
        .fold(f64::INFINITY, f64::min)
        .sqrt()
}

#[test]
fn neck_vein_passes_a_few_tenths_of_a_mm_from_the_tumor() {
    let case = named_case("neck", &PhantomOptions::default()).unwrap();
    let names: Vec<&str> = case.meshes.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["tumor", "vein", "trachea"]);
    let (tumor, vein, trachea) = (&case.meshes[0].1, &case.meshes[1].1, &case.meshes[2].1);
    // Vertex-to-vertex distance bounds the surface distance from above.
    let d = min_vertex_distance(tumor, vein);
    assert!(d > 0.1 && d < 0.8, "tumor-vein {d} mm");
    assert!(min_vertex_distance(tumor, trachea) > 3.0);
}

#[test]
fn cohort_cases_are_reproducible_and_varied() {
    let a = cohort_case(3, 11);
    let b = cohort_case(3, 11);
    for ((_, m), (_, n)) in a.meshes.iter().zip(&b.meshes) {
        assert_eq!(m, n);
    }
    let spacings: std::collections::BTreeSet<String> = (0..8)
        .map(|i| format!("{:?}", cohort_case(i, 11).info.spacing_mm))
        .collect();
    assert!(spacings.len() > 1);
    for i in 0..8 {
        let case = cohort_case(i, 5);
        for (name, mesh) in &case.meshes {
            let t = Topology::build(mesh);
            assert!(t.is_closed_oriented_manifold(), "case {i} {name}");
            assert!(mesh.n_triangles() > 500, "case {i} {name}");
        }
    }
}
