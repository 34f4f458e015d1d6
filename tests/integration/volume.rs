//! Label maps in: NIfTI-1 and NRRD round trips with oblique, anisotropic grids in LPS and RAS,
//! qform-only NIfTI, detached NRRD headers, Slicer segment names and layers, and bad headers
//! (zero spacing, singular directions, sizes that do not match, truncated gzip, mutations),
//! which give errors naming the file and never a panic.

use destair::volume::{nifti, nrrd, read_label_map, Grid, LabelVolume, Segment, Space};

/// A random oblique grid: a random rotation, anisotropic spacing, and an origin.
fn random_grid(rng: &mut fastrand::Rng, space: Space) -> Grid {
    let q: [f64; 4] = [
        rng.f64() - 0.5,
        rng.f64() - 0.5,
        rng.f64() - 0.5,
        rng.f64() - 0.5,
    ];
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    let [a, b, c, d] = q.map(|x| x / n);
    let rot = destair::volume::grid::quaternion_rotation(a, b, c, d);
    let spacing = [0.3 + rng.f64(), 0.3 + rng.f64(), 1.0 + 3.0 * rng.f64()];
    let mut matrix = [[0.0; 3]; 3];
    for r in 0..3 {
        for col in 0..3 {
            matrix[r][col] = rot[r][col] * spacing[col];
        }
    }
    let origin = [
        100.0 * rng.f64() - 50.0,
        100.0 * rng.f64() - 50.0,
        100.0 * rng.f64() - 50.0,
    ];
    Grid {
        matrix,
        origin,
        space,
    }
}

fn random_volume(rng: &mut fastrand::Rng, space: Space) -> LabelVolume {
    let dims = [rng.usize(2..12), rng.usize(2..12), rng.usize(2..9)];
    let n = dims.iter().product::<usize>();
    let values = [0i64, 0, 0, 1, 2, 3, 7, 300, -5];
    let raw: Vec<i64> = (0..n).map(|_| values[rng.usize(..values.len())]).collect();
    LabelVolume::from_values(dims, random_grid(rng, space), raw.into_iter()).unwrap()
}

fn assert_same_grid(a: &Grid, b: &Grid, tol: f64) {
    assert_eq!(a.space, b.space);
    for r in 0..3 {
        assert!((a.origin[r] - b.origin[r]).abs() < tol, "{a:?} vs {b:?}");
        for c in 0..3 {
            assert!(
                (a.matrix[r][c] - b.matrix[r][c]).abs() < tol,
                "{a:?} vs {b:?}"
            );
        }
    }
}

#[test]
fn nifti_and_nrrd_round_trip_oblique_grids_in_either_space() {
    let mut rng = fastrand::Rng::with_seed(3);
    let dir = tempfile::tempdir().unwrap();
    for round in 0..40 {
        let space = if rng.bool() { Space::Lps } else { Space::Ras };
        let v = random_volume(&mut rng, space);
        let gz = rng.bool();
        let files = [
            (
                format!("v{round}.nii{}", if gz { ".gz" } else { "" }),
                nifti::encode(&v, gz).unwrap(),
            ),
            (
                format!("v{round}.nrrd"),
                nrrd::encode(std::slice::from_ref(&v), &[], gz).unwrap(),
            ),
        ];
        for (name, bytes) in files {
            let path = dir.path().join(&name);
            std::fs::write(&path, &bytes).unwrap();
            for want in [Space::Lps, Space::Ras] {
                let map = read_label_map(&path, want).unwrap();
                let got = &map.layers[0];
                assert_eq!(got.dims, v.dims, "{name}");
                assert_eq!(got.voxels, v.voxels, "{name}");
                assert_eq!(got.labels, v.labels, "{name}");
                // NIfTI stores f32: a few micrometres.
                assert_same_grid(&got.grid, &v.grid.in_space(want), 1e-4);
            }
        }
    }
}

