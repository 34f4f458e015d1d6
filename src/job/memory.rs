//! Memory: what a case is estimated to need (24 bytes per mesh byte; what reading a label map
//! takes by its header), and how much this process may use: the smallest of the machine's
//! physical memory, the cgroup limit (Slurm, containers), the address-space and data limits
//! (`ulimit -v`, `-d`) and Slurm's `--mem`. The memory budget defaults to half of it, and a
//! configured budget is held to it, so a case the budget admits can get its memory and one it
//! cannot fails alone, with the figure, instead of the allocator aborting the whole run.

use std::path::{Path, PathBuf};

/// Input bytes are multiplied by this to estimate a case's peak memory (decoded meshes,
/// topology, reference grids, smoothing buffers, metrics, encoded outputs). Measured on binary
/// PLY phantom cases of 40 k to 4 M triangles; see `tests/memory.rs` for the check against the
/// peak resident memory of real runs.
pub const MEMORY_PER_INPUT_BYTE: u64 = 24;

/// Estimated peak memory of a case's mesh files (structure, path) while it is processed
/// (bytes): 24 per input byte.
pub fn mesh_memory(meshes: &[(String, PathBuf)]) -> u64 {
    meshes
        .iter()
        .map(|(_, p)| std::fs::metadata(p).map_or(0, |m| m.len()))
        .sum::<u64>()
        .saturating_mul(MEMORY_PER_INPUT_BYTE)
}

/// Estimated peak memory of a case before it is read (bytes): its meshes, and what reading
/// its label maps takes by their headers (their surfaces are counted once they are read, and
/// the case's share of the budget grows then; see [`LoadedCase::memory`](super::load::LoadedCase::memory)).
pub fn memory_estimate(meshes: &[(String, PathBuf)], label_maps: &[PathBuf]) -> u64 {
    let voxels = label_maps
        .iter()
        .map(|p| {
            crate::volume::read_header(p).map_or_else(
                |_| std::fs::metadata(p).map_or(0, |m| m.len()),
                |h| h.bytes_to_read(),
            )
        })
        .fold(0u64, u64::saturating_add);
    mesh_memory(meshes).saturating_add(voxels)
}

/// The memory this process may use and what sets it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MemoryLimit {
    pub bytes: u64,
    /// What sets it, for messages ("physical memory", "ulimit -v", ...).
    pub source: String,
}

/// The smallest of the limits this process runs under (physical memory when nothing else is
/// smaller; `u64::MAX` where nothing can be read at all).
pub fn process_memory_limit() -> MemoryLimit {
    let mut limits: Vec<(u64, String)> = Vec::new();
    if let Some(total) = meminfo_total() {
        limits.push((total, "physical memory".into()));
    }
    if let Some(c) = cgroup_limit() {
        limits.push((c, "the cgroup's memory limit".into()));
    }
    for (resource, name) in [
        (libc::RLIMIT_AS, "ulimit -v (address space)"),
        (libc::RLIMIT_DATA, "ulimit -d (data)"),
    ] {
        if let Some(b) = rlimit(resource) {
            limits.push((b, name.into()));
        }
    }
    if let Some(mb) = std::env::var("SLURM_MEM_PER_NODE")
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
        .filter(|&mb| mb > 0)
    {
        limits.push((mb.saturating_mul(1 << 20), "Slurm's --mem".into()));
    }
    limits.into_iter().min_by_key(|(b, _)| *b).map_or(
        MemoryLimit {
            bytes: u64::MAX,
            source: "no limit found".into(),
        },
        |(bytes, source)| MemoryLimit { bytes, source },
    )
}

fn meminfo_total() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb.saturating_mul(1024))
}

/// The cgroup memory limit of this process: v2's `memory.max` of its cgroup and every parent
/// (the smallest), else v1's `memory.limit_in_bytes`.
fn cgroup_limit() -> Option<u64> {
    let own = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let mut best: Option<u64> = None;
    let mut take = |v: Option<u64>| {
        if let Some(v) = v {
            best = Some(best.map_or(v, |b| b.min(v)));
        }
    };
    for line in own.lines() {
        let mut parts = line.splitn(3, ':');
        let (Some(_), Some(controllers), Some(path)) = (parts.next(), parts.next(), parts.next())
        else {
            continue;
        };
        if controllers.is_empty() {
            // cgroup v2: the limit of the process's cgroup and of every cgroup above it.
            let mut dir = Path::new("/sys/fs/cgroup").join(path.trim_start_matches('/'));
            loop {
                take(read_limit(&dir.join("memory.max")));
                if !dir.pop() || !dir.starts_with("/sys/fs/cgroup") {
                    break;
                }
            }
        } else if controllers.split(',').any(|c| c == "memory") {
            let dir = Path::new("/sys/fs/cgroup/memory").join(path.trim_start_matches('/'));
            take(read_limit(&dir.join("memory.limit_in_bytes")));
        }
    }
    best
}

/// A cgroup limit file: a number of bytes, or `max` (none). v1 writes a huge number for none.
fn read_limit(path: &Path) -> Option<u64> {
    let text = std::fs::read_to_string(path).ok()?;
    let v: u64 = text.trim().parse().ok()?;
    (v < 1 << 60).then_some(v)
}

fn rlimit(resource: libc::__rlimit_resource_t) -> Option<u64> {
    // SAFETY: getrlimit fills a plain struct we own.
    let mut r: libc::rlimit = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrlimit(resource, &mut r) } != 0 || r.rlim_cur == libc::RLIM_INFINITY {
        return None;
    }
    Some(r.rlim_cur)
}
