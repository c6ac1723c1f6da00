//! Claiming an output before any work: it is writable, it is not one of the command's inputs
//! (nor contains one, nor lies inside an input folder), and it is locked for the command's
//! lifetime, so a second rtr process writing there is refused naming the first.

use std::fs::File;
use std::io::Write;
use std::path::{Component, Path, PathBuf};

use super::output::{OutputKind, check_output, create_folder, folder_of};
use crate::error::{Error, Result};

/// The files and folders a command reads, each with the flag that named it.
#[derive(Debug, Default, Clone)]
pub struct Inputs {
    items: Vec<(String, PathBuf)>,
}

impl Inputs {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds the input `path` given with `flag`.
    pub fn with(mut self, flag: &str, path: impl AsRef<Path>) -> Self {
        self.items
            .push((flag.to_string(), path.as_ref().to_path_buf()));
        self
    }

    /// Adds every path of `paths`, each given with `flag`.
    pub fn with_all<P: AsRef<Path>>(self, flag: &str, paths: impl IntoIterator<Item = P>) -> Self {
        paths
            .into_iter()
            .fold(self, |inputs, p| inputs.with(flag, p))
    }
}

/// What an output file is: an existing file is replaced only by one of its kind.
#[derive(Debug, Clone, Copy)]
pub struct FileKind {
    /// How messages name it ("a scene list").
    pub name: &'static str,
    /// The file name extensions it is written under (compared in any case).
    pub extensions: &'static [&'static str],
    /// Whether a file's first bytes (up to [`RECOGNISED_BYTES`], possibly cut mid-line) are
    /// of this kind.
    pub recognise: fn(&[u8]) -> bool,
}

/// How much of an existing output file is read to tell its kind.
pub const RECOGNISED_BYTES: usize = 64 * 1024;

/// Checks, before any work, that the file `path` (given with `flag`) can be written and is
/// none of `inputs`, nor inside an input folder, and that a file already there is of `kind`,
/// by name and by content: a run file, recordings or notes of the user's are not replaced by
/// a scene list or a map (`notes.txt` is no scene list though both end in `.txt`). Then locks
/// it against other rtr processes until the returned claim is dropped.
pub fn claim_output_file(
    path: &Path,
    flag: &str,
    inputs: &Inputs,
    kind: &FileKind,
) -> Result<OutputClaim> {
    // An input first: that says more than "is a file" of the same path.
    refuse_overlap(path, flag, inputs)?;
    check_output(path, OutputKind::File, flag)?;
    let target = resolved(path);
    refuse_inside_a_claim(&target, path, flag)?;
    refuse_inside_a_result_set(&target, path, flag)?;
    refuse_replacing_another_kind(path, flag, kind)?;
    let claim = lock(&target, path, flag)?;
    // Under the lock: the temporary file a killed writer of this output left is nobody's.
    super::output::remove_stale_temporaries(folder_of(&target));
    Ok(claim)
}

/// Refuses an existing file at `path` whose extension is none of `kind`'s, or whose content
/// is not of `kind` (an empty file holds nothing to lose).
fn refuse_replacing_another_kind(path: &Path, flag: &str, kind: &FileKind) -> Result<()> {
    if !path.is_file() {
        return Ok(());
    }
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    let refuse = |why: String| {
        Err(Error::InvalidArgument(format!(
            "{flag} {} exists and {why}; it would be replaced: choose another {flag}, or \
             remove it first",
            path.display()
        )))
    };
    if !kind
        .extensions
        .iter()
        .any(|e| name.ends_with(&format!(".{e}")))
    {
        let names: Vec<String> = kind.extensions.iter().map(|e| format!(".{e}")).collect();
        return refuse(format!(
            "is not a file this command writes ({})",
            names.join(" or ")
        ));
    }
    let head = super::input::read_head(path, RECOGNISED_BYTES)?;
    if head.is_empty() || (kind.recognise)(&head) {
        return Ok(());
    }
    refuse(format!(
        "is not {} (its content is not what this command writes)",
        kind.name
    ))
}

