//! End-to-end tests of the `destair` binary.

use crate::common;
use common::cohort::{destair, destair_ok};

/// Asserts a run succeeded, showing its stderr if not.
fn assert_ok(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn inspect_text_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("octa.ply");
    let mesh = common::reference_mesh();
    let meta = destair::io::MeshMeta {
        comments: vec!["SPACE=LPS".into()],
        obj_info: vec![],
    };
    destair::io::ply::write_ply(&path, &mesh, &meta, &[]).unwrap();
    let p = path.to_str().unwrap();

    let out = destair(&["inspect", p]);
    assert_ok(&out);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("vertices 7  triangles 8  edges 12"), "{text}");
    assert!(text.contains("1 unreferenced vertices"), "{text}");
    assert!(text.contains("comment: SPACE=LPS"), "{text}");

    let out = destair(&["inspect", p, "--json", "--read-mode", "read"]);
    assert!(out.status.success());
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["n_vertices"], 7);
    assert_eq!(json["n_triangles"], 8);
    assert_eq!(json["n_components"], 1);
    assert_eq!(json["euler_characteristic"], 2);
    assert_eq!(json["closed_oriented_manifold"], true);
    assert_eq!(json["format"], "ply_binary_little_endian");
    assert!(json["volume_mm3"].as_f64().unwrap() > 0.0);
}

#[test]
fn bad_input_exits_3_and_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.stl");
    std::fs::write(&path, vec![7u8; 200]).unwrap();
    let out = destair(&["inspect", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(3));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("broken.stl") && err.contains("declares"),
        "{err}"
    );

    let out = destair(&["inspect", dir.path().join("missing.ply").to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(3));
}

#[test]
fn usage_errors_exit_2() {
    assert_eq!(destair(&["frobnicate"]).status.code(), Some(2));
    assert_eq!(destair(&["inspect"]).status.code(), Some(2));
    assert_eq!(
        destair(&["--threads", "0", "inspect", "x.ply"])
            .status
            .code(),
        Some(2)
    );
}

