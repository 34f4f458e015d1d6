//! Honest results: nothing wrong is reported as ok, every failure says why in words a user
//! reads, configs that cannot work are refused before anything runs, and the cluster and
//! workflow helpers do what they say.

use crate::common;

use common::cohort::{cohort, destair, destair_ok, smooth, stderr, CONFIG};
use std::path::{Path, PathBuf};
use std::process::Command;

fn stdout(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

#[test]
fn out_of_range_parameters_are_refused_everywhere() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    cohort(dir, 1, false);
    let tumor = dir.join("cases/case-000/tumor.ply");
    let bad = [
        (
            "method = \"hc\"\nlambda = 5",
            "lambda = 5 must lie in (0, 1]",
        ),
        ("lambda = nan", "lambda = NaN"),
        ("lambda = inf", "lambda = inf"),
        ("lambda = 1e30", "lambda = 1.000e30"),
        ("lambda = 1e300", "lambda = inf"),
        ("method = \"taubin\"\nmu = nan", "mu = NaN"),
        (
            "method = \"taubin\"\nlambda = 0.6",
            "Taubin needs mu < -lambda",
        ),
        ("beta = 2", "beta = 2"),
        ("threshold = -1", "threshold = -1"),
        ("tau = 1.5", "tau = 1.5"),
        ("beta_min = -0.1", "beta_min = -0.1"),
        ("tau_max = 0", "tau_max = 0"),
        ("voxel = [0.5, 0, 3]", "voxel = [0.5, 0, 3]"),
        ("distance_scaling = \"exp:0\"", "exp:K"),
        ("distance_scaling = \"margin:-1\"", "margin"),
        ("max_displacement_voxels = 0", "max_displacement_voxels"),
        ("iterations = 1000000", "iterations"),
    ];
    for (line, needle) in bad {
        let c = write(
            dir,
            "c.toml",
            &CONFIG
                .replace("[defaults]\n", &format!("[defaults]\n{line}\n"))
                .replace(
                    "method = \"hc\"\n",
                    if line.contains("method") {
                        ""
                    } else {
                        "method = \"hc\"\n"
                    },
                ),
        );
        for cmd in ["check", "run"] {
            let out = destair(&[cmd, c.to_str().unwrap()]);
            assert_eq!(out.status.code(), Some(2), "{cmd} {line}: {}", stderr(&out));
            assert!(
                stderr(&out).contains(needle),
                "{cmd} {line}: {}",
                stderr(&out)
            );
            assert!(stderr(&out).len() < 400, "{}", stderr(&out));
        }
    }
    for args in [
        vec!["--lambda", "5"],
        vec!["--lambda", "nan"],
        vec!["--lambda", "inf"],
        vec!["--lambda", "1e30"],
        vec!["--beta", "-1"],
    ] {
        let out_path = dir.join("x.ply");
        let out = smooth(&tumor, &out_path, "hc", &args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(!out_path.exists());
    }
}

#[test]
fn a_diverged_smoothing_fails_with_the_reason_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    cohort(dir, 1, false);
    // In range, but Taubin with |mu| far above lambda amplifies every step: it diverges.
    let diverging = "method = \"taubin\"\nlambda = 0.01\nmu = -1\niterations = 60";
    let c = write(
        dir,
        "c.toml",
        &CONFIG.replace("method = \"hc\"\n", &format!("{diverging}\n")),
    );
    let run = destair(&["run", c.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
    assert!(stderr(&run).contains("smoothing"), "{}", stderr(&run));
    let report = json(&dir.join("out/case-000/report.json"));
    assert_eq!(report["status"], "failed");
    let tumor = report["structures"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == "tumor")
        .unwrap();
    assert_eq!(tumor["status"], "failed");
    assert!(
        tumor["error"].as_str().unwrap().contains("voxel diagonals")
            || tumor["error"].as_str().unwrap().contains("non-finite"),
        "{tumor}"
    );
    assert!(!dir.join("out/case-000/tumor.ply").exists());
    let summary = std::fs::read_to_string(dir.join("out/summary.csv")).unwrap();
    assert!(
        !summary.contains("inf") && !summary.contains("NaN"),
        "{summary}"
    );
    let out_path = dir.join("x.ply");
    let tumor = dir.join("cases/case-000/tumor.ply");
    let out = smooth(
        &tumor,
        &out_path,
        "taubin",
        &["--lambda", "0.01", "--mu", "-1", "--iterations", "200"],
    );
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert!(stderr(&out).contains("nothing written"), "{}", stderr(&out));
    assert!(!out_path.exists());
}

#[test]
fn configs_that_cannot_work_are_refused_by_check_and_run() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    cohort(dir, 2, false);
    let cases = [
        (
            CONFIG.replace("references = [\"tumor\"]", "references = [\"tumour\"]"),
            "reference \"tumour\"",
        ),
        (
            CONFIG.replace("roots = [\"cases\"]", "roots = [\"casez\"]"),
            "casez does not exist",
        ),
        (
            CONFIG.replace("roots = [\"cases\"]", "roots = [\"empty\"]"),
            "no cases found",
        ),
    ];
    std::fs::create_dir_all(dir.join("empty")).unwrap();
    for (text, needle) in cases {
        let c = write(dir, "c.toml", &text);
        for args in [
            vec!["check"],
            vec!["run"],
            vec!["run", "--shard", "0/2"],
            vec!["list"],
        ] {
            let mut full = args.clone();
            full.push(c.to_str().unwrap());
            let out = destair(&full);
            assert_eq!(
                out.status.code(),
                Some(2),
                "{args:?} {needle}: {}",
                stderr(&out)
            );
            assert!(stderr(&out).contains(needle), "{args:?}: {}", stderr(&out));
        }
    }
    // A pattern that matches nothing may be legitimate: a warning that check prints and run repeats.
    let c = write(
        dir,
        "c.toml",
        &format!("{CONFIG}\n[[structure]]\npattern = \"aneurysm*\"\nskip = true\n"),
    );
    let check = destair(&["check", c.to_str().unwrap()]);
    assert!(check.status.success());
    assert!(
        stdout(&check).contains("pattern \"aneurysm*\" matches no structure"),
        "{}",
        stdout(&check)
    );
    let run = destair(&["run", c.to_str().unwrap()]);
    assert!(run.status.success());
    assert!(stderr(&run).contains("pattern \"aneurysm*\" matches no structure"));
}

#[test]
fn check_prints_the_values_that_will_be_used() {
    let tmp = tempfile::tempdir().unwrap();
    let c = cohort(tmp.path(), 1, false);
    let out = destair_ok(&["check", c.to_str().unwrap()]);
    let text = stdout(&out);
    assert!(
        !text.contains("null") && !text.contains("cap_params"),
        "{text}"
    );
    // Each structure's block is valid config syntax that the config accepts as [defaults].
    let tumor = text
        .split("# tumor:")
        .nth(1)
        .unwrap()
        .split("\n# ")
        .next()
        .unwrap();
    let tumor_body: String = tumor.lines().skip(1).collect::<Vec<_>>().join("\n");
    for needle in [
        "method = \"hc\"",
        "lambda = 0.5",
        "beta = 0.5",
        "tau = \"auto\"",
        "references = [\"vein\", \"trachea\"]",
        "caps = \"smooth\"",
    ] {
        assert!(tumor_body.contains(needle), "{needle}: {tumor_body}");
    }
    let again = CONFIG.replace(
        "[defaults]\nmethod = \"hc\"\nstaircase = true\ncaps = \"smooth\"\n",
        &format!("[defaults]\n{tumor_body}\n"),
    );
    let c2 = write(tmp.path(), "again.toml", &again);
    let out = destair(&["check", c2.to_str().unwrap()]);
    assert!(out.status.success(), "{}\n{again}", stderr(&out));
}

#[test]
fn shards_summaries_and_failures_say_what_happened() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let c = cohort(dir, 3, true);
    let cfg = c.to_str().unwrap();
    let shard = destair(&["run", cfg, "--shard", "0/2"]);
    assert!(
        stderr(&shard).contains(&format!(
            "destair summarize {} --config {cfg}",
            dir.join("out").display()
        )),
        "{}",
        stderr(&shard)
    );
    let run = destair(&["run", cfg]);
    assert_eq!(run.status.code(), Some(3));
    let err = stderr(&run);
    // The first error line of each failed structure, not "see its report.json".
    assert!(
        err.contains("case zz-corrupt failed:\n")
            && err.contains("    tumor: cases/zz-corrupt/tumor.ply:"),
        "{err}"
    );
    assert!(
        err.contains("reference \"vein\" named in the config is not in this case"),
        "{err}"
    );
    assert!(
        err.contains("structures failed in 2 cases") && err.contains("5/5 cases done"),
        "{err}"
    );
    assert!(
        !err.contains(" 1 cases,") && !err.contains(" 1 structures"),
        "{err}"
    );
    let sum = destair(&["summarize", "--config", cfg]);
    assert_eq!(sum.status.code(), Some(3));
    assert!(
        stderr(&sum).contains("the cohort is complete, 2 cases failed"),
        "{}",
        stderr(&sum)
    );
    let sum = destair(&["summarize", dir.join("out").to_str().unwrap()]);
    assert!(
        stderr(&sum).contains("without --config, summarize cannot know which cases are missing"),
        "{}",
        stderr(&sum)
    );
}