/// An output claimed by [`claim_output_file`] or [`claim_output_folder`]; the claim lasts as
/// long as this value.
#[must_use = "the output is locked only while its claim lives"]
#[derive(Debug)]
pub struct OutputClaim {
    lock: File,
    path: PathBuf,
}

impl Drop for OutputClaim {
    fn drop(&mut self) {
        // Removed while still locked, so no one can lock this file after we let go of it
        // (a waiting process notices the path has gone and opens a fresh one).
        let _ = std::fs::remove_file(&self.path);
        let _ = self.lock.unlock();
        held_here().retain(|p| p != &self.path);
    }
}

/// On SIGINT, SIGTERM or SIGHUP, removes the lock files this process holds and exits as
/// the signal would have (128 + its number): a writer stopped with Ctrl-C leaves no
/// `.rtr-lock-*` file behind. (Its staging folders, named with its process id, are removed by
/// the next command that writes beside them.)
pub fn release_locks_on_signal() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
        return;
    };
    std::thread::spawn(move || {
        if let Some(signal) = signals.forever().next() {
            for path in held_here().iter() {
                let _ = std::fs::remove_file(path);
            }
            std::process::exit(128 + signal);
        }
    });
}

/// The lock files this process holds: its own claims inside a folder it has claimed (a
/// sweep's points) are not another writer's.
fn held_here() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    static HELD: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    HELD.lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Refuses `target` when a folder above it is claimed by another rtr process: that process
/// replaces its folder whole, and whatever is written inside meanwhile is lost or mixed in.
fn refuse_inside_a_claim(target: &Path, shown: &Path, flag: &str) -> Result<()> {
    for folder in target.ancestors().skip(1) {
        let Some(parent) = folder.parent() else {
            break;
        };
        // Only a lock file someone holds counts: a killed writer's is free.
        if let Some(holder) = live_holder(&parent.join(lock_name(folder))) {
            return Err(Error::InvalidArgument(format!(
                "{flag} {} lies inside {}, which another rtr process is writing ({holder}); \
                 what is written inside it meanwhile would be lost or mixed into that \
                 process's results: wait for it to end or choose another {flag}",
                shown.display(),
                folder.display(),
            )));
        }
    }
    Ok(())
}

/// Whether `dir` holds the result set of an rtr command: a record of its files
/// ([`super::staged::OWN_FILES`]), a training run (`checkpoints/latest`) or a model
/// (`policy.bpk`).
pub(super) fn is_result_set(dir: &Path) -> bool {
    dir.join(super::staged::OWN_FILES).is_file()
        || dir.join("checkpoints").join("latest").exists()
        || dir.join("policy.bpk").exists()
}

/// Refuses `target` inside another command's result set (a training run, a model, an
/// evaluation): that command rewrites or reads its folder as a whole, so a file put there is
/// lost at its next run or breaks it (a report written over a run's `latest`). Result sets
/// this process itself claimed (a sweep's folder around its points) are its own.
fn refuse_inside_a_result_set(target: &Path, shown: &Path, flag: &str) -> Result<()> {
    for folder in target.ancestors().skip(1) {
        let Some(parent) = folder.parent() else {
            break;
        };
        if held_here().contains(&parent.join(lock_name(folder))) || !is_result_set(folder) {
            continue;
        }
        let record = folder.join(super::staged::OWN_FILES);
        let what = if record.is_file() {
            format!("its {} records what rtr wrote there", record.display())
        } else {
            "a training run or a model".to_string()
        };
        return Err(Error::InvalidArgument(format!(
            "{flag} {} lies inside {}, the result set of another rtr command ({what}); writing \
             there would change or break it: choose another {flag}",
            shown.display(),
            folder.display()
        )));
    }
    Ok(())
}