#[test]
fn qform_only_nifti_gives_the_same_grid_as_its_sform() {
    let mut rng = fastrand::Rng::with_seed(5);
    let dir = tempfile::tempdir().unwrap();
    for round in 0..30 {
        let v = random_volume(&mut rng, Space::Ras);
        let mut bytes = nifti::encode(&v, false).unwrap();
        bytes[254..256].copy_from_slice(&0i16.to_le_bytes()); // sform_code 0: qform only
        let path = dir.path().join(format!("q{round}.nii"));
        std::fs::write(&path, &bytes).unwrap();
        let got = read_label_map(&path, Space::Ras).unwrap();
        assert_same_grid(&got.layers[0].grid, &v.grid, 1e-4);
        // Neither form: pixdim scaling with a warning.
        bytes[252..254].copy_from_slice(&0i16.to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        let got = read_label_map(&path, Space::Ras).unwrap();
        assert!(got.warnings[0].contains("neither sform nor qform"));
    }
}

#[test]
fn sform_and_qform_that_disagree_are_a_warning_naming_both() {
    let mut rng = fastrand::Rng::with_seed(9);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("q.nii");
    for round in 0..10 {
        let v = random_volume(&mut rng, Space::Ras);
        let mut bytes = nifti::encode(&v, false).unwrap();
        // Both forms as written: they agree (float32 storage alone), no warning.
        std::fs::write(&path, &bytes).unwrap();
        let got = read_label_map(&path, Space::Ras).unwrap();
        assert!(got.warnings.is_empty(), "{round}: {:?}", got.warnings);
        // The qform's offset (qoffset_x, bytes 268-271) moved by 5 mm: the sform still places
        // the grid, and the warning names both placements.
        let at = 268;
        let x = f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        bytes[at..at + 4].copy_from_slice(&(x + 5.0).to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        let got = read_label_map(&path, Space::Ras).unwrap();
        assert_same_grid(&got.layers[0].grid, &v.grid, 1e-4);
        let w = got.warnings.join("; ");
        assert!(
            w.contains("the sform and the qform place the grid differently")
                && w.contains("5.000 mm apart")
                && w.contains("the sform is used"),
            "{round}: {w}"
        );
    }
}

#[test]
fn slicer_segments_name_labels_and_layers_hold_overlaps() {
    let dir = tempfile::tempdir().unwrap();
    let g = Grid::axis_aligned([0.5, 0.5, 2.0], [1.0, 2.0, 3.0], Space::Lps);
    let a = LabelVolume::from_values(
        [3, 2, 2],
        g,
        [1i64, 1, 0, 2, 2, 0, 0, 0, 1, 1, 1, 0].into_iter(),
    )
    .unwrap();
    let b = LabelVolume::from_values(
        [3, 2, 2],
        g,
        [0i64, 3, 3, 0, 0, 0, 0, 0, 0, 0, 0, 3].into_iter(),
    )
    .unwrap();
    let segments = [
        Segment {
            name: "tumor".into(),
            value: 1,
            layer: 0,
        },
        Segment {
            name: "vena jugularis".into(),
            value: 2,
            layer: 0,
        },
        Segment {
            name: "trachea".into(),
            value: 3,
            layer: 1,
        },
    ];
    let path = dir.path().join("case.seg.nrrd");
    std::fs::write(
        &path,
        nrrd::encode(&[a.clone(), b.clone()], &segments, true).unwrap(),
    )
    .unwrap();
    let map = read_label_map(&path, Space::Lps).unwrap();
    assert_eq!(map.layers.len(), 2);
    assert_eq!(map.layers[0].voxels, a.voxels);
    assert_eq!(map.layers[1].voxels, b.voxels);
    let names: Vec<&str> = map
        .layers
        .iter()
        .flat_map(|l| l.labels.iter().map(|x| x.name.as_str()))
        .collect();
    assert_eq!(names, ["tumor", "vena jugularis", "trachea"]);
    assert_eq!(map.segments, segments);
    // Slicer's own header text: as 3D Slicer 5 writes a one-layer segmentation.
    let header = "NRRD0004\n# Complete NRRD file format specification at:\n# http://teem.sourceforge.net/nrrd/format.html\ntype: unsigned char\ndimension: 3\nspace: left-posterior-superior\nsizes: 2 2 1\nspace directions: (0.8,0,0) (0,0.8,0) (0,0,3)\nkinds: domain domain domain\nencoding: raw\nspace origin: (-10,-20,30)\nSegment0_Color:=0.5 0.68 0.5\nSegment0_ID:=Segment_1\nSegment0_LabelValue:=1\nSegment0_Layer:=0\nSegment0_Name:=liver\nSegment0_Tags:=Segmentation.Status:inprogress|\nSegmentation_MasterRepresentation:=Binary labelmap\n\n";
    let mut bytes = header.as_bytes().to_vec();
    bytes.extend([0u8, 1, 1, 0]);
    std::fs::write(&path, &bytes).unwrap();
    let map = read_label_map(&path, Space::Lps).unwrap();
    assert_eq!(map.layers[0].labels[0].name, "liver");
    assert_eq!(map.layers[0].labels[0].n_voxels, 2);
    let w = map.layers[0].grid.world([1.0, 1.0, 0.0]);
    assert_eq!(w, [-9.2, -19.2, 30.0]);
}

#[test]
fn detached_nrrd_headers_read_their_data_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("v.raw"), [0u8, 0, 5, 5, 5, 0, 0, 0]).unwrap();
    let nhdr = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspace: RAS\nspace directions: (1,0,0) (0,1,0) (0,0,2)\nencoding: raw\ndata file: v.raw\n";
    let path = dir.path().join("v.nhdr");
    std::fs::write(&path, nhdr).unwrap();
    let map = read_label_map(&path, Space::Lps).unwrap();
    assert_eq!(map.layers[0].labels[0].value, 5);
    assert_eq!(map.layers[0].labels[0].n_voxels, 3);
    // RAS read as LPS: x and y negated.
    assert_eq!(map.layers[0].grid.world([1.0, 1.0, 1.0]), [-1.0, -1.0, 2.0]);
}

