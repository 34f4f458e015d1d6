//! Tests of `src/io/atomic.rs`.

use destair::io::atomic::*;

#[test]
fn failed_write_leaves_target_untouched_and_no_temp_files() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("mesh.ply");
    std::fs::write(&target, b"old").unwrap();
    let err = write_atomically(&target, |w| {
        w.write_all(b"half")?;
        Err(std::io::Error::other("disk full"))
    });
    assert!(err.is_err());
    assert_eq!(std::fs::read(&target).unwrap(), b"old");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    write_atomically(&target, |w| w.write_all(b"new")).unwrap();
    assert_eq!(std::fs::read(&target).unwrap(), b"new");
}