#[test]
fn bench_io_runs_small() {
    let dir = tempfile::tempdir().unwrap();
    let out = destair(&[
        "bench",
        "io",
        "--triangles",
        "20000",
        "--repeat",
        "1",
        "--json",
        "--dir",
        dir.path().to_str().unwrap(),
    ]);
    assert_ok(&out);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let n = json["n_triangles"].as_u64().unwrap();
    assert!((19_000..=21_000).contains(&n), "{n}");
    assert!(json["read_mmap_s"].as_f64().unwrap() > 0.0);
    // Whole smooth processes ran (plain and with the context) and left no file behind.
    let process = &json["smooth_process"];
    assert!(process["plain_s"].as_f64().unwrap() > 0.0, "{process}");
    assert!(process["context_s"].as_f64().unwrap() > 0.0, "{process}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

/// `bench smooth` on a small phantom: every smoother timed, the three numberings giving the
/// same surface, and both bounds of the Laplace kernel reported and consistent.
#[test]
fn bench_smooth_reports_both_bounds() {
    let out = destair(&[
        "--threads",
        "2",
        "bench",
        "smooth",
        "--triangles",
        "20000",
        "--iterations",
        "2",
        "--repeat",
        "1",
        "--json",
    ]);
    assert_ok(&out);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let f = |key: &str| {
        json[key]
            .as_f64()
            .unwrap_or_else(|| panic!("{key}: {json}"))
    };
    assert_eq!(json["smoothers"].as_array().unwrap().len(), 8);
    for numbering in json["numberings"].as_array().unwrap() {
        assert!(
            numbering["passes_seconds"].as_f64().unwrap() > 0.0,
            "{numbering}"
        );
        assert!(
            numbering["max_difference_mm"].as_f64().unwrap() < 1e-3,
            "{numbering}"
        );
    }
    assert!(f("laplace_bound_s") > 0.0 && f("passes_one_thread_s") > 0.0);
    // Two Laplace iterations leave the blob without a fold.
    assert!(f("self_intersections_s") > 0.0 && json["self_intersections"] == 0);
    // The compute bound is the in-cache rate on every thread, for this mesh's updates.
    let updates = f("n_vertices") * f("iterations");
    let expected = updates / (f("in_cache_updates_per_s") * f("threads"));
    let bound = f("laplace_compute_bound_s");
    assert!(
        bound > 0.0 && (bound - expected).abs() <= 1e-9 * expected,
        "{bound} against {expected}"
    );
}

/// `bench context --shuffle` renumbers the vertices and lists the faces in another order: the
/// same surface, so the same query distances as in the phantom's own numbering (their mean summed
/// in the faces' order, so to the rounding of the sum).
#[test]
fn bench_context_shuffled_measures_the_same_surface() {
    let run = |shuffle: bool| {
        let mut args = vec!["bench", "context", "--triangles", "20000", "--repeat", "1"];
        if shuffle {
            args.push("--shuffle");
        }
        args.push("--json");
        let out = destair(&args);
        assert_ok(&out);
        serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()
    };
    let (plain, shuffled) = (run(false), run(true));
    assert_eq!(plain["shuffled"], false);
    assert_eq!(shuffled["shuffled"], true);
    assert_eq!(plain["n_vertices"], shuffled["n_vertices"]);
    let mean = |j: &serde_json::Value| j["far_mean_distance_mm"].as_f64().unwrap();
    assert!(mean(&plain) > 1.0, "{}", mean(&plain));
    let (a, b) = (mean(&plain), mean(&shuffled));
    assert!((a - b).abs() <= 1e-12 * a, "{a} against {b}");
}

#[test]
fn phantom_writes_meshes_and_description() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("neck");
    let run = destair(&[
        "phantom",
        "neck",
        "--out",
        out.to_str().unwrap(),
        "--seed",
        "4",
    ]);
    assert_ok(&run);
    for s in ["tumor", "vein", "trachea"] {
        let report = destair(&[
            "inspect",
            out.join(format!("{s}.ply")).to_str().unwrap(),
            "--json",
        ]);
        let json: serde_json::Value = serde_json::from_slice(&report.stdout).unwrap();
        assert_eq!(json["closed_oriented_manifold"], true, "{s}");
        assert_eq!(json["voxel_size"]["axes"][2]["mm"], 3.0, "{s}");
    }
    let info: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("phantom.json")).unwrap()).unwrap();
    assert_eq!(info["seed"], 4);
    assert_eq!(info["structures"].as_array().unwrap().len(), 3);

    let rotated = dir.path().join("rotated");
    let run = destair(&[
        "phantom",
        "sphere-aniso",
        "--rotate-x",
        "-30",
        "--out",
        rotated.to_str().unwrap(),
    ]);
    assert_ok(&run);
    let report = destair(&["inspect", rotated.join("sphere.ply").to_str().unwrap()]);
    let text = String::from_utf8(report.stdout).unwrap();
    assert!(
        text.contains("not a marching-cubes surface on an axis-aligned grid"),
        "{text}"
    );

    let cohort = dir.path().join("cohort");
    let run = destair(&[
        "phantom",
        "cohort",
        "--cases",
        "3",
        "--out",
        cohort.to_str().unwrap(),
    ]);
    assert!(run.status.success());
    let cases: Vec<_> = std::fs::read_dir(&cohort)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(cases.len(), 3);

    let bad = destair(&[
        "phantom",
        "dodecahedron",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown phantom"));
}

#[test]
fn smooth_then_compare() {
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("neck");
    destair_ok(&["phantom", "neck", "--out", case.to_str().unwrap()]);
    let tumor = case.join("tumor.ply");
    let vein = case.join("vein.ply");
    let out = dir.path().join("tumor-smooth.ply");
    for method in [
        "laplace",
        "hc",
        "taubin",
        "mcf",
        "npc",
        "cell-size",
        "cell-edge",
        "diamond",
    ] {
        let run = destair(&[
            "smooth",
            tumor.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--method",
            method,
            "--annotate",
        ]);
        assert!(
            run.status.success(),
            "{method}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        let cmp = destair(&[
            "compare",
            tumor.to_str().unwrap(),
            out.to_str().unwrap(),
            "--reference",
            vein.to_str().unwrap(),
            "--json",
        ]);
        assert!(cmp.status.success());
        let json: serde_json::Value = serde_json::from_slice(&cmp.stdout).unwrap();
        let c0 = json["normal_curvature_original_deg"].as_f64().unwrap();
        let c1 = json["normal_curvature_smoothed_deg"].as_f64().unwrap();
        assert!(c1 < c0, "{method}: curvature {c0} -> {c1}");
        assert_eq!(json["references"][0]["name"], "vein");
        assert!(json["displacement"]["max_mm"].as_f64().unwrap() > 0.0);
        assert_eq!(json["voxel_size_mm"][2], 3.0);
    }
    // The annotated output carries weight and displacement properties.
    let text = String::from_utf8_lossy(&std::fs::read(&out).unwrap()[..400]).into_owned();
    assert!(text.contains("property float weight") && text.contains("property float displacement"));
    // A rotated mesh has no reconstructable voxel size: constrained methods ask for --voxel.
    let rotated = dir.path().join("rot");
    destair_ok(&[
        "phantom",
        "sphere-iso",
        "--rotate-x",
        "20",
        "--out",
        rotated.to_str().unwrap(),
    ]);
    let run = destair(&[
        "smooth",
        rotated.join("sphere.ply").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--method",
        "diamond",
    ]);
    assert_eq!(run.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&run.stderr).contains("--voxel"));
    let run = destair(&[
        "smooth",
        rotated.join("sphere.ply").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--method",
        "diamond",
        "--voxel",
        "1,1,1",
    ]);
    assert!(run.status.success());
    // Weights from a PLY property: weight 0 everywhere leaves the mesh as it was.
    let zero = dir.path().join("zero.ply");
    let loaded = destair::io::read_mesh(&tumor, &Default::default()).unwrap();
    let w = vec![0.0f32; loaded.mesh.n_vertices()];
    destair::io::ply::write_ply(&zero, &loaded.mesh, &loaded.meta, &[("weight", &w)]).unwrap();
    let run = destair(&[
        "smooth",
        tumor.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--method",
        "laplace",
        "--weights",
        zero.to_str().unwrap(),
    ]);
    assert_ok(&run);
    let smoothed = destair::io::read_mesh(&out, &Default::default()).unwrap();
    assert_eq!(smoothed.mesh.positions(), loaded.mesh.positions());
}

