//! Every file rtr reads or writes, and its standard output, goes through this module: one
//! way in ([`input`]: regular files only, capped sizes, errors that name the file and line),
//! one way out ([`output`], [`StagedFolder`]: atomic, checked, all or nothing) and a console
//! that a closed pipe cannot crash ([`console`]). `tests/structure.rs` keeps every other
//! module off `std::fs` and the printing macros.

mod claim;
pub mod console;
mod input;
mod output;
mod process_files;
mod staged;

pub use claim::{FolderClaim, Inputs, check_output_file, claim_output_folder};
pub use input::{
    Capped, Format, capped, check_input_file, check_input_path, list_folder, open_regular,
    read_bytes, read_error, read_text, utf8_text,
};
pub(crate) use output::temp_name;
pub use output::{
    atomic_write, atomic_write_with, create_file, create_folder, is_temporary_name, remove_file,
    remove_folder, rename, write_new,
};
pub use process_files::{read_process_file, write_process_file};
pub use staged::StagedFolder;

use crate::error::{Error, Result};

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
