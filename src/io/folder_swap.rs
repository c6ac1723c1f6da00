//! Replacing an existing result folder in one step. The new folder is built beside the old
//! one: the new result set, plus a hard link to every file of the old folder that stays (the
//! user's own files, rtr's files the new set does not replace). One atomic exchange of the two
//! folders then publishes it, so a reader, or a run killed at any moment, sees either the
//! whole earlier folder or the whole new one, never a mix. Hard links leave every old file
//! where it is until the exchange, so an interrupted preparation changes nothing.

use std::io;
use std::path::{Path, PathBuf};

/// Fills `staging` (which already holds the new result set, `replaced`) with hard links to
/// every entry of `target` that survives: all but `replaced`, the `dropped` files (rtr's
/// earlier set, which the new one supersedes) and the top-level `skip` name (the record of
/// rtr's files, rewritten for the new set). Folders are recreated with their permissions;
/// symbolic links are linked as links, never followed.
pub(super) fn link_survivors(
    target: &Path,
    staging: &Path,
    replaced: &[PathBuf],
    dropped: &[PathBuf],
    skip: &str,
) -> io::Result<()> {
    fn walk(
        root: &Path,
        dir: &Path,
        staging: &Path,
        keep: &dyn Fn(&Path) -> bool,
    ) -> io::Result<()> {
        let mut empty = true;
        for entry in std::fs::read_dir(dir)? {
            let entry = entry?;
            empty = false;
            let path = entry.path();
            let relative = path.strip_prefix(root).unwrap_or(&path);
            if entry.file_type()?.is_dir() {
                walk(root, &path, staging, keep)?;
            } else if keep(relative) {
                let link = staging.join(relative);
                if let Some(parent) = link.parent() {
                    std::fs::create_dir_all(parent)?;
                }
                std::fs::hard_link(&path, &link)?;
            }
        }
        let relative = dir.strip_prefix(root).unwrap_or(dir);
        let copy = staging.join(relative);
        // A user's empty folder stays; one emptied by dropped files goes (as it would by hand).
        if empty || copy.is_dir() {
            std::fs::create_dir_all(&copy)?;
            std::fs::set_permissions(&copy, std::fs::metadata(dir)?.permissions())?;
        }
        Ok(())
    }
    let keep = |relative: &Path| {
        relative != Path::new(skip)
            && !replaced.iter().any(|f| f == relative)
            && !dropped.iter().any(|f| f == relative)
    };
    walk(target, target, staging, &keep)
}

/// Removes from `staging` everything but the `keep` files (the new result set): undoes
/// [`link_survivors`] when the exchange cannot be made. The links only name files that also
/// live in the target, so removing them loses nothing.
pub(super) fn unlink_survivors(staging: &Path, keep: &[PathBuf]) -> io::Result<()> {
    fn walk(root: &Path, dir: &Path, keep: &[PathBuf]) -> io::Result<bool> {
        let mut kept = false;
        for entry in std::fs::read_dir(dir)? {
            let path = entry?.path();
            let relative = path.strip_prefix(root).unwrap_or(&path).to_path_buf();
            if path.symlink_metadata()?.is_dir() {
                if walk(root, &path, keep)? {
                    kept = true;
                } else {
                    std::fs::remove_dir(&path)?;
                }
            } else if keep.contains(&relative) {
                kept = true;
            } else {
                std::fs::remove_file(&path)?;
            }
        }
        Ok(kept)
    }
    walk(staging, staging, keep).map(|_| ())
}

/// Swaps the folders `a` and `b` in one atomic step. Fails with `Unsupported` where the
/// operating system has no such operation. Called through `libc` (one system call, already a
/// dependency) rather than rustix: adding rustix's `fs` feature changes the build of the whole
/// burn stack.
pub(super) fn exchange(a: &Path, b: &Path) -> io::Result<()> {
    #[cfg(any(target_os = "linux", target_vendor = "apple"))]
    {
        use std::os::unix::ffi::OsStrExt;
        let c = |p: &Path| {
            std::ffi::CString::new(p.as_os_str().as_bytes())
                .map_err(|_| io::Error::from(io::ErrorKind::InvalidInput))
        };
        let (a, b) = (c(a)?, c(b)?);
        // SAFETY: both are valid NUL-terminated paths that outlive the call.
        #[cfg(target_os = "linux")]
        let status = unsafe {
            libc::renameat2(
                libc::AT_FDCWD,
                a.as_ptr(),
                libc::AT_FDCWD,
                b.as_ptr(),
                libc::RENAME_EXCHANGE,
            )
        };
        // SAFETY: as above.
        #[cfg(target_vendor = "apple")]
        let status = unsafe { libc::renamex_np(a.as_ptr(), b.as_ptr(), libc::RENAME_SWAP) };
        if status == 0 {
            Ok(())
        } else {
            Err(io::Error::last_os_error())
        }
    }
    #[cfg(not(any(target_os = "linux", target_vendor = "apple")))]
    {
        let _ = (a, b);
        Err(io::ErrorKind::Unsupported.into())
    }
}

