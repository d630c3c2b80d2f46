//! Why a table was refused at open.

use std::fmt;

/// A table that cannot be opened, and why. Every variant is detected at open; after a
/// successful open nothing is checked again and nothing can fail.
#[derive(Debug)]
#[non_exhaustive]
pub enum OpenError {
    /// Reading or mapping the file failed.
    Io(std::io::Error),
    /// The file is shorter than its header says it must be.
    Truncated {
        /// The length found, bytes.
        len: u64,
        /// The length needed, bytes.
        needed: u64,
    },
    /// The file is longer than its header says: bytes were appended.
    TrailingBytes {
        /// The length found, bytes.
        len: u64,
        /// The length the header gives, bytes.
        expected: u64,
    },
    /// The first eight bytes are not the table magic: not a table file.
    BadMagic,
    /// The endianness mark reads wrong: written or read with the other byte order.
    Endianness {
        /// The mark as read.
        mark: u16,
    },
    /// The format version is outside what this runtime reads.
    UnsupportedVersion {
        /// The file's version.
        found: u16,
        /// The oldest version this runtime reads.
        oldest: u16,
        /// The newest version this runtime reads.
        newest: u16,
    },
    /// The table was written by an rkyv build with other format features.
    RkyvFormat {
        /// The file's flags.
        found: u32,
        /// This runtime's flags.
        expected: u32,
    },
    /// The header's checksum does not match its contents.
    HeaderChecksum {
        /// The checksum stored in the file.
        stored: u64,
        /// The checksum of the bytes read.
        computed: u64,
    },
    /// The payload's checksum does not match its contents.
    PayloadChecksum {
        /// The checksum stored in the header.
        stored: u64,
        /// The checksum of the bytes read.
        computed: u64,
    },
    /// The buffer handed to [`crate::Table::from_bytes`] is not 16-byte aligned.
    Misaligned {
        /// The buffer's address modulo 16.
        offset: usize,
    },
    /// The payload is not a valid archive (bounds, alignment, overlap).
    Archive(String),
    /// The archive is well formed but breaks an invariant of the table.
    Corrupt {
        /// The invariant broken.
        what: &'static str,
    },
    /// A parameter, grid field or stored value is outside the range any real table
    /// respects (an ε of 1e300 mm, say), though the checksums are intact.
    Implausible(crate::format::Implausible),
    /// The memory for a copy of the table could not be allocated ([`crate::AlignedBytes`]).
    OutOfMemory {
        /// The table's length, bytes.
        len: u64,
    },
    /// Locking the table in memory was required and failed
    /// ([`crate::residency::Lock::Required`]).
    Lock(std::io::Error),
}

impl fmt::Display for OpenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const REBUILD: &str = "rebuild the table with `tablec build`";
        match self {
            OpenError::Io(e) => write!(f, "cannot read the table: {e}"),
            OpenError::Truncated { len, needed } => write!(
                f,
                "table is truncated: {len} bytes, at least {needed} needed; {REBUILD}"
            ),
            OpenError::TrailingBytes { len, expected } => write!(
                f,
                "table has {len} bytes where its header says {expected}; {REBUILD}"
            ),
            OpenError::BadMagic => write!(f, "not a correction table (wrong magic bytes)"),
            OpenError::Endianness { mark } => write!(
                f,
                "table byte order mark is {mark:#06x}, expected 0xfeff: written for another \
                 byte order; {REBUILD}"
            ),
            OpenError::UnsupportedVersion {
                found,
                oldest,
                newest,
            } => write!(
                f,
                "table format version {found} is not supported: this runtime reads versions \
                 {oldest} to {newest}; {REBUILD} of a matching version"
            ),
            OpenError::RkyvFormat { found, expected } => write!(
                f,
                "table archive format flags {found:#x} differ from this runtime's {expected:#x}; \
                 {REBUILD}"
            ),
            OpenError::HeaderChecksum { stored, computed } => write!(
                f,
                "table header is corrupt: checksum {computed:#018x} where {stored:#018x} was \
                 stored; {REBUILD}"
            ),
            OpenError::PayloadChecksum { stored, computed } => write!(
                f,
                "table contents are corrupt: checksum {computed:#018x} where {stored:#018x} was \
                 stored; {REBUILD}"
            ),
            OpenError::Misaligned { offset } => write!(
                f,
                "table buffer starts {offset} bytes past a 16-byte boundary; copy it into \
                 aligned memory first (Table::from_vec)"
            ),
            OpenError::Archive(reason) => {
                write!(f, "table archive is invalid: {reason}; {REBUILD}")
            }
            OpenError::Corrupt { what } => write!(f, "table is inconsistent: {what}; {REBUILD}"),
            OpenError::Implausible(e) => {
                write!(f, "table holds an implausible value: {e}; {REBUILD}")
            }
            OpenError::OutOfMemory { len } => write!(
                f,
                "cannot allocate {len} bytes for a copy of the table; open the file by memory \
                 map instead, or free memory"
            ),
            OpenError::Lock(e) => write!(
                f,
                "cannot lock the table in memory: {e}; raise the locked-memory limit \
                 (ulimit -l) or open without requiring the lock"
            ),
        }
    }
}

/// No `source`: the message of every variant already includes its cause (C callers get
/// one string, [`crate::capi::adwi_last_open_error`]), and a chain printer would print the
/// OS error twice. The I/O error itself is in the variant.
impl std::error::Error for OpenError {}

impl From<std::io::Error> for OpenError {
    fn from(e: std::io::Error) -> OpenError {
        OpenError::Io(e)
    }
}
