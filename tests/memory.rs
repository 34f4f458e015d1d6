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
    let estimate_mb = input_mb * destair::job::pipeline::MEMORY_PER_INPUT_BYTE as f64;
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
