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

#[test]
fn an_output_that_is_or_holds_or_lies_in_an_input_is_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let run_dir = dir.path().join("run");
    std::fs::create_dir_all(&run_dir).expect("mkdir");
    let run_file = run_dir.join("il.toml");
    std::fs::write(&run_file, "method = \"IL\"\n").expect("write");
    let scenarios = dir.path().join("scenarios");
    std::fs::create_dir_all(scenarios.join("eval")).expect("mkdir");
    let recordings = dir.path().join("tracks.csv");
    std::fs::write(
        &recordings,
        "track_id,t,x,y,heading,speed,accel_cmd,steer_cmd\n",
    )
    .expect("write");
    let xodr = "data/automatum-a9/staticWorld.xodr";
    let path = |p: &Path| p.to_str().expect("UTF-8 path").to_string();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![
                "train".into(),
                "--config".into(),
                path(&run_file),
                "--out".into(),
                path(&run_dir),
            ],
            "holds the input --config",
        ),
        (
            vec![
                "eval".into(),
                "--checkpoint".into(),
                "models/il_main".into(),
                "--set".into(),
                "longtail".into(),
                "--scenarios".into(),
                path(&scenarios),
                "--out".into(),
                path(&scenarios.join("eval/results")),
            ],
            "lies inside the input --scenarios",
        ),
        (
            vec![
                "sim2real".into(),
                "--recordings".into(),
                path(&recordings),
                "--report".into(),
                path(&recordings),
            ],
            "is the input --recordings",
        ),
        (
            vec![
                "map".into(),
                "export".into(),
                "--xodr".into(),
                xodr.into(),
                "--out".into(),
                xodr.into(),
            ],
            "is the input --xodr",
        ),
    ];
    for (args, expected) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_refused(&args, &[expected]);
    }
    assert_eq!(
        std::fs::read_to_string(&run_file).expect("the run file"),
        "method = \"IL\"\n"
    );
}

#[test]
fn a_folder_of_the_users_is_never_written_over() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("mine");
    std::fs::create_dir_all(&out).expect("mkdir");
    std::fs::write(out.join("table.md"), "my notes").expect("write");
    let out_str = out.to_str().expect("UTF-8 path");
    assert_refused(
        &[
            "train",
            "--config",
            "experiments/main/il.toml",
            "--out",
            out_str,
        ],
        &["not a run's", "table.md"],
    );
    assert_refused(
        &[
            "eval",
            "--checkpoint",
            "models/il_main",
            "--set",
            "nominal",
            "--scenes",
            "1",
            "--out",
            out_str,
        ],
        &["did not write", "table.md"],
    );
    assert_eq!(
        std::fs::read_to_string(out.join("table.md")).expect("kept"),
        "my notes"
    );
}

#[test]
fn a_second_writer_of_a_folder_is_refused_naming_the_first() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("eval");
    let _first = rtr::io::claim_output_folder(&out, "--out", &rtr::io::Inputs::new())
        .expect("this process claims it");
    let out_str = out.to_str().expect("UTF-8 path");
    let pid = std::process::id().to_string();
    assert_refused(
        &[
            "eval",
            "--checkpoint",
            "models/il_main",
            "--set",
            "nominal",
            "--out",
            out_str,
        ],
        &["another rtr process", &pid],
    );
    assert_refused(
        &[
            "train",
            "--config",
            "experiments/main/il.toml",
            "--out",
            out_str,
        ],
        &["another rtr process", &pid],
    );
}