#[test]
fn inspect_context_and_context_aware_smoothing() {
    let dir = tempfile::tempdir().unwrap();
    let an = dir.path().join("an");
    destair_ok(&["phantom", "aneurysm", "--out", an.to_str().unwrap()]);
    let mesh = an.join("aneurysm.ply");
    let export = dir.path().join("weights.ply");
    let out = destair(&[
        "inspect",
        mesh.to_str().unwrap(),
        "--context",
        "--json",
        "--export",
        export.to_str().unwrap(),
    ]);
    assert_ok(&out);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // An isotropic grid: the estimate, set to its nearest grid axis.
    assert_eq!(json["context"]["axis_source"], "estimate_on_grid");
    assert_eq!(json["context"]["caps"].as_array().unwrap().len(), 3);
    assert!(json["context"]["n_staircase_vertices"].as_u64().unwrap() > 0);
    let options = destair::io::ReadOptions {
        keep_vertex_properties: true,
        ..Default::default()
    };
    let w = destair::io::read_mesh(&export, &options).unwrap();
    let names: Vec<&str> = w
        .vertex_properties
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    assert_eq!(
        names,
        [
            "weight",
            "staircase",
            "cap",
            "staircase_distance",
            "quality"
        ]
    );
    // `quality` repeats the weight, for MeshLab.
    assert_eq!(w.vertex_properties[4].values, w.vertex_properties[0].values);
    // Cap vertices have weight 0 (preserved).
    let (weight, cap) = (
        &w.vertex_properties[0].values,
        &w.vertex_properties[2].values,
    );
    assert!(cap
        .iter()
        .zip(weight)
        .all(|(&c, &wv)| c == 0.0 || wv == 0.0));

    // Given axis, staircase smoothing: caps stay exactly in place.
    let smoothed = dir.path().join("s.ply");
    let run = destair(&[
        "smooth",
        mesh.to_str().unwrap(),
        "-o",
        smoothed.to_str().unwrap(),
        "--method",
        "hc",
        "--staircase",
        "--axis",
        "0,0,1",
    ]);
    assert_ok(&run);
    assert!(String::from_utf8_lossy(&run.stderr).contains("stack axis (given)"));
    let a = destair::io::read_mesh(&mesh, &Default::default())
        .unwrap()
        .mesh;
    let b = destair::io::read_mesh(&smoothed, &Default::default())
        .unwrap()
        .mesh;
    for (v, &c) in cap.iter().enumerate() {
        if c == 1.0 {
            assert_eq!(a.positions()[v], b.positions()[v]);
        }
    }
    assert_ne!(a.positions(), b.positions());

    // Bad context options are usage errors.
    for bad in [
        ["--axis", "0,0,0"],
        ["--distance-scaling", "ramp:5,1"],
        ["--tau", "3"],
    ] {
        let run = destair(&[
            "inspect",
            mesh.to_str().unwrap(),
            "--context",
            bad[0],
            bad[1],
        ]);
        assert_eq!(run.status.code(), Some(2), "{bad:?}");
    }
}

