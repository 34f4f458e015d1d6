//! Label maps as cases of the cohort runner: labels become structures named by `[labels]`, the
//! file's segment names or `label_<value>`; they are smoothed with the header's voxel size and
//! stack axis in the grid's own frame, so an oblique acquisition gives the same result as an
//! axis-aligned one up to the rigid motion; outputs are in world LPS or RAS; resume, name
//! clashes, images that are not segmentations and corrupt files behave as for meshes.

use crate::common;

use common::cohort::{destair, destair_ok, stderr};
use destair::io::{read_mesh, ReadOptions};
use destair::volume::{nifti, nrrd, Grid, LabelVolume, Segment, Space};
use std::path::{Path, PathBuf};

fn write(path: &Path, bytes: &[u8]) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, bytes).unwrap();
}

fn phantom(dir: &Path, extra: &[&str]) {
    let mut args = vec!["phantom", "labelmap-neck", "--out", dir.to_str().unwrap()];
    args.extend_from_slice(extra);
    let out = destair(&args);
    assert!(out.status.success(), "{}", stderr(&out));
}

fn config(dir: &Path, text: &str) -> PathBuf {
    let path = dir.join("cohort.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn report(dir: &Path, case: &str) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("out").join(case).join("report.json")).unwrap())
        .unwrap()
}

fn structure<'a>(report: &'a serde_json::Value, name: &str) -> &'a serde_json::Value {
    report["structures"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == name)
        .unwrap_or_else(|| panic!("no structure {name} in {report}"))
}

/// Cases under cases/, outputs in out/, labels 1 and 2 named.
macro_rules! head {
    () => {
        r#"
[input]
roots = ["cases"]
case_depth = 1
[output]
root = "out"
[labels]
1 = "tumor"
2 = "vein"
"#
    };
}

const BASE: &str = concat!(
    head!(),
    r#"[defaults]
surface = "binary"
method = "hc"
iterations = 20
[[structure]]
pattern = "tumor"
references = ["vein"]
"#
);

#[test]
fn labels_become_structures_smoothed_with_the_header_geometry() {
    let tmp = tempfile::tempdir().unwrap();
    phantom(&tmp.path().join("cases/straight"), &[]);
    phantom(
        &tmp.path().join("cases/oblique"),
        &["--rotate-x", "25", "--rotate-y", "-40"],
    );
    let text = format!("{BASE}[[structure]]\npattern = \"label_3\"\nskip = true\n");
    let cfg = config(tmp.path(), &text);
    let out = destair_ok(&["run", cfg.to_str().unwrap()]);
    assert!(
        !stderr(&out).contains("matches no structure"),
        "{}",
        stderr(&out)
    );
    let straight = report(tmp.path(), "straight");
    let oblique = report(tmp.path(), "oblique");
    for r in [&straight, &oblique] {
        assert_eq!(r["status"], "ok", "{r}");
        let labels = &r["label_maps"][0]["labels"];
        let names: Vec<&str> = labels
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l["structure"].as_str().unwrap())
            .collect();
        // [labels] names 1 and 2; 3 has no name anywhere.
        assert_eq!(names, ["tumor", "vein", "label_3"]);
        for name in ["tumor", "vein"] {
            let s = structure(r, name);
            assert_eq!(s["status"], "ok");
            let src = &s["source"];
            // The voxel size and the stack axis are the header's, not estimates.
            let v = src["voxel_mm"].as_array().unwrap();
            assert!((v[0].as_f64().unwrap() - 0.45).abs() < 1e-6, "{src}");
            assert!((v[2].as_f64().unwrap() - 3.0).abs() < 1e-6, "{src}");
            assert_eq!(s["context"]["axis_source"], "label_map_header");
            assert!(s["context"]["n_staircase_vertices"].as_u64().unwrap() > 0);
            assert_eq!(s["method"]["method"], "hc", "{}", s["method"]);
            // The reported axis is the header's slice normal in world.
            let axis: Vec<f64> = s["context"]["axis"]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect();
            let want: Vec<f64> = src["stack_axis"]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect();
            let dot: f64 = axis.iter().zip(&want).map(|(a, b)| a * b).sum();
            assert!(dot.abs() > 1.0 - 1e-5, "{axis:?} vs {want:?}");
        }
        assert_eq!(structure(r, "label_3")["status"], "skipped");
    }
    // Oblique and straight differ by a rigid motion only: the same smoothing, the same figures.
    for name in ["tumor", "vein"] {
        let (a, b) = (structure(&straight, name), structure(&oblique, name));
        assert_eq!(a["n_vertices"], b["n_vertices"]);
        assert_eq!(
            a["context"]["n_staircase_vertices"],
            b["context"]["n_staircase_vertices"]
        );
        for key in ["volume_percent", "normal_curvature_smoothed_deg"] {
            let (x, y) = (
                a["metrics"][key].as_f64().unwrap(),
                b["metrics"][key].as_f64().unwrap(),
            );
            assert!(
                (x - y).abs() <= 1e-3 * x.abs().max(1.0),
                "{name} {key}: {x} vs {y}"
            );
        }
        let (x, y) = (
            a["metrics"]["distance"]["hausdorff_mm"].as_f64().unwrap(),
            b["metrics"]["distance"]["hausdorff_mm"].as_f64().unwrap(),
        );
        assert!((x - y).abs() < 1e-3, "{name} hausdorff {x} vs {y}");
    }
    // Outputs are in world LPS: a skipped label is exactly what `destair extract` writes.
    let ex = tmp.path().join("extracted");
    destair_ok(&[
        "extract",
        tmp.path()
            .join("cases/oblique/segmentation.nii.gz")
            .to_str()
            .unwrap(),
        "--out",
        ex.to_str().unwrap(),
        "--labels",
        "1=tumor,2=vein",
        "--surface",
        "binary",
    ]);
    // A binary extraction has nothing to compare with itself.
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(ex.join("extract.json")).unwrap()).unwrap();
    for l in report["labels"].as_array().unwrap() {
        assert!(l.get("against_binary").is_none(), "{l}");
    }
    let opts = ReadOptions::default();
    let extracted = read_mesh(&ex.join("label_3.ply"), &opts).unwrap();
    let copied = read_mesh(&tmp.path().join("out/oblique/label_3.ply"), &opts).unwrap();
    assert!(copied.meta.comments.iter().any(|c| c == "SPACE=LPS"));
    assert_eq!(extracted.mesh.triangles(), copied.mesh.triangles());
    let worst = extracted
        .mesh
        .positions()
        .iter()
        .zip(copied.mesh.positions())
        .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).abs()).fold(0f32, f32::max))
        .fold(0f32, f32::max);
    assert!(worst < 1e-3, "copied label moved by {worst} mm");
    // Smoothed outputs stay where the label is, outward oriented, within a voxel of it.
    for name in ["tumor", "vein"] {
        let before = read_mesh(&ex.join(format!("{name}.ply")), &opts).unwrap();
        let after = read_mesh(&tmp.path().join(format!("out/oblique/{name}.ply")), &opts).unwrap();
        let (vb, va) = (
            destair::mesh::geometry::signed_volume(&before.mesh),
            destair::mesh::geometry::signed_volume(&after.mesh),
        );
        assert!(
            va > 0.0 && (va / vb - 1.0).abs() < 0.05,
            "{name}: {vb} -> {va}"
        );
        let moved = before
            .mesh
            .positions()
            .iter()
            .zip(after.mesh.positions())
            .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f32>().sqrt())
            .fold(0f32, f32::max);
        assert!(
            moved > 0.01 && moved < 3.0,
            "{name}: moved at most {moved} mm"
        );
    }
}

