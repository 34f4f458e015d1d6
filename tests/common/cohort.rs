//! Cohort fixtures for the runner's end-to-end tests: the binary, phantom cohorts, a config,
//! and snapshots of output folders.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Writes a config file `name` with `text` into `dir`; its path.
pub fn write_config(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// Runs the destair binary to completion.
pub fn destair(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_destair"))
        .args(args)
        .output()
        .expect("run destair")
}

/// Runs the destair binary and asserts it succeeded (its stderr in the failure message).
pub fn destair_ok(args: &[&str]) -> Output {
    let out = destair(args);
    assert!(
        out.status.success(),
        "destair {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Stderr of a run as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

pub const CONFIG: &str = r#"
[input]
roots = ["cases"]
case_depth = 1

[output]
root = "out"
formats = ["ply", "stl"]

[defaults]
method = "hc"
staircase = true
caps = "smooth"

[[structure]]
pattern = "tumor"
references = ["vein", "trachea"]

[[structure]]
pattern = "vein"
references = ["tumor"]
caps = "preserve"

[[structure]]
pattern = "trachea"
skip = true
"#;

/// A cohort of `n` phantom cases plus, optionally, a case with a corrupt mesh and a case whose
/// tumor's reference (vein) is missing. Returns the config path.
pub fn cohort(dir: &Path, n: usize, broken: bool) -> PathBuf {
    let cases = dir.join("cases");
    destair_ok(&[
        "phantom",
        "cohort",
        "--cases",
        &n.to_string(),
        "--out",
        cases.to_str().unwrap(),
    ]);
    if broken {
        let corrupt = cases.join("zz-corrupt");
        std::fs::create_dir_all(&corrupt).unwrap();
        std::fs::copy(
            cases.join("case-000/trachea.ply"),
            corrupt.join("trachea.ply"),
        )
        .unwrap();
        let mut bytes = std::fs::read(cases.join("case-000/tumor.ply")).unwrap();
        bytes.truncate(bytes.len() / 2);
        std::fs::write(corrupt.join("tumor.ply"), bytes).unwrap();
        let missing = cases.join("zz-missing-ref");
        std::fs::create_dir_all(&missing).unwrap();
        for s in ["tumor", "trachea"] {
            std::fs::copy(
                cases.join(format!("case-001/{s}.ply")),
                missing.join(format!("{s}.ply")),
            )
            .unwrap();
        }
    }
    let config = dir.join("cohort.toml");
    std::fs::write(&config, CONFIG).unwrap();
    config
}

/// Every file under `dir` (relative path -> bytes), except timings.json.
pub fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.file_name().unwrap() != "timings.json" {
                out.insert(
                    p.strip_prefix(dir).unwrap().display().to_string(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    out
}

/// `destair smooth INPUT -o OUTPUT --method METHOD EXTRA...`.
pub fn smooth(input: &Path, output: &Path, method: &str, extra: &[&str]) -> Output {
    let mut args = vec![
        "smooth",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--method",
        method,
    ];
    args.extend_from_slice(extra);
    destair(&args)
}

/// Peak resident memory (kB) and exit code of a child run with extra environment variables,
/// from wait4's rusage (which also reaps it).
#[allow(clippy::zombie_processes)]
pub fn peak_rss_kb(args: &[&str], envs: &[(&str, &str)]) -> (i64, Option<i32>) {
    let child = Command::new(env!("CARGO_BIN_EXE_destair"))
        .args(args)
        .envs(envs.iter().copied())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut status = 0;
    // SAFETY: rusage is plain data; wait4 reaps our own child and fills it in.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let pid = unsafe { libc::wait4(child.id() as i32, &mut status, 0, &mut usage) };
    assert_eq!(pid, child.id() as i32);
    let code = libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status));
    (usage.ru_maxrss, code)
}
