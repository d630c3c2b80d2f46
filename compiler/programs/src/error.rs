//! What can go wrong before or while a program is compensated.

use std::path::PathBuf;

/// Why a compensation job could not be made or run. Every error about a program names
/// the file, line and column; nothing is written when one occurs.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A program that does not read as its format: file, line and column (1-based, the
    /// column in bytes), and what was expected.
    #[error(
        "{}:{line}:{column}: {}",
        escape_controls(file),
        escape_controls(message)
    )]
    Syntax {
        /// The program file, as given.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column, in bytes.
        column: usize,
        /// What is wrong there.
        message: String,
    },
    /// An option, or a combination of options and inputs, that cannot work.
    #[error("{0}")]
    Option(String),
    /// An option the inputs it is used with cannot take, found once they are read (turn
    /// axes the robot has not, or that the controller's file contradicts): a usage error,
    /// as an option refused before any file is read.
    #[error("{0}")]
    OptionMisfit(String),
    /// A file could not be read.
    #[error("cannot read {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The table could not be opened.
    #[error("cannot open table {path}: {source}")]
    Table {
        /// The table file.
        path: PathBuf,
        /// Why.
        #[source]
        source: adwi_runtime::OpenError,
    },
    /// The robot file could not be loaded or does not fit the table.
    #[error("cannot use the robot {path}: {message}")]
    Robot {
        /// The robot file.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// The program would take longer to compensate than the job allows: refused before
    /// any target is corrected, with its size and the estimate. Reading stops once the
    /// targets read exceed the bound, so a huge program is refused as fast as a small one.
    #[error(
        "{file}: {bytes} bytes, {}: about {seconds:.0} s of work, more than the \
         {limit_seconds} s allowed (max_seconds); refused before any",
        if let Some(at) = read_bytes { format!("more than {targets} targets in its first {at} bytes") } else { format!("{targets} targets") }
    )]
    TooLarge {
        /// The program file.
        file: String,
        /// Its size.
        bytes: usize,
        /// The targets read.
        targets: usize,
        /// The bytes read before reading stopped, when it stopped early.
        read_bytes: Option<usize>,
        /// The estimated work, seconds (extrapolated by the file's size when reading
        /// stopped early).
        seconds: f64,
        /// The bound, seconds.
        limit_seconds: f64,
    },
    /// The program would take more memory than the job allows: refused before any target
    /// is corrected, with its size and the estimate. Reading stops once the targets read
    /// exceed the bound, so a huge program is refused without being held.
    #[error(
        "{file}: {bytes} bytes, {}: about {} MB of memory, more than the {} MB allowed \
         (max_memory_bytes); refused before any work",
        if let Some(at) = read_bytes { format!("more than {targets} targets in its first {at} bytes") } else { format!("{targets} targets") },
        estimated_bytes.div_ceil(1_000_000),
        limit_bytes / 1_000_000
    )]
    TooMuchMemory {
        /// The program file.
        file: String,
        /// Its size.
        bytes: usize,
        /// The targets read.
        targets: usize,
        /// The bytes read before reading stopped, when it stopped early.
        read_bytes: Option<usize>,
        /// The estimated memory, bytes (extrapolated by the file's size when reading
        /// stopped early).
        estimated_bytes: u64,
        /// The bound, bytes.
        limit_bytes: u64,
    },
    /// `strict`: some target was not corrected, so nothing is written.
    #[error(
        "{not_corrected} of {total} targets not corrected (strict: nothing written); the first: {}",
        escape_controls(first)
    )]
    NotAllCorrected {
        /// Targets left unchanged.
        not_corrected: usize,
        /// Targets in the program.
        total: usize,
        /// The first of them: name, place and status.
        first: String,
    },
    /// The output would replace an input (or another output), or could not be written.
    #[error(transparent)]
    Write(#[from] adwi_output::OutputError),
}

/// `text` with every control character (and every character that reorders text on a
/// terminal) escaped as Rust writes it (`\u{1b}`, `\t`): a message that quotes a file's
/// bytes never sends a terminal an escape sequence.
pub fn escape_controls(text: &str) -> std::borrow::Cow<'_, str> {
    let hostile =
        |c: char| c.is_control() || matches!(c, '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}');
    if !text.chars().any(hostile) {
        return std::borrow::Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        if hostile(c) {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    std::borrow::Cow::Owned(out)
}
