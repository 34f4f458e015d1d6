//! Data safety of the runner and the one-mesh commands: inputs are never written, whatever the
//! path spelling; outputs never come back as cases; one run at a time per output folder; a stop
//! takes effect within a second; limits, odd files, full disks and unreadable folders give
//! clear errors; and a randomized soak of all of these ends with untouched inputs and the
//! bytes of a clean run.

use crate::common;

use common::cohort::{cohort, destair, destair_ok, smooth, snapshot, stderr, write_config};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_destair"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn signal(child: &Child, sig: i32) {
    // SAFETY: sending a signal to our own child process.
    unsafe {
        libc::kill(child.id() as i32, sig);
    }
}

/// Content hashes of every file below `dir`.
fn hashes(dir: &Path) -> BTreeMap<String, String> {
    snapshot(dir)
        .into_iter()
        .map(|(k, v)| (k, blake3::hash(&v).to_hex().to_string()))
        .collect()
}

/// The standard config with other `[input]`/`[output]` roots and extra lines.
fn config_with(out_root: &str, extra_output: &str) -> String {
    common::cohort::CONFIG.replace(
        "root = \"out\"",
        &format!("root = {out_root:?}\n{extra_output}"),
    )
}

#[test]
fn output_roots_that_are_the_input_root_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    cohort(dir, 2, false);
    std::os::unix::fs::symlink(dir.join("cases"), dir.join("link")).unwrap();
    let before = hashes(&dir.join("cases"));
    for out in ["cases/../cases", "./cases/", "cases", "link", "link/", "."] {
        let c = write_config(dir, "c.toml", &config_with(out, ""));
        let run = destair(&["run", c.to_str().unwrap()]);
        assert_eq!(run.status.code(), Some(2), "{out}: {}", stderr(&run));
        assert!(
            stderr(&run).contains("input root"),
            "{out}: {}",
            stderr(&run)
        );
    }
    let c = write_config(dir, "c.toml", common::cohort::CONFIG);
    for out in ["cases", "cases/case-000", "cases/../cases/", "link"] {
        let run = destair(&[
            "run-case",
            dir.join("cases/case-000").to_str().unwrap(),
            "--config",
            c.to_str().unwrap(),
            "--out",
            dir.join(out).to_str().unwrap(),
        ]);
        assert_eq!(run.status.code(), Some(2), "{out}: {}", stderr(&run));
    }
    assert_eq!(hashes(&dir.join("cases")), before, "inputs changed");
    // The last line of defence: an output path that is an input by inode (a hard link left in
    // the output folder) fails that case and leaves the input alone.
    std::fs::create_dir_all(dir.join("out/case-001")).unwrap();
    std::fs::hard_link(
        dir.join("cases/case-001/tumor.ply"),
        dir.join("out/case-001/tumor.ply"),
    )
    .unwrap();
    let run = destair(&["run", c.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
    assert!(
        stderr(&run).contains("is an input of this run"),
        "{}",
        stderr(&run)
    );
    assert_eq!(hashes(&dir.join("cases")), before, "inputs changed");
}

#[test]
fn outputs_never_come_back_as_cases() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    cohort(dir, 2, false);
    for (i, out) in ["out", "cases/../out", "./out/", "link-out"]
        .iter()
        .enumerate()
    {
        if *out == "link-out" {
            std::os::unix::fs::symlink(dir.join("out"), dir.join("link-out")).unwrap();
        }
        let text = format!(
            "[input]\nroots = [\".\"]\n[output]\nroot = {out:?}\n[defaults]\nmethod = \"laplace\"\n"
        );
        let c = write_config(dir, "here.toml", &text);
        let run = destair(&["run", c.to_str().unwrap()]);
        assert!(run.status.success(), "{out}: {}", stderr(&run));
        let list = destair(&["list", c.to_str().unwrap()]);
        let ids: Vec<String> = String::from_utf8_lossy(&list.stdout)
            .lines()
            .map(|l| l.split('\t').next().unwrap().to_string())
            .collect();
        assert_eq!(
            ids,
            ["cases/case-000", "cases/case-001"],
            "round {i}: {out}"
        );
        assert!(!dir.join("out/out").exists() && !dir.join("out/cases/out").exists());
    }
}

