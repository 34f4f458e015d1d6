//! The streaming pipeline: a loader thread reads and hashes cases, a fixed number of worker
//! threads process them (rayon only inside a case), and the calling thread writes the results,
//! joined by bounded channels. Cases in flight are bounded by a memory budget on their
//! estimated memory (see [`super::memory`]), so a cohort of 10 000 cases runs in the memory of
//! a few.
//!
//! Stopping: when the stop flag is set (SIGTERM, SIGINT), the loader takes no new case, and the
//! writer returns as soon as the case it is writing (if any) is complete. Cases still being
//! computed are abandoned: their threads are not waited for and end with the process, their
//! folders keep whatever a previous run wrote, and a rerun redoes them. So a stop takes effect
//! within a fraction of a second whatever the size of the cases.

use super::case::{process_case, CaseOutput};
use super::discover::CaseInput;
use super::load::{load_case, LoadedCase};
use super::lock::{LockMode, LockScope, OutputLock, Wait};
use super::memory::memory_estimate;
use super::outputs::{case_dir, is_done, read_manifest, write_case_output};
use super::plan::Plan;
use crate::io::{remove_stale_temp_files, ProtectedFiles};

use crossbeam_channel::{bounded, RecvTimeoutError};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

/// How often the writer looks at the stop flag while it waits for a case.
const POLL: Duration = Duration::from_millis(25);

/// Options of a run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Redo cases even when their manifest says they are done with the same inputs and settings.
    pub force: bool,
    /// Input files and folders of the whole cohort: nothing is ever written onto one of them.
    pub protected: ProtectedFiles,
}

/// What the pipeline reports as it goes.
#[derive(Debug, Clone)]
pub enum Event {
    /// A case was written (or skipped as already done); `structures` counts its meshes.
    CaseDone {
        id: String,
        failed: bool,
        skipped: bool,
        structures: usize,
        /// Structures that failed.
        failed_structures: usize,
        /// The first error line of each failed structure (or of the case).
        errors: Vec<String>,
    },
    /// A case could not be written (its outputs are incomplete; a rerun redoes it).
    WriteFailed {
        id: String,
        error: String,
        /// The device is full or the quota used up.
        disk_full: bool,
    },
}

/// The outcome of a run.
#[derive(Debug, Clone, Default)]
pub struct RunResult {
    pub processed: Vec<String>,
    pub skipped: Vec<String>,
    pub failed: Vec<String>,
    /// Cases not started because the run was stopped.
    pub not_started: usize,
    /// Cases started but abandoned unwritten because the run was stopped.
    pub unfinished: usize,
}

/// Bounds the estimated memory of the cases in flight.
struct Budget {
    limit: u64,
    used: Mutex<u64>,
    freed: Condvar,
}

impl Budget {
    fn acquire(&self, n: u64) {
        let mut used = self.used.lock().unwrap_or_else(|e| e.into_inner());
        // A case larger than the whole budget still runs, alone.
        while *used > 0 && used.saturating_add(n) > self.limit {
            used = self.freed.wait(used).unwrap_or_else(|e| e.into_inner());
        }
        *used += n;
    }

    /// Grows a share of `held` bytes by `n` (a case whose surfaces were counted after it was
    /// read), waiting while other cases hold what it needs; alone it always gets it.
    fn acquire_more(&self, held: u64, n: u64) {
        let mut used = self.used.lock().unwrap_or_else(|e| e.into_inner());
        while *used > held && used.saturating_add(n) > self.limit {
            used = self.freed.wait(used).unwrap_or_else(|e| e.into_inner());
        }
        *used = used.saturating_add(n);
    }

    fn release(&self, n: u64) {
        let mut used = self.used.lock().unwrap_or_else(|e| e.into_inner());
        *used = used.saturating_sub(n);
        self.freed.notify_all();
    }
}

/// What the writer receives.
enum Finished {
    Done(Box<CaseOutput>, u64),
    Skipped(String, u64, usize),
}

