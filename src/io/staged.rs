//! Outputs of one command made all or nothing. A command that writes several files (a study's
//! tables and figures, a scenario set, a report with its plots) writes them into a hidden
//! staging folder beside the real one and moves them in only once everything was written; if
//! it fails on the way, the staging folder is removed and the destination is as it was.
//! Single files are already atomic ([`super::atomic_write`]); this extends that to a folder.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// A folder being written: write under [`Self::path`], then [`Self::commit`]. Dropped without
/// a commit (an error on the way), it removes what it staged and the folders it created.
#[derive(Debug)]
pub struct StagedFolder {
    target: PathBuf,
    staging: PathBuf,
    /// Folders on the way to `target` that did not exist, outermost first.
    created: Vec<PathBuf>,
    committed: bool,
    /// The command whose results these are (`rtr eval`), recorded with them.
    kind: &'static str,
}

impl StagedFolder {
    /// Stages the result set of the command `kind` (`rtr eval`) in the new or existing folder
    /// `target`, whose earlier result set, if rtr recorded one, must be of the same kind
    /// ([`check_result_folder`]). Creates its missing parents (removed again if nothing is
    /// committed) and the staging folder beside it.
    pub fn new(target: &Path, kind: &'static str) -> Result<Self> {
        if target.is_file() {
            return Err(Error::InvalidArgument(format!(
                "{} is a file; expected a folder",
                target.display()
            )));
        }
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let created = create_missing(&parent)?;
        super::output::remove_stale_temporaries(&parent);
        let staged = Self {
            target: target.to_path_buf(),
            staging: super::output::temp_name(&parent, "staging", None),
            created,
            committed: false,
            kind,
        };
        // A leftover of a killed run with the same process id.
        super::remove_folder(&staged.staging)?;
        std::fs::create_dir(&staged.staging).map_err(|e| Error::io(&staged.staging, e))?;
        Ok(staged)
    }

    /// Where the command writes what will end up in the target folder.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Where `staged` (a path under [`Self::path`]) lands once committed.
    pub fn final_path(&self, staged: &Path) -> PathBuf {
        match staged.strip_prefix(&self.staging) {
            Ok(rest) => self.target.join(rest),
            Err(_) => staged.to_path_buf(),
        }
    }

    /// Runs `write` on the staging folder; an error it returns names the file where it will
    /// land (`out/table.md`), not the hidden staging name the user never sees.
    pub fn fill<T>(&self, write: impl FnOnce(&Path) -> Result<T>) -> Result<T> {
        write(&self.staging).map_err(|e| self.relocated(e))
    }

    fn relocated(&self, error: Error) -> Error {
        let staging = self.staging.display().to_string();
        let target = self.target.display().to_string();
        match error {
            Error::Io { path, source } => Error::Io {
                path: self.final_path(&path),
                source,
            },
            Error::InvalidArgument(message) => {
                Error::InvalidArgument(message.replace(&staging, &target))
            }
            Error::InvalidData {
                source_name,
                place,
                message,
            } => Error::InvalidData {
                source_name: source_name.replace(&staging, &target),
                place,
                message: message.replace(&staging, &target),
            },
            other => other,
        }
    }

    /// Moves everything staged into the target folder and records it there as rtr's result
    /// set ([`OWN_FILES`]); the files of rtr's earlier set that the new one lacks (an earlier
    /// run's figures) are removed, and anything else in the folder is left alone. Refuses,
    /// before moving anything, when a staged file would replace a file rtr did not write, or
    /// a file would land on a folder or a folder on a file.
    pub fn commit(mut self) -> Result<()> {
        let staged = relative_files(&self.staging)?;
        if self.target.exists() {
            refuse_other_kind(&self.target, self.kind)?;
            super::nested::refuse_nested_result_sets(&self.target, self.kind)?;
            check_mergeable(&self.staging, &self.target)?;
            let earlier = own_files(&self.target)?;
            refuse_foreign(&self.target, &staged, &earlier)?;
            let dropped: Vec<PathBuf> = earlier
                .iter()
                .filter(|f| !staged.contains(f))
                .cloned()
                .collect();
            if !self.swap_in(&staged, &earlier, &dropped)? {
                merge(&self.staging, &self.target)?;
                super::remove_folder(&self.staging)?;
                record_own_files(&self.target, Some(self.kind), &staged)?;
                remove_stale(&self.target, &dropped)?;
            }
        } else {
            record_own_files(&self.staging, Some(self.kind), &staged)?;
            super::rename(&self.staging, &self.target)?;
        }
        self.committed = true;
        Ok(())
    }