#[test]
fn smooth_and_export_refuse_to_overwrite_their_input() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    cohort(dir, 1, false);
    let tumor = dir.join("cases/case-000/tumor.ply");
    let before = std::fs::read(&tumor).unwrap();
    let spelled = dir.join("cases/case-000/../case-000/tumor.ply");
    for out in [&tumor, &spelled] {
        let run = smooth(&tumor, out, "laplace", &[]);
        assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
        assert!(stderr(&run).contains("--force"), "{}", stderr(&run));
    }
    let run = destair(&[
        "inspect",
        tumor.to_str().unwrap(),
        "--export",
        spelled.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    assert_eq!(std::fs::read(&tumor).unwrap(), before);
    let run = smooth(&tumor, &tumor, "laplace", &["--force"]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert_ne!(std::fs::read(&tumor).unwrap(), before);
}

/// A cohort whose one big case keeps a run busy for a long time (huge iteration count).
fn slow_cohort(dir: &Path, triangles: u64, iterations: usize) -> PathBuf {
    destair_ok(&[
        "phantom",
        "big",
        &triangles.to_string(),
        "--out",
        dir.join("cases/big").to_str().unwrap(),
    ]);
    write_config(
        dir,
        "slow.toml",
        &format!(
            "[input]\nroots = [\"cases\"]\ncase_depth = 1\n[output]\nroot = \"out\"\n[defaults]\nmethod = \"laplace\"\nstaircase = false\niterations = {iterations}\n"
        ),
    )
}

/// Reads a spawned run's stderr until its first line, which it prints once it holds its output
/// folder; the rest of stderr is drained in the background.
fn wait_until_running(child: &mut Child) {
    use std::io::BufRead;
    let mut lines = std::io::BufReader::new(child.stderr.take().unwrap()).lines();
    let first = lines.next().unwrap().unwrap();
    assert!(first.contains("destair:"), "{first}");
    std::thread::spawn(move || lines.for_each(drop));
}

#[test]
fn one_run_at_a_time_per_output_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let c = slow_cohort(dir, 100_000, 100_000);
    let mut first = spawn(&["run", c.to_str().unwrap()]);
    wait_until_running(&mut first);
    let second = destair(&["run", c.to_str().unwrap()]);
    let err = stderr(&second);
    assert_eq!(second.status.code(), Some(2), "{err}");
    assert!(
        err.contains("in use by another destair run")
            && err.contains(&format!("pid {}", first.id())),
        "{err}"
    );
    // Shards and run-case share the folder with each other, not with an unsharded run.
    let shard = destair(&["run", c.to_str().unwrap(), "--shard", "0/2"]);
    assert_eq!(shard.status.code(), Some(2), "{}", stderr(&shard));
    // --wait waits, and a stop while waiting ends it with 143.
    let mut waiting = spawn(&["run", c.to_str().unwrap(), "--wait"]);
    std::thread::sleep(Duration::from_millis(500));
    assert!(
        waiting.try_wait().unwrap().is_none(),
        "--wait returned early"
    );
    signal(&waiting, libc::SIGTERM);
    assert_eq!(waiting.wait().unwrap().code(), Some(143));
    signal(&first, libc::SIGTERM);
    assert_eq!(first.wait().unwrap().code(), Some(143));
    // With the folder free, --wait runs at once.
    let quick = write_config(
        dir,
        "slow.toml",
        "[input]\nroots = [\"cases\"]\ncase_depth = 1\n[output]\nroot = \"out\"\n[defaults]\nmethod = \"laplace\"\niterations = 1\nstaircase = false\n",
    );
    destair_ok(&["run", quick.to_str().unwrap(), "--wait"]);
}

#[test]
fn concurrent_shards_and_run_case_share_an_output_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let c = cohort(dir, 8, false);
    let c = c.to_str().unwrap();
    let clean = {
        destair_ok(&["run", c]);
        let s = snapshot(&dir.join("out"));
        std::fs::remove_dir_all(dir.join("out")).unwrap();
        s
    };
    let mut children: Vec<Child> = (0..3)
        .map(|i| spawn(&["run", c, "--shard", &format!("{i}/3")]))
        .collect();
    // Run-case jobs for some of the same cases at the same time, as a second workflow might.
    for case in ["case-000", "case-005"] {
        children.push(spawn(&[
            "run-case",
            dir.join("cases").join(case).to_str().unwrap(),
            "--config",
            c,
            "--out",
            dir.join("out").to_str().unwrap(),
            "--wait",
        ]));
    }
    for mut ch in children {
        let status = ch.wait().unwrap();
        assert!(status.success(), "{status:?}");
    }
    destair_ok(&[
        "summarize",
        dir.join("out").to_str().unwrap(),
        "--config",
        c,
    ]);
    assert!(
        snapshot(&dir.join("out")) == clean,
        "concurrent shards differ from one run"
    );
}