/// The failed output of a case whose processing hit an internal error (a bug).
fn internal_error(id: String, key: String) -> CaseOutput {
    CaseOutput {
        report: crate::report::case::CaseReport {
            schema_version: crate::report::case::SCHEMA_VERSION,
            case: id.clone(),
            status: "failed".into(),
            inputs: Vec::new(),
            label_maps: Vec::new(),
            structures: Vec::new(),
            guard: None,
            warnings: Vec::new(),
            errors: vec![
                "internal error while processing this case (a bug in destair; please report it)"
                    .into(),
            ],
        },
        id,
        files: Vec::new(),
        timings: serde_json::Value::Null,
        key,
    }
}

/// The loader: reads the cases one after the other within the memory budget; clears temp files
/// that killed runs left in each case's folder (done or not) and passes on what is to be done.
#[allow(clippy::too_many_arguments)]
fn load_cases(
    plan: &Plan,
    cases: Vec<CaseInput>,
    force: bool,
    budget: &Budget,
    started: &AtomicUsize,
    lock: &OutputLock,
    stop: &AtomicBool,
    work: &crossbeam_channel::Sender<(LoadedCase, u64)>,
    done: &crossbeam_channel::Sender<Finished>,
) {
    for case in cases {
        if stop.load(Ordering::Relaxed) {
            return;
        }
        let size = memory_estimate(&case.meshes, &case.label_maps);
        budget.acquire(size);
        // The wait may have been long: a stop during it must not start another case.
        if stop.load(Ordering::Relaxed) {
            budget.release(size);
            return;
        }
        started.fetch_add(1, Ordering::Relaxed);
        let loaded = load_case(plan, case);
        // The label maps' surfaces are counted now: the case's share grows to its estimate.
        let extra = loaded.memory().saturating_sub(size);
        budget.acquire_more(size, extra);
        let size = size + extra;
        let dir = case_dir(plan, &loaded.input.id);
        let scope = LockScope::Case(loaded.input.id.clone());
        if lock
            .lock(&scope, LockMode::Exclusive, Wait::Until(stop))
            .is_err()
        {
            return;
        }
        let _ = remove_stale_temp_files(&dir);
        let already = !force && is_done(&dir, &loaded.key);
        // A case to compute keeps its lock until the writer has written it: a `run-case` or
        // another shard asking for it meanwhile waits (or is told it is busy) instead of
        // computing it alongside.
        let sent = if already {
            lock.unlock(&scope);
            let n = loaded.files.len();
            done.send(Finished::Skipped(loaded.input.id, size, n))
                .is_ok()
        } else {
            work.send((loaded, size)).is_ok()
        };
        if !sent {
            return;
        }
    }
}

/// The first line of each error of a failed case, for the console.
fn first_error_lines(out: &CaseOutput) -> Vec<String> {
    let first = |e: &str| e.lines().next().unwrap_or("").to_string();
    let mut lines: Vec<String> = out
        .report
        .structures
        .iter()
        .filter_map(|s| {
            s.error
                .as_ref()
                .map(|e| format!("{}: {}", s.name, first(e)))
        })
        .collect();
    if lines.is_empty() {
        lines = out.report.errors.iter().map(|e| first(e)).collect();
    }
    lines
}

