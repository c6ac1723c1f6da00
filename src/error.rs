//! One error type for the library. Every variant that comes from user input names the file
//! (or other source) and, where there is one, the line or field, and what was expected.

use std::path::PathBuf;

/// Result alias used across the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be opened or read.
    #[error("{}: {source}", shown_path(path))]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    /// A shipped data file does not have the checksum it was published with.
    #[error(
        "{path}: sha256 is {actual}, expected {expected}; the file is not the original \
         (truncated, corrupted or modified copy): restore it byte-identical"
    )]
    Checksum {
        path: PathBuf,
        expected: String,
        actual: String,
    },

    /// A syntax or structure error at a known place in a text file (JSON, XML, CSV, TOML).
    #[error("{source_name}: line {line}, column {column}: {message}")]
    Parse {
        source_name: String,
        line: usize,
        column: usize,
        message: String,
    },

    /// Well-formed input whose content is not what rtr can use (a NaN coordinate, a negative
    /// length, a map element rtr does not support). `source_name` names the file or generator,
    /// `place` the record or field.
    #[error("{source_name}: {place}: {message}")]
    InvalidData {
        source_name: String,
        place: String,
        message: String,
    },

    /// Training produced NaN or infinity; nothing after the last good checkpoint was written.
    #[error(
        "training diverged at iteration {iteration} (after {update} optimizer steps): the \
         {what} is {value}; the last good checkpoint is {checkpoint}. Lower \
         optimizer.learning_rate or check the data, then resume or restart"
    )]
    Diverged {
        iteration: usize,
        update: usize,
        what: String,
        value: f64,
        checkpoint: String,
    },

    /// A command-line value or configuration value that is out of range.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
}

/// A path as an error shows it: an empty one (a field or flag given as "") said in words.
fn shown_path(path: &std::path::Path) -> String {
    if path.as_os_str().is_empty() {
        "an empty path (\"\"), where a file name was expected,".into()
    } else {
        path.display().to_string()
    }
}

impl Error {
    /// This error, said of the input path a run file's `field` names (`init.policy`), so the
    /// user knows which line of the run file to change.
    pub fn in_field(self, field: &str) -> Self {
        Error::InvalidData {
            source_name: "run file".into(),
            place: format!("field `{field}`"),
            message: match self {
                Error::InvalidArgument(message) => message,
                other => other.to_string(),
            },
        }
    }

    /// Wraps an I/O error with the path it happened on.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// Shorthand for [`Error::InvalidData`].
    pub fn invalid(
        source_name: impl Into<String>,
        place: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Error::InvalidData {
            source_name: source_name.into(),
            place: place.into(),
            message: message.into(),
        }
    }
}
