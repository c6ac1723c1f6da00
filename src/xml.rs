//! The roxmltree plumbing shared by the XML formats rtr reads (OpenDRIVE, CommonRoad): parse
//! a document with a located error, and place an error at an element's line and column.

use roxmltree::{Document, Node};

use crate::{Error, Result};

/// Parses `text`; `source` (usually the file path) names it in the error.
pub fn parse_document<'input>(text: &'input str, source: &str) -> Result<Document<'input>> {
    Document::parse(text).map_err(|e| {
        let pos = e.pos();
        Error::Parse {
            source_name: source.to_string(),
            line: pos.row as usize,
            column: pos.col as usize,
            message: format!("not well-formed XML: {e}"),
        }
    })
}

/// An error about `node` of `doc`, at the line and column where the element starts.
pub fn error_at(doc: &Document, source: &str, node: Node, message: impl Into<String>) -> Error {
    let pos = doc.text_pos_at(node.range().start);
    Error::Parse {
        source_name: source.to_string(),
        line: pos.row as usize,
        column: pos.col as usize,
        message: message.into(),
    }
}
