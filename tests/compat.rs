//! Tables of every format version this runtime claims to read, committed under
//! `tables/compat/v<N>/` with the command that produced them, still open and still give
//! their recorded answers.

use std::path::{Path, PathBuf};

use adwi_compile::reference;
use adwi_runtime::format::{CONTENT_JOINTS, CONTENT_MODEL};
use adwi_runtime::format::{FORMAT_VERSION, OLDEST_SUPPORTED_VERSION};
use adwi_runtime::{Residual, Status, Table, Target};
use adwi_samples::{read_samples, ColumnMap};

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

/// `tables/compat/v1/README.md`'s answers of the hybrid fixture: target (mm), joint angles
/// (degrees), error (mm), neighbours, status.
type HybridAnswer = ([f64; 3], [f64; 6], Option<[f64; 3]>, u32, Status);

const FIRST_POSE_MM: [f64; 3] = [-495.48014933320513, -261.22060558066715, 359.404929823319];
const FIRST_JOINTS_DEG: [f64; 6] = [
    17.272893800633657,
    -81.98887450752903,
    88.40996156653269,
    0.07134692051529574,
    93.45549391078386,
    -0.12149026052282592,
];

const V1_HYBRID_ANSWERS: [HybridAnswer; 5] = [
    (
        FIRST_POSE_MM,
        FIRST_JOINTS_DEG,
        Some([
            -2.431379815316371,
            -0.41332581267771124,
            -0.6695839219887557,
        ]),
        8,
        Status::Ok,
    ),
    (
        [-496.5584396318196, -303.7438549414801, 389.15230080163224],
        [
            23.470392864049625,
            -77.07699251876265,
            77.09116418455962,
            11.235902610533948,
            104.46604662450441,
            -2.872462361249245,
        ],
        Some([
            -2.6503179853352505,
            -0.048157265372807616,
            -0.7107791381900339,
        ]),
        8,
        Status::Ok,
    ),
    (
        [-379.4891043290153, -391.437788426598, 321.30117534761547],
        [
            39.90741597526584,
            -78.49182609849096,
            88.15719596291765,
            6.224929174902254,
            117.51697908151714,
            17.389107740297682,
        ],
        Some([
            -2.5134941452891595,
            -0.2622417025364461,
            -0.5025847404468314,
        ]),
        8,
        Status::Ok,
    ),
    (
        FIRST_POSE_MM,
        [
            17.272893800633657,
            -81.98887450752903,
            88.40996156653269,
            90.0713469205153,
            93.45549391078386,
            -0.12149026052282592,
        ],
        None,
        0,
        Status::NoAdmissibleNeighbour,
    ),
    (
        [500.0, -261.22060558066715, 359.404929823319],
        FIRST_JOINTS_DEG,
        None,
        0,
        Status::OutsideGrid,
    ),
];

#[test]
fn the_version_1_hybrid_table_opens_and_gives_its_recorded_answers() {
    let path = root().join("tables/compat/v1/ur5_hybrid.tbl");
    assert_eq!(std::fs::metadata(&path).unwrap().len(), 178_992);
    // SAFETY: a committed fixture, not modified while the test runs.
    let table = unsafe { Table::open(&path) }.unwrap();
    let header = table.header();
    assert_eq!(header.version, 1);
    assert_eq!(header.content_flags, CONTENT_JOINTS | CONTENT_MODEL);
    assert_eq!(header.source_hash, 0x1ac4_b533_b619_3568);
    assert_eq!(header.joint_radius_rad, 60f64.to_radians());
    assert_eq!(table.sample_count(), 1000);
    assert!(table.is_hybrid());
    // (Version 1 hashed joint angles in degrees; samples now hold radians, so the hash of
    // the shipped measurements is no longer comparable with the recorded one above.)
    for (p, joints_deg, error, neighbours, status) in V1_HYBRID_ANSWERS {
        let target = Target::at(p);
        let q = joints_deg.map(f64::to_radians);
        let c = table.query_with_joints(&target, &q);
        // Where the residuals had nothing, the model now answers alone, or the joints are
        // refused when they do not reach the target.
        if status != Status::Ok {
            let model = table.model().unwrap();
            // The model as a hybrid query computes it (with its orientation).
            let at = model.at(&q).unwrap();
            let off_mm = adwi_runtime::method::distance_mm(at.nominal_tcp_mm, p);
            if off_mm > table.joints_tolerance_mm().unwrap() {
                assert_eq!(c.status, Status::JointsMismatch, "{p:?}");
            } else {
                assert_eq!((c.status, c.residual), (Status::Ok, Residual::ModelOnly));
                assert_eq!(c.position_error_mm, at.position_mm, "{p:?}");
            }
            continue;
        }
        assert_eq!(c.status, status, "{p:?} {joints_deg:?}");
        assert_eq!(c.neighbours, neighbours, "{p:?} {joints_deg:?}");
        // No orientation error: the samples measured position alone, which does not
        // determine the model's.
        assert_eq!(c.orientation_error_rad, [0.0; 3], "{p:?}");
        match error {
            Some(e) => {
                for (got, want) in c.position_error_mm.iter().zip(e) {
                    assert!((got - want).abs() <= 1e-12, "{p:?}: {got} vs {want}");
                }
            }
            None => assert_eq!(c.position_error_mm, [0.0; 3]),
        }
        assert_eq!(table.query(p).status, Status::MissingJoints, "{p:?}");
    }
}