#[test]
fn skipped_folders_and_duplicate_structures_are_reported() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let c = cohort(dir, 2, false);
    std::fs::create_dir_all(dir.join("cases/notes")).unwrap();
    std::fs::write(dir.join("cases/notes/readme.txt"), b"x").unwrap();
    std::fs::copy(
        dir.join("cases/case-001/tumor.ply"),
        dir.join("cases/case-001/tumor.stl.bak"),
    )
    .unwrap();
    let stl = smooth(
        &dir.join("cases/case-001/tumor.ply"),
        &dir.join("cases/case-001/tumor.stl"),
        "laplace",
        &["--iterations", "1"],
    );
    assert!(stl.status.success(), "{}", stderr(&stl));
    for text in [CONFIG.to_string(), CONFIG.replace("case_depth = 1\n", "")] {
        let _ = std::fs::remove_dir_all(dir.join("out"));
        std::fs::write(&c, &text).unwrap();
        let run = destair(&["run", c.to_str().unwrap()]);
        assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
        assert!(
            stderr(&run).contains("skipped folder cases/notes: 1 files, none of them a mesh"),
            "{}",
            stderr(&run)
        );
        assert!(
            stderr(&run).contains("structure \"tumor\" has 2 files (tumor.ply, tumor.stl)"),
            "{}",
            stderr(&run)
        );
        let summary = json(&dir.join("out/summary.json"));
        assert_eq!(
            summary["skipped_folders"].as_array().unwrap().len(),
            1,
            "{summary}"
        );
        assert_eq!(
            summary["duplicate_structures"],
            serde_json::json!(["case-001: tumor (tumor.ply, tumor.stl)"])
        );
        assert_eq!(summary["failed"], serde_json::json!(["case-001"]));
    }
    std::fs::write(
        &c,
        CONFIG.replace(
            "case_depth = 1\n",
            "case_depth = 1\nextension_order = [\"stl\", \"ply\"]\n",
        ),
    )
    .unwrap();
    destair_ok(&["run", c.to_str().unwrap()]);
    let report = json(&dir.join("out/case-001/report.json"));
    let input = report["inputs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|i| i["structure"] == "tumor")
        .unwrap()
        .clone();
    assert_eq!(input["file"], "tumor.stl");
    assert!(
        report["warnings"].to_string().contains("tumor.stl is used"),
        "{report}"
    );
}

