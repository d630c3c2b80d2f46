//! Real-time handling of live tables: replacing a table while other threads query it, and
//! opening with prefaulting and memory locking.

use crate::common;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use adwi_runtime::{Correction, Lock, OpenError, OpenOptions, Status, Table, TableSwap};

const READERS: usize = 3;
const SWAPS: usize = 2_000;

#[test]
fn readers_see_one_whole_table_or_the_other_while_it_is_replaced() {
    // Two tables over the same lattice whose errors differ by a factor of two, so that
    // every answer says which table gave it.
    let bytes_a = common::lattice_table(3, 1.0);
    let bytes_b = common::lattice_table(3, 2.0);
    let a = Table::from_vec(&bytes_a).unwrap();
    let b = Table::from_vec(&bytes_b).unwrap();
    let targets = common::targets(5, 512);
    let answers: Vec<(Correction, Correction)> =
        targets.iter().map(|&p| (a.query(p), b.query(p))).collect();
    let differing = answers
        .iter()
        .filter(|(x, y)| x.status == Status::Ok && x != y)
        .count();
    assert!(differing > 500, "the tables must differ: {differing}");

    let live = TableSwap::new(a);
    let stop = AtomicBool::new(false);
    let seen_a = AtomicU64::new(0);
    let seen_b = AtomicU64::new(0);
    std::thread::scope(|s| {
        for reader in 0..READERS {
            let (live, stop, targets, answers) = (&live, &stop, &targets, &answers);
            let (seen_a, seen_b) = (&seen_a, &seen_b);
            s.spawn(move || {
                let mut i = reader;
                while !stop.load(Ordering::Relaxed) {
                    let k = i % targets.len();
                    let c = live.query(targets[k]);
                    let (from_a, from_b) = answers[k];
                    if c == from_a {
                        seen_a.fetch_add(1, Ordering::Relaxed);
                    } else if c == from_b {
                        seen_b.fetch_add(1, Ordering::Relaxed);
                    } else {
                        panic!("target {:?}: {c:?} is neither table's answer", targets[k]);
                    }
                    // A whole compensation runs on one table, even across a swap.
                    let comp = live.compensate(&adwi_runtime::Target::at(targets[k]), 1e-9, 5);
                    let first = comp.correction;
                    assert!(first.status != Status::InvalidInput, "{first:?}");
                    i += 1;
                }
            });
        }
        let mut spare = Some(b);
        for swap in 0..SWAPS {
            let next = spare.take().unwrap();
            let retired = live.replace(next);
            // The old table is reclaimed here, on the swapping thread, once unused.
            spare = Some(retired.wait_unused(Duration::from_micros(10)));
            if swap % 100 == 0 {
                std::thread::sleep(Duration::from_millis(1));
            }
        }
        stop.store(true, Ordering::Relaxed);
    });
    let (na, nb) = (seen_a.into_inner(), seen_b.into_inner());
    assert!(
        na > 0 && nb > 0,
        "readers saw table a {na} times, b {nb} times"
    );
}

#[test]
fn a_retired_table_is_held_while_a_reader_uses_it() {
    let bytes = common::lattice_table(3, 1.0);
    let live = TableSwap::new(Table::from_vec(&bytes).unwrap());
    let p = common::targets(9, 1)[0];
    let held = live.current();
    let before = held.query(p);
    let retired = live.replace(Table::from_vec(common::lattice_table(3, 2.0)).unwrap());
    assert!(!retired.is_unused(), "a reader still holds the old table");
    // The reader's view is unchanged by the replacement; new readers see the new table.
    assert_eq!(held.query(p), before);
    assert_ne!(live.query(p), before);
    let retired = match retired.try_into_table() {
        Ok(_) => panic!("taken back while held"),
        Err(r) => r,
    };
    drop(held);
    assert!(retired.is_unused());
    let old = retired.wait_unused(Duration::from_micros(1));
    assert_eq!(old.query(p), before);
}

#[test]
fn open_with_prefaults_and_locks_or_reports_why_not() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lattice.tbl");
    let bytes = common::lattice_table(3, 1.0);
    std::fs::write(&path, &bytes).unwrap();
    let p = common::targets(9, 1)[0];
    let expected = Table::from_vec(&bytes).unwrap().query(p);

    // SAFETY: the file is private to this test and not modified while mapped.
    let (table, residency) = unsafe { Table::open_with(&path, OpenOptions::real_time()) }.unwrap();
    assert_eq!(table.query(p), expected);
    assert_eq!(residency.pages_touched, bytes.len().div_ceil(4096));
    // Best effort: either locked, or the reason is reported and the table works anyway.
    assert_eq!(residency.locked, residency.lock_error.is_none());

    let required = OpenOptions {
        prefault: false,
        lock: Lock::Required,
    };
    // SAFETY: as above.
    match unsafe { Table::open_with(&path, required) } {
        Ok((table, residency)) => {
            assert!(residency.locked);
            assert_eq!(residency.pages_touched, 0);
            assert_eq!(table.query(p), expected);
        }
        Err(OpenError::Lock(e)) => {
            // Only where mlock is not allowed, and then best effort must have said so.
            assert!(
                !residency.locked,
                "locking failed only the second time: {e}"
            );
        }
        Err(e) => panic!("unexpected error: {e}"),
    }

    // SAFETY: as above.
    let (table, residency) = unsafe { Table::open_with(&path, OpenOptions::default()) }.unwrap();
    assert!(!residency.locked && residency.lock_error.is_none());
    assert_eq!(table.query(p), expected);
}
