//! Tables of every format version this runtime claims to read, committed under
//! `tables/compat/v<N>/` with the command that produced them, still open and still give
//! their recorded answers.

use std::path::{Path, PathBuf};

use adwi_compile::reference;
use adwi_compile::samples::{read_samples, ColumnMap};
use adwi_runtime::format::{FORMAT_VERSION, OLDEST_SUPPORTED_VERSION};
use adwi_runtime::{Status, Table, Target};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `tables/compat/v1/README.md`'s table of answers: target, error, neighbours, status.
type Answer = ([f64; 3], Option<[f64; 3]>, u32, Status);

const V1_ANSWERS: [Answer; 5] = [
    (
        [2000.0, 700.0, 1000.0],
        Some([0.044584991, 0.995639127, -0.230310237]),
        8,
        Status::Ok,
    ),
    (
        [1980.0, 690.0, 1010.0],
        Some([0.044545231, 0.995326254, -0.230048001]),
        8,
        Status::Ok,
    ),
    (
        [2040.0, 740.0, 960.0],
        Some([0.044601142, 0.995253988, -0.231196162]),
        8,
        Status::Ok,
    ),
    (
        [1950.0, 750.0, 1050.0],
        Some([0.042193600, 0.996989097, -0.228903413]),
        8,
        Status::Ok,
    ),
    ([3000.0, 700.0, 1000.0], None, 0, Status::OutsideGrid),
];

#[test]
fn every_supported_version_has_a_fixture() {
    for version in OLDEST_SUPPORTED_VERSION..=FORMAT_VERSION {
        let dir = root().join(format!("tables/compat/v{version}"));
        assert!(dir.join("README.md").exists(), "{} missing", dir.display());
    }
}

#[test]
fn the_version_1_table_opens_and_gives_its_recorded_answers() {
    let path = root().join("tables/compat/v1/worked_example.tbl");
    // SAFETY: a committed fixture, not modified while the test runs.
    let table = unsafe { Table::open(&path) }.unwrap();
    assert_eq!(table.header().version, 1);
    assert_eq!(table.header().source_hash, 0xf825_78c5_0b9b_b5e3);
    assert_eq!(table.sample_count(), 8);
    for (p, error, neighbours, status) in V1_ANSWERS {
        let c = table.query(p);
        assert_eq!(c.status, status, "{p:?}");
        assert_eq!(c.neighbours, neighbours, "{p:?}");
        if let Some(e) = error {
            for (got, want) in c.position_error_mm.iter().zip(e) {
                // Recorded with 9 decimals.
                assert!((got - want).abs() <= 5.1e-10, "{p:?}: {got} vs {want}");
            }
        }
    }
}

#[test]
fn the_version_1_table_agrees_with_the_method_on_its_samples() {
    // The fixture's samples are the worked example's: the brute force over them must
    // give the fixture's answers to rounding.
    let table =
        Table::from_vec(std::fs::read(root().join("tables/compat/v1/worked_example.tbl")).unwrap())
            .unwrap();
    let samples = read_samples(
        &root().join("tables/paper/worked_example_p1.csv"),
        &ColumnMap::default(),
    )
    .unwrap();
    assert_eq!(samples.source_hash(), table.header().source_hash);
    let records = samples.records();
    for (p, error, _, _) in V1_ANSWERS {
        let target = Target::at(p);
        let c = table.query_target(&target);
        match (error, reference::predict(&records, table.method(), &target)) {
            (Some(_), Some(r)) => {
                for axis in 0..3 {
                    let d = (c.position_error_mm[axis] - r.position_error_mm[axis]).abs();
                    assert!(d <= 1e-12, "{p:?}: {d}");
                }
            }
            (None, _) => assert_ne!(c.status, Status::Ok),
            (Some(_), None) => panic!("{p:?}: the reference has no answer"),
        }
    }
}