#[test]
fn one_mesh_commands_word_their_refusals() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let rotated = dir.join("rot");
    destair_ok(&[
        "phantom",
        "sphere-aniso",
        "--rotate-x",
        "30",
        "--out",
        rotated.to_str().unwrap(),
    ]);
    let sphere = rotated.join("sphere.ply");
    let out_path = dir.join("x.ply");
    let run = smooth(&sphere, &out_path, "diamond", &[]);
    assert_eq!(run.status.code(), Some(2));
    let err = stderr(&run);
    assert!(
        err.contains("diamond needs the voxel size, which is not reconstructable")
            && !err.contains("VoxelSizeEstimate"),
        "{err}"
    );
    let run = smooth(
        &sphere,
        &out_path,
        "diamond",
        &["--voxel", "1,1,3", "--iterations", "3"],
    );
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(
        stderr(&run).contains("warning:") && stderr(&run).contains("--voxel is used"),
        "{}",
        stderr(&run)
    );
    let missing = dir.join("no/such/folder/x.ply");
    let run = smooth(&sphere, &missing, "hc", &[]);
    assert_eq!(run.status.code(), Some(2));
    assert_eq!(stderr(&run).lines().count(), 1, "{}", stderr(&run));
    let run = smooth(&sphere, &dir.join("x.stl"), "hc", &["--annotate"]);
    assert_eq!(run.status.code(), Some(2));
    assert!(stderr(&run).contains("STL cannot hold"));
}

