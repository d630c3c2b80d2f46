//! Writing output files so that nothing is ever lost: no partial file, no damaged
//! existing file, no temporary file left behind, no input overwritten — one writer for
//! every output of every command ([`OutputPlan`]).
//!
//! The policy sits at the bottom of the workspace, below every crate that writes a file
//! (tables, programs, reports, samples): it depends on nothing of adwi, so each writer
//! takes it without taking the table compiler.

use std::io::Write;
use std::path::{Path, PathBuf};

/// What an output file holds: its bytes, or what writes them, for an output too large to
/// hold in memory beside what it is made from (an evaluation's per-point JSON of a million
/// samples is a gigabyte of text). Either is written to a temporary file and renamed into
/// place with the plan's other outputs, all or nothing.
#[derive(Clone, Copy)]
pub enum Content<'a> {
    /// The bytes themselves.
    Bytes(&'a [u8]),
    /// A writer of them, given a buffered writer to the temporary file; an error it returns
    /// leaves nothing written.
    Written(&'a dyn Fn(&mut dyn Write) -> std::io::Result<()>),
}

/// Why an output was refused before any work, or could not be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The output is one of the command's inputs.
    #[error(
        "refusing to write {}: it is the input {} (the same file{}); choose another output",
        output.display(),
        input.display(),
        if *through_link { ", through a link" } else { "" }
    )]
    IsInput {
        /// The output as given.
        output: PathBuf,
        /// The input it is.
        input: PathBuf,
        /// Whether the two names differ (a symbolic or hard link joins them).
        through_link: bool,
    },
    /// Two outputs of one command are the same file: one would silently replace the other.
    #[error(
        "refusing to write {} and {}: they are the same file; give two different outputs",
        first.display(),
        second.display()
    )]
    SameOutput {
        /// The first output.
        first: PathBuf,
        /// The second, the same file.
        second: PathBuf,
    },
    /// The output exists and is not a regular file (or a symbolic link to one): a
    /// directory, a FIFO, a device or a socket is never replaced by a file.
    #[error(
        "refusing to write {}: it exists and is {kind}, not a regular file; give a file name",
        path.display()
    )]
    NotRegular {
        /// The output as given.
        path: PathBuf,
        /// What it is (`a directory`, `a FIFO`, ...).
        kind: &'static str,
    },
    /// The output's directory does not exist (or, for a directory the command creates, a
    /// file stands where a directory of its path would be).
    #[error(
        "cannot write {}: {} is not an existing directory",
        path.display(),
        dir.display()
    )]
    NoDirectory {
        /// The output as given.
        path: PathBuf,
        /// Its directory.
        dir: PathBuf,
    },
    /// Writing failed (nothing was replaced).
    #[error("cannot write {}", path.display())]
    Write {
        /// The output as given.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

/// Refuses to write `output` when it is one of `inputs` — the same file, also through a
/// symbolic or hard link — before anything is written: a mistyped output path must never
/// replace the calibration data it was computed from. Inputs that do not exist are
/// skipped, and an output that does not exist yet cannot be an input.
///
/// # Errors
///
/// [`OutputError::IsInput`], naming the output and the input it is.
pub fn refuse_overwriting(output: &Path, inputs: &[&Path]) -> Result<(), OutputError> {
    let Ok(out) = std::fs::metadata(output) else {
        return Ok(());
    };
    for input in inputs {
        let Ok(inp) = std::fs::metadata(input) else {
            continue;
        };
        if same_file(&out, &inp, output, input) {
            return Err(OutputError::IsInput {
                output: output.to_path_buf(),
                input: input.to_path_buf(),
                through_link: output != *input,
            });
        }
    }
    Ok(())
}

/// The outputs of one command, checked before any work and written all or nothing.
///
/// [`OutputPlan::check`] refuses, before the command does anything: an output that is an
/// input ([`refuse_overwriting`]), two outputs that are the same file, an existing output
/// that is not a regular file (a symbolic link to a regular file is written through: its
/// target is replaced), and an output whose directory does not exist (unless the command
/// creates it: [`OutputPlan::check_in_new_directory`]). [`OutputPlan::write`] then writes
/// every file complete to a temporary beside its target and renames them into place only
/// once all are complete: a failure, a full disk or a kill leaves every existing file as
/// it was.
#[derive(Debug, Clone, Default)]
pub struct OutputPlan {
    outputs: Vec<Planned>,
}

#[derive(Debug, Clone)]
struct Planned {
    /// As given, for messages and for [`OutputPlan::write`]'s lookup.
    given: PathBuf,
    /// Where the bytes go: `given`, or the file a symbolic link at `given` points to.
    target: PathBuf,
    /// Whether its directory is created at write time.
    create_directory: bool,
}

impl OutputPlan {
    /// Checks `outputs` against `inputs` and each other (the type's docs).
    ///
    /// # Errors
    ///
    /// The first refusal, as an [`OutputError`].
    pub fn check(outputs: &[&Path], inputs: &[&Path]) -> Result<OutputPlan, OutputError> {
        let mut plan = OutputPlan::default();
        for output in outputs {
            plan.add(output, inputs, false)?;
        }
        Ok(plan)
    }

    /// Adds an output whose directory the command creates when it writes (a report's
    /// folder), checked as [`OutputPlan::check`] checks the others, except that a symbolic
    /// link already at `output` is never followed: the user named the folder, not what a
    /// link in it points to, so the link itself is replaced by the new file.
    ///
    /// # Errors
    ///
    /// As [`OutputPlan::check`].
    pub fn check_in_new_directory(
        &mut self,
        output: &Path,
        inputs: &[&Path],
    ) -> Result<(), OutputError> {
        self.add(output, inputs, true)
    }

    fn add(&mut self, output: &Path, inputs: &[&Path], create: bool) -> Result<(), OutputError> {
        refuse_overwriting(output, inputs)?;
        let target = if create {
            in_folder_target(output)?
        } else {
            regular_target(output)?
        };
        let dir = directory_of(&target);
        // A directory the command creates must be creatable: its nearest existing
        // ancestor a directory.
        let existing = if create {
            dir.ancestors()
                .find(|a| a.as_os_str().is_empty() || a.exists())
        } else {
            Some(dir)
        };
        if !existing.is_some_and(|d| d.as_os_str().is_empty() || d.is_dir()) {
            return Err(OutputError::NoDirectory {
                path: output.to_path_buf(),
                dir: existing.unwrap_or(dir).to_path_buf(),
            });
        }
        for other in &self.outputs {
            if other.target == target || same_existing(&other.target, &target) {
                return Err(OutputError::SameOutput {
                    first: other.given.clone(),
                    second: output.to_path_buf(),
                });
            }
        }
        self.outputs.push(Planned {
            given: output.to_path_buf(),
            target,
            create_directory: create,
        });
        Ok(())
    }

    /// The outputs, as given.
    pub fn paths(&self) -> impl Iterator<Item = &Path> {
        self.outputs.iter().map(|o| o.given.as_path())
    }

    /// Writes `contents` (each output's path as given, and its bytes) all or nothing:
    /// every file complete beside its target first, then every rename. An output of the
    /// plan missing from `contents` is not written; a path not in the plan is an error
    /// (a bug in the caller), as is a file that stopped being regular since the check.
    ///
    /// # Errors
    ///
    /// [`OutputError::Write`] (nothing was replaced), or a refusal found again.
    pub fn write(&self, contents: &[(&Path, &[u8])]) -> Result<(), OutputError> {
        let contents: Vec<(&Path, Content<'_>)> = contents
            .iter()
            .map(|&(path, bytes)| (path, Content::Bytes(bytes)))
            .collect();
        self.write_contents(&contents)
    }

    /// [`OutputPlan::write`] of outputs given as [`Content`]: bytes, or what writes them.
    ///
    /// # Errors
    ///
    /// As [`OutputPlan::write`]; a writer's error is [`OutputError::Write`] of its output.
    pub fn write_contents(&self, contents: &[(&Path, Content<'_>)]) -> Result<(), OutputError> {
        let mut staged: Vec<(PathBuf, &Planned)> = Vec::with_capacity(contents.len());
        let result = (|| {
            for (path, content) in contents {
                let planned = self
                    .outputs
                    .iter()
                    .find(|o| o.given == *path)
                    .ok_or_else(|| OutputError::Write {
                        path: path.to_path_buf(),
                        source: std::io::Error::other("not an output checked before the work"),
                    })?;
                // Checked again: the file may have been replaced since.
                if planned.create_directory {
                    in_folder_target(&planned.given)?;
                } else {
                    regular_target(&planned.given)?;
                }
                let dir = directory_of(&planned.target);
                let failed = |source| OutputError::Write {
                    path: planned.given.clone(),
                    source,
                };
                if planned.create_directory {
                    std::fs::create_dir_all(dir).map_err(failed)?;
                }
                remove_stale_temporaries(dir);
                let temporary = stage(dir, content).map_err(|source| OutputError::Write {
                    path: planned.given.clone(),
                    source,
                })?;
                staged.push((temporary, planned));
            }
            Ok(())
        })();
        if let Err(e) = result {
            for (temporary, _) in &staged {
                let _ = std::fs::remove_file(temporary);
            }
            return Err(e);
        }
        // Two writers of the same outputs (a program and its report, say) rename one after
        // the other, never interleaved: the outputs always come from one run.
        let _lock = lock_directories(staged.iter().map(|(_, p)| directory_of(&p.target)));
        for (i, (temporary, planned)) in staged.iter().enumerate() {
            if let Err(source) = std::fs::rename(temporary, &planned.target) {
                for (later, _) in &staged[i..] {
                    let _ = std::fs::remove_file(later);
                }
                return Err(OutputError::Write {
                    path: planned.given.clone(),
                    source,
                });
            }
            sync_directory(directory_of(&planned.target));
        }
        Ok(())
    }
}

/// An exclusive lock on each of `dirs` (`flock` on the directory itself, so that no lock
/// file is left behind), taken in one order by every writer so that two never wait on each
/// other; released when the returned files are dropped. Best effort: a directory that
/// cannot be opened or locked is written without.
fn lock_directories<'a>(dirs: impl Iterator<Item = &'a Path>) -> Vec<std::fs::File> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        use std::os::unix::io::AsRawFd;
        let mut open: Vec<((u64, u64), std::fs::File)> = dirs
            .filter_map(|d| {
                let file = std::fs::File::open(d).ok()?;
                let m = file.metadata().ok()?;
                Some(((m.dev(), m.ino()), file))
            })
            .collect();
        open.sort_by_key(|(id, _)| *id);
        open.dedup_by_key(|(id, _)| *id);
        open.into_iter()
            .filter_map(|(_, file)| loop {
                // SAFETY: `file` is an open descriptor for the whole call.
                if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX) } == 0 {
                    break Some(file);
                }
                if std::io::Error::last_os_error().kind() != std::io::ErrorKind::Interrupted {
                    break None;
                }
            })
            .collect()
    }
    #[cfg(not(unix))]
    {
        let _ = dirs.count();
        Vec::new()
    }
}

