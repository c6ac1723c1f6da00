//! One way in: every file rtr reads is opened by [`open_regular`] (directly or through
//! [`read_bytes`] / [`read_text`]), which refuses anything that is not a regular file (a FIFO
//! would block forever, `/dev/zero` would fill memory) and caps how many bytes are read at
//! what the file's [`Format`] can plausibly hold.

use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

const MIB: u64 = 1 << 20;

/// What kind of file is read; it sets the cap on how many bytes are read. Each cap is far
/// above any real file of the kind and far below memory, so a wrong file is refused with a
/// message instead of exhausting the machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// A settings file: run files, model configs, scenario families, dynamics files (TOML),
    /// a checkpoint's loop state (JSON) and its `latest` pointer.
    Settings,
    /// A scene list (one id per line).
    SceneList,
    /// A concrete scenario (JSON).
    Scenario,
    /// An OpenDRIVE road network (XML).
    OpenDrive,
    /// A CommonRoad scenario (XML, possibly gzip-compressed; the cap applies to both sizes).
    CommonRoad,
    /// An AUTOMATUM recording (gzip-compressed JSON; the cap applies to both sizes).
    Automatum,
    /// Vehicle recordings for sim-to-real (CSV).
    Recordings,
    /// A run's training curves (CSV, one row of about 300 bytes per optimizer step).
    Curves,
    /// Network parameters (burnpack) of a model or checkpoint.
    Parameters,
}

impl Format {
    /// The most bytes a file of this format may hold.
    pub fn limit(self) -> u64 {
        match self {
            Format::Settings => 16 * MIB,
            Format::SceneList | Format::Scenario => 64 * MIB,
            Format::Curves => 256 * MIB,
            Format::OpenDrive | Format::CommonRoad => 512 * MIB,
            Format::Automatum | Format::Recordings => 2048 * MIB,
            Format::Parameters => 1024 * MIB,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Format::Settings => "a settings file",
            Format::SceneList => "a scene list",
            Format::Scenario => "a scenario file",
            Format::OpenDrive => "an OpenDRIVE file",
            Format::CommonRoad => "a CommonRoad file",
            Format::Automatum => "an AUTOMATUM recording",
            Format::Recordings => "a recordings file",
            Format::Curves => "a training-curves file",
            Format::Parameters => "a parameter file",
        }
    }
}

/// Checks that the input `path` given with `flag` is a regular file, so a folder, a missing
/// path, a FIFO or a device is refused naming the option (before any work) rather than
/// blocking, filling memory or failing with the operating system's bare message.
pub fn check_input_file(path: &Path, flag: &str) -> Result<()> {
    remember_flag(path, flag);
    let why = match path.metadata() {
        Ok(m) if m.is_file() => return Ok(()),
        Ok(m) if m.is_dir() => "is a folder; expected a file".to_string(),
        Ok(m) => format!("is {}; expected a regular file", kind_of(&m)),
        Err(e) if path.symlink_metadata().is_ok() => broken_link(&e).to_string(),
        Err(_) => "no such file".to_string(),
    };
    Err(Error::InvalidArgument(format!(
        "{flag} {}: {why}",
        path.display()
    )))
}

/// Checks that the input `path` given with `flag` is a folder (`expected` says which, for the
/// message), refusing a file, a FIFO, a device, a dangling link or a missing path by the
/// option's name rather than with the operating system's bare "Not a directory".
pub fn check_input_folder(path: &Path, flag: &str, expected: &str) -> Result<()> {
    remember_flag(path, flag);
    let why = match path.metadata() {
        Ok(m) if m.is_dir() => return Ok(()),
        Ok(m) => format!("is {}", kind_of(&m)),
        Err(e) if path.symlink_metadata().is_ok() => broken_link(&e).to_string(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => "does not exist".to_string(),
        Err(e) => format!("cannot be read ({e})"),
    };
    Err(Error::InvalidArgument(format!(
        "{flag} {}: {why}; expected {expected}",
        path.display()
    )))
}

/// Checks that the input `path` given with `flag` is a regular file or a folder (a model or
/// run folder, a scenario set), refusing a FIFO, a device, a dangling link or a missing path
/// by the option's name.
pub fn check_input_path(path: &Path, flag: &str) -> Result<()> {
    remember_flag(path, flag);
    match path.metadata() {
        Ok(m) if m.is_dir() => Ok(()),
        _ => check_input_file(path, flag),
    }
}

/// Opens `path` for reading if it is a regular file. The open itself cannot block: a FIFO
/// is opened non-blocking and then refused by its type.
pub fn open_regular(path: &Path) -> Result<File> {
    // Classified before the open: opening a socket fails with a bare "no such device", a
    // dangling link with "no such file".
    if let Some(why) = not_regular(path) {
        return Err(Error::invalid(path.display().to_string(), "file", why));
    }
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path).map_err(|e| Error::io(path, e))?;
    let metadata = file.metadata().map_err(|e| Error::io(path, e))?;
    if !metadata.is_file() {
        return Err(Error::invalid(
            path.display().to_string(),
            "file",
            format!("is {}; expected a regular file", kind_of(&metadata)),
        ));
    }
    Ok(file)
}

