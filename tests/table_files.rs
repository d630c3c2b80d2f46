//! Tables that are truncated, bit-flipped, of another version or not tables at all are
//! refused at open with a reason, and never make the runtime panic.

use adwi_compile::build::{compile, BuildOptions};
use adwi_runtime::format::{Header, HEADER_LEN};
use adwi_runtime::{OpenError, Status, Table};
use adwi_samples::{parse_samples, ColumnMap};

/// A 3 × 3 × 4 lattice, 30 mm apart, with orientation errors and two configurations; with
/// joint values `j1..j6` when `joints`.
fn lattice_csv(joints: bool) -> String {
    let mut csv = String::from("x,y,z,dx,dy,dz,rx,ry,rz,config");
    if joints {
        csv += ",j1,j2,j3,j4,j5,j6";
    }
    csv += "\n";
    let mut n = 0;
    for k in 0..4 {
        for j in 0..3 {
            for i in 0..3 {
                let (x, y, z) = (1000 + 30 * i, 30 * j, 500 + 30 * k);
                let e = 0.1 + 0.01 * (n % 7) as f64;
                csv += &format!(
                    "{x},{y},{z},{e},0.2,-{e},1e-4,0,{},{}",
                    1e-5 * n as f64,
                    n % 2
                );
                if joints {
                    csv += &format!(",{},{},{},0,90,0", i * 10, j * 10, k * 10);
                }
                csv += "\n";
                n += 1;
            }
        }
    }
    csv
}

