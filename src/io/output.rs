//! One way out: every file rtr writes is written to a temporary file beside its destination
//! and renamed into place ([`atomic_write_with`]), so a crash never leaves a half file, and
//! only after it was checked to be whole (its size as written). A command's several files
//! are staged together ([`super::StagedFolder`]).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::error::{Error, Result};

/// A hidden temporary name in `folder` unique to this process and call, ending in
/// `extension` (some writers pick the format from it). Short whatever the final name's
/// length, so a destination name near the file system's limit still has a temporary one.
pub(crate) fn temp_name(folder: &Path, what: &str, extension: Option<&str>) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = format!("{TEMPORARY_PREFIX}{what}-{}-{n}", std::process::id());
    folder.join(match extension {
        Some(ext) => format!("{name}.{ext}"),
        None => name,
    })
}

/// The longest file name (bytes) common file systems take.
const MAX_NAME_BYTES: usize = 255;

/// How every temporary name of rtr starts.
const TEMPORARY_PREFIX: &str = ".rtr-tmp-";

/// Whether `name` is one of rtr's temporary names (a leftover of a killed run).
pub fn is_temporary_name(name: &str) -> bool {
    name.starts_with(TEMPORARY_PREFIX)
}

/// Removes from `folder` the temporary files and folders that rtr processes which no longer
/// run left behind (killed mid-write). Those of live processes are theirs and stay.
pub(crate) fn remove_stale_temporaries(folder: &Path) {
    let Ok(entries) = std::fs::read_dir(folder) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = name.strip_prefix(TEMPORARY_PREFIX) else {
            continue;
        };
        // `{what}-{pid}-{n}[.ext]`
        let Some(pid) = rest.split('-').nth(1).and_then(|p| p.parse::<u32>().ok()) else {
            continue;
        };
        if pid == std::process::id() || process_runs(pid) {
            continue;
        }
        let path = entry.path();
        let _ = if path.is_dir() {
            std::fs::remove_dir_all(&path)
        } else {
            std::fs::remove_file(&path)
        };
    }
}

/// Whether a process with id `pid` runs (a signal 0 reaches it, or it exists but is not ours),
/// a killed one that its parent has not yet reaped (a zombie) excepted.
fn process_runs(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    // SAFETY: signal 0 only checks that the process exists and may be signalled.
    let result = unsafe { libc::kill(pid, 0) };
    let exists = result == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH);
    exists && !is_zombie(pid)
}

/// Whether `pid` has ended and waits to be reaped (Linux: state `Z` in `/proc/PID/stat`,
/// after the command name in parentheses; elsewhere never known, so never).
fn is_zombie(pid: libc::pid_t) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|stat| {
        stat.rsplit_once(") ")
            .is_some_and(|(_, rest)| rest.starts_with('Z'))
    })
}

/// The folder `path` lives in (`.` for a bare file name).
pub(super) fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    }
}

