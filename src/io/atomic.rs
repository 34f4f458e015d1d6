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
