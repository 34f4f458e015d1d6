//! Peak memory of cohort runs: it does not grow with the number of cases, and a cohort of large
//! cases stays within its memory budget. In a test binary of their own, one test at a time, so
//! that no other test runs beside them: other runs competing for the two cores change which
//! threads take which case and which case data is still held when the peak is taken (by 3 MB
//! to 16 MB, measured).

mod common;

use common::cohort::{cohort, destair, peak_rss_kb, write_config};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Held by each test here, so they run one after the other.
static ALONE: Mutex<()> = Mutex::new(());

/// A cohort of `n` copies of one phantom case, so that only the number of cases differs. The
/// memory budget admits one case at a time, so the peak does not depend on how the threads
/// happen to be scheduled (other tests run beside this one).
fn copies(dir: &Path, n: usize) -> PathBuf {
    let config = cohort(dir, 1, false);
    let text = std::fs::read_to_string(&config).unwrap();
    std::fs::write(&config, format!("{text}\n[run]\nmemory_budget_mb = 1\n")).unwrap();
    let cases = dir.join("cases");
    for i in 1..n {
        let to = cases.join(format!("copy-{i:04}"));
        std::fs::create_dir_all(&to).unwrap();
        for s in ["tumor", "vein", "trachea"] {
            std::fs::copy(
                cases.join(format!("case-000/{s}.ply")),
                to.join(format!("{s}.ply")),
            )
            .unwrap();
        }
    }
    config
}

#[test]
fn peak_memory_does_not_grow_with_the_cohort() {
    let _alone = ALONE.lock().unwrap_or_else(|e| e.into_inner());
    let small = tempfile::tempdir().unwrap();
    let large = tempfile::tempdir().unwrap();
    let small_config = copies(small.path(), 10);
    let large_config = copies(large.path(), 100);
    // One malloc arena: with several, which threads get an arena of their own depends on their
    // timing (other tests run beside this one) and moves the peak by 3 MB either way, which is
    // not what this test is about.
    let one_arena = [("MALLOC_ARENA_MAX", "1")];
    let (rss_small, code_small) = peak_rss_kb(&["run", small_config.to_str().unwrap()], &one_arena);
    let (rss_large, code_large) = peak_rss_kb(&["run", large_config.to_str().unwrap()], &one_arena);
    assert_eq!((code_small, code_large), (Some(0), Some(0)));
    eprintln!("peak RSS: 10 cases {rss_small} kB, 100 cases {rss_large} kB");
    // What grows with the cohort (case list, summary rows) is about 6 KB per case: ten times the
    // cases stays inside 20 % plus 1 MiB.
    assert!(
        (rss_large as f64) <= 1.2 * rss_small as f64 + 1024.0,
        "{rss_small} kB -> {rss_large} kB"
    );
}

#[test]
fn a_cohort_of_large_cases_stays_within_the_memory_budget() {
    let _alone = ALONE.lock().unwrap_or_else(|e| e.into_inner());
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let run = destair(&[
        "phantom",
        "big",
        "200000",
        "--out",
        dir.join("cases/c0").to_str().unwrap(),
    ]);
    assert!(run.status.success());
    for i in 1..4 {
        std::fs::create_dir_all(dir.join(format!("cases/c{i}"))).unwrap();
        std::fs::copy(
            dir.join("cases/c0/blob.ply"),
            dir.join(format!("cases/c{i}/blob.ply")),
        )
        .unwrap();
    }
    let input_mb = std::fs::metadata(dir.join("cases/c0/blob.ply"))
        .unwrap()
        .len() as f64
        / 1048576.0;
    // Room for one case and a bit by the estimate, so two workers must take turns: an estimate
    // below the real peak lets both run at once and the peak goes over.
    let estimate_mb = input_mb * destair::job::memory::MEMORY_PER_INPUT_BYTE as f64;
    let budget_mb = (1.2 * estimate_mb).ceil() as u64;
    let c = write_config(
        dir,
        "c.toml",
        &format!(
            "[input]\nroots = [\"cases\"]\ncase_depth = 1\n[output]\nroot = \"out\"\nformats = [\"ply\", \"stl\"]\n[run]\nworkers = 2\nmemory_budget_mb = {budget_mb}\n[defaults]\nmethod = \"hc\"\n"
        ),
    );
    let (rss_kb, code) = peak_rss_kb(&["run", c.to_str().unwrap()], &[]);
    assert_eq!(code, Some(0));
    eprintln!(
        "4 cases of {input_mb:.1} MB, budget {budget_mb} MB: peak RSS {} MB",
        rss_kb / 1024
    );
    assert!(
        (rss_kb / 1024) as u64 <= budget_mb,
        "peak {} MB over the {budget_mb} MB budget",
        rss_kb / 1024
    );
}