    /// Replaces the existing target folder by the staged one in one atomic exchange
    /// ([`super::folder_swap`]), keeping every file of the target but the `staged` ones it
    /// replaces and the `dropped` ones of rtr's `earlier` files. Returns false, with the
    /// target and the staged set untouched, where the file system cannot link or exchange;
    /// the caller then merges file by file.
    fn swap_in(
        &mut self,
        staged: &[PathBuf],
        earlier: &[PathBuf],
        dropped: &[PathBuf],
    ) -> Result<bool> {
        use super::folder_swap::{exchange, link_survivors, return_late_files, unlink_survivors};
        if self.target.is_symlink() {
            // Exchanging would replace the link, not the folder it names.
            return Ok(false);
        }
        let prepared = link_survivors(&self.target, &self.staging, staged, dropped, OWN_FILES)
            .and_then(|()| {
                record_own_files(&self.staging, Some(self.kind), staged)
                    .map_err(|e| std::io::Error::other(e.to_string()))
            })
            .and_then(|()| exchange(&self.staging, &self.target));
        if let Err(e) = prepared {
            unlink_survivors(&self.staging, staged).map_err(|e| Error::io(&self.staging, e))?;
            return match e.raw_os_error() {
                // No hard links or no exchange on this file system: merge instead.
                Some(libc::EXDEV | libc::EPERM | libc::EMLINK | libc::EINVAL | libc::ENOSYS)
                | Some(libc::ENOTSUP) => Ok(false),
                _ if e.kind() == std::io::ErrorKind::Unsupported => Ok(false),
                _ => Err(Error::io(&self.target, e)),
            };
        }
        // Published: from here on the staging path holds the earlier folder.
        self.committed = true;
        let stranded = return_late_files(&self.staging, &self.target, earlier, OWN_FILES)
            .map_err(|e| Error::io(&self.staging, e))?;
        if stranded.is_empty() {
            super::remove_folder(&self.staging)?;
            return Ok(true);
        }
        let kept = self.target.with_file_name(format!(
            "{}.earlier-{}",
            self.target
                .file_name()
                .unwrap_or_default()
                .to_string_lossy(),
            std::process::id()
        ));
        super::rename(&self.staging, &kept)?;
        Err(Error::InvalidArgument(format!(
            "{} was replaced by the new results, but {} written there meanwhile clashed with \
             them; the earlier folder, with those files, is kept as {}",
            self.target.display(),
            stranded.len(),
            kept.display()
        )))
    }
}

/// The file in a folder written through [`StagedFolder`] that lists the files of rtr's last
/// result set there, one path per line relative to the folder, after a `# kind` line naming
/// the command that wrote it (when it is a command's result set).
pub const OWN_FILES: &str = ".rtr-output";

/// Checks, before any work, that the command `kind` (`rtr eval`) may write its result set
/// into `target`: that rtr's earlier set there, if any, is of the same kind, and that none of
/// `names` (the set's top-level files and folders) is already there but not rtr's. So a
/// command refused at its end (see [`StagedFolder::commit`]) is refused at its start too, and
/// no hours of work are lost to it.
pub fn check_result_folder(target: &Path, kind: &str, names: &[&str]) -> Result<()> {
    if !target.is_dir() {
        return Ok(());
    }
    refuse_other_kind(target, kind)?;
    refuse_a_folder_of_the_users(target, kind)?;
    super::nested::refuse_nested_result_sets(target, kind)?;
    let earlier = own_files(target)?;
    let foreign: Vec<PathBuf> = names
        .iter()
        .map(PathBuf::from)
        .filter(|name| {
            let path = target.join(name);
            if path.is_dir() {
                // A folder of rtr's is one whose every file rtr wrote.
                relative_files(&path)
                    .is_ok_and(|files| files.iter().any(|f| !earlier.contains(&name.join(f))))
            } else {
                path.exists() && !earlier.contains(name)
            }
        })
        .collect();
    refuse_foreign(target, &foreign, &[])
}

