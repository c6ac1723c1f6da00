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

/// Every command's files are written before a full stdout ends it: a picture drawn to two
/// formats keeps both.
#[test]
fn a_full_stdout_does_not_cut_the_files_short() {
    if !Path::new("/dev/full").exists() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let prefix = dir.path().join("curve");
    let prefix_arg = prefix.to_str().expect("UTF-8");
    for args in [
        vec![
            "map",
            "render",
            "--procedural",
            "curve",
            "--out",
            prefix_arg,
        ],
        vec![
            "recordings",
            "generate",
            "--effect",
            "none",
            "--tracks",
            "3",
            "--out",
        ],
    ] {
        let mut args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
        if args[0] == "recordings" {
            args.push(dir.path().join("rec.csv").display().to_string());
        }
        let what = args.join(" ");
        let child = rtr()
            .args(&args)
            .stdout(std::fs::File::create("/dev/full").expect("/dev/full"))
            .stderr(Stdio::piped())
            .spawn()
            .expect("the rtr binary runs");
        let (status, stderr) = finish(child, Duration::from_secs(300), &what);
        assert_no_panic(&stderr, &what);
        assert_eq!(status.code(), Some(1), "`rtr {what}`:\n{stderr}");
        assert!(stderr.contains("standard output"), "{stderr}");
    }
    for file in ["curve.png", "curve.svg", "rec.csv"] {
        let size = std::fs::metadata(dir.path().join(file)).map_or(0, |m| m.len());
        assert!(size > 0, "{file} was not written whole");
    }
}

/// An output path that is a device, a FIFO or a socket is refused by what it is, never replaced
/// by a file (`--out /dev/null` must not take /dev/null from the system); one that is a link
/// to a file writes the file and leaves the link a link.
#[test]
fn an_output_that_is_not_a_file_is_refused_and_a_link_is_written_through() {
    let dir = tempfile::tempdir().expect("temp dir");
    let pipe = fifo(&dir.path().join("pipe.xodr"));
    let pipe = pipe.to_str().expect("UTF-8");
    assert_refused(
        &["map", "export", "--procedural", "straight", "--out", pipe],
        &["--out", "FIFO", "expected a regular file path"],
    );
    assert_refused(
        &["recordings", "generate", "--effect", "none", "--out", pipe],
        &["--out", "FIFO"],
    );
    // A folder output is named for what it is, and so is a non-folder on its way.
    assert_refused(
        &["scenarios", "generate", "--out", pipe],
        &["--out", "is a FIFO", "expected a folder"],
    );
    let under = format!("{pipe}/sub");
    assert_refused(
        &["scenarios", "generate", "--out", &under],
        &["--out", "is a FIFO", "nothing can be written under it"],
    );
    if Path::new("/dev/null").exists() {
        assert_refused(
            &[
                "map",
                "export",
                "--procedural",
                "straight",
                "--out",
                "/dev/null",
            ],
            &["--out /dev/null", "is a device"],
        );
        let meta = std::fs::metadata("/dev/null").expect("/dev/null");
        assert!(!meta.is_file(), "/dev/null was replaced by a file");
    }
    // A link to nothing on the way is named as that, whichever command writes there.
    let dangling = dir.path().join("gone");
    std::os::unix::fs::symlink(dir.path().join("nowhere"), &dangling).expect("symlink");
    let below = |name: &str| dangling.join(name).to_str().expect("UTF-8").to_string();
    for args in [
        vec!["scenarios", "generate", "--out", &below("sets")],
        vec![
            "map",
            "export",
            "--procedural",
            "straight",
            "--out",
            &below("a.xodr"),
        ],
        average_into(&below("mean")),
    ] {
        assert_refused(
            &args,
            &[
                "--out",
                "link to nothing",
                "nothing can be written under it",
            ],
        );
    }
    // The link itself as the output, spelt with a trailing slash (which follows the link).
    let as_folder = format!("{}/", dangling.to_str().expect("UTF-8"));
    for args in [
        vec!["scenarios", "generate", "--out", &as_folder],
        average_into(&as_folder),
    ] {
        assert_refused(&args, &["--out", "link to nothing"]);
    }
    let target = dir.path().join("real.xodr");
    std::fs::write(&target, "<OpenDRIVE><header/></OpenDRIVE>").expect("write");
    let link = dir.path().join("link.xodr");
    std::os::unix::fs::symlink(&target, &link).expect("symlink");
    let status = rtr()
        .args(["map", "export", "--procedural", "straight", "--out"])
        .arg(&link)
        .stdout(Stdio::null())
        .status()
        .expect("runs");
    assert!(status.success());
    assert!(
        std::fs::symlink_metadata(&link)
            .expect("link")
            .file_type()
            .is_symlink(),
        "the link is still a link"
    );
    let written = std::fs::read_to_string(&target).expect("target");
    assert!(written.contains("<road"), "the target was written");
}