#[test]
fn bad_headers_name_the_file_and_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let good = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspace: LPS\nspace directions: (1,0,0) (0,1,0) (0,0,2)\nencoding: raw\n\n";
    let cases: [(&str, String, Vec<u8>); 8] = [
        (
            "zero spacing",
            good.replace("(0,0,2)", "(0,0,0)"),
            vec![0; 8],
        ),
        ("singular", good.replace("(0,1,0)", "(1,0,0)"), vec![0; 8]),
        ("short data", good.to_string(), vec![0; 7]),
        (
            "lying sizes",
            good.replace("sizes: 2 2 2", "sizes: 1000000 1000000 1000000"),
            vec![0; 8],
        ),
        ("float", good.replace("uchar", "float"), vec![0; 32]),
        ("gzip truncated", good.replace("raw", "gzip"), {
            use std::io::Write;
            let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
            e.write_all(&[1u8; 8]).unwrap();
            let b = e.finish().unwrap();
            b[..b.len() - 6].to_vec()
        }),
        (
            "unknown space",
            good.replace("LPS", "scanner-xyz"),
            vec![0; 8],
        ),
        (
            "2D",
            good.replace("dimension: 3\nsizes: 2 2 2", "dimension: 2\nsizes: 2 2"),
            vec![0; 4],
        ),
    ];
    for (what, header, data) in cases {
        let path = dir.path().join("bad.nrrd");
        let mut bytes = header.into_bytes();
        bytes.extend(data);
        std::fs::write(&path, &bytes).unwrap();
        let err = read_label_map(&path, Space::Lps).unwrap_err().to_string();
        assert!(err.contains("bad.nrrd"), "{what}: {err}");
        eprintln!("{what}: {err}");
    }
    // NIfTI: size mismatch, zero spacing, a 4D image, a truncated .nii.gz.
    let v = LabelVolume::from_values(
        [3, 3, 3],
        Grid::axis_aligned([1.0, 1.0, 2.0], [0.0; 3], Space::Ras),
        (0..27).map(|i| (i % 3) as i64),
    )
    .unwrap();
    let bytes = nifti::encode(&v, false).unwrap();
    let path = dir.path().join("bad.nii");
    std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
    assert!(read_label_map(&path, Space::Lps)
        .unwrap_err()
        .to_string()
        .contains("the data holds"));
    let mut zero = bytes.clone();
    for at in [280usize, 296, 312] {
        zero[at..at + 12].fill(0); // every sform row's directions
    }
    std::fs::write(&path, &zero).unwrap();
    let err = read_label_map(&path, Space::Lps).unwrap_err().to_string();
    assert!(err.contains("spacing"), "{err}");
    let gz = nifti::encode(&v, true).unwrap();
    let path = dir.path().join("bad.nii.gz");
    std::fs::write(&path, &gz[..gz.len() - 8]).unwrap();
    assert!(read_label_map(&path, Space::Lps).is_err());
}