/// Refuses a first result set into a folder holding files of the user's: publishing records
/// the folder as rtr's (`.rtr-output`), after which every other rtr output inside it is
/// refused as lying in another command's result set, so a working folder (a home, a project)
/// would silently become closed to rtr. A result set goes into a new or empty folder, or over
/// its own earlier set; result sets inside (a sweep's training runs) are rtr's own.
fn refuse_a_folder_of_the_users(target: &Path, kind: &str) -> Result<()> {
    if !matches!(recorded_kind(target)?, Kind::None) {
        return Ok(());
    }
    let users: Vec<String> = super::list_folder(target)?
        .iter()
        .filter(|p| {
            let name = p.file_name().map(|n| n.to_string_lossy().into_owned());
            !super::claim::is_bookkeeping(p)
                && !super::claim::is_result_set(p)
                && !name.is_some_and(|n| super::is_temporary_name(&n))
        })
        .map(|p| {
            let name = p.file_name().unwrap_or_default().to_string_lossy();
            if p.is_dir() {
                format!("{name}/")
            } else {
                name.into_owned()
            }
        })
        .collect();
    if users.is_empty() {
        return Ok(());
    }
    let shown: Vec<&str> = users.iter().take(5).map(String::as_str).collect();
    Err(Error::InvalidArgument(format!(
        "{} holds files rtr did not write ({}{}); `{kind}` writes its results into a folder of \
         their own (new, empty, or holding its earlier results), which rtr then keeps as a \
         whole. Choose a new folder",
        target.display(),
        shown.join(", "),
        if users.len() > shown.len() {
            format!(" and {} more", users.len() - shown.len())
        } else {
            String::new()
        }
    )))
}

/// Refuses when rtr's last result set in `target` came from another command than `kind`:
/// `rtr downstream` into an `rtr eval` folder would replace one study with another.
fn refuse_other_kind(target: &Path, kind: &str) -> Result<()> {
    let earlier = match recorded_kind(target)? {
        // A model or a training run: no record of rtr's results, but rtr's all the same.
        Kind::None if super::claim::is_result_set(target) => {
            "a model or a training run (policy.bpk or checkpoints/)".into()
        }
        Kind::None => return Ok(()),
        Kind::Command(earlier) if earlier == kind => return Ok(()),
        Kind::Command(earlier) => format!("the results of `{earlier}`"),
        Kind::Unnamed => "results of an earlier rtr that did not record its command".into(),
    };
    Err(Error::InvalidArgument(format!(
        "{} holds {earlier}; `{kind}` would replace them. Choose another folder, or move them \
         away",
        target.display()
    )))
}

/// What [`recorded_kind`] found.
enum Kind {
    /// No record: no result set of rtr's.
    None,
    Command(String),
    /// A record without a command line (written before rtr recorded it).
    Unnamed,
}

/// The command whose result set `dir` holds.
fn recorded_kind(dir: &Path) -> Result<Kind> {
    let record = dir.join(OWN_FILES);
    if !record.is_file() {
        return Ok(Kind::None);
    }
    let text = super::read_text(&record, super::Format::SceneList)?;
    Ok(
        match text.lines().next().and_then(|l| l.strip_prefix("# ")) {
            Some(kind) => Kind::Command(kind.to_string()),
            None => Kind::Unnamed,
        },
    )
}

/// Every file under `dir`, as paths relative to it, sorted.
fn relative_files(dir: &Path) -> Result<Vec<PathBuf>> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
        for path in super::list_folder(dir)? {
            if path.is_dir() {
                walk(root, &path, out)?;
            } else if let Ok(relative) = path.strip_prefix(root) {
                out.push(relative.to_path_buf());
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out)?;
    out.sort();
    Ok(out)
}

/// The files of rtr's last result set in `dir` ([`OWN_FILES`]); none if it has no record.
fn own_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let record = dir.join(OWN_FILES);
    if !record.is_file() {
        return Ok(Vec::new());
    }
    let text = super::read_text(&record, super::Format::SceneList)?;
    // Only paths inside the folder: a record edited to name `../x` or `/x` must not make rtr
    // replace or remove anything outside it.
    Ok(text
        .lines()
        .filter(|l| !l.is_empty() && !l.starts_with("# "))
        .map(PathBuf::from)
        .filter(|p| {
            p.components()
                .all(|c| matches!(c, std::path::Component::Normal(_)))
        })
        .collect())
}