/// Runs the cases through the pipeline; `on_event` is called from the writer (this thread) for
/// each case. `lock` is the output root's lock file, which holds the per-case locks.
pub fn run(
    plan: &Plan,
    cases: Vec<CaseInput>,
    options: &RunOptions,
    lock: &Arc<OutputLock>,
    stop: &Arc<AtomicBool>,
    on_event: &mut dyn FnMut(Event),
) -> std::io::Result<RunResult> {
    let plan = Arc::new(plan.clone());
    let budget = Arc::new(Budget {
        limit: plan.memory_budget_bytes,
        used: Mutex::new(0),
        freed: Condvar::new(),
    });
    let started = Arc::new(AtomicUsize::new(0));
    let n_cases = cases.len();
    let (work_tx, work_rx) = bounded::<(LoadedCase, u64)>(plan.workers);
    let (done_tx, done_rx) = bounded::<Finished>(plan.workers);
    let mut handles = Vec::new();
    {
        let (plan, budget, started, lock, stop) = (
            plan.clone(),
            budget.clone(),
            started.clone(),
            lock.clone(),
            stop.clone(),
        );
        let done = done_tx.clone();
        let force = options.force;
        handles.push(
            std::thread::Builder::new()
                .name("destair-loader".into())
                .spawn(move || {
                    load_cases(
                        &plan, cases, force, &budget, &started, &lock, &stop, &work_tx, &done,
                    )
                })?,
        );
    }
    for i in 0..plan.workers {
        let (rx, tx, plan, stop) = (work_rx.clone(), done_tx.clone(), plan.clone(), stop.clone());
        handles.push(
            std::thread::Builder::new()
                .name(format!("destair-worker-{i}"))
                .spawn(move || {
                    for (loaded, size) in rx {
                        if stop.load(Ordering::Relaxed) {
                            return;
                        }
                        // A bug must not take the cohort down: it fails this case only.
                        let id = loaded.input.id.clone();
                        let key = loaded.key.clone();
                        let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                            process_case(&plan, loaded)
                        }))
                        .unwrap_or_else(|_| internal_error(id, key));
                        if tx.send(Finished::Done(Box::new(out), size)).is_err() {
                            return;
                        }
                    }
                })?,
        );
    }
    drop(done_tx);
    drop(work_rx);
    let mut result = RunResult::default();
    let mut written = 0usize;
    let mut stopped = false;
    loop {
        if stop.load(Ordering::Relaxed) {
            stopped = true;
            break;
        }
        let finished = match done_rx.recv_timeout(POLL) {
            Ok(f) => f,
            Err(RecvTimeoutError::Timeout) => continue,
            Err(RecvTimeoutError::Disconnected) => break,
        };
        match finished {
            Finished::Skipped(id, size, structures) => {
                budget.release(size);
                written += 1;
                let failed = read_manifest(&case_dir(&plan, &id)).is_some_and(|m| m.status != "ok");
                if failed {
                    result.failed.push(id.clone());
                }
                result.skipped.push(id.clone());
                on_event(Event::CaseDone {
                    id,
                    failed,
                    skipped: true,
                    structures,
                    failed_structures: 0,
                    errors: Vec::new(),
                });
            }
            Finished::Done(out, size) => {
                let scope = LockScope::Case(out.id.clone());
                if lock
                    .lock(&scope, LockMode::Exclusive, Wait::Until(stop))
                    .is_err()
                {
                    stopped = true;
                    break;
                }
                let outcome = write_case_output(&plan, &out, &options.protected);
                lock.unlock(&scope);
                written += 1;
                let event = match outcome {
                    Ok(()) => {
                        let failed = out.failed();
                        if failed {
                            result.failed.push(out.id.clone());
                        }
                        result.processed.push(out.id.clone());
                        Event::CaseDone {
                            id: out.id.clone(),
                            failed,
                            skipped: false,
                            structures: out.report.structures.len(),
                            failed_structures: out
                                .report
                                .structures
                                .iter()
                                .filter(|s| s.error.is_some())
                                .count(),
                            errors: if failed {
                                first_error_lines(&out)
                            } else {
                                Vec::new()
                            },
                        }
                    }
                    Err(e) => {
                        result.failed.push(out.id.clone());
                        Event::WriteFailed {
                            id: out.id.clone(),
                            error: e.to_string(),
                            disk_full: e.is_disk_full(),
                        }
                    }
                };
                // The case's memory is freed before its share of the budget is: otherwise the
                // next case loads while this one's outputs are still held.
                drop(out);
                budget.release(size);
                on_event(event);
            }
        }
    }
    if !stopped {
        for h in handles {
            let _ = h.join();
        }
    }
    let started = started.load(Ordering::Relaxed);
    result.not_started = n_cases - started.min(n_cases);
    result.unfinished = started.saturating_sub(written);
    Ok(result)
}
