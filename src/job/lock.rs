//! The output folder's marker and locks. Every output root holds a small marker file,
//! [`MARKER`]: discovery never looks for cases below a folder that has one, whatever the path
//! spelling, and runs lock byte ranges of it with POSIX record locks (`fcntl`), which the kernel
//! drops when the process dies (even by kill -9), which work on NFS, and whose holder's pid can
//! be asked for. Byte 0 is the folder: an unsharded `run` takes it exclusively, shards and
//! `run-case` share it. Each shard `I/N` and each case has a byte of its own above that, taken
//! exclusively while the shard runs, or from the moment a case is taken up until its folder is
//! written.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;
use thiserror::Error;

/// Name of the marker and lock file in an output root.
pub const MARKER: &str = ".destair-output";

/// What the marker file says to a person who opens it.
pub const MARKER_TEXT: &str =
    "This folder holds destair outputs. destair never looks for cases below a folder\n\
holding this file, and locks this file while a run writes here. Keep it.\n";

/// Whether `dir` is a destair output root (holds the marker).
pub fn is_output_root(dir: &Path) -> bool {
    dir.join(MARKER).is_file()
}

/// An output folder that cannot be used now.
#[derive(Debug, Error)]
pub enum LockError {
    #[error("{}: cannot use this output folder: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: {what} is in use by another destair run ({holder}); wait for it to end, or pass --wait", path.display())]
    Busy {
        path: PathBuf,
        what: String,
        holder: String,
    },
    #[error("{}: stopped while waiting for the lock on {what}", path.display())]
    Stopped { path: PathBuf, what: String },
}

/// What part of an output root a lock covers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LockScope {
    /// The whole folder (byte 0).
    Root,
    /// Shard `index` of `count`.
    Shard { index: u64, count: u64 },
    /// One case's output folder, by case id.
    Case(String),
}

impl LockScope {
    /// The byte this scope locks; shards and cases never share one (cases hash into 2^40..2^41).
    pub fn byte(&self) -> i64 {
        match self {
            LockScope::Root => 0,
            LockScope::Shard { index, count } => {
                let n = (*count).min(1 << 19) as i64;
                1 + n * (n - 1) / 2 + (*index).min(1 << 19) as i64
            }
            LockScope::Case(id) => {
                let h = blake3::hash(id.as_bytes());
                let v = u64::from_le_bytes(h.as_bytes()[..8].try_into().unwrap_or([0; 8]));
                (1i64 << 40) + (v % (1 << 40)) as i64
            }
        }
    }

    fn describe(&self) -> String {
        match self {
            LockScope::Root => "the output folder".into(),
            LockScope::Shard { index, count } => format!("shard {index}/{count}"),
            LockScope::Case(id) => format!("the outputs of case {id:?}"),
        }
    }
}

/// Exclusive (one holder) or shared (many holders, no exclusive one).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LockMode {
    Exclusive,
    Shared,
}

/// How long to try for a lock.
#[derive(Clone, Copy)]
pub enum Wait<'a> {
    /// Fail at once with [`LockError::Busy`].
    No,
    /// Retry until it is free, or until the flag is set ([`LockError::Stopped`]).
    Until(&'a AtomicBool),
}

/// An output root's marker file, opened once for the life of the run; its locks go with it.
/// (POSIX locks belong to the process and end when any descriptor of the file is closed, so
/// the file is opened exactly once per process and kept open.)
#[derive(Debug)]
pub struct OutputLock {
    file: File,
    root: PathBuf,
}