fn record_own_files(dir: &Path, kind: Option<&str>, files: &[PathBuf]) -> Result<()> {
    let header = kind.map(|k| format!("# {k}\n")).unwrap_or_default();
    let text: String = files.iter().map(|f| format!("{}\n", f.display())).collect();
    super::atomic_write(&dir.join(OWN_FILES), (header + &text).as_bytes())
}

/// Refuses when a staged file would replace a file of `target` that is not in rtr's `earlier`
/// result set there: a file of the user's, or of an rtr too old to keep the record.
fn refuse_foreign(target: &Path, staged: &[PathBuf], earlier: &[PathBuf]) -> Result<()> {
    let foreign: Vec<String> = staged
        .iter()
        .filter(|f| target.join(f).exists() && !earlier.contains(f))
        .map(|f| target.join(f).display().to_string())
        .collect();
    if foreign.is_empty() {
        return Ok(());
    }
    Err(Error::InvalidArgument(format!(
        "{} already holds {} that rtr did not write there ({}); nothing was written. Move \
         them away or choose another folder",
        target.display(),
        if foreign.len() == 1 {
            "a file"
        } else {
            "files"
        },
        foreign.join(", ")
    )))
}

/// Removes the `dropped` files of rtr's earlier set, and the folders that leaves empty.
fn remove_stale(target: &Path, dropped: &[PathBuf]) -> Result<()> {
    for file in dropped {
        let path = target.join(file);
        super::remove_file(&path)?;
        for dir in path.ancestors().skip(1) {
            if dir == target || !dir.starts_with(target) {
                break;
            }
            if !super::list_folder(dir).is_ok_and(|entries| entries.is_empty()) {
                break;
            }
            super::remove_folder(dir)?;
        }
    }
    Ok(())
}

impl Drop for StagedFolder {
    fn drop(&mut self) {
        if self.committed {
            return;
        }
        let _ = std::fs::remove_dir_all(&self.staging);
        for dir in self.created.iter().rev() {
            // Only empty folders go: anything another process put there stays.
            let _ = std::fs::remove_dir(dir);
        }
    }
}

/// Creates `dir` and its missing ancestors; returns those it created, outermost first.
fn create_missing(dir: &Path) -> Result<Vec<PathBuf>> {
    let missing: Vec<PathBuf> = dir
        .ancestors()
        .take_while(|a| !a.as_os_str().is_empty() && !a.exists())
        .map(Path::to_path_buf)
        .collect();
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    Ok(missing.into_iter().rev().collect())
}

/// Every staged entry can land in `target`: no file onto a folder, no folder onto a file.
fn check_mergeable(staged: &Path, target: &Path) -> Result<()> {
    for entry in std::fs::read_dir(staged).map_err(|e| Error::io(staged, e))? {
        let entry = entry.map_err(|e| Error::io(staged, e))?;
        let from = entry.path();
        let to = target.join(entry.file_name());
        match (from.is_dir(), to.exists(), to.is_dir()) {
            (true, true, true) => check_mergeable(&from, &to)?,
            (true, true, false) => {
                return Err(Error::InvalidArgument(format!(
                    "{} is a file where a folder is to be written; nothing was written",
                    to.display()
                )));
            }
            (false, true, true) => {
                return Err(Error::InvalidArgument(format!(
                    "{} is a folder where a file is to be written; nothing was written",
                    to.display()
                )));
            }
            _ => {}
        }
    }
    Ok(())
}

