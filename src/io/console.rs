//! Standard output and error as fallible writes. `println!` panics when stdout is a closed
//! pipe (`rtr data summary | head -1`) or a full disk; here a closed pipe silences the rest of
//! the command's printing while it goes on to finish its files (as `head` expects), and any
//! other failure is an error naming standard output. Use [`crate::outln!`] / [`crate::out!`]
//! for results and [`crate::errln!`] for progress and warnings.

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::{Error, Result};

/// Set once the reader of standard output has gone away.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Writes `text` to standard output. A closed pipe is not an error: this and later writes are
/// dropped. Any other failure (a full disk) is.
pub fn write_stdout(text: &str) -> Result<()> {
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        return Ok(());
    }
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
            STDOUT_CLOSED.store(true, Ordering::Relaxed);
            Ok(())
        }
        Err(e) => Err(Error::io("standard output", e)),
    }
}

/// Writes `text` to standard error. Messages to a closed or full standard error are dropped:
/// there is nowhere left to report that.
pub fn write_stderr(text: &str) {
    let _ = std::io::stderr().lock().write_all(text.as_bytes());
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