/// Calls `write` with a temporary path next to `path`, checks that it wrote a file, then
/// renames it onto `path`. On error the temporary file is removed and `path` is left as it
/// was.
pub fn atomic_write_with(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let (path, tmp) = staged_file(path)?;
    let result = written_beside(&path, &tmp, write)
        .and_then(|()| std::fs::rename(&tmp, &path).map_err(|e| Error::io(&path, e)));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes every `(path, bytes)` as one set (a picture's PNG and SVG): each is written to a
/// temporary beside it and checked before any is renamed into place, so a full disk leaves
/// every path as it was, never one new file beside an old one.
pub fn atomic_write_all(files: &[(&Path, &[u8])]) -> Result<()> {
    let mut staged = Vec::new();
    let mut result = Ok(());
    for (path, bytes) in files {
        let step = staged_file(path).and_then(|(path, tmp)| {
            staged.push((path.clone(), tmp.clone()));
            written_beside(&path, &tmp, |tmp| write_new(tmp, bytes))
        });
        if let Err(e) = step {
            result = Err(e);
            break;
        }
    }
    if result.is_ok() {
        result = staged
            .iter()
            .try_for_each(|(path, tmp)| std::fs::rename(tmp, path).map_err(|e| Error::io(path, e)));
    }
    if result.is_err() {
        for (_, tmp) in &staged {
            let _ = std::fs::remove_file(tmp);
        }
    }
    result
}

/// The file `path` stands for (a link's target) and a temporary name beside it, its folder
/// created.
fn staged_file(path: &Path) -> Result<(std::path::PathBuf, std::path::PathBuf)> {
    let path = link_target(path).unwrap_or_else(|| path.to_path_buf());
    refuse_folder(&path)?;
    let folder = folder_of(&path);
    create_folder(folder)?;
    let extension = path.extension().and_then(|e| e.to_str());
    let tmp = temp_name(folder, "tmp", extension);
    Ok((path, tmp))
}

/// Runs `write` on `tmp` and checks that it wrote a file; a failure names `path`, the file
/// the user asked for, not the temporary beside it.
fn written_beside(path: &Path, tmp: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    write(tmp)
        .map_err(|e| match e {
            Error::Io { path: at, source } if at == tmp => Error::io(path, source),
            other => other,
        })
        .and_then(|()| check_written(tmp, path))
}

/// A file is to be written at `path`, where a folder is: said in words (the rename would
/// fail with the system's "Is a directory", which names no remedy).
fn refuse_folder(path: &Path) -> Result<()> {
    if path.is_dir() {
        return Err(Error::InvalidArgument(format!(
            "{} is a folder where rtr writes a file; move the folder away or choose another \
             output",
            path.display()
        )));
    }
    Ok(())
}

/// Where a symbolic link `path` leads, when it is one: the file written is its target, and
/// the link stays a link.
fn link_target(path: &Path) -> Option<std::path::PathBuf> {
    let is_link = path
        .symlink_metadata()
        .is_ok_and(|m| m.file_type().is_symlink());
    if is_link {
        path.canonicalize().ok()
    } else {
        None
    }
}

/// A writer that reported success left a non-empty file and it reached the disk (synced, so
/// a full disk surfaces here rather than as a silently empty file after the rename).
fn check_written(tmp: &Path, path: &Path) -> Result<()> {
    let file = std::fs::File::open(tmp).map_err(|e| Error::io(path, e))?;
    file.sync_all().map_err(|e| Error::io(path, e))?;
    let size = file.metadata().map_err(|e| Error::io(path, e))?.len();
    if size == 0 {
        return Err(Error::io(
            path,
            std::io::Error::other("the writer produced an empty file (disk full?)"),
        ));
    }
    Ok(())
}

/// Writes `bytes` to `path` atomically.
pub fn atomic_write(path: &Path, bytes: &[u8]) -> Result<()> {
    atomic_write_with(path, |tmp| write_new(tmp, bytes))
}

/// Writes `bytes` to a new file `path` and checks that all of them arrived. Not atomic: for
/// files inside a folder that is itself staged and renamed into place.
pub fn write_new(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    refuse_folder(path)?;
    let mut file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    file.write_all(bytes)
        .and_then(|()| file.sync_all())
        .map_err(|e| Error::io(path, e))
}

/// Creates the folder `dir` and its missing parents.
pub fn create_folder(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))
}

/// Removes the folder `dir` and everything in it; a missing folder is not an error.
pub fn remove_folder(dir: &Path) -> Result<()> {
    match std::fs::remove_dir_all(dir) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(Error::io(dir, e)),
    }
}

/// Removes the file `path`; a missing file is not an error.
pub fn remove_file(path: &Path) -> Result<()> {
    match std::fs::remove_file(path) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(Error::io(path, e)),
    }
}

/// Renames `from` to `to` (one atomic step within a file system).
pub fn rename(from: &Path, to: &Path) -> Result<()> {
    std::fs::rename(from, to).map_err(|e| Error::io(to, e))
}

/// A writer's output for [`std::fs::File`]-based encoders (GIF, PNG streams): creates `path`.
pub fn create_file(path: &Path) -> Result<std::fs::File> {
    refuse_folder(path)?;
    std::fs::File::create(path).map_err(|e| Error::io(path, e))
}

/// Whether `path` is, or links to, a file descriptor of this process (`/dev/stdout`,
/// `/dev/fd/1`, `/proc/self/fd/1`): a process-specific alias whose target cannot be replaced.
fn names_an_open_stream(path: &Path) -> bool {
    let is_stream = |p: &Path| {
        let p = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        ["/dev/fd", "/dev/stdin", "/dev/stdout", "/dev/stderr"]
            .iter()
            .any(|prefix| p.starts_with(prefix))
            || (p.starts_with("/proc") && p.components().any(|c| c.as_os_str() == "fd"))
    };
    is_stream(path) || path.read_link().is_ok_and(|target| is_stream(&target))
}

/// What an output path must be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum OutputKind {
    File,
    Folder,
}

