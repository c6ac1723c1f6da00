//! A bounded walk of the tree under an output folder, for the checks that must see what lies
//! inside before publishing there (a live writer, another result set). Deep enough for any
//! rtr layout (a sweep's point's checkpoints), bounded so a `--out` naming a large tree is
//! not walked whole. Links are not followed: what a link leads to is not inside.

use std::path::Path;

use crate::error::Result;

const MAX_DEPTH: usize = 8;
const MAX_ENTRIES: usize = 200_000;

/// Calls `visit(path, is_folder)` for the entries under `root`, descending into a folder
/// when `visit` returns `Ok(true)` for it; stops at the first error.
pub fn walk(root: &Path, mut visit: impl FnMut(&Path, bool) -> Result<bool>) -> Result<()> {
    let mut pending = vec![(root.to_path_buf(), 0usize)];
    let mut seen = 0usize;
    while let Some((dir, depth)) = pending.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten() {
            seen += 1;
            if seen > MAX_ENTRIES {
                return Ok(());
            }
            let path = entry.path();
            let is_folder = entry.file_type().is_ok_and(|t| t.is_dir());
            if visit(&path, is_folder)? && is_folder && depth < MAX_DEPTH {
                pending.push((path, depth + 1));
            }
        }
    }
    Ok(())
}