/// A study folder is checked before the work: a file of the user's where results go, or the
/// results of another command, refuse the command at its start.
#[test]
fn a_result_folder_is_checked_before_the_work() {
    let dir = tempfile::tempdir().expect("temp dir");
    let users = dir.path().join("users");
    std::fs::create_dir(&users).expect("mkdir");
    std::fs::write(users.join("table.md"), "my notes").expect("write");
    let users = users.to_str().expect("UTF-8");
    assert_refused(
        &["eval", "--idm", "--out", users],
        &["table.md", "rtr did not write", "Choose a new folder"],
    );
    assert_refused(
        &[
            "sweep",
            "--config",
            "experiments/main/rtr.toml",
            "--points",
            "1:0.5",
            "--out",
            users,
        ],
        &["table.md", "rtr did not write"],
    );
    assert_eq!(
        std::fs::read_to_string(dir.path().join("users/table.md")).expect("read"),
        "my notes"
    );
    // The results of `rtr eval` are not replaced by another study's.
    let evaluated = dir.path().join("evaluated");
    std::fs::create_dir(&evaluated).expect("mkdir");
    std::fs::write(evaluated.join("results.json"), "{}").expect("write");
    std::fs::write(evaluated.join(".rtr-output"), "# rtr eval\nresults.json\n").expect("write");
    let evaluated = evaluated.to_str().expect("UTF-8");
    assert_refused(
        &["scenarios", "generate", "--out", evaluated],
        &[
            "holds the results of `rtr eval`",
            "`rtr scenarios generate` would replace them",
        ],
    );
    assert_refused(
        &["downstream", "--idm", "--out", evaluated],
        &[
            "holds the results of `rtr eval`",
            "`rtr downstream` would replace them",
        ],
    );
}

/// What is named twice is refused, not done twice: a sweep point, a probe task, a
/// checkpoint to evaluate or to average, a scene set, a CommonRoad clip.
#[test]
fn an_input_named_twice_is_refused() {
    assert_refused(
        &[
            "sweep",
            "--config",
            "experiments/main/rtr.toml",
            "--points",
            "1:0.5,1.0:0.50",
            "--out",
            "unused",
        ],
        &["sweep point 1:0.5 is given twice"],
    );
    assert_refused(
        &["probe", "ppo", "--tasks", "brake,brake"],
        &["`brake` is given twice"],
    );
    assert_refused(
        &[
            "eval",
            "--checkpoint",
            "models/il_main",
            "--checkpoint",
            "models/il_main/",
            "--scenes",
            "1",
        ],
        &["names the same policy", "pass each once"],
    );
    assert_refused(
        &[
            "eval",
            "--checkpoint",
            "models/il_main",
            "--set",
            "nominal,longtail,nominal",
            "--scenes",
            "1",
        ],
        &["--set names `nominal` twice"],
    );
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("avg");
    assert_refused(
        &[
            "model",
            "average",
            "--checkpoint",
            "models/il_main",
            "--checkpoint",
            "models/il_main/policy.bpk",
            "--out",
            out.to_str().expect("UTF-8"),
        ],
        &["holds the same weights as"],
    );
    let clip = "data/commonroad-us101/USA_US101-5_1_T-1.xml.gz";
    assert_refused(
        &[
            "data",
            "summary",
            "--commonroad",
            clip,
            "--commonroad",
            "data/commonroad-us101",
        ],
        &["USA_US101-5_1_T-1.xml.gz", "is given twice"],
    );
}

/// A path that is not UTF-8 (legal on Unix) is written, not a panic.
#[test]
fn a_path_that_is_not_utf8_is_no_panic() {
    use std::os::unix::ffi::OsStrExt;
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join(std::ffi::OsStr::from_bytes(b"x\xff.svg"));
    let child = rtr()
        .args(["map", "render", "--procedural", "straight", "--out"])
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the rtr binary runs");
    let (status, stderr) = finish(child, REFUSAL_LIMIT, "map render --out x\\xff.svg");
    assert_no_panic(&stderr, "map render");
    assert!(status.success(), "{stderr}");
    assert!(out.is_file());
}