/// The first `limit` bytes of the regular file `path` (all of it if shorter).
pub fn read_head(path: &Path, limit: usize) -> Result<Vec<u8>> {
    use std::io::Read;
    let mut head = Vec::new();
    open_regular(path)?
        .take(limit as u64)
        .read_to_end(&mut head)
        .map_err(|e| Error::io(path, e))?;
    Ok(head)
}

/// Why `path` is not a regular file that can be read (a folder, FIFO, device, socket, a
/// dangling link), or `None` when it is one or does not exist at all.
pub fn not_regular(path: &Path) -> Option<String> {
    match path.metadata() {
        Ok(m) if m.is_file() => None,
        Ok(m) => Some(format!("is {}; expected a regular file", kind_of(&m))),
        Err(e) if path.symlink_metadata().is_ok() => {
            Some(format!("{}; expected a regular file", broken_link(&e)))
        }
        Err(_) => None,
    }
}

/// What is wrong with a link whose target cannot be read (`error`, from following it).
pub(super) fn broken_link(error: &std::io::Error) -> &'static str {
    if error.raw_os_error() == Some(libc::ELOOP) {
        "is a link that leads back to itself (a symlink loop)"
    } else {
        "is a link to nothing (dangling symlink)"
    }
}

/// What a non-regular file is, for messages.
pub(super) fn kind_of(metadata: &std::fs::Metadata) -> &'static str {
    if metadata.is_dir() {
        return "a folder";
    }
    if metadata.is_file() {
        return "a file";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let kind = metadata.file_type();
        if kind.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if kind.is_char_device() || kind.is_block_device() {
            return "a device";
        }
        if kind.is_socket() {
            return "a socket";
        }
    }
    "not a regular file"
}

/// The inputs checked so far with the flag that gave each, so that an error found later,
/// reading one of them or a file inside one, names the flag too.
fn given() -> std::sync::MutexGuard<'static, Vec<(std::path::PathBuf, String)>> {
    static GIVEN: std::sync::Mutex<Vec<(std::path::PathBuf, String)>> =
        std::sync::Mutex::new(Vec::new());
    GIVEN
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn remember_flag(path: &Path, flag: &str) {
    given().push((path.to_path_buf(), flag.to_string()));
}

/// `path` as an error names it: with the flag that gave it (or the folder holding it), when
/// a command checked it as an input.
fn named(path: &Path) -> String {
    let given = given();
    let flag = given
        .iter()
        .rev()
        .find(|(p, _)| path.starts_with(p))
        .map(|(_, flag)| flag.clone());
    match flag {
        Some(flag) => format!("{} (given with {flag})", path.display()),
        None => path.display().to_string(),
    }
}

/// Refuses the file `path` if it is larger than `format` allows (as [`read_bytes`] would),
/// before anything else is read: a command checks the files it will read at its start.
pub fn check_size(path: &Path, format: Format) -> Result<()> {
    match std::fs::metadata(path) {
        Ok(meta) if meta.is_file() && meta.len() > format.limit() => {
            Err(read_error(path, too_large(format)))
        }
        _ => Ok(()),
    }
}

/// The whole of the regular file `path`, refused if larger than `format` allows.
pub fn read_bytes(path: &Path, format: Format) -> Result<Vec<u8>> {
    let file = open_regular(path)?;
    // A file larger than the cap is refused from its size, before any of it is read (a
    // compressed one is capped again as it is decompressed).
    if let Ok(meta) = file.metadata()
        && meta.len() > format.limit()
    {
        return Err(read_error(path, too_large(format)));
    }
    let mut bytes = Vec::new();
    capped(file, format)
        .read_to_end(&mut bytes)
        .map_err(|e| read_error(path, e))?;
    Ok(bytes)
}

