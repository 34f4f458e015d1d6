//! Tests of `src/io/mapped.rs`: a file cut short while it is mapped fails its reader with the
//! reason instead of killing the process with SIGBUS.

use destair::io::{with_file_bytes, MappedFile, ReadMode};

/// The guard slots are shared by the process: the test that takes them all runs alone among
/// these, or the others would find none and read into memory, which nothing can cut short.
static SLOTS: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// A file of `n` bytes, every byte 7.
fn file_of(dir: &std::path::Path, n: usize) -> std::path::PathBuf {
    let path = dir.join("data.bin");
    std::fs::write(&path, vec![7u8; n]).unwrap();
    path
}

#[test]
fn a_file_truncated_under_its_mapping_reads_as_zeros_and_fails_verification() {
    let _alone = SLOTS.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let path = file_of(dir.path(), 1 << 20);
    let file = std::fs::File::open(&path).unwrap();
    let map = MappedFile::map(&file).unwrap();
    assert!(map.verify().is_ok());
    // Another writer cuts the file to one page while it is mapped: every later read past the
    // new end would raise SIGBUS.
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(4096)
        .unwrap();
    let sum: u64 = map.bytes().iter().map(|&b| b as u64).sum();
    assert!(sum < 7 * (1 << 20), "the cut part reads as zeros");
    let err = map.verify().unwrap_err().to_string();
    assert!(err.contains("became shorter"), "{err}");
}

#[test]
fn with_file_bytes_fails_when_the_file_shrinks_while_it_is_read() {
    let _alone = SLOTS.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let path = file_of(dir.path(), 3 << 20);
    let cut = |p: &std::path::Path| {
        std::fs::OpenOptions::new()
            .write(true)
            .open(p)
            .unwrap()
            .set_len(1000)
            .unwrap()
    };
    let read = with_file_bytes(&path, ReadMode::Mmap, |b| {
        cut(&path);
        b.iter().map(|&x| x as u64).sum::<u64>()
    });
    assert!(read.is_err(), "{read:?}");
    // A whole file reads, and so does one read into memory, which nothing can cut.
    let path = file_of(dir.path(), 3 << 20);
    assert_eq!(
        with_file_bytes(&path, ReadMode::Mmap, |b| b.len()).unwrap(),
        3 << 20
    );
    let read = with_file_bytes(&path, ReadMode::Read, |b| {
        cut(&path);
        b.iter().map(|&x| x as u64).sum::<u64>()
    });
    assert_eq!(read.unwrap(), 7 * (3 << 20));
}

#[test]
fn many_mappings_at_once_are_each_guarded_and_released() {
    let _alone = SLOTS.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let path = file_of(dir.path(), 8192);
    let file = std::fs::File::open(&path).unwrap();
    // More than the guard slots: the rest are read into memory, all give the same bytes.
    let maps: Vec<MappedFile> = (0..300).map(|_| MappedFile::map(&file).unwrap()).collect();
    assert!(maps.iter().all(|m| m.bytes() == vec![7u8; 8192].as_slice()));
    assert!(maps.iter().all(|m| m.verify().is_ok()));
    drop(maps);
    let again = MappedFile::map(&file).unwrap();
    assert_eq!(again.bytes().len(), 8192);
}