/// Grids that put voxels beyond +-1e6 mm (1 km) are refused with their reach named: their
/// surfaces would hold coordinates near f32's limit, which the first sum overflows. Grids
/// within it read.
#[test]
fn grids_reaching_beyond_a_kilometre_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("far.nrrd");
    let nrrd = |origin: &str, z: &str| {
        let mut b = format!("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspace: LPS\nspace directions: (1,0,0) (0,1,0) (0,0,{z})\nspace origin: {origin}\nencoding: raw\n\n").into_bytes();
        b.extend([1u8; 8]);
        b
    };
    for (origin, z) in [("(1e7,0,0)", "2"), ("(0,0,0)", "1e9"), ("(0,-3e38,0)", "2")] {
        std::fs::write(&path, nrrd(origin, z)).unwrap();
        let err = read_label_map(&path, Space::Lps).unwrap_err().to_string();
        assert!(
            err.contains("far.nrrd") && err.contains("beyond +-1e6 mm"),
            "{origin} {z}: {err}"
        );
    }
    std::fs::write(&path, nrrd("(9e5,0,-9e5)", "2")).unwrap();
    assert!(read_label_map(&path, Space::Lps).is_ok());
    let volume = |origin: [f64; 3]| {
        let grid = Grid::axis_aligned([1.0, 1.0, 2.0], origin, Space::Ras);
        LabelVolume::from_values([3, 3, 3], grid, (0..27).map(|i| (i % 2) as i64)).unwrap()
    };
    let path = dir.path().join("far.nii");
    std::fs::write(
        &path,
        nifti::encode(&volume([0.0, 2e6, 0.0]), false).unwrap(),
    )
    .unwrap();
    let err = read_label_map(&path, Space::Lps).unwrap_err().to_string();
    assert!(
        err.contains("far.nii") && err.contains("beyond +-1e6 mm"),
        "{err}"
    );
    std::fs::write(
        &path,
        nifti::encode(&volume([0.0, -9e5, 0.0]), false).unwrap(),
    )
    .unwrap();
    assert!(read_label_map(&path, Space::Lps).is_ok());
}

/// Truncations at every offset and random byte mutations: an error or a volume, never a panic.
#[test]
fn mutated_label_maps_never_panic() {
    let mut rng = fastrand::Rng::with_seed(11);
    let dir = tempfile::tempdir().unwrap();
    let v = random_volume(&mut rng, Space::Lps);
    for (name, bytes) in [
        ("m.nii", nifti::encode(&v, false).unwrap()),
        ("m.nii.gz", nifti::encode(&v, true).unwrap()),
        (
            "m.nrrd",
            nrrd::encode(std::slice::from_ref(&v), &[], false).unwrap(),
        ),
        (
            "m.seg.nrrd",
            nrrd::encode(std::slice::from_ref(&v), &[], true).unwrap(),
        ),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(
            read_label_map(&path, Space::Lps).unwrap().layers[0].voxels,
            v.voxels
        );
        // A file cut short anywhere is an error, never a smaller volume.
        for cut in (0..bytes.len()).step_by(7) {
            std::fs::write(&path, &bytes[..cut]).unwrap();
            assert!(
                read_label_map(&path, Space::Lps).is_err(),
                "{name} cut at {cut}"
            );
        }
        for _ in 0..300 {
            let mut b = bytes.clone();
            for _ in 0..rng.usize(1..4) {
                let at = rng.usize(..b.len());
                b[at] = rng.u8(..);
            }
            std::fs::write(&path, &b).unwrap();
            let _ = read_label_map(&path, Space::Lps);
        }
    }
}

