//! serde_json's errors as rtr reports them: the position in its own fields (serde_json also
//! appends it to the message, which would show it twice), and the key being read where the
//! line holds one.

use crate::error::Error;

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
    let about_a_field = ["missing field", "unknown field", "duplicate field"]
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
        let e = serde_json::from_str::<Vec<f64>>("[1, NaN]").expect_err("no NaN");
        let shown = json_error("v.json", None, &e).to_string();
        assert!(shown.contains("JSON has no NaN"), "{shown}");
    }
}