/// After the exchange `old` holds the earlier folder. A file there that has no other link
/// and is not one of rtr's `earlier` files (replaced or dropped) was put into the target by
/// someone else while the new folder was being built; it moves back into `target`. Returns
/// the files that could not (the new folder holds a file of that name), which stay in `old`.
pub(super) fn return_late_files(
    old: &Path,
    target: &Path,
    earlier: &[PathBuf],
    skip: &str,
) -> io::Result<Vec<PathBuf>> {
    use std::os::unix::fs::MetadataExt;
    let mut stranded = Vec::new();
    let mut stack = vec![old.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir)? {
            let path = entry?.path();
            let meta = path.symlink_metadata()?;
            let relative = path.strip_prefix(old).unwrap_or(&path).to_path_buf();
            if meta.is_dir() {
                stack.push(path);
                continue;
            }
            if meta.nlink() > 1 || relative == Path::new(skip) || earlier.contains(&relative) {
                continue;
            }
            let destination = target.join(&relative);
            if destination.symlink_metadata().is_ok() {
                stranded.push(path);
                continue;
            }
            if let Some(parent) = destination.parent() {
                std::fs::create_dir_all(parent)?;
            }
            std::fs::rename(&path, &destination)?;
        }
    }
    Ok(stranded)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn survivors_are_linked_and_unlinking_restores_the_staged_set() {
        let root = tempfile::tempdir().expect("temp dir");
        let (target, staging) = (root.path().join("out"), root.path().join("staging"));
        for dir in ["figures/old", "mine/empty"] {
            std::fs::create_dir_all(target.join(dir)).expect("mkdir");
        }
        for (file, text) in [
            ("results.json", "old"),
            ("figures/old/a.svg", "stale"),
            ("mine/notes.txt", "keep"),
            ("record", "list"),
        ] {
            std::fs::write(target.join(file), text).expect("write");
        }
        std::fs::create_dir(&staging).expect("mkdir");
        std::fs::write(staging.join("results.json"), "new").expect("write");
        let replaced = [PathBuf::from("results.json")];
        let dropped = [PathBuf::from("figures/old/a.svg")];
        link_survivors(&target, &staging, &replaced, &dropped, "record").expect("link");
        let read = |p: &str| std::fs::read_to_string(staging.join(p)).expect("read");
        assert_eq!(read("results.json"), "new");
        assert_eq!(read("mine/notes.txt"), "keep");
        assert!(
            staging.join("mine/empty").is_dir(),
            "a user's empty folder stays"
        );
        assert!(
            !staging.join("figures").exists(),
            "emptied by the dropped set"
        );
        assert!(!staging.join("record").exists());
        unlink_survivors(&staging, &replaced).expect("unlink");
        let mut left: Vec<_> = std::fs::read_dir(&staging)
            .expect("list")
            .map(|e| e.expect("entry").file_name())
            .collect();
        left.sort();
        assert_eq!(left, ["results.json"]);
        assert_eq!(
            std::fs::read_to_string(target.join("mine/notes.txt")).expect("read"),
            "keep",
            "unlinking leaves the originals"
        );
    }

    #[test]
    fn a_file_written_during_the_swap_returns_to_the_target() {
        let root = tempfile::tempdir().expect("temp dir");
        let (target, staging) = (root.path().join("out"), root.path().join("staging"));
        std::fs::create_dir(&target).expect("mkdir");
        std::fs::create_dir(&staging).expect("mkdir");
        std::fs::write(target.join("mine.txt"), "keep").expect("write");
        std::fs::write(staging.join("results.json"), "new").expect("write");
        link_survivors(&target, &staging, &[], &[], "record").expect("link");
        // Someone writes into the target between the preparation and the exchange.
        std::fs::write(target.join("late.txt"), "late").expect("write");
        std::fs::write(target.join("results.json"), "clash").expect("write");
        exchange(&staging, &target).expect("exchange");
        let stranded = return_late_files(&staging, &target, &[], "record").expect("return");
        assert_eq!(stranded, [staging.join("results.json")]);
        let read = |p: &Path| std::fs::read_to_string(p).expect("read");
        assert_eq!(read(&target.join("late.txt")), "late");
        assert_eq!(read(&target.join("mine.txt")), "keep");
        assert_eq!(read(&target.join("results.json")), "new");
    }
}