/// A folder flag given a file is named with the folder it expects.
#[test]
fn a_folder_flag_given_a_file_names_the_flag() {
    let file = "experiments/main/rtr.toml";
    assert_refused(
        &["scenarios", "list", "--families", file],
        &["--families", "is a file", "expected a folder"],
    );
    assert_refused(
        &["data", "summary", "--data", file],
        &["--data", "is a file", "AUTOMATUM"],
    );
    assert_refused(
        &["eval", "--idm", "--set", "longtail", "--scenarios", file],
        &["--scenarios", "is a file", "rtr scenarios generate"],
    );
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
    let results = dir.path().join("results");
    let results = results.to_str().expect("UTF-8 path");
    for (args, flag) in [
        (vec!["train", "--config", pipe, "--out", out], "--config"),
        (vec!["map", "summary", "--xodr", pipe], "--xodr"),
        (
            vec!["sim2real", "--recordings", pipe, "--out", results],
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
            vec!["sim2real", "--recordings", "/dev/urandom", "--out", results],
            "--recordings",
        ),
    ] {
        assert_refused(&args, &[flag, "device"]);
    }
    // A folder where a file is expected, a link that loops, and a FIFO named in a run file:
    // each named by its flag or field, and called what it is.
    let folder = dir.path().join("folder");
    std::fs::create_dir_all(&folder).expect("mkdir");
    let loop_link = dir.path().join("loop.xodr");
    std::os::unix::fs::symlink(&loop_link, &loop_link).expect("symlink");
    let run_file = dir.path().join("curated.toml");
    std::fs::write(
        &run_file,
        format!("method = \"IL\"\n[data]\ncurated = {pipe:?}\n"),
    )
    .expect("write");
    let config = "experiments/main/il.toml";
    let folder = folder.to_str().expect("UTF-8 path");
    let loop_link = loop_link.to_str().expect("UTF-8 path");
    let run_file = run_file.to_str().expect("UTF-8 path");
    for (args, expected) in [
        (
            vec![
                "train",
                "--config",
                config,
                "--dynamics",
                folder,
                "--out",
                out,
            ],
            ["--dynamics", "is a folder"],
        ),
        (
            vec!["map", "summary", "--xodr", loop_link],
            ["--xodr", "symlink loop"],
        ),
        (
            vec!["train", "--config", run_file, "--out", out],
            ["data.curated", "FIFO"],
        ),
    ] {
        assert_refused(&args, &expected);
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
                "--out".into(),
                path(&recordings),
            ],
            "is the input --recordings",
        ),
        (
            vec![
                "sim2real".into(),
                "--recordings".into(),
                path(&recordings),
                "--out".into(),
                path(recordings.parent().expect("folder")),
            ],
            "holds the input --recordings",
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
        // The same place spelt through a folder that does not exist and `..`.
        (
            vec![
                "sim2real".into(),
                "--recordings".into(),
                path(&recordings),
                "--out".into(),
                path(&dir.path().join("absent").join("..").join("tracks.csv")),
            ],
            "is the input --recordings",
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
                path(&scenarios.join("absent/../eval/results")),
            ],
            "lies inside the input --scenarios",
        ),
    ];
    for (args, expected) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_refused(&args, &[expected]);
    }
    assert!(
        !dir.path().join("absent").exists() && !scenarios.join("absent").exists(),
        "a refused output leaves no folder behind"
    );
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
        &["holds files but no run", "table.md"],
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
    // A working folder whose files no result set would replace is not taken over either:
    // once rtr's, every other output inside it would be refused.
    let work = dir.path().join("work");
    std::fs::create_dir_all(&work).expect("mkdir");
    std::fs::write(work.join("todo.md"), "my list").expect("write");
    let work_str = work.to_str().expect("UTF-8 path");
    for args in [
        vec!["eval", "--idm", "--scenes", "1", "--out", work_str],
        vec![
            "scenarios",
            "generate",
            "--in-distribution",
            "8",
            "--ood",
            "2",
            "--out",
            work_str,
        ],
        average_into(work_str),
    ] {
        assert_refused(
            &args,
            &["holds files rtr did not write (todo.md)", "new folder"],
        );
    }
    assert!(!work.join(".rtr-output").exists(), "not taken over");
    // A folder where a run writes a file is not a run's either, nor a run's file names
    // without a run.
    let odd = dir.path().join("odd");
    std::fs::create_dir_all(odd.join("config.toml")).expect("mkdir");
    let odd_str = odd.to_str().expect("UTF-8 path");
    assert_refused(
        &[
            "train",
            "--config",
            "experiments/main/il.toml",
            "--out",
            odd_str,
        ],
        &["holds files but no run", "config.toml/"],
    );
    let notes = dir.path().join("notes");
    std::fs::create_dir_all(&notes).expect("mkdir");
    std::fs::write(notes.join("curves.csv"), "mine").expect("write");
    assert_refused(
        &[
            "train",
            "--config",
            "experiments/main/il.toml",
            "--out",
            notes.to_str().expect("UTF-8 path"),
        ],
        &["holds files but no run", "curves.csv"],
    );
    assert_eq!(
        std::fs::read_to_string(notes.join("curves.csv")).expect("kept"),
        "mine"
    );
    // What a run stopped before its first checkpoint leaves (its config) is not the user's:
    // the run goes on to its next check (here its warm start, which is not there).
    let left = dir.path().join("left");
    std::fs::create_dir_all(&left).expect("mkdir");
    let run_file = std::fs::read_to_string("experiments/main/il.toml").expect("run file");
    std::fs::write(left.join("config.toml"), run_file).expect("write");
    assert_refused(
        &[
            "train",
            "--config",
            "experiments/main/il.toml",
            "--out",
            left.to_str().expect("UTF-8 path"),
        ],
        &["field `init.policy`"],
    );
}