#[test]
fn a_label_whose_surface_encloses_far_less_than_its_voxels_is_a_warning() {
    // A block of 20 x 20 x 8 voxels and a vessel 2 x 2 voxels across along the slices, on
    // 0.8 x 0.8 x 2.5 mm: the constrained surface keeps the block's volume, not the vessel's.
    let tmp = tempfile::tempdir().unwrap();
    let dims = [32, 32, 14];
    let mut values = vec![0i64; dims.iter().product()];
    for k in 1..13 {
        for j in 2..30 {
            for i in 2..30 {
                let label = if (4..24).contains(&i) && (4..24).contains(&j) && (3..11).contains(&k)
                {
                    1
                } else if (27..29).contains(&i) && (27..29).contains(&j) {
                    2
                } else {
                    0
                };
                values[i + dims[0] * (j + dims[1] * k)] = label;
            }
        }
    }
    let grid = Grid::axis_aligned([0.8, 0.8, 2.5], [0.0; 3], Space::Ras);
    let volume = LabelVolume::from_values(dims, grid, values.into_iter()).unwrap();
    write(
        &tmp.path().join("cases/a/seg.nii.gz"),
        &nifti::encode(&volume, true).unwrap(),
    );
    let cfg = config(tmp.path(), head!());
    destair_ok(&["run", cfg.to_str().unwrap()]);
    let r = report(tmp.path(), "a");
    let warned = |name: &str| {
        let s = structure(&r, name);
        let enclosed = s["metrics"]["volume_smoothed_mm3"].as_f64().unwrap();
        let voxels = s["source"]["voxel_volume_mm3"].as_f64().unwrap();
        let warning = s["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("the surface encloses"));
        (enclosed / voxels, warning)
    };
    let (block, block_warned) = warned("tumor");
    assert!((block - 1.0).abs() <= 0.1 && !block_warned, "{block}");
    let (vessel, vessel_warned) = warned("vein");
    assert!(vessel < 0.9 && vessel_warned, "{vessel}");
}

/// Two overlapping layers of a `.seg.nrrd` (a liver with a cyst in layer 0, a tumour inside the
/// liver in layer 1), both value 1 for liver and tumour, named by Slicer's segments.
fn two_layer_seg_nrrd(path: &Path) {
    let dims = [20, 20, 8];
    let grid = Grid {
        matrix: [[0.8, 0.0, 0.0], [0.0, 0.8, 0.0], [0.0, 0.0, 2.5]],
        origin: [0.0, 0.0, 0.0],
        space: Space::Lps,
    };
    let at = |i: usize, j: usize, k: usize| i + dims[0] * (j + dims[1] * k);
    let mut layers = [vec![0i64; 20 * 20 * 8], vec![0i64; 20 * 20 * 8]];
    for k in 2..6 {
        for j in 4..18 {
            for i in 4..18 {
                layers[0][at(i, j, k)] = if i >= 15 && j >= 15 { 2 } else { 1 };
                if (8..13).contains(&i) && (8..13).contains(&j) && k < 5 {
                    layers[1][at(i, j, k)] = 1;
                }
            }
        }
    }
    let volumes: Vec<LabelVolume> = layers
        .into_iter()
        .map(|v| LabelVolume::from_values(dims, grid, v.into_iter()).unwrap())
        .collect();
    let segment = |name: &str, value, layer| Segment {
        name: name.into(),
        value,
        layer,
    };
    let segments = [
        segment("liver parenchyma", 1, 0),
        segment("cyst", 2, 0),
        segment("tumor", 1, 1),
    ];
    write(path, &nrrd::encode(&volumes, &segments, true).unwrap());
}

#[test]
fn two_layers_of_a_seg_nrrd_by_their_names_or_by_layer() {
    let tmp = tempfile::tempdir().unwrap();
    two_layer_seg_nrrd(&tmp.path().join("cases/a/seg.seg.nrrd"));
    let head = "[input]\nroots = [\"cases\"]\ncase_depth = 1\n[output]\nroot = \"out\"\npictures = false\nhtml = false\n";
    // The file's names alone: value 1 of each layer is its own structure.
    let cfg = config(tmp.path(), head);
    destair_ok(&["run", cfg.to_str().unwrap()]);
    let r = report(tmp.path(), "a");
    assert_eq!(r["status"], "ok", "{r}");
    for name in ["liver parenchyma", "cyst", "tumor"] {
        structure(&r, name);
    }
    // A plain value names it in every layer: two structures of one name, which fails the case
    // with the layers said and the way out.
    std::fs::remove_dir_all(tmp.path().join("out")).unwrap();
    let cfg = config(tmp.path(), &format!("{head}[labels]\n1 = \"spleen\"\n"));
    let out = destair(&["run", cfg.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("label 1 of seg.seg.nrrd and label 1 (layer 1) of seg.seg.nrrd")
            && err.contains("\"1:2\" for value 2 in layer 1"),
        "{err}"
    );
    // Layer and value: each named; a name the file gives otherwise is a warning that says both,
    // and the file's name stays in the report; a key no voxel matches is a warning.
    std::fs::remove_dir_all(tmp.path().join("out")).unwrap();
    let labels = "[labels]\n\"0:1\" = \"liver\"\n\"1:1\" = \"tumor\"\n\"3:7\" = \"duct\"\n";
    let cfg = config(tmp.path(), &format!("{head}{labels}"));
    destair_ok(&["run", cfg.to_str().unwrap()]);
    let r = report(tmp.path(), "a");
    assert_eq!(r["status"], "ok", "{r}");
    let map = &r["label_maps"][0];
    let entry = |layer: u64, value: i64| {
        map["labels"]
            .as_array()
            .unwrap()
            .iter()
            .find(|e| e["layer"] == layer && e["value"] == value)
            .unwrap_or_else(|| panic!("no label {value} of layer {layer}: {map}"))
    };
    assert_eq!(entry(0, 1)["structure"], "liver");
    assert_eq!(entry(0, 1)["file_name"], "liver parenchyma");
    assert_eq!(entry(0, 2)["structure"], "cyst");
    assert_eq!(entry(1, 1)["structure"], "tumor");
    assert_eq!(entry(1, 1)["file_name"], "tumor");
    let warnings: Vec<&str> = map["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    assert!(
        warnings.iter().any(|w| w.contains(
            "names label 1 (layer 0) of seg.seg.nrrd \"liver\", but the file names it \"liver parenchyma\""
        )),
        "{warnings:?}"
    );
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("3:7 = \"duct\", but no voxel of seg.seg.nrrd in layer 3 holds 7")),
        "{warnings:?}"
    );
    // Only where the names differ: the tumour's name agrees.
    assert_eq!(
        warnings
            .iter()
            .filter(|w| w.contains("but the file names it"))
            .count(),
        1
    );
    // `check` says what label structures get: the constrained surface and no smoother unless
    // `method` is set for one (here the tumour), also for labels no name reaches yet.
    let cfg = config(
        tmp.path(),
        &format!("{head}{labels}[[structure]]\npattern = \"tumor\"\nmethod = \"taubin\"\n"),
    );
    let out = destair_ok(&["check", cfg.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    let section = |name: &str| {
        let start = (text.find(&format!("\n# {name}:")))
            .or_else(|| text.find(&format!("\n# {name} (")))
            .unwrap_or_else(|| panic!("no section {name}: {text}"));
        let rest = &text[start + 1..];
        rest[..rest.find("\n\n").unwrap_or(rest.len())].to_string()
    };
    let unsmoothed = "the constrained surface is the result; no mesh smoother runs on it";
    assert!(section("liver").contains(unsmoothed), "{text}");
    assert!(section("cyst").contains(unsmoothed), "{text}");
    assert!(
        section("the label maps' other labels").contains(unsmoothed),
        "{text}"
    );
    let tumor = section("tumor");
    assert!(
        tumor.contains("then the mesh smoother below") && tumor.contains("method = \"taubin\""),
        "{text}"
    );
    // A key that is neither form is refused with the forms it may take.
    let cfg = config(tmp.path(), &format!("{head}[labels]\n\"a:1\" = \"x\"\n"));
    let out = destair(&["check", cfg.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("\"1:2\" (layer 1, counted from 0, value 2)"),
        "{}",
        stderr(&out)
    );
}

/// A 3-label volume on a mirrored grid (NIfTI's qfac = -1 kind) in RAS.
fn mirrored_volume() -> LabelVolume {
    let dims = [24, 20, 10];
    let mut values = vec![0i64; dims.iter().product()];
    for k in 2..8 {
        for j in 3..17 {
            for i in 3..21 {
                let label = if i < 10 {
                    1
                } else if i < 15 {
                    2
                } else {
                    7
                };
                values[i + dims[0] * (j + dims[1] * k)] = label;
            }
        }
    }
    let grid = Grid {
        matrix: [[-0.8, 0.0, 0.0], [0.0, 0.8, 0.0], [0.0, 0.0, 2.5]],
        origin: [40.0, -10.0, 5.0],
        space: Space::Ras,
    };
    LabelVolume::from_values(dims, grid, values.into_iter()).unwrap()
}

#[test]
fn names_spaces_mirrors_and_resume() {
    let tmp = tempfile::tempdir().unwrap();
    let volume = mirrored_volume();
    // A .seg.nrrd with Slicer's names; [labels] wins for value 2.
    let segments = vec![
        Segment {
            name: "liver".into(),
            value: 1,
            layer: 0,
        },
        Segment {
            name: "portal vein".into(),
            value: 2,
            layer: 0,
        },
    ];
    write(
        &tmp.path().join("cases/a/seg.seg.nrrd"),
        &nrrd::encode(std::slice::from_ref(&volume), &segments, true).unwrap(),
    );
    let text = r#"
[input]
roots = ["cases"]
case_depth = 1
[output]
root = "out"
space = "ras"
[labels]
2 = "vein"
[defaults]
method = "laplace"
iterations = 5
[[structure]]
pattern = "liver"
references = ["vein"]
"#;
    let cfg = config(tmp.path(), text);
    destair_ok(&["run", cfg.to_str().unwrap()]);
    let r = report(tmp.path(), "a");
    assert_eq!(r["status"], "ok", "{r}");
    let names: Vec<&str> = r["structures"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["label_7", "liver", "vein"]);
    assert_eq!(r["label_maps"][0]["space"], "RAS");
    let opts = ReadOptions::default();
    for name in names {
        let m = read_mesh(&tmp.path().join(format!("out/a/{name}.ply")), &opts).unwrap();
        assert!(m.meta.comments.iter().any(|c| c == "SPACE=RAS"));
        // Outward normals despite the mirrored grid; where the affine puts the label.
        assert!(
            destair::mesh::geometry::signed_volume(&m.mesh) > 0.0,
            "{name}"
        );
        let xs: Vec<f32> = m.mesh.positions().iter().map(|p| p[0]).collect();
        let max_x = xs.iter().copied().fold(f32::MIN, f32::max);
        // i from 3 on, x = 40 - 0.8 i: nothing beyond x = 40 - 0.8 * 2.5.
        assert!(max_x <= 38.0 + 0.8, "{name}: max x {max_x}");
    }
    // The liver touches the vein: the reference distance is 0 before and after.
    let liver = structure(&r, "liver");
    assert_eq!(liver["metrics"]["references"][0]["name"], "vein");
    // Resume: nothing changes, nothing is redone.
    let again = destair(&["run", cfg.to_str().unwrap()]);
    assert!(again.status.success());
    assert!(
        stderr(&again).contains("1 already done"),
        "{}",
        stderr(&again)
    );
    // Naming a label is a different output: redone.
    std::fs::write(
        &cfg,
        text.replace("2 = \"vein\"", "2 = \"vein\"\n7 = \"duct\""),
    )
    .unwrap();
    let renamed = destair_ok(&["run", cfg.to_str().unwrap()]);
    assert!(
        stderr(&renamed).contains("0 already done"),
        "{}",
        stderr(&renamed)
    );
    assert!(tmp.path().join("out/a/duct.ply").exists());
    // The old name's output is gone with the new manifest.
    assert!(!tmp.path().join("out/a/label_7.ply").exists());
}

/// A reference mesh file measured in a label structure's grid frame is checked there: one
/// 10 km away (valid in world mm, beyond +-1e7 mm in the frame of a grid 900 m off the
/// origin) fails the structure with the reason, not with invalid coordinates.
#[test]
fn a_reference_beyond_the_coordinate_bound_in_a_grids_frame_fails_its_structure() {
    let tmp = tempfile::tempdir().unwrap();
    let mut volume = mirrored_volume();
    // RAS x = 900 m is LPS x = -900 m, where the cohort (LPS) reads the probe at +9500 m.
    volume.grid.origin = [9e5, -10.0, 5.0];
    write(
        &tmp.path().join("cases/far/seg.nii.gz"),
        &nifti::encode(&volume, true).unwrap(),
    );
    let x = 9.5e6f32;
    let tetrahedron = destair::Mesh::new(
        vec![
            [x, 0.0, 0.0],
            [x + 1.0, 0.0, 0.0],
            [x, 1.0, 0.0],
            [x, 0.0, 1.0],
        ],
        vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
    )
    .unwrap();
    let ply = destair::io::ply::encode_ply(&tetrahedron, &Default::default(), &[]).unwrap();
    write(&tmp.path().join("cases/far/probe.ply"), &ply);
    let text = concat!(
        head!(),
        r#"[defaults]
method = "laplace"
iterations = 3
[[structure]]
pattern = "tumor"
references = ["probe"]
"#
    );
    let cfg = config(tmp.path(), text);
    let out = destair(&["run", cfg.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    let r = report(tmp.path(), "far");
    let tumor = structure(&r, "tumor").to_string();
    assert!(
        tumor.contains("reference \\\"probe\\\" in this structure's grid")
            && tumor.contains("within +-1e7 mm"),
        "{tumor}"
    );
    assert_eq!(structure(&r, "vein")["status"], "ok", "{r}");
}

#[test]
fn clashes_images_and_corrupt_label_maps_fail_their_case_only() {
    let tmp = tempfile::tempdir().unwrap();
    let volume = mirrored_volume();
    let nii = nifti::encode(&volume, true).unwrap();
    // ok: a plain label map.
    write(&tmp.path().join("cases/ok/seg.nii.gz"), &nii);
    // clash: a mesh file named like a label.
    write(&tmp.path().join("cases/clash/seg.nii.gz"), &nii);
    let tetra = destair::Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ],
        vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    )
    .unwrap();
    destair::io::ply::write_ply(
        &tmp.path().join("cases/clash/tumor.ply"),
        &tetra,
        &Default::default(),
        &[],
    )
    .unwrap();
    // image: 2000 distinct values, as an intensity image has.
    let dims = [20, 20, 10];
    let image = LabelVolume::from_values(
        dims,
        Grid::axis_aligned([1.0; 3], [0.0; 3], Space::Ras),
        (0..4000).map(|i| (i % 2000) as i64),
    )
    .unwrap();
    write(
        &tmp.path().join("cases/image/ct.nii.gz"),
        &nifti::encode(&image, true).unwrap(),
    );
    // corrupt: truncated gzip.
    write(
        &tmp.path().join("cases/corrupt/seg.nii.gz"),
        &nii[..nii.len() / 2],
    );
    let text = r#"
[input]
roots = ["cases"]
case_depth = 1
[output]
root = "out"
[labels]
1 = "tumor"
[defaults]
method = "laplace"
iterations = 3
"#;
    let cfg = config(tmp.path(), text);
    let out = destair(&["run", cfg.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert_eq!(report(tmp.path(), "ok")["status"], "ok");
    let clash = report(tmp.path(), "clash");
    assert_eq!(clash["status"], "failed");
    let e = clash["errors"].to_string();
    assert!(
        e.contains("\\\"tumor\\\" comes from both label 1 of seg.nii.gz and tumor.ply"),
        "{e}"
    );
    let image = report(tmp.path(), "image")["errors"].to_string();
    assert!(
        image.contains("ct.nii.gz")
            && image.contains("1999 distinct values")
            && image.contains("[input] label_maps"),
        "{image}"
    );
    let corrupt = report(tmp.path(), "corrupt")["errors"].to_string();
    assert!(
        corrupt.contains("cases/corrupt/seg.nii.gz") && corrupt.contains("gzip"),
        "{corrupt}"
    );
    // Selecting the label maps by name leaves the image out: that folder is no case any more.
    std::fs::write(
        &cfg,
        text.replace("case_depth = 1", "case_depth = 1\nlabel_maps = [\"seg*\"]"),
    )
    .unwrap();
    let list = destair(&["list", cfg.to_str().unwrap(), "--jsonl"]);
    let text = String::from_utf8_lossy(&list.stdout);
    assert!(!text.contains("\"image\""), "{text}");
    assert!(text.contains("\"label_maps\":[\"seg.nii.gz\"]"), "{text}");
}

#[test]
fn combined_interfaces_carry_the_labels_of_both_sides() {
    let tmp = tempfile::tempdir().unwrap();
    let volume = mirrored_volume();
    let map = tmp.path().join("seg.nii");
    write(&map, &nifti::encode(&volume, false).unwrap());
    let out_dir = tmp.path().join("meshes");
    let combined = tmp.path().join("all.ply");
    destair_ok(&[
        "extract",
        map.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
        "--combined",
        combined.to_str().unwrap(),
    ]);
    // Parse the binary PLY by hand: x y z floats, then faces with two int properties.
    let bytes = std::fs::read(&combined).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = String::from_utf8_lossy(&bytes[..end]);
    assert!(header.contains("comment SPACE=LPS"), "{header}");
    assert!(
        header.contains("property int inner_label\nproperty int outer_label\nend_header"),
        "{header}"
    );
    let count = |what: &str| -> usize {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {what} ")))
            .unwrap()
            .parse()
            .unwrap()
    };
    let (nv, nf) = (count("vertex"), count("face"));
    let faces = &bytes[end + 12 * nv..];
    assert_eq!(faces.len(), nf * 21);
    let int = |b: &[u8]| i32::from_le_bytes(b.try_into().unwrap());
    let vertex = |v: usize| -> [f64; 3] {
        std::array::from_fn(|k| {
            let at = end + 12 * v + 4 * k;
            f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as f64
        })
    };
    let mut per_label = std::collections::BTreeMap::<i32, usize>::new();
    // Signed volume per label from its share, turned where it is the outer side: positive
    // when every normal points from inner to outer.
    let mut volume_of = std::collections::BTreeMap::<i32, f64>::new();
    for f in faces.chunks(21) {
        assert_eq!(f[0], 3);
        let (inner, outer) = (int(&f[13..17]), int(&f[17..21]));
        assert_ne!(inner, outer);
        let [a, b, c] = [1, 5, 9].map(|o| vertex(int(&f[o..o + 4]) as usize));
        let det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0]);
        *volume_of.entry(inner).or_default() += det / 6.0;
        *volume_of.entry(outer).or_default() -= det / 6.0;
        for l in [inner, outer] {
            *per_label.entry(l).or_default() += 1;
        }
    }
    // Each structure's own surface is exactly its share of the interfaces.
    let opts = ReadOptions::default();
    for (value, n) in &per_label {
        if *value == 0 {
            continue;
        }
        let own = read_mesh(&out_dir.join(format!("label_{value}.ply")), &opts).unwrap();
        assert_eq!(own.mesh.n_triangles(), *n, "label {value}");
        let want = destair::mesh::geometry::signed_volume(&own.mesh);
        let got = volume_of[value];
        assert!(
            want > 0.0 && (got - want).abs() < 1e-3 * want,
            "label {value}: {got} vs {want}"
        );
    }
    assert_eq!(per_label.keys().copied().collect::<Vec<_>>(), [0, 1, 2, 7]);
}

#[test]
fn extract_constrained_surfaces_from_the_command_line() {
    let tmp = tempfile::tempdir().unwrap();
    phantom(&tmp.path().join("p"), &["--rotate-x", "15"]);
    let map = tmp.path().join("p/segmentation.nii.gz");
    let out = tmp.path().join("smooth");
    destair_ok(&[
        "extract",
        map.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--surface",
        "constrained",
    ]);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("extract.json")).unwrap()).unwrap();
    for l in report["labels"].as_array().unwrap() {
        let e = &l["extraction"];
        assert_eq!(e["surface"], "constrained", "{l}");
        assert_eq!(
            (&e["noise"], &e["thin"]),
            (&"smooth".into(), &"protect".into())
        );
        // sigma: 1.5 times the smallest spacing (0.45 mm).
        let sigma = e["sigma_mm"].as_f64().unwrap();
        assert!((sigma - 0.675).abs() < 1e-5, "{sigma}");
        assert_eq!(l["closed_oriented_manifold"], true, "{l}");
        let (m, v) = (
            l["mesh_volume_mm3"].as_f64().unwrap(),
            l["voxel_volume_mm3"].as_f64().unwrap(),
        );
        assert!((m / v - 1.0).abs() < 0.1, "{l}");
        // What the smoothing changed against the binary surface of the same label.
        let a = &l["against_binary"];
        let (b, change) = (
            a["binary_mesh_volume_mm3"].as_f64().unwrap(),
            a["volume_change_percent"].as_f64().unwrap(),
        );
        assert!((100.0 * (m / b - 1.0) - change).abs() < 1e-9, "{l}");
        assert!(change.abs() < 10.0, "{l}");
        let (cb, c) = (
            a["binary_curvature_deg"].as_f64().unwrap(),
            a["curvature_deg"].as_f64().unwrap(),
        );
        assert!(c < 0.6 * cb, "{l}");
    }
    for bad in [
        vec!["--surface", "constrained", "--sigma-mm", "0"],
        vec!["--surface", "binary", "--sigma-mm", "1"],
        vec!["--surface", "binary", "--noise", "keep"],
        vec!["--surface", "binary", "--thin", "off"],
    ] {
        let mut args = vec![
            "extract",
            map.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        let flag = if bad.contains(&"--noise") {
            "--noise"
        } else if bad.contains(&"--thin") {
            "--thin"
        } else {
            "--sigma-mm"
        };
        args.extend(bad);
        let r = destair(&args);
        assert_eq!(r.status.code(), Some(2), "{}", stderr(&r));
        assert!(stderr(&r).contains(flag), "{}", stderr(&r));
    }
}

/// Label-map structures are constrained surfaces by default, with no mesh smoother after them
/// unless `method` is configured; the report keeps the extraction's settings and counts, and
/// the metrics measure the change from the binary extraction. Every key works per structure.
#[test]
fn label_surfaces_are_constrained_by_default_and_per_structure() {
    let tmp = tempfile::tempdir().unwrap();
    phantom(&tmp.path().join("cases/neck"), &[]);
    let text = concat!(
        head!(),
        r#"[[structure]]
pattern = "vein"
noise = "keep"
thin = "off"
sigma_mm = 0.7
[[structure]]
pattern = "label_3"
surface = "binary"
"#
    );
    let cfg = config(tmp.path(), text);
    destair_ok(&["run", cfg.to_str().unwrap()]);
    let r = report(tmp.path(), "neck");
    assert_eq!(r["status"], "ok", "{r}");
    let tumor = structure(&r, "tumor");
    let e = &tumor["source"]["extraction"];
    assert_eq!(e["surface"], "constrained", "{e}");
    assert_eq!(
        (&e["noise"], &e["thin"]),
        (&"smooth".into(), &"protect".into())
    );
    assert!(
        (e["sigma_mm"].as_f64().unwrap() - 0.675).abs() < 1e-6,
        "{e}"
    );
    assert!(e["noise_voxels"].as_u64().unwrap() > 0, "{e}");
    // No mesh smoother: the change is the extraction's, from the binary surface.
    assert!(tumor["method"].is_null(), "{}", tumor["method"]);
    let m = &tumor["metrics"];
    let (before, after) = (
        m["normal_curvature_original_deg"].as_f64().unwrap(),
        m["normal_curvature_smoothed_deg"].as_f64().unwrap(),
    );
    assert!(after < 0.5 * before, "{before} -> {after}");
    let vein = &structure(&r, "vein")["source"]["extraction"];
    assert_eq!(
        (&vein["noise"], &vein["thin"]),
        (&"keep".into(), &"off".into())
    );
    assert_eq!(vein["noise_voxels"], 0);
    assert!(
        (vein["sigma_mm"].as_f64().unwrap() - 0.7).abs() < 1e-9,
        "{vein}"
    );
    let third = &structure(&r, "label_3")["source"]["extraction"];
    assert_eq!(third["surface"], "binary", "{third}");
    assert!(third["sigma_mm"].is_null(), "{third}");
    let md = std::fs::read_to_string(tmp.path().join("out/neck/report.md")).unwrap();
    assert!(
        md.contains("`tumor`: surface constrained (sigma 0.675 mm"),
        "{md}"
    );
    assert!(md.contains("`label_3`: surface binary"), "{md}");
    // A wrong value names the key.
    let bad = config(
        tmp.path(),
        &text.replace("surface = \"binary\"", "surface = \"smooth\""),
    );
    let out = destair(&["run", bad.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("surface = \"smooth\""),
        "{}",
        stderr(&out)
    );
}

/// A small map with 1,000 random labels (64 KB) is refused at once by `max_labels` (default
/// 255), with the reason; raising the limit in the config admits its labels.
#[test]
fn a_map_with_more_labels_than_allowed_fails_at_once() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let mut rng = fastrand::Rng::with_seed(5);
    let grid = Grid::axis_aligned([1.0; 3], [0.0; 3], Space::Ras);
    let v = LabelVolume::from_values(
        [32, 32, 32],
        grid,
        (0..32 * 32 * 32).map(|i| if i < 1000 { i + 1 } else { rng.i64(0..=1000) }),
    )
    .unwrap();
    assert_eq!(v.labels.len(), 1000);
    write(
        &dir.join("cases/c/seg.nii"),
        &destair::volume::nifti::encode(&v, false).unwrap(),
    );
    let c = config(
        dir,
        "[input]\nroots = [\"cases\"]\ncase_depth = 1\n[output]\nroot = \"out\"\n",
    );
    let started = std::time::Instant::now();
    let run = destair(&["run", c.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(3), "{err}");
    assert!(
        err.contains("max_labels") && err.contains("seg.nii"),
        "{err}"
    );
    assert!(started.elapsed().as_secs_f64() < 30.0);
}

#[test]
fn caps_on_a_structure_that_reaches_no_edge_of_its_volume_are_a_warning() {
    // Two tubes along the slices (0.5 x 0.5 x 2 mm): one runs to one slice short of both ends
    // of the volume (the field of view clipped it), the other is cut flat well inside. Both get
    // their two end discs as caps; only the second's are questioned.
    let tmp = tempfile::tempdir().unwrap();
    let dims = [64, 36, 24];
    let mut values = vec![0i64; dims.iter().product()];
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let r2 = |ci: f64| (i as f64 - ci).powi(2) + (j as f64 - 17.5).powi(2);
                let label = if r2(16.5) <= 64.0 && (1..23).contains(&k) {
                    2
                } else if r2(46.5) <= 64.0 && (6..18).contains(&k) {
                    1
                } else {
                    0
                };
                values[i + dims[0] * (j + dims[1] * k)] = label;
            }
        }
    }
    let grid = Grid {
        matrix: [[0.5, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 2.0]],
        origin: [0.0, 0.0, 0.0],
        space: Space::Ras,
    };
    let volume = LabelVolume::from_values(dims, grid, values.into_iter()).unwrap();
    write(
        &tmp.path().join("cases/tubes/seg.nii.gz"),
        &nifti::encode(&volume, true).unwrap(),
    );
    // The vein (label 2) leaves the field of view, the "tumour" (label 1) is the tube inside.
    let cfg = config(
        tmp.path(),
        concat!(
            head!(),
            r#"[defaults]
surface = "binary"
method = "hc"
"#
        ),
    );
    destair_ok(&["run", cfg.to_str().unwrap()]);
    let r = report(tmp.path(), "tubes");
    for (name, reaches_edge) in [("vein", true), ("tumor", false)] {
        let s = structure(&r, name);
        assert_eq!(s["source"]["reaches_volume_edge"], reaches_edge, "{name}");
        let caps = s["context"]["caps"].as_array().unwrap();
        assert_eq!(caps.len(), 2, "{name}: {caps:?}");
        let warned = s["warnings"].as_array().unwrap().iter().any(|w| {
            w.as_str()
                .unwrap()
                .contains("reaches no edge of its volume")
        });
        assert_eq!(warned, !reaches_edge, "{name}: {}", s["warnings"]);
    }
}