#[test]
fn inspect_shows_a_label_maps_grid_and_labels() {
    let dir = tempfile::tempdir().unwrap();
    let g = Grid::axis_aligned([0.5, 0.5, 2.0], [10.0, 20.0, 30.0], Space::Ras);
    let v = LabelVolume::from_values([4, 4, 4], g, (0..64).map(|i| if i < 10 { 4 } else { 0 }))
        .unwrap();
    let path = dir.path().join("seg.nii.gz");
    std::fs::write(&path, nifti::encode(&v, true).unwrap()).unwrap();
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_destair"))
        .args(["inspect", path.to_str().unwrap(), "--json"])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(json["space"], "LPS");
    assert_eq!(json["labels"][0]["value"], 4);
    assert_eq!(json["labels"][0]["n_voxels"], 10);
    assert!((json["labels"][0]["volume_mm3"].as_f64().unwrap() - 5.0).abs() < 1e-5);
    // RAS origin (10, 20, 30) is (-10, -20, 30) in LPS.
    assert!((json["origin_mm"][0].as_f64().unwrap() + 10.0).abs() < 1e-5);
    assert_eq!(json["stack_axis"], serde_json::json!([0.0, 0.0, 1.0]));
    let bad = dir.path().join("bad.nii");
    std::fs::write(&bad, b"not a nifti").unwrap();
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_destair"))
        .args(["inspect", bad.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(3));
    assert!(String::from_utf8_lossy(&run.stderr).contains("bad.nii: "));
}

#[test]
fn the_labelmap_neck_phantom_has_touching_structures_and_can_be_oblique() {
    let dir = tempfile::tempdir().unwrap();
    for (rot, sub) in [("0", "straight"), ("20", "oblique")] {
        let out = dir.path().join(sub);
        let run = std::process::Command::new(env!("CARGO_BIN_EXE_destair"))
            .args([
                "phantom",
                "labelmap-neck",
                "--rotate-x",
                rot,
                "--out",
                out.to_str().unwrap(),
            ])
            .output()
            .unwrap();
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let map = read_label_map(&out.join("segmentation.nii.gz"), Space::Lps).unwrap();
        let v = &map.layers[0];
        assert_eq!(v.dims, [160, 160, 20]);
        let values: Vec<i64> = v.labels.iter().map(|l| l.value).collect();
        assert_eq!(values, [1, 2, 3]);
        assert!(v.labels.iter().all(|l| l.n_voxels > 500), "{:?}", v.labels);
        // Tumor (1) and vein (2) share voxel faces.
        let [nx, ny, nz] = v.dims;
        let mut shared = 0;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx - 1 {
                    let (a, b) = (v.at(i, j, k), v.at(i + 1, j, k));
                    shared += (a != b && a.min(b) == 1 && a.max(b) == 2) as usize;
                }
            }
        }
        assert!(shared > 20, "{sub}: {shared} shared faces");
        let sp = v.grid.spacing();
        assert!(
            (sp[0] - 0.45).abs() < 1e-5 && (sp[2] - 3.0).abs() < 1e-5,
            "{sp:?}"
        );
        let axis = v.grid.stack_axis();
        let expected_z = if rot == "0" {
            1.0
        } else {
            20f64.to_radians().cos()
        };
        assert!((axis[2].abs() - expected_z).abs() < 1e-5, "{sub}: {axis:?}");
        let info: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("phantom.json")).unwrap()).unwrap();
        assert_eq!(info["labels"][1]["name"], "vein");
    }
}