/// `tables/compat/v2/README.md`'s answers of `worked_example.tbl`: served, then exact.
const V2_ANSWERS: [(bool, Answer); 10] = [
    (
        false,
        (
            [2000.0, 700.0, 1000.0],
            Some([0.044719917, 0.995300158, -0.230415065]),
            8,
            Status::Ok,
        ),
    ),
    (
        false,
        (
            [1980.0, 690.0, 1010.0],
            Some([0.044935429, 0.995502446, -0.229656906]),
            8,
            Status::Ok,
        ),
    ),
    (
        false,
        (
            [2040.0, 740.0, 960.0],
            Some([0.043726180, 0.994152413, -0.232225095]),
            8,
            Status::Ok,
        ),
    ),
    (
        false,
        (
            [1950.0, 750.0, 1050.0],
            Some([0.042193600, 0.996989097, -0.228903413]),
            8,
            Status::Ok,
        ),
    ),
    (
        false,
        ([3000.0, 700.0, 1000.0], None, 0, Status::OutsideGrid),
    ),
    (true, V1_ANSWERS[0]),
    (true, V1_ANSWERS[1]),
    (true, V1_ANSWERS[2]),
    (true, V1_ANSWERS[3]),
    (true, V1_ANSWERS[4]),
];

/// The three UR5 poses of `tables/compat/v2/README.md`: position (mm), joints (deg),
/// served and exact errors (mm).
type V2HybridAnswer = ([f64; 3], [f64; 6], [f64; 3], [f64; 3]);

const V2_HYBRID_ANSWERS: [V2HybridAnswer; 3] = [
    (
        [-495.48014933320513, -261.22060558066715, 359.404929823319],
        [
            17.272893800633657,
            -81.98887450752903,
            88.40996156653269,
            0.07134692051529574,
            93.45549391078386,
            -0.12149026052282592,
        ],
        [-2.447803398, -0.396245906, -0.671138845],
        [-2.431379815, -0.413325813, -0.669583922],
    ),
    (
        [-496.5584396318196, -303.7438549414801, 389.15230080163224],
        [
            23.470392864049625,
            -77.07699251876265,
            77.09116418455962,
            11.235902610533948,
            104.46604662450441,
            -2.872462361249245,
        ],
        [-2.660801131, -0.082845631, -0.685257147],
        [-2.650317985, -0.048157265, -0.710779138],
    ),
    (
        [-379.4891043290153, -391.437788426598, 321.30117534761547],
        [
            39.90741597526584,
            -78.49182609849096,
            88.15719596291765,
            6.224929174902254,
            117.51697908151714,
            17.389107740297682,
        ],
        [-2.510536707, -0.266201873, -0.517639264],
        [-2.513494145, -0.262241703, -0.502584740],
    ),
];

fn assert_close(got: &[f64; 3], want: &[f64; 3], what: &str) {
    for (g, w) in got.iter().zip(want) {
        // Recorded with 9 decimals.
        assert!((g - w).abs() <= 5.1e-10, "{what}: {got:?} vs {want:?}");
    }
}

