//! The loader on mutated tables whose header and checksums are kept valid, so that every
//! mutation reaches rkyv validation and the semantic checks: a deterministic, stable-Rust
//! counterpart of the `open_table` fuzz target (`fuzz/`), run on every `cargo test`.
//!
//! Opening must never panic, whatever the payload; a table that opens must answer
//! queries without panicking. Iterations per seed: `ADWI_STRESS_ITERATIONS` (default
//! 4,000); seed of the mutations: `ADWI_STRESS_SEED` (default 1).

use std::path::Path;

use adwi_compiler::build::{compile, BuildOptions};
use adwi_compiler::samples::{parse_samples, ColumnMap};
use adwi_runtime::format::HEADER_LEN;
use adwi_runtime::testing::{repair_header, seal_header};
use adwi_runtime::{OpenError, Status, Table, Target};
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

/// Bytes to write at an offset.
type Edit = (usize, Vec<u8>);

/// A seed table with header fields overwritten and only the header checksum recomputed:
/// exactly the edited fields are wrong.
fn with_header_edits(bytes: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut out = bytes.to_vec();
    for (offset, value) in edits {
        out[*offset..offset + value.len()].copy_from_slice(value);
    }
    seal_header(&mut out);
    out
}

fn f64_at(offset: usize, v: f64) -> Edit {
    (offset, v.to_le_bytes().to_vec())
}

fn u32_at(offset: usize, v: u32) -> Edit {
    (offset, v.to_le_bytes().to_vec())
}

fn seed(name: &str) -> Vec<u8> {
    seeds()
        .into_iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("no seed table {name}"))
        .1
}

#[test]
fn a_checksummed_header_with_radius_and_cell_of_1e300_is_refused() {
    // ε (offset 56) and the cell edge (offset 104) at 1e300 mm, checksum recomputed: the
    // table used to open and answer NaN with status ok.
    let bytes = with_header_edits(
        &seed("worked_example.tbl"),
        &[f64_at(56, 1e300), f64_at(104, 1e300)],
    );
    match Table::from_vec(&bytes) {
        Ok(table) => {
            let c = table.query([2000.0, 700.0, 1000.0]);
            let k = table.compensate(&Target::at([2000.0, 700.0, 1000.0]), 1e-6, 20);
            panic!("opened; query {c:?}, compensate {k:?}");
        }
        Err(e) => {
            let message = e.to_string();
            assert!(matches!(e, OpenError::Implausible(_)), "{message}");
            assert!(message.contains("e300"), "{message}");
        }
    }
}

#[test]
fn hostile_headers_with_valid_checksums_are_refused() {
    let base = seed("worked_example.tbl");
    // The seed: ε 200 mm, 5 × 5 × 5 cells of 100 mm from (1750, 450, 750), 8 samples,
    // positions only, no joint angles.
    Table::from_vec(&base).unwrap();
    let nan = f64::NAN;
    let (inf, subnormal) = (f64::INFINITY, 1e-320);
    let cases: Vec<(&str, Vec<Edit>)> = vec![
        ("magic", vec![(0, b"ADWITBX\0".to_vec())]),
        (
            "endianness mark",
            vec![(8, 0xFFFEu16.to_le_bytes().to_vec())],
        ),
        ("version 0", vec![(10, 0u16.to_le_bytes().to_vec())]),
        ("version 2", vec![(10, 2u16.to_le_bytes().to_vec())]),
        ("header length", vec![u32_at(12, 255)]),
        ("rkyv flags", vec![u32_at(16, 0)]),
        ("unknown content flag", vec![u32_at(20, 1 << 4)]),
        ("model flag without a model", vec![u32_at(20, 1 << 3)]),
        ("joints flag without joints", vec![u32_at(20, 1 << 2)]),
        (
            "payload length + 16",
            vec![(24, 8616u64.to_le_bytes().to_vec())],
        ),
        ("payload checksum", vec![(32, 0u64.to_le_bytes().to_vec())]),
        ("k 0", vec![u32_at(48, 0)]),
        ("k 17", vec![u32_at(48, 17)]),
        ("screen 2", vec![u32_at(52, 2)]),
        ("ε 1e300", vec![f64_at(56, 1e300)]),
        ("ε beyond every distance", vec![f64_at(56, 1e5)]),
        ("ε NaN", vec![f64_at(56, nan)]),
        ("ε inf", vec![f64_at(56, inf)]),
        ("ε -0", vec![f64_at(56, -0.0)]),
        ("ω1 NaN", vec![f64_at(64, nan)]),
        ("ω2 -inf", vec![f64_at(72, -inf)]),
        ("r 1e300", vec![f64_at(80, 1e300)]),
        ("[λ] inf", vec![f64_at(88, inf)]),
        ("[λ] negative", vec![f64_at(88, -1.0)]),
        ("[ζ] NaN", vec![f64_at(96, nan)]),
        ("cell 1e300", vec![f64_at(104, 1e300)]),
        ("cell beyond a kilometre", vec![f64_at(104, 1e6)]),
        ("cell negative", vec![f64_at(104, -100.0)]),
        ("cell -0", vec![f64_at(104, -0.0)]),
        ("cell NaN", vec![f64_at(104, nan)]),
        ("cell inf", vec![f64_at(104, inf)]),
        ("cell subnormal", vec![f64_at(104, subnormal)]),
        ("origin x 1e300", vec![f64_at(112, 1e300)]),
        ("origin y NaN", vec![f64_at(120, nan)]),
        ("origin z -inf", vec![f64_at(128, -inf)]),
        ("origin x beyond a kilometre", vec![f64_at(112, 2e6)]),
        ("dims x 6", vec![u32_at(136, 6)]),
        ("dims y 0", vec![u32_at(140, 0)]),
        ("dims z max", vec![u32_at(144, u32::MAX)]),
        ("dims 25 × 1 × 5", vec![u32_at(136, 25), u32_at(140, 1)]),
        ("sample count 9", vec![u32_at(148, 9)]),
        ("sample count 0", vec![u32_at(148, 0)]),
        ("joint radius 1e300", vec![f64_at(152, 1e300)]),
        ("joint radius NaN", vec![f64_at(152, nan)]),
        ("joint radius negative", vec![f64_at(152, -1.0)]),
        ("joint radius without joints", vec![f64_at(152, 0.5)]),
        ("reserved byte", vec![(200, vec![1])]),
    ];
    let mut opened = Vec::new();
    for (name, edits) in &cases {
        match Table::from_vec(with_header_edits(&base, edits)) {
            Ok(table) => opened.push(format!(
                "{name}: opened, query {:?}",
                table.query([2000.0, 700.0, 1000.0])
            )),
            Err(e) => eprintln!("{name}: {e}"),
        }
    }
    assert!(opened.is_empty(), "{}", opened.join("\n"));
}

