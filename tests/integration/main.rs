//! destair's end-to-end and property tests, one module per area, in one test binary: one link
//! and one set of monomorphised library code instead of one per file, and one pool of test
//! threads over all of them (the slow ones no longer wait for each other). The peak-memory
//! test stays in a binary of its own (`tests/memory.rs`): nothing may run beside it.

#[path = "../common/mod.rs"]
mod common;

mod cfd;
mod cli;
mod context;
mod context_other_tools;
mod extract;
mod honesty;
mod io_corrupt;
mod io_dialects;
mod label_cases;
mod label_shapes;
mod phantom;
mod pictures;
mod remesh;
mod report_html;
mod run;
mod safety;
mod smooth;
mod topology;
mod volume;