/// Where writing `output` puts its bytes: the path itself when it does not exist or is a
/// regular file, the file a symbolic link points to when it points to a regular file (or
/// to nothing yet); a refusal for anything else.
fn regular_target(output: &Path) -> Result<PathBuf, OutputError> {
    let refuse = |kind| OutputError::NotRegular {
        path: output.to_path_buf(),
        kind,
    };
    let Ok(link) = std::fs::symlink_metadata(output) else {
        return Ok(output.to_path_buf());
    };
    if link.file_type().is_symlink() {
        let target = match std::fs::read_link(output) {
            Ok(t) if t.is_absolute() => t,
            Ok(t) => directory_of(output).join(t),
            Err(_) => return Err(refuse("an unreadable symbolic link")),
        };
        return match std::fs::metadata(&target) {
            Ok(m) if m.is_file() => Ok(target),
            Ok(m) => Err(refuse(kind_of(&m))),
            // A dangling link: the file it names is created.
            Err(_) => Ok(target),
        };
    }
    if link.is_file() {
        Ok(output.to_path_buf())
    } else {
        Err(refuse(kind_of(&link)))
    }
}

/// Where writing a file inside a report's folder puts its bytes: always the path itself,
/// a symbolic link there included (the rename replaces the link, never its target); a
/// refusal for a directory, a FIFO or a device there.
fn in_folder_target(output: &Path) -> Result<PathBuf, OutputError> {
    match std::fs::symlink_metadata(output) {
        Ok(m) if !(m.is_file() || m.file_type().is_symlink()) => Err(OutputError::NotRegular {
            path: output.to_path_buf(),
            kind: kind_of(&m),
        }),
        _ => Ok(output.to_path_buf()),
    }
}