/// An output file that exists is replaced only by a file of its kind, by content as well as
/// by name: a user's notes, table or sketch that happens to carry the extension stays.
#[test]
fn a_file_of_the_users_is_never_written_over() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mine = |name: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, "my own words\n").expect("write");
        path.to_str().expect("UTF-8 path").to_string()
    };
    let cases: [(Vec<&str>, String, &str); 5] = [
        (
            vec!["curate", "--checkpoint", "models/il_main", "--out"],
            mine("notes.txt"),
            "is not a scene list",
        ),
        (
            vec![
                "recordings",
                "generate",
                "--effect",
                "none",
                "--tracks",
                "3",
                "--out",
            ],
            mine("table.csv"),
            "is not a recordings CSV",
        ),
        (
            vec!["map", "export", "--procedural", "curve", "--out"],
            mine("sketch.xodr"),
            "is not an OpenDRIVE map",
        ),
        (
            vec!["map", "render", "--procedural", "curve", "--out"],
            mine("logo.svg"),
            "is not a PNG or SVG picture",
        ),
        (
            vec!["render", "--animate", "--out"],
            mine("clip.gif"),
            "is not a GIF animation",
        ),
    ];
    for (args, out, expected) in &cases {
        let mut args = args.clone();
        args.push(out);
        assert_refused(&args, &[expected, out]);
        assert_eq!(
            std::fs::read_to_string(out).expect("kept"),
            "my own words\n"
        );
    }
    // A file the command wrote itself is replaced.
    let own = dir.path().join("own.xodr");
    let own_str = own.to_str().expect("UTF-8 path");
    for preset in ["curve", "lane_drop"] {
        let status = rtr()
            .args(["map", "export", "--procedural", preset, "--out", own_str])
            .stdout(Stdio::null())
            .status()
            .expect("runs");
        assert!(status.success(), "map export {preset}");
    }
}

/// `rtr model average` of two shipped models into `out`.
fn average_into(out: &str) -> Vec<&str> {
    let models = ["--checkpoint", "models/il", "--checkpoint", "models/rtr"];
    [&["model", "average"][..], &models, &["--out", out]].concat()
}

