//! A cohort run's pages and viewer files: report.html per case and index.html with their
//! pictures (rendered by headless Chromium where it is installed), and .vtp files that VTK
//! reads with every array (checked with VTK's Python package where it is installed).

use crate::common;

use common::cohort::{cohort, destair, destair_ok, stderr};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs a 2-case cohort (plus a broken case) writing PLY with annotations and VTP.
fn run_cohort(dir: &Path) -> PathBuf {
    let config = cohort(dir, 2, true);
    let text = std::fs::read_to_string(&config).unwrap().replace(
        "formats = [\"ply\", \"stl\"]",
        "formats = [\"ply\", \"vtp\"]\nannotate = true",
    );
    std::fs::write(&config, text).unwrap();
    let run = destair(&["run", config.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
    dir.join("out")
}

/// Non-white share and the number of viridis-purple pixels (the low end of the displacement
/// scale: only the pictures have it) of a PNG screenshot.
fn screenshot_stats(path: &Path) -> (f64, usize) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    let pixels: Vec<&[u8]> = buf[..info.buffer_size()].chunks(channels).collect();
    let non_white = pixels
        .iter()
        .filter(|p| p[..3].iter().any(|&c| c < 240))
        .count();
    let purple = pixels
        .iter()
        .filter(|p| p[0] > 40 && p[0] < 90 && p[1] < 40 && p[2] > 60 && p[2] < 120)
        .count();
    (non_white as f64 / pixels.len() as f64, purple)
}

#[test]
fn every_case_gets_a_page_with_its_pictures_and_the_cohort_an_index() {
    let t = tempfile::tempdir().unwrap();
    let out = run_cohort(t.path());
    let index = std::fs::read_to_string(out.join("index.html")).unwrap();
    // Failed cases first, every structure a row, thumbnails of existing pictures.
    let failed = index.find(">zz-corrupt<").expect("failed case listed");
    let ok = index.find(">case-000<").expect("ok case listed");
    assert!(failed < ok, "failed cases come first");
    assert!(
        !index.contains("http://") && !index.contains("https://"),
        "no network"
    );
    let images: Vec<&str> = index
        .split("<image href=\"")
        .skip(1)
        .map(|s| &s[..s.find('"').unwrap()])
        .collect();
    // Two ok cases with tumor and vein (trachea is skipped), one with only the reference
    // missing... the missing-reference case fails its tumor but smooths nothing else.
    assert!(images.len() >= 4, "{images:?}");
    for src in &images {
        let bytes = std::fs::read(out.join(src)).unwrap_or_else(|e| panic!("{src}: {e}"));
        assert_eq!(&bytes[1..4], b"PNG");
    }
    for case in ["case-000", "case-001"] {
        let page = std::fs::read_to_string(out.join(case).join("report.html")).unwrap();
        assert!(page.contains(&format!(
            "<h1>destair report: case <code>{case}</code></h1>"
        )));
        for s in ["tumor", "vein"] {
            assert!(
                page.contains(&format!("src=\"{s}_views.png\"")),
                "{case} {s}"
            );
            assert!(out.join(case).join(format!("{s}_views.png")).is_file());
        }
        assert!(page.contains("vertex displacement"), "histogram");
        assert!(page.contains("smallest distance to each reference"));
        let manifest = std::fs::read_to_string(out.join(case).join("manifest.json")).unwrap();
        assert!(manifest.contains("tumor_views.png"), "pictures are outputs");
    }
}

#[test]
fn pages_render_in_headless_chromium_with_their_pictures() {
    let Some(chromium) = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|c| {
            Command::new(c)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
    else {
        eprintln!("skipped: no Chromium installed");
        return;
    };
    let t = tempfile::tempdir().unwrap();
    let out = run_cohort(t.path());
    for (page, min_purple) in [
        (out.join("index.html"), 200),
        (out.join("case-000/report.html"), 2000),
    ] {
        let shot = t.path().join("shot.png");
        let _ = std::fs::remove_file(&shot);
        let profile = t.path().join("chromium-profile");
        let run = Command::new("timeout")
            .args([
                "120",
                chromium,
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
            ])
            .arg("--hide-scrollbars")
            .arg("--window-size=1400,1400")
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg(format!("--screenshot={}", shot.display()))
            .arg(format!("file://{}", page.canonicalize().unwrap().display()))
            .output()
            .unwrap();
        assert!(
            shot.is_file(),
            "no screenshot of {}: {}",
            page.display(),
            String::from_utf8_lossy(&run.stderr)
        );
        let (ink, purple) = screenshot_stats(&shot);
        assert!(
            ink > 0.02,
            "{}: {ink:.3} of the screenshot is not white",
            page.display()
        );
        assert!(
            purple >= min_purple,
            "{}: the pictures did not load ({purple} picture pixels)",
            page.display()
        );
    }
}

#[test]
fn vtp_outputs_open_in_vtk_with_every_array() {
    let t = tempfile::tempdir().unwrap();
    let out = run_cohort(t.path());
    // One Python process reads every file (importing VTK takes about a second); it prints
    // `no-vtk` when VTK's Python package is not installed, and one JSON line per file otherwise.
    let script = r#"
import sys, json
try:
    import vtk
except ImportError:
    print("no-vtk")
    sys.exit(0)
for path in sys.argv[1:]:
    r = vtk.vtkXMLPolyDataReader()
    r.SetFileName(path)
    r.Update()
    if r.GetErrorCode():
        sys.exit("read error: " + path)
    m = r.GetOutput()
    pd = m.GetPointData()
    arrays = {}
    for i in range(pd.GetNumberOfArrays()):
        a = pd.GetArray(i)
        v = [a.GetValue(k) for k in range(a.GetNumberOfTuples())]
        arrays[a.GetName()] = [len(v), sum(v), min(v), max(v)]
    pts = m.GetPoints()
    s = [sum(pts.GetPoint(k)[c] for k in range(m.GetNumberOfPoints())) for c in range(3)]
    space = m.GetFieldData().GetAbstractArray("SPACE")
    print(json.dumps({"points": m.GetNumberOfPoints(), "polys": m.GetNumberOfPolys(),
      "cells": m.GetNumberOfCells(), "arrays": arrays, "sum": s,
      "active": pd.GetScalars().GetName() if pd.GetScalars() else None,
      "space": space.GetValue(0) if space else None}))
"#;
    let files: Vec<(&str, &str)> = ["case-000", "case-001"]
        .into_iter()
        .flat_map(|case| ["tumor", "vein"].map(|s| (case, s)))
        .collect();
    let run = Command::new("python3")
        .args(["-c", script])
        .args(
            files
                .iter()
                .map(|(case, s)| out.join(case).join(format!("{s}.vtp"))),
        )
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let stdout = String::from_utf8_lossy(&run.stdout);
    if stdout.trim() == "no-vtk" {
        eprintln!("skipped: VTK's Python package is not installed");
        return;
    }
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), files.len(), "{stdout}");
    for (&(case, s), line) in files.iter().zip(lines) {
        let got: serde_json::Value = serde_json::from_str(line).unwrap();
        // The annotated PLY of the same run holds the same surface and arrays.
        let ply = destair::io::read_mesh(
            &out.join(case).join(format!("{s}.ply")),
            &destair::io::ReadOptions {
                keep_vertex_properties: true,
                ..Default::default()
            },
        )
        .unwrap();
        let n = ply.mesh.n_vertices();
        assert_eq!(got["points"], n);
        assert_eq!(got["polys"], ply.mesh.n_triangles());
        assert_eq!(got["cells"], ply.mesh.n_triangles());
        assert_eq!(got["active"], "displacement");
        for c in 0..3 {
            let want: f64 = ply.mesh.positions().iter().map(|p| p[c] as f64).sum();
            let have = got["sum"][c].as_f64().unwrap();
            assert!(
                (want - have).abs() <= 1e-6 * (1.0 + want.abs()),
                "{want} {have}"
            );
        }
        let arrays = got["arrays"].as_object().unwrap();
        let names: Vec<&str> = arrays.keys().map(String::as_str).collect();
        for want in [
            "weight",
            "staircase",
            "cap",
            "staircase_distance",
            "reference_distance",
            "displacement",
        ] {
            assert!(
                names.contains(&want),
                "{case}/{s}: {want} missing from {names:?}"
            );
            let p = ply
                .vertex_properties
                .iter()
                .find(|p| p.name == want)
                .unwrap();
            let a = &arrays[want];
            assert_eq!(a[0], n);
            let sum: f64 = p.values.iter().map(|&x| x as f64).sum();
            let (lo, hi) = p
                .values
                .iter()
                .fold((f32::MAX, f32::MIN), |(l, h), &x| (l.min(x), h.max(x)));
            assert!((a[1].as_f64().unwrap() - sum).abs() <= 1e-4 * (1.0 + sum.abs()));
            assert_eq!(a[2].as_f64().unwrap() as f32, lo);
            assert_eq!(a[3].as_f64().unwrap() as f32, hi);
        }
        // The PLY also carries the displacement as `quality`, which MeshLab shows.
        let q = ply
            .vertex_properties
            .iter()
            .find(|p| p.name == "quality")
            .unwrap();
        let d = ply
            .vertex_properties
            .iter()
            .find(|p| p.name == "displacement")
            .unwrap();
        assert_eq!(q.values, d.values);
        assert_eq!(got["space"], ply.meta.space().unwrap_or("unknown"));
    }
}

#[test]
fn pictures_and_pages_turned_off_are_not_written_and_old_ones_go() {
    let t = tempfile::tempdir().unwrap();
    let config = cohort(t.path(), 1, false);
    destair_ok(&["run", config.to_str().unwrap()]);
    let out = t.path().join("out");
    let case = out.join("case-000");
    assert!(case.join("tumor_views.png").is_file() && case.join("report.html").is_file());
    assert!(out.join("index.html").is_file());
    let text = std::fs::read_to_string(&config).unwrap().replace(
        "root = \"out\"",
        "root = \"out\"\npictures = false\nhtml = false",
    );
    std::fs::write(&config, text).unwrap();
    destair_ok(&["run", config.to_str().unwrap()]);
    assert!(
        !case.join("tumor_views.png").exists(),
        "stale picture removed"
    );
    assert!(!case.join("report.html").exists(), "stale page removed");
    assert!(!out.join("index.html").exists(), "stale index removed");
    assert!(case.join("tumor.ply").is_file() && case.join("report.md").is_file());
    let report = std::fs::read_to_string(case.join("report.json")).unwrap();
    assert!(!report.contains("\"picture\""));
}