#[test]
fn stale_temp_files_go_and_outputs_no_longer_made_are_removed() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let c = cohort(dir, 3, false);
    let c_str = c.to_str().unwrap();
    destair_ok(&["run", c_str]);
    let case = dir.join("out/case-001");
    // A temp file of a write cut short by kill -9 in a case that is done.
    std::fs::write(case.join(".destair-AbC123.tmp"), vec![0u8; 1000]).unwrap();
    let rerun = destair(&["run", c_str]);
    assert!(
        stderr(&rerun).contains("3 already done"),
        "{}",
        stderr(&rerun)
    );
    assert!(!case.join(".destair-AbC123.tmp").exists());
    // Fewer formats, then another naming: the old files go.
    std::fs::write(
        &c,
        common::cohort::CONFIG.replace("formats = [\"ply\", \"stl\"]", "formats = [\"ply\"]"),
    )
    .unwrap();
    destair_ok(&["run", c_str]);
    assert!(case.join("tumor.ply").is_file() && !case.join("tumor.stl").exists());
    std::fs::write(
        &c,
        common::cohort::CONFIG.replace(
            "formats = [\"ply\", \"stl\"]",
            "formats = [\"ply\"]\nnaming = \"{case}_{structure}\"",
        ),
    )
    .unwrap();
    destair_ok(&["run", c_str]);
    let names: Vec<String> = std::fs::read_dir(&case)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".ply") || n.ends_with(".stl"))
        .collect();
    let mut names = names;
    names.sort();
    assert_eq!(
        names,
        [
            "case-001_trachea.ply",
            "case-001_tumor.ply",
            "case-001_vein.ply"
        ]
    );
    // A case leaves the cohort: run warns, summarize names it, --prune removes it.
    std::fs::remove_dir_all(dir.join("cases/case-002")).unwrap();
    let run = destair(&["run", c_str]);
    assert!(run.status.success());
    assert!(
        stderr(&run).contains("no longer in the cohort: case-002"),
        "{}",
        stderr(&run)
    );
    let sum = destair_ok(&[
        "summarize",
        dir.join("out").to_str().unwrap(),
        "--config",
        c_str,
    ]);
    assert!(String::from_utf8_lossy(&sum.stdout).contains("not in the cohort: case-002"));
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("out/summary.json")).unwrap()).unwrap();
    assert_eq!(summary["n_cases"], 2);
    assert!(dir.join("out/case-002").exists());
    destair_ok(&["run", c_str, "--prune"]);
    assert!(!dir.join("out/case-002").exists());
    assert!(
        destair(&["run", c_str, "--prune", "--shard", "0/2"])
            .status
            .code()
            == Some(2)
    );
}

#[test]
fn sigterm_ends_a_run_within_a_second_whatever_the_case_size() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    // First a quick run, whose outputs a stopped run must leave as they are.
    let c = slow_cohort(dir, 400_000, 1);
    destair_ok(&["run", c.to_str().unwrap()]);
    let before = snapshot(&dir.join("out"));
    let c = slow_cohort(dir, 400_000, 100_000);
    for delay_ms in [300u64, 1500] {
        let mut child = spawn(&["run", c.to_str().unwrap()]);
        std::thread::sleep(Duration::from_millis(delay_ms));
        signal(&child, libc::SIGTERM);
        let sent = Instant::now();
        let status = child.wait().unwrap();
        let took = sent.elapsed().as_secs_f64();
        eprintln!(
            "SIGTERM after {delay_ms} ms: exit {:?} {took:.3} s later",
            status.code()
        );
        assert_eq!(status.code(), Some(143));
        assert!(took < 1.0, "exit {took:.2} s after SIGTERM");
        assert!(
            snapshot(&dir.join("out")) == before,
            "a stopped case touched its outputs"
        );
    }
}

