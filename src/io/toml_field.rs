//! Where a settings file sets a field: a value refused after parsing (a learning rate of -1)
//! is reported at its line with the value found, as a syntax error is.

use crate::error::Error;

/// The 1-based line and the value text of the `key = value` line that sets the dotted
/// `field` (`optimizer.learning_rate`, `data.commonroad.weight`: the first such line under a
/// `[data.commonroad]` or `[[data.commonroad]]` header), or `None` when the file does not set
/// it on a line of its own (a default, an inline table).
pub fn field_line(text: &str, field: &str) -> Option<(usize, String)> {
    let mut table = String::new();
    for (k, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.starts_with('[') {
            table = line.trim_matches(['[', ']', ' ']).to_string();
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            continue;
        };
        let key = key.trim().trim_matches('"');
        let full = if table.is_empty() {
            key.to_string()
        } else {
            format!("{table}.{key}")
        };
        if full == field {
            // A trailing comment is not part of the value (a `#` inside a string would end it
            // early, which only shortens what the message shows).
            let value = value.split(" #").next().unwrap_or(value).trim();
            return Some((k + 1, value.to_string()));
        }
    }
    None
}

/// The error for a `field` of the settings file `source_name` (text `text`) whose value is
/// refused with `message`: at its line with the value found where the file sets it, else
/// naming the field alone (a default the other fields make impossible).
pub fn field_error(text: &str, source_name: &str, field: &str, message: &str) -> Error {
    match field_line(text, field) {
        Some((line, value)) => Error::Parse {
            source_name: source_name.to_string(),
            line,
            column: 1,
            message: format!("field `{field}` = {value}: {message}"),
        },
        None => Error::invalid(source_name, format!("field `{field}`"), message),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_field_is_found_under_its_table_with_its_value() {
        let text = "alpha = 2.0 # too much\n\n[optimizer]\nlearning_rate = -1.0\n\
                    [[data.commonroad]]\npath = \"a.xml\"\nweight = -3\n";
        assert_eq!(field_line(text, "alpha"), Some((1, "2.0".into())));
        assert_eq!(
            field_line(text, "optimizer.learning_rate"),
            Some((4, "-1.0".into()))
        );
        assert_eq!(
            field_line(text, "data.commonroad.weight"),
            Some((7, "-3".into()))
        );
        assert_eq!(field_line(text, "learning_rate"), None);
        assert_eq!(field_line(text, "optimizer.epochs"), None);
        let e = field_error(text, "run.toml", "alpha", "expected a share in [0, 1]");
        assert_eq!(
            e.to_string(),
            "run.toml: line 1, column 1: field `alpha` = 2.0: expected a share in [0, 1]"
        );
        let e = field_error(text, "run.toml", "optimizer.epochs", "must be >= 1");
        assert_eq!(
            e.to_string(),
            "run.toml: field `optimizer.epochs`: must be >= 1"
        );
    }
}