/// The regular file `path` as text (see [`utf8_text`]), refused if larger than `format`
/// allows.
pub fn read_text(path: &Path, format: Format) -> Result<String> {
    utf8_text(read_bytes(path, format)?, &path.display().to_string())
}

/// The text of a line-based file (a CSV) with no line longer than `max_line` bytes: a longer
/// one is refused at its line as soon as it is met, so a file that is one huge line (binary
/// data, a missing line break) costs `max_line` bytes to refuse, not its whole size twice
/// over in a parser's buffers.
pub fn read_lines(path: &Path, format: Format, max_line: usize) -> Result<String> {
    use std::io::BufRead;
    let file = open_regular(path)?;
    if let Ok(meta) = file.metadata()
        && meta.len() > format.limit()
    {
        return Err(read_error(path, too_large(format)));
    }
    let mut reader = std::io::BufReader::new(capped(file, format));
    let mut bytes = Vec::new();
    for line in 1.. {
        let start = bytes.len();
        let read = (&mut reader)
            .take(max_line as u64 + 1)
            .read_until(b'\n', &mut bytes)
            .map_err(|e| read_error(path, e))?;
        if read == 0 {
            break;
        }
        if read > max_line && bytes.last() != Some(&b'\n') {
            return Err(Error::Parse {
                source_name: named(path),
                line,
                column: 1,
                message: format!(
                    "the line is longer than {max_line} bytes; expected {} (a line break \
                     missing, or not a text file?)",
                    format.name()
                ),
            });
        }
        bytes.truncate(start + read);
    }
    utf8_text(bytes, &path.display().to_string())
}

/// `reader` that fails with [`std::io::ErrorKind::FileTooLarge`] (and a message naming the
/// format's cap) once it has yielded more than `format` allows. For streams whose size is not
/// known in advance, such as a decompressed gzip file.
pub fn capped<R: Read>(reader: R, format: Format) -> Capped<R> {
    Capped {
        inner: reader,
        left: format.limit(),
        format,
    }
}

/// See [`capped`].
pub struct Capped<R> {
    inner: R,
    left: u64,
    format: Format,
}

impl<R: Read> Read for Capped<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        // One byte more than allowed is asked for, so reaching the cap exactly is not an error.
        let want = buf
            .len()
            .min(usize::try_from(self.left + 1).unwrap_or(usize::MAX));
        let n = self.inner.read(&mut buf[..want])?;
        if n as u64 > self.left {
            return Err(too_large(self.format));
        }
        self.left -= n as u64;
        Ok(n)
    }
}

/// The error of a file or stream larger than `format` may be.
fn too_large(format: Format) -> std::io::Error {
    std::io::Error::new(
        std::io::ErrorKind::FileTooLarge,
        format!(
            "more than {} MiB, the most {} may hold; is this the right file?",
            format.limit() / MIB,
            format.name()
        ),
    )
}

/// A read error as the library reports it: a file over its cap is invalid data (named), any
/// other failure an I/O error on the path.
pub fn read_error(path: &Path, e: std::io::Error) -> Error {
    if e.kind() == std::io::ErrorKind::FileTooLarge {
        Error::invalid(named(path), "size", e.to_string())
    } else {
        Error::io(path, e)
    }
}

/// The entries of the folder `dir`, sorted by name so every listing is reproducible.
pub fn list_folder(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut paths = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .map(|entry| entry.map(|e| e.path()).map_err(|e| Error::io(dir, e)))
        .collect::<Result<Vec<_>>>()?;
    paths.sort();
    Ok(paths)
}

