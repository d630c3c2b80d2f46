//! [`TableSwap`]: a table that can be replaced by a freshly built one while other threads
//! keep querying.
//!
//! # Design
//!
//! The current table sits behind an [`arc_swap::ArcSwap`]. A reader loads it with a few
//! atomic operations and no lock: it never blocks, whatever the writer does, and it always
//! sees one whole table, the old or the new, never a mixture — the pointer is swapped as a
//! unit, and a table is immutable once validated. `arc-swap` is used rather than a
//! hand-rolled `AtomicPtr` scheme because safe reclamation (knowing when no reader can
//! still hold the old pointer) is exactly the hard part, and `arc-swap` solves it with a
//! well-tested debt list.
//!
//! # Reclamation
//!
//! [`TableSwap::replace`] returns the previous table as [`Retired`], which still counts as a
//! holder: a reader that loaded the old table before the swap finishes its query on it and
//! lets go. The thread that swapped then calls [`Retired::wait_unused`] (or polls
//! [`Retired::try_into_table`]) and drops the old table itself. That keeps the cost of
//! freeing a table — an `munmap`, or freeing a large buffer — off the real-time threads.
//! Dropping a [`Retired`] early is safe, but the last reader then frees the table.
//!
//! # Real-time notes
//!
//! A thread's first load registers it with `arc-swap` (one small allocation, once per
//! thread, reused afterwards); make one query on each real-time thread before entering its
//! control loop. After that, queries through a `TableSwap` allocate nothing.

use std::ops::Deref;
use std::sync::Arc;
use std::time::Duration;

use arc_swap::ArcSwap;

use crate::{Compensation, Correction, Table, Target};

/// A table that readers query while a writer may replace it at any time.
///
/// ```
/// # fn demo(a: adwi_runtime::Table<Vec<u8>>, b: adwi_runtime::Table<Vec<u8>>) {
/// use adwi_runtime::TableSwap;
/// let live = TableSwap::new(a);
/// let before = live.query([2000.0, 700.0, 1000.0]);
/// // On another thread, after rebuilding:
/// let old = live.replace(b);
/// drop(old.wait_unused(std::time::Duration::from_micros(100)));
/// # }
/// ```
pub struct TableSwap<D> {
    current: ArcSwap<Table<D>>,
}

/// A borrowed view of the table that was current when [`TableSwap::current`] was called;
/// it stays valid (and unchanged) while held, even across a replacement.
pub struct Current<D>(arc_swap::Guard<Arc<Table<D>>>);

impl<D> Deref for Current<D> {
    type Target = Table<D>;

    #[inline]
    fn deref(&self) -> &Table<D> {
        &self.0
    }
}

/// A table taken out of service by [`TableSwap::replace`], possibly still in use by
/// readers that loaded it before the swap.
#[must_use = "dropping a retired table may move its reclamation onto a reader thread; \
              call `wait_unused` on the thread that swapped"]
pub struct Retired<D>(Arc<Table<D>>);

impl<D: AsRef<[u8]>> TableSwap<D> {
    /// Puts `table` into service.
    pub fn new(table: Table<D>) -> TableSwap<D> {
        TableSwap {
            current: ArcSwap::from_pointee(table),
        }
    }

    /// The current table. Lock-free; holding the result delays reclamation of this table
    /// only, never a replacement.
    #[inline]
    pub fn current(&self) -> Current<D> {
        Current(self.current.load())
    }

    /// [`Table::query`] on the current table. Never blocks, allocates (see the module's
    /// real-time notes) or panics.
    #[inline]
    pub fn query(&self, position_mm: [f64; 3]) -> Correction {
        self.current.load().query(position_mm)
    }

    /// [`Table::query_target`] on the current table.
    #[inline]
    pub fn query_target(&self, target: &Target) -> Correction {
        self.current.load().query_target(target)
    }

    /// [`Table::compensate`] on the current table: every iteration uses the same table,
    /// even if a replacement happens meanwhile.
    #[inline]
    pub fn compensate(
        &self,
        target: &Target,
        tolerance_mm: f64,
        max_iterations: u32,
    ) -> Compensation {
        self.current
            .load()
            .compensate(target, tolerance_mm, max_iterations)
    }

    /// Puts `table` into service atomically and returns the previous one. Readers that
    /// start after this call see `table`; readers already running finish on the old one.
    pub fn replace(&self, table: Table<D>) -> Retired<D> {
        Retired(self.current.swap(Arc::new(table)))
    }
}

impl<D> Retired<D> {
    /// Whether no reader holds the retired table any more.
    pub fn is_unused(&self) -> bool {
        Arc::strong_count(&self.0) == 1
    }

    /// The retired table, once no reader holds it; otherwise `self` back.
    ///
    /// # Errors
    ///
    /// `Err(self)` while a reader still holds the table.
    pub fn try_into_table(self) -> Result<Table<D>, Retired<D>> {
        Arc::try_unwrap(self.0).map_err(Retired)
    }

    /// Waits until no reader holds the retired table, sleeping `poll` between checks,
    /// and returns it for the caller to drop (or reuse). Readers hold a table for one
    /// query or one compensation, so this returns within microseconds unless a reader
    /// keeps a [`Current`] for long.
    pub fn wait_unused(self, poll: Duration) -> Table<D> {
        let mut retired = self;
        loop {
            match retired.try_into_table() {
                Ok(table) => return table,
                Err(again) => {
                    retired = again;
                    std::thread::sleep(poll);
                }
            }
        }
    }
}
