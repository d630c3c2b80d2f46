//! The loader and every query on mutated tables whose checksums are recomputed, so that
//! each mutation reaches rkyv validation, the semantic and plausibility checks and, when
//! the table still opens, the queries: a bounded, stable-Rust counterpart of the
//! `open_table` fuzz target (`fuzz/`), run on every `cargo test`.
//!
//! Opening must never panic, whatever the bytes; a table that opens must answer `query`,
//! `query_target`, `query_with_joints`, `explain` and `compensate` (and the C ABI) without
//! panicking, and never with status ok and a non-finite value.
//!
//! The structured test runs `ADWI_MUTATION_CASES` cases (default 200,000: about 10 s on
//! one core) from seed `ADWI_MUTATION_SEED` (default 1): the same cases on every machine,
//! however fast; a longer soak gives more cases or another seed. Case `i` depends on the
//! seed and `i` alone, so `ADWI_MUTATION_CASE=i` replays one case. It prints the seed, the
//! cases and their time.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::time::Instant;

use adwi_compile::build::{compile, BuildOptions};
use adwi_runtime::capi::{self, AdwiCompensation, AdwiCorrection, AdwiResult};
use adwi_runtime::format::HEADER_LEN;
use adwi_runtime::testing::{reseal, seal_header};
use adwi_runtime::{Correction, OpenError, Status, Table, Target};
use adwi_samples::{parse_samples, ColumnMap};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn env_or(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The fuzz target's seed tables, small tables of real builds (`fuzz/seeds/README.md`):
/// positions only, orientation with configurations, the worked example, a hybrid table
/// with joint angles, a kinematic model and a joint-space screen, and a table of merged
/// samples (version 4).
fn seeds() -> Vec<(String, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds/open_table");
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| {
            let path = e.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&path).unwrap())
        })
        .collect();
    out.sort();
    assert!(
        out.len() >= 10,
        "seed tables missing from {}",
        dir.display()
    );
    for (name, bytes) in &out {
        let table = Table::from_vec(bytes).unwrap_or_else(|e| panic!("seed {name}: {e}"));
        let version = if name.starts_with("v1_") {
            1
        } else if name.starts_with("v6_") {
            6
        } else if name.starts_with("merged_") {
            4
        } else {
            2
        };
        assert_eq!(table.header().version, version, "{name}");
        if name.contains("hybrid") {
            assert!(table.is_hybrid(), "{name}");
            assert_eq!(table.has_served_field(), name.contains("served"), "{name}");
        }
    }
    out
}

/// The header's fields: offset and width in bytes, with the f64 fields apart.
const HEADER_INTEGERS: [(usize, usize); 17] = [
    (0, 8),   // magic
    (8, 2),   // endianness mark
    (10, 2),  // version
    (12, 4),  // header length
    (16, 4),  // rkyv flags
    (20, 4),  // content flags
    (24, 8),  // payload length
    (32, 8),  // payload checksum
    (40, 8),  // source hash
    (48, 4),  // k
    (52, 4),  // consistency screen
    (136, 4), // grid size x
    (140, 4), // grid size y
    (144, 4), // grid size z
    (148, 4), // sample count
    (160, 8), // reserved (first word; any reserved byte below)
    (244, 4), // version 4: the merge voxel (f32); reserved before
];
/// ε, ω1, ω2, r, [λ], [ζ], cell edge, origin x, y, z, joint radius.
const HEADER_F64: [usize; 11] = [56, 64, 72, 80, 88, 96, 104, 112, 120, 128, 152];

const INTERESTING_U64: [u64; 10] = [
    0,
    1,
    2,
    7,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFE,
    0xFFFF_FFFF,
    1 << 32,
    u64::MAX,
];
const INTERESTING_F64: [f64; 14] = [
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    1e300,
    -1e300,
    0.0,
    -0.0,
    5e-324, // the smallest subnormal
    1e-310, // a subnormal
    f64::MIN_POSITIVE,
    f64::MAX,
    1.0,
    -1.0,
    1e6,
];
const INTERESTING_BYTES: [u8; 6] = [0x00, 0x01, 0x7F, 0x80, 0xFE, 0xFF];

/// An interesting f64 in place of `current`: one of the list, or a small change of it.
fn interesting_f64(current: f64, rng: &mut ChaCha8Rng) -> f64 {
    match rng.gen_range(0..4) {
        0 => current * 2.0,
        1 => -current,
        2 => f64::from_bits(current.to_bits().wrapping_add(rng.gen_range(1..=4))),
        _ => INTERESTING_F64[rng.gen_range(0..INTERESTING_F64.len())],
    }
}

