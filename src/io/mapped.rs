//! Memory-mapped input files that survive being cut short while mapped. A file truncated by
//! another process under a mapping makes every read past its new end raise SIGBUS, which
//! would kill the whole run for one case. Each live mapping is registered here; a SIGBUS
//! inside a registered mapping puts zero pages over the rest of it, marks it, and lets the
//! read go on. [`MappedFile::verify`] then fails that file with the reason, so the case fails
//! and the run does not. A SIGBUS anywhere else keeps its default effect.

use std::fs::File;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Once;

/// Mappings that can be guarded at once; beyond that a file is read into memory instead.
const SLOTS: usize = 256;
/// A slot's start while it is being filled in (never a mapping's address).
const CLAIMED: usize = 1;

/// Start address of each registered mapping (0: free, [`CLAIMED`]: being filled in).
static STARTS: [AtomicUsize; SLOTS] = [const { AtomicUsize::new(0) }; SLOTS];
/// End address (exclusive, rounded up to a page) of each registered mapping.
static ENDS: [AtomicUsize; SLOTS] = [const { AtomicUsize::new(0) }; SLOTS];
/// Whether a read ran past the file's end in each registered mapping.
static CUT_SHORT: [AtomicBool; SLOTS] = [const { AtomicBool::new(false) }; SLOTS];
static PAGE: AtomicUsize = AtomicUsize::new(4096);
static INSTALL: Once = Once::new();
/// The SIGBUS action before this module's, which a SIGBUS outside every mapping is passed to (a
/// fuzzer's crash handler, say).
static PREVIOUS: std::sync::OnceLock<Previous> = std::sync::OnceLock::new();

/// A saved signal action (plain data: a handler address, flags, a mask).
struct Previous(libc::sigaction);
// SAFETY: the action is written once before the handler that reads it is installed, and only
// read afterwards.
unsafe impl Sync for Previous {}
unsafe impl Send for Previous {}

/// The bytes of an input file: mapped (and guarded), or read into memory where mapping is not
/// possible (an empty file, or every guard slot taken).
#[derive(Debug)]
pub struct MappedFile {
    map: Option<memmap2::Mmap>,
    owned: Vec<u8>,
    slot: Option<usize>,
}

impl MappedFile {
    /// Maps `file` read-only (its pages read ahead when `populate`), guarded against
    /// truncation.
    pub fn map_with(file: &File, populate: bool) -> std::io::Result<MappedFile> {
        let len = file.metadata()?.len();
        if len == 0 {
            return Ok(MappedFile {
                map: None,
                owned: Vec::new(),
                slot: None,
            });
        }
        install_handler();
        let Some(slot) = claim_slot() else {
            return Ok(MappedFile {
                map: None,
                owned: read_whole(file, len)?,
                slot: None,
            });
        };
        let mut options = memmap2::MmapOptions::new();
        if populate {
            options.populate();
        }
        // SAFETY: a read-only map of a file opened for reading. Another process may still
        // truncate the file while it is mapped: reads past the new end raise SIGBUS, which the
        // handler installed above turns into zero pages and a mark that `verify` reports.
        let map = match unsafe { options.map(file) } {
            Ok(map) => map,
            Err(e) => {
                release_slot(slot);
                return Err(e);
            }
        };
        let page = PAGE.load(Ordering::Relaxed);
        let start = map.as_ptr() as usize;
        ENDS[slot].store((start + map.len()).next_multiple_of(page), Ordering::SeqCst);
        CUT_SHORT[slot].store(false, Ordering::SeqCst);
        STARTS[slot].store(start, Ordering::SeqCst);
        Ok(MappedFile {
            map: Some(map),
            owned: Vec::new(),
            slot: Some(slot),
        })
    }

    /// Bytes already in memory, held as a [`MappedFile`] (nothing to guard).
    pub fn from_bytes(bytes: Vec<u8>) -> MappedFile {
        MappedFile {
            map: None,
            owned: bytes,
            slot: None,
        }
    }

    /// Maps `file` read-only, guarded against truncation.
    pub fn map(file: &File) -> std::io::Result<MappedFile> {
        MappedFile::map_with(file, false)
    }

    /// The file's bytes (as long as the file stays whole; see [`MappedFile::verify`]).
    pub fn bytes(&self) -> &[u8] {
        match &self.map {
            Some(m) => m,
            None => &self.owned,
        }
    }

    /// Fails when the file was cut short while mapped: some of the bytes read were zeros
    /// standing in for what was no longer there.
    pub fn verify(&self) -> std::io::Result<()> {
        match self.slot {
            Some(slot) if CUT_SHORT[slot].load(Ordering::SeqCst) => Err(std::io::Error::other(
                "the file became shorter while it was being read (truncated or rewritten in place by another program); read it again once it is complete",
            )),
            _ => Ok(()),
        }
    }
}

