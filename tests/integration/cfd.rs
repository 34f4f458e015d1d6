//! Boundary patches of vessel surfaces (the cfd profile): found, measured and ordered the same
//! way on reruns and rotations, with the inlet chosen as asked; surfaces that are not one
//! 2-manifold vessel refused with the reason.

use crate::common;

use common::{aneurysm, open_box};
use destair::cfd::{
    close_open_ends, find_patches, CloseError, Inlet, PatchError, PatchKind, Patches, WALL_ID,
};
use destair::phantom::marching_cubes::BorderEnds;
use destair::phantom::volume::{apply, rotation_matrix};
use destair::phantom::{named_case, PhantomOptions};
use destair::{Mesh, Topology};

fn patches_of(mesh: &Mesh, inlet: Inlet) -> Result<Patches, PatchError> {
    find_patches(mesh, &Topology::build(mesh), inlet, None)
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d: f64 = (0..3).map(|k| a[k] * b[k]).sum();
    d.clamp(-1.0, 1.0).acos().to_degrees()
}

#[test]
fn an_open_square_is_measured_as_computed_by_hand() {
    let m = open_box();
    let found = patches_of(&m, Inlet::Largest).unwrap();
    assert_eq!(found.patches.len(), 1);
    let p = &found.patches[0];
    assert_eq!(
        (p.id, p.name.as_str(), p.kind),
        (2, "inlet", PatchKind::OpenEnd)
    );
    assert!((p.area_mm2 - 1.0).abs() < 1e-12, "{}", p.area_mm2);
    assert!(
        distance(p.centre_mm, [0.5, 0.5, 1.0]) < 1e-12,
        "{:?}",
        p.centre_mm
    );
    // Out of the fluid: up, where the missing top face would point.
    assert!(
        distance(p.normal, [0.0, 0.0, 1.0]) < 1e-12,
        "{:?}",
        p.normal
    );
    assert!((p.diameter_mm - (4.0 / std::f64::consts::PI).sqrt()).abs() < 1e-12);
    assert_eq!(p.planarity_mm, 0.0);
    assert_eq!(p.vertices.len(), 4);
    assert_eq!(found.wall_faces, 10);
    assert!(found.face_ids.iter().all(|&id| id == WALL_ID));

    // Inside out, the fluid is still below the opening.
    let (positions, triangles) = m.into_parts();
    let flipped = Mesh::new(
        positions,
        triangles.iter().map(|t| [t[0], t[2], t[1]]).collect(),
    )
    .unwrap();
    let p = &patches_of(&flipped, Inlet::Largest).unwrap().patches[0];
    assert!(
        distance(p.normal, [0.0, 0.0, 1.0]) < 1e-12,
        "{:?}",
        p.normal
    );
}

#[test]
fn the_capped_aneurysm_has_an_inlet_and_two_outlets() {
    let m = aneurysm(BorderEnds::Capped, 0.0, 0.0);
    let found = patches_of(&m, Inlet::Largest).unwrap();
    let names: Vec<&str> = found.patches.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["inlet", "outlet_1", "outlet_2"]);
    let ids: Vec<u32> = found.patches.iter().map(|p| p.id).collect();
    assert_eq!(ids, [2, 3, 4]);
    for p in &found.patches {
        assert_eq!(p.kind, PatchKind::Cap);
        // Marching-cubes caps lie on one plane half a voxel outside the volume.
        assert!(p.planarity_mm < 1e-4, "{p:?}");
        let faces = found.face_ids.iter().filter(|&&id| id == p.id).count();
        assert_eq!(faces, p.faces.len());
    }
    // The inlet is the largest cap, at the bottom (normal -z); the outlets at the top.
    let inlet = &found.patches[0];
    assert!(inlet.area_mm2 > found.patches[1].area_mm2);
    assert!(found.patches[1].area_mm2 >= found.patches[2].area_mm2);
    assert!(
        angle_deg(inlet.normal, [0.0, 0.0, -1.0]) < 1e-3,
        "{inlet:?}"
    );
    for outlet in &found.patches[1..] {
        assert!(
            angle_deg(outlet.normal, [0.0, 0.0, 1.0]) < 1e-3,
            "{outlet:?}"
        );
    }
    let cap_faces: usize = found.patches.iter().map(|p| p.faces.len()).sum();
    assert_eq!(found.wall_faces + cap_faces, m.n_triangles());
    // Reruns give the same patches.
    assert_eq!(patches_of(&m, Inlet::Largest).unwrap(), found);
}

