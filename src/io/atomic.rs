//! Atomic file writes: the data goes to a temp file in the target folder, which is renamed over
//! the target only once complete, so a killed job never leaves a half-written mesh or report.
//! (Atomic against a crashed or killed process; no fsync, so not against a power loss.)

use std::io::{BufWriter, Write};
use std::path::Path;

/// Writes a file atomically: `fill` writes the contents into a buffered temp file next to
/// `path`, which then replaces `path` in one rename.
pub fn write_atomically<F>(path: &Path, fill: F) -> std::io::Result<()>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".destair-").suffix(".tmp");
    #[cfg(unix)]
    {
        // NamedTempFile defaults to 0600; outputs should get the usual umask-based mode.
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder.tempfile_in(dir)?;
    {
        let mut w = BufWriter::with_capacity(1 << 20, tmp.as_file_mut());
        fill(&mut w)?;
        w.flush()?;
    }
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}

/// Removes temp files that writes cut short by a killed process left in `dir`.
pub fn remove_stale_temp_files(dir: &Path) -> std::io::Result<()> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(());
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let name = name.to_string_lossy();
        if name.starts_with(".destair-") && name.ends_with(".tmp") && e.path().is_file() {
            std::fs::remove_file(e.path())?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