#[test]
fn the_version_2_tables_open_and_give_their_recorded_answers() {
    let path = root().join("tables/compat/v2/worked_example.tbl");
    // A table before version 4 records no evidence; `tablec inspect` says what follows.
    let o = crate::common::tablec(&["inspect", path.to_str().unwrap()], &root());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains(
            "evidence        not recorded (format version 2): orientations are not checked, \
             a named TCP is flagged `tcp`"
        ),
        "{out}"
    );
    // SAFETY: committed fixtures, not modified while the test runs.
    let table = unsafe { Table::open(&path) }.unwrap();
    assert_eq!(table.header().version, 2);
    assert_eq!(table.header().source_hash, 0xf825_78c5_0b9b_b5e3);
    assert!(table.has_served_field());
    for (exact, (p, error, neighbours, status)) in V2_ANSWERS {
        let c = if exact {
            table.exact().query(p)
        } else {
            table.query(p)
        };
        assert_eq!(c.status, status, "{p:?}");
        assert_eq!(c.neighbours, neighbours, "{p:?}");
        if let Some(e) = error {
            assert_close(&c.position_error_mm, &e, &format!("{p:?} exact {exact}"));
        }
    }
    let hybrid = unsafe { Table::open(root().join("tables/compat/v2/ur5_hybrid.tbl")) }.unwrap();
    assert_eq!(hybrid.header().source_hash, 0x543d_a92b_eccb_c6c5);
    assert!(hybrid.is_hybrid() && hybrid.has_served_field());
    assert_eq!(hybrid.joint_count(), Some(6));
    for (p, joints_deg, served, exact) in V2_HYBRID_ANSWERS {
        let target = Target::at(p);
        let q = joints_deg.map(f64::to_radians);
        assert_eq!(hybrid.query_target(&target).status, Status::MissingJoints);
        let c = hybrid.query_with_joints(&target, &q);
        assert_eq!((c.status, c.neighbours), (Status::Ok, 8));
        assert_close(&c.position_error_mm, &served, "served");
        let c = hybrid.exact().query_with_joints(&target, &q);
        assert_eq!((c.status, c.neighbours), (Status::Ok, 8));
        assert_close(&c.position_error_mm, &exact, "exact");
    }
}

/// `tables/compat/v3/README.md`'s answers: served (with the posture term) and exact
/// errors (mm) at the poses and joint angles of [`V2_HYBRID_ANSWERS`].
const V3_HYBRID_ANSWERS: [([f64; 3], [f64; 3]); 3] = [
    (
        [-2.426598318, -0.401574017, -0.682478181],
        [-2.430698292, -0.412749320, -0.671847173],
    ),
    (
        [-2.658488330, -0.028547154, -0.737099939],
        [-2.650718765, -0.047799751, -0.709384042],
    ),
    (
        [-2.467678842, -0.255059509, -0.547871685],
        [-2.516729391, -0.262274028, -0.505607972],
    ),
];

#[test]
fn the_version_3_table_opens_and_gives_its_recorded_answers() {
    let path = root().join("tables/compat/v3/ur5_hybrid_posture.tbl");
    // SAFETY: a committed fixture, not modified while the test runs.
    let table = unsafe { Table::open(path) }.unwrap();
    assert_eq!(table.header().version, 3);
    assert_eq!(table.header().source_hash, 0x543d_a92b_eccb_c6c5);
    assert!(table.posture().is_some() && table.has_served_field());
    for ((p, joints_deg, _, _), (served, exact)) in V2_HYBRID_ANSWERS.iter().zip(V3_HYBRID_ANSWERS)
    {
        let target = Target::at(*p);
        let q = joints_deg.map(f64::to_radians);
        let c = table.query_with_joints(&target, &q);
        assert_eq!((c.status, c.neighbours), (Status::Ok, 8));
        assert_close(&c.position_error_mm, &served, "served");
        let c = table.exact().query_with_joints(&target, &q);
        assert_eq!((c.status, c.neighbours), (Status::Ok, 8));
        assert_close(&c.position_error_mm, &exact, "exact");
    }
}

/// `tables/compat/v4/README.md`'s answers at the poses and joint angles of
/// [`V2_HYBRID_ANSWERS`]: served and exact position errors (mm), and the model's
/// orientation error (rad), which the table does not serve (its samples measured position
/// alone).
type V4HybridAnswer = ([f64; 3], [f64; 3], [f64; 3]);

const V4_HYBRID_ANSWERS: [V4HybridAnswer; 3] = [
    (
        [-2.4471808475893266, -0.395809105868331, -0.6735556792868956],
        [
            -2.4306982922279166,
            -0.4127493204655287,
            -0.6718471731482983,
        ],
        [
            0.010788686959380851,
            0.00394292365207006,
            0.001982701490489588,
        ],
    ),
    (
        [
            -2.6610676417950305,
            -0.08228687639944124,
            -0.6846993156266301,
        ],
        [
            -2.650718765095082,
            -0.04779975133963073,
            -0.7093840424986455,
        ],
        [
            0.01047111470808937,
            0.005183879332500223,
            0.0006991805178936392,
        ],
    ),
    (
        [
            -2.5139413913681508,
            -0.26671482227712545,
            -0.5179220688773808,
        ],
        [
            -2.5167293911953155,
            -0.26227402773869285,
            -0.5056079723545379,
        ],
        [
            0.009071593866342343,
            0.008264315596956567,
            0.0026492628915198223,
        ],
    ),
];

