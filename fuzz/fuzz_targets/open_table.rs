//! Table bytes with a valid header (magic, version, lengths, checksums recomputed after the
//! fuzzer's mutation), so that mutations reach rkyv validation and the semantic checks
//! rather than stopping at a checksum. Opening must never panic; a table that opens must
//! answer queries without panicking.

#![no_main]

use adwi_runtime::format::{FORMAT_VERSION, HEADER_LEN, MAGIC, RKYV_FLAGS};
use adwi_runtime::{Table, Target};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut bytes = data.to_vec();
    if bytes.len() >= HEADER_LEN {
        repair_header(&mut bytes);
    }
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

/// Writes the fields a random mutation would almost always break: magic, endianness
/// mark, version, header length, rkyv flags, payload length and both checksums.
fn repair_header(bytes: &mut [u8]) {
    let payload_len = (bytes.len() - HEADER_LEN) as u64;
    bytes[0..8].copy_from_slice(&MAGIC);
    bytes[8..10].copy_from_slice(&0xFEFFu16.to_le_bytes());
    bytes[10..12].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
    bytes[12..16].copy_from_slice(&(HEADER_LEN as u32).to_le_bytes());
    bytes[16..20].copy_from_slice(&RKYV_FLAGS.to_le_bytes());
    bytes[24..32].copy_from_slice(&payload_len.to_le_bytes());
    let payload = xxhash_rust::xxh3::xxh3_64(&bytes[HEADER_LEN..]);
    bytes[32..40].copy_from_slice(&payload.to_le_bytes());
    let header = xxhash_rust::xxh3::xxh3_64(&bytes[..248]);
    bytes[248..256].copy_from_slice(&header.to_le_bytes());
}