/// Moves the entries of `staged` into `target`, folder by folder (each file by one rename):
/// the fallback where the folders cannot be exchanged in one step, so a run killed midway
/// leaves a mix there.
fn merge(staged: &Path, target: &Path) -> Result<()> {
    for entry in std::fs::read_dir(staged).map_err(|e| Error::io(staged, e))? {
        let entry = entry.map_err(|e| Error::io(staged, e))?;
        let from = entry.path();
        let to = target.join(entry.file_name());
        if from.is_dir() && to.is_dir() {
            merge(&from, &to)?;
        } else {
            std::fs::rename(&from, &to).map_err(|e| Error::io(&to, e))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .expect("list")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_failed_command_leaves_nothing() {
        let root = tempfile::tempdir().expect("temp dir");
        let target = root.path().join("a/b/out");
        let result: Result<()> = (|| {
            let staged = StagedFolder::new(&target, "rtr test")?;
            std::fs::write(staged.path().join("results.json"), b"{}")
                .map_err(|e| Error::io(staged.path(), e))?;
            Err(Error::InvalidArgument("a figure failed".into()))
        })();
        assert!(result.is_err());
        assert!(names(root.path()).is_empty(), "{:?}", names(root.path()));
    }

    #[test]
    fn an_error_while_filling_names_where_the_file_lands() {
        let root = tempfile::tempdir().expect("temp dir");
        let target = root.path().join("out");
        let staged = StagedFolder::new(&target, "rtr test").expect("stage");
        let full = || std::io::Error::from_raw_os_error(libc::ENOSPC);
        let err = staged
            .fill(|dir| -> Result<()> { Err(Error::io(dir.join("figures/a.svg"), full())) })
            .expect_err("failed")
            .to_string();
        let expected = target.join("figures/a.svg").display().to_string();
        assert!(err.starts_with(&expected), "{err}");
        let err = staged
            .fill(|dir| -> Result<()> {
                Err(Error::InvalidArgument(format!("{} is bad", dir.display())))
            })
            .expect_err("failed")
            .to_string();
        assert!(!err.contains(".rtr-"), "{err}");
        assert!(err.contains(&target.display().to_string()), "{err}");
        drop(staged);
        assert!(names(root.path()).is_empty(), "{:?}", names(root.path()));
    }

    #[test]
    fn a_model_or_a_training_run_is_no_other_commands_output() {
        let root = tempfile::tempdir().expect("temp dir");
        let model = root.path().join("model");
        std::fs::create_dir(&model).expect("mkdir");
        std::fs::write(model.join("policy.bpk"), b"weights").expect("write");
        let err = check_result_folder(&model, "rtr scenarios generate", &["train"])
            .expect_err("a model folder")
            .to_string();
        assert!(err.contains("a model or a training run"), "{err}");
    }

    #[test]
    fn commit_creates_or_merges_the_folder() {
        let root = tempfile::tempdir().expect("temp dir");
        let target = root.path().join("out");
        let staged = StagedFolder::new(&target, "rtr test").expect("stage");
        std::fs::create_dir(staged.path().join("figures")).expect("mkdir");
        std::fs::write(staged.path().join("figures/a.svg"), b"a").expect("write");
        assert_eq!(
            staged.final_path(&staged.path().join("figures/a.svg")),
            target.join("figures/a.svg")
        );
        staged.commit().expect("commit");
        // Into an existing folder: rtr's own files are replaced, the user's stay.
        std::fs::write(target.join("keep.txt"), b"k").expect("write");
        let staged = StagedFolder::new(&target, "rtr test").expect("stage");
        std::fs::create_dir(staged.path().join("figures")).expect("mkdir");
        std::fs::write(staged.path().join("figures/a.svg"), b"new").expect("write");
        std::fs::write(staged.path().join("table.md"), b"t").expect("write");
        staged.commit().expect("commit");
        assert_eq!(
            names(&target),
            [OWN_FILES, "figures", "keep.txt", "table.md"]
        );
        assert_eq!(
            std::fs::read(target.join("figures/a.svg")).expect("read"),
            b"new"
        );
        assert_eq!(names(root.path()), ["out"], "no staging folder is left");
    }

    #[test]
    fn an_earlier_result_set_leaves_nothing_beside_the_new_one() {
        let root = tempfile::tempdir().expect("temp dir");
        let target = root.path().join("out");
        let staged = StagedFolder::new(&target, "rtr test").expect("stage");
        std::fs::create_dir_all(staged.path().join("figures/old")).expect("mkdir");
        std::fs::write(staged.path().join("figures/old/a.svg"), b"a").expect("write");
        std::fs::write(staged.path().join("results.json"), b"1").expect("write");
        staged.commit().expect("commit");
        let staged = StagedFolder::new(&target, "rtr test").expect("stage");
        std::fs::write(staged.path().join("results.json"), b"2").expect("write");
        staged.commit().expect("commit");
        assert_eq!(names(&target), [OWN_FILES, "results.json"]);
        assert_eq!(
            std::fs::read(target.join("results.json")).expect("read"),
            b"2"
        );
    }

    #[test]
    fn what_a_killed_writer_left_is_removed_and_a_live_ones_is_not() {
        let root = tempfile::tempdir().expect("temp dir");
        // No process has pid 0x7ffffffe; pid 1 always runs.
        let dead = root.path().join(".rtr-tmp-staging-2147483646-0");
        let live = root.path().join(".rtr-tmp-tmp-1-0.json");
        std::fs::create_dir(&dead).expect("mkdir");
        std::fs::write(dead.join("results.json"), b"half").expect("write");
        std::fs::write(&live, b"busy").expect("write");
        let staged = StagedFolder::new(&root.path().join("out"), "rtr test").expect("stage");
        std::fs::write(staged.path().join("a.json"), b"{}").expect("write");
        staged.commit().expect("commit");
        assert!(!dead.exists(), "the killed writer's staging folder is gone");
        assert!(live.exists(), "a live writer's file stays");
    }

    #[test]
    fn a_file_rtr_did_not_write_is_never_replaced() {
        let root = tempfile::tempdir().expect("temp dir");
        let target = root.path().join("out");
        std::fs::create_dir(&target).expect("mkdir");
        std::fs::write(target.join("table.md"), b"mine").expect("write");
        let staged = StagedFolder::new(&target, "rtr test").expect("stage");
        std::fs::write(staged.path().join("table.md"), b"t").expect("write");
        std::fs::write(staged.path().join("results.json"), b"{}").expect("write");
        let err = staged.commit().expect_err("the user's table.md");
        assert!(err.to_string().contains("did not write"), "{err}");
        assert_eq!(names(&target), ["table.md"]);
        assert_eq!(
            std::fs::read(target.join("table.md")).expect("read"),
            b"mine"
        );
        assert_eq!(names(root.path()), ["out"], "no staging folder is left");
    }

    #[test]
    fn a_record_reaches_nothing_outside_its_folder_and_another_commands_set_is_kept() {
        let root = tempfile::tempdir().expect("temp dir");
        let target = root.path().join("out");
        std::fs::create_dir(&target).expect("mkdir");
        let outside = root.path().join("victim.txt");
        std::fs::write(&outside, b"keep").expect("write");
        let record = format!("# rtr test\n../victim.txt\n{}\n", outside.display());
        std::fs::write(target.join(OWN_FILES), record).expect("write");
        let staged = StagedFolder::new(&target, "rtr test").expect("stage");
        std::fs::write(staged.path().join("a.json"), b"{}").expect("write");
        staged.commit().expect("commit");
        assert_eq!(std::fs::read(&outside).expect("read"), b"keep");
        // Another command's results there are refused, at the start and at the end.
        let err = check_result_folder(&target, "rtr other", &["a.json"]).expect_err("kind");
        assert!(
            err.to_string().contains("holds the results of `rtr test`"),
            "{err}"
        );
        let staged = StagedFolder::new(&target, "rtr other").expect("stage");
        std::fs::write(staged.path().join("b.json"), b"{}").expect("write");
        assert!(staged.commit().is_err());
        assert_eq!(names(&target), [OWN_FILES, "a.json"]);
    }

    #[test]
    fn a_conflict_is_refused_before_anything_moves() {
        let root = tempfile::tempdir().expect("temp dir");
        let target = root.path().join("out");
        std::fs::create_dir(&target).expect("mkdir");
        std::fs::write(target.join("figures"), b"a file").expect("write");
        let staged = StagedFolder::new(&target, "rtr test").expect("stage");
        std::fs::write(staged.path().join("results.json"), b"{}").expect("write");
        std::fs::create_dir(staged.path().join("figures")).expect("mkdir");
        let err = staged.commit().expect_err("figures is a file");
        assert!(err.to_string().contains("figures"), "{err}");
        assert_eq!(names(&target), ["figures"]);
        assert_eq!(names(root.path()), ["out"]);
    }
}