#[test]
fn open_ends_match_the_caps_they_replace() {
    let capped = patches_of(&aneurysm(BorderEnds::Capped, 0.0, 0.0), Inlet::Largest).unwrap();
    let open_mesh = aneurysm(BorderEnds::Open, 0.0, 0.0);
    let open = patches_of(&open_mesh, Inlet::Largest).unwrap();
    assert_eq!(open.patches.len(), 3);
    for (c, o) in capped.patches.iter().zip(&open.patches) {
        assert_eq!(o.kind, PatchKind::OpenEnd);
        assert_eq!(c.name, o.name);
        // The loop lies half a voxel (0.2 mm) inside the cap's plane, around the same centre.
        assert!(angle_deg(c.normal, o.normal) < 1e-3, "{c:?} {o:?}");
        assert!(o.planarity_mm < 1e-4, "{o:?}");
        // The rim lies in a plane z = const: its area by the shoelace formula in x, y.
        let p = open_mesh.positions();
        let rim: Vec<[f64; 2]> = o
            .vertices
            .iter()
            .map(|&v| [p[v as usize][0] as f64, p[v as usize][1] as f64])
            .collect();
        let shoelace: f64 = (0..rim.len())
            .map(|i| {
                let (a, b) = (rim[i], rim[(i + 1) % rim.len()]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum::<f64>()
            .abs()
            / 2.0;
        assert!((o.area_mm2 - shoelace).abs() < 1e-6, "{o:?} {shoelace}");

        let lateral = distance(
            [c.centre_mm[0], c.centre_mm[1], 0.0],
            [o.centre_mm[0], o.centre_mm[1], 0.0],
        );
        assert!(lateral < 0.1, "{c:?} {o:?}");
    }
    assert!(open.face_ids.iter().all(|&id| id == WALL_ID));
}

#[test]
fn patches_follow_the_vessel_when_it_is_rotated() {
    for ends in [BorderEnds::Capped, BorderEnds::Open] {
        let base = patches_of(&aneurysm(ends, 0.0, 0.0), Inlet::Largest).unwrap();
        for (rx, ry) in [(30.0, 0.0), (0.0, 45.0), (60.0, 30.0), (90.0, 90.0)] {
            let turned = patches_of(&aneurysm(ends, rx, ry), Inlet::Largest)
                .unwrap_or_else(|e| panic!("{ends:?} {rx} {ry}: {e}"));
            assert_eq!(
                turned.patches.len(),
                base.patches.len(),
                "{ends:?} {rx} {ry}"
            );
            let r = rotation_matrix([rx, ry, 0.0]);
            for (b, t) in base.patches.iter().zip(&turned.patches) {
                assert_eq!((b.id, &b.name, b.kind), (t.id, &t.name, t.kind));
                assert!((b.area_mm2 / t.area_mm2 - 1.0).abs() < 1e-3, "{b:?} {t:?}");
                assert!(
                    angle_deg(apply(&r, b.normal), t.normal) < 0.01,
                    "{ends:?} {rx} {ry}: {b:?} {t:?}"
                );
            }
            // Distances between patch centres do not depend on the rotation's centre.
            for i in 0..base.patches.len() {
                for j in 0..i {
                    let d = |p: &Patches| distance(p.patches[i].centre_mm, p.patches[j].centre_mm);
                    assert!((d(&base) - d(&turned)).abs() < 1e-3, "{ends:?} {rx} {ry}");
                }
            }
        }
    }
}

#[test]
fn the_inlet_is_the_patch_the_config_names() {
    let m = aneurysm(BorderEnds::Capped, 0.0, 0.0);
    let by_area = patches_of(&m, Inlet::Largest).unwrap();
    let second = by_area.patches[1].clone();
    let third = by_area.patches[2].clone();
    let by_index = patches_of(&m, Inlet::Index(1)).unwrap();
    assert_eq!(by_index.patches[0].name, "inlet");
    assert_eq!(by_index.patches[0].area_mm2, second.area_mm2);
    assert_eq!(by_index.patches[1].area_mm2, by_area.patches[0].area_mm2);
    let near = [
        third.centre_mm[0] + 0.3,
        third.centre_mm[1] - 0.2,
        third.centre_mm[2] + 1.0,
    ];
    let by_point = patches_of(&m, Inlet::Point(near)).unwrap();
    assert_eq!(by_point.patches[0].centre_mm, third.centre_mm);
    assert_eq!(by_point.patches[0].id, 2);
    // Cap faces carry the id of the patch they now are.
    let faces = by_point.face_ids.iter().filter(|&&id| id == 2).count();
    assert_eq!(faces, third.faces.len());
    assert_eq!(
        patches_of(&m, Inlet::Index(3)).unwrap_err(),
        PatchError::InletIndex { index: 3, n: 3 }
    );
}

#[test]
fn a_count_other_than_expected_fails_with_both_numbers() {
    let m = aneurysm(BorderEnds::Capped, 0.0, 0.0);
    let t = Topology::build(&m);
    assert!(find_patches(&m, &t, Inlet::Largest, Some(3)).is_ok());
    let e = find_patches(&m, &t, Inlet::Largest, Some(4)).unwrap_err();
    assert_eq!(
        e,
        PatchError::Count {
            found: 3,
            expected: 4
        }
    );
    assert_eq!(
        e.to_string(),
        "3 patches found, 4 expected (expect_patches)"
    );
}

#[test]
fn surfaces_that_are_not_one_vessel_are_refused() {
    // Two vessels in one file.
    let m = open_box();
    let (mut p, mut t) = m.into_parts();
    let n = p.len() as u32;
    p.extend(p.clone().iter().map(|q| [q[0] + 5.0, q[1], q[2]]));
    t.extend(t.clone().iter().map(|f| f.map(|v| v + n)));
    let two = Mesh::new(p, t).unwrap();
    assert_eq!(
        patches_of(&two, Inlet::Largest).unwrap_err(),
        PatchError::Components(2)
    );

    // A third face on an edge.
    let (mut p, mut t) = open_box().into_parts();
    p.push([0.5, -1.0, 0.5]);
    t.push([0, 1, 8]);
    let fin = Mesh::new(p, t).unwrap();
    assert!(matches!(
        patches_of(&fin, Inlet::Largest).unwrap_err(),
        PatchError::NonManifoldEdges(_)
    ));

    // One face turned against its neighbours.
    let (p, mut t) = open_box().into_parts();
    t[0] = [t[0][0], t[0][2], t[0][1]];
    let turned = Mesh::new(p, t).unwrap();
    assert!(matches!(
        patches_of(&turned, Inlet::Largest).unwrap_err(),
        PatchError::Inconsistent(_)
    ));

    // A closed round surface has no end.
    let blob = named_case("sphere-iso", &PhantomOptions::default()).unwrap();
    let e = patches_of(&blob.meshes[0].1, Inlet::Largest).unwrap_err();
    assert_eq!(e, PatchError::NoEnds);
    assert!(e.to_string().contains("no caps and no open ends"));
}

/// Largest distance of a patch's vertices from the plane through its centre (mm), measured
/// on the f32 positions as written.
fn off_plane(mesh: &Mesh, p: &destair::cfd::Patch) -> f64 {
    let q = mesh.positions();
    p.vertices
        .iter()
        .map(|&v| {
            (0..3)
                .map(|k| (q[v as usize][k] as f64 - p.centre_mm[k]) * p.normal[k])
                .sum::<f64>()
                .abs()
        })
        .fold(0.0, f64::max)
}

#[test]
fn open_ends_close_into_flat_caps_and_a_closed_vessel() {
    for (rx, ry) in [(0.0, 0.0), (30.0, 0.0), (60.0, 30.0)] {
        let open = aneurysm(BorderEnds::Open, rx, ry);
        let found = patches_of(&open, Inlet::Largest).unwrap();
        let (closed, patches) = close_open_ends(&open, &found).unwrap();
        let t = Topology::build(&closed);
        assert!(t.is_closed_oriented_manifold(), "{rx} {ry}");
        assert_eq!(t.n_components(), 1);
        assert!(destair::mesh::geometry::signed_volume(&closed) > 0.0);
        assert_eq!(closed.n_vertices(), open.n_vertices() + 3);
        assert_eq!(patches.face_ids.len(), closed.n_triangles());
        for (before, after) in found.patches.iter().zip(&patches.patches) {
            assert_eq!(after.kind, PatchKind::ClosedEnd);
            assert_eq!((before.id, &before.name), (after.id, &after.name));
            assert!(
                angle_deg(before.normal, after.normal) < 0.01,
                "{before:?} {after:?}"
            );
            assert!((before.area_mm2 / after.area_mm2 - 1.0).abs() < 1e-3);
            let faces = patches
                .face_ids
                .iter()
                .filter(|&&id| id == after.id)
                .count();
            assert_eq!(faces, after.faces.len());
            assert_eq!(faces, before.vertices.len());
            // Planar to float precision, rim and centre alike.
            let off = off_plane(&closed, after);
            assert!(
                off < 1e-5,
                "{rx} {ry} {}: {off} mm off the plane",
                after.name
            );
        }
        // Every face of a closed end faces out of the fluid along the patch normal.
        let normals = destair::mesh::geometry::face_normals(&closed);
        for p in &patches.patches {
            for &f in &p.faces {
                let n = normals[f as usize].map(f64::from);
                // f32 normals of small fan triangles: a few hundredths of a degree.
                assert!(angle_deg(n, p.normal) < 0.05, "{rx} {ry} {}: {n:?}", p.name);
            }
        }
    }
    // Patches of another mesh are refused, not indexed out of range.
    let open = aneurysm(BorderEnds::Open, 0.0, 0.0);
    let found = patches_of(&open, Inlet::Largest).unwrap();
    let small = open_box();
    assert!(matches!(
        close_open_ends(&small, &found).unwrap_err(),
        CloseError::Mismatch(_)
    ));
    let dir = tempfile::tempdir().unwrap();
    let meta = destair::io::MeshMeta::default();
    assert!(destair::cfd::write_patch_files(dir.path(), "x", &small, &meta, &found).is_err());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    // Caps found on a closed vessel stay as they are.
    let capped = aneurysm(BorderEnds::Capped, 0.0, 0.0);
    let found = patches_of(&capped, Inlet::Largest).unwrap();
    let (same, patches) = close_open_ends(&capped, &found).unwrap();
    assert_eq!(same, capped);
    assert_eq!(patches, found);
}

#[test]
fn an_end_a_fan_cannot_close_is_refused() {
    // An open box whose opening is a non-convex, L-shaped rim seen from its centre... made
    // by pushing one rim corner of the open square past the centre.
    let (mut p, t) = open_box().into_parts();
    p[7] = [0.1, 0.1, 1.0];
    let m = Mesh::new(p, t).unwrap();
    let found = patches_of(&m, Inlet::Largest).unwrap();
    assert_eq!(
        close_open_ends(&m, &found).unwrap_err(),
        CloseError::NotStarShaped {
            name: "inlet".into()
        }
    );
}

/// The bytes of the appended block at `offset` (after its 8-byte size) in a `.vtp` we wrote.
fn vtp_block<'a>(vtp: &'a [u8], name: &str) -> &'a [u8] {
    let text = String::from_utf8_lossy(vtp);
    let tag = format!("Name=\"{name}\"");
    let line = text.lines().find(|l| l.contains(&tag)).unwrap();
    let offset: usize = line
        .split("offset=\"")
        .nth(1)
        .unwrap()
        .split('"')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let start = vtp.windows(2).position(|w| w == b" _").unwrap() + 2 + offset;
    let size = u64::from_le_bytes(vtp[start..start + 8].try_into().unwrap()) as usize;
    &vtp[start + 8..start + 8 + size]
}

#[test]
fn patch_files_hold_one_solid_per_patch_and_cell_entity_ids() {
    let open = aneurysm(BorderEnds::Open, 30.0, 0.0);
    let found = patches_of(&open, Inlet::Largest).unwrap();
    let (closed, patches) = close_open_ends(&open, &found).unwrap();
    let meta = destair::io::MeshMeta {
        comments: vec!["SPACE=LPS".into()],
        obj_info: vec![],
    };
    let dir = tempfile::tempdir().unwrap();
    let written =
        destair::cfd::write_patch_files(dir.path(), "vessel", &closed, &meta, &patches).unwrap();
    assert_eq!(
        written,
        destair::cfd::outputs::planned_files(dir.path(), "vessel", &patches)
    );
    let names: Vec<String> = written
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "vessel_solids.stl",
            "vessel_wall.stl",
            "vessel_inlet.stl",
            "vessel_outlet_1.stl",
            "vessel_outlet_2.stl",
            "vessel.vtp",
            "vessel_patches.json"
        ]
    );
    let read =
        |name: &str| destair::io::read_mesh(&dir.path().join(name), &Default::default()).unwrap();

    // Multi-solid STL: one solid per patch with its faces, the whole surface read back with
    // every coordinate bit-exact and the same topology.
    let text = std::fs::read_to_string(dir.path().join("vessel_solids.stl")).unwrap();
    let mut solids: Vec<(String, usize)> = Vec::new();
    for line in text.lines() {
        if let Some(rest) = line.strip_prefix("solid ") {
            solids.push((rest.split_whitespace().next().unwrap().into(), 0));
        } else if line.trim_start().starts_with("facet") {
            solids.last_mut().unwrap().1 += 1;
        }
    }
    let mut expected = vec![("wall".to_string(), patches.wall_faces)];
    expected.extend(
        patches
            .patches
            .iter()
            .map(|p| (p.name.clone(), p.faces.len())),
    );
    assert_eq!(solids, expected);
    let back = read("vessel_solids.stl");
    assert_eq!(back.meta.space(), Some("LPS"));
    assert_eq!(back.mesh.n_triangles(), closed.n_triangles());
    assert_eq!(back.mesh.n_vertices(), closed.n_vertices());
    let sorted = |m: &Mesh| {
        let mut v: Vec<[u32; 3]> = m.positions().iter().map(|p| p.map(f32::to_bits)).collect();
        v.sort_unstable();
        v
    };
    assert_eq!(sorted(&back.mesh), sorted(&closed));
    assert!(Topology::build(&back.mesh).is_closed_oriented_manifold());

    // One binary STL per patch.
    for (name, faces) in &expected {
        let m = read(&format!("vessel_{name}.stl")).mesh;
        assert_eq!(m.n_triangles(), *faces, "{name}");
    }

    // VTP: CellEntityIds per face, points bit-exact, triangles as written.
    let vtp = std::fs::read(dir.path().join("vessel.vtp")).unwrap();
    let ids: Vec<u32> = vtp_block(&vtp, "CellEntityIds")
        .chunks_exact(4)
        .map(|b| i32::from_le_bytes(b.try_into().unwrap()) as u32)
        .collect();
    assert_eq!(ids, patches.face_ids);
    let points: Vec<u32> = vtp_block(&vtp, "Points")
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    let expect: Vec<u32> = closed
        .positions()
        .iter()
        .flat_map(|p| p.map(f32::to_bits))
        .collect();
    assert_eq!(points, expect);
    let connectivity: Vec<u32> = vtp_block(&vtp, "connectivity")
        .chunks_exact(8)
        .map(|b| i64::from_le_bytes(b.try_into().unwrap()) as u32)
        .collect();
    assert_eq!(connectivity, closed.triangles().concat());
    assert_eq!(vtp_block(&vtp, "SPACE"), b"LPS\0");

    // The patch table.
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("vessel_patches.json")).unwrap())
            .unwrap();
    assert_eq!(json["space"], "LPS");
    let table = json["patches"].as_array().unwrap();
    assert_eq!(table.len(), 3);
    assert_eq!(table[0]["name"], "inlet");
    assert_eq!(table[0]["kind"], "closed_end");
    assert_eq!(json["wall_faces"], patches.wall_faces);

    // VTK's own reader, where a Python with VTK is at hand (DESTAIR_VTK_PYTHON, else python3).
    let python = std::env::var("DESTAIR_VTK_PYTHON").unwrap_or_else(|_| "python3".into());
    let script = "import sys, vtk\nr = vtk.vtkXMLPolyDataReader(); r.SetFileName(sys.argv[1]); r.Update()\no = r.GetOutput(); a = o.GetCellData().GetArray('CellEntityIds')\nprint(o.GetNumberOfPoints(), o.GetNumberOfCells(), *[int(a.GetValue(i)) for i in range(o.GetNumberOfCells())])";
    match std::process::Command::new(&python)
        .args(["-c", script])
        .arg(dir.path().join("vessel.vtp"))
        .output()
    {
        Ok(out) if out.status.success() => {
            let got: Vec<usize> = String::from_utf8_lossy(&out.stdout)
                .split_whitespace()
                .map(|x| x.parse().unwrap())
                .collect();
            assert_eq!(got[0], closed.n_vertices());
            assert_eq!(got[1], closed.n_triangles());
            let ids: Vec<usize> = patches.face_ids.iter().map(|&x| x as usize).collect();
            assert_eq!(&got[2..], &ids[..]);
            eprintln!("VTK's vtkXMLPolyDataReader read the .vtp");
        }
        _ => eprintln!("no Python with VTK ({python}); the .vtp was checked by its bytes only"),
    }
}

