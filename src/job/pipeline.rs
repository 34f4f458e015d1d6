//! The streaming pipeline: a loader thread reads and hashes cases, a fixed number of worker
//! threads process them (rayon only inside a case), and the calling thread writes the results,
//! joined by bounded channels. Cases in flight are bounded by a memory budget on their input
//! bytes, so a cohort of 10 000 cases runs in the memory of a few. A stop flag (set on SIGTERM
//! or SIGINT) stops the loader from taking new cases; cases in flight finish and are written.

use super::case::{load_case, process_case, CaseOutput};
use super::discover::CaseInput;
use super::plan::Plan;
use crate::io::write_atomically;

use crossbeam_channel::bounded;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Condvar, Mutex};

/// Input bytes are multiplied by this to estimate a case's peak memory (decoded mesh,
/// topology, buffers, encoded outputs).
const MEMORY_PER_INPUT_BYTE: u64 = 8;

/// Options of a run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Redo cases even when their manifest says they are done with the same inputs and settings.
    pub force: bool,
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
    },
    /// A case could not be written (its outputs are incomplete; a rerun redoes it).
    WriteFailed { id: String, error: String },
}

/// The outcome of a run.
#[derive(Debug, Clone, Default)]
pub struct RunResult {
    pub processed: Vec<String>,
    pub skipped: Vec<String>,
    pub failed: Vec<String>,
    /// Cases not started because the run was stopped.
    pub not_started: usize,
}

/// `manifest.json` of a case: written last, so its presence means every output is complete.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Manifest {
    pub key: String,
    pub status: String,
    pub outputs: Vec<String>,
}

/// Output folder of a case.
pub fn case_dir(plan: &Plan, id: &str) -> PathBuf {
    if id == "." {
        plan.output_root.clone()
    } else {
        plan.output_root.join(id)
    }
}