impl Drop for MappedFile {
    fn drop(&mut self) {
        if let Some(slot) = self.slot {
            // Unregistered before it is unmapped: the range may be mapped again by anyone.
            release_slot(slot);
        }
    }
}

/// The file's `len` bytes from its start (whatever its read position, which other readers of
/// the same handle share).
fn read_whole(file: &File, len: u64) -> std::io::Result<Vec<u8>> {
    use std::os::unix::fs::FileExt;
    let n = usize::try_from(len).map_err(|_| std::io::Error::other("the file is too large"))?;
    let mut buf = Vec::new();
    buf.try_reserve_exact(n).map_err(|_| {
        std::io::Error::new(
            std::io::ErrorKind::OutOfMemory,
            format!("cannot allocate {n} bytes to read the file"),
        )
    })?;
    buf.resize(n, 0);
    file.read_exact_at(&mut buf, 0).map_err(|e| {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            std::io::Error::other(
                "the file became shorter while it was being read (truncated or rewritten in place by another program); read it again once it is complete",
            )
        } else {
            e
        }
    })?;
    Ok(buf)
}

fn claim_slot() -> Option<usize> {
    (0..SLOTS).find(|&i| {
        STARTS[i]
            .compare_exchange(0, CLAIMED, Ordering::SeqCst, Ordering::SeqCst)
            .is_ok()
    })
}

fn release_slot(slot: usize) {
    STARTS[slot].store(CLAIMED, Ordering::SeqCst);
    ENDS[slot].store(0, Ordering::SeqCst);
    STARTS[slot].store(0, Ordering::SeqCst);
}

/// Installs the SIGBUS handler once per process.
fn install_handler() {
    INSTALL.call_once(|| {
        // SAFETY: sysconf has no preconditions; sigaction with a zeroed, then filled-in struct
        // and a handler that only does async-signal-safe work (atomics, mmap, signal).
        unsafe {
            let page = libc::sysconf(libc::_SC_PAGESIZE);
            if page > 0 {
                PAGE.store(page as usize, Ordering::Relaxed);
            }
            let mut previous: libc::sigaction = std::mem::zeroed();
            libc::sigaction(libc::SIGBUS, std::ptr::null(), &mut previous);
            let _ = PREVIOUS.set(Previous(previous));
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = on_sigbus as *const () as usize;
            action.sa_flags = libc::SA_SIGINFO;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(libc::SIGBUS, &action, std::ptr::null_mut());
        }
    });
}

/// SIGBUS: inside a registered mapping, zero pages from the faulting page to the mapping's end
/// and a mark; anywhere else, the action there was before (a handler of its own is called; the
/// default is restored, so the faulting access repeats and ends the process as it would have).
extern "C" fn on_sigbus(
    signal: libc::c_int,
    info: *mut libc::siginfo_t,
    context: *mut libc::c_void,
) {
    // SAFETY: the kernel passes a valid siginfo for SA_SIGINFO handlers.
    let addr = unsafe { (*info).si_addr() } as usize;
    let page = PAGE.load(Ordering::Relaxed);
    for slot in 0..SLOTS {
        let start = STARTS[slot].load(Ordering::SeqCst);
        let end = ENDS[slot].load(Ordering::SeqCst);
        if start <= CLAIMED || !(start..end).contains(&addr) {
            continue;
        }
        let from = addr & !(page - 1);
        // SAFETY: [from, end) lies inside a live read-only mapping this module registered;
        // MAP_FIXED replaces those pages with zero-filled anonymous ones, which the owning
        // MappedFile unmaps with the rest when it is dropped.
        let replaced = unsafe {
            libc::mmap(
                from as *mut libc::c_void,
                end - from,
                libc::PROT_READ,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_FIXED,
                -1,
                0,
            )
        };
        if replaced != libc::MAP_FAILED {
            CUT_SHORT[slot].store(true, Ordering::SeqCst);
            return;
        }
    }
    if let Some(Previous(previous)) = PREVIOUS.get() {
        let handler = previous.sa_sigaction;
        if handler != libc::SIG_DFL && handler != libc::SIG_IGN {
            // SAFETY: a handler installed before this one, called as the kernel would have.
            unsafe {
                if previous.sa_flags & libc::SA_SIGINFO != 0 {
                    let f: extern "C" fn(libc::c_int, *mut libc::siginfo_t, *mut libc::c_void) =
                        std::mem::transmute(handler);
                    f(signal, info, context);
                } else {
                    let f: extern "C" fn(libc::c_int) = std::mem::transmute(handler);
                    f(signal);
                }
            }
            return;
        }
    }
    // SAFETY: signal() is async-signal-safe; restoring the default disposition.
    unsafe {
        libc::signal(libc::SIGBUS, libc::SIG_DFL);
    }
}