#[test]
fn inspect_patches_names_the_inlet_and_fails_on_a_wrong_count() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    destair_ok(&["phantom", "aneurysm", "--open-ends", "--out", d]);
    let mesh = dir.path().join("aneurysm.ply");
    let m = mesh.to_str().unwrap();

    let out = destair(&["inspect", m, "--patches", "--json"]);
    assert_ok(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let patches = v["patches"]["patches"].as_array().unwrap();
    let names: Vec<&str> = patches
        .iter()
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["inlet", "outlet_1", "outlet_2"]);
    assert_eq!(patches[0]["id"], 2);
    assert_eq!(patches[0]["kind"], "open_end");
    let area = |p: &serde_json::Value| p["area_mm2"].as_f64().unwrap();
    assert!(area(&patches[0]) > area(&patches[1]));

    // The inlet named by a point near the second outlet's centre.
    let c: Vec<f64> = patches[2]["centre_mm"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let point = format!("{},{},{}", c[0] + 0.5, c[1], c[2]);
    let out = destair(&["inspect", m, "--patches", "--inlet", &point]);
    assert_ok(&out);
    let text = String::from_utf8(out.stdout).unwrap();
    let inlet_line = text.lines().find(|l| l.contains(" inlet ")).unwrap();
    assert!(inlet_line.contains(&format!("{:.3}", c[0])), "{text}");

    let out = destair(&["inspect", m, "--patches", "--expect-patches", "2"]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("3 patches found, 2 expected"), "{err}");
    assert!(err.contains("aneurysm.ply"), "{err}");

    let files = dir.path().join("files");
    let f = files.to_str().unwrap();
    let out = destair(&["inspect", m, "--patches", "--patch-files", f]);
    assert_eq!(out.status.code(), Some(2), "the folder does not exist");
    std::fs::create_dir(&files).unwrap();
    let out = destair(&[
        "inspect",
        m,
        "--patches",
        "--close-open-ends",
        "--patch-files",
        f,
    ]);
    assert_ok(&out);
    let solids = std::fs::read_to_string(files.join("aneurysm_solids.stl")).unwrap();
    let names: Vec<&str> = solids
        .lines()
        .filter_map(|l| l.strip_prefix("solid "))
        .collect();
    assert_eq!(names, ["wall", "inlet", "outlet_1", "outlet_2"]);
    assert!(files.join("aneurysm.vtp").is_file());
    let out = destair(&["inspect", m, "--close-open-ends"]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "--close-open-ends needs --patch-files"
    );

    let map = dir.path().join("seg.nii.gz");
    let (volume, _) =
        destair::phantom::cases::label_map_case("labelmap-neck", &Default::default()).unwrap();
    std::fs::write(&map, destair::volume::nifti::encode(&volume, true).unwrap()).unwrap();
    let out = destair(&["inspect", map.to_str().unwrap(), "--patches"]);
    assert_eq!(out.status.code(), Some(2), "a label map has no patches");

    let out = destair(&["inspect", m, "--patches", "--inlet", "1,2"]);
    assert_eq!(out.status.code(), Some(2));
    let out = destair(&["inspect", m, "--inlet", "0"]);
    assert_eq!(out.status.code(), Some(2), "--inlet needs --patches");
}