/// Whether a case's outputs are complete and were made from the same inputs and settings.
fn is_done(dir: &Path, key: &str) -> bool {
    let Ok(text) = std::fs::read(dir.join("manifest.json")) else {
        return false;
    };
    let Ok(m) = serde_json::from_slice::<Manifest>(&text) else {
        return false;
    };
    m.key == key
        && dir.join("report.json").is_file()
        && m.outputs.iter().all(|o| dir.join(o).is_file())
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
        while *used > 0 && *used + n > self.limit {
            used = self.freed.wait(used).unwrap_or_else(|e| e.into_inner());
        }
        *used += n;
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

/// Writes one case's outputs, reports and (last) its manifest, each atomically.
pub fn write_case_output(plan: &Plan, out: &CaseOutput) -> std::io::Result<()> {
    let dir = case_dir(plan, &out.id);
    std::fs::create_dir_all(&dir)?;
    // A case is only redone when its earlier writing did not finish; clear what that left.
    crate::io::remove_stale_temp_files(&dir)?;
    for (name, bytes) in &out.files {
        write_atomically(&dir.join(name), |w| w.write_all(bytes))?;
    }
    let report = serde_json::to_vec_pretty(&out.report).map_err(std::io::Error::other)?;
    write_atomically(&dir.join("report.json"), |w| w.write_all(&report))?;
    write_atomically(&dir.join("report.md"), |w| {
        w.write_all(out.report.to_markdown().as_bytes())
    })?;
    let timings = serde_json::to_vec_pretty(&out.timings).map_err(std::io::Error::other)?;
    write_atomically(&dir.join("timings.json"), |w| w.write_all(&timings))?;
    let manifest = Manifest {
        key: out.key.clone(),
        status: out.report.status.clone(),
        outputs: out.files.iter().map(|(n, _)| n.clone()).collect(),
    };
    let manifest = serde_json::to_vec_pretty(&manifest).map_err(std::io::Error::other)?;
    write_atomically(&dir.join("manifest.json"), |w| w.write_all(&manifest))
}

/// The failed output of a case whose processing hit an internal error (a bug).
fn internal_error(id: String, key: String) -> CaseOutput {
    CaseOutput {
        report: crate::report::case::CaseReport {
            schema_version: crate::report::case::SCHEMA_VERSION,
            case: id.clone(),
            status: "failed".into(),
            inputs: Vec::new(),
            structures: Vec::new(),
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

/// Runs the cases through the pipeline; `on_event` is called from the writer for each case.
pub fn run(
    plan: &Plan,
    cases: Vec<CaseInput>,
    options: &RunOptions,
    stop: &AtomicBool,
    on_event: &mut dyn FnMut(Event),
) -> RunResult {
    let budget = Budget {
        limit: plan.memory_budget_bytes,
        used: Mutex::new(0),
        freed: Condvar::new(),
    };
    let n_cases = cases.len();
    let (work_tx, work_rx) = bounded::<(super::case::LoadedCase, u64)>(plan.workers);
    let (done_tx, done_rx) = bounded::<Finished>(plan.workers);
    let mut result = RunResult::default();
    let mut started = 0usize;
    std::thread::scope(|scope| {
        // Loader.
        let loader_done = done_tx.clone();
        let budget = &budget;
        let started_ref = &mut started;
        scope.spawn(move || {
            for case in cases {
                if stop.load(Ordering::Relaxed) {
                    break;
                }
                let size: u64 = case
                    .meshes
                    .iter()
                    .map(|(_, p)| std::fs::metadata(p).map_or(0, |m| m.len()))
                    .sum::<u64>()
                    * MEMORY_PER_INPUT_BYTE;
                budget.acquire(size);
                *started_ref += 1;
                let loaded = load_case(plan, case);
                if !options.force && is_done(&case_dir(plan, &loaded.input.id), &loaded.key) {
                    let skipped =
                        Finished::Skipped(loaded.input.id.clone(), size, loaded.files.len());
                    if loader_done.send(skipped).is_err() {
                        break;
                    }
                    continue;
                }
                if work_tx.send((loaded, size)).is_err() {
                    break;
                }
            }
        });
        // Workers.
        for _ in 0..plan.workers {
            let rx = work_rx.clone();
            let tx = done_tx.clone();
            scope.spawn(move || {
                for (loaded, size) in rx {
                    // A bug must not take the cohort down: it fails this case only.
                    let id = loaded.input.id.clone();
                    let key = loaded.key.clone();
                    let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                        process_case(plan, loaded)
                    }))
                    .unwrap_or_else(|_| internal_error(id, key));
                    if tx.send(Finished::Done(Box::new(out), size)).is_err() {
                        break;
                    }
                }
            });
        }
        drop(done_tx);
        drop(work_rx);
        // Writer: this thread.
        for finished in done_rx {
            match finished {
                Finished::Skipped(id, size, structures) => {
                    budget.release(size);
                    let failed = std::fs::read(case_dir(plan, &id).join("manifest.json"))
                        .ok()
                        .and_then(|t| serde_json::from_slice::<Manifest>(&t).ok())
                        .is_some_and(|m| m.status != "ok");
                    if failed {
                        result.failed.push(id.clone());
                    }
                    result.skipped.push(id.clone());
                    on_event(Event::CaseDone {
                        id,
                        failed,
                        skipped: true,
                        structures,
                    });
                }
                Finished::Done(out, size) => {
                    let written = write_case_output(plan, &out);
                    budget.release(size);
                    match written {
                        Ok(()) => {
                            let failed = out.failed();
                            if failed {
                                result.failed.push(out.id.clone());
                            }
                            result.processed.push(out.id.clone());
                            on_event(Event::CaseDone {
                                id: out.id.clone(),
                                failed,
                                skipped: false,
                                structures: out.report.structures.len(),
                            });
                        }
                        Err(e) => {
                            result.failed.push(out.id.clone());
                            on_event(Event::WriteFailed {
                                id: out.id.clone(),
                                error: e.to_string(),
                            });
                        }
                    }
                }
            }
        }
    });
    result.not_started = n_cases - started;
    result
}
