//! Files by identity (device and inode) rather than by spelling, so `cases/../cases`, a
//! symlink and a hard link all count as the same file: what keeps outputs off inputs.

use std::collections::HashSet;
use std::path::Path;

/// Device and inode of a file or folder (symlinks followed), if it exists.
pub fn file_id(path: &Path) -> Option<(u64, u64)> {
    let m = std::fs::metadata(path).ok()?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        Some((m.dev(), m.ino()))
    }
    #[cfg(not(unix))]
    {
        let _ = m;
        let c = path.canonicalize().ok()?;
        Some((
            0,
            blake3::hash(c.as_os_str().as_encoded_bytes()).as_bytes()[0] as u64,
        ))
    }
}

/// Whether two paths name the same existing file or folder.
pub fn same_file(a: &Path, b: &Path) -> bool {
    matches!((file_id(a), file_id(b)), (Some(x), Some(y)) if x == y)
}

/// Checks that `path` can be read as a file: it exists and is a regular file (after symlinks),
/// not a folder, device, FIFO or socket, which would block or never end.
pub fn check_regular_file(path: &Path) -> std::io::Result<std::fs::Metadata> {
    let m = std::fs::metadata(path)?;
    if m.is_file() {
        return Ok(m);
    }
    let what = if m.is_dir() {
        "is a folder, not a file"
    } else {
        "is not a regular file (a device, FIFO or socket); give a file"
    };
    Err(std::io::Error::new(std::io::ErrorKind::InvalidInput, what))
}

/// The identities of a run's input files and case folders: no output may be written onto one.
#[derive(Debug, Clone, Default)]
pub struct ProtectedFiles {
    ids: HashSet<(u64, u64)>,
}

impl ProtectedFiles {
    /// Adds a file or folder (ignored if it does not exist).
    pub fn insert(&mut self, path: &Path) {
        if let Some(id) = file_id(path) {
            self.ids.insert(id);
        }
    }

    /// Whether `path` exists and is one of the protected files or folders.
    pub fn contains(&self, path: &Path) -> bool {
        !self.ids.is_empty() && file_id(path).is_some_and(|id| self.ids.contains(&id))
    }

    /// Number of protected files and folders.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// Whether nothing is protected.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }
}
