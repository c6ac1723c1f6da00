//! The code's shape, enforced on `src/`:
//! - the layers `src/lib.rs` states: no module names (`crate::...`) a module of a higher
//!   layer. The list is read from lib.rs's doc comment, so the rule and its statement cannot
//!   drift apart; a module missing from the list fails too;
//! - no function longer than [`MAX_FUNCTION_LINES`] lines: a longer one mixes stages that
//!   deserve names;
//! - no file access or printing outside `src/io/` (in `src/` and `examples/`): every input
//!   goes through its one opener, every output through its one writer, every print through
//!   its console.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Module name -> layer, from the numbered lines of `lib_rs`'s `//!` comment
/// (`//! 3. \`scene\`: ...`; a list may continue on the next `//!    ` lines).
fn layers(lib_rs: &str) -> BTreeMap<String, usize> {
    let mut out = BTreeMap::new();
    let mut current = None;
    for line in lib_rs.lines() {
        let Some(doc) = line.strip_prefix("//!") else {
            continue;
        };
        let doc = doc.trim_start();
        let numbered = doc
            .split_once(". ")
            .and_then(|(n, rest)| n.parse::<usize>().ok().map(|n| (n, rest)));
        let text = match numbered {
            Some((n, rest)) => {
                current = Some(n);
                rest
            }
            // A continuation line of the current item, or the end of the list.
            None if current.is_some() && line.starts_with("//!    ") => doc,
            None => {
                current = None;
                continue;
            }
        };
        // Module names are the backticked words before the item's colon.
        let names = text.split(':').next().unwrap_or("");
        for (k, part) in names.split('`').enumerate() {
            if k % 2 == 1 {
                out.insert(part.to_string(), current.expect("inside an item"));
            }
        }
    }
    out
}

/// The code of `source`, line by line, without comments (doc comments' paths are only links)
/// and without the contents of string literals.
fn code_lines(source: &str) -> impl Iterator<Item = (usize, String)> + '_ {
    source.lines().enumerate().map(|(i, line)| {
        let mut in_string = false;
        let mut code = String::new();
        let bytes: Vec<char> = line.chars().collect();
        let mut k = 0;
        while k < bytes.len() {
            let c = bytes[k];
            if c == '"' && (k == 0 || bytes[k - 1] != '\\') {
                in_string = !in_string;
            } else if in_string {
                // A string's contents are data, not paths.
                k += 1;
                continue;
            }
            if !in_string && c == '/' && bytes.get(k + 1) == Some(&'/') {
                break;
            }
            code.push(c);
            k += 1;
        }
        (i + 1, code)
    })
}

/// The top-level modules `code` names through `crate::`, including each item of a
/// `crate::{a::b, c}` group.
fn crate_paths(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = code;
    while let Some(at) = rest.find("crate::") {
        let after = &rest[at + "crate::".len()..];
        if let Some(group) = after.strip_prefix('{') {
            let mut depth = 0;
            let mut item = String::new();
            let mut items = Vec::new();
            for c in group.chars() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => items.push(std::mem::take(&mut item)),
                    _ => {}
                }
                item.push(c);
            }
            items.push(item);
            for item in items {
                let name: String = item
                    .trim_start_matches([',', ' ', '\n'])
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    out.push(name);
                }
            }
        } else {
            let name: String = after
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            out.push(name);
        }
        rest = after;
    }
    out
}

/// Every upward use in `files` (path relative to `src/`, source) under `layers`, as
/// "file:line: ..." messages; a file whose module has no layer is reported too.
fn upward_uses(layers: &BTreeMap<String, usize>, files: &[(PathBuf, String)]) -> Vec<String> {
    let mut found = Vec::new();
    for (path, source) in files {
        let module = path
            .components()
            .next()
            .and_then(|c| c.as_os_str().to_str())
            .map(|c| c.trim_end_matches(".rs").to_string())
            .unwrap_or_default();
        if module == "lib" || module == "main" || module == "bin" {
            continue;
        }
        let Some(&own) = layers.get(&module) else {
            found.push(format!(
                "src/{}: module `{module}` is in no layer of lib.rs's list",
                path.display()
            ));
            continue;
        };
        for (line, code) in code_lines(source) {
            for used in crate_paths(&code) {
                // Re-exports at the crate root (`crate::Result`) belong to layer 1.
                let layer = layers.get(&used).copied().unwrap_or(1);
                if layer > own {
                    found.push(format!(
                        "src/{}:{line}: `{module}` (layer {own}) uses `crate::{used}` (layer \
                         {layer})",
                        path.display()
                    ));
                }
            }
        }
    }
    found
}

