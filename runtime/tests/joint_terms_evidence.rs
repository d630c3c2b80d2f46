//! A model's joint-space terms are known over the angles they were identified from; beyond
//! them (by more than `TERMS_MARGIN_RAD`) the model holds each term at its range's end, and
//! the answer says so ([`Evidence::JOINTS`], docs/runtime.md, "Evidence"). Read on the
//! committed version-5 fixture (`tables/compat/v5/`), whose model has terms on joints 1, 2,
//! 4 and 5.

use std::path::Path;

use adwi_runtime::joint_terms::TERMS_MARGIN_RAD;
use adwi_runtime::{Evidence, Status, Table, Target};

/// Joint values of the UR5's first random pose (rad), within every joint's range.
const POSE_RAD: [f64; 6] = [0.30147, -1.43097, 1.54304, 0.00124, 1.63111, -0.00212];

fn fixture() -> Table<memmap2::Mmap> {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../tables/compat/v5/ur5_hybrid_terms.tbl");
    // SAFETY: a committed fixture, not modified while the test runs.
    unsafe { Table::open(&path) }.unwrap()
}

/// Both tiers' answers at joint values `q`, the target where the nominal chain puts the
/// tool (so that the joints reach it).
fn answers(table: &Table<memmap2::Mmap>, q: &[f64]) -> [adwi_runtime::Correction; 2] {
    let at = table.model().unwrap().at(q).unwrap();
    let target = Target::at(at.nominal_tcp_mm);
    [
        table.query_with_joints(&target, q),
        table.exact().query_with_joints(&target, q),
    ]
}

#[test]
fn an_answer_beyond_a_termed_joints_range_is_flagged_and_within_it_is_not() {
    let table = fixture();
    let terms = *table.model().unwrap().joint_terms();
    let has_term = |j: usize| terms.coefficients_rad[j].iter().any(|&c| c != 0.0);
    assert!(
        has_term(0) && !has_term(2),
        "the fixture's terms: {terms:?}"
    );
    for c in answers(&table, &POSE_RAD) {
        assert_eq!(c.status, Status::Ok);
        assert!(!c.evidence.contains(Evidence::JOINTS), "{c:?}");
    }
    let [lo, hi] = terms.range_rad[0];
    for (q0, flagged) in [
        (hi + 0.5 * TERMS_MARGIN_RAD, false),
        (lo - 0.5 * TERMS_MARGIN_RAD, false),
        (hi + 2.0 * TERMS_MARGIN_RAD, true),
        (lo - 2.0 * TERMS_MARGIN_RAD, true),
        (hi + 1.0, true),
    ] {
        let mut q = POSE_RAD;
        q[0] = q0;
        for c in answers(&table, &q) {
            // Still the model's answer (continuous across the edge), flagged beyond it.
            assert_eq!(c.status, Status::Ok, "joint 1 at {q0} rad");
            assert_eq!(
                c.evidence.contains(Evidence::JOINTS),
                flagged,
                "{q0}: {c:?}"
            );
        }
    }
    // A joint without terms is free to go anywhere the chain reaches.
    let [_, hi3] = terms.range_rad[2];
    let mut q = POSE_RAD;
    q[2] = hi3 + 0.3;
    for c in answers(&table, &q) {
        assert!(!c.evidence.contains(Evidence::JOINTS), "{c:?}");
    }
}

#[test]
fn the_evidence_names_cover_every_bit() {
    let names: Vec<&str> = (0..=Evidence::KNOWN)
        .map(|b| Evidence(b).as_str())
        .collect();
    assert_eq!(
        names,
        [
            "within",
            "orientation",
            "tcp",
            "orientation+tcp",
            "joints",
            "orientation+joints",
            "tcp+joints",
            "orientation+tcp+joints"
        ]
    );
}