#[test]
fn surface_checks_name_what_is_wrong() {
    use destair::cfd::check_surface;
    // The closed capped aneurysm passes.
    let m = aneurysm(BorderEnds::Capped, 0.0, 0.0);
    let c = check_surface(&m, &Topology::build(&m), false, None);
    assert!(c.failures().is_empty(), "{:?}", c.failures());
    assert!(c.signed_volume_mm3 > 0.0);
    // Turned inside out: normals into the fluid.
    let flipped: Vec<[u32; 3]> = m.triangles().iter().map(|t| [t[0], t[2], t[1]]).collect();
    let inside_out = Mesh::new(m.positions().to_vec(), flipped).unwrap();
    let c = check_surface(&inside_out, &Topology::build(&inside_out), false, None);
    assert!(
        c.failures().iter().any(|f| f.contains("into the fluid")),
        "{:?}",
        c.failures()
    );
    // One vertex pushed through the opposite wall: self-intersections, and where.
    let mut p = m.positions().to_vec();
    let v = (0..p.len())
        .max_by(|&a, &b| p[a][0].total_cmp(&p[b][0]))
        .unwrap();
    p[v][0] -= 8.0;
    let pushed = Mesh::new(p, m.triangles().to_vec()).unwrap();
    let c = check_surface(&pushed, &Topology::build(&pushed), false, None);
    assert!(c.self_intersections > 0 && c.first_self_intersection_mm.is_some());
    assert!(c.failures().iter().any(|f| f.contains("intersect")));
    // Open ends: refused unless allowed.
    let open = aneurysm(BorderEnds::Open, 0.0, 0.0);
    let t = Topology::build(&open);
    assert!(check_surface(&open, &t, false, None).failures()[0].contains("not watertight"));
    assert!(check_surface(&open, &t, true, None).failures().is_empty());
}