#[test]
fn the_version_4_table_opens_and_gives_its_recorded_answers() {
    use adwi_runtime::Evidence;
    let path = root().join("tables/compat/v4/ur5_hybrid.tbl");
    // SAFETY: a committed fixture, not modified while the test runs.
    let table = unsafe { Table::open(path) }.unwrap();
    let header = table.header();
    assert_eq!(header.version, 4);
    assert_eq!(header.source_hash, 0x543d_a92b_eccb_c6c5);
    let point = header.evidence.point_in_flange.unwrap();
    assert_eq!(point.translation_mm, [0.0, 0.09f32 as f64, 31.0]);
    assert_eq!(point.rotation_rad, [0.0; 3]);
    let cone = header.evidence.approach.unwrap();
    let axis = [
        -0.9811967015266418,
        -0.18234983086585999,
        0.06325812637805939,
    ];
    assert_eq!((cone.axis, cone.spread_rad), (axis, 0.42157110571861267));
    let model = table.model().unwrap();
    let close = |got: &[f64; 3], want: &[f64; 3], what: &str| {
        for (g, w) in got.iter().zip(want) {
            assert!((g - w).abs() <= 1e-12, "{what}: {got:?} vs {want:?}");
        }
    };
    for ((p, joints_deg, _, _), (served, exact, rotation)) in
        V2_HYBRID_ANSWERS.iter().zip(V4_HYBRID_ANSWERS)
    {
        let q = joints_deg.map(f64::to_radians);
        let target = Target::at(*p);
        let c = table.query_with_joints(&target, &q);
        assert_eq!((c.status, c.evidence), (Status::Ok, Evidence::WITHIN));
        close(&c.position_error_mm, &served, "served");
        // The model's rotation error is the recorded one; the UR5's samples measured
        // position alone, which does not determine it, and no answer serves it.
        close(
            &model.error(&q).unwrap().1,
            &rotation,
            "the model's orientation",
        );
        assert_eq!(c.orientation_error_rad, [0.0; 3]);
        let e = table.exact().query_with_joints(&target, &q);
        close(&e.position_error_mm, &exact, "exact");
        assert_eq!(e.orientation_error_rad, [0.0; 3]);
        // The 200 mm TCP: 169 mm along the flange's z axis from the point, less its y. The
        // point's answer carried unturned, and flagged: no measured rotation turns the lever.
        let nominal = model.nominal().tcp_pose(&q).unwrap();
        let at_tcp = nominal.transform_point([0.0, -(0.09f32 as f64), 169.0]);
        let t = table.query_with_joints(&Target::at(at_tcp).with_tcp([0.0, 0.0, 200.0]), &q);
        assert_eq!((t.status, t.evidence), (Status::Ok, Evidence::TCP));
        let point = table.query_with_joints(&Target::at(nominal.translation_mm), &q);
        close(&t.position_error_mm, &point.position_error_mm, "tcp");
    }
    // The first pose with its wrist turned 60°: an approach axis the samples never had,
    // flagged.
    let mut q = V2_HYBRID_ANSWERS[0].1.map(f64::to_radians);
    q[4] += 60f64.to_radians();
    let at = model.nominal().tcp_pose(&q).unwrap().translation_mm;
    let c = table.query_with_joints(&Target::at(at), &q);
    assert_eq!(c.status, Status::Ok);
    assert_eq!(c.evidence, Evidence::ORIENTATION);
    assert_eq!(c.orientation_error_rad, [0.0; 3]);
}

/// `tables/compat/v6/README.md`'s answers: served and exact position errors (mm) and the
/// served orientation error (rad) at the first three random UR5 poses.
const V6_ANSWERS: [([f64; 3], [f64; 3], [f64; 3]); 3] = [
    (
        [-2.449057494, -0.397001820, -0.673431153],
        [-2.433766034, -0.412719148, -0.671846109],
        [0.010788687, 0.003942924, 0.001982701],
    ),
    (
        [-2.664131701, -0.083651455, -0.683472288],
        [-2.654528067, -0.051653353, -0.706373889],
        [0.010471115, 0.005183879, 0.000699181],
    ),
    (
        [-2.517010377, -0.264581274, -0.517458894],
        [-2.519596322, -0.260461172, -0.506034363],
        [0.009071594, 0.008264316, 0.002649263],
    ),
];

