//! Standard output and error as fallible writes. `println!` panics when stdout is a closed
//! pipe (`rtr data summary | head -1`) or a full disk; here a failed stdout silences the rest
//! of the command's printing while it goes on to finish its files: a closed pipe is then no
//! error (as `head` expects), any other failure is one, naming standard output, reported when
//! the command ends ([`check_stdout`]). Use [`crate::outln!`] / [`crate::out!`]
//! for results and [`crate::errln!`] for progress and warnings.

use std::io::Write;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::{Error, Result};

/// Set once standard output can take no more: its reader has gone away, or it failed.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// How standard output failed (a full disk), kept until the command has finished its files.
static STDOUT_FAILURE: Mutex<Option<std::io::Error>> = Mutex::new(None);

/// Writes `text` to standard output. Once it cannot be written, this and later writes are
/// dropped, so that a command still finishes its files: a closed pipe is not an error, any
/// other failure (a full disk) is kept for [`check_stdout`].
pub fn write_stdout(text: &str) -> Result<()> {
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        return Ok(());
    }
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        STDOUT_CLOSED.store(true, Ordering::Relaxed);
        if e.kind() != std::io::ErrorKind::BrokenPipe
            && let Ok(mut failure) = STDOUT_FAILURE.lock()
        {
            failure.get_or_insert(e);
        }
    }
    Ok(())
}

/// The error standard output met, if it failed other than by its reader going away: a
/// program calls this after its command has written its files, and fails with it.
pub fn check_stdout() -> Result<()> {
    match STDOUT_FAILURE.lock().ok().and_then(|mut f| f.take()) {
        Some(failure) => Err(Error::io("standard output", failure)),
        None => Ok(()),
    }
}

/// Writes `text` to standard error. Messages to a closed or full standard error are dropped:
/// there is nowhere left to report that.
pub fn write_stderr(text: &str) {
    let _ = std::io::stderr().lock().write_all(text.as_bytes());
}

/// The most characters of a message shown: one that quotes a huge input (a header line of
/// hundreds of megabytes, a run-file value) keeps its beginning and end.
const MAX_MESSAGE_CHARS: usize = 1200;

/// `message`, cut in the middle when longer than [`MAX_MESSAGE_CHARS`], saying how much was
/// left out.
pub fn bounded(message: &str) -> String {
    let chars = message.chars().count();
    if chars <= MAX_MESSAGE_CHARS {
        return message.to_string();
    }
    let head: String = message.chars().take(MAX_MESSAGE_CHARS * 2 / 3).collect();
    let tail: String = message
        .chars()
        .skip(chars - MAX_MESSAGE_CHARS / 3)
        .collect();
    let left_out = chars - MAX_MESSAGE_CHARS * 2 / 3 - MAX_MESSAGE_CHARS / 3;
    format!("{head}[... {left_out} characters left out ...]{tail}")
}

/// `println!` to standard output through [`write_stdout`]; evaluates to `Result<()>`.
#[macro_export]
macro_rules! outln {
    () => {
        $crate::io::console::write_stdout("\n")
    };
    ($($arg:tt)*) => {
        $crate::io::console::write_stdout(&format!("{}\n", format_args!($($arg)*)))
    };
}

/// `print!` to standard output through [`write_stdout`]; evaluates to `Result<()>`.
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::io::console::write_stdout(&format!($($arg)*))
    };
}

/// `eprintln!` through [`write_stderr`], which never panics.
#[macro_export]
macro_rules! errln {
    () => {
        $crate::io::console::write_stderr("\n")
    };
    ($($arg:tt)*) => {
        $crate::io::console::write_stderr(&format!("{}\n", format_args!($($arg)*)))
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_message_keeps_its_ends_and_says_what_was_cut() {
        assert_eq!(bounded("short"), "short");
        let long = format!("start {} end", "Q".repeat(50_000));
        let shown = bounded(&long);
        assert!(
            shown.starts_with("start QQ") && shown.ends_with("QQ end"),
            "{shown}"
        );
        assert!(shown.contains("characters left out"), "{shown}");
        assert!(shown.chars().count() < MAX_MESSAGE_CHARS + 60);
    }
}
