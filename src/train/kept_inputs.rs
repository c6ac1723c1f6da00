//! A run keeps a copy of the small files it reads (its dynamics file, its curated scene
//! list) in `inputs/`, named by field and content digest. A run's identity includes their
//! contents, so once another command replaces one at its path (a `sim2real` re-run into the
//! same folder, a `curate` onto the same list) the run can neither resume nor be evaluated;
//! with the copy the message can say how to put the file back instead of asking for a file
//! that is gone.

use std::path::{Path, PathBuf};

use crate::data::automatum::sha256_hex;
use crate::error::Result;
use crate::io::Format;

use super::config::TrainConfig;

/// The run's sub-folder of kept inputs.
pub const KEPT_FOLDER: &str = "inputs";

/// The fields whose file is kept, with its read cap: settings-sized files. (Scenario folders,
/// clips and policies can be large; they are identified by digest only.)
const KEPT_FIELDS: [(&str, Format); 2] = [
    ("dynamics", Format::Settings),
    ("data.curated", Format::SceneList),
];

/// Digits of the sha256 in a kept file's name.
const NAME_DIGITS: usize = 16;

/// Copies each kept input of `config` into `run_dir/inputs/` (once per content).
pub fn keep(run_dir: &Path, config: &TrainConfig) -> Result<()> {
    for (field, path) in config.input_paths() {
        let Some((_, format)) = KEPT_FIELDS.iter().find(|(f, _)| *f == field) else {
            continue;
        };
        let bytes = crate::io::read_bytes(&path, *format).map_err(|e| e.in_field(field))?;
        let kept = run_dir
            .join(KEPT_FOLDER)
            .join(kept_name(field, &sha256_hex(&bytes), &path));
        if !kept.is_file() {
            crate::io::create_folder(&run_dir.join(KEPT_FOLDER))?;
            crate::io::atomic_write(&kept, &bytes)?;
        }
    }
    Ok(())
}

/// `dynamics-<digest>.toml`: the field, the first digits of the content's sha256, and the
/// original's extension.
fn kept_name(field: &str, digest: &str, original: &Path) -> String {
    let extension = original
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    format!(
        "{}-{}{extension}",
        field.replace('.', "_"),
        &digest[..NAME_DIGITS.min(digest.len())]
    )
}

/// The copy `run_dir` kept of `field`'s file as it was when its digest was `digest`.
pub fn kept_copy(run_dir: &Path, field: &str, digest: &str) -> Option<PathBuf> {
    let prefix = kept_name(field, digest, Path::new(""));
    crate::io::list_folder(&run_dir.join(KEPT_FOLDER))
        .ok()?
        .into_iter()
        .find(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with(&prefix))
        })
}

/// How to put `field`'s file at `path` back as the run read it (digest `then`), or how to
/// go on without it.
pub fn restore_hint(run_dir: &Path, field: &str, then: &str, path: &Path) -> String {
    match kept_copy(run_dir, field, then) {
        Some(copy) => format!(
            "the run kept what it read: `cp {} {}` restores it",
            copy.display(),
            path.display()
        ),
        None => "restore the file".to_string(),
    }
}

/// Whether `folder` is a run's own `inputs/`: every file in it named by its content's
/// digest, as [`keep`] writes them.
pub fn is_kept_folder(folder: &Path) -> bool {
    let Ok(files) = crate::io::list_folder(folder) else {
        return false;
    };
    files.iter().all(|file| {
        let Some(name) = file.file_name().map(|n| n.to_string_lossy().into_owned()) else {
            return false;
        };
        let Ok(bytes) = crate::io::read_bytes(file, Format::Settings) else {
            return false;
        };
        let digest = sha256_hex(&bytes);
        KEPT_FIELDS
            .iter()
            .any(|(field, _)| name.starts_with(&kept_name(field, &digest, Path::new(""))))
    })
}
