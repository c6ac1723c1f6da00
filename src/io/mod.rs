//! File input and output shared by every module. Output is atomic: results, checkpoints and
//! pictures are written to a temporary file in the destination's folder and renamed into
//! place, so a crash never leaves a half file; a command's several files are staged together
//! ([`StagedFolder`]). TOML input errors name the line and column.

mod staged;

use std::path::{Path, PathBuf};

pub use staged::StagedFolder;

use crate::error::{Error, Result};

/// A temporary sibling of `path` that keeps its extension (some writers pick the format from
/// it).
fn temp_sibling(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.tmp.{name}", std::process::id()))
}

/// Calls `write` with a temporary path next to `path`, then renames it onto `path`. On error
/// the temporary file is removed and `path` is left as it was.
pub fn atomic_write_with(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let tmp = temp_sibling(path);
    let result =
        write(&tmp).and_then(|()| std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e)));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes `bytes` to `path` atomically.
pub fn atomic_write(path: &Path, bytes: &[u8]) -> Result<()> {
    atomic_write_with(path, |tmp| {
        std::fs::write(tmp, bytes).map_err(|e| Error::io(tmp, e))
    })
}

/// Checks that the input `path` given with `flag` is a file, so a folder or a missing path is
/// refused naming the option rather than with the operating system's bare message.
pub fn check_input_file(path: &Path, flag: &str) -> Result<()> {
    let why = match path.metadata() {
        Ok(m) if m.is_dir() => "is a folder; expected a file",
        Ok(_) => return Ok(()),
        Err(_) => "no such file",
    };
    Err(Error::InvalidArgument(format!(
        "{flag} {}: {why}",
        path.display()
    )))
}

/// What an output path must be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputKind {
    File,
    Folder,
}

/// Checks, before any work, that `path` can be written as `kind`: it is not the other kind,
/// nothing on its way is a file, and its nearest existing folder accepts a new file (probed
/// with a file created and removed at once). `flag` names the option in the error. Leaves the
/// file system as it was, so a command refused here has written nothing.
pub fn check_output(path: &Path, kind: OutputKind, flag: &str) -> Result<()> {
    let fail = |why: String| {
        Err(Error::InvalidArgument(format!(
            "{flag} {}: {why}",
            path.display()
        )))
    };
    match (path.metadata(), kind) {
        (Ok(m), OutputKind::File) if m.is_dir() => {
            return fail("is a folder; expected a file path".into());
        }
        (Ok(m), OutputKind::Folder) if !m.is_dir() => {
            return fail("is a file; expected a folder".into());
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
        .find(|a| a.exists());
    let Some(folder) = existing else {
        return fail("no part of the path exists".into());
    };
    if !folder.is_dir() {
        return fail(format!(
            "{} is a file, so nothing can be written under it",
            folder.display()
        ));
    }
    let probe = folder.join(format!(".rtr-write-probe.{}", std::process::id()));
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

/// Reads a text file; bytes that are not UTF-8 are an error naming the line and column where
/// they start (a binary or Latin-1 file given by mistake), not a bare "invalid UTF-8".
pub fn read_text(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    utf8_text(bytes, &path.display().to_string())
}

/// `bytes` as text, or an error naming `source_name` and the line and column of the first
/// byte that is not UTF-8.
pub fn utf8_text(bytes: Vec<u8>, source_name: &str) -> Result<String> {
    String::from_utf8(bytes).map_err(|e| {
        let valid = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        // Everything before `valid` is UTF-8, so it can be counted as text.
        let before = std::str::from_utf8(&bytes[..valid]).unwrap_or_default();
        let (line, column) = line_column(before, before.len());
        Error::Parse {
            source_name: source_name.to_string(),
            line,
            column,
            message: format!(
                "byte 0x{:02x} is not UTF-8 text; expected a UTF-8 text file",
                bytes[valid]
            ),
        }
    })
}

/// Parses a TOML document; errors name `source_name` and the 1-based line and column.
pub fn parse_toml<T: serde::de::DeserializeOwned>(text: &str, source_name: &str) -> Result<T> {
    toml::from_str(text).map_err(|e| {
        let (line, column) = e
            .span()
            .map(|span| line_column(text, span.start))
            .unwrap_or((0, 0));
        Error::Parse {
            source_name: source_name.to_string(),
            line,
            column,
            message: e.message().to_string(),
        }
    })
}

/// 1-based line and column of byte `offset` in `text`.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.chars().rev().take_while(|&c| c != '\n').count() + 1;
    (line, column)
}

#[cfg(test)]
mod tests {
    use super::*;

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
