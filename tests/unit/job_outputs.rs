//! Tests of `src/job/outputs.rs`.

use destair::io::ProtectedFiles;
use destair::job::outputs::*;

#[test]
fn manifests_cannot_name_files_outside_their_folder() {
    for bad in [
        "",
        ".",
        "..",
        "../x.ply",
        "a/b.ply",
        "/etc/passwd",
        "manifest.json",
    ] {
        assert!(!is_plain_name(bad), "{bad:?}");
    }
    assert!(is_plain_name("tumor.ply") && is_plain_name("case-1_tumor_smooth.stl"));
}

#[test]
fn prune_keeps_foreign_files_and_removes_empty_folders() {
    let root = tempfile::tempdir().unwrap();
    let case = root.path().join("a/b");
    std::fs::create_dir_all(&case).unwrap();
    let manifest = Manifest {
        key: "k".into(),
        status: "ok".into(),
        outputs: vec!["tumor.ply".into(), "../escape.ply".into()],
    };
    std::fs::write(
        case.join("manifest.json"),
        serde_json::to_vec(&manifest).unwrap(),
    )
    .unwrap();
    std::fs::write(root.path().join("a/escape.ply"), b"keep").unwrap();
    for f in ["tumor.ply", "report.json", "report.md", ".destair-x.tmp"] {
        std::fs::write(case.join(f), b"x").unwrap();
    }
    let orphans = orphan_case_dirs(root.path(), &["other".to_string()]);
    assert_eq!(orphans.len(), 1);
    assert_eq!(orphans[0].0, "a/b");
    std::fs::write(case.join("notes.txt"), b"mine").unwrap();
    let left = prune_case_dir(&case, root.path(), &ProtectedFiles::default()).unwrap();
    assert_eq!(left, ["notes.txt"]);
    assert!(root.path().join("a/escape.ply").is_file());
    std::fs::remove_file(case.join("notes.txt")).unwrap();
    std::fs::remove_file(root.path().join("a/escape.ply")).unwrap();
    assert!(
        prune_case_dir(&case, root.path(), &ProtectedFiles::default())
            .unwrap()
            .is_empty()
    );
    assert!(!root.path().join("a").exists() && root.path().exists());
}
