//! Table bytes with a valid header (magic, version, lengths, checksums recomputed after the
//! fuzzer's mutation), so that mutations reach rkyv validation and the semantic checks
//! rather than stopping at a checksum. Opening must never panic; a table that opens must
//! answer queries (with and without joint angles) without panicking, and never with
//! status ok and a non-finite value.

#![no_main]

use adwi_runtime::testing::repair_header;
use adwi_runtime::{Correction, Status, Table, Target};
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
    let words: Vec<f64> = data
        .rchunks_exact(8)
        .take(48)
        .map(|w| f64::from_le_bytes(w.try_into().unwrap()))
        .collect();
    for p in words.chunks_exact(3).take(8) {
        targets.push([p[0], p[1], p[2]]);
    }
    // Joint angles: none moved, a sample's, read from the input's tail, not finite.
    let mut joints = vec![[0.0; 6], [0.0, 0.0, 0.0, 0.0, 0.0, f64::NAN]];
    if let Some(adwi_runtime::Payload::V2(d)) = table.payload() {
        if let Some(q) = d.joints_rad.get(..6) {
            joints.push(std::array::from_fn(|i| q[i].to_native()));
        }
    }
    for q in words.chunks_exact(6).take(2) {
        joints.push([q[0], q[1], q[2], q[3], q[4], q[5]]);
    }
    for p in targets {
        for config in [None, Some(0), Some(4)] {
            let target = Target {
                position_mm: p,
                config,
                rotation_rad: None,
                tcp_mm: None,
            };
            check(&table.query_target(&target));
            for q in &joints {
                check(&table.query_with_joints(&target, q));
            }
            if let Ok(e) = table.explain(&target) {
                assert!(e.position_error_mm.iter().all(|v| v.is_finite()));
            }
            let k = table.compensate(&target, 1e-6, 10);
            check(&k.correction);
            if k.correction.status == Status::Ok {
                assert!(k.command_position_mm.iter().all(|v| v.is_finite()));
            }
        }
    }
});

/// A correction with status ok is finite.
fn check(c: &Correction) {
    if c.status == Status::Ok {
        let values = c.position_error_mm.iter().chain(&c.orientation_error_rad);
        assert!(values.into_iter().all(|v| v.is_finite()), "{c:?}");
    }
}