#[test]
fn smooth_with_the_cfd_profile_writes_checked_patch_files_with_planar_caps_and_extensions() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (folder, extra) in [("capped", None), ("open", Some("--open-ends"))] {
        let out = d.join(folder);
        let mut args = vec![
            "phantom",
            "aneurysm",
            "--rotate-x",
            "30",
            "--rotate-y",
            "45",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        assert_ok(&destair(&args));
    }
    let smoothed = d.join("cfd");
    std::fs::create_dir(&smoothed).unwrap();
    for (folder, close) in [("capped", false), ("open", true)] {
        let input = d.join(folder).join("aneurysm.ply");
        let output = smoothed.join(format!("{folder}.ply"));
        let mut args = vec!["--iterations", "20", "--profile", "cfd", "--edge-mm", "0.4"];
        if close {
            args.push("--close-open-ends");
        } else {
            args.extend(["--flow-extension", "5"]);
        }
        let run = common::cohort::smooth(&input, &output, "taubin", &args);
        assert_ok(&run);
        let text = String::from_utf8_lossy(&run.stdout);
        assert!(text.contains("checks passed: watertight,"), "{text}");
        // Caps (and closed ends) planar after smoothing and remeshing.
        let json: serde_json::Value = serde_json::from_slice(
            &std::fs::read(smoothed.join(format!("{folder}_patches.json"))).unwrap(),
        )
        .unwrap();
        let patches = json["patches"].as_array().unwrap();
        assert_eq!(patches.len(), 3, "{json}");
        for p in patches {
            let off = p["planarity_mm"].as_f64().unwrap();
            assert!(off < 1e-5, "{folder} {}: {off} mm off its plane", p["name"]);
            let extension = p["extension_mm"].as_f64().unwrap();
            let diameter = p["diameter_mm"].as_f64().unwrap();
            if close {
                assert_eq!(extension, 0.0);
            } else {
                assert!(
                    (extension / diameter - 5.0).abs() < 0.2,
                    "{extension} {diameter}"
                );
            }
        }
        // The written surface is the checked one: closed and oriented.
        let mesh = destair::io::read_mesh(&output, &Default::default())
            .unwrap()
            .mesh;
        let topology = destair::Topology::build(&mesh);
        assert!(topology.is_closed_oriented_manifold());
        for name in [
            "solids.stl",
            "wall.stl",
            "inlet.stl",
            "outlet_1.stl",
            "outlet_2.stl",
        ] {
            assert!(
                smoothed.join(format!("{folder}_{name}")).is_file(),
                "{name}"
            );
        }
    }
    // A wrong patch count: refused, nothing written.
    let input = d.join("capped").join("aneurysm.ply");
    let output = smoothed.join("wrong.ply");
    let run = common::cohort::smooth(
        &input,
        &output,
        "taubin",
        &["--profile", "cfd", "--expect-patches", "2"],
    );
    assert!(!run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(err.contains("3 patches found, 2 expected"), "{err}");
    assert!(!output.exists() && !smoothed.join("wrong_patches.json").exists());
}

#[test]
fn the_cfd_profile_refuses_a_vessel_that_smoothing_pinched() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Open where it leaves the volume: its capped ends, two voxels across, have too few flat
    // faces to be told from the flat strips along it, and those strips are no ends.
    destair_ok(&[
        "phantom",
        "thin-vessel",
        "--open-ends",
        "--out",
        d.to_str().unwrap(),
    ]);
    let input = d.join("vessel.ply");
    let run = |method: &str, out: &str| {
        common::cohort::smooth(
            &input,
            &d.join(out),
            method,
            &[
                "--iterations",
                "20",
                "--profile",
                "cfd",
                "--staircase",
                "false",
            ],
        )
    };
    // Uniform Laplace shrinks the two-voxel vessel to a third of its narrowest lumen.
    let pinched = run("laplace", "laplace.ply");
    assert!(!pinched.status.success());
    let err = String::from_utf8_lossy(&pinched.stderr);
    assert!(err.contains("pinched the vessel"), "{err}");
    assert!(!d.join("laplace.ply").exists() && !d.join("laplace_patches.json").exists());
    // Taubin keeps it.
    let kept = run("taubin", "taubin.ply");
    assert_ok(&kept);
    assert!(d.join("taubin_patches.json").is_file());
}

/// `smooth` with a cohort's settings gives the bytes the cohort run gives: the same defaults
/// (Laplace+HC, staircase weighting on, caps preserved, tau auto) and the same meaning of each
/// switch, whichever way round they are set.
#[test]
fn smooth_gives_the_cohort_runs_bytes_for_the_same_settings() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    destair_ok(&[
        "phantom",
        "cap-cylinder",
        "--out",
        root.join("phantom").to_str().unwrap(),
    ]);
    std::fs::create_dir_all(root.join("cases/c1")).unwrap();
    let input = root.join("cases/c1/vessel.ply");
    std::fs::copy(root.join("phantom/cap-cylinder.ply"), &input).unwrap();
    for (i, (config, flags)) in [
        ("", vec![]),
        (
            "method = \"hc\"\nstaircase = true\ncaps = \"preserve\"\ntau = \"auto\"\n",
            vec![
                "--method",
                "hc",
                "--staircase",
                "--caps",
                "preserve",
                "--tau",
                "auto",
            ],
        ),
        ("staircase = false\n", vec!["--staircase", "false"]),
        ("caps = \"smooth\"\n", vec!["--caps", "smooth"]),
        (
            "method = \"laplace\"\nstaircase = false\ncaps = \"smooth\"\n",
            vec![
                "--method",
                "laplace",
                "--staircase",
                "false",
                "--caps",
                "smooth",
            ],
        ),
        (
            "method = \"taubin\"\ntau = 0.3\nbeta_min = 0.0\n",
            vec!["--method", "taubin", "--tau", "0.3", "--beta-min", "0"],
        ),
    ]
    .into_iter()
    .enumerate()
    {
        let out = root.join(format!("out{i}"));
        let toml = format!(
            "[input]\nroots = [\"cases\"]\ncase_depth = 1\n\n[output]\nroot = \"{}\"\n\n[defaults]\n{config}",
            out.file_name().unwrap().to_str().unwrap()
        );
        let config_path = root.join(format!("c{i}.toml"));
        std::fs::write(&config_path, toml).unwrap();
        destair_ok(&["run", config_path.to_str().unwrap()]);
        let single = root.join(format!("single{i}.ply"));
        let mut args = vec![
            "smooth",
            input.to_str().unwrap(),
            "-o",
            single.to_str().unwrap(),
        ];
        if !flags.contains(&"--method") {
            args.extend(["--method", "hc"]);
        }
        args.extend(flags.iter().copied());
        assert_ok(&destair(&args));
        let cohort = std::fs::read(out.join("c1/vessel.ply")).unwrap();
        assert!(
            cohort == std::fs::read(&single).unwrap(),
            "settings {i}: {config:?} / {flags:?} differ"
        );
        if i > 0 {
            // Each switch changes the result (the settings are not all ignored).
            let first = std::fs::read(root.join("out0/c1/vessel.ply")).unwrap();
            assert_eq!(cohort == first, i == 1, "settings {i}");
        }
    }
}