fn compiled(csv: &str, options: BuildOptions) -> Vec<u8> {
    let samples = parse_samples("t.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
    compile(&samples, &options, &|_| {}).unwrap().0
}

/// The plain small table: orientation errors, two configurations (three node sets), and
/// candidate lists too long for their cell records (the overflow list).
fn small_table() -> Vec<u8> {
    compiled(
        &lattice_csv(false),
        BuildOptions {
            cell_mm: Some(60.0),
            ..BuildOptions::default()
        },
    )
}

/// Small tables that together hold every section of the format — the plain one, one with
/// a joint screen (the samples' joint values, no served tier), and a hybrid one (the
/// nominal and calibrated chains) — each a few kilobytes, so that every bit of each can be
/// flipped in a test.
fn small_tables() -> Vec<(&'static str, Vec<u8>)> {
    let screened = compiled(
        &lattice_csv(true),
        BuildOptions {
            cell_mm: Some(60.0),
            joint_radius_deg: Some(30.0),
            ..BuildOptions::default()
        },
    );
    let (_, samples, calibration) = crate::common::kr150_calibration();
    let near: Vec<usize> = (0..samples.len())
        .filter(|&i| {
            let p = samples.nominal_mm[i];
            p[0] <= 1550.0 && p[1] <= 250.0 && p[2] <= 1050.0
        })
        .collect();
    let hybrid = crate::common::hybrid_table_bytes(
        &samples.subset(&near),
        &calibration.prepared_model(),
        &BuildOptions {
            cell_mm: Some(200.0),
            ..BuildOptions::default()
        },
    );
    vec![
        ("plain", small_table()),
        ("screened", screened),
        ("hybrid", hybrid),
    ]
}

/// Opens through the public entry point, checking that a refused table is refused and an
/// accepted one answers a query without panicking.
fn open(bytes: &[u8]) -> Result<(), OpenError> {
    let table = Table::from_vec(bytes)?;
    let c = table.query([1050.0, 50.0, 500.0]);
    assert!(matches!(
        c.status,
        Status::Ok | Status::NoAdmissibleNeighbour | Status::MissingJoints | Status::OutsideGrid
    ));
    Ok(())
}

#[test]
fn the_small_table_opens() {
    open(&small_table()).unwrap();
}

#[test]
fn every_truncation_is_refused() {
    let bytes = small_table();
    for len in 0..bytes.len() {
        let err = open(&bytes[..len]).expect_err("truncated table accepted");
        assert!(
            matches!(err, OpenError::Truncated { .. }),
            "len {len}: {err}"
        );
    }
}

#[test]
fn appended_bytes_are_refused() {
    let mut bytes = small_table();
    bytes.extend_from_slice(&[0; 16]);
    assert!(matches!(open(&bytes), Err(OpenError::TrailingBytes { .. })));
}

#[test]
fn every_single_bit_flip_is_refused() {
    for (name, bytes) in small_tables() {
        assert!(bytes.len() < 40_000, "{name}: {} bytes", bytes.len());
        open(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        let mut flipped = bytes.clone();
        for byte in 0..bytes.len() {
            for bit in 0..8 {
                flipped[byte] ^= 1 << bit;
                let result = open(&flipped);
                assert!(
                    result.is_err(),
                    "{name}: flip of bit {bit} of byte {byte} accepted"
                );
                flipped[byte] ^= 1 << bit;
            }
        }
    }
}

/// The small tables hold every section: the overflow list, orientation errors,
/// configurations and their node sets, the joint screen's joint values, the model.
#[test]
fn the_small_tables_hold_every_section() {
    let tables = small_tables();
    let (plain, screened, hybrid) = (&tables[0].1, &tables[1].1, &tables[2].1);
    let plain = Table::from_vec(plain).unwrap();
    let Some(adwi_runtime::Payload::V2(data)) = plain.payload() else {
        panic!("a version-2 table")
    };
    assert!(!data.overflow.is_empty(), "an overflow list");
    assert!(!data.orientation_errors_rad.is_empty() && !data.configs.is_empty());
    assert!(
        data.node_sets.len() >= 3,
        "{} node sets",
        data.node_sets.len()
    );
    let screened = Table::from_vec(screened).unwrap();
    let Some(adwi_runtime::Payload::V2(data)) = screened.payload() else {
        panic!("a version-2 table")
    };
    assert!(!data.joints_rad.is_empty() && data.node_sets.is_empty());
    assert!(Table::from_vec(hybrid).unwrap().is_hybrid());
}

#[test]
fn wrong_magic_and_versions_are_refused_naming_both_versions() {
    let bytes = small_table();
    let mut not_a_table = bytes.clone();
    not_a_table[0] = b'X';
    assert!(matches!(open(&not_a_table), Err(OpenError::BadMagic)));

    let header = Header::from_bytes(&bytes).unwrap();
    // Below the oldest, just above the newest (a file from a newer tablec), far above.
    let newest = adwi_runtime::format::FORMAT_VERSION;
    let oldest = adwi_runtime::format::OLDEST_SUPPORTED_VERSION;
    for version in [oldest - 1, newest + 1, newest + 7, u16::MAX] {
        let mut other = bytes.clone();
        let h = Header { version, ..header };
        // `to_bytes` recomputes the header checksum: only the version is wrong.
        let mut raw = h.to_bytes();
        raw[10..12].copy_from_slice(&version.to_le_bytes());
        let checksum = xxhash_rust::xxh3::xxh3_64(&raw[..248]);
        raw[248..].copy_from_slice(&checksum.to_le_bytes());
        other[..HEADER_LEN].copy_from_slice(&raw);
        let err = open(&other).unwrap_err();
        let message = err.to_string();
        assert!(
            matches!(err, OpenError::UnsupportedVersion { found, .. } if found == version),
            "{message}"
        );
        assert!(
            message.contains(&format!("version {version} is not supported")),
            "{message}"
        );
        assert!(
            message.contains(&format!("reads versions {oldest} to {newest}")),
            "{message}"
        );
    }
}

/// [`small_table`]'s header and version-2 payload, as values to edit and re-encode (with
/// valid checksums: what an edit breaks, the semantic pass must catch).
fn small_table_payload() -> (Header, adwi_runtime::format::v2::TableData) {
    let table = Table::from_vec(small_table()).unwrap();
    let Some(adwi_runtime::Payload::V2(archived)) = table.payload() else {
        panic!("the compiler writes version 2");
    };
    let data = rkyv::deserialize::<_, rkyv::rancor::Error>(archived).unwrap();
    (*table.header(), data)
}

#[test]
fn a_table_with_a_broken_invariant_but_valid_checksums_is_refused() {
    // Re-encode with a candidate naming a sample that does not exist: checksums and rkyv
    // validation pass, the semantic pass must not.
    let (header, mut data) = small_table_payload();
    let cell = data.cells.iter().position(|r| r[0] > 0).unwrap();
    data.cells[cell][1] = 99;
    let corrupt = adwi_runtime::format::encode(header, &data).unwrap();
    let err = open(&corrupt).unwrap_err();
    assert!(
        err.to_string()
            .contains("names a sample that does not exist"),
        "{err}"
    );
}

#[test]
fn a_table_listing_a_sample_twice_in_a_cell_is_refused() {
    // A cell with two candidates or more names its first twice: checksums and rkyv pass,
    // the semantic pass must not (a sample listed twice would be selected twice). Every
    // other cell's list names samples the others name too, so the check's marks are
    // cleared between cells, or the unchanged table would be refused.
    let (header, mut data) = small_table_payload();
    let cell = data.cells.iter().rposition(|r| r[0] >= 2).unwrap();
    assert!(
        usize::from(data.cells[cell][0]) <= adwi_runtime::format::v2::INLINE_CANDIDATES,
        "an inline list"
    );
    let unchanged = adwi_runtime::format::encode(header, &data).unwrap();
    assert!(open(&unchanged).is_ok());
    data.cells[cell][2] = data.cells[cell][1];
    let corrupt = adwi_runtime::format::encode(header, &data).unwrap();
    let err = open(&corrupt).unwrap_err();
    assert!(err.to_string().contains("names a sample twice"), "{err}");
}

#[test]
fn empty_and_misaligned_buffers_are_refused() {
    assert!(matches!(
        open(&[]),
        Err(OpenError::Truncated { len: 0, .. })
    ));
    let bytes = small_table();
    let mut shifted = vec![0u8; bytes.len() + 1];
    shifted[1..].copy_from_slice(&bytes);
    // `from_bytes` on a slice that starts one byte past an aligned allocation.
    let aligned = adwi_runtime::AlignedBytes::copy_from(&shifted).unwrap();
    let err = Table::from_bytes(&aligned[1..]).err().unwrap();
    assert!(matches!(err, OpenError::Misaligned { offset: 1 }), "{err}");
}