fn rust_files(dir: &Path, root: &Path, out: &mut Vec<(PathBuf, String)>) {
    for entry in std::fs::read_dir(dir).expect("a readable source folder") {
        let path = entry.expect("a directory entry").path();
        if path.is_dir() {
            rust_files(&path, root, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            let source = std::fs::read_to_string(&path).expect("a UTF-8 source file");
            out.push((
                path.strip_prefix(root).expect("under root").to_path_buf(),
                source,
            ));
        }
    }
}

#[test]
fn no_module_uses_a_higher_layer() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let lib = std::fs::read_to_string(src.join("lib.rs")).expect("lib.rs");
    let layers = layers(&lib);
    for module in lib.lines().filter_map(|l| {
        l.trim()
            .strip_prefix("pub mod")
            .or(l.trim().strip_prefix("mod"))
    }) {
        let module = module.trim().trim_end_matches(';');
        assert!(
            layers.contains_key(module),
            "src/lib.rs declares `{module}` but its layer list does not name it"
        );
    }
    let mut files = Vec::new();
    rust_files(&src, &src, &mut files);
    let found = upward_uses(&layers, &files);
    assert!(found.is_empty(), "upward uses:\n{}", found.join("\n"));
}

#[test]
fn an_upward_use_is_reported_with_its_file_and_line() {
    let lib = "//! Layers:\n//!\n//! 1. `error`, `geometry`,\n//!    `io`: foundations;\n\
               //! 2. `map`: roads;\n//! 3. `train`: training;\n\npub mod map;\n";
    let layers = layers(lib);
    assert_eq!(layers.get("io"), Some(&1));
    assert_eq!(layers.get("train"), Some(&3));
    let file = |path: &str, source: &str| (PathBuf::from(path), source.to_string());
    let files = [
        file(
            "map/parse.rs",
            "//! Links to [`crate::train`] are fine.\nuse crate::geometry::Point;\n\
             use crate::{error::Result, train::Trainer};\nlet s = \"crate::train\"; // crate::train\n",
        ),
        file("train/loop.rs", "use crate::map::Map;\n"),
        file("predict.rs", "use crate::map::Map;\n"),
    ];
    let found = upward_uses(&layers, &files);
    assert_eq!(found.len(), 2, "{found:#?}");
    assert!(
        found[0].starts_with("src/map/parse.rs:3:") && found[0].contains("`crate::train`"),
        "{found:#?}"
    );
    assert!(found[1].contains("`predict` is in no layer"), "{found:#?}");
}

/// The longest a function in `src/` may be, signature and closing brace included.
const MAX_FUNCTION_LINES: usize = 120;

/// `(name, first line, lines)` of every function in `source` with a body. Relies on rustfmt's
/// layout (which CI enforces): a body closes with `}` alone at the indentation of its `fn`.
fn function_lengths(source: &str) -> Vec<(String, usize, usize)> {
    let lines: Vec<&str> = source.lines().collect();
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let code = line.trim_start();
        let indent = &line[..line.len() - code.len()];
        let Some(name) = function_name(code) else {
            continue;
        };
        // A declaration without a body (a trait method) ends with `;` before any `{`.
        let body = lines[i..]
            .iter()
            .position(|l| l.contains('{') || l.trim_end().ends_with(';'))
            .filter(|&k| lines[i + k].contains('{'));
        if body.is_none() {
            continue;
        }
        let closing = format!("{indent}}}");
        if let Some(k) = lines[i..].iter().position(|l| l.trim_end() == closing) {
            out.push((name, i + 1, k + 1));
        }
    }
    out
}

/// The name of the function `code` (a trimmed line) declares, if it declares one.
fn function_name(code: &str) -> Option<String> {
    let mut words = code.split_whitespace().peekable();
    while let Some(&w) = words.peek() {
        let qualifier = w.starts_with("pub") || ["const", "async", "unsafe", "extern"].contains(&w);
        if !qualifier {
            break;
        }
        words.next();
    }
    if words.next()? != "fn" {
        return None;
    }
    let name: String = words
        .next()?
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect();
    (!name.is_empty()).then_some(name)
}

fn long_functions(files: &[(PathBuf, String)]) -> Vec<String> {
    let mut found = Vec::new();
    for (path, source) in files {
        for (name, line, length) in function_lengths(source) {
            if length > MAX_FUNCTION_LINES {
                found.push(format!(
                    "src/{}:{line}: `{name}` is {length} lines (at most {MAX_FUNCTION_LINES})",
                    path.display()
                ));
            }
        }
    }
    found
}

#[test]
fn no_function_is_longer_than_the_limit() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &src, &mut files);
    let found = long_functions(&files);
    assert!(found.is_empty(), "long functions:\n{}", found.join("\n"));
}

