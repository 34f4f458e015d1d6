//! Peak memory of a cohort run does not grow with the number of cases. In a test binary of its
//! own, so that no other test runs beside it: other runs competing for the two cores change
//! which case data is still held when the peak is taken, by about 3 MB.

mod common;

use common::cohort::{cohort, peak_rss_kb};
use std::path::{Path, PathBuf};

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
    let small = tempfile::tempdir().unwrap();
    let large = tempfile::tempdir().unwrap();
    let small_config = copies(small.path(), 20);
    let large_config = copies(large.path(), 200);
    // One malloc arena: with several, which threads get an arena of their own depends on their
    // timing (other tests run beside this one) and moves the peak by 3 MB either way, which is
    // not what this test is about.
    let one_arena = [("MALLOC_ARENA_MAX", "1")];
    let (rss_small, code_small) = peak_rss_kb(&["run", small_config.to_str().unwrap()], &one_arena);
    let (rss_large, code_large) = peak_rss_kb(&["run", large_config.to_str().unwrap()], &one_arena);
    assert_eq!((code_small, code_large), (Some(0), Some(0)));
    eprintln!("peak RSS: 20 cases {rss_small} kB, 200 cases {rss_large} kB");
    // What grows with the cohort (case list, summary rows) is about 6 KB per case: ten times the
    // cases stays inside 20 % plus 1 MiB.
    assert!(
        (rss_large as f64) <= 1.2 * rss_small as f64 + 1024.0,
        "{rss_small} kB -> {rss_large} kB"
    );
}