#[test]
fn absurd_limits_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    cohort(dir, 1, false);
    for (extra, needle) in [
        ("[run]\nworkers = 100000000\n", "workers"),
        (
            "[run]\nmemory_budget_mb = 100000000000000\n",
            "memory_budget_mb",
        ),
        ("[defaults]\niterations = 100000000000\n", "iterations"),
        ("[defaults]\niterations = 0\n", "iterations"),
    ] {
        let text = common::cohort::CONFIG.replace("[defaults]\n", "[defaults_]\n");
        let text = if extra.starts_with("[defaults]") {
            common::cohort::CONFIG.replace("[defaults]\n", extra)
        } else {
            format!("{}{extra}", text.replace("[defaults_]\n", "[defaults]\n"))
        };
        let c = write_config(dir, "c.toml", &text);
        let run = destair(&["run", c.to_str().unwrap()]);
        assert_eq!(run.status.code(), Some(2), "{extra}: {}", stderr(&run));
        assert!(stderr(&run).contains(needle), "{}", stderr(&run));
    }
    let tumor = dir.join("cases/case-000/tumor.ply");
    let started = Instant::now();
    let run = destair(&["--threads", "2000", "inspect", tumor.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    assert!(started.elapsed() < Duration::from_secs(2));
    let run = Command::new(env!("CARGO_BIN_EXE_destair"))
        .args(["inspect", tumor.to_str().unwrap()])
        .env("SLURM_CPUS_PER_TASK", "0")
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(2));
    assert!(
        stderr(&run).contains("SLURM_CPUS_PER_TASK"),
        "{}",
        stderr(&run)
    );
    let out = dir.join("x.ply");
    let run = smooth(&tumor, &out, "hc", &["--iterations", "100000000000"]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
}

#[test]
fn devices_fifos_and_folders_are_refused_at_once() {
    let tmp = tempfile::tempdir().unwrap();
    let fifo = tmp.path().join("mesh.ply");
    let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: mkfifo on a path we own.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
    for (path, needle) in [
        ("/dev/zero", "not a regular file"),
        (fifo.to_str().unwrap(), "not a regular file"),
        (tmp.path().to_str().unwrap(), "is a folder"),
    ] {
        let started = Instant::now();
        let run = destair(&["inspect", path]);
        assert_eq!(run.status.code(), Some(3), "{path}: {}", stderr(&run));
        assert!(stderr(&run).contains(needle), "{path}: {}", stderr(&run));
        assert!(started.elapsed() < Duration::from_secs(2));
    }
    let run = destair(&["check", "/dev/zero"]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    assert!(stderr(&run).contains("not a regular file"));
}

/// Mounts a tmpfs of `size` at `dir` (root only); false where mounting is not allowed.
fn mount_tmpfs(dir: &Path, size: &str) -> bool {
    std::fs::create_dir_all(dir).unwrap();
    Command::new("mount")
        .args([
            "-t",
            "tmpfs",
            "-o",
            &format!("size={size}"),
            "tmpfs",
            dir.to_str().unwrap(),
        ])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

fn umount(dir: &Path) {
    let _ = Command::new("umount").arg(dir).status();
}

#[test]
fn full_disks_and_bad_output_roots_say_what_and_where() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let c = cohort(dir, 4, false);
    // An output root that is a file: exit 2, named.
    std::fs::write(dir.join("out"), b"not a folder").unwrap();
    let run = destair(&["run", c.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    assert!(
        stderr(&run).contains("out") && stderr(&run).contains("not a folder"),
        "{}",
        stderr(&run)
    );
    std::fs::remove_file(dir.join("out")).unwrap();
    if !mount_tmpfs(&dir.join("out"), "600k") {
        eprintln!("skipped the full-disk part: cannot mount a tmpfs here");
        return;
    }
    let run = destair(&["run", c.to_str().unwrap()]);
    let err = stderr(&run);
    umount(&dir.join("out"));
    assert_eq!(run.status.code(), Some(3), "{err}");
    assert_eq!(err.matches("output device is full").count(), 1, "{err}");
    assert!(
        err.contains("No space left on device") && err.contains("/out/case-"),
        "{err}"
    );
}

#[test]
fn an_unreadable_case_folder_is_a_failed_case() {
    // SAFETY: geteuid has no preconditions.
    let root = unsafe { libc::geteuid() } == 0;
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let c = cohort(dir, 3, false);
    let locked = dir.join("cases/case-001");
    let mode = |p: &Path, m: u32| {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(p, std::fs::Permissions::from_mode(m)).unwrap()
    };
    // Root reads everything, so the run drops to `nobody`, which needs to see the rest.
    if root {
        for p in [dir.to_path_buf(), dir.join("cases")] {
            mode(&p, 0o777);
        }
    }
    mode(&locked, 0o000);
    let texts = [
        common::cohort::CONFIG.to_string(),
        common::cohort::CONFIG.replace("case_depth = 1\n", ""),
    ];
    for text in texts {
        let _ = std::fs::remove_dir_all(dir.join("out"));
        std::fs::write(&c, &text).unwrap();
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_destair"));
        cmd.args(["run", c.to_str().unwrap()]);
        if root {
            use std::os::unix::process::CommandExt;
            // SAFETY: only async-signal-safe calls between fork and exec.
            unsafe {
                cmd.pre_exec(|| {
                    if libc::setgid(65534) != 0 || libc::setuid(65534) != 0 {
                        return Err(std::io::Error::last_os_error());
                    }
                    Ok(())
                });
            }
        }
        let run = cmd.output().unwrap();
        assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
        let summary: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("out/summary.json")).unwrap()).unwrap();
        assert_eq!(
            summary["failed"],
            serde_json::json!(["case-001"]),
            "{summary}"
        );
        let report = std::fs::read_to_string(dir.join("out/case-001/report.json")).unwrap();
        assert!(report.contains("Permission denied"), "{report}");
    }
    mode(&locked, 0o755);
}

#[test]
fn list_escapes_tabs_newlines_and_commas() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    cohort(dir, 1, false);
    let odd = dir.join("cases/odd\tname\nx");
    std::fs::create_dir_all(&odd).unwrap();
    std::fs::copy(dir.join("cases/case-000/tumor.ply"), odd.join("a,b.ply")).unwrap();
    let c = dir.join("cohort.toml");
    let list = destair(&["list", c.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&list.stdout);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 2, "{text}");
    for l in &lines {
        assert_eq!(l.split('\t').count(), 3, "{l}");
    }
    assert!(
        lines[1].starts_with("odd\\tname\\nx\t") && lines[1].ends_with("\ta\\,b"),
        "{text}"
    );
}

/// One soak round's config: the standard one with the roots spelled as given.
fn soak_config(dir: &Path, input: &str, output: &str) -> PathBuf {
    let text = common::cohort::CONFIG
        .replace("roots = [\"cases\"]", &format!("roots = [{input:?}]"))
        .replace("root = \"out\"", &format!("root = {output:?}"));
    write_config(dir, "soak.toml", &text)
}

/// Waits for a child at most `limit`; kills it if it is still running then.
fn wait_at_most(child: &mut Child, limit: Duration) -> Option<i32> {
    let started = Instant::now();
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s.code();
        }
        if started.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("a run did not end within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Many runs of a small cohort with random path spellings, random SIGTERM and kill -9
/// moments, concurrent runs and run-case jobs, and (where a tmpfs can be mounted) a disk that
/// fills up. Afterwards every input is byte-identical, and a clean rerun gives exactly the
/// files of an uninterrupted run. DESTAIR_SOAK_ROUNDS and DESTAIR_SOAK_SEED make it longer.
#[test]
fn randomized_soak_keeps_inputs_and_ends_with_clean_run_bytes() {
    let rounds: usize = std::env::var("DESTAIR_SOAK_ROUNDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10);
    let seed: u64 = std::env::var("DESTAIR_SOAK_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(9);
    let mut rng = fastrand::Rng::with_seed(seed);
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let c = cohort(dir, 4, false);
    destair_ok(&["run", c.to_str().unwrap()]);
    let clean = snapshot(&dir.join("out"));
    std::fs::remove_dir_all(dir.join("out")).unwrap();
    let inputs = hashes(&dir.join("cases"));
    std::os::unix::fs::symlink(dir.join("cases"), dir.join("link-cases")).unwrap();
    std::fs::create_dir_all(dir.join("out")).unwrap();
    std::os::unix::fs::symlink(dir.join("out"), dir.join("link-out")).unwrap();
    let input_spellings = [
        "cases",
        "./cases/",
        "link-cases",
        "cases/../cases",
        "link-cases/.",
    ];
    let output_spellings = [
        "out",
        "./out",
        "out/",
        "cases/../out",
        "link-out",
        "link-out/",
    ];
    let full = dir.join("full");
    let can_mount = mount_tmpfs(&full, "400k");
    let (mut refused, mut killed, mut terminated, mut raced, mut disk_full) = (0, 0, 0, 0, 0);
    for round in 0..rounds {
        let input = input_spellings[rng.usize(..input_spellings.len())];
        // Now and then an output root that is the input root in disguise: always refused.
        let disguised = rng.usize(..6) == 0;
        let output = if disguised {
            input_spellings[rng.usize(..input_spellings.len())]
        } else {
            output_spellings[rng.usize(..output_spellings.len())]
        };
        let config = soak_config(dir, input, output);
        let cfg = config.to_str().unwrap();
        let force = rng.bool();
        let mut args = vec!["run", cfg];
        if force {
            args.push("--force");
        }
        let what = rng.usize(..5);
        let context = format!(
            "round {round}: roots {input:?}, output {output:?}, action {what}, force {force}"
        );
        if disguised {
            let run = destair(&args);
            assert_eq!(run.status.code(), Some(2), "{context}: {}", stderr(&run));
            refused += 1;
        } else {
            match what {
                // kill -9 at a random moment.
                0 => {
                    let mut child = spawn(&args);
                    std::thread::sleep(Duration::from_millis(rng.u64(0..600)));
                    let _ = child.kill();
                    let _ = child.wait();
                    killed += 1;
                }
                // SIGTERM at a random moment: 0 or 143, within a second.
                1 => {
                    let mut child = spawn(&args);
                    std::thread::sleep(Duration::from_millis(rng.u64(0..600)));
                    signal(&child, libc::SIGTERM);
                    let code = wait_at_most(&mut child, Duration::from_secs(1));
                    assert!(matches!(code, Some(0) | Some(143)), "{context}: {code:?}");
                    terminated += 1;
                }
                // A second run at the same time: it runs after (0) or is refused (2).
                2 => {
                    let mut first = spawn(&args);
                    std::thread::sleep(Duration::from_millis(rng.u64(0..300)));
                    let second = destair(&["run", cfg]);
                    assert!(
                        matches!(second.status.code(), Some(0) | Some(2)),
                        "{context}: {}",
                        stderr(&second)
                    );
                    assert_eq!(
                        wait_at_most(&mut first, Duration::from_secs(60)),
                        Some(0),
                        "{context}"
                    );
                    raced += 1;
                }
                // run-case jobs for random cases beside a run, then killed.
                3 => {
                    let mut first = spawn(&args);
                    let case = format!("{input}/case-00{}", rng.usize(..4));
                    let out = dir.join(output);
                    let mut job = spawn(&[
                        "run-case",
                        dir.join(&case).to_str().unwrap(),
                        "--config",
                        cfg,
                        "--out",
                        out.to_str().unwrap(),
                    ]);
                    std::thread::sleep(Duration::from_millis(rng.u64(0..400)));
                    let _ = first.kill();
                    let _ = first.wait();
                    let code = wait_at_most(&mut job, Duration::from_secs(60));
                    // Refused while the run held the folder (2), or done (0), or killed.
                    assert!(matches!(code, Some(0) | Some(2)), "{context}: {code:?}");
                    raced += 1;
                }
                // A full disk: the output root on a tiny tmpfs.
                _ => {
                    if can_mount {
                        let config = soak_config(dir, input, "full");
                        let run = destair(&["run", config.to_str().unwrap()]);
                        let err = stderr(&run);
                        assert!(
                            matches!(run.status.code(), Some(3) | Some(2)),
                            "{context}: {err}"
                        );
                        assert!(err.contains("No space left on device"), "{context}: {err}");
                        disk_full += 1;
                    }
                }
            }
        }
        assert!(
            hashes(&dir.join("cases")) == inputs,
            "{context}: inputs changed"
        );
    }
    if can_mount {
        // Space freed: the same folder now ends with the clean bytes as well.
        let remount = Command::new("mount")
            .args(["-o", "remount,size=64m", full.to_str().unwrap()])
            .status()
            .unwrap();
        assert!(remount.success());
        destair_ok(&["run", soak_config(dir, "cases", "full").to_str().unwrap()]);
        let got = snapshot(&full);
        umount(&full);
        assert!(
            got == clean,
            "the once-full output folder differs from a clean run"
        );
    }
    destair_ok(&["run", c.to_str().unwrap()]);
    let got = snapshot(&dir.join("out"));
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        clean.keys().collect::<Vec<_>>()
    );
    assert!(got == clean, "final outputs differ from a clean run");
    assert!(hashes(&dir.join("cases")) == inputs);
    eprintln!(
        "soak: {rounds} rounds (seed {seed}): {refused} refused spellings, {killed} kill -9, {terminated} SIGTERM, {raced} concurrent, {disk_full} full disk{}",
        if can_mount { "" } else { " (no tmpfs here)" }
    );
}

/// A case a shard has taken up stays locked until its outputs are written: `run-case` for it
/// meanwhile is told the case is busy (exit 2) instead of computing it alongside.
#[test]
fn run_case_does_not_compute_a_case_a_shard_is_computing() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let c = slow_cohort(dir, 100_000, 100_000);
    let c = c.to_str().unwrap();
    let mut shard = spawn(&["run", c, "--shard", "0/1"]);
    {
        // Its shard line, then the first line of every run, once it holds its folder.
        use std::io::BufRead;
        let mut lines = std::io::BufReader::new(shard.stderr.take().unwrap()).lines();
        assert!(lines.any(|l| l.unwrap().contains("destair:")));
        std::thread::spawn(move || lines.for_each(drop));
    }
    // Until the shard's loader holds the case (it reads the case first).
    let out = dir.join("out");
    let probe = destair::job::OutputLock::open(&out).unwrap();
    let scope = destair::job::LockScope::Case("big".into());
    let started = Instant::now();
    while probe
        .lock(
            &scope,
            destair::job::LockMode::Exclusive,
            destair::job::Wait::No,
        )
        .is_ok()
    {
        probe.unlock(&scope);
        assert!(
            started.elapsed() < Duration::from_secs(30),
            "never taken up"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let mut case = spawn(&[
        "run-case",
        dir.join("cases/big").to_str().unwrap(),
        "--config",
        c,
        "--out",
        out.to_str().unwrap(),
    ]);
    let started = Instant::now();
    let status = loop {
        if let Some(s) = case.try_wait().unwrap() {
            break Some(s);
        }
        if started.elapsed() > Duration::from_secs(10) {
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let Some(status) = status else {
        signal(&case, libc::SIGKILL);
        signal(&shard, libc::SIGKILL);
        panic!("run-case computed the case alongside the shard");
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut case.stderr.take().unwrap(), &mut err).unwrap();
    assert_eq!(status.code(), Some(2), "{err}");
    // Busy on the case itself (the folder is shared by shards and run-case jobs).
    assert!(
        err.contains("the outputs of case \"big\" is in use by another destair run"),
        "{err}"
    );
    signal(&shard, libc::SIGTERM);
    assert_eq!(shard.wait().unwrap().code(), Some(143));
}

/// An output root that is a case folder, lies inside one, or is one under another name (a
/// symlink; a bind mount where one can be made) is refused before anything is written: its
/// outputs would land among that case's inputs and its marker would hide the case for good.
#[test]
fn output_roots_in_case_folders_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    cohort(dir, 2, false);
    std::os::unix::fs::symlink(dir.join("cases/case-000"), dir.join("caselink")).unwrap();
    let before = hashes(&dir.join("cases"));
    for out in [
        "cases/case-000",
        "cases/case-000/results",
        "caselink",
        "caselink/results",
    ] {
        let c = write_config(dir, "c.toml", &config_with(out, ""));
        let run = destair(&["run", c.to_str().unwrap()]);
        let err = stderr(&run);
        assert_eq!(run.status.code(), Some(2), "{out}: {err}");
        assert!(
            err.contains("case folder") || err.contains("holds input files"),
            "{out}: {err}"
        );
    }
    let c = write_config(dir, "c.toml", common::cohort::CONFIG);
    for out in [
        "cases/case-001",
        "cases/case-001/results",
        "caselink",
        "cases/case-000/x",
    ] {
        let run = destair(&[
            "run-case",
            dir.join("cases/case-000").to_str().unwrap(),
            "--config",
            c.to_str().unwrap(),
            "--out",
            dir.join(out).to_str().unwrap(),
        ]);
        let err = stderr(&run);
        assert_eq!(run.status.code(), Some(2), "{out}: {err}");
    }
    // A folder of meshes of no root is somebody's inputs too.
    std::fs::create_dir_all(dir.join("elsewhere")).unwrap();
    std::fs::copy(
        dir.join("cases/case-001/tumor.ply"),
        dir.join("elsewhere/tumor.ply"),
    )
    .unwrap();
    let run = destair(&[
        "run-case",
        dir.join("cases/case-000").to_str().unwrap(),
        "--config",
        c.to_str().unwrap(),
        "--out",
        dir.join("elsewhere").to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    assert!(!dir.join("elsewhere/.destair-output").exists());
    assert_eq!(hashes(&dir.join("cases")), before, "inputs changed");
    // The input root bind-mounted as the output root: the same folder by identity.
    let bind = dir.join("bind");
    std::fs::create_dir_all(&bind).unwrap();
    let mounted = Command::new("mount")
        .args([
            "--bind",
            dir.join("cases").to_str().unwrap(),
            bind.to_str().unwrap(),
        ])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        eprintln!("skipped the bind-mount part: cannot mount here");
        return;
    }
    let c = write_config(dir, "c.toml", &config_with("bind", ""));
    let run = destair(&["run", c.to_str().unwrap()]);
    umount(&bind);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    assert!(stderr(&run).contains("input root"), "{}", stderr(&run));
    assert!(!dir.join("cases/.destair-output").exists());
    assert_eq!(hashes(&dir.join("cases")), before, "inputs changed");
}

/// Thread counts are checked whatever their source: RAYON_NUM_THREADS=20000 is refused at
/// once (rayon would start them, taking minutes, and abort), 0 keeps rayon's meaning (every
/// core).
#[test]
fn thread_counts_from_the_environment_are_checked() {
    let tmp = tempfile::tempdir().unwrap();
    let mesh = tmp.path().join("t.ply");
    destair_ok(&["phantom", "neck", "--out", tmp.path().to_str().unwrap()]);
    std::fs::copy(tmp.path().join("tumor.ply"), &mesh).unwrap();
    for (value, ok) in [("20000", false), ("lots", false), ("0", true), ("2", true)] {
        let started = Instant::now();
        let run = Command::new(env!("CARGO_BIN_EXE_destair"))
            .args(["inspect", mesh.to_str().unwrap()])
            .env("RAYON_NUM_THREADS", value)
            .output()
            .unwrap();
        assert_eq!(run.status.success(), ok, "{value}: {}", stderr(&run));
        if !ok {
            assert_eq!(run.status.code(), Some(2));
            assert!(
                stderr(&run).contains("RAYON_NUM_THREADS"),
                "{}",
                stderr(&run)
            );
        }
        assert!(started.elapsed() < Duration::from_secs(5), "{value}");
    }
}

/// A root that is itself a case is named after its folder, its outputs in a folder of their
/// own (not a case called "." writing among the cohort's summary files).
#[test]
fn a_root_that_is_a_case_is_named_after_its_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    cohort(dir, 1, false);
    let c = write_config(
        dir,
        "one.toml",
        "[input]\nroots = [\"cases/case-000\"]\n[output]\nroot = \"out\"\n[defaults]\nmethod = \"laplace\"\n",
    );
    destair_ok(&["run", c.to_str().unwrap()]);
    assert!(dir.join("out/case-000/report.json").is_file());
    assert!(!dir.join("out/report.json").exists());
    let summary = std::fs::read_to_string(dir.join("out/summary.csv")).unwrap();
    assert!(
        summary.contains("case-000") && !summary.contains("\n.,"),
        "{summary}"
    );
}

/// An input cut short by another program while a run has it mapped: its case fails (or, cut
/// before it was opened, reads as the shorter file), and the run is never killed by SIGBUS
/// (1 trial in 12 was, before). Random moments over a 4 M-triangle mesh.
#[test]
fn an_input_truncated_while_mapped_never_kills_the_run() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    destair_ok(&[
        "phantom",
        "big",
        "1000000",
        "--out",
        dir.join("src").to_str().unwrap(),
    ]);
    let c = write_config(
        dir,
        "t.toml",
        "[input]\nroots = [\"cases\"]\ncase_depth = 1\n[output]\nroot = \"out\"\npictures = false\nhtml = false\n[defaults]\nmethod = \"laplace\"\niterations = 1\nstaircase = false\n",
    );
    let mut rng = fastrand::Rng::with_seed(12);
    let mut failed = 0;
    for trial in 0..8 {
        let _ = std::fs::remove_dir_all(dir.join("cases"));
        let _ = std::fs::remove_dir_all(dir.join("out"));
        std::fs::create_dir_all(dir.join("cases/c")).unwrap();
        let mesh = dir.join("cases/c/blob.ply");
        std::fs::copy(dir.join("src/blob.ply"), &mesh).unwrap();
        let mut run = Command::new(env!("CARGO_BIN_EXE_destair"))
            .args(["run", c.to_str().unwrap()])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(rng.u64(0..200)));
        std::fs::OpenOptions::new()
            .write(true)
            .open(&mesh)
            .unwrap()
            .set_len(4096)
            .unwrap();
        let status = run.wait().unwrap();
        use std::os::unix::process::ExitStatusExt;
        assert_eq!(status.signal(), None, "trial {trial}: killed by a signal");
        assert!(
            matches!(status.code(), Some(0) | Some(3)),
            "trial {trial}: {status:?}"
        );
        failed += (status.code() == Some(3)) as usize;
    }
    eprintln!(
        "8 truncations: {failed} cases failed with the reason, the rest read before or after"
    );
}
