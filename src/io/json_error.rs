//! serde_json's errors as rtr reports them: the position in its own fields (serde_json also
//! appends it to the message, which would show it twice), and the path of the value at fault
//! (`agents[2].position`), or the key being read where the line holds one.

use crate::error::{Error, Result};

/// Reads the JSON document `text` (named `source` in errors) as a `T`. An error names the
/// path of the value at fault from the document's root (`agents[2].position: invalid length
/// 3, expected 2 elements`): serde_json's own position is where it noticed, which for an
/// array of the wrong length is its closing bracket, far from any key.
pub fn parse_json<T: serde::de::DeserializeOwned>(text: &str, source: &str) -> Result<T> {
    deserialize(serde_json::Deserializer::from_str(text), source, Some(text))
}

/// [`parse_json`] of a stream (a decompressed file too large to hold as text twice).
pub fn parse_json_reader<T: serde::de::DeserializeOwned>(
    reader: impl std::io::Read,
    source: &str,
) -> Result<T> {
    deserialize(serde_json::Deserializer::from_reader(reader), source, None)
}

fn deserialize<'de, R: serde_json::de::Read<'de>, T: serde::de::DeserializeOwned>(
    mut reader: serde_json::Deserializer<R>,
    source: &str,
    text: Option<&str>,
) -> Result<T> {
    let value = serde_path_to_error::deserialize(&mut reader).map_err(|e| {
        let path = e.path().to_string();
        let error = json_error(source, text, e.inner());
        if path == "." {
            return error;
        }
        with_path(error, &path)
    })?;
    reader.end().map_err(|e| json_error(source, text, &e))?;
    Ok(value)
}

/// `error`'s message led by `path` in place of the key [`json_error`] found on the line.
fn with_path(error: Error, path: &str) -> Error {
    let Error::Parse {
        source_name,
        line,
        column,
        message,
    } = error
    else {
        return error;
    };
    let message = match message.strip_prefix('`').and_then(|m| m.split_once("`: ")) {
        Some((_, rest)) => rest.to_string(),
        None => message,
    };
    // serde_json says this of a fixed-length array given more elements than it holds.
    let message = if message.starts_with("text after the end") {
        "more elements than this array holds".to_string()
    } else {
        message
    };
    Error::Parse {
        source_name,
        line,
        column,
        message: format!("`{path}`: {message}"),
    }
}

/// The error `e` of reading the JSON `source`; `text`, when at hand, lets the message name
/// the key of the value at fault (`"dt": "half"` -> `dt: invalid type ...`).
pub fn json_error(source: &str, text: Option<&str>, e: &serde_json::Error) -> Error {
    let mut message = e.to_string();
    if let Some(cut) = message.rfind(" at line ") {
        message.truncate(cut);
    }
    message = super::number_words(&message);
    if message.starts_with("expected value") {
        message.push_str(" (a number, string, array or object; JSON has no NaN or Infinity)");
    }
    // A field missing, unknown or repeated is the object's fault, and the message names the
    // field; the key before the position belongs to a value read without fault.
    // Text after the document is no value's fault either.
    if message == "trailing characters" {
        message = "text after the end of the JSON value (trailing characters)".to_string();
    }
    let about_a_field = [
        "missing field",
        "unknown field",
        "duplicate field",
        "text after the end",
    ]
    .iter()
    .any(|p| message.starts_with(p));
    if !about_a_field && let Some(key) = text.and_then(|t| key_before(t, e.line(), e.column())) {
        message = format!("`{key}`: {message}");
    }
    Error::Parse {
        source_name: source.to_string(),
        line: e.line(),
        column: e.column(),
        message,
    }
}

/// The last `"key":` on the 1-based `line` of `text` before `column`. None where the
/// position closes an object or a list: serde reads some objects whole (a tagged one) and
/// reports a value's error at their end, after keys that are not at fault.
fn key_before(text: &str, line: usize, column: usize) -> Option<String> {
    let row = text.lines().nth(line.checked_sub(1)?)?;
    let head = row.get(..column.min(row.len()))?;
    if head.trim_end().ends_with(['}', ']']) || head.trim().is_empty() {
        return None;
    }
    let colon = head.rfind("\":")?;
    let open = head[..colon].rfind('"')?;
    Some(head[open + 1..colon].to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_position_is_said_once_and_the_key_named() {
        let text = "{\n  \"dt\": \"half\"\n}";
        let e = serde_json::from_str::<std::collections::BTreeMap<String, f64>>(text)
            .expect_err("not a number");
        let shown = json_error("s.json", Some(text), &e).to_string();
        assert!(shown.starts_with("s.json: line 2, column"), "{shown}");
        assert!(
            shown.contains("`dt`: found string \"half\", expected a number"),
            "{shown}"
        );
        assert_eq!(shown.matches("line 2").count(), 1, "{shown}");
        #[derive(Debug, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct Two {
            index: usize,
            description: String,
        }
        for (text, expected) in [
            (r#"{"index": 1, "bogus": 2}"#, "unknown field `bogus`"),
            (r#"{"index": 1}"#, "missing field `description`"),
        ] {
            let e = serde_json::from_str::<Two>(text).expect_err("refused");
            let shown = json_error("c.json", Some(text), &e).to_string();
            assert!(
                shown.contains(expected) && !shown.contains("`index`: "),
                "{shown}"
            );
        }
        // An array of the wrong length is noticed at its closing bracket, far from its key:
        // the path names it.
        #[derive(Debug, serde::Deserialize)]
        #[allow(dead_code)]
        struct Agent {
            position: [f64; 2],
        }
        #[derive(Debug, serde::Deserialize)]
        #[allow(dead_code)]
        struct Scene {
            agents: Vec<Agent>,
        }
        let text =
            "{\"agents\": [\n {\"position\": [1, 2]},\n {\"position\": [\n  1, 2, 3\n ]}\n]}";
        let shown = parse_json::<Scene>(text, "s.json")
            .expect_err("three numbers")
            .to_string();
        assert!(
            shown.contains("`agents[1].position`: more elements than this array holds"),
            "{shown}"
        );
        let shown = parse_json::<Scene>(&text.replace("1, 2, 3", "1"), "s.json")
            .expect_err("one number")
            .to_string();
        assert!(
            shown.contains("`agents[1].position`: invalid length 1"),
            "{shown}"
        );
        let shown = parse_json::<Scene>("{\"agents\": [{}]}", "s.json")
            .expect_err("no position")
            .to_string();
        assert!(
            shown.contains("`agents[0]`: missing field `position`"),
            "{shown}"
        );
        let shown = parse_json::<Scene>("{\"agents\": []} x", "s.json")
            .expect_err("trailing characters")
            .to_string();
        assert!(shown.contains("trailing characters"), "{shown}");
        let e = serde_json::from_str::<Vec<f64>>("[1, NaN]").expect_err("no NaN");
        let shown = json_error("v.json", None, &e).to_string();
        assert!(shown.contains("JSON has no NaN"), "{shown}");
    }
}