#[test]
fn reports_hold_no_absolute_paths() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let c = cohort(dir, 2, true);
    assert_eq!(
        destair(&["run", c.to_str().unwrap()]).status.code(),
        Some(3)
    );
    let root = dir.canonicalize().unwrap();
    for case in ["case-000", "zz-corrupt", "zz-missing-ref"] {
        let text = std::fs::read_to_string(dir.join("out").join(case).join("report.json")).unwrap();
        assert!(
            !text.contains(root.to_str().unwrap()) && !text.contains(dir.to_str().unwrap()),
            "{case}: {text}"
        );
    }
    let text = std::fs::read_to_string(dir.join("out/zz-corrupt/report.json")).unwrap();
    assert!(text.contains("cases/zz-corrupt/tumor.ply"), "{text}");
}

#[test]
fn the_readme_reference_config_is_coherent() {
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let section = readme.split("### Configuration reference").nth(1).unwrap();
    let toml = section
        .split("```toml\n")
        .nth(1)
        .unwrap()
        .split("```")
        .next()
        .unwrap();
    let tmp = tempfile::tempdir().unwrap();
    cohort(tmp.path(), 2, false);
    let c = write(tmp.path(), "readme.toml", toml);
    let out = destair(&["check", c.to_str().unwrap()]);
    assert!(out.status.success(), "{}\n{toml}", stderr(&out));
    assert!(
        stdout(&out).contains("valid; 2 cases, 3 structure names"),
        "{}",
        stdout(&out)
    );
}

/// A fake `sbatch` on PATH that records its arguments and answers with a job id.
fn fake_sbatch(dir: &Path) -> PathBuf {
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let log = dir.join("sbatch.log");
    let script = format!("#!/bin/sh\necho \"$@\" >> {}\necho 4242\n", log.display());
    let p = bin.join("sbatch");
    std::fs::write(&p, script).unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
    log
}

#[test]
fn submit_slurm_sizes_the_array_and_passes_options_on() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let c = cohort(dir, 5, false);
    let log = fake_sbatch(dir);
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/submit-slurm.sh");
    let path = format!(
        "{}:{}",
        dir.join("bin").display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let run = |args: &[&str]| {
        let _ = std::fs::remove_file(&log);
        let out = Command::new("bash")
            .arg(script)
            .args(args)
            .env("PATH", &path)
            .env("DESTAIR", env!("CARGO_BIN_EXE_destair"))
            .env("CASES_PER_SHARD", "2")
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        std::fs::read_to_string(&log).unwrap()
    };
    let calls = run(&[c.to_str().unwrap(), "--", "--partition=short", "--mem=8G"]);
    let lines: Vec<&str> = calls.lines().collect();
    assert_eq!(lines.len(), 2, "{calls}");
    // 5 cases at 2 per shard: 3 tasks; options and the config passed on.
    assert!(
        lines[0].contains("--array=0-2") && lines[0].contains("--partition=short --mem=8G"),
        "{calls}"
    );
    assert!(
        lines[0].ends_with(&format!("slurm-array.sbatch {}", c.display())),
        "{calls}"
    );
    assert!(
        lines[1].contains("--dependency=afterany:4242")
            && lines[1].contains("--output=destair-summary-%j.log")
            && lines[1].contains("--mem=")
            && lines[1].contains("--time="),
        "{calls}"
    );
    assert!(
        lines[1].contains(&format!("summarize --config \"{}\"", c.display())),
        "{calls}"
    );
    let calls = run(&[c.to_str().unwrap(), "7"]);
    assert!(
        calls.lines().next().unwrap().contains("--array=0-6"),
        "{calls}"
    );
}