/// Checks, before any work, that `path` can be written as `kind`: it is not the other kind,
/// nothing on its way is a file, and its nearest existing folder accepts a new file (probed
/// with a file created and removed at once). `flag` names the option in the error. Leaves the
/// file system as it was, so a command refused here has written nothing.
pub(super) fn check_output(path: &Path, kind: OutputKind, flag: &str) -> Result<()> {
    // Without a trailing slash: `link/` would follow a link to nothing and see no link at all.
    let path = &path.components().collect::<PathBuf>();
    let fail = |why: String| {
        Err(Error::InvalidArgument(format!(
            "{flag} {}: {why}",
            path.display()
        )))
    };
    if let Some(name) = path.file_name().filter(|n| n.len() > MAX_NAME_BYTES) {
        return fail(format!(
            "its name is {} bytes long; file systems allow at most {MAX_NAME_BYTES}",
            name.len()
        ));
    }
    if names_an_open_stream(path) {
        return fail(
            "names one of the command's open streams (/dev/fd, /dev/stdout, /proc/*/fd), not \
             a file: rtr writes a new file by name and renames it into place; give a file path"
                .into(),
        );
    }
    if let (Err(e), Ok(_)) = (path.metadata(), path.symlink_metadata()) {
        return fail(format!(
            "{}; remove it or name another path",
            super::input::broken_link(&e)
        ));
    }
    match (path.metadata(), kind) {
        (Ok(m), OutputKind::File) if m.is_dir() => {
            return fail("is a folder; expected a file path".into());
        }
        // Written by renaming a new file onto it, a device, FIFO or socket would be replaced
        // (and /dev/null taken from the whole system): refused, not written through.
        (Ok(m), OutputKind::File) if !m.is_file() => {
            return fail(format!(
                "is {}; expected a regular file path (rtr writes a new file there)",
                super::input::kind_of(&m)
            ));
        }
        (Ok(m), OutputKind::Folder) if !m.is_dir() => {
            return fail(format!(
                "is {}; expected a folder",
                super::input::kind_of(&m)
            ));
        }
        _ => {}
    }
    let existing = path
        .ancestors()
        .skip(usize::from(kind == OutputKind::File || !path.is_dir()))
        .map(|a| {
            if a.as_os_str().is_empty() {
                Path::new(".")
            } else {
                a
            }
        })
        // A dangling link on the way counts as there: it is what stops the way.
        .find(|a| a.symlink_metadata().is_ok());
    let Some(folder) = existing else {
        return fail("no part of the path exists".into());
    };
    match folder.metadata() {
        Ok(m) if !m.is_dir() => {
            return fail(format!(
                "{} is {}, so nothing can be written under it",
                folder.display(),
                super::input::kind_of(&m)
            ));
        }
        Err(e) => {
            return fail(format!(
                "{} {}, so nothing can be written under it",
                folder.display(),
                super::input::broken_link(&e)
            ));
        }
        Ok(_) => {}
    }
    let probe = temp_name(folder, "probe", None);
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
    {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => fail(format!("cannot write in {}: {e}", folder.display())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A killed writer's temporaries go at the next write beside them, also while its parent
    /// has not reaped it yet.
    #[test]
    fn a_writer_that_ended_is_not_running_even_unreaped() {
        let mut child = std::process::Command::new("true").spawn().expect("spawn");
        let pid = child.id();
        let waited = std::time::Instant::now();
        while process_runs(pid) && waited.elapsed() < std::time::Duration::from_secs(5) {
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        assert!(!process_runs(pid), "ended, not yet reaped");
        let dir = tempfile::tempdir().expect("temp dir");
        let leftover = dir
            .path()
            .join(format!("{TEMPORARY_PREFIX}checkpoint-{pid}-3"));
        std::fs::create_dir(&leftover).expect("mkdir");
        remove_stale_temporaries(dir.path());
        assert!(!leftover.exists());
        child.wait().expect("reaped");
        assert!(process_runs(std::process::id()));
    }

    #[test]
    fn a_set_of_files_is_written_whole_or_not_at_all() {
        let dir = tempfile::tempdir().expect("temp dir");
        let (a, b) = (dir.path().join("a.png"), dir.path().join("a.svg"));
        std::fs::write(&a, "old").expect("write");
        std::fs::create_dir(&b).expect("a folder where a file goes");
        atomic_write_all(&[(&a, b"new"), (&b, b"new")]).expect_err("b is a folder");
        assert_eq!(std::fs::read_to_string(&a).expect("a"), "old");
        let names: Vec<_> = std::fs::read_dir(dir.path()).expect("list").collect();
        assert_eq!(names.len(), 2, "no temporary left");
        std::fs::remove_dir(&b).expect("rmdir");
        atomic_write_all(&[(&a, b"new"), (&b, b"new")]).expect("both");
        assert_eq!(std::fs::read_to_string(&b).expect("b"), "new");
    }

    #[test]
    fn an_open_stream_is_no_output() {
        for path in ["/dev/stdout", "/dev/fd/1", "/proc/self/fd/1"] {
            let e = check_output(Path::new(path), OutputKind::File, "--out")
                .expect_err("a stream")
                .to_string();
            assert!(e.contains("open streams"), "{e}");
        }
    }

    #[test]
    fn failed_write_leaves_the_old_file() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("out.json");
        atomic_write(&path, b"old").expect("first write");
        let err = atomic_write_with(&path, |tmp| {
            std::fs::write(tmp, b"half").map_err(|e| Error::io(tmp, e))?;
            Err(Error::InvalidArgument("interrupted".into()))
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read(&path).expect("read"), b"old");
        let leftovers = std::fs::read_dir(dir.path()).expect("list").count();
        assert_eq!(leftovers, 1, "the temporary file is cleaned up");
    }
}