/// The files under `dir` and its sub-folders, hidden ones (names starting with `.`) left out,
/// each folder's in name order, a sub-folder's files where its name sorts. A folder reached
/// twice (a link back to a folder above it) is refused by name rather than walked until the
/// path is too long.
pub fn files_in_tree(dir: &Path) -> Result<Vec<PathBuf>> {
    fn walk(dir: &Path, seen: &mut Vec<PathBuf>, out: &mut Vec<PathBuf>) -> Result<()> {
        let real = dir.canonicalize().map_err(|e| Error::io(dir, e))?;
        if seen.contains(&real) {
            return Err(Error::invalid(
                dir.display().to_string(),
                "folder",
                "leads back to a folder already read (a symlink loop); expected a tree",
            ));
        }
        seen.push(real);
        for path in list_folder(dir)? {
            let hidden = path
                .file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with('.'));
            if hidden {
                continue;
            }
            if path.is_dir() {
                walk(&path, seen, out)?;
            } else {
                out.push(path);
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    walk(dir, &mut Vec::new(), &mut out)?;
    Ok(out)
}

/// `bytes` as text, or an error naming `source_name` and the line and column of the first
/// byte that is not UTF-8 (a binary or Latin-1 file given by mistake), not a bare "invalid
/// UTF-8".
pub fn utf8_text(bytes: Vec<u8>, source_name: &str) -> Result<String> {
    String::from_utf8(bytes).map_err(|e| {
        let valid = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        // Everything before `valid` is UTF-8, so it can be counted as text.
        let before = std::str::from_utf8(&bytes[..valid]).unwrap_or_default();
        let (line, column) = super::line_column(before, before.len());
        Error::Parse {
            source_name: source_name.to_string(),
            line,
            column,
            message: format!(
                "byte 0x{:02x} is not UTF-8 text; expected a UTF-8 text file",
                bytes[valid]
            ),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tree_is_read_whole_and_a_folder_loop_is_named() {
        let dir = tempfile::tempdir().expect("temp dir");
        std::fs::create_dir_all(dir.path().join("a/b")).expect("mkdir");
        std::fs::write(dir.path().join("a/b/clip.xml"), "x").expect("write");
        std::fs::write(dir.path().join("top.xml"), "x").expect("write");
        std::fs::write(dir.path().join(".hidden.xml"), "x").expect("write");
        let files = files_in_tree(dir.path()).expect("a tree");
        assert_eq!(files.len(), 2, "{files:?}");
        std::os::unix::fs::symlink("..", dir.path().join("a/b/up")).expect("symlink");
        let err = files_in_tree(dir.path()).expect_err("a loop").to_string();
        assert!(err.contains("symlink loop"), "{err}");
    }

    #[test]
    fn a_fifo_is_refused_without_blocking() {
        let dir = tempfile::tempdir().expect("temp dir");
        let fifo = dir.path().join("run.toml");
        let c_path = std::ffi::CString::new(fifo.to_string_lossy().as_bytes()).expect("path");
        // SAFETY: a valid NUL-terminated path; mkfifo only creates a file.
        assert_eq!(unsafe { libc::mkfifo(c_path.as_ptr(), 0o600) }, 0);
        let err = read_text(&fifo, Format::Settings).expect_err("a FIFO is not a file");
        assert!(err.to_string().contains("FIFO"), "{err}");
        let err = check_input_file(&fifo, "--config").expect_err("refused by flag");
        assert!(err.to_string().contains("--config"), "{err}");
        assert!(err.to_string().contains("FIFO"), "{err}");
    }

    #[test]
    fn a_device_is_refused() {
        let err = read_bytes(Path::new("/dev/zero"), Format::Settings).expect_err("a device");
        assert!(err.to_string().contains("device"), "{err}");
    }

    #[test]
    fn a_stream_past_its_cap_is_refused_and_the_cap_itself_is_not() {
        let limit = Format::Settings.limit() as usize;
        let mut exact = Vec::new();
        capped(std::io::repeat(b'a').take(limit as u64), Format::Settings)
            .read_to_end(&mut exact)
            .expect("exactly the cap is fine");
        assert_eq!(exact.len(), limit);
        let err = capped(std::io::repeat(b'a'), Format::Settings)
            .read_to_end(&mut Vec::new())
            .expect_err("endless stream");
        assert_eq!(err.kind(), std::io::ErrorKind::FileTooLarge);
        assert!(err.to_string().contains("settings"), "{err}");
    }

    #[test]
    fn a_file_too_large_is_named_with_its_flag() {
        let dir = tempfile::tempdir().expect("temp dir");
        let big = dir.path().join("big.toml");
        let file = std::fs::File::create(&big).expect("create");
        file.set_len(Format::Settings.limit() + 1).expect("sparse");
        check_input_file(&big, "--config").expect("a regular file");
        let err = read_text(&big, Format::Settings)
            .expect_err("too large")
            .to_string();
        assert!(err.contains("given with --config"), "{err}");
    }

    #[test]
    fn a_dangling_link_and_a_folder_are_named() {
        let dir = tempfile::tempdir().expect("temp dir");
        let link = dir.path().join("gone.toml");
        std::os::unix::fs::symlink(dir.path().join("missing"), &link).expect("symlink");
        let err = check_input_file(&link, "--config").expect_err("dangling");
        assert!(err.to_string().contains("dangling"), "{err}");
        let err = check_input_file(dir.path(), "--config").expect_err("folder");
        assert!(err.to_string().contains("folder"), "{err}");
    }
}
