//! Table bytes with a valid header (magic, version, lengths, checksums recomputed after the
//! fuzzer's mutation), so that mutations reach rkyv validation and the semantic checks
//! rather than stopping at a checksum. Opening must never panic; a table that opens must
//! answer queries without panicking.

#![no_main]

use adwi_runtime::testing::repair_header;
use adwi_runtime::{Table, Target};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut bytes = data.to_vec();
    repair_header(&mut bytes);
    let Ok(table) = Table::from_vec(&bytes) else {
        return;
    };
    let grid = *table.grid();
    let lo = grid.origin_mm;
    let hi = grid.max_mm();
    // The grid's corners and centre, and targets read from the input's tail.
    let mut targets = vec![lo, hi, [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]))];
    for chunk in data.rchunks_exact(24).take(8) {
        let f = |i: usize| f64::from_le_bytes(chunk[i..i + 8].try_into().unwrap());
        targets.push([f(0), f(8), f(16)]);
    }
    for p in targets {
        for config in [None, Some(0), Some(4)] {
            let target = Target {
                position_mm: p,
                config,
            };
            let _ = table.query_target(&target);
            let _ = table.explain(&target);
            let _ = table.compensate(&target, 1e-6, 10);
        }
    }
});