#[test]
fn flow_extensions_run_along_the_normal_and_end_in_a_flat_cap() {
    use destair::cfd::{add_flow_extensions, check_surface, ExtendError};
    for (ends, rx, ry) in [
        (BorderEnds::Capped, 0.0, 0.0),
        (BorderEnds::Capped, 30.0, 45.0),
        (BorderEnds::Open, 20.0, -35.0),
    ] {
        let m = aneurysm(ends, rx, ry);
        let before = patches_of(&m, Inlet::Largest).unwrap();
        let (extended, after) = add_flow_extensions(&m, &before, 5.0, &[]).unwrap();
        let topology = Topology::build(&extended);
        let checks = check_surface(&extended, &topology, false, None);
        assert!(checks.failures().is_empty(), "{:?}", checks.failures());
        for (b, a) in before.patches.iter().zip(&after.patches) {
            assert_eq!((a.id, &a.name), (b.id, &b.name));
            let length = 5.0 * b.diameter_mm;
            assert!((a.extension_mm - length).abs() < 1e-9);
            // The new cap: one extension length out along the normal, the same direction, a
            // circle of about the same area, exactly flat.
            let expected: [f64; 3] = std::array::from_fn(|k| b.centre_mm[k] + length * b.normal[k]);
            assert!(
                distance(a.centre_mm, expected) < 1e-3,
                "{} {:?}",
                a.name,
                a.centre_mm
            );
            assert!(angle_deg(a.normal, b.normal) < 1e-3);
            assert!(
                (a.diameter_mm / b.diameter_mm - 1.0).abs() < 0.03,
                "{} {} -> {}",
                a.name,
                b.diameter_mm,
                a.diameter_mm
            );
            assert!(a.planarity_mm < 1e-5, "{}: {}", a.name, a.planarity_mm);
            assert!(!a.faces.is_empty() && a.kind != PatchKind::OpenEnd);
        }
        // Only the inlet extended: the outlets stay where they were.
        let (_, only) = add_flow_extensions(&m, &before, 2.0, &[2]).unwrap();
        assert!(only.patches[0].extension_mm > 0.0);
        for (b, a) in before.patches.iter().zip(&only.patches).skip(1) {
            assert_eq!(a.extension_mm, 0.0);
            assert!(distance(a.centre_mm, b.centre_mm) < 1e-6);
        }
    }
    let m = aneurysm(BorderEnds::Capped, 0.0, 0.0);
    let p = patches_of(&m, Inlet::Largest).unwrap();
    assert_eq!(
        add_flow_extensions(&m, &p, 0.0, &[]).unwrap_err(),
        ExtendError::Length(0.0)
    ); // A patch id the vessel does not have is an error, not a silent no-op.
    let err = add_flow_extensions(&m, &p, 2.0, &[7]).unwrap_err();
    assert!(
        matches!(err, ExtendError::UnknownPatch { id: 7, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("2 inlet"), "{err}");
}

#[test]
fn the_narrowest_lumen_is_the_smallest_opposite_wall_distance() {
    use destair::cfd::checks::{narrowest_lumen, opposite_wall_distance};
    let thin = named_case("thin-vessel", &PhantomOptions::default()).unwrap();
    let mut meshes = vec![
        aneurysm(BorderEnds::Capped, 0.0, 0.0),
        aneurysm(BorderEnds::Open, 25.0, 10.0),
        thin.meshes[0].1.clone(),
    ];
    // Smoothed copies: the narrowest point moves off the staircase.
    let m = meshes[0].clone();
    let t = Topology::build(&m);
    let (p, _) = destair::smooth::smooth(
        &m,
        &t,
        &destair::smooth::Method::Laplace { lambda: 0.5 },
        15,
        &destair::weights::VertexWeights::uniform(m.n_vertices()),
        &vec![false; m.n_vertices()],
    );
    let mut smoothed = m.clone();
    smoothed.positions_mut().copy_from_slice(&p);
    meshes.push(smoothed);
    for m in &meshes {
        let t = Topology::build(m);
        let all = opposite_wall_distance(m, &t);
        let brute = all
            .iter()
            .enumerate()
            .filter(|(_, d)| d.is_finite())
            .min_by(|a, b| a.1.total_cmp(b.1).then(a.0.cmp(&b.0)))
            .map(|(v, &d)| (v, d));
        assert!(brute.is_some());
        assert_eq!(narrowest_lumen(m, &t), brute);
    }
}

/// How much a closed polyline zigzags (mm): each point's offset from its neighbours' middle,
/// against the mean of its neighbours' offsets. A circle turns the same at every point (0);
/// a staircase turns one way, then the other.
fn zigzag(points: &[[f64; 3]]) -> f64 {
    let n = points.len();
    let turn: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let (a, b, x) = (points[(i + n - 1) % n], points[(i + 1) % n], points[i]);
            std::array::from_fn(|k| x[k] - 0.5 * (a[k] + b[k]))
        })
        .collect();
    (0..n)
        .map(|i| {
            let (a, b) = (turn[(i + n - 1) % n], turn[(i + 1) % n]);
            distance(turn[i], std::array::from_fn(|k| 0.5 * (a[k] + b[k])))
        })
        .sum::<f64>()
        / n as f64
}