/// `tablec query` explains a joints mismatch by the distance the query compared: with
/// `--tcp`, the named TCP's at the joints from the target (the fixture records its point,
/// 31 mm out on the flange: a TCP 400 mm out lies 369 mm past it), not the measured
/// point's, which these joints put on the target.
#[test]
fn a_joints_mismatch_is_explained_by_the_distance_the_query_compared() {
    let path = root().join("tables/compat/v6/ur5_hybrid.tbl");
    let query = |extra: &[&str]| {
        let joints = "17.2729,-81.9889,88.4100,0.0713,93.4555,30.3";
        let mut args = vec!["query", path.to_str().unwrap(), "--joints", joints];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--", "-495.480149", "-261.220606", "359.404930"]);
        crate::common::tablec(&args, &root())
    };
    let o = query(&["--tcp", "0,0,400"]);
    assert_eq!(o.status.code(), Some(3));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(
            "the joints' nominal forward kinematics puts the --tcp point 369.0 mm from the \
             target (the table allows 200.0 mm)"
        ),
        "{err}"
    );
    // Without the TCP these joints reach the target: answered.
    assert_eq!(query(&[]).status.code(), Some(0));
}

/// The version-6 fixture opens, records the angles its samples span, gives its recorded
/// answers within them from both tiers, and beyond them fades its residual: with the
/// wrist's last joint turned 1.5° past the samples' range (its TCP still in the grid) the
/// answer is faded, 10° past it is the model's alone.
#[test]
fn the_version_6_table_opens_and_bounds_its_residual_by_its_samples_joints() {
    let path = root().join("tables/compat/v6/ur5_hybrid.tbl");
    // SAFETY: a committed fixture, not modified while the test runs.
    let table = unsafe { Table::open(&path) }.unwrap();
    assert_eq!(table.header().version, 6);
    let model = table.model().unwrap();
    assert!(model.bounds_residual() && model.joint_terms().is_none());
    let points = crate::common::ur5_random();
    for (s, e) in crate::common::assert_recorded_ur5_answers(&table, &points, &V6_ANSWERS) {
        assert_eq!((s.residual, e.residual), (Residual::Full, Residual::Full));
    }
    // `tablec inspect` shows the ranges.
    let o = crate::common::tablec(&["inspect", path.to_str().unwrap()], &root());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("residual joints j1 [-24.4, 56.5], j2 [-105.0, -25.5], j3 [30.1, 140.4]"),
        "{out}"
    );
    // What it serves, and what a named TCP gets: the UR5's samples measured position alone.
    assert!(
        out.contains(
            "measured point (0.000, 0.090, 31.000) mm in the flange frame: no orientation \
             error is served (the samples measured position alone, which does not determine \
             the model's), and a named TCP more than 1 mm from it is carried unturned and \
             flagged `tcp`"
        ),
        "{out}"
    );
    // `tablec query` says which joint lies beyond the samples' angles, and how far.
    let o = crate::common::tablec(
        &[
            "query",
            path.to_str().unwrap(),
            "-495.480149",
            "-261.220606",
            "359.404930",
            "--joints",
            "17.2729,-81.9889,88.4100,0.0713,93.4555,30.3",
        ],
        &root(),
    );
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains(
            "residual     model_only: joint 6 at 30.3° lies 10.0° beyond the -29.4° to 20.3° \
             the samples span"
        ),
        "{out}"
    );
    let [_, hi] = model.joint_terms().range_rad[5];
    for (past_deg, residual) in [(1.5, Residual::Faded), (10.0, Residual::ModelOnly)] {
        let mut q = points.joints_rad(0).unwrap().to_vec();
        q[5] = hi + f64::to_radians(past_deg);
        let target = Target::at(model.nominal().tcp_pose(&q).unwrap().translation_mm);
        for c in [
            table.query_with_joints(&target, &q),
            table.exact().query_with_joints(&target, &q),
        ] {
            assert_eq!((c.status, c.residual), (Status::Ok, residual), "{c:?}");
            if residual == Residual::ModelOnly {
                let (model_mm, _) = model.error(&q).unwrap();
                for (got, want) in c.position_error_mm.iter().zip(model_mm) {
                    assert!((got - want).abs() < 1e-9, "{c:?}");
                }
            }
        }
    }
}