#[test]
fn plausible_edits_still_open() {
    // The bounds refuse damage, not unusual but sensible parameters: a wide ε within the
    // workspace, other weights, k, screen.
    let base = seed("worked_example.tbl");
    for edits in [
        vec![f64_at(56, 800.0)],
        vec![f64_at(64, 0.5), f64_at(72, 0.5)],
        vec![u32_at(48, 16), u32_at(52, 0)],
    ] {
        Table::from_vec(with_header_edits(&base, &edits)).unwrap();
    }
}

#[test]
fn targets_at_the_base_origin_never_answer_a_non_finite_correction_with_status_ok() {
    // A lattice around the base origin, whose centre sample lies 1e-160 mm from it. For a
    // target as close, the approximation degrees overflow (|p| · |s| · |s − p| underflows
    // to zero, whose reciprocal is infinite): the answer must then be a failure, never NaN
    // with status ok.
    let mut csv = String::from("x,y,z,dx,dy,dz\n");
    for i in -1..=1 {
        for j in -1..=1 {
            for k in -1..=1 {
                let p = [i, j, k].map(|v| 100.0 * f64::from(v));
                if p == [0.0; 3] {
                    // A sample measured 1e-160 mm from the origin, without error.
                    csv += "1e-160,0,0,0,0,0\n";
                } else {
                    csv += &format!("{},{},{},0.1,-0.2,0.05\n", p[0], p[1], p[2]);
                }
            }
        }
    }
    let samples =
        parse_samples("origin.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
    let bytes = compile(&samples, &BuildOptions::default(), &|_| {})
        .unwrap()
        .0;
    let table = Table::from_vec(&bytes).unwrap();
    let mut failures = Vec::new();
    let mut withheld = 0;
    for p in [
        [0.0, 1e-160, 0.0],
        [1e-160, 1e-160, 0.0],
        [-1e-160, 0.0, 0.0],
        [0.0, 0.0, 1e-158],
        [1e-320, 0.0, 0.0],
        [0.0, 1e-310, 0.0],
        [5e-324, 5e-324, 5e-324],
        [1e-200, 1e-200, 0.0],
        [1e-160, 0.0, 0.0],
        [0.0, 0.0, 0.0],
        [-1e-320, 1e-320, 0.0],
    ] {
        let target = Target::at(p);
        let c = table.query_target(&target);
        if c.status == Status::Ok && !finite(&c.position_error_mm) {
            failures.push(format!("query {p:?}: {c:?}"));
        }
        if c.status == Status::NumericalFailure {
            withheld += 1;
            assert_eq!(c, table.query_with_joints(&target, &[0.0; 6]));
        }
        if let Ok(e) = table.explain(&target) {
            if !finite(&e.position_error_mm) || !e.weights.as_slice().iter().all(|q| q.is_finite())
            {
                failures.push(format!("explain {p:?}: {e:?}"));
            }
        }
        let k = table.compensate(&target, 1e-9, 20);
        if k.correction.status == Status::Ok
            && !(finite(&k.command_position_mm) && k.residual_mm.is_finite())
        {
            failures.push(format!("compensate {p:?}: {k:?}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(withheld > 0, "no target reached the degenerate case");
}

fn finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}
