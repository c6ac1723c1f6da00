//! Every file rtr reads or writes, and its standard output, goes through this module: one
//! way in ([`input`]: regular files only, capped sizes, errors that name the file and line),
//! one way out ([`output`], [`StagedFolder`]: atomic, checked, all or nothing) and a console
//! that a closed pipe cannot crash ([`console`]). `tests/structure.rs` keeps every other
//! module off `std::fs` and the printing macros.

mod claim;
pub mod console;
mod folder_swap;
mod input;
mod json_error;
mod nested;
mod output;
mod output_tree;
mod process_files;
mod staged;
mod toml_field;

pub use claim::{
    FileKind, Inputs, OutputClaim, RECOGNISED_BYTES, claim_output_file, claim_output_folder,
    is_bookkeeping, release_locks_on_signal, resolved,
};
pub use input::{
    Capped, Format, capped, check_input_file, check_input_folder, check_input_path, check_size,
    files_in_tree, list_folder, not_regular, open_regular, read_bytes, read_error, read_lines,
    read_text, utf8_text,
};
pub use json_error::{json_error, parse_json, parse_json_reader};
pub use nested::SWEEP_KIND;
pub use output::{
    atomic_write, atomic_write_all, atomic_write_with, create_file, create_folder,
    is_temporary_name, remove_file, remove_folder, rename, write_new,
};
pub(crate) use output::{remove_stale_temporaries, temp_name};
pub use process_files::{read_process_file, write_process_file};
pub use staged::{StagedFolder, check_result_folder};
pub use toml_field::field_error;

use crate::error::{Error, Result};

/// Parses a TOML document; errors name `source_name` and the 1-based line and column.
pub fn parse_toml<T: serde::de::DeserializeOwned>(text: &str, source_name: &str) -> Result<T> {
    toml::from_str(text).map_err(|e| {
        let (line, column) = e
            .span()
            .map(|span| line_column(text, span.start))
            .unwrap_or((0, 0));
        let (mut line, mut column) = (line, column);
        let mut message = plain_words(e.message());
        // An empty span is the document itself (a missing top-level key): no table to blame.
        let in_a_table = e.span().is_some_and(|span| !span.is_empty());
        if let Some((header_line, hint)) = table_kind_hint::<T>(text, line).filter(|_| in_a_table) {
            // serde's own words describe the misread, not the mistake, which is the header.
            (line, column, message) = (header_line, 1, hint);
        } else if message.starts_with("duplicate key")
            && let Some(span) = e.span()
        {
            let key = text[span].trim().trim_matches(['[', ']']);
            message = format!("`{key}` is defined twice; expected each key and table once");
        } else if let Some(key) = key_on_line(text, line).filter(|_| in_a_table) {
            // A value of the wrong type for a field of fixed names: list them.
            if let Some(names) = variant_names::<T>(text, line, key)
                && let Some(at) = message.find("expected ")
            {
                message.truncate(at);
                message.push_str(&format!("{names}, as a quoted string"));
            }
            if !message.contains(&format!("`{key}`")) {
                message = format!("`{key}`: {message}");
            }
        }
        Error::Parse {
            source_name: source_name.to_string(),
            line,
            column,
            message,
        }
    })
}

/// The key of a `key = value` line (1-based `line`), if it is one.
fn key_on_line(text: &str, line: usize) -> Option<&str> {
    let (key, _) = text.lines().nth(line.checked_sub(1)?)?.split_once('=')?;
    let key = key.trim();
    let bare = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '"');
    (!key.is_empty() && key.chars().all(bare)).then_some(key)
}

/// The names an enum field accepts (`expected ...`), as serde lists them for a name it does
/// not know: the document is parsed again with the field's value replaced by such a name. For
/// a value of the wrong type (`method = 5`) serde says only that it wanted a name.
fn variant_names<T: serde::de::DeserializeOwned>(
    text: &str,
    line: usize,
    key: &str,
) -> Option<String> {
    let probe = format!("{key} = \"?\"");
    let rewritten: Vec<&str> = text
        .lines()
        .enumerate()
        .map(|(i, l)| if i + 1 == line { probe.as_str() } else { l })
        .collect();
    let e = toml::from_str::<T>(&rewritten.join("\n")).err()?;
    let message = e.message();
    message.contains("unknown variant").then_some(())?;
    // "expected `a` or `b`", "expected one of `a`, `b`, `c`".
    let (_, names) = message.split_once("expected ")?;
    Some(format!("expected {}", names.trim()))
}