/// A `sigma_mm` beyond twice the map's smallest spacing cuts the 5-tap Gaussian short (surfaces
/// rougher, not smoother): the structure that asks for it fails with the range, its neighbours
/// run as they would, and `extract` refuses it before any work.
#[test]
fn a_sigma_beyond_what_the_spacing_allows_is_refused_with_the_range() {
    let tmp = tempfile::tempdir().unwrap();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/labels/septum.nii.gz");
    write(
        &tmp.path().join("cases/a/seg.nii.gz"),
        &std::fs::read(&src).unwrap(),
    );
    let text = concat!(
        head!(),
        "[[structure]]\npattern = \"tumor\"\nsigma_mm = 50\n[[structure]]\npattern = \"vein\"\nsigma_mm = 1.6\n"
    );
    let cfg = config(tmp.path(), text);
    let out = destair(&["run", cfg.to_str().unwrap()]);
    assert!(!out.status.success());
    let r = report(tmp.path(), "a");
    let tumor = structure(&r, "tumor");
    assert_eq!(tumor["status"], "failed", "{tumor}");
    let error = tumor["error"].as_str().unwrap();
    assert!(
        error.contains("sigma_mm = 50") && error.contains("up to 1.6 mm"),
        "{error}"
    );
    // The largest sigma accepted (0.8 mm voxels: 1.6 mm) runs, and so does the default.
    assert_eq!(structure(&r, "vein")["status"], "ok");
    assert_eq!(structure(&r, "label_3")["status"], "ok");
    let bad = destair(&[
        "extract",
        src.to_str().unwrap(),
        "--out",
        tmp.path().join("x").to_str().unwrap(),
        "--sigma-mm",
        "1.7",
    ]);
    assert_eq!(bad.status.code(), Some(2));
    let said = stderr(&bad);
    assert!(
        said.contains("septum.nii.gz") && said.contains("up to 1.6 mm"),
        "{said}"
    );
    assert!(!tmp.path().join("x").join("extract.json").exists());
}