/// An interesting value of `width` bytes in place of `current`.
fn interesting_integer(current: u64, width: usize, rng: &mut ChaCha8Rng) -> u64 {
    let value = match rng.gen_range(0..3) {
        0 => current.wrapping_add_signed(rng.gen_range(-4..=4)),
        1 => rng.gen(),
        _ => INTERESTING_U64[rng.gen_range(0..INTERESTING_U64.len())],
    };
    value & (u64::MAX >> (64 - 8 * width))
}

fn read_u64(bytes: &[u8], at: usize, width: usize) -> u64 {
    let mut word = [0u8; 8];
    word[..width].copy_from_slice(&bytes[at..at + width]);
    u64::from_le_bytes(word)
}

/// One structured mutation of `bytes`; `others` are the seed tables, for splices. Payload
/// damage is resealed (payload length, both checksums), header edits get their checksum
/// recomputed only, so that exactly the edited field is wrong.
fn mutate(bytes: &mut Vec<u8>, others: &[(String, Vec<u8>)], rng: &mut ChaCha8Rng) {
    let len = bytes.len();
    let in_payload = |rng: &mut ChaCha8Rng, width: usize| {
        // Aligned to the width, as the archive's fields are.
        let slots = (len - HEADER_LEN) / width;
        HEADER_LEN + width * rng.gen_range(0..slots)
    };
    // A payload shorter than a word takes bit flips.
    let kinds = if len < HEADER_LEN + 8 { 1 } else { 10 };
    match rng.gen_range(0..kinds) {
        0 => {
            let i = rng.gen_range(0..len);
            bytes[i] ^= 1 << rng.gen_range(0..8);
            reseal(bytes);
        }
        1 => {
            let i = rng.gen_range(0..len);
            bytes[i] = INTERESTING_BYTES[rng.gen_range(0..INTERESTING_BYTES.len())];
            reseal(bytes);
        }
        2 => {
            // A truncation anywhere, the header too.
            bytes.truncate(rng.gen_range(0..len));
            reseal(bytes);
        }
        3 => {
            // A splice: the start of this table and the end of another (or the same one),
            // often exactly this header on another payload.
            let (_, other) = &others[rng.gen_range(0..others.len())];
            let (cut, from) = if rng.gen_bool(0.3) {
                (HEADER_LEN, HEADER_LEN)
            } else {
                (rng.gen_range(0..=len), rng.gen_range(0..=other.len()))
            };
            bytes.truncate(cut);
            bytes.extend_from_slice(&other[from..]);
            reseal(bytes);
        }
        4 => {
            let (at, width) = HEADER_INTEGERS[rng.gen_range(0..HEADER_INTEGERS.len())];
            let value = interesting_integer(read_u64(bytes, at, width), width, rng);
            bytes[at..at + width].copy_from_slice(&value.to_le_bytes()[..width]);
            seal_header(bytes);
        }
        5 => {
            // One f64 field changed, or several set to one value (ε and the cell edge at
            // 1e300 together, say: each alone is mild).
            let fields = if rng.gen_bool(0.3) {
                rng.gen_range(2..=4)
            } else {
                1
            };
            let shared = INTERESTING_F64[rng.gen_range(0..INTERESTING_F64.len())];
            for _ in 0..fields {
                let at = HEADER_F64[rng.gen_range(0..HEADER_F64.len())];
                let current = f64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
                let value = if fields == 1 {
                    interesting_f64(current, rng)
                } else {
                    shared
                };
                bytes[at..at + 8].copy_from_slice(&value.to_le_bytes());
            }
            seal_header(bytes);
        }
        6 => {
            // A reserved header byte.
            let at = rng.gen_range(160..248);
            bytes[at] = rng.gen_range(1..=255);
            seal_header(bytes);
        }
        7 => {
            // An f64 of the payload: sample values, norms, weights, joint angles, model.
            let at = in_payload(rng, 8);
            let current = f64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
            let value = interesting_f64(current, rng);
            bytes[at..at + 8].copy_from_slice(&value.to_le_bytes());
            reseal(bytes);
        }
        8 => {
            // A u32 of the payload (indices, ranges, lengths, relative pointers) changed a
            // little or set to an interesting value.
            let at = in_payload(rng, 4);
            let current = read_u64(bytes, at, 4);
            let value = interesting_integer(current, 4, rng);
            bytes[at..at + 4].copy_from_slice(&value.to_le_bytes()[..4]);
            reseal(bytes);
        }
        _ => {
            // A run of the payload copied over another: duplicated records, shifted
            // pointers.
            let n = rng.gen_range(1..64).min(len - HEADER_LEN);
            let from = rng.gen_range(HEADER_LEN..=len - n);
            let to = rng.gen_range(HEADER_LEN..=len - n);
            bytes.copy_within(from..from + n, to);
            reseal(bytes);
        }
    }
}