#[test]
fn a_long_function_is_reported_with_its_file_line_and_length() {
    let body = "    let x = 1;\n".repeat(MAX_FUNCTION_LINES - 2);
    let source = format!(
        "trait T {{\n    fn declared(&self) -> u8;\n}}\n\n\
         pub(crate) fn fits() {{\n{body}}}\n\n\
         impl S {{\n    pub async fn too_long(\n        &self,\n    ) {{\n{body}    }}\n}}\n"
    );
    let found = long_functions(&[(PathBuf::from("m/x.rs"), source.clone())]);
    assert_eq!(
        found,
        [format!(
            "src/m/x.rs:{}: `too_long` is {} lines (at most {MAX_FUNCTION_LINES})",
            // After the trait (3 lines), a blank, `fits`, a blank and `impl S {`.
            3 + 1 + MAX_FUNCTION_LINES + 1 + 1 + 1,
            MAX_FUNCTION_LINES + 2
        )]
    );
    let lengths = function_lengths(&source);
    assert_eq!(lengths[0], ("fits".to_string(), 5, MAX_FUNCTION_LINES));
    assert!(
        lengths.iter().all(|(name, ..)| name != "declared"),
        "a declaration without a body is not a function: {lengths:?}"
    );
}

/// What only `src/io/` may write: file-system calls and the printing macros (which panic on a
/// closed pipe). Everything else reads and writes through `rtr::io`, so that every input is
/// opened by the one opener and every output written by the one writer.
const IO_ONLY: [&str; 8] = [
    "std::fs",
    "fs::",
    "File::",
    "OpenOptions",
    "println!(",
    "print!(",
    "eprintln!(",
    "eprint!(",
];

/// Whether `code` names `item` as a whole path or macro (`DynamicsFile::load` does not name
/// `File::`).
fn names_item(code: &str, item: &str) -> bool {
    code.match_indices(item).any(|(at, _)| {
        !code[..at]
            .chars()
            .next_back()
            .is_some_and(|c| c.is_alphanumeric() || c == '_')
    })
}

/// The files of `files` that only tests compile: modules declared under `#[cfg(test)]`.
fn test_only_files(files: &[(PathBuf, String)]) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for (path, source) in files {
        let module_dir = match path.file_name().and_then(|n| n.to_str()) {
            Some("mod.rs" | "lib.rs" | "main.rs") => path.parent().unwrap_or(Path::new("")).into(),
            _ => path.with_extension(""),
        };
        let lines: Vec<&str> = source.lines().collect();
        for pair in lines.windows(2) {
            let declared = pair[1]
                .trim()
                .trim_start_matches("pub ")
                .strip_prefix("mod ");
            if let (true, Some(name)) = (pair[0].trim() == "#[cfg(test)]", declared) {
                let name = name.trim_end_matches(';');
                out.push(module_dir.join(format!("{name}.rs")));
                out.push(module_dir.join(name).join("mod.rs"));
            }
        }
    }
    out
}

/// Every use of an [`IO_ONLY`] item outside `src/io/` and outside test code (test-only files
/// and a file's trailing `#[cfg(test)] mod` block), as "file:line: ..." messages; `files`
/// are named relative to the repository.
fn io_outside_io(files: &[(PathBuf, String)]) -> Vec<String> {
    let test_only = test_only_files(files);
    let mut found = Vec::new();
    for (path, source) in files {
        if path.starts_with("src/io") || test_only.contains(path) {
            continue;
        }
        let lines: Vec<&str> = source.lines().collect();
        // The test module: from `#[cfg(test)]` followed by a `mod ... {` to the end.
        let tests_start = lines
            .windows(2)
            .position(|w| w[0].trim() == "#[cfg(test)]" && w[1].trim().starts_with("mod "))
            .unwrap_or(lines.len());
        for (line, code) in code_lines(source).take(tests_start) {
            if let Some(item) = IO_ONLY.iter().find(|item| names_item(&code, item)) {
                found.push(format!(
                    "{}:{line}: `{item}` outside src/io/: {}",
                    path.display(),
                    code.trim()
                ));
            }
        }
    }
    found
}

#[test]
fn every_file_access_and_print_goes_through_rtr_io() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    // The library, the command-line tool and the examples users run.
    rust_files(&root.join("src"), root, &mut files);
    rust_files(&root.join("examples"), root, &mut files);
    let found = io_outside_io(&files);
    assert!(
        found.is_empty(),
        "I/O outside src/io/:\n{}",
        found.join("\n")
    );
}

#[test]
fn io_outside_io_is_reported_with_its_file_and_line() {
    let file = |path: &str, source: &str| (PathBuf::from(path), source.to_string());
    let files = [
        file(
            "src/eval/write.rs",
            "use std::fs;\nlet s = \"std::fs\"; // std::fs\neprintln!(\"x\");\n\
             crate::outln!(\"x\")?;\nDynamicsFile::load(p);\n#[cfg(test)]\nmod tests {\n    std::fs::write(p, b);\n}\n",
        ),
        file("src/io/output.rs", "std::fs::write(p, b);\n"),
        file("src/map/mod.rs", "#[cfg(test)]\nmod test_maps;\n"),
        file("src/map/test_maps.rs", "std::fs::read(p);\n"),
    ];
    let found = io_outside_io(&files);
    assert_eq!(found.len(), 2, "{found:#?}");
    assert!(found[0].starts_with("src/eval/write.rs:1:"), "{found:#?}");
    assert!(found[1].starts_with("src/eval/write.rs:3:"), "{found:#?}");
}