/// What a file that is not regular is, in words.
fn kind_of(m: &std::fs::Metadata) -> &'static str {
    if m.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = m.file_type();
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "not a regular file"
}

/// The directory a file is written in (`.` for a bare name).
fn directory_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Whether two paths name one existing file.
fn same_existing(a: &Path, b: &Path) -> bool {
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(ma), Ok(mb)) => same_file(&ma, &mb, a, b),
        _ => false,
    }
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

/// Writes `bytes` to `path` so that no reader, crash or kill ever sees a partial file and
/// an existing file at `path` (even a table mapped by a running controller) stays intact
/// until the complete new one replaces it by rename: [`OutputPlan`] with one output and no
/// inputs. An existing `path` that is not a regular file is refused.
///
/// On Linux the data goes to an unnamed `O_TMPFILE` file in the target directory, which
/// the kernel frees if the process dies before it is named; once written and flushed it is
/// linked as `.tablec-PID-N.tmp` and renamed into place. Elsewhere (or on file systems
/// without `O_TMPFILE`) it is written under that name from the start. Either way a process
/// killed between naming and renaming leaves a named file behind, and every write first
/// removes such files in its directory whose writing process is gone, so none accumulates.
/// The file is made readable by all (0644): controllers often run as other users.
///
/// # Errors
///
/// As [`OutputPlan::check`] and [`OutputPlan::write`].
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    OutputPlan::check(&[path], &[])?.write(&[(path, bytes)])
}