/// How a mutated table fared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
enum Outcome {
    Opened,
    Integrity,
    Archive,
    Corrupt,
    Implausible,
    Other,
}

fn outcome_of(error: &OpenError) -> Outcome {
    match error {
        OpenError::Truncated { .. }
        | OpenError::TrailingBytes { .. }
        | OpenError::HeaderChecksum { .. }
        | OpenError::PayloadChecksum { .. } => Outcome::Integrity,
        OpenError::Archive(_) => Outcome::Archive,
        OpenError::Corrupt { .. } => Outcome::Corrupt,
        OpenError::Implausible(_) => Outcome::Implausible,
        _ => Outcome::Other,
    }
}

/// Targets that probe every path: inside the grid, on cell faces and corners, at and next
/// to samples, outside, at the base origin, not finite.
fn targets(table: &Table<adwi_runtime::AlignedBytes>, rng: &mut ChaCha8Rng) -> Vec<Target> {
    let grid = *table.grid();
    let (lo, hi) = (grid.origin_mm, grid.max_mm());
    let mut points = vec![lo, hi, [0.0; 3], [1e-160, 0.0, 0.0]];
    for _ in 0..3 {
        points.push([0, 1, 2].map(|a| lo[a] + rng.gen::<f64>() * (hi[a] - lo[a])));
    }
    // On cell faces: whole multiples of the cell edge from the origin.
    let face = [0, 1, 2].map(|a| {
        let cells = grid.dims[a].max(1);
        lo[a] + f64::from(rng.gen_range(0..=cells)) * grid.cell_mm
    });
    points.push(face);
    let records = adwi_eval::latency::records_of(table);
    for _ in 0..2 {
        if let Some(s) = records.get(rng.gen_range(0..records.len().max(1))) {
            points.push(s.actual_mm);
            points.push(s.nominal_mm);
            points.push(s.actual_mm.map(|v| v + 1e-9));
        }
    }
    points.push([hi[0] + 1.0, lo[1], lo[2]]);
    points.push([lo[0], lo[1] - 1e300, lo[2]]);
    points.push([f64::NAN, lo[1], lo[2]]);
    points.push([lo[0], f64::INFINITY, hi[2]]);
    points
        .into_iter()
        .map(|position_mm| Target {
            position_mm,
            config: match rng.gen_range(0..4) {
                0 => None,
                1 => Some(0),
                2 => Some(rng.gen()),
                _ => Some(u8::MAX),
            },
            rotation_rad: None,
            tcp_mm: None,
        })
        .collect()
}

/// Joint vectors of the table's joint count (6 when it has none): a sample's, near it,
/// random, huge, not finite, and one of the wrong length.
fn joint_vectors(table: &Table<adwi_runtime::AlignedBytes>, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    let n = table.joint_count().unwrap_or(6);
    let stored: Vec<f64> = match table.payload() {
        Some(adwi_runtime::Payload::V1(d)) => d
            .joints_rad
            .iter()
            .flat_map(|q| q.map(|v| v.to_native()))
            .collect(),
        Some(adwi_runtime::Payload::V2(d)) => d.joints_rad.iter().map(|v| v.to_native()).collect(),
        None => Vec::new(),
    };
    let mut out = vec![vec![0.0; n]];
    if stored.len() >= n {
        let row = rng.gen_range(0..stored.len() / n);
        let q = stored[row * n..(row + 1) * n].to_vec();
        out.push(q.iter().map(|v| v + rng.gen_range(-0.2..0.2)).collect());
        out.push(q);
    }
    out.push((0..n).map(|_| rng.gen_range(-7.0..7.0)).collect());
    out.push(
        (0..n)
            .map(|i| if i % 2 == 0 { 1e300 } else { -1e300 })
            .collect(),
    );
    let mut nan = out[rng.gen_range(0..out.len())].clone();
    nan[rng.gen_range(0..n)] = f64::NAN;
    out.push(nan);
    let mut inf = out[0].clone();
    inf[n - 1] = f64::NEG_INFINITY;
    out.push(inf);
    out.push(vec![0.0; n + 1]);
    out
}