#[test]
fn rims_are_smoothed_within_their_planes_only() {
    use destair::cfd::rims::smooth_rims;
    for (ends, rx, ry) in [
        (BorderEnds::Capped, 0.0, 0.0),
        (BorderEnds::Capped, 30.0, 45.0),
        (BorderEnds::Open, 20.0, -35.0),
    ] {
        let m = aneurysm(ends, rx, ry);
        let patches = patches_of(&m, Inlet::Largest).unwrap();
        let (s, summary) = smooth_rims(&m, &patches);
        assert_eq!(summary.patches, 3, "{summary:?}");
        assert!(summary.kept.is_empty());
        let before = |v: u32| m.positions()[v as usize].map(f64::from);
        let after = |v: u32| s.positions()[v as usize].map(f64::from);
        // Only patch vertices move, and none across its patch's plane.
        let on_patch = destair::cfd::patch_vertices(&patches, m.n_vertices());
        for v in 0..m.n_vertices() as u32 {
            if !on_patch[v as usize] {
                assert_eq!(before(v), after(v));
            }
        }
        for p in &patches.patches {
            for &v in &p.vertices {
                let off = |x: [f64; 3]| {
                    (0..3)
                        .map(|k| (x[k] - p.centre_mm[k]) * p.normal[k])
                        .sum::<f64>()
                };
                assert!((off(after(v)) - off(before(v))).abs() < 1e-5, "{}", p.name);
            }
        }
        // The rim loses its zigzag but keeps its size, and nothing turned over.
        let t = Topology::build(&s);
        let again = destair::cfd::remeasure_patches(&s, &t, patches.face_ids.clone(), &patches);
        for (b, a) in patches.patches.iter().zip(&again.patches) {
            assert!(
                (a.area_mm2 / b.area_mm2 - 1.0).abs() < 0.02,
                "{}: {} -> {}",
                b.name,
                b.area_mm2,
                a.area_mm2
            );
        }
        if ends == BorderEnds::Open {
            for l in t.boundary_loops() {
                let rim = |f: &dyn Fn(u32) -> [f64; 3]| {
                    zigzag(&l.vertices.iter().map(|&v| f(v)).collect::<Vec<_>>())
                };
                assert!(
                    rim(&after) < 0.5 * rim(&before),
                    "{} {}",
                    rim(&before),
                    rim(&after)
                );
            }
        }
        let checks = destair::cfd::check_surface(&s, &t, ends == BorderEnds::Open, None);
        assert!(checks.failures().is_empty(), "{:?}", checks.failures());
    }
}