/// Every config either runs (exit 0 or 3) or is refused with exit 2, and a run never reports a
/// structure ok with non-finite or absurd results: random values and types for every key.
/// 80 configs by default; DESTAIR_FUZZ_ROUNDS makes it longer.
#[test]
fn fuzzed_configs_run_or_are_refused_and_never_report_garbage_as_ok() {
    let rounds: usize = std::env::var("DESTAIR_FUZZ_ROUNDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(80);
    let mut rng = fastrand::Rng::with_seed(17);
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    cohort(dir, 1, false);
    let numbers = [
        "0", "-1", "0.5", "1", "2", "1e30", "1e300", "nan", "inf", "-inf", "0.001", "-0.53", "7",
        "100001", "3.0",
    ];
    let garbage = |rng: &mut fastrand::Rng| -> String {
        match rng.usize(..5) {
            0 | 1 => numbers[rng.usize(..numbers.len())].to_string(),
            2 => ["true", "false"][rng.usize(..2)].to_string(),
            3 => ["\"hc\"", "\"exp:0\"", "\"x\"", "\"\""][rng.usize(..4)].to_string(),
            _ => format!(
                "[{}, {}]",
                numbers[rng.usize(..numbers.len())],
                numbers[rng.usize(..numbers.len())]
            ),
        }
    };
    // Mostly meaningful values per key, so that many configs run; now and then garbage.
    let keys: [(&str, &[&str]); 20] = [
        (
            "method",
            &[
                "\"laplace\"",
                "\"hc\"",
                "\"taubin\"",
                "\"mcf\"",
                "\"npc\"",
                "\"cell-size\"",
                "\"cell-edge\"",
                "\"diamond\"",
            ],
        ),
        ("iterations", &["1", "5", "20"]),
        ("lambda", &["0.1", "0.5", "1"]),
        ("mu", &["-0.53", "-0.9", "-1"]),
        ("alpha", &["0", "0.5", "1"]),
        ("beta", &["0", "0.5", "1"]),
        ("threshold", &["0.002", "0.01"]),
        (
            "voxel",
            &["[0.45, 0.45, 3]", "[1, 1, 1]", "[0.3, 0.3, 0.3]"],
        ),
        ("staircase", &["true", "false"]),
        ("axis", &["\"auto\"", "[0, 0, 1]", "[1, 0, 0]"]),
        ("tau", &["0.7", "0.3", "1", "0"]),
        ("tau_max", &["3", "1", "20"]),
        ("beta_min", &["0", "0.1", "1"]),
        ("caps", &["\"preserve\"", "\"smooth\""]),
        (
            "references",
            &["[\"vein\"]", "[]", "[\"trachea\", \"vein\"]"],
        ),
        (
            "distance_scaling",
            &[
                "\"linear\"",
                "\"margin:2\"",
                "\"exp:3\"",
                "\"exp:-3\"",
                "\"ramp:1,2\"",
            ],
        ),
        ("combine", &["\"product\"", "\"min\""]),
        ("move_boundary", &["true", "false"]),
        ("skip", &["true", "false"]),
        ("max_displacement_voxels", &["10", "1", "0.01"]),
    ];
    let (mut refused, mut ran) = (0, 0);
    for round in 0..rounds {
        let mut text = String::from(
            "[input]\nroots = [\"cases\"]\ncase_depth = 1\n[output]\nroot = \"out\"\n[run]\n",
        );
        if rng.bool() {
            text.push_str(&format!(
                "workers = {}\n",
                ["1", "2", "1", "2", "0", "300", "-1", "1.5"][rng.usize(..8)]
            ));
        }
        text.push_str("[defaults]\n");
        for (key, good) in keys {
            if rng.usize(..3) == 0 {
                let value = if rng.usize(..12) == 0 {
                    garbage(&mut rng)
                } else {
                    good[rng.usize(..good.len())].to_string()
                };
                text.push_str(&format!("{key} = {value}\n"));
            }
        }
        // Keep most runs short.
        if !text.contains("\niterations") {
            text.push_str("iterations = 3\n");
        }
        let c = write(dir, "fuzz.toml", &text);
        let _ = std::fs::remove_dir_all(dir.join("out"));
        let out = destair(&["run", c.to_str().unwrap()]);
        match out.status.code() {
            Some(2) => refused += 1,
            Some(0) | Some(3) => {
                ran += 1;
                for case in ["case-000"] {
                    let report = json(&dir.join("out").join(case).join("report.json"));
                    for s in report["structures"].as_array().unwrap() {
                        if s["status"] != "ok" {
                            continue;
                        }
                        let m = &s["metrics"];
                        for key in ["volume_percent", "normal_curvature_smoothed_deg"] {
                            let v = m[key].as_f64();
                            assert!(
                                v.is_some_and(f64::is_finite),
                                "round {round}: {key} = {:?}\n{text}",
                                m[key]
                            );
                        }
                        let h = m["distance"]["hausdorff_mm"].as_f64().unwrap();
                        assert!(
                            h.is_finite() && h < 100.0,
                            "round {round}: Hausdorff {h} reported ok\n{text}"
                        );
                        let vol = m["volume_percent"].as_f64().unwrap();
                        assert!(
                            vol > 0.0 && vol < 1000.0,
                            "round {round}: volume {vol} % reported ok\n{text}"
                        );
                    }
                }
            }
            other => panic!("round {round}: exit {other:?}\n{text}\n{}", stderr(&out)),
        }
    }
    eprintln!("fuzzed configs: {rounds} rounds, {ran} ran, {refused} refused");
    assert!(ran > 0 && refused > 0, "{ran} ran, {refused} refused");
}
