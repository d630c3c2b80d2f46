//! Writing a table file so that nothing is ever lost: no partial table, no damaged
//! existing table, no temporary file left behind.

use std::io::Write;
use std::path::Path;

/// Refuses to write `output` when it is one of `inputs` — the same file, also through a
/// symbolic or hard link — before anything is written: a mistyped output path must never
/// replace the calibration data it was computed from. Inputs that do not exist are
/// skipped, and an output that does not exist yet cannot be an input.
///
/// # Errors
///
/// [`std::io::ErrorKind::AlreadyExists`], naming the output and the input it is.
pub fn refuse_overwriting(output: &Path, inputs: &[&Path]) -> std::io::Result<()> {
    let Ok(out) = std::fs::metadata(output) else {
        return Ok(());
    };
    for input in inputs {
        let Ok(inp) = std::fs::metadata(input) else {
            continue;
        };
        if same_file(&out, &inp, output, input) {
            return Err(std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                format!(
                    "refusing to write {}: it is the input {} (the same file{}); choose another output",
                    output.display(),
                    input.display(),
                    if output == *input {
                        ""
                    } else {
                        ", through a link"
                    }
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(unix)]
fn same_file(a: &std::fs::Metadata, b: &std::fs::Metadata, _: &Path, _: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    a.dev() == b.dev() && a.ino() == b.ino()
}

#[cfg(not(unix))]
fn same_file(_: &std::fs::Metadata, _: &std::fs::Metadata, a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// Writes `bytes` to `path` so that no reader, crash or kill ever sees a partial table and
/// an existing table at `path` (even one mapped by a running controller) stays intact until
/// the complete new one replaces it by rename.
///
/// On Linux the data goes to an unnamed `O_TMPFILE` file in the target directory, which
/// the kernel frees if the process dies before it is named; once written and flushed it is
/// linked as `.tablec-PID-N.tmp` and renamed into place at once. Elsewhere (or on file
/// systems without `O_TMPFILE`) it is written under that name from the start. Either way a
/// process killed between naming and renaming leaves a named file behind, and every write
/// first removes such files in its directory whose writing process is gone, so none
/// accumulates. The table is made readable by all (0644): controllers often run as other
/// users.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    remove_stale_temporaries(dir);
    #[cfg(target_os = "linux")]
    match unnamed::write(dir, path, bytes) {
        Err(e) if unnamed::unsupported(&e) => {}
        done => return done,
    }
    let (temporary, mut file) = create_named_temporary(dir)?;
    let written = fill(&mut file, bytes).and_then(|()| std::fs::rename(&temporary, path));
    if written.is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
    written?;
    sync_directory(dir);
    Ok(())
}

/// The prefix of the temporary files a write may leave when killed at the wrong moment;
/// the writer's process id follows it.
const TEMPORARY_PREFIX: &str = ".tablec-";
const TEMPORARY_SUFFIX: &str = ".tmp";

/// A fresh `.tablec-PID-N.tmp` name in `dir`.
fn temporary_name(dir: &Path, attempt: u32) -> std::path::PathBuf {
    use std::time::{SystemTime, UNIX_EPOCH};
    let nanos = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    dir.join(format!(
        "{TEMPORARY_PREFIX}{}-{nanos:09}{attempt}{TEMPORARY_SUFFIX}",
        std::process::id()
    ))
}

/// Creates a new, empty temporary file in `dir` (never opening an existing one).
fn create_named_temporary(dir: &Path) -> std::io::Result<(std::path::PathBuf, std::fs::File)> {
    let mut attempt = 0;
    loop {
        let name = temporary_name(dir, attempt);
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&name)
        {
            Ok(file) => return Ok((name, file)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && attempt < 100 => {
                attempt += 1
            }
            Err(e) => return Err(e),
        }
    }
}

/// Writes the bytes, sets the permissions and flushes them to the disk.
fn fill(file: &mut std::fs::File, bytes: &[u8]) -> std::io::Result<()> {
    file.write_all(bytes)?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        file.set_permissions(std::fs::Permissions::from_mode(0o644))?;
    }
    file.sync_all()
}

/// Flushes the directory entry of a rename (best effort: not every platform can).
fn sync_directory(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

/// Removes the `.tablec-PID-N.tmp` files in `dir` whose writing process no longer runs
/// (best effort: a file that cannot be removed is left).
pub fn remove_stale_temporaries(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(temporary_owner) else {
            continue;
        };
        if pid != std::process::id() && !process_alive(pid) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// The writer's process id of a temporary file name, or `None` for any other name.
fn temporary_owner(name: &str) -> Option<u32> {
    let rest = name
        .strip_prefix(TEMPORARY_PREFIX)?
        .strip_suffix(TEMPORARY_SUFFIX)?;
    let (pid, tail) = rest.split_once('-')?;
    if tail.is_empty() || !tail.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok()
}

/// Whether process `pid` exists. Where that cannot be known, it is taken to exist, so
/// that a live writer's file is never removed.
fn process_alive(pid: u32) -> bool {
    #[cfg(unix)]
    {
        let Ok(pid) = libc::pid_t::try_from(pid) else {
            return false;
        };
        // SAFETY: signal 0 checks only that the process exists; nothing is sent.
        let result = unsafe { libc::kill(pid, 0) };
        result == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
    }
    #[cfg(not(unix))]
    {
        let _ = pid;
        true
    }
}

/// Unnamed temporary files (`O_TMPFILE`), Linux only.
#[cfg(target_os = "linux")]
mod unnamed {
    use std::ffi::CString;
    use std::os::unix::ffi::OsStrExt;
    use std::os::unix::fs::OpenOptionsExt;
    use std::os::unix::io::AsRawFd;
    use std::path::Path;

    /// Whether `e` says the file system cannot make unnamed files (the caller then falls
    /// back to a named temporary).
    pub fn unsupported(e: &std::io::Error) -> bool {
        matches!(
            e.raw_os_error(),
            Some(libc::EOPNOTSUPP | libc::EISDIR | libc::EINVAL | libc::ENOENT)
        )
    }

    pub fn write(dir: &Path, path: &Path, bytes: &[u8]) -> std::io::Result<()> {
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_TMPFILE)
            .mode(0o644)
            .open(dir)?;
        super::fill(&mut file, bytes)?;
        // Named only now, complete; renamed over the target at once.
        let temporary = link(&file, dir)?;
        let renamed = std::fs::rename(&temporary, path);
        if renamed.is_err() {
            let _ = std::fs::remove_file(&temporary);
        }
        renamed?;
        super::sync_directory(dir);
        Ok(())
    }

    /// Gives the unnamed file a fresh temporary name in `dir`.
    fn link(file: &std::fs::File, dir: &Path) -> std::io::Result<std::path::PathBuf> {
        let source = CString::new(format!("/proc/self/fd/{}", file.as_raw_fd()))
            .map_err(std::io::Error::other)?;
        let mut attempt = 0;
        loop {
            let name = super::temporary_name(dir, attempt);
            let target =
                CString::new(name.as_os_str().as_bytes()).map_err(std::io::Error::other)?;
            // SAFETY: both paths are NUL-terminated strings that outlive the call.
            let result = unsafe {
                libc::linkat(
                    libc::AT_FDCWD,
                    source.as_ptr(),
                    libc::AT_FDCWD,
                    target.as_ptr(),
                    libc::AT_SYMLINK_FOLLOW,
                )
            };
            if result == 0 {
                return Ok(name);
            }
            let e = std::io::Error::last_os_error();
            if e.kind() != std::io::ErrorKind::AlreadyExists || attempt >= 100 {
                return Err(e);
            }
            attempt += 1;
        }
    }
}