/// A training run's folder belongs to its trainer, which replaces and prunes what is there:
/// an average written into it, or into its checkpoints, is refused.
#[test]
fn nothing_else_writes_into_a_training_run() {
    let dir = tempfile::tempdir().expect("temp dir");
    let run = dir.path().join("run");
    let checkpoint = run.join("checkpoints").join("iter-000001");
    std::fs::create_dir_all(&checkpoint).expect("mkdir");
    std::fs::write(run.join("checkpoints").join("latest"), "iter-000001").expect("write");
    for out in [
        run.clone(),
        run.join("checkpoints/mean"),
        run.join("x/../checkpoints/avg"),
    ] {
        let out = out.to_str().expect("UTF-8 path");
        assert_refused(
            &average_into(out),
            &["lies in the training run", "choose a folder outside it"],
        );
    }
    assert_eq!(
        walk(&run),
        [run.join("checkpoints/latest")],
        "the run is as it was"
    );
    assert_eq!(
        std::fs::read_dir(&run).expect("list").count(),
        1,
        "nothing was created in the run"
    );
    // Nor does any other command's single file, over a file of the run or beside them.
    let inside = |name: &str| run.join(name).to_str().expect("UTF-8").to_string();
    for args in [
        vec![
            "recordings",
            "generate",
            "--effect",
            "none",
            "--tracks",
            "3",
            "--out",
            &inside("curves.csv"),
        ],
        vec![
            "map",
            "export",
            "--procedural",
            "straight",
            "--out",
            &inside("config.toml"),
        ],
        vec![
            "map",
            "render",
            "--procedural",
            "straight",
            "--out",
            &inside("checkpoints/iter-000001/road.png"),
        ],
        vec![
            "curate",
            "--checkpoint",
            "models/il_main",
            "--out",
            &inside("policy.bpk"),
        ],
    ] {
        assert_refused(&args, &["lies inside", "result set"]);
    }
    assert_eq!(
        walk(&run),
        [run.join("checkpoints/latest")],
        "the run is as it was"
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
    // Inside the claimed folder, a file or a folder of another command is refused too: the
    // first writer replaces its folder whole when it ends.
    let inside = out.join("train");
    assert_refused(
        &[
            "recordings",
            "generate",
            "--effect",
            "none",
            "--tracks",
            "3",
            "--out",
            inside.join("zz.json").to_str().expect("UTF-8 path"),
        ],
        &["lies inside", "another rtr process", &pid],
    );
    assert_refused(
        &[
            "train",
            "--config",
            "experiments/main/il.toml",
            "--out",
            inside.to_str().expect("UTF-8 path"),
        ],
        &["lies inside", "another rtr process", &pid],
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
    // A scenario as JSON without its digest: edited copies below are hand-made files, so the
    // checks behind the digest are what must refuse them.
    let unstamped = |bytes: &[u8]| {
        let mut v: serde_json::Value = serde_json::from_slice(bytes).expect("JSON");
        v.as_object_mut().expect("object").remove("content_sha256");
        v
    };
    let relabelled = |path: &Path, set: &str| {
        let mut v = unstamped(&std::fs::read(path).expect("read"));
        v["set"] = serde_json::Value::String(set.into());
        v["index"] = serde_json::json!(99);
        serde_json::to_vec_pretty(&v).expect("JSON")
    };
    let relabelled_bytes = |bytes: &[u8], set: &str| {
        let mut v = unstamped(bytes);
        v["set"] = serde_json::Value::String(set.into());
        v["index"] = serde_json::json!(98);
        serde_json::to_vec_pretty(&v).expect("JSON")
    };
    // The same draw with every state's x moved by `dx` metres and a new seed.
    let nudged = |path: &Path, dx: f64| {
        let mut v = unstamped(&std::fs::read(path).expect("read"));
        v["seed"] = serde_json::json!(12345);
        for agent in v["agents"].as_array_mut().expect("agents") {
            for state in agent["states"].as_array_mut().expect("states") {
                if let Some(x) = state.get(0).and_then(serde_json::Value::as_f64) {
                    state[0] = serde_json::json!(x + dx);
                }
            }
        }
        serde_json::to_vec_pretty(&v).expect("JSON")
    };
    // One state of the first agent moved 5 km: a teleport, not wrong speed units.
    let teleported = |path: &Path| {
        let mut v = unstamped(&std::fs::read(path).expect("read"));
        let states = v["agents"][0]["states"].as_array_mut().expect("states");
        let middle = states.len() / 2;
        let x = states[middle][0]
            .as_f64()
            .expect("a state in the middle of the history");
        states[middle][0] = serde_json::json!(x + 5000.0);
        serde_json::to_vec_pretty(&v).expect("JSON")
    };
    // The first eval scenario with its JSON changed by `edit`.
    let edited = |edit: &dyn Fn(&mut serde_json::Value)| {
        let mut v = unstamped(&std::fs::read(first("eval")).expect("read"));
        edit(&mut v);
        serde_json::to_vec_pretty(&v).expect("JSON")
    };
    // The same edit with the digest left in place, as a script that edits one field would.
    let stamped_edit = |edit: &dyn Fn(&mut serde_json::Value)| {
        let mut v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(first("eval")).expect("read")).expect("JSON");
        assert!(
            v["content_sha256"].is_string(),
            "generated files carry a digest"
        );
        edit(&mut v);
        serde_json::to_vec_pretty(&v).expect("JSON")
    };
    // A drawn value of the first hero's first phase, by its name in `parameters`.
    let phase_label = |v: &serde_json::Value| -> (String, String, String) {
        let name = v["parameters"]
            .as_object()
            .expect("parameters")
            .keys()
            .find(|k| k.starts_with("heroes[0].phases[0]."))
            .expect("the first hero's first phase has a drawn value")
            .clone();
        let mut parts = name.rsplitn(3, '.');
        let field = parts.next().expect("field").to_string();
        let part = parts.next().expect("trigger or action").to_string();
        (name, part, field)
    };
    let label_cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "zz-index-edited.json",
            stamped_edit(&|v| v["index"] = serde_json::json!(5)),
            "content_sha256",
        ),
        (
            "zz-length-edited.json",
            stamped_edit(&|v| {
                let length = v["agents"][1]["length"].as_f64().expect("length");
                v["agents"][1]["length"] = serde_json::json!(length + 0.3);
            }),
            "content_sha256",
        ),
        (
            "zz-label-edited.json",
            edited(&|v| {
                let (name, _, _) = phase_label(v);
                let drawn = v["parameters"][&name].as_f64().expect("number");
                v["parameters"][&name] = serde_json::json!(drawn + 1.0);
            }),
            "heroes[0].phases[0]",
        ),
        (
            "zz-script-edited.json",
            edited(&|v| {
                let (_, part, field) = phase_label(v);
                let value = &mut v["heroes"][0]["phases"][0][&part][&field];
                *value = serde_json::json!(value.as_f64().expect("number") + 1.0);
            }),
            "heroes[0].phases[0]",
        ),
        (
            "zz-unlabelled.json",
            edited(&|v| {
                let (name, _, _) = phase_label(v);
                v["parameters"].as_object_mut().expect("map").remove(&name);
            }),
            "has no `heroes[0].phases[0]",
        ),
        (
            "zz-unknown-label.json",
            edited(&|v| v["parameters"]["hero.speed"] = serde_json::json!(3.0)),
            "parameters.hero.speed",
        ),
        (
            "zz-reference.json",
            edited(&|v| {
                let collided = v["reference"]["collided_agents"]
                    .as_array_mut()
                    .expect("list");
                if collided.is_empty() {
                    collided.push(serde_json::json!(1));
                } else {
                    collided.clear();
                }
            }),
            "reference.collided_agents",
        ),
    ];
    // Scoring the long tail of the scenario folder `root` is refused, saying `expected`.
    let eval_refuses = |root: &Path, expected: &[&str]| {
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
                root.to_str().expect("UTF-8 path"),
            ],
            expected,
        );
    };
    // A scenario edited in place, in a set and as a single file.
    let original = first("eval");
    let original_name = original
        .file_name()
        .and_then(|n| n.to_str())
        .expect("UTF-8 name");
    for (k, (name, bytes, expected)) in label_cases.iter().enumerate() {
        let root = dir.path().join(format!("edited{k}"));
        copy_folder(&good, &root);
        std::fs::write(root.join("eval").join(original_name), bytes).expect("write");
        eval_refuses(&root, &[original_name, expected]);
        let file = dir.path().join(name);
        std::fs::write(&file, bytes).expect("write");
        let out = dir.path().join(format!("{name}.svg"));
        assert_refused(
            &[
                "render",
                "--scenario",
                file.to_str().expect("UTF-8 path"),
                "--out",
                out.to_str().expect("UTF-8 path"),
            ],
            &[name, expected],
        );
    }
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "zz-teleported.json",
            teleported(&first("eval")),
            "a jump (teleport",
        ),
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
            "zz-renamed-family.json",
            edited(&|v| {
                v["family"] = serde_json::json!("my_own_family");
                v["description"] = serde_json::json!("mine");
            }),
            "same scenario as",
        ),
        (
            "zz-relabelled.json",
            relabelled(&first("train"), "eval"),
            "of the train set",
        ),
        (
            "zz-nudged.json",
            nudged(&first("eval"), 0.001),
            "same scenario as",
        ),
        (
            "zz-moved.json",
            nudged(&first("eval"), 100.0),
            "same scenario as",
        ),
        (
            "zz-moved-train.json",
            relabelled_bytes(&nudged(&first("train"), 0.001), "eval"),
            "of the train set",
        ),
        // Files the loader would otherwise skip: the set would be scored without them.
        (
            "zz-upper.JSON",
            std::fs::read(first("eval")).expect("read"),
            "is not a scenario file",
        ),
        ("notes.txt", b"my notes".to_vec(), "is not a scenario file"),
    ];
    for (k, (name, bytes, expected)) in cases.into_iter().enumerate() {
        let root = dir.path().join(format!("case{k}"));
        copy_folder(&good, &root);
        std::fs::write(root.join("eval").join(name), bytes).expect("write");
        eval_refuses(&root, &[name, expected]);
    }
    let root = dir.path().join("subfolder");
    copy_folder(&good, &root);
    std::fs::create_dir(root.join("eval").join("old")).expect("mkdir");
    eval_refuses(&root, &["old", "folder", "is not a scenario file"]);
    // An evaluation scenario moved into the training folder: the set would be scored short.
    let root = dir.path().join("moved-out");
    copy_folder(&good, &root);
    let moved = root.join("train").join(original_name);
    std::fs::rename(root.join("eval").join(original_name), &moved).expect("move");
    eval_refuses(&root, &[original_name, "train set's folder"]);
}

