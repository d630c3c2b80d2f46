//! Keeping a mapped table in memory: prefaulting and locking at open, so that no query on
//! a real-time thread ever waits for the disk.
//!
//! A memory-mapped table is read through the page cache. Validation at open computes a
//! checksum over every byte, so every page is resident when [`crate::Table::open`] returns; but
//! clean file-backed pages may be evicted later under memory pressure, and the next query
//! touching one would then block on a page fault that reads the disk. Locking the mapping
//! (`mlock`) keeps the pages resident for the table's lifetime. Locking can fail where the
//! process's locked-memory limit (`RLIMIT_MEMLOCK`, `ulimit -l`) is too small; whether that
//! failure is fatal is the caller's choice ([`Lock`]).

/// Whether to lock a table's pages in memory at open.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Lock {
    /// Do not lock: pages may be evicted under memory pressure and faulted back in by a
    /// query.
    #[default]
    No,
    /// Try to lock; a failure is reported in [`Residency::lock_error`] and the table opens
    /// anyway.
    BestEffort,
    /// Lock or refuse to open ([`crate::OpenError::Lock`]).
    Required,
}

/// How [`crate::Table::open_with`] maps a table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OpenOptions {
    /// Ask the kernel to fault every page in while mapping (`MAP_POPULATE` on Linux,
    /// ignored elsewhere), then touch one byte of every page before validating. Validation
    /// reads every byte anyway; prefaulting makes that read one bulk operation and
    /// guarantees residency on platforms without `MAP_POPULATE`.
    pub prefault: bool,
    /// Whether to `mlock` the mapping.
    pub lock: Lock,
}

impl OpenOptions {
    /// What a real-time controller wants: prefault, and lock if the OS allows it.
    pub fn real_time() -> OpenOptions {
        OpenOptions {
            prefault: true,
            lock: Lock::BestEffort,
        }
    }
}

/// What [`crate::Table::open_with`] achieved about keeping the table in memory.
#[derive(Debug)]
pub struct Residency {
    /// The number of pages touched by prefaulting (0 without [`OpenOptions::prefault`]).
    pub pages_touched: usize,
    /// Whether the mapping is locked in memory for the table's lifetime.
    pub locked: bool,
    /// Why locking failed, with [`Lock::BestEffort`]; `None` when locked or not asked to.
    pub lock_error: Option<std::io::Error>,
}

/// The page size assumed when touching pages: the smallest in use on supported platforms.
/// Touching more often than the real page size costs a few extra reads, never a missed
/// page.
const TOUCH_STRIDE: usize = 4096;

/// Reads one byte of every page of `bytes`, so that each is faulted in now rather than by
/// a later query. Returns the number of pages touched.
pub(crate) fn touch_pages(bytes: &[u8]) -> usize {
    let mut pages = 0;
    let mut sum = 0u8;
    for page in bytes.chunks(TOUCH_STRIDE) {
        // `black_box` keeps the otherwise unused reads from being optimised away.
        sum = sum.wrapping_add(std::hint::black_box(page[0]));
        pages += 1;
    }
    std::hint::black_box(sum);
    pages
}
