//! Tables that are truncated, bit-flipped, of another version or not tables at all are
//! refused at open with a reason, and never make the runtime panic.

use adwi_compile::build::{compile, BuildOptions};
use adwi_runtime::format::{Header, HEADER_LEN};
use adwi_runtime::{OpenError, Status, Table};
use adwi_samples::{parse_samples, ColumnMap};

fn small_table() -> Vec<u8> {
    let csv = "x,y,z,dx,dy,dz,rx,ry,rz,config\n\
               1000,0,500,0.1,0.2,0.3,1e-4,0,0,0\n\
               1100,0,500,0.2,0.1,0.3,0,1e-4,0,0\n\
               1000,100,500,0.1,0.3,0.2,0,0,1e-4,1\n\
               1100,100,500,0.3,0.2,0.1,0,0,0,1\n\
               1050,50,600,0.2,0.2,0.2,0,0,0,0\n";
    let samples = parse_samples("t.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
    let options = BuildOptions {
        cell_mm: Some(50.0),
        ..BuildOptions::default()
    };
    compile(&samples, &options, &|_| {}).unwrap().0
}

/// Opens through the public entry point, checking that a refused table is refused and an
/// accepted one answers a query without panicking.
fn open(bytes: &[u8]) -> Result<(), OpenError> {
    let table = Table::from_vec(bytes)?;
    let c = table.query([1050.0, 50.0, 500.0]);
    assert!(matches!(
        c.status,
        Status::Ok | Status::NoAdmissibleNeighbour
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
    let bytes = small_table();
    let mut flipped = bytes.clone();
    for byte in 0..bytes.len() {
        for bit in 0..8 {
            flipped[byte] ^= 1 << bit;
            let result = open(&flipped);
            assert!(result.is_err(), "flip of bit {bit} of byte {byte} accepted");
            flipped[byte] ^= 1 << bit;
        }
    }
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

#[test]
fn a_table_with_a_broken_invariant_but_valid_checksums_is_refused() {
    // Re-encode with a candidate naming a sample that does not exist: checksums and rkyv
    // validation pass, the semantic pass must not.
    let bytes = small_table();
    let table = Table::from_vec(&bytes).unwrap();
    let header = *table.header();
    let Some(adwi_runtime::Payload::V2(archived)) = table.payload() else {
        panic!("the compiler writes version 2");
    };
    let mut data: adwi_runtime::format::v2::TableData =
        rkyv::deserialize::<_, rkyv::rancor::Error>(archived).unwrap();
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
fn empty_and_misaligned_buffers_are_refused() {
    assert!(matches!(
        open(&[]),
        Err(OpenError::Truncated { len: 0, .. })
    ));
    let bytes = small_table();
    let mut shifted = vec![0u8; bytes.len() + 1];
    shifted[1..].copy_from_slice(&bytes);
    // `from_bytes` on a slice that starts one byte past an aligned allocation.
    let mut aligned = adwi_runtime::AlignedBytes::new();
    aligned.extend_from_slice(&shifted);
    let err = Table::from_bytes(&aligned[1..]).err().unwrap();
    assert!(matches!(err, OpenError::Misaligned { offset: 1 }), "{err}");
}