/// A `[[name]]` header makes `name` a list of tables and `[name]` one table; written the
/// wrong way round, serde reads one as the other and complains about something unrelated.
/// When the error at `line` lies under such a header written once, and with the other
/// bracketing the document gets past that line (parses, or fails only further down), say so.
/// Returns the header's 1-based line with the hint.
fn table_kind_hint<T: serde::de::DeserializeOwned>(
    text: &str,
    line: usize,
) -> Option<(usize, String)> {
    let lines: Vec<&str> = text.lines().collect();
    let (index, header) = lines
        .get(..line.min(lines.len()))?
        .iter()
        .enumerate()
        .rev()
        .map(|(i, l)| (i, l.trim()))
        .find(|(_, l)| l.starts_with('['))?;
    let (name, other, what) = match header.strip_prefix("[[").and_then(|h| h.strip_suffix("]]")) {
        Some(name) => (
            name.trim(),
            format!("[{}]", name.trim()),
            "a list of tables, but it is one section",
        ),
        None => {
            let name = header.strip_prefix('[')?.strip_suffix(']')?.trim();
            (
                name,
                format!("[[{name}]]"),
                "one table, but it is a list (one table per entry)",
            )
        }
    };
    if lines.iter().filter(|l| l.trim() == header).count() != 1 {
        return None;
    }
    let rewritten: Vec<String> = lines
        .iter()
        .map(|l| match l.trim() == header {
            true => other.clone(),
            false => l.to_string(),
        })
        .collect();
    let rewritten = rewritten.join("\n");
    let past = match toml::from_str::<T>(&rewritten) {
        Ok(_) => true,
        Err(e) => e
            .span()
            .is_some_and(|span| line_column(&rewritten, span.start).0 > line),
    };
    past.then(|| {
        (
            index + 1,
            format!("`{header}` makes `{name}` {what}: write `{other}`"),
        )
    })
}

/// serde's names for Rust number types, in words: shared by the TOML and JSON messages.
const NUMBER_WORDS: [(&str, &str); 10] = [
    // serde_json and toml read a number too large for 64 bits as a 128-bit one.
    (" as i128", ""),
    (" as u128", ""),
    (
        "expected usize",
        "expected a whole number from 0 to 18446744073709551615",
    ),
    (
        "expected u64",
        "expected a whole number from 0 to 18446744073709551615",
    ),
    (
        "expected u32",
        "expected a whole number from 0 to 4294967295",
    ),
    ("expected u8", "expected a whole number from 0 to 255"),
    ("expected i64", "expected a whole number"),
    ("expected i32", "expected a whole number"),
    ("expected f64", "expected a number"),
    ("expected f32", "expected a number"),
];

/// `message` with serde's "invalid type" and number type names in words.
pub fn number_words(message: &str) -> String {
    let text = message.replacen("invalid type: ", "found ", 1);
    NUMBER_WORDS
        .iter()
        .fold(text, |text, (rust, plain)| text.replace(rust, plain))
}

