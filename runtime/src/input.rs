//! Opening input files: regular files only, refused at once otherwise.
//!
//! Every reader of every crate opens its inputs here — tables (Rust and C), samples, robot
//! files and URDFs, programs, plans, measured cycles, validation files — so that one rule
//! holds everywhere: an input that is not a regular file (a FIFO, a character device such
//! as `/dev/zero`, a socket, a directory) is refused before a byte is read. A FIFO would
//! otherwise block the open or the read until a writer comes, forever for a controller;
//! `/dev/zero` would be read until memory runs out.
//!
//! The file is opened with `O_NONBLOCK` (so that opening a FIFO with no writer returns at
//! once instead of waiting for one), then the *opened descriptor* is examined with
//! `fstat`: a check of the path before opening could be raced by a rename in between.
//! A regular file then has `O_NONBLOCK` cleared again (it has no effect on regular files
//! on Linux, but a reader should not depend on that).

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

/// Opens `path` for reading if it is a regular file (a symbolic link to one is followed).
///
/// # Errors
///
/// The open's error, or [`io::ErrorKind::InvalidInput`] saying what the file is when it is
/// not a regular file; nothing is read from it.
pub fn open_regular(path: &Path) -> io::Result<File> {
    let file = open_nonblocking(path)?;
    let kind = file.metadata()?.file_type();
    if !kind.is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{}, not a regular file: only regular files are read",
                describe(&kind)
            ),
        ));
    }
    blocking_again(&file)?;
    Ok(file)
}

/// Reads the whole regular file at `path` ([`open_regular`]).
///
/// # Errors
///
/// As [`open_regular`], and a failed read.
pub fn read_regular(path: &Path) -> io::Result<Vec<u8>> {
    let mut file = open_regular(path)?;
    let mut bytes = Vec::new();
    // The size is a hint only (the file may grow or shrink while read).
    let hint = file.metadata().map_or(0, |m| m.len());
    bytes
        .try_reserve(usize::try_from(hint).unwrap_or(0))
        .map_err(|_| {
            io::Error::new(
                io::ErrorKind::OutOfMemory,
                format!("{hint} bytes do not fit in memory"),
            )
        })?;
    file.read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// Reads the whole regular file at `path` as UTF-8 text ([`open_regular`]).
///
/// # Errors
///
/// As [`read_regular`], and [`io::ErrorKind::InvalidData`] for text that is not UTF-8.
pub fn read_regular_to_string(path: &Path) -> io::Result<String> {
    String::from_utf8(read_regular(path)?).map_err(|_| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            "stream did not contain valid UTF-8",
        )
    })
}

#[cfg(unix)]
fn open_nonblocking(path: &Path) -> io::Result<File> {
    use std::os::unix::fs::OpenOptionsExt;
    std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
}

#[cfg(not(unix))]
fn open_nonblocking(path: &Path) -> io::Result<File> {
    File::open(path)
}

/// Clears `O_NONBLOCK` on an opened regular file.
#[cfg(unix)]
fn blocking_again(file: &File) -> io::Result<()> {
    use std::os::unix::io::AsRawFd;
    let fd = file.as_raw_fd();
    // SAFETY: `fd` is an open descriptor owned by `file` for the duration of both calls;
    // F_GETFL and F_SETFL read and set its status flags only.
    unsafe {
        let flags = libc::fcntl(fd, libc::F_GETFL);
        if flags < 0 || libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK) < 0 {
            return Err(io::Error::last_os_error());
        }
    }
    Ok(())
}

#[cfg(not(unix))]
fn blocking_again(_: &File) -> io::Result<()> {
    Ok(())
}

/// What a file that is not regular is, in words.
fn describe(kind: &std::fs::FileType) -> &'static str {
    if kind.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            return "a FIFO";
        }
        if kind.is_char_device() {
            return "a character device";
        }
        if kind.is_block_device() {
            return "a block device";
        }
        if kind.is_socket() {
            return "a socket";
        }
    }
    "a special file"
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fifo(dir: &Path) -> std::path::PathBuf {
        let path = dir.join("fifo");
        let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
        // SAFETY: a NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        path
    }

    /// A FIFO without a writer would block a plain open forever; a character device
    /// would be read without end. Both are refused at once, saying what they are.
    #[test]
    fn fifos_devices_and_directories_are_refused_at_once() {
        let dir = std::env::temp_dir().join(format!("adwi-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let fifo = fifo(&dir);
        let started = std::time::Instant::now();
        for (path, kind) in [
            (fifo.as_path(), "a FIFO"),
            (Path::new("/dev/zero"), "a character device"),
            (dir.as_path(), "a directory"),
        ] {
            let e = read_regular(path).unwrap_err();
            assert_eq!(e.kind(), io::ErrorKind::InvalidInput, "{path:?}");
            assert!(e.to_string().starts_with(kind), "{path:?}: {e}");
        }
        assert!(started.elapsed() < std::time::Duration::from_secs(5));
        let file = dir.join("regular");
        std::fs::write(&file, b"abc").unwrap();
        assert_eq!(read_regular(&file).unwrap(), b"abc");
        assert_eq!(read_regular_to_string(&file).unwrap(), "abc");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