/// `what` names the call, written only for a failure: a case makes hundreds of calls,
/// and formatting their arguments each time was a third of this test's time.
fn check_correction(what: impl FnOnce() -> String, c: &Correction) -> Result<(), String> {
    let values = c.position_error_mm.iter().chain(&c.orientation_error_rad);
    if c.status == Status::Ok {
        // A hybrid table's model alone weighs no neighbour.
        let weighed = c.neighbours > 0 || c.residual == adwi_runtime::Residual::ModelOnly;
        if !values.clone().all(|v| v.is_finite()) || !weighed {
            return Err(format!("{}: status ok with {c:?}", what()));
        }
    } else if values.clone().any(|&v| v != 0.0) || c.neighbours != 0 {
        return Err(format!("{}: a failure that is not zero: {c:?}", what()));
    }
    Ok(())
}

/// Every query on one opened table.
fn exercise(table: &Table<adwi_runtime::AlignedBytes>, rng: &mut ChaCha8Rng) -> Result<(), String> {
    let joints = joint_vectors(table, rng);
    for target in targets(table, rng) {
        let p = target.position_mm;
        check_correction(|| format!("query {p:?}"), &table.query(p))?;
        check_correction(|| format!("exact query {p:?}"), &table.exact().query(p))?;
        let c = table.query_target(&target);
        check_correction(|| format!("query_target {target:?}"), &c)?;
        if table.is_hybrid() && c.status != Status::MissingJoints {
            return Err(format!("hybrid table answered without joints: {c:?}"));
        }
        for q in &joints {
            let c = table.query_with_joints(&target, q);
            check_correction(|| format!("query_with_joints {target:?} {q:?}"), &c)?;
            let wrong = !q.iter().all(|v| v.is_finite())
                || table.joint_count().is_some_and(|n| n != q.len());
            if wrong && c.status != Status::InvalidInput {
                return Err(format!("invalid joints {q:?} answered {c:?}"));
            }
            let exact = table.exact().query_with_joints(&target, q);
            check_correction(
                || format!("exact query_with_joints {target:?} {q:?}"),
                &exact,
            )?;
        }
        if let Ok(e) = table.explain(&target) {
            let values = (e.position_error_mm.iter())
                .chain(&e.orientation_error_rad)
                .chain(e.weights.as_slice());
            if !values.into_iter().all(|v| v.is_finite()) || e.neighbours.as_slice().is_empty() {
                return Err(format!("explain {target:?}: {e:?}"));
            }
        }
        let (tolerance_mm, iterations) = [(1e-6, 10), (0.0, 3), (1e-3, 1)][rng.gen_range(0..3)];
        let k = table.compensate(&target, tolerance_mm, iterations);
        check_correction(|| format!("compensate {target:?}"), &k.correction)?;
        if k.correction.status == Status::Ok {
            let values = (k.command_position_mm.iter())
                .chain(&k.command_rotation_rad)
                .chain([&k.residual_mm]);
            if !values.into_iter().all(|v| v.is_finite()) {
                return Err(format!("compensate {target:?}: status ok with {k:?}"));
            }
        }
    }
    Ok(())
}