/// Writes `content` complete and flushed to a fresh temporary file in `dir`, and returns
/// its name.
fn stage(dir: &Path, content: &Content<'_>) -> std::io::Result<PathBuf> {
    #[cfg(target_os = "linux")]
    match unnamed::stage(dir, content) {
        Err(e) if unnamed::unsupported(&e) => {}
        done => return done,
    }
    let (temporary, mut file) = create_named_temporary(dir)?;
    if let Err(e) = fill(&mut file, content) {
        let _ = std::fs::remove_file(&temporary);
        return Err(e);
    }
    Ok(temporary)
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

/// Writes the content, sets the permissions and flushes them to the disk.
fn fill(file: &mut std::fs::File, content: &Content<'_>) -> std::io::Result<()> {
    match content {
        Content::Bytes(bytes) => file.write_all(bytes)?,
        Content::Written(write) => {
            let mut buffered = std::io::BufWriter::new(&mut *file);
            write(&mut buffered)?;
            buffered.flush()?;
        }
    }
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

    /// Writes `content` to an unnamed file in `dir` and names it once complete.
    pub fn stage(dir: &Path, content: &super::Content<'_>) -> std::io::Result<std::path::PathBuf> {
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_TMPFILE)
            .mode(0o644)
            .open(dir)?;
        super::fill(&mut file, content)?;
        link(&file, dir)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The files of `dir`, by name.
    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_written_output_is_what_its_writer_wrote_beside_the_others() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.json"), dir.path().join("b.txt"));
        let plan = OutputPlan::check(&[&a, &b], &[]).unwrap();
        let write = |w: &mut dyn Write| {
            for i in 0..100_000 {
                writeln!(w, "{i}")?;
            }
            Ok(())
        };
        plan.write_contents(&[(&a, Content::Written(&write)), (&b, Content::Bytes(b"b"))])
            .unwrap();
        let expected: String = (0..100_000).map(|i| format!("{i}\n")).collect();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), expected);
        assert_eq!(std::fs::read(&b).unwrap(), b"b");
        assert_eq!(names(dir.path()), ["a.json", "b.txt"]);
    }

    #[test]
    fn a_failing_writer_replaces_nothing_and_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.json"), dir.path().join("b.txt"));
        std::fs::write(&a, "old a").unwrap();
        std::fs::write(&b, "old b").unwrap();
        let plan = OutputPlan::check(&[&b, &a], &[]).unwrap();
        let failing = |w: &mut dyn Write| {
            w.write_all(&[b'x'; 100_000])?;
            Err(std::io::Error::other("the encoder failed"))
        };
        let e = plan
            .write_contents(&[
                (&b, Content::Bytes(b"new b")),
                (&a, Content::Written(&failing)),
            ])
            .unwrap_err();
        let cause = std::error::Error::source(&e).map(ToString::to_string);
        assert_eq!(cause.as_deref(), Some("the encoder failed"), "{e}");
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "old b");
        assert_eq!(names(dir.path()), ["a.json", "b.txt"]);
    }
}
