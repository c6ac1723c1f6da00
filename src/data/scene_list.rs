//! A list of scene ids in a text file: one id per line, `#` starts a comment line, blank lines
//! are skipped. `rtr curate` writes one (the nominal training scenes a policy fails on) and a
//! run file's `data.curated` reads it.

use std::collections::HashSet;
use std::path::Path;

use crate::error::{Error, Result};

/// Reads the ids of `path`, in file order. A repeated id or a file with no id is an error
/// naming the file (and the line).
pub fn read_scene_list(path: &Path) -> Result<Vec<String>> {
    let text = crate::io::read_text(path, crate::io::Format::SceneList)?;
    parse_scene_list(&text, &path.display().to_string())
}

/// Parses the text of a scene list; `source_name` names it in errors.
pub fn parse_scene_list(text: &str, source_name: &str) -> Result<Vec<String>> {
    let mut seen = HashSet::new();
    let mut ids = Vec::new();
    for (k, line) in text.lines().enumerate() {
        let id = line.trim();
        if id.is_empty() || id.starts_with('#') {
            continue;
        }
        if id.split_whitespace().count() > 1 {
            return Err(Error::invalid(
                source_name,
                format!("line {}", k + 1),
                format!("expected one scene id per line, found `{id}`"),
            ));
        }
        if !seen.insert(id.to_string()) {
            return Err(Error::invalid(
                source_name,
                format!("line {}", k + 1),
                format!("scene `{id}` is listed twice"),
            ));
        }
        ids.push(id.to_string());
    }
    if ids.is_empty() {
        return Err(Error::invalid(
            source_name,
            "the list",
            "expected at least one scene id",
        ));
    }
    Ok(ids)
}

/// A scene list as an output: a `.txt` or `.list` file that reads as one.
pub const SCENE_LIST: crate::io::FileKind = crate::io::FileKind {
    name: "a scene list",
    extensions: &["txt", "list"],
    recognise: reads_as_scene_list,
};

/// Whether `head`, a file's first bytes, reads as a scene list (its last line may be cut).
fn reads_as_scene_list(head: &[u8]) -> bool {
    let Ok(text) = std::str::from_utf8(head).or_else(|e| {
        // A cut through a multi-byte character at the end of the head.
        std::str::from_utf8(&head[..e.valid_up_to()])
    }) else {
        return false;
    };
    let whole_lines = match text.rfind('\n') {
        Some(end) if head.len() >= crate::io::RECOGNISED_BYTES => &text[..end],
        _ => text,
    };
    parse_scene_list(whole_lines, "").is_ok()
}

/// Writes `ids` to `path` atomically, after `header` as `#` comment lines.
pub fn write_scene_list(path: &Path, header: &str, ids: &[String]) -> Result<()> {
    let mut text: String = header.lines().map(|l| format!("# {l}\n")).collect();
    for id in ids {
        text.push_str(id);
        text.push('\n');
    }
    crate::io::atomic_write(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_keeps_order_and_skips_comments() {
        let dir = std::env::temp_dir().join(format!("rtr-scene-list-{}", std::process::id()));
        let path = dir.join("list.txt");
        let ids = vec!["a9-0120.0".to_string(), "a9-0003.5".to_string()];
        write_scene_list(&path, "failing scenes\nof models/il", &ids).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.starts_with("# failing scenes\n# of models/il\n"),
            "{text}"
        );
        assert_eq!(read_scene_list(&path).unwrap(), ids);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse_scene_list("# c\na\n\nb\na\n", "list.txt").unwrap_err();
        let e = e.to_string();
        assert!(
            e.contains("list.txt") && e.contains("line 5") && e.contains("twice"),
            "{e}"
        );
        let e = parse_scene_list("a b\n", "list.txt")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 1") && e.contains("one scene id"), "{e}");
        let e = parse_scene_list("# only a comment\n", "list.txt").unwrap_err();
        assert!(e.to_string().contains("at least one"), "{e}");
    }
}