/// serde's names for Rust types ("invalid type: string \"x\", expected usize") in the words
/// of the file's format, so a message says what to write rather than how it is stored.
fn plain_words(message: &str) -> String {
    let mut text = number_words(message);
    for (rust, plain) in [
        ("expected a sequence", "expected a list [ ... ]"),
        ("expected a map", "expected a table"),
        ("found map", "found a table"),
        ("found sequence", "found a list"),
        (
            "wanted string or table",
            "expected one of its names, as a quoted string",
        ),
        ("expected an array of length", "expected a list of length"),
    ] {
        text = text.replace(rust, plain);
    }
    // "expected struct RunConfig": the section's own name is in the line the error points at.
    if let Some(at) = text.find("expected struct ") {
        text.truncate(at);
        text.push_str("expected a table");
    }
    text
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

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Run {
        backend: Option<String>,
        checkpoint_every: Option<usize>,
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Clip {
        path: String,
        weight: f64,
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct File {
        #[serde(default)]
        seed: u64,
        #[serde(default)]
        run: Option<Run>,
        #[serde(default)]
        clips: Vec<Clip>,
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct WithMethod {
        method: String,
        #[serde(default)]
        run: Option<Backend>,
    }

    /// Like the run file's `[run]`: a struct whose first field is an enum, which serde also
    /// reads from a list (by position), so `[[run]]` fails further down than `[run]`.
    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Backend {
        backend: Kind,
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(rename_all = "lowercase")]
    #[allow(dead_code)]
    enum Kind {
        Ndarray,
        Flex,
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Dynamics {
        terms: Vec<Clip>,
    }

    #[test]
    fn a_list_written_as_one_table_and_a_key_twice_are_named_as_such() {
        let err = parse_toml::<Dynamics>("[terms]\npath = \"a\"\nweight = 1.0\n", "d.toml")
            .expect_err("one table where a list belongs");
        assert!(err.to_string().contains("write `[[terms]]`"), "{err}");
        let err = parse_toml::<File>("[run]\n[run]\n", "run.toml").expect_err("twice");
        assert!(err.to_string().contains("`run` is defined twice"), "{err}");
    }

    #[test]
    fn a_section_written_as_a_list_of_tables_is_named_as_such() {
        let err = parse_toml::<File>("\n[[run]]\ncheckpoint_every = 2\n", "run.toml")
            .expect_err("a list where one section belongs");
        assert!(err.to_string().contains("write `[run]`"), "{err}");
        assert!(
            err.to_string().contains("line 2, column 1"),
            "the header's line: {err}"
        );
        // A missing key of the file's top level is that, whatever header comes first.
        let text = "[run]\nbackend = \"ndarray\"\n";
        let err = parse_toml::<WithMethod>(text, "run.toml").expect_err("no method");
        assert!(err.to_string().contains("missing field `method`"), "{err}");
        assert!(!err.to_string().contains("write `["), "{err}");
        // A real list with a wrong value inside gets serde's message alone.
        let err = parse_toml::<File>("[[clips]]\npath = \"a\"\nweight = \"x\"\n", "run.toml")
            .expect_err("a string weight");
        assert!(!err.to_string().contains("write `["), "{err}");
        assert!(err.to_string().contains("line 3"), "{err}");
    }

    #[test]
    fn wrong_value_types_are_named_in_the_file_format_words() {
        let cases = [
            (
                "[run]\ncheckpoint_every = \"x\"\n",
                "expected a whole number from 0 to 18446744073709551615",
            ),
            // Too large for 64 bits: the limit, not the 128-bit type it was read as.
            (
                "seed = 18446744073709551616\n",
                "found integer `18446744073709551616`, expected a whole number from 0 to",
            ),
            (
                "[[clips]]\npath = \"a\"\nweight = \"x\"\n",
                "expected a number",
            ),
            ("clips = 3\n", "expected a list [ ... ]"),
            ("run = 3\n", "expected a table"),
        ];
        for (text, words) in cases {
            let err = parse_toml::<File>(text, "run.toml").expect_err(text);
            let message = err.to_string();
            assert!(message.contains(words), "{text:?}: {message}");
            for rust in ["usize", "f64", "i128", "sequence", "struct "] {
                assert!(!message.contains(rust), "{text:?}: {message}");
            }
        }
        // A field of fixed names given a number: the field is named and its names listed.
        let err = parse_toml::<WithMethod>("method = \"x\"\n[run]\nbackend = 5\n", "run.toml")
            .expect_err("a number for a name");
        let message = err.to_string();
        assert!(message.contains("`backend`"), "{message}");
        assert!(message.contains("`ndarray` or `flex`"), "{message}");
    }
}