/// A run resumed with its scenario folder spelt another way (`./S/` for `S`) is the same run.
#[test]
fn a_scenario_folder_spelt_another_way_resumes_the_run() {
    let dir = tempfile::tempdir().expect("temp dir");
    let status = rtr()
        .current_dir(dir.path())
        .args([
            "scenarios",
            "generate",
            "--in-distribution",
            "8",
            "--ood",
            "0",
        ])
        .args(["--out", "S"])
        .stdout(Stdio::null())
        .status()
        .expect("rtr runs");
    assert!(status.success());
    let config = std::path::absolute("experiments/main/small/rtr.toml").expect("path");
    let train = |scenarios: &str, resume: bool| {
        let mut command = rtr();
        command
            .current_dir(dir.path())
            .arg("train")
            .arg("--config")
            .arg(&config)
            .args([
                "--scenarios",
                scenarios,
                "--out",
                "run",
                "--stop-after",
                "1",
            ]);
        if resume {
            command.arg("--resume");
        }
        let out = command.output().expect("rtr runs");
        assert!(
            out.status.success(),
            "train --scenarios {scenarios}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    train("./S/", false);
    train("S", true);
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

/// `recordings generate --values` sets the concealed effect's parameters, checked against the
/// ranges sim2real fits: a count that does not match, a value outside its range and values for
/// an effect without catalogue parameters are refused by name.
#[test]
fn generated_effect_values_are_checked_against_the_catalogue() {
    let generate = |effect: &str, values: &str| {
        vec![
            "recordings".to_string(),
            "generate".into(),
            "--effect".into(),
            effect.into(),
            "--values".into(),
            values.into(),
            "--tracks".into(),
            "3".into(),
            "--out".into(),
            "unused.csv".into(),
        ]
    };
    let cases = [
        (generate("drag", "0.0006"), vec!["1 given", "c_d, c_r"]),
        (
            generate("sideslip", "7"),
            vec!["sideslip's lr_m in m", "[0, 3]"],
        ),
        (generate("sideslip", "nan"), vec!["--values NaN"]),
        (
            generate("none", "0.4"),
            vec!["--effect none has no catalogue parameters"],
        ),
    ];
    for (args, expected) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_refused(&args, &expected);
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("weak.csv");
    let output = rtr()
        .args([
            "recordings",
            "generate",
            "--effect",
            "sideslip",
            "--values",
            "0.4",
        ])
        .args(["--tracks", "3", "--out"])
        .arg(&out)
        .output()
        .expect("runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let said = String::from_utf8_lossy(&output.stdout);
    assert!(said.contains("concealed sideslip [0.4]"), "{said}");
}