/// VTK's own readers, when Python with the `vtk` package is installed (skipped otherwise): the
/// VTP opens, with as many cells per `CellEntityIds` value as the patch table says, closed; the
/// multi-solid STL opens with one solid per patch.
#[test]
fn vtk_reads_the_vtp_with_its_cell_entity_ids() {
    let m = aneurysm(BorderEnds::Capped, 30.0, 45.0);
    let patches = patches_of(&m, Inlet::Largest).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let meta = destair::io::MeshMeta::default();
    destair::cfd::write_patch_files(dir.path(), "vessel", &m, &meta, &patches).unwrap();
    // One Python process reads both files (importing VTK takes about a second). The STL
    // reader's tag counts solids from 0 in file order: the wall, then the patches.
    let script = r#"
import sys, collections
try:
    import vtk
except ImportError:
    print("no-vtk")
    sys.exit(0)
r = vtk.vtkXMLPolyDataReader(); r.SetFileName(sys.argv[1]); r.Update()
pd = r.GetOutput()
ids = pd.GetCellData().GetArray("CellEntityIds")
counts = collections.Counter(int(ids.GetValue(i)) for i in range(ids.GetNumberOfTuples()))
fe = vtk.vtkFeatureEdges(); fe.SetInputData(pd)
fe.BoundaryEdgesOn(); fe.NonManifoldEdgesOn(); fe.FeatureEdgesOff(); fe.ManifoldEdgesOff()
fe.Update()
print(pd.GetNumberOfPoints(), fe.GetOutput().GetNumberOfCells(), *sorted(counts.items()))
r = vtk.vtkSTLReader(); r.SetFileName(sys.argv[2]); r.ScalarTagsOn(); r.Update()
pd = r.GetOutput(); tags = pd.GetCellData().GetScalars()
counts = collections.Counter(int(tags.GetValue(i)) for i in range(pd.GetNumberOfCells()))
print(pd.GetNumberOfPoints(), *sorted(counts.items()))
"#;
    let out = std::process::Command::new("python3")
        .args(["-c", script])
        .arg(dir.path().join("vessel.vtp"))
        .arg(dir.path().join("vessel_solids.stl"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    if stdout.trim() == "no-vtk" {
        eprintln!("skipped: python3 with the vtk package is not installed");
        return;
    }
    let mut vtp = format!("{} 0 (1, {})", m.n_vertices(), patches.wall_faces);
    for p in &patches.patches {
        vtp.push_str(&format!(" ({}, {})", p.id, p.faces.len()));
    }
    let mut stl = format!("{} (0, {})", m.n_vertices(), patches.wall_faces);
    for (k, p) in patches.patches.iter().enumerate() {
        stl.push_str(&format!(" ({}, {})", k + 1, p.faces.len()));
    }
    let lines: Vec<&str> = stdout.lines().map(str::trim).collect();
    assert_eq!(lines, [vtp.as_str(), stl.as_str()]);
}

/// Work is bounded by the structure as it came in: a target or flow extensions that would make
/// more than 64 times its faces (at least 65536) are refused before any is made, with the
/// figures (a 1,092-face vessel at 0.05 x its radius ran 124 s and took 694 MB before). A
/// surface that encloses nothing (one triangle) is no vessel, whatever its open end.
#[test]
fn targets_beyond_the_face_budget_and_sheets_are_refused_at_once() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    // Open-ended: its ends are the patches (capped, two voxels across, none is found).
    common::cohort::destair_ok(&[
        "phantom",
        "thin-vessel",
        "--open-ends",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let vessel = dir.join("vessel.ply");
    let one = dir.join("one.ply");
    std::fs::write(
        &one,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    )
    .unwrap();
    for (input, extra, says) in [
        (
            &vessel,
            &["--edge-per-radius", "0.05"][..],
            "more than 67584",
        ),
        (
            &vessel,
            &["--edge-mm", "0.1", "--flow-extension", "100"][..],
            "flow extensions of 100 diameters",
        ),
        (&one, &["--edge-mm", "0.1"][..], "encloses no lumen"),
    ] {
        let started = std::time::Instant::now();
        let out = dir.join("out.ply");
        let mut args = vec!["--profile", "cfd"];
        args.extend_from_slice(extra);
        let run = common::cohort::smooth(input, &out, "hc", &args);
        let err = common::cohort::stderr(&run);
        assert_eq!(run.status.code(), Some(3), "{extra:?}: {err}");
        assert!(err.contains(says), "{extra:?}: {err}");
        assert!(!out.exists(), "{extra:?}: wrote an output");
        assert!(
            started.elapsed().as_secs_f64() < 10.0,
            "{extra:?}: {:?}",
            started.elapsed()
        );
    }
}
