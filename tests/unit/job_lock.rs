//! Tests of `src/job/lock.rs`.

use destair::job::lock::*;

#[test]
fn scopes_have_distinct_bytes() {
    let mut seen = std::collections::HashSet::new();
    assert!(seen.insert(LockScope::Root.byte()));
    for n in 1..40 {
        for i in 0..n {
            assert!(seen.insert(LockScope::Shard { index: i, count: n }.byte()));
        }
    }
    for c in 0..1000 {
        let b = LockScope::Case(format!("case-{c}")).byte();
        assert!(b >= 1 << 40 && seen.insert(b));
    }
}

#[test]
fn marker_is_written_once_and_root_must_be_a_folder() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("out");
    let lock = OutputLock::open(&root).unwrap();
    assert!(is_output_root(&root));
    lock.lock(&LockScope::Root, LockMode::Exclusive, Wait::No)
        .unwrap();
    drop(lock);
    let _again = OutputLock::open(&root).unwrap();
    assert_eq!(
        std::fs::read_to_string(root.join(MARKER)).unwrap(),
        MARKER_TEXT
    );
    let file = dir.path().join("file");
    std::fs::write(&file, b"x").unwrap();
    let err = OutputLock::open(&file).unwrap_err().to_string();
    assert!(err.contains("not a folder"), "{err}");
}