/// Refuses the folder `target` when another rtr process is writing somewhere inside it:
/// publishing a result set replaces the folder whole, and that process's files would be
/// pulled from under it.
fn refuse_holding_a_claim(target: &Path, shown: &Path, flag: &str) -> Result<()> {
    super::output_tree::walk(target, |path, is_folder| {
        if is_folder || !is_lock_file(path) {
            return Ok(true);
        }
        match live_holder(path) {
            None => Ok(true),
            Some(holder) => Err(Error::InvalidArgument(format!(
                "{flag} {} holds an output that another rtr process is writing (in {}: \
                 {holder}); publishing there would replace that folder under it: wait for it \
                 or choose another {flag}",
                shown.display(),
                path.parent().unwrap_or(path).display(),
            ))),
        }
    })
}

fn is_lock_file(path: &Path) -> bool {
    path.file_name()
        .is_some_and(|n| n.to_string_lossy().starts_with(LOCK_PREFIX))
}

/// The name prefix of the lock file beside a claimed output.
const LOCK_PREFIX: &str = ".rtr-lock-";

/// Whether `path` is rtr's own bookkeeping (a result set's record or an output's lock), which
/// a reader of a folder's files skips.
pub fn is_bookkeeping(path: &Path) -> bool {
    is_lock_file(path)
        || path
            .file_name()
            .is_some_and(|n| n == super::staged::OWN_FILES)
}

/// The holder recorded in the lock file at `path` when another process holds it now.
fn live_holder(path: &Path) -> Option<String> {
    if held_here().iter().any(|p| p == path) {
        return None;
    }
    let file = File::open(path).ok()?;
    match file.try_lock_shared() {
        Ok(()) => {
            let _ = file.unlock();
            None
        }
        Err(std::fs::TryLockError::WouldBlock) => Some(
            std::fs::read_to_string(path)
                .unwrap_or_default()
                .trim()
                .to_string(),
        ),
        Err(std::fs::TryLockError::Error(_)) => None,
    }
}

/// Checks, before any work, that the folder `path` (given with `flag`) can be written, is
/// none of `inputs`, holds none and lies in none; then locks it against other rtr processes
/// until the returned claim is dropped. A second writer gets an error naming the first.
pub fn claim_output_folder(path: &Path, flag: &str, inputs: &Inputs) -> Result<OutputClaim> {
    // An input first: that says more than "is a file" of the same path.
    refuse_overlap(path, flag, inputs)?;
    check_output(path, OutputKind::Folder, flag)?;
    let target = resolved(path);
    refuse_inside_a_claim(&target, path, flag)?;
    refuse_inside_a_result_set(&target, path, flag)?;
    refuse_holding_a_claim(&target, path, flag)?;
    let claim = lock(&target, path, flag)?;
    // Under the lock: what a killed writer of this folder left is nobody's.
    super::output::remove_stale_temporaries(folder_of(&target));
    super::output::remove_stale_temporaries(&target);
    Ok(claim)
}

/// `path` made absolute with every existing part's links resolved and `.` and `..` applied
/// (an output need not exist yet, and `..` after a part that does not exist is applied to the
/// words: no link can hide there), so that two spellings of one place compare equal.
pub fn resolved(path: &Path) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let parts: Vec<Component> = absolute.components().collect();
    for split in (1..=parts.len()).rev() {
        let Ok(real) = parts[..split].iter().collect::<PathBuf>().canonicalize() else {
            continue;
        };
        let mut out = real;
        let mut moved_up = false;
        for part in &parts[split..] {
            match part {
                Component::ParentDir => {
                    out.pop();
                    moved_up = true;
                }
                Component::Normal(name) => out.push(name),
                _ => {}
            }
        }
        // Back up into existing folders, whose links must be resolved in turn.
        return if moved_up { resolved(&out) } else { out };
    }
    absolute
}