impl OutputLock {
    /// Creates the output root if needed, marks it, and opens its marker for locking.
    pub fn open(root: &Path) -> Result<OutputLock, LockError> {
        let io = |source| LockError::Io {
            path: root.to_path_buf(),
            source,
        };
        if root.exists() && !root.is_dir() {
            return Err(io(std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                "exists and is not a folder",
            )));
        }
        std::fs::create_dir_all(root).map_err(io)?;
        let path = root.join(MARKER);
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(io)?;
        if file.metadata().map_err(io)?.len() == 0 {
            std::io::Write::write_all(&mut &file, MARKER_TEXT.as_bytes()).map_err(io)?;
        }
        Ok(OutputLock {
            file,
            root: root.to_path_buf(),
        })
    }

    /// The output root.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Takes a lock on `scope`, waiting as `wait` says.
    pub fn lock(&self, scope: &LockScope, mode: LockMode, wait: Wait) -> Result<(), LockError> {
        loop {
            match self.set(scope.byte(), Some(mode)) {
                Ok(true) => return Ok(()),
                Ok(false) => {}
                Err(source) => {
                    return Err(LockError::Io {
                        path: self.root.clone(),
                        source,
                    })
                }
            }
            match wait {
                Wait::No => {
                    return Err(LockError::Busy {
                        path: self.root.clone(),
                        what: scope.describe(),
                        holder: self.holder(scope.byte(), mode),
                    })
                }
                Wait::Until(stop) => {
                    if stop.load(Ordering::Relaxed) {
                        return Err(LockError::Stopped {
                            path: self.root.clone(),
                            what: scope.describe(),
                        });
                    }
                    std::thread::sleep(Duration::from_millis(50));
                }
            }
        }
    }

    /// Releases a lock taken with [`OutputLock::lock`].
    pub fn unlock(&self, scope: &LockScope) {
        let _ = self.set(scope.byte(), None);
    }

    /// F_SETLK on one byte: Ok(false) when another process holds a conflicting lock.
    fn set(&self, byte: i64, mode: Option<LockMode>) -> std::io::Result<bool> {
        use std::os::unix::io::AsRawFd;
        let mut fl = flock_for(byte, mode);
        // SAFETY: fcntl with F_SETLK on a descriptor we own and a fully initialised flock.
        let r = unsafe { libc::fcntl(self.file.as_raw_fd(), libc::F_SETLK, &mut fl) };
        if r == 0 {
            return Ok(true);
        }
        let e = std::io::Error::last_os_error();
        match e.raw_os_error() {
            Some(libc::EAGAIN) | Some(libc::EACCES) => Ok(false),
            Some(libc::EINTR) => Ok(false),
            _ => Err(e),
        }
    }

    /// Who holds a lock that conflicts with `mode` on `byte`: pid and, where /proc has it, the
    /// command line.
    fn holder(&self, byte: i64, mode: LockMode) -> String {
        use std::os::unix::io::AsRawFd;
        let mut fl = flock_for(byte, Some(mode));
        // SAFETY: as in `set`; F_GETLK only fills in `fl`.
        let r = unsafe { libc::fcntl(self.file.as_raw_fd(), libc::F_GETLK, &mut fl) };
        if r != 0 || fl.l_type == libc::F_UNLCK as i16 || fl.l_pid <= 0 {
            return "another process".into();
        }
        let pid = fl.l_pid;
        match std::fs::read(format!("/proc/{pid}/cmdline")) {
            Ok(cmd) if !cmd.is_empty() => {
                let words: Vec<String> = cmd
                    .split(|&b| b == 0)
                    .filter(|w| !w.is_empty())
                    .map(|w| String::from_utf8_lossy(w).into_owned())
                    .collect();
                format!("pid {pid}: {}", words.join(" "))
            }
            _ => format!("pid {pid}"),
        }
    }
}

fn flock_for(byte: i64, mode: Option<LockMode>) -> libc::flock {
    // SAFETY: flock is plain data; all-zero is a valid value, then set field by field.
    let mut fl: libc::flock = unsafe { std::mem::zeroed() };
    fl.l_type = match mode {
        Some(LockMode::Exclusive) => libc::F_WRLCK,
        Some(LockMode::Shared) => libc::F_RDLCK,
        None => libc::F_UNLCK,
    } as i16;
    fl.l_whence = libc::SEEK_SET as i16;
    fl.l_start = byte as libc::off_t;
    fl.l_len = 1;
    fl
}
