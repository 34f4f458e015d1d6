//! Tests of `src/io/identity.rs`.

use destair::io::identity::*;
use std::path::Path;

#[test]
fn spellings_links_and_hard_links_are_the_same_file() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.ply");
    std::fs::write(&a, b"x").unwrap();
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    let spelled = dir.path().join("sub/../a.ply");
    let hard = dir.path().join("hard.ply");
    std::fs::hard_link(&a, &hard).unwrap();
    let soft = dir.path().join("soft.ply");
    #[cfg(unix)]
    std::os::unix::fs::symlink(&a, &soft).unwrap();
    let mut p = ProtectedFiles::default();
    p.insert(&a);
    for other in [&spelled, &hard, &soft] {
        assert!(
            same_file(&a, other) && p.contains(other),
            "{}",
            other.display()
        );
    }
    std::fs::write(dir.path().join("b.ply"), b"x").unwrap();
    assert!(!p.contains(&dir.path().join("b.ply")));
    assert!(!p.contains(&dir.path().join("missing.ply")));
}

#[test]
fn devices_fifos_and_folders_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    assert!(check_regular_file(dir.path())
        .unwrap_err()
        .to_string()
        .contains("folder"));
    #[cfg(unix)]
    assert!(check_regular_file(Path::new("/dev/zero"))
        .unwrap_err()
        .to_string()
        .contains("not a regular file"));
}