#[test]
fn a_new_result_set_replaces_the_earlier_one_whole() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("eval");
    let out_str = out.to_str().expect("UTF-8 path");
    let eval = |extra: &[&str]| {
        let status = rtr()
            .args([
                "eval",
                "--checkpoint",
                "models/il_main",
                "--set",
                "nominal",
                "--scenes",
                "1",
            ])
            .args(extra)
            .args(["--out", out_str])
            .stdout(Stdio::null())
            .status()
            .expect("rtr runs");
        assert!(status.success(), "eval {extra:?}");
    };
    let files = || {
        let mut names: Vec<String> = walk(&out)
            .iter()
            .map(|f| {
                f.strip_prefix(&out)
                    .expect("under out")
                    .display()
                    .to_string()
            })
            .collect();
        names.sort();
        names
    };
    eval(&[
        "--commonroad",
        "data/commonroad-us101/USA_US101-3_1_T-1.xml.gz",
    ]);
    let first = files();
    let clip = |f: &&String| f.contains("commonroad") || f.contains("us101");
    assert!(first.iter().filter(clip).count() >= 2, "{first:?}");
    eval(&[]);
    let second = files();
    let stale: Vec<_> = second.iter().filter(clip).collect();
    assert!(
        stale.is_empty(),
        "files of the earlier result set left: {stale:?}"
    );
    let results = std::fs::read_to_string(out.join("results.json")).expect("results");
    assert!(!results.contains("commonroad"), "{results}");
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).expect("list") {
        let path = entry.expect("entry").path();
        if path.is_dir() {
            out.extend(walk(&path));
        } else {
            out.push(path);
        }
    }
    out
}

/// Copies the folder `from` to `to` (a scenario set under test).
fn copy_folder(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("mkdir");
    for entry in std::fs::read_dir(from).expect("list") {
        let path = entry.expect("entry").path();
        let target = to.join(path.file_name().expect("name"));
        if path.is_dir() {
            copy_folder(&path, &target);
        } else {
            std::fs::copy(&path, &target).expect("copy");
        }
    }
}

#[test]
fn a_scenario_folder_is_checked_as_a_set() {
    let dir = tempfile::tempdir().expect("temp dir");
    let good = dir.path().join("good");
    let status = rtr()
        .args([
            "scenarios",
            "generate",
            "--in-distribution",
            "12",
            "--ood",
            "0",
            "--out",
        ])
        .arg(&good)
        .stdout(Stdio::null())
        .status()
        .expect("rtr runs");
    assert!(status.success());
    let first = |set: &str| {
        let mut files: Vec<PathBuf> = std::fs::read_dir(good.join(set))
            .expect("list")
            .map(|e| e.expect("entry").path())
            .collect();
        files.sort();
        files[0].clone()
    };
    let relabelled = |path: &Path, set: &str| {
        let mut v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(path).expect("read")).expect("JSON");
        v["set"] = serde_json::Value::String(set.into());
        v["index"] = serde_json::json!(99);
        serde_json::to_vec_pretty(&v).expect("JSON")
    };
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            ".rtr-tmp-tmp-1-0.json",
            std::fs::read(first("eval")).expect("read"),
            "is hidden",
        ),
        (
            "zz-copy.json",
            std::fs::read(first("eval")).expect("read"),
            "same scenario as",
        ),
        (
            "zz-train.json",
            std::fs::read(first("train")).expect("read"),
            "is `train`",
        ),
        (
            "zz-relabelled.json",
            relabelled(&first("train"), "eval"),
            "of the train set",
        ),
    ];
    for (k, (name, bytes, expected)) in cases.into_iter().enumerate() {
        let root = dir.path().join(format!("case{k}"));
        copy_folder(&good, &root);
        std::fs::write(root.join("eval").join(name), bytes).expect("write");
        let root = root.to_str().expect("UTF-8 path");
        assert_refused(
            &[
                "eval",
                "--checkpoint",
                "models/il_main",
                "--set",
                "longtail",
                "--scenes",
                "1",
                "--scenarios",
                root,
            ],
            &[name, expected],
        );
    }
}

#[test]
fn a_scenario_folder_a_run_would_ignore_is_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let sets = dir.path().to_str().expect("UTF-8 path");
    let out = dir.path().join("run");
    assert_refused(
        &[
            "train",
            "--config",
            "experiments/main/il.toml",
            "--scenarios",
            sets,
            "--out",
            out.to_str().expect("UTF-8 path"),
        ],
        &["--scenarios", "trains on no long-tail scenarios"],
    );
}