/// A detached header (`.nhdr`) names its data file; destair reads it only when it resolves
/// (symlinks followed) to a regular file beside the header or below it, of exactly the size the
/// header implies. A header from someone else's case folder cannot make it read any other file
/// (whose bytes would come back as labels in the surfaces and reports).
#[test]
fn detached_data_files_stay_beside_their_header() {
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("case");
    std::fs::create_dir_all(case.join("data")).unwrap();
    let secret = dir.path().join("secret.raw");
    std::fs::write(&secret, [1u8, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    std::os::unix::fs::symlink(&secret, case.join("link.raw")).unwrap();
    std::fs::write(case.join("data/v.raw"), [0u8, 0, 5, 5, 5, 0, 0, 0]).unwrap();
    std::fs::write(case.join("short.raw"), [0u8; 7]).unwrap();
    let header = |data: &str| {
        format!("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspace: LPS\nspace directions: (1,0,0) (0,1,0) (0,0,2)\nencoding: raw\ndata file: {data}\n")
    };
    let path = case.join("v.nhdr");
    let outside = secret.to_str().unwrap().to_string();
    for (data, says) in [
        ("../secret.raw", "outside the header's folder"),
        (outside.as_str(), "outside the header's folder"),
        ("link.raw", "outside the header's folder"),
        ("/proc/self/environ", "outside the header's folder"),
        ("data/../../secret.raw", "outside the header's folder"),
        ("short.raw", "holds 7 bytes; the header says 8"),
        ("missing.raw", "missing.raw"),
        ("data", "is a folder"),
    ] {
        std::fs::write(&path, header(data)).unwrap();
        let err = read_label_map(&path, Space::Lps).unwrap_err().to_string();
        assert!(
            err.contains("v.nhdr") && err.contains(says),
            "{data}: {err}"
        );
    }
    // Beside or below the header it reads, and the map names the resolved file.
    std::fs::write(&path, header("data/v.raw")).unwrap();
    let map = read_label_map(&path, Space::Lps).unwrap();
    assert_eq!(map.layers[0].labels[0].n_voxels, 3);
    assert_eq!(
        map.data_file.unwrap(),
        case.join("data/v.raw").canonicalize().unwrap()
    );
}

/// A cohort case holding a `.nhdr` that points outside the case fails that case with the
/// reason, and nothing of the file it points to reaches an output.
#[test]
fn a_case_whose_header_points_outside_it_fails_and_discloses_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let secret = dir.path().join("secret.txt");
    // 8 bytes of text: as voxels they would become labels 0x41.. and surfaces around them.
    std::fs::write(&secret, b"ABCDEFGH").unwrap();
    let case = dir.path().join("cases/c");
    std::fs::create_dir_all(&case).unwrap();
    std::fs::write(
        case.join("seg.nhdr"),
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspace: LPS\nspace directions: (1,0,0) (0,1,0) (0,0,2)\nencoding: raw\ndata file: ../../secret.txt\n",
    )
    .unwrap();
    let config = dir.path().join("c.toml");
    std::fs::write(
        &config,
        "[input]\nroots = [\"cases\"]\ncase_depth = 1\n[output]\nroot = \"out\"\n",
    )
    .unwrap();
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_destair"))
        .args(["run", config.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(3), "{err}");
    assert!(err.contains("outside the header's folder"), "{err}");
    let report = std::fs::read_to_string(dir.path().join("out/c/report.json")).unwrap();
    assert!(
        report.contains("\"failed\"") && !report.contains("label_65"),
        "{report}"
    );
    let written: Vec<_> = std::fs::read_dir(dir.path().join("out/c"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".ply") || n.ends_with(".stl"))
        .collect();
    assert!(written.is_empty(), "{written:?}");
}

/// NIfTI geometry that no scan has is refused with what is wrong: a qform quaternion longer
/// than 1 (its "rotation" scales voxels to 75 mm), a negative or zero voxel size, spacings of
/// 1e-40 mm or 5000 mm; a wider range can be asked for.
#[test]
fn label_map_geometry_that_is_no_scan_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let v = LabelVolume::from_values(
        [3, 3, 3],
        Grid::axis_aligned([1.0, 1.0, 2.0], [0.0; 3], Space::Ras),
        (0..27).map(|i| (i % 2) as i64),
    )
    .unwrap();
    let good = nifti::encode(&v, false).unwrap();
    let path = dir.path().join("g.nii");
    let put = |b: &mut Vec<u8>, at: usize, x: f32| b[at..at + 4].copy_from_slice(&x.to_le_bytes());
    let qform_only = |b: &mut Vec<u8>| b[254..256].copy_from_slice(&0i16.to_le_bytes());
    let mut cases: Vec<(&str, Vec<u8>, &str)> = Vec::new();
    let mut q = good.clone();
    qform_only(&mut q);
    put(&mut q, 256, 1.0);
    put(&mut q, 260, 1.0);
    cases.push(("non-unit quaternion", q, "longer than 1"));
    let mut q = good.clone();
    qform_only(&mut q);
    put(&mut q, 80, -1.0);
    cases.push(("negative pixdim", q, "pixdim[1]"));
    let mut q = good.clone();
    qform_only(&mut q);
    put(&mut q, 84, 0.0);
    cases.push(("zero pixdim", q, "pixdim[2]"));
    let mut tiny = good.clone();
    for (at, x) in [(280, 1e-40f32), (300, 1e-40), (320, 1e-40)] {
        put(&mut tiny, at, x);
    }
    cases.push(("1e-40 mm", tiny, "outside the 0.001 to 1000 mm"));
    let mut huge = good.clone();
    put(&mut huge, 320, 5000.0);
    cases.push(("5000 mm", huge.clone(), "outside the 0.001 to 1000 mm"));
    for (what, bytes, says) in cases {
        std::fs::write(&path, &bytes).unwrap();
        let err = read_label_map(&path, Space::Lps).unwrap_err().to_string();
        assert!(err.contains("g.nii") && err.contains(says), "{what}: {err}");
    }
    // The range is a default, not a law.
    std::fs::write(&path, &huge).unwrap();
    let wide = destair::volume::LabelMapLimits {
        spacing_mm: [1e-3, 1e4],
        ..Default::default()
    };
    let map = destair::volume::read_label_map_within(&path, Space::Lps, &wide).unwrap();
    assert_eq!(map.layers[0].grid.spacing()[2], 5000.0);
    // The same for NRRD spacings.
    let nrrd_path = dir.path().join("g.nrrd");
    let mut b = b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspacings: 1 1 1e-40\nencoding: raw\n\n".to_vec();
    b.extend([1u8; 8]);
    std::fs::write(&nrrd_path, &b).unwrap();
    let err = read_label_map(&nrrd_path, Space::Lps)
        .unwrap_err()
        .to_string();
    assert!(err.contains("outside the 0.001 to 1000 mm"), "{err}");
}

/// What a map may hold is checked from its header before any voxel is inflated, and its labels
/// before the voxels are mapped: a 4-gigavoxel header fails at once whatever its data, and a
/// map with more labels than allowed names the limit.
#[test]
fn label_maps_beyond_their_limits_are_refused_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.nrrd");
    // 2048 x 2048 x 1024 declared over 8 bytes of data.
    let mut b = b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2048 2048 1024\nspacings: 1 1 1\nencoding: raw\n\n".to_vec();
    b.extend([0u8; 8]);
    std::fs::write(&path, &b).unwrap();
    let started = std::time::Instant::now();
    let err = read_label_map(&path, Space::Lps).unwrap_err().to_string();
    assert!(err.contains("max_label_voxels"), "{err}");
    assert!(started.elapsed().as_secs_f64() < 1.0);
    let header = destair::volume::read_header(&path).unwrap();
    assert_eq!(header.n_voxels(), 1 << 32);
    assert_eq!(header.bytes_to_read(), 3 << 32);
    // 300 labels: more than the default 255, in 16- and 32-bit maps.
    let grid = Grid::axis_aligned([1.0; 3], [0.0; 3], Space::Ras);
    let v = LabelVolume::from_values([10, 10, 3], grid, (0..300).map(|i| i as i64 + 1)).unwrap();
    for (name, bytes) in [
        ("many.nii", nifti::encode(&v, false).unwrap()),
        (
            "many.nrrd",
            nrrd::encode(std::slice::from_ref(&v), &[], false).unwrap(),
        ),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let err = read_label_map(&path, Space::Lps).unwrap_err().to_string();
        assert!(err.contains("max_labels") && err.contains(name), "{err}");
        let more = destair::volume::LabelMapLimits {
            max_labels: 300,
            ..Default::default()
        };
        let map = destair::volume::read_label_map_within(&path, Space::Lps, &more).unwrap();
        assert_eq!(map.layers[0].labels.len(), 300);
    }
}

/// Two Slicer segments naming one label differently: which is right cannot be known, so the
/// label keeps its neutral name and the map says why.
#[test]
fn conflicting_segment_names_leave_the_label_unnamed_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.seg.nrrd");
    let mut b = b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 1\nspace: LPS\nspace directions: (1,0,0) (0,1,0) (0,0,3)\nencoding: raw\nSegment0_Name:=liver\nSegment0_LabelValue:=1\nSegment0_Layer:=0\nSegment1_Name:=spleen\nSegment1_LabelValue:=1\nSegment1_Layer:=0\nSegment2_Name:=kidney\nSegment2_LabelValue:=2\nSegment2_Layer:=0\n\n".to_vec();
    b.extend([0u8, 1, 2, 1]);
    std::fs::write(&path, &b).unwrap();
    let map = read_label_map(&path, Space::Lps).unwrap();
    let names: Vec<&str> = map.layers[0]
        .labels
        .iter()
        .map(|l| l.name.as_str())
        .collect();
    assert_eq!(names, ["label_1", "kidney"]);
    assert!(
        map.warnings
            .iter()
            .any(|w| w.contains("\"liver\"") && w.contains("\"spleen\"")),
        "{:?}",
        map.warnings
    );
}