/// Label maps of noise (each 64^3 voxels, 262 KB, 3.4 M surface triangles) under a 64 MB
/// budget with 4 workers: their surfaces are counted before any is made, so each case fails
/// with the figure and the run stays within the budget (it took 2.8 GB before).
#[test]
fn noise_label_maps_stay_within_the_memory_budget() {
    let _alone = ALONE.lock().unwrap_or_else(|e| e.into_inner());
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let mut rng = fastrand::Rng::with_seed(3);
    for i in 0..4 {
        let grid =
            destair::volume::Grid::axis_aligned([1.0; 3], [0.0; 3], destair::volume::Space::Ras);
        let v = destair::volume::LabelVolume::from_values(
            [64, 64, 64],
            grid,
            (0..64 * 64 * 64).map(|_| rng.i64(0..3)),
        )
        .unwrap();
        let case = dir.join(format!("cases/noise-{i}"));
        std::fs::create_dir_all(&case).unwrap();
        std::fs::write(
            case.join("seg.nii"),
            destair::volume::nifti::encode(&v, false).unwrap(),
        )
        .unwrap();
    }
    let c = write_config(
        dir,
        "c.toml",
        "[input]\nroots = [\"cases\"]\ncase_depth = 1\n[output]\nroot = \"out\"\n[run]\nworkers = 4\nmemory_budget_mb = 64\n",
    );
    let (rss_kb, code) = peak_rss_kb(&["run", c.to_str().unwrap()], &[]);
    assert_eq!(code, Some(3));
    eprintln!(
        "4 noise maps, budget 64 MB, 4 workers: peak RSS {} MB",
        rss_kb / 1024
    );
    assert!(rss_kb <= (1.2 * 64.0 * 1024.0) as i64, "peak {rss_kb} kB");
    let report = std::fs::read_to_string(dir.join("out/noise-0/report.json")).unwrap();
    assert!(
        report.contains("triangles") && report.contains("memory budget"),
        "{report}"
    );
}

