//! Faults that a user's shell and file system produce, through several commands each: a
//! reader of stdout that goes away, a full stdout, inputs that are not regular files. Each
//! must end in a clear message or a quiet exit, never a panic or a hang, and never cost the
//! command's files.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// How long a refused command may take: it must refuse before any real work.
const REFUSAL_LIMIT: Duration = Duration::from_secs(120);

fn rtr() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_rtr"));
    command.current_dir(env!("CARGO_MANIFEST_DIR"));
    command
}

/// Waits for `child` at most `limit`; a child still running then is killed and the test fails
/// (a hang). Returns its exit status and standard error.
fn finish(mut child: Child, limit: Duration, what: &str) -> (std::process::ExitStatus, String) {
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            let mut stderr = String::new();
            if let Some(mut e) = child.stderr.take() {
                use std::io::Read;
                let _ = e.read_to_string(&mut stderr);
            }
            return (status, stderr);
        }
        if started.elapsed() > limit {
            let _ = child.kill();
            panic!("`rtr {what}` still ran after {limit:?}: it hangs");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Runs `rtr args` with its stdout a pipe whose reader has already gone.
fn with_closed_stdout(args: &[&str]) -> (std::process::ExitStatus, String) {
    let mut child = rtr()
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the rtr binary runs");
    drop(child.stdout.take());
    finish(child, Duration::from_secs(900), &args.join(" "))
}

fn assert_no_panic(stderr: &str, what: &str) {
    assert!(
        !stderr.contains("panicked"),
        "`rtr {what}` panicked:\n{stderr}"
    );
}

#[test]
fn a_reader_that_goes_away_ends_each_command_quietly() {
    let xodr = "data/automatum-a9/staticWorld.xodr";
    for args in [
        vec!["data", "summary"],
        vec!["map", "summary", "--xodr", xodr],
        vec!["scenarios", "list"],
        vec!["model", "info"],
    ] {
        let what = args.join(" ");
        let (status, stderr) = with_closed_stdout(&args);
        assert_no_panic(&stderr, &what);
        assert!(status.success(), "`rtr {what}`: {status}\n{stderr}");
    }
}

#[test]
fn a_reader_that_goes_away_does_not_cost_the_files() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("eval");
    let (status, stderr) = with_closed_stdout(&[
        "eval",
        "--checkpoint",
        "models/il_main",
        "--set",
        "nominal",
        "--scenes",
        "1",
        "--out",
        out.to_str().expect("UTF-8 path"),
    ]);
    assert_no_panic(&stderr, "eval");
    assert!(status.success(), "{status}\n{stderr}");
    let results: serde_json::Value = serde_json::from_slice(
        &std::fs::read(out.join("results.json")).expect("results.json was written"),
    )
    .expect("whole JSON");
    assert!(results.to_string().contains("nominal"), "{results}");
    assert!(out.join("table.md").is_file());
}

#[test]
fn a_full_stdout_is_an_error_that_names_it() {
    if !Path::new("/dev/full").exists() {
        return;
    }
    for args in [vec!["data", "summary"], vec!["scenarios", "list"]] {
        let what = args.join(" ");
        let child = rtr()
            .args(&args)
            .stdout(std::fs::File::create("/dev/full").expect("/dev/full"))
            .stderr(Stdio::piped())
            .spawn()
            .expect("the rtr binary runs");
        let (status, stderr) = finish(child, REFUSAL_LIMIT, &what);
        assert_no_panic(&stderr, &what);
        assert_eq!(status.code(), Some(1), "`rtr {what}`:\n{stderr}");
        assert!(
            stderr.contains("standard output"),
            "`rtr {what}`:\n{stderr}"
        );
    }
}

/// A named pipe at `path` (nothing ever writes to it: an open for reading would block).
fn fifo(path: &Path) -> PathBuf {
    let c_path = std::ffi::CString::new(path.to_str().expect("UTF-8 path")).expect("path");
    // SAFETY: a valid NUL-terminated path; mkfifo only creates a file.
    assert_eq!(unsafe { libc::mkfifo(c_path.as_ptr(), 0o600) }, 0, "mkfifo");
    path.to_path_buf()
}

/// Runs `rtr args`, which must fail within [`REFUSAL_LIMIT`] with a message containing each
/// of `expected`.
fn assert_refused(args: &[&str], expected: &[&str]) {
    let what = args.join(" ");
    let child = rtr()
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the rtr binary runs");
    let (status, stderr) = finish(child, REFUSAL_LIMIT, &what);
    assert_no_panic(&stderr, &what);
    assert!(!status.success(), "`rtr {what}` accepted it");
    for text in expected {
        assert!(
            stderr.contains(text),
            "`rtr {what}`: no `{text}` in\n{stderr}"
        );
    }
}

#[test]
fn inputs_that_are_not_regular_files_are_refused_without_blocking() {
    let dir = tempfile::tempdir().expect("temp dir");
    let pipe = fifo(&dir.path().join("input"));
    let pipe = pipe.to_str().expect("UTF-8 path");
    let out = dir.path().join("out");
    let out = out.to_str().expect("UTF-8 path");
    let report = dir.path().join("report.json");
    let report = report.to_str().expect("UTF-8 path");
    for (args, flag) in [
        (vec!["train", "--config", pipe, "--out", out], "--config"),
        (vec!["map", "summary", "--xodr", pipe], "--xodr"),
        (
            vec!["sim2real", "--recordings", pipe, "--report", report],
            "--recordings",
        ),
        (
            vec!["render", "--scenario", pipe, "--out", out],
            "--scenario",
        ),
        (
            vec!["curate", "--checkpoint", pipe, "--out", out],
            "--checkpoint",
        ),
    ] {
        assert_refused(&args, &[flag, "FIFO"]);
    }
    for (args, flag) in [
        (
            vec!["train", "--config", "/dev/zero", "--out", out],
            "--config",
        ),
        (
            vec![
                "sim2real",
                "--recordings",
                "/dev/urandom",
                "--report",
                report,
            ],
            "--recordings",
        ),
    ] {
        assert_refused(&args, &[flag, "device"]);
    }
}

#[test]
fn a_fifo_inside_an_input_folder_is_refused_without_blocking() {
    let dir = tempfile::tempdir().expect("temp dir");
    let eval = dir.path().join("scenarios/eval");
    std::fs::create_dir_all(&eval).expect("mkdir");
    fifo(&eval.join("scenario.json"));
    let scenarios = dir.path().join("scenarios");
    assert_refused(
        &[
            "eval",
            "--checkpoint",
            "models/il_main",
            "--set",
            "longtail",
            "--scenarios",
            scenarios.to_str().expect("UTF-8 path"),
        ],
        &["scenario.json", "FIFO"],
    );
    let families = dir.path().join("families");
    std::fs::create_dir_all(&families).expect("mkdir");
    fifo(&families.join("family.toml"));
    assert_refused(
        &[
            "scenarios",
            "generate",
            "--families",
            families.to_str().expect("UTF-8 path"),
            "--out",
            dir.path().join("sets").to_str().expect("UTF-8 path"),
        ],
        &["family.toml", "FIFO"],
    );
}