/// Refuses an output that is an input, holds one or lies inside an input folder.
fn refuse_overlap(output: &Path, flag: &str, inputs: &Inputs) -> Result<()> {
    let out = resolved(output);
    for (input_flag, input) in &inputs.items {
        let inp = resolved(input);
        let why = if out == inp {
            "is"
        } else if inp.starts_with(&out) {
            "holds"
        } else if out.starts_with(&inp) && input.is_dir() {
            "lies inside"
        } else {
            continue;
        };
        return Err(Error::InvalidArgument(format!(
            "{flag} {} {why} the input {input_flag} {}: writing there would change what the \
             command reads; choose another {flag}",
            output.display(),
            input.display()
        )));
    }
    Ok(())
}

/// Locks `target` through a lock file beside it (the target may be replaced or not exist
/// yet). The operating system releases the lock when the process ends, however it ends; the
/// file itself is removed on release.
fn lock(target: &Path, shown: &Path, flag: &str) -> Result<OutputClaim> {
    let parent = folder_of(target);
    create_folder(parent)?;
    let path = parent.join(lock_name(target));
    loop {
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(|e| Error::io(&path, e))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => return Err(held(shown, flag, &path)),
            Err(std::fs::TryLockError::Error(e)) => return Err(Error::io(&path, e)),
        }
        // Locked a file its releaser had already removed: take the path's present one.
        if !same_file(&file, &path) {
            continue;
        }
        let holder = format!(
            "pid {}: {}",
            std::process::id(),
            std::env::args_os()
                .map(|a| a.to_string_lossy().into_owned())
                .collect::<Vec<_>>()
                .join(" ")
        );
        // The holder is only for messages: a failure to record it does not matter.
        let _ = file
            .set_len(0)
            .and_then(|()| file.write_all(holder.as_bytes()));
        held_here().push(path.clone());
        remove_stale_locks(parent);
        return Ok(OutputClaim { lock: file, path });
    }
}

/// Removes the lock files in `folder` that no process holds: what a writer ended by a signal
/// (Ctrl-C) left. Each is removed while locked here, as its own holder would on release, so
/// a process that opened it meanwhile notices and takes a fresh one.
fn remove_stale_locks(folder: &Path) {
    let Ok(entries) = std::fs::read_dir(folder) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let is_lock = entry
            .file_name()
            .to_str()
            .is_some_and(|n| n.starts_with(LOCK_PREFIX));
        if !is_lock || held_here().iter().any(|p| p == &path) {
            continue;
        }
        let Ok(file) = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&path)
        else {
            continue;
        };
        if file.try_lock().is_ok() {
            if same_file(&file, &path) {
                let _ = std::fs::remove_file(&path);
            }
            let _ = file.unlock();
        }
    }
}

/// Whether the open `file` is the one at `path` now.
fn same_file(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), path.metadata()) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

fn held(target: &Path, flag: &str, lock_path: &Path) -> Error {
    let holder = std::fs::read_to_string(lock_path).unwrap_or_default();
    Error::InvalidArgument(format!(
        "{flag} {}: another rtr process is writing there ({}); wait for it to end or choose \
         another {flag}",
        target.display(),
        if holder.trim().is_empty() {
            "unknown"
        } else {
            holder.trim()
        }
    ))
}