/// The same bytes through the C ABI: open, a query, a joint query, a compensation and
/// close, with the same answers as the Rust API's.
fn exercise_c_abi(
    bytes: &[u8],
    table: Option<&Table<adwi_runtime::AlignedBytes>>,
) -> Result<(), String> {
    let mut handle = std::ptr::null_mut();
    // SAFETY: `bytes` is valid for its length; `handle` is writable.
    let code = unsafe { capi::adwi_table_open_bytes(bytes.as_ptr(), bytes.len(), &mut handle) };
    let Some(table) = table else {
        return match code {
            AdwiResult::Ok => Err("the C ABI opened what the Rust API refused".into()),
            _ => Ok(()),
        };
    };
    if code != AdwiResult::Ok {
        return Err(format!(
            "the C ABI refused what the Rust API opened: {code:?}"
        ));
    }
    let grid = *table.grid();
    let centre = [0, 1, 2].map(|a| 0.5 * (grid.origin_mm[a] + grid.max_mm()[a]));
    let mut c = AdwiCorrection::default();
    let mut k = AdwiCompensation::default();
    let joints: Vec<f64> = [0.1, -1.0, 1.5, 0.0, 0.5, 0.0]
        .into_iter()
        .cycle()
        .take(table.joint_count().unwrap_or(6))
        .collect();
    // SAFETY: a live handle, valid pointers to three doubles, to `joints` and to the
    // outputs.
    let codes = unsafe {
        [
            capi::adwi_table_query(handle, centre.as_ptr(), -1, &mut c),
            capi::adwi_table_query_joints(
                handle,
                centre.as_ptr(),
                -1,
                joints.as_ptr(),
                joints.len(),
                &mut c,
            ),
            capi::adwi_table_compensate(handle, centre.as_ptr(), -1, 1e-6, 10, &mut k),
        ]
    };
    // SAFETY: a live handle, closed once.
    unsafe { capi::adwi_table_close(handle) };
    if codes.iter().any(|&code| code != AdwiResult::Ok) {
        return Err(format!("C ABI calls failed: {codes:?}"));
    }
    let want = table.query_with_joints(&Target::at(centre), &joints);
    let status_ok = Status::Ok as i32;
    let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
    if c.status != want.status as i32
        || (c.status == status_ok && !finite(&c.position_error_mm))
        || (k.correction.status == status_ok && !finite(&k.command_position_mm))
    {
        return Err(format!("C ABI answered {c:?} / {k:?}, Rust {want:?}"));
    }
    Ok(())
}

/// Case `case` of seed `seed`: mutates a seed table one to three times, opens it, and if
/// it opens queries it every way. `Err` describes a wrong answer.
fn run_case(
    tables: &[(String, Vec<u8>)],
    seed: u64,
    case: u64,
) -> Result<(usize, Outcome), String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(case);
    let which = rng.gen_range(0..tables.len());
    let mut bytes = tables[which].1.clone();
    for _ in 0..rng.gen_range(1..=3) {
        if bytes.len() <= HEADER_LEN {
            break;
        }
        mutate(&mut bytes, tables, &mut rng);
    }
    let outcome = match Table::from_vec(&bytes) {
        Ok(table) => {
            exercise(&table, &mut rng)?;
            if rng.gen_bool(0.25) {
                exercise_c_abi(&bytes, Some(&table))?;
            }
            Outcome::Opened
        }
        Err(e) => {
            if rng.gen_bool(0.05) {
                exercise_c_abi(&bytes, None)?;
            }
            outcome_of(&e)
        }
    };
    Ok((which, outcome))
}