/// Runs the cases below `dir/cases` (Laplace) with the address space limited to `kib` KiB, as
/// `ulimit -v` (and clusters) set it: the exit code and stderr.
fn run_under_address_limit(dir: &Path, kib: u64) -> (Option<i32>, String) {
    let c = write_config(
        dir,
        "c.toml",
        "[input]\nroots = [\"cases\"]\ncase_depth = 1\n[output]\nroot = \"out\"\n[defaults]\nmethod = \"laplace\"\n",
    );
    let run = std::process::Command::new("sh")
        .args([
            "-c",
            &format!("ulimit -v {kib} && exec \"$0\" run \"$1\""),
            env!("CARGO_BIN_EXE_destair"),
            c.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    (
        run.status.code(),
        String::from_utf8_lossy(&run.stderr).into_owned(),
    )
}

/// A gzip bomb (1 MB inflating to exactly the gigabyte its header declares) in a cohort of three
/// under a 3 GB address-space limit, as clusters set: refused from its header before a byte is
/// inflated; the other two cases are done and the run exits 3 (the session-start binary
/// inflated it, then aborted with SIGABRT allocating its labels; every rerun would too).
#[test]
fn a_gzip_bomb_under_an_address_space_limit_fails_alone() {
    let _alone = ALONE.lock().unwrap_or_else(|e| e.into_inner());
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    for case in ["a", "b"] {
        let run = destair(&[
            "phantom",
            "neck",
            "--out",
            dir.join("cases").join(case).to_str().unwrap(),
        ]);
        assert!(run.status.success());
    }
    // 1024 x 1024 x 1000 u8 voxels, all zero: a first gzip member with the header, then
    // members of 64 MB of zeros (gzip files may hold several; readers join them).
    let grid = destair::volume::Grid::axis_aligned([1.0; 3], [0.0; 3], destair::volume::Space::Ras);
    let tiny =
        destair::volume::LabelVolume::from_values([1, 1, 1], grid, std::iter::once(0)).unwrap();
    let mut header = destair::volume::nifti::encode(&tiny, false).unwrap();
    header.truncate(352);
    for (k, d) in [1024i16, 1024, 1000].iter().enumerate() {
        header[42 + 2 * k..44 + 2 * k].copy_from_slice(&d.to_le_bytes());
    }
    let gz = |bytes: &[u8]| {
        use std::io::Write;
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        e.write_all(bytes).unwrap();
        e.finish().unwrap()
    };
    // Exactly the declared bytes, so a reader that trusts the header inflates them all.
    let chunk = 64usize << 20;
    let zeros = vec![0u8; chunk];
    let mut bomb = gz(&[header.as_slice(), &zeros].concat());
    let member = gz(&zeros);
    let mut left = 1024 * 1024 * 1000 - chunk;
    while left >= chunk {
        bomb.extend_from_slice(&member);
        left -= chunk;
    }
    if left > 0 {
        bomb.extend_from_slice(&gz(&zeros[..left]));
    }
    std::fs::create_dir_all(dir.join("cases/bomb")).unwrap();
    std::fs::write(dir.join("cases/bomb/seg.nii.gz"), &bomb).unwrap();
    eprintln!("bomb: {} bytes", bomb.len());
    // 3 GB: the voxels (1 GB) fit, their labels (2 GB more) do not.
    let (code, err) = run_under_address_limit(dir, 3 << 20);
    assert_eq!(code, Some(3), "{err}");
    assert!(err.contains("1 case of 3 failed: bomb"), "{err}");
    assert!(
        err.contains("memory budget") && err.contains("ulimit -v"),
        "{err}"
    );
    for case in ["a", "b"] {
        let report =
            std::fs::read_to_string(dir.join("out").join(case).join("report.json")).unwrap();
        assert!(report.contains("\"status\": \"ok\""), "{case}: {report}");
    }
}

/// A mesh case whose estimate (24 bytes a mesh byte) exceeds what the process may use fails
/// with the figures under an address-space limit; the other case is done (the run aborted with
/// SIGABRT before, and every rerun at the same case).
#[test]
fn a_mesh_case_beyond_the_address_space_limit_fails_alone() {
    let _alone = ALONE.lock().unwrap_or_else(|e| e.into_inner());
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    for (case, args) in [("small", vec!["neck"]), ("big", vec!["big", "2000000"])] {
        let mut all = vec!["phantom"];
        all.extend(args);
        let out = dir.join("cases").join(case);
        all.extend(["--out", out.to_str().unwrap()]);
        assert!(destair(&all).status.success());
    }
    let (code, err) = run_under_address_limit(dir, 400 << 10);
    assert_eq!(code, Some(3), "{err}");
    assert!(
        err.contains("1 case of 2 failed: big") && err.contains("by the estimate"),
        "{err}"
    );
    let report = std::fs::read_to_string(dir.join("out/small/report.json")).unwrap();
    assert!(report.contains("\"status\": \"ok\""), "{report}");
}
