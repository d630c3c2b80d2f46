//! The loader on mutated tables whose header and checksums are kept valid, so that every
//! mutation reaches rkyv validation and the semantic checks: a deterministic, stable-Rust
//! counterpart of the `open_table` fuzz target (`fuzz/`), run on every `cargo test`.
//!
//! Opening must never panic, whatever the payload; a table that opens must answer
//! queries without panicking. Iterations per seed: `ADWI_STRESS_ITERATIONS` (default
//! 4,000); seed of the mutations: `ADWI_STRESS_SEED` (default 1).

use std::path::Path;

use adwi_runtime::format::HEADER_LEN;
use adwi_runtime::testing::repair_header;
use adwi_runtime::{OpenError, Table, Target};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn env_or(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The fuzz target's seed tables: small tables of real builds.
fn seeds() -> Vec<(String, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/seeds/open_table");
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| {
            let path = e.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&path).unwrap())
        })
        .collect();
    out.sort();
    assert!(out.len() >= 3, "seed tables missing from {}", dir.display());
    out
}

const INTERESTING_U32: [u32; 8] = [0, 1, 2, 7, 0x7FFF_FFFF, 0x8000_0000, 0xFFFF_FFFE, u32::MAX];
const INTERESTING_F64: [f64; 8] = [
    0.0,
    -0.0,
    1.0,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    f64::MAX,
    f64::MIN_POSITIVE,
];

/// One random mutation anywhere in the file (the header is repaired afterwards, except
/// for the parameters and the grid, which stay mutated).
fn mutate(bytes: &mut Vec<u8>, rng: &mut ChaCha8Rng) {
    let len = bytes.len();
    match rng.gen_range(0..7) {
        0 => {
            let i = rng.gen_range(0..len);
            bytes[i] ^= 1 << rng.gen_range(0..8);
        }
        1 => {
            let i = rng.gen_range(0..len);
            bytes[i] = rng.gen();
        }
        2 => {
            let i = rng.gen_range(0..len - 4) & !3;
            let v = INTERESTING_U32[rng.gen_range(0..INTERESTING_U32.len())];
            bytes[i..i + 4].copy_from_slice(&v.to_le_bytes());
        }
        3 => {
            let i = rng.gen_range(0..len - 8) & !7;
            let v = INTERESTING_F64[rng.gen_range(0..INTERESTING_F64.len())];
            bytes[i..i + 8].copy_from_slice(&v.to_le_bytes());
        }
        4 => {
            // A small signed change to an aligned u32: offsets and lengths off by a little.
            let i = rng.gen_range(0..len - 4) & !3;
            let v = u32::from_le_bytes(bytes[i..i + 4].try_into().unwrap());
            let v = v.wrapping_add_signed(rng.gen_range(-16..=16));
            bytes[i..i + 4].copy_from_slice(&v.to_le_bytes());
        }
        5 => {
            // Copy a run of bytes over another: duplicated records, shifted pointers.
            let n = rng.gen_range(1..64).min(len - HEADER_LEN);
            let from = rng.gen_range(HEADER_LEN..len - n + 1);
            let to = rng.gen_range(HEADER_LEN..len - n + 1);
            bytes.copy_within(from..from + n, to);
        }
        _ => {
            // Grow or shrink the payload by up to 64 bytes at the end (the root's side).
            let delta = rng.gen_range(1..=64usize);
            if rng.gen() && len - delta > HEADER_LEN {
                bytes.truncate(len - delta);
            } else {
                bytes.extend((0..delta).map(|_| rng.gen::<u8>()));
            }
        }
    }
}

#[test]
fn mutated_tables_with_valid_checksums_never_panic() {
    let iterations = env_or("ADWI_STRESS_ITERATIONS", 4_000);
    let mut rng = ChaCha8Rng::seed_from_u64(env_or("ADWI_STRESS_SEED", 1));
    let (mut opened, mut archive, mut corrupt, mut other) = (0u64, 0u64, 0u64, 0u64);
    for (name, seed) in seeds() {
        for _ in 0..iterations {
            let mut bytes = seed.clone();
            for _ in 0..rng.gen_range(1..=4) {
                mutate(&mut bytes, &mut rng);
            }
            repair_header(&mut bytes);
            match Table::from_vec(&bytes) {
                Ok(table) => {
                    opened += 1;
                    let grid = *table.grid();
                    let (lo, hi) = (grid.origin_mm, grid.max_mm());
                    for _ in 0..8 {
                        let p = [0, 1, 2].map(|a| lo[a] + rng.gen::<f64>() * (hi[a] - lo[a]));
                        let target = Target {
                            position_mm: p,
                            config: rng.gen_bool(0.5).then(|| rng.gen_range(0..8)),
                        };
                        let _ = table.query_target(&target);
                        let _ = table.compensate(&target, 1e-6, 10);
                    }
                }
                Err(OpenError::Archive(_)) => archive += 1,
                Err(OpenError::Corrupt { .. }) => corrupt += 1,
                Err(_) => other += 1,
            }
        }
        eprintln!("{name}: cumulative opened {opened}, archive {archive}, invariant {corrupt}, other {other}");
    }
    // The mutations reach every layer: some still open (harmless changes to values),
    // some fail rkyv validation, some fail the semantic checks.
    assert!(opened > 0 && archive > 0 && corrupt > 0);
}