/// The lock file's name for `target`: hidden, and short whatever the folder's name.
fn lock_name(target: &Path) -> String {
    let name = target
        .components()
        .next_back()
        .map(|c| match c {
            Component::Normal(n) => n.to_string_lossy().into_owned(),
            _ => "out".into(),
        })
        .unwrap_or_else(|| "out".into());
    if name.len() <= 100 {
        return format!("{LOCK_PREFIX}{name}");
    }
    use sha2::Digest;
    let digest = sha2::Sha256::digest(name.as_bytes());
    let hex: String = digest[..16].iter().map(|b| format!("{b:02x}")).collect();
    format!("{LOCK_PREFIX}{hex}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_claim_is_refused_naming_the_first_and_released_with_it() {
        let dir = tempfile::tempdir().expect("temp dir");
        let out = dir.path().join("run");
        let first = claim_output_folder(&out, "--out", &Inputs::new()).expect("first claim");
        let err = claim_output_folder(&out, "--out", &Inputs::new()).expect_err("second");
        assert!(err.to_string().contains("another rtr process"), "{err}");
        assert!(
            err.to_string().contains(&std::process::id().to_string()),
            "{err}"
        );
        drop(first);
        let lock_files = || {
            std::fs::read_dir(dir.path())
                .expect("list")
                .filter(|e| {
                    e.as_ref()
                        .is_ok_and(|e| e.file_name().to_string_lossy().starts_with(".rtr-lock"))
                })
                .count()
        };
        assert_eq!(lock_files(), 0, "the lock file goes with its claim");
        let _claim = claim_output_folder(&out, "--out", &Inputs::new()).expect("free again");
        let file = dir.path().join("report.json");
        let _report = claim_output_file(&file, "--report", &Inputs::new(), &JSON).expect("a file");
        let err = claim_output_file(&file, "--report", &Inputs::new(), &JSON).expect_err("twice");
        assert!(err.to_string().contains("another rtr process"), "{err}");
    }

    #[test]
    fn a_lock_left_by_a_killed_writer_is_removed_by_the_next_claim_beside_it() {
        let dir = tempfile::tempdir().expect("temp dir");
        let stale = dir.path().join(".rtr-lock-killed");
        std::fs::write(&stale, "pid 1: rtr eval").expect("write");
        let first = claim_output_folder(&dir.path().join("a"), "--out", &Inputs::new())
            .expect("first claim");
        assert!(!stale.exists(), "nobody held it");
        let _second = claim_output_folder(&dir.path().join("b"), "--out", &Inputs::new())
            .expect("second claim");
        let held = dir.path().join(".rtr-lock-a");
        assert!(held.exists(), "a held lock stays");
        drop(first);
        assert!(!held.exists());
    }

    /// A CSV whose header starts with `track_id`.
    const CSV: FileKind = FileKind {
        name: "a track CSV",
        extensions: &["csv"],
        recognise: |head| head.starts_with(b"track_id"),
    };

    /// Any `.json` file.
    const JSON: FileKind = FileKind {
        name: "JSON",
        extensions: &["json"],
        recognise: |_| true,
    };

    #[test]
    fn an_existing_file_of_another_kind_is_not_replaced() {
        let dir = tempfile::tempdir().expect("temp dir");
        let run_file = dir.path().join("run.toml");
        std::fs::write(&run_file, "method = \"IL\"\n").expect("write");
        let err = claim_output_file(&run_file, "--out", &Inputs::new(), &CSV)
            .expect_err("a run file is not recordings")
            .to_string();
        assert!(err.contains("run.toml") && err.contains("(.csv)"), "{err}");
        let old = dir.path().join("old.CSV");
        std::fs::write(&old, "track_id\n").expect("write");
        drop(claim_output_file(&old, "--out", &Inputs::new(), &CSV).expect("its own kind"));
        // The right name is not enough: a user's table under the same extension stays.
        let table = dir.path().join("table.csv");
        std::fs::write(&table, "name,score\nx,1\n").expect("write");
        let err = claim_output_file(&table, "--out", &Inputs::new(), &CSV)
            .expect_err("another CSV")
            .to_string();
        assert!(
            err.contains("table.csv") && err.contains("is not a track CSV"),
            "{err}"
        );
        let empty = dir.path().join("empty.csv");
        std::fs::write(&empty, "").expect("write");
        drop(claim_output_file(&empty, "--out", &Inputs::new(), &CSV).expect("nothing to lose"));
        drop(
            claim_output_file(&dir.path().join("new.toml"), "--out", &Inputs::new(), &CSV)
                .expect("a new file, whatever its name"),
        );
    }

    #[test]
    fn an_output_inside_another_commands_result_set_is_refused() {
        let dir = tempfile::tempdir().expect("temp dir");
        let run = dir.path().join("run");
        std::fs::create_dir_all(run.join("checkpoints/iter-000004")).expect("mkdir");
        std::fs::write(run.join("checkpoints/latest"), "iter-000004").expect("write");
        let model = dir.path().join("model");
        std::fs::create_dir_all(&model).expect("mkdir");
        std::fs::write(model.join("policy.bpk"), "weights").expect("write");
        let eval = dir.path().join("eval");
        std::fs::create_dir_all(eval.join("figures")).expect("mkdir");
        std::fs::write(eval.join(".rtr-output"), "# rtr eval\ntable.md\n").expect("write");
        for file in [
            run.join("curves.csv"),
            run.join("checkpoints/latest"),
            run.join("checkpoints/iter-000004/x.png"),
            model.join("policy.bpk"),
            eval.join("figures/extra.png"),
        ] {
            let err = claim_output_file(&file, "--out", &Inputs::new(), &JSON).expect_err("inside");
            assert!(err.to_string().contains("result set"), "{err}");
        }
        let err = claim_output_folder(&run.join("checkpoints/mean"), "--out", &Inputs::new())
            .expect_err("a folder inside");
        assert!(err.to_string().contains("result set"), "{err}");
        // The set itself (its own command's next run) and a sibling are fine.
        let _own = claim_output_folder(&eval, "--out", &Inputs::new()).expect("the set itself");
        let _sibling = claim_output_file(
            &dir.path().join("r.json"),
            "--report",
            &Inputs::new(),
            &JSON,
        )
        .expect("beside it");
    }

    #[test]
    fn a_folder_holding_another_writers_output_is_refused() {
        let dir = tempfile::tempdir().expect("temp dir");
        let outer = dir.path().join("study");
        std::fs::create_dir_all(outer.join("run")).expect("mkdir");
        // Another process's claim on study/run: its lock file beside the run, held.
        let lock_path = outer.join(lock_name(&outer.join("run")));
        std::fs::write(&lock_path, "pid 4242: rtr train --out study/run").expect("write");
        let other = File::open(&lock_path).expect("open");
        other.lock().expect("lock");
        let err = claim_output_folder(&outer, "--out", &Inputs::new()).expect_err("holds");
        assert!(err.to_string().contains("pid 4242"), "{err}");
        other.unlock().expect("unlock");
        let _claim = claim_output_folder(&outer, "--out", &Inputs::new()).expect("free now");
    }

    #[test]
    fn an_output_that_is_holds_or_lies_in_an_input_is_refused() {
        let dir = tempfile::tempdir().expect("temp dir");
        let sets = dir.path().join("scenarios");
        std::fs::create_dir_all(sets.join("eval")).expect("mkdir");
        let run_file = dir.path().join("runs/a/run.toml");
        std::fs::create_dir_all(run_file.parent().expect("parent")).expect("mkdir");
        std::fs::write(&run_file, "method = \"IL\"").expect("write");
        let inputs = Inputs::new()
            .with("--scenarios", &sets)
            .with("--config", &run_file);
        for (out, why) in [
            (sets.join("eval/results"), "lies inside"),
            (dir.path().join("runs/a"), "holds"),
            (dir.path().join("runs/./a/../a"), "holds"),
        ] {
            let err = claim_output_folder(&out, "--out", &inputs).expect_err("overlap");
            assert!(err.to_string().contains(why), "{err}");
        }
        let err = claim_output_file(&run_file, "--report", &inputs, &JSON).expect_err("same file");
        assert!(err.to_string().contains("is the input --config"), "{err}");
        let _claim = claim_output_folder(&dir.path().join("runs/b"), "--out", &inputs)
            .expect("a sibling is fine");
    }
}