/// A file whose vertex numbering and face order are scattered is worked in scanline order, its
/// faces sorted by vertex, and written back in its own numbering and face order: `smooth` and a
/// cohort run write the same bytes, the faces are the file's, the annotations belong to the
/// file's vertices, and the surface is the one the unscattered file gives, to float rounding.
#[test]
fn a_scattered_numbering_is_worked_in_scanline_order_and_written_back() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    // A stair-stepped blob of about 75 k vertices: enough that a shuffle scatters it.
    let case = destair::phantom::big_case(150_000, &Default::default());
    let plain = case.meshes.into_iter().next().unwrap().1;
    let old = destair::bench::permutation(plain.n_vertices(), 3);
    let shuffled = destair::bench::relisted(
        &destair::bench::renumbered(&plain, &old),
        &destair::bench::permutation(plain.n_triangles(), 4),
    );
    assert!(destair::mesh::order::working_numbering(&plain).is_none());
    let working = destair::mesh::order::working_numbering(&shuffled);
    assert!(working.is_some_and(|r| r.faces.is_some()));
    let meta = destair::io::MeshMeta::default();
    std::fs::create_dir_all(root.join("cases/c1")).unwrap();
    let input = root.join("cases/c1/blob.ply");
    destair::io::ply::write_ply(&input, &shuffled, &meta, &[]).unwrap();
    let plain_path = root.join("plain.ply");
    destair::io::ply::write_ply(&plain_path, &plain, &meta, &[]).unwrap();
    std::fs::write(
        root.join("c.toml"),
        "[input]\nroots = [\"cases\"]\ncase_depth = 1\n\n[output]\nroot = \"out\"\n",
    )
    .unwrap();
    destair_ok(&["run", root.join("c.toml").to_str().unwrap()]);
    let smooth = |from: &std::path::Path, to: &str, extra: &[&str]| {
        let out = root.join(to);
        let mut args = vec![
            "smooth",
            from.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        assert_ok(&destair(&args));
        out
    };
    let single = smooth(&input, "single.ply", &[]);
    assert!(
        std::fs::read(root.join("out/c1/blob.ply")).unwrap() == std::fs::read(&single).unwrap()
    );
    let read = |p: &std::path::Path| {
        let options = destair::io::ReadOptions {
            keep_vertex_properties: true,
            ..Default::default()
        };
        destair::io::read_mesh(p, &options).unwrap()
    };
    // The file's faces, and vertex i of the output is vertex i of the file, moved a little.
    let done = read(&single).mesh;
    assert!(done.triangles() == shuffled.triangles());
    let reference = read(&smooth(&plain_path, "plain_out.ply", &[])).mesh;
    let mut largest = 0.0f32;
    for (i, &o) in old.iter().enumerate() {
        let (p, q) = (done.positions()[i], reference.positions()[o as usize]);
        largest = (0..3).map(|k| (p[k] - q[k]).abs()).fold(largest, f32::max);
    }
    // Float rounding of coordinates up to about 100 mm (a few units in the last place).
    assert!(
        largest < 1e-4,
        "the shuffled file's surface differs by {largest} mm"
    );
    let moved = done
        .positions()
        .iter()
        .zip(shuffled.positions())
        .filter(|(p, q)| p != q)
        .count();
    assert!(moved > plain.n_vertices() / 10, "{moved} vertices moved");
    // Annotations: each vertex's displacement is its own.
    let annotated = read(&smooth(&input, "annotated.ply", &["--annotate"]));
    let displacement = annotated
        .vertex_properties
        .iter()
        .find(|p| p.name == "displacement")
        .unwrap();
    for (i, (p, q)) in annotated
        .mesh
        .positions()
        .iter()
        .zip(shuffled.positions())
        .enumerate()
    {
        let d = (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f32>().sqrt();
        assert!((d - displacement.values[i]).abs() < 1e-4, "vertex {i}");
    }
    // A cohort's annotations too, and its weights are `smooth`'s.
    std::fs::write(
        root.join("a.toml"),
        "[input]\nroots = [\"cases\"]\ncase_depth = 1\n\n[output]\nroot = \"out_a\"\nannotate = true\n",
    )
    .unwrap();
    destair_ok(&["run", root.join("a.toml").to_str().unwrap()]);
    let cohort = read(&root.join("out_a/c1/blob.ply"));
    assert!(cohort.mesh.positions() == annotated.mesh.positions());
    let values = |m: &destair::io::LoadedMesh, name: &str| {
        let p = m.vertex_properties.iter().find(|p| p.name == name);
        p.unwrap().values.clone()
    };
    for name in ["weight", "displacement"] {
        assert!(values(&cohort, name) == values(&annotated, name), "{name}");
    }
    // A weights file in the file's numbering: each vertex takes its own weight (here 0 below
    // the middle height, which holds those vertices in place, and 1 above).
    let middle = {
        let mut z: Vec<f32> = plain.positions().iter().map(|p| p[2]).collect();
        z.sort_by(f32::total_cmp);
        z[z.len() / 2]
    };
    let weights_of = |m: &destair::Mesh| -> Vec<f32> {
        let w = m.positions().iter().map(|p| f32::from(p[2] >= middle));
        w.collect()
    };
    let with_weights = |mesh: &destair::Mesh, from: &std::path::Path, name: &str| {
        let w = root.join(format!("{name}_weights.ply"));
        let weights = weights_of(mesh);
        destair::io::ply::write_ply(&w, mesh, &meta, &[("weight", &weights)]).unwrap();
        let out = smooth(
            from,
            &format!("{name}_weighted.ply"),
            &["--weights", w.to_str().unwrap()],
        );
        (read(&out).mesh, weights)
    };
    let (weighted, weights) = with_weights(&shuffled, &input, "shuffled");
    let (reference, _) = with_weights(&plain, &plain_path, "plain");
    let mut largest = 0.0f32;
    for (i, &o) in old.iter().enumerate() {
        let (p, q) = (weighted.positions()[i], reference.positions()[o as usize]);
        largest = (0..3).map(|k| (p[k] - q[k]).abs()).fold(largest, f32::max);
        if weights[i] == 0.0 {
            assert!(p == shuffled.positions()[i], "vertex {i} of weight 0 moved");
        }
    }
    assert!(largest < 1e-4, "weighted: {largest} mm");
    assert!(weighted.positions() != done.positions());
    // `inspect` works the scattered file in its working order too: the ordered file's report
    // (sums to rounding), and an export whose arrays belong to the file's vertices.
    let inspect = |from: &std::path::Path, export: &str| {
        let path = root.join(export);
        let out = destair(&[
            "inspect",
            from.to_str().unwrap(),
            "--context",
            "--json",
            "--export",
            path.to_str().unwrap(),
        ]);
        assert_ok(&out);
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        (json, read(&path))
    };
    let ((a, exported_a), (b, exported_b)) = (
        inspect(&plain_path, "plain_export.ply"),
        inspect(&input, "shuffled_export.ply"),
    );
    for key in ["n_vertices", "n_triangles", "n_edges", "n_components"] {
        assert_eq!(a[key], b[key], "{key}");
    }
    assert_eq!(a["context"]["caps"], b["context"]["caps"]);
    for key in ["area_mm2", "volume_mm3", "average_normal_curvature_deg"] {
        let (x, y) = (a[key].as_f64().unwrap(), b[key].as_f64().unwrap());
        assert!((x - y).abs() <= 1e-9 * x.abs(), "{key}: {x} against {y}");
    }
    assert!(exported_b.mesh.triangles() == shuffled.triangles());
    for (p, q) in exported_a
        .vertex_properties
        .iter()
        .zip(&exported_b.vertex_properties)
    {
        assert_eq!(p.name, q.name);
        for (i, &o) in old.iter().enumerate() {
            let (x, y) = (q.values[i], p.values[o as usize]);
            assert!(
                (x - y).abs() <= 1e-4,
                "{} of vertex {i}: {x} against {y}",
                p.name
            );
        }
    }
}

/// `compare` measures a scattered pair (a shuffled mesh and its moved copy, numbered alike) in
/// scanline order: the same report as the unscattered pair, but for the rounding of sums.
#[test]
fn compare_gives_a_scattered_pair_the_measures_of_the_unscattered_one() {
    let dir = tempfile::tempdir().unwrap();
    let case = destair::phantom::big_case(150_000, &Default::default());
    let plain = case.meshes.into_iter().next().unwrap().1;
    let mut moved = plain.clone();
    for (i, p) in moved.positions_mut().iter_mut().enumerate() {
        p[i % 3] += 0.05 * ((i % 7) as f32 - 3.0);
    }
    let old = destair::bench::permutation(plain.n_vertices(), 5);
    let meta = destair::io::MeshMeta::default();
    let mut reports = Vec::new();
    for (tag, a, b) in [
        ("plain", plain.clone(), moved.clone()),
        (
            "shuffled",
            destair::bench::renumbered(&plain, &old),
            destair::bench::renumbered(&moved, &old),
        ),
    ] {
        let (pa, pb) = (
            dir.path().join(format!("{tag}_a.ply")),
            dir.path().join(format!("{tag}_b.ply")),
        );
        destair::io::ply::write_ply(&pa, &a, &meta, &[]).unwrap();
        destair::io::ply::write_ply(&pb, &b, &meta, &[]).unwrap();
        let out = destair(&[
            "compare",
            pa.to_str().unwrap(),
            pb.to_str().unwrap(),
            "--json",
        ]);
        assert_ok(&out);
        reports.push(serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap());
    }
    assert!(
        destair::mesh::order::working_numbering(&destair::bench::renumbered(&plain, &old))
            .is_some()
    );
    let (p, s) = (&reports[0], &reports[1]);
    // Maxima and sums over faces in the same order are the same to the bit.
    for path in [
        "/distance/hausdorff_mm",
        "/distance/a_to_b_max_mm",
        "/distance/b_to_a_max_mm",
        "/volume_original_mm3",
        "/volume_smoothed_mm3",
        "/min_triangle_angle_smoothed_deg",
        "/displacement/max_mm",
    ] {
        assert_eq!(p.pointer(path), s.pointer(path), "{path}");
        assert!(p.pointer(path).is_some_and(|v| v.is_number()), "{path}");
    }
    // Means and curvature: sums over vertices and edges in another order.
    for path in [
        "/distance/mean_mm",
        "/normal_curvature_original_deg",
        "/normal_curvature_smoothed_deg",
        "/displacement/mean_mm",
    ] {
        let (a, b) = (
            p.pointer(path).and_then(|v| v.as_f64()).unwrap(),
            s.pointer(path).and_then(|v| v.as_f64()).unwrap(),
        );
        assert!((a - b).abs() <= 1e-12 * a.abs(), "{path}: {a} against {b}");
    }
}

/// An output that cannot be written (a name too long for the filesystem; a full disk alike)
/// is bad input to the command, exit 3, with the file named and the reason said once; not an
/// internal error.
#[test]
fn outputs_that_cannot_be_written_exit_3_naming_the_file_once() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    common::cohort::destair_ok(&["phantom", "neck", "--out", dir.to_str().unwrap()]);
    let long = dir.join(format!("{}.ply", "a".repeat(300)));
    let run = common::cohort::smooth(&dir.join("tumor.ply"), &long, "laplace", &[]);
    let err = common::cohort::stderr(&run);
    assert_eq!(run.status.code(), Some(3), "{err}");
    assert!(err.contains(&"a".repeat(300)), "{err}");
    assert_eq!(err.matches("File name too long").count(), 1, "{err}");
    // A Slicer segment whose name makes a file name too long: extract says which file.
    let seg = dir.join("long.seg.nrrd");
    let mut b = format!("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspace: LPS\nspace directions: (1,0,0) (0,1,0) (0,0,2)\nencoding: raw\nSegment0_Name:={}\nSegment0_LabelValue:=1\nSegment0_Layer:=0\n\n", "b".repeat(300)).into_bytes();
    b.extend([1u8, 1, 0, 0, 0, 0, 0, 0]);
    std::fs::write(&seg, b).unwrap();
    let run = common::cohort::destair(&[
        "extract",
        seg.to_str().unwrap(),
        "--out",
        dir.join("ex").to_str().unwrap(),
    ]);
    let err = common::cohort::stderr(&run);
    assert_eq!(run.status.code(), Some(3), "{err}");
    assert!(err.contains(&"b".repeat(300)), "{err}");
    assert_eq!(err.matches("File name too long").count(), 1, "{err}");
    // Any command: a folder that cannot be made is the disk's problem, not an internal error.
    let run = common::cohort::destair(&[
        "phantom",
        "neck",
        "--out",
        dir.join("c".repeat(300)).to_str().unwrap(),
    ]);
    let err = common::cohort::stderr(&run);
    assert_eq!(run.status.code(), Some(3), "{err}");
    assert_eq!(err.matches("File name too long").count(), 1, "{err}");
}