#[test]
fn structured_mutations_never_panic_nor_answer_non_finite_values_with_status_ok() {
    let total = env_or("ADWI_MUTATION_CASES", 200_000);
    let seed = env_or("ADWI_MUTATION_SEED", 1);
    let only: Option<u64> = std::env::var("ADWI_MUTATION_CASE")
        .ok()
        .and_then(|v| v.parse().ok());
    let tables = seeds();
    let start = Instant::now();
    let mut counts = std::collections::BTreeMap::new();
    let mut opened_per_table = vec![0u64; tables.len()];
    let mut case = only.unwrap_or(0);
    let mut cases = 0u64;
    while only.is_some() || case < total {
        let rerun = format!("ADWI_MUTATION_SEED={seed} ADWI_MUTATION_CASE={case}");
        match catch_unwind(AssertUnwindSafe(|| run_case(&tables, seed, case))) {
            Ok(Ok((which, outcome))) => {
                *counts.entry(outcome).or_insert(0u64) += 1;
                if outcome == Outcome::Opened {
                    opened_per_table[which] += 1;
                }
            }
            Ok(Err(wrong)) => panic!("seed {seed}, case {case}: {wrong} (replay: {rerun})"),
            Err(_) => panic!("seed {seed}, case {case}: panicked (replay: {rerun})"),
        }
        cases += 1;
        case += 1;
        if only.is_some() {
            break;
        }
    }
    let seconds_run = start.elapsed().as_secs_f64();
    eprintln!("structured mutation: seed {seed}, {cases} cases in {seconds_run:.1} s: {counts:?}");
    for ((name, _), opened) in tables.iter().zip(&opened_per_table) {
        eprintln!("  {name}: {opened} mutated tables opened and queried");
    }
    if only.is_none() {
        // The mutations reach every layer: integrity checks, rkyv validation, invariants,
        // plausibility; and mutated tables of every seed open and are queried.
        for outcome in [
            Outcome::Opened,
            Outcome::Integrity,
            Outcome::Archive,
            Outcome::Corrupt,
            Outcome::Implausible,
        ] {
            assert!(
                counts.get(&outcome).copied().unwrap_or(0) > 0,
                "{outcome:?}: {counts:?}"
            );
        }
        assert!(
            opened_per_table.iter().all(|&n| n > 0),
            "{opened_per_table:?}"
        );
    }
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
        ("version 3", vec![(10, 3u16.to_le_bytes().to_vec())]),
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
        ("joint count 3", vec![u32_at(160, 3)]),
        ("joint count max", vec![u32_at(160, u32::MAX)]),
        ("node sets 0", vec![u32_at(164, 0)]),
        ("node sets 2", vec![u32_at(164, 2)]),
        ("served field kind 2", vec![u32_at(172, 2)]),
        ("served field kind max", vec![u32_at(172, u32::MAX)]),
        (
            "kriging served field without node sets",
            vec![u32_at(172, 1), u32_at(164, 0)],
        ),
        ("tuned mean without folds", vec![f64_at(176, 0.07)]),
        ("tuned mean NaN", vec![u32_at(168, 5), f64_at(176, nan)]),
        (
            "tuned mean negative",
            vec![u32_at(168, 5), f64_at(176, -0.1)],
        ),
        ("tuned mean 1e300", vec![u32_at(168, 5), f64_at(176, 1e300)]),
        ("served tuned mean without folds", vec![f64_at(184, 0.07)]),
        (
            "served tuned mean NaN",
            vec![u32_at(168, 5), f64_at(184, nan)],
        ),
        (
            "served tuned mean negative",
            vec![u32_at(168, 5), f64_at(184, -0.1)],
        ),
        ("grid moved by a cell", vec![f64_at(112, 1850.0)]),
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

/// A version-4 table whose samples (a tracked line, 0.1 mm apart) were merged in 1 mm
/// voxels.
fn merged_table() -> Vec<u8> {
    let mut csv = String::from("x,y,z,dx,dy,dz\n");
    for i in 0..2000 {
        let x = 1000.0 + 0.1 * f64::from(i);
        csv += &format!("{x},500,800,{},0.2,-0.1\n", 0.1 + 1e-4 * f64::from(i));
    }
    let s = parse_samples("line.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
    let options = BuildOptions {
        merge_voxel_mm: Some(1.0),
        cell_mm: Some(20.0),
        method: adwi_runtime::method::MethodParams::paper(Some(10.0)),
        ..BuildOptions::default()
    };
    compile(&s, &options, &|_| {}).unwrap().0
}

#[test]
fn hostile_merge_voxels_with_valid_checksums_are_refused() {
    let base = merged_table();
    let table = Table::from_vec(&base).unwrap();
    assert_eq!(table.header().version, 4);
    assert_eq!(table.header().merge_voxel_mm, Some(1.0));
    assert_eq!(table.sample_count(), 200);
    let voxel = |v: f32| (244, v.to_le_bytes().to_vec());
    for (name, value) in [
        ("NaN", f32::NAN),
        ("inf", f32::INFINITY),
        ("negative", -1.0),
        ("-0", -0.0),
        ("below a nanometre", 1e-7),
        ("subnormal", 1e-40),
        ("beyond a kilometre", 2e6),
    ] {
        match Table::from_vec(with_header_edits(&base, &[voxel(value)])) {
            Ok(_) => panic!("merge voxel {name} opened"),
            Err(e) => assert!(e.to_string().contains("merge voxel"), "{name}: {e}"),
        }
    }
    // Any plausible voxel, or none, opens: the record does not change what is answered.
    for value in [0.0, 0.5, 100.0] {
        Table::from_vec(with_header_edits(&base, &[voxel(value)])).unwrap();
    }
    // A version-2 table has no such field: its bytes 244-247 are reserved.
    let v2 = seed("worked_example.tbl");
    let Err(err) = Table::from_vec(with_header_edits(&v2, &[voxel(1.0)])) else {
        panic!("a version-2 table with a merge voxel opened");
    };
    assert!(err.to_string().contains("reserved"), "{err}");
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
        vec![u32_at(168, 5), f64_at(176, 0.069)],
        vec![u32_at(172, 1)],
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
        let served = table.query_target(&target);
        if served.status == Status::Ok && !finite(&served.position_error_mm) {
            failures.push(format!("served query {p:?}: {served:?}"));
        }
        let c = table.exact().query_target(&target);
        if c.status == Status::Ok && !finite(&c.position_error_mm) {
            failures.push(format!("query {p:?}: {c:?}"));
        }
        if c.status == Status::NumericalFailure {
            withheld += 1;
            assert_eq!(c, table.exact().query_with_joints(&target, &[0.0; 6]));
        }
        if let Ok(e) = table.explain(&target) {
            if !finite(&e.position_error_mm) || !e.weights.as_slice().iter().all(|q| q.is_finite())
            {
                failures.push(format!("explain {p:?}: {e:?}"));
            }
        }
        for k in [
            table.compensate(&target, 1e-9, 20),
            table.exact().compensate(&target, 1e-9, 20),
        ] {
            if k.correction.status == Status::Ok
                && !(finite(&k.command_position_mm) && k.residual_mm.is_finite())
            {
                failures.push(format!("compensate {p:?}: {k:?}"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(withheld > 0, "no target reached the degenerate case");
}

fn finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

#[test]
fn hostile_hybrid_tables_with_valid_checksums_are_refused() {
    let base = seed("v1_ur5_hybrid.tbl");
    let table = Table::from_vec(&base).unwrap();
    for edits in [vec![f64_at(152, 13.0)], vec![f64_at(152, 1e300)]] {
        let err = Table::from_vec(with_header_edits(&base, &edits)).err();
        assert!(matches!(err, Some(OpenError::Implausible(_))), "{err:?}");
    }
    // The kinematic model, re-encoded with one value out of range: checksums and rkyv
    // validation pass, the plausibility check must not.
    let header = *table.header();
    let Some(adwi_runtime::Payload::V1(archived)) = table.payload() else {
        panic!("the hybrid seed of version 1");
    };
    let data: adwi_runtime::format::v1::TableData =
        rkyv::deserialize::<_, rkyv::rancor::Error>(archived).unwrap();
    type Edit = fn(&mut adwi_runtime::format::KinematicModel);
    let edits: [(&str, Edit); 4] = [
        ("base x 1e300", |m| m.calibrated.base[3] = 1e300),
        ("tool rotation entry 2", |m| m.nominal.tool[0] = 2.0),
        ("joint length beyond a kilometre", |m| {
            m.calibrated.joints[1][0] = -2e6
        }),
        ("tool z -1e300", |m| m.nominal.tool[11] = -1e300),
    ];
    for (name, edit) in edits {
        let mut damaged = data.clone();
        edit(damaged.model.as_mut().unwrap());
        let bytes = adwi_runtime::testing::encode_v1(&header, &damaged).unwrap();
        let err = Table::from_vec(&bytes).err();
        assert!(
            matches!(err, Some(OpenError::Implausible(_))),
            "{name}: {err:?}"
        );
    }
    // Joint angles of any finite size are the caller's: answered, never with NaN.
    let q = [1e300, -1e300, 1e300, 1e300, 1e300, 1e300];
    let sample = archived.samples[0].actual_mm.map(|v| v.to_native());
    let c = table.query_with_joints(&Target::at(sample), &q);
    check_correction(|| "huge joint angles".into(), &c).unwrap();
}

/// A version-2 hybrid table re-encoded with a damaged chain (checksums and rkyv
/// validation pass) is refused by the semantic pass, with a reason.
#[test]
fn hostile_version_2_chains_with_valid_checksums_are_refused() {
    let base = seed("ur5_hybrid_served.tbl");
    let table = Table::from_vec(&base).unwrap();
    let header = *table.header();
    let Some(adwi_runtime::Payload::V2(archived)) = table.payload() else {
        panic!("a version-2 seed");
    };
    let data: adwi_runtime::format::v2::TableData =
        rkyv::deserialize::<_, rkyv::rancor::Error>(archived).unwrap();
    type Edit = fn(&mut adwi_runtime::format::v2::ModelRecord);
    let edits: [(&str, Edit, bool); 6] = [
        ("base x 1e300", |m| m.calibrated.base[3] = 1e300, true),
        (
            "joint origin beyond a kilometre",
            |m| m.nominal.joints[2].origin[3] = -2e6,
            true,
        ),
        (
            "unknown joint kind",
            |m| m.calibrated.joints[0].kind = 7,
            false,
        ),
        (
            "axis not a unit vector",
            |m| m.calibrated.joints[1].axis = [0.0, 0.0, 2.0],
            false,
        ),
        (
            "rotation not orthonormal",
            |m| m.nominal.tool[0] = 2.0,
            false,
        ),
        (
            "a joint less",
            |m| {
                m.calibrated.joints.pop();
            },
            false,
        ),
    ];
    for (name, edit, implausible) in edits {
        let mut damaged = data.clone();
        edit(damaged.model.as_mut().unwrap());
        let bytes = adwi_runtime::format::encode(header, &damaged).unwrap();
        let err = Table::from_vec(&bytes).err();
        let refused = if implausible {
            matches!(err, Some(OpenError::Implausible(_)))
        } else {
            matches!(err, Some(OpenError::Corrupt { .. }))
        };
        assert!(refused, "{name}: {err:?}");
    }
}

/// A version-2 hybrid served table re-encoded as a tool-axis field (header byte 172 = 2)
/// with node arrays that break its layout — one vector a node, a node's vectors missing
/// in part — is refused at open with the reason; the same arrays laid out right open.
#[test]
fn tool_axis_node_layouts_with_valid_checksums_are_checked() {
    use adwi_runtime::format::ServedField;
    let base = seed("ur5_hybrid_served.tbl");
    let table = Table::from_vec(&base).unwrap();
    let mut header = *table.header();
    let Some(adwi_runtime::Payload::V2(archived)) = table.payload() else {
        panic!("a version-2 seed");
    };
    let data: adwi_runtime::format::v2::TableData =
        rkyv::deserialize::<_, rkyv::rancor::Error>(archived).unwrap();
    header.served_field = ServedField::KrigingToolAxis;
    let refused = |data: &adwi_runtime::format::v2::TableData| -> String {
        let bytes = adwi_runtime::format::encode(header, data).unwrap();
        match Table::from_vec(&bytes) {
            Err(OpenError::Corrupt { what }) => what.to_string(),
            other => panic!("opened or refused otherwise: {:?}", other.err()),
        }
    };
    // The stride-1 nodes relabelled: a quarter of the vectors a tool-axis field needs.
    let why = refused(&data);
    assert!(
        why.contains("node values do not fill whole node sets"),
        "{why}"
    );
    // Four vectors a node: f, then h = 0.
    let mut laid_out = data.clone();
    laid_out.node_errors_mm = data
        .node_errors_mm
        .iter()
        .flat_map(|&f| {
            let h = if f.iter().all(|v| v.is_nan()) {
                f
            } else {
                [0.0; 3]
            };
            [f, h, h, h]
        })
        .collect();
    let bytes = adwi_runtime::format::encode(header, &laid_out).unwrap();
    let opened = Table::from_vec(&bytes).unwrap();
    assert_eq!(opened.header().served_field, ServedField::KrigingToolAxis);
    let missing = laid_out
        .node_errors_mm
        .iter()
        .position(|v| v.iter().all(|x| x.is_nan()))
        .expect("the seed has uncovered nodes");
    let mut partial = laid_out.clone();
    partial.node_errors_mm[missing - missing % 4 + 1] = [0.0; 3];
    let why = refused(&partial);
    assert!(why.contains("marked missing in part"), "{why}");
    let mut infinite = laid_out;
    let present = infinite
        .node_errors_mm
        .iter()
        .position(|v| v.iter().all(|x| x.is_finite()))
        .unwrap();
    infinite.node_errors_mm[present - present % 4 + 2] = [f64::INFINITY, 0.0, 0.0];
    let why = refused(&infinite);
    assert!(why.contains("neither finite nor marked missing"), "{why}");
    // A tool-axis table relabelled as a Cartesian kriging one, checksums recomputed: its
    // four vectors a node would read as four times the nodes, three quarters of them used
    // by no set.
    let tool_axis = seed("ur5_hybrid_tool_axis_served.tbl");
    let table = Table::from_vec(&tool_axis).unwrap();
    let mut header = *table.header();
    assert_eq!(header.served_field, ServedField::KrigingToolAxis);
    let Some(adwi_runtime::Payload::V2(archived)) = table.payload() else {
        panic!("a version-2 seed");
    };
    let data: adwi_runtime::format::v2::TableData =
        rkyv::deserialize::<_, rkyv::rancor::Error>(archived).unwrap();
    header.served_field = ServedField::Kriging;
    let bytes = adwi_runtime::format::encode(header, &data).unwrap();
    match Table::from_vec(&bytes) {
        Err(OpenError::Corrupt { what }) => {
            assert!(what.contains("no node set uses"), "{what}")
        }
        other => panic!("opened or refused otherwise: {:?}", other.err()),
    }
}
