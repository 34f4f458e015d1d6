//! Tests of `src/job/paths.rs`.

use destair::job::paths::*;
use std::path::PathBuf;

#[test]
fn spellings_of_one_folder_are_one_path() {
    let tmp = tempfile::tempdir().unwrap();
    let base = tmp.path().canonicalize().unwrap();
    let cases = base.join("cases");
    std::fs::create_dir_all(cases.join("a")).unwrap();
    std::os::unix::fs::symlink(&cases, base.join("link")).unwrap();
    for spelling in [
        "cases",
        "cases/",
        "./cases",
        "cases/../cases",
        "cases/a/..",
        "link",
        "link/a/../",
        "missing/../cases",
    ] {
        assert_eq!(canonical(&base.join(spelling)), cases, "{spelling}");
    }
    assert_eq!(canonical(&base.join("out/x/../y")), base.join("out/y"));
    assert_eq!(
        relative_to(&base, &base.join("cases/a")),
        PathBuf::from("cases/a")
    );
    assert_eq!(
        relative_to(&cases.join("a"), &base.join("out")),
        PathBuf::from("../../out")
    );
    assert_eq!(relative_to(&base, &base), PathBuf::from("."));
    let roots = [base.join("cases")];
    assert!(check_output_root(&base.join("cases/../cases"), &roots).is_err());
    assert!(check_output_root(&base.join("link"), &roots).is_err());
    assert!(check_output_root(&base, &roots).is_err());
    assert!(check_output_root(&base.join("out"), &roots).is_ok());
    assert!(check_output_root(&base.join("cases/out"), &roots).is_ok());
    std::fs::write(base.join("file"), b"x").unwrap();
    assert!(check_output_root(&base.join("file"), &roots).is_err());
}
