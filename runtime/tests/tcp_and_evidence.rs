//! A named TCP and the evidence flag (docs/runtime.md, "Another TCP" and "Evidence"): a
//! hybrid table answers the error at any TCP from its model's full pose error, held here
//! to the slow, obvious reference (both chains walked again with the TCP as their tool);
//! answers beyond the samples' orientations or at a TCP the table cannot place carry the
//! flag. Tables are written by hand (the runtime cannot depend on the compiler).

use adwi_runtime::chain::Chain;
use adwi_runtime::format::v2::{self, ChainRecord, ModelRecord, NodeSet, QuerySample};
use adwi_runtime::format::{
    encode, ApproachCone, EvidenceRecord, Grid, Header, PointInFlange, ServedField, CONTENT_MODEL,
    CONTENT_ORIENTATION, FORMAT_VERSION, ORIENTATION_MARGIN_RAD, RKYV_FLAGS, TCP_MARGIN_MM,
};
use adwi_runtime::kinematics::{rotation_from_vector, rotation_vector, MdhJoint, Transform};
use adwi_runtime::method::{self, MethodParams};
use adwi_runtime::{Evidence, Residual, Status, Table, Target};
use proptest::prelude::*;

const GRID: Grid = Grid {
    origin_mm: [500.0, -100.0, 200.0],
    cell_mm: 50.0,
    dims: [2, 2, 1],
};
/// Nodes a set: `(2 + 1)(2 + 1)(1 + 1)`.
const PER_SET: usize = 18;
/// Every node's residual: the served field is this constant inside the grid.
const RESIDUAL_MM: [f64; 3] = [0.1, -0.2, 0.05];
/// Where the joints put the nominal point: the grid's middle.
const POINT_MM: [f64; 3] = [550.0, -50.0, 225.0];

/// The measured point in the flange frame (a probe 31 mm out, turned a little), as the
/// header stores it.
fn point_in_flange() -> PointInFlange {
    PointInFlange::stored([0.0, 0.09, 31.0], [0.02, -0.01, 0.3])
}

fn pose_of(p: &PointInFlange) -> Transform {
    Transform {
        rotation: rotation_from_vector(p.rotation_rad),
        translation_mm: p.translation_mm,
    }
}

/// Nominal and calibrated chains: the calibrated one off in every way that turns the
/// flange (joint offsets, a tilted base, its tool), both bases moved so that the nominal
/// point at `q` is `POINT_MM`.
fn chains(q: &[f64; 6]) -> (Chain, Chain) {
    use std::f64::consts::FRAC_PI_2;
    let j = |a_mm, d_mm, alpha_rad| MdhJoint {
        a_mm,
        d_mm,
        alpha_rad,
        ..MdhJoint::default()
    };
    let joints = [
        j(350.0, 750.0, -FRAC_PI_2),
        j(1250.0, 0.0, 0.0),
        j(55.0, 0.0, FRAC_PI_2),
        j(0.0, 1100.0, -FRAC_PI_2),
        j(0.0, 0.0, FRAC_PI_2),
        j(0.0, 230.0, 0.0),
    ];
    // The flange in the last joint's frame (a mounting plate), then the point on it.
    let flange = Transform {
        rotation: rotation_from_vector([0.0, 0.0, 0.5]),
        translation_mm: [1.0, 2.0, 10.0],
    };
    let tool_nominal = flange.compose(&pose_of(&point_in_flange()));
    let mut calibrated_joints = joints;
    calibrated_joints[1].theta_offset_rad = 2e-3;
    calibrated_joints[4].theta_offset_rad = -3e-3;
    calibrated_joints[5].alpha_rad = 1e-3;
    let base = Transform {
        rotation: rotation_from_vector([1e-3, -2e-3, 5e-4]),
        translation_mm: [0.25, -0.1, 0.4],
    };
    let tool_calibrated = tool_nominal.compose(&Transform {
        rotation: rotation_from_vector([2e-4, 0.0, -1e-4]),
        translation_mm: [0.3, -0.2, 0.1],
    });
    let nominal = Chain::from_mdh(Transform::IDENTITY, &joints, tool_nominal, None).unwrap();
    let calibrated = Chain::from_mdh(base, &calibrated_joints, tool_calibrated, None).unwrap();
    let at = nominal.tcp_pose(q).unwrap().translation_mm;
    let shift = [0, 1, 2].map(|a| POINT_MM[a] - at[a]);
    let moved = |c: Chain| {
        let mut c = c;
        for (t, s) in c.base.translation_mm.iter_mut().zip(shift) {
            *t += s;
        }
        c
    };
    (moved(nominal), moved(calibrated))
}

/// One sample at [`POINT_MM`] listed by every cell, the served field the constant
/// [`RESIDUAL_MM`], and `model` (a hybrid table's).
fn data(model: Option<ModelRecord>) -> v2::TableData {
    let mut cell = [0u16; 32];
    cell[0] = 1;
    v2::TableData {
        cells: vec![cell; 4],
        samples: vec![QuerySample {
            actual_mm: POINT_MM,
            norm_mm: method::norm_mm(POINT_MM),
        }],
        errors_mm: vec![RESIDUAL_MM],
        node_sets: vec![NodeSet {
            config: method::CONFIG_UNKNOWN,
            first_node: 0,
        }],
        node_errors_mm: vec![RESIDUAL_MM; PER_SET],
        model,
        ..v2::TableData::default()
    }
}

/// A hybrid table of [`chains`] at `q`, its served field the constant [`RESIDUAL_MM`],
/// recording `evidence`, of samples that measured position alone.
fn table(q: &[f64; 6], evidence: EvidenceRecord) -> Table<adwi_runtime::AlignedBytes> {
    Table::from_vec(table_bytes(q, evidence)).unwrap()
}

/// [`table`] of samples that measured orientation too (their orientation residuals zero).
fn table_with_orientation(
    q: &[f64; 6],
    evidence: EvidenceRecord,
) -> Table<adwi_runtime::AlignedBytes> {
    Table::from_vec(table_bytes_measuring(q, evidence, Some([0.0; 3]))).unwrap()
}

/// The bytes of [`table`].
fn table_bytes(q: &[f64; 6], evidence: EvidenceRecord) -> Vec<u8> {
    table_bytes_measuring(q, evidence, None)
}

/// The bytes of [`table`], or, with `orientation` (the residual's orientation error, rad,
/// every sample's and node's), of a table of samples that measured orientation.
fn table_bytes_measuring(
    q: &[f64; 6],
    evidence: EvidenceRecord,
    orientation: Option<[f64; 3]>,
) -> Vec<u8> {
    let (nominal, calibrated) = chains(q);
    let mut data = data(Some(ModelRecord {
        nominal: ChainRecord::from_chain(&nominal),
        calibrated: ChainRecord::from_chain(&calibrated),
    }));
    if let Some(r) = orientation {
        data.orientation_errors_rad = vec![r; data.samples.len()];
        data.node_orientation_errors_rad = vec![r; data.node_errors_mm.len()];
    }
    let header = Header {
        version: FORMAT_VERSION,
        rkyv_flags: RKYV_FLAGS,
        content_flags: if orientation.is_some() {
            CONTENT_MODEL | CONTENT_ORIENTATION
        } else {
            CONTENT_MODEL
        },
        payload_len: 0,
        payload_checksum: 0,
        source_hash: 0,
        method: MethodParams::paper(100.0),
        grid: GRID,
        sample_count: 1,
        joint_radius_rad: 0.0,
        joint_count: 6,
        node_set_count: 1,
        tuning: None,
        served_field: ServedField::Method,
        evidence,
        merge_voxel_mm: None,
    };
    let bytes = encode(header, &data).unwrap();
    assert_eq!(
        u16::from_le_bytes([bytes[10], bytes[11]]),
        if evidence.is_empty() { 2 } else { 4 }
    );
    bytes
}

/// The error at the TCP `tcp_mm` (flange frame) by the definition: both chains walked again
/// with the TCP as their tool, rigid with the measured point (`tool · M⁻¹ · t`), position
/// and orientation, base frame; and where the nominal TCP is.
fn reference(q: &[f64; 6], tcp_mm: [f64; 3]) -> ([f64; 3], [f64; 3], [f64; 3]) {
    let (nominal, calibrated) = chains(q);
    let point_to_tcp = pose_of(&point_in_flange()).inverse().compose(&Transform {
        rotation: Transform::IDENTITY.rotation,
        translation_mm: tcp_mm,
    });
    let (mut nominal_tcp, mut calibrated_tcp) = (nominal, calibrated);
    nominal_tcp.tool = nominal.tool.compose(&point_to_tcp);
    calibrated_tcp.tool = calibrated.tool.compose(&point_to_tcp);
    let n = nominal_tcp.tcp_pose(q).unwrap();
    let c = calibrated_tcp.tcp_pose(q).unwrap();
    let position = [0, 1, 2].map(|a| c.translation_mm[a] - n.translation_mm[a]);
    let rt = n.rotation;
    let turn = [0, 1, 2]
        .map(|i| [0, 1, 2].map(|j| (0..3).map(|k| c.rotation[i][k] * rt[j][k]).sum::<f64>()));
    (position, rotation_vector(&turn), n.translation_mm)
}

fn recorded() -> EvidenceRecord {
    EvidenceRecord {
        approach: None,
        point_in_flange: Some(point_in_flange()),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// A hybrid table of samples with orientation answers the error at a named TCP as the
    /// chains walked with that TCP as their tool give it, plus the residual at the
    /// table's point, within its samples' evidence. One of samples of position alone
    /// serves no rotation error (positions at one point do not determine it): the lever
    /// is carried unturned, the answer the point's error, within the evidence only for a
    /// TCP within `TCP_MARGIN_MM` of the point and flagged `tcp` beyond.
    #[test]
    fn a_named_tcp_is_answered_as_the_chains_with_that_tool(
        q in prop::array::uniform6(-3.0..3.0f64),
        tcp in prop::array::uniform3(-300.0..300.0f64),
        near in prop::bool::weighted(0.2),
    ) {
        let point = point_in_flange().translation_mm;
        // Some TCPs within a millimetre of the point, where either table is within.
        let tcp = if near { [0, 1, 2].map(|a| point[a] + tcp[a] / 600.0) } else { tcp };
        let (position_mm, rotation_rad, at_mm) = reference(&q, tcp);
        let (point_error_mm, _, _) = reference(&q, point);
        let within_margin = method::distance_mm(tcp, point) <= TCP_MARGIN_MM;
        for (table, flagged, position_mm, rotation_rad) in [
            (table_with_orientation(&q, recorded()), false, position_mm, rotation_rad),
            (table(&q, recorded()), !within_margin, point_error_mm, [0.0; 3]),
        ] {
            let got = table.query_with_joints(&Target::at(at_mm).with_tcp(tcp), &q);
            prop_assert_eq!(got.status, Status::Ok);
            prop_assert_eq!(got.residual, Residual::Full);
            let evidence = if flagged { Evidence::TCP } else { Evidence::WITHIN };
            prop_assert_eq!(got.evidence, evidence);
            for c in 0..3 {
                let expected = position_mm[c] + RESIDUAL_MM[c];
                prop_assert!((got.position_error_mm[c] - expected).abs() <= 1e-9, "{:?} vs {:?}", got.position_error_mm, position_mm);
                prop_assert!((got.orientation_error_rad[c] - rotation_rad[c]).abs() <= 1e-12, "{:?} vs {:?}", got.orientation_error_rad, rotation_rad);
            }
        }
    }

    /// `joints_offset_mm` is the distance a query compares with `joints_tolerance_mm`:
    /// with the table's point recorded, of the named TCP at the joints (the chains walked
    /// with it as their tool) from the target; without, of the table's point from the
    /// target. A query refuses exactly the targets it puts beyond the tolerance, and
    /// answers the others (the model alone beyond the grid).
    #[test]
    fn the_joints_offset_is_what_a_query_compares(
        q in prop::array::uniform6(-3.0..3.0f64),
        tcp in prop::array::uniform3(-300.0..300.0f64),
        shift in prop::array::uniform3(-120.0..120.0f64),
    ) {
        let (_, _, at_mm) = reference(&q, tcp);
        let target = Target::at([0, 1, 2].map(|a| at_mm[a] + shift[a])).with_tcp(tcp);
        for (table, want_mm) in [
            (table(&q, recorded()), method::norm_mm(shift)),
            (
                table(&q, EvidenceRecord::default()),
                method::distance_mm(POINT_MM, target.position_mm),
            ),
        ] {
            let off = table.joints_offset_mm(&target, &q).unwrap();
            prop_assert!((off - want_mm).abs() <= 1e-9, "{} against {}", off, want_mm);
            let tolerance = table.joints_tolerance_mm().unwrap();
            let want = if off > tolerance { Status::JointsMismatch } else { Status::Ok };
            prop_assert_eq!(table.query_with_joints(&target, &q).status, want);
            prop_assert_eq!(table.exact().query_with_joints(&target, &q).status, want);
        }
    }
}

/// At the table's own point (no TCP named) the answer is the model's error at the point,
/// with the model's orientation error where the samples measured orientation; where they
/// measured position alone, which does not determine it, with none (zero, as a
/// position-only table's), the position the same.
#[test]
fn a_hybrid_table_answers_the_model_orientation_error_where_its_samples_measured_one() {
    let q = [0.3, -0.8, 1.1, 0.4, 0.9, -0.6];
    let (nominal, calibrated) = chains(&q);
    let n = nominal.tcp_pose(&q).unwrap();
    let c = calibrated.tcp_pose(&q).unwrap();
    let (position, rotation) = adwi_runtime::kinematics::pose_error(&n, &c);
    assert!(method::norm_mm(rotation) > 1e-3);
    for (table, served) in [
        (table_with_orientation(&q, recorded()), rotation),
        (table(&q, recorded()), [0.0; 3]),
    ] {
        let got = table.query_with_joints(&Target::at(POINT_MM), &q);
        assert_eq!(got.status, Status::Ok);
        assert_eq!(got.evidence, Evidence::WITHIN);
        for a in 0..3 {
            assert!((got.position_error_mm[a] - position[a] - RESIDUAL_MM[a]).abs() < 1e-9);
            assert!((got.orientation_error_rad[a] - served[a]).abs() < 1e-12);
        }
        let exact = table.exact().query_with_joints(&Target::at(POINT_MM), &q);
        assert_eq!(exact.orientation_error_rad, got.orientation_error_rad);
    }
}

/// A named TCP's lever is turned by the answer's whole rotation error, the model's and
/// the residual's, as the TCP rides on the point: `e_tcp = e_point + (Exp(ω) − I) · x`,
/// `e_point` and `ω` the answer at the point, `x` the lever in the base frame (the nominal
/// TCP less the nominal point). `tablec compensate` carries a TCP by the same rotation.
#[test]
fn a_named_tcp_turns_by_the_models_and_the_residuals_rotation() {
    let q = [0.3, -0.8, 1.1, 0.4, 0.9, -0.6];
    let residual_rad = [4e-4, -3e-4, 2e-4];
    let bytes = table_bytes_measuring(&q, recorded(), Some(residual_rad));
    let table = Table::from_vec(bytes).unwrap();
    let (_, _, point_at_mm) = reference(&q, point_in_flange().translation_mm);
    for tcp in [[0.0, 0.0, 200.0], [40.0, -25.0, 350.0]] {
        let (_, _, at_mm) = reference(&q, tcp);
        let lever_mm = [0, 1, 2].map(|a| at_mm[a] - point_at_mm[a]);
        for exact in [false, true] {
            let ask = |t: &Target| match exact {
                false => table.query_with_joints(t, &q),
                true => table.exact().query_with_joints(t, &q),
            };
            let at_point = ask(&Target::at(point_at_mm));
            let at_tcp = ask(&Target::at(at_mm).with_tcp(tcp));
            assert_eq!(
                (at_tcp.status, at_tcp.evidence),
                (Status::Ok, Evidence::WITHIN)
            );
            // (The point is the target less the lever: the same to rounding.)
            let rotation_apart =
                method::distance_mm(at_tcp.orientation_error_rad, at_point.orientation_error_rad);
            assert!(rotation_apart < 1e-12, "{rotation_apart} rad");
            let turned = rotation_from_vector(at_point.orientation_error_rad);
            for a in 0..3 {
                let turn: f64 =
                    (0..3).map(|k| turned[a][k] * lever_mm[k]).sum::<f64>() - lever_mm[a];
                let want = at_point.position_error_mm[a] + turn;
                assert!(
                    (at_tcp.position_error_mm[a] - want).abs() < 1e-9,
                    "exact {exact}: {:?} vs {want} ({a})",
                    at_tcp.position_error_mm
                );
            }
            // The residual's rotation is felt: without it the lever turns less.
            let model_rad = [0, 1, 2].map(|a| at_point.orientation_error_rad[a] - residual_rad[a]);
            let model_only = rotation_from_vector(model_rad);
            let apart: f64 = (0..3)
                .map(|a| {
                    let t: f64 = (0..3)
                        .map(|k| (turned[a][k] - model_only[a][k]) * lever_mm[k])
                        .sum();
                    t * t
                })
                .sum::<f64>()
                .sqrt();
            assert!(apart > 0.05, "{apart} mm");
        }
    }
}

/// The lever matters: a 200 mm TCP's error differs from the point's by the rotation error
/// times the lever (here millimetres), within the samples' evidence when they measured
/// orientation. Samples of position alone do not determine that rotation: the point's
/// error is carried unturned and flagged. A table that does not record its point says it
/// cannot place the TCP instead of answering the point's error as the TCP's.
#[test]
fn a_far_tcp_moves_the_answer_and_an_unplaceable_one_is_flagged() {
    let q = [0.3, -0.8, 1.1, 0.4, 0.9, -0.6];
    let tcp = [0.0, 0.0, 200.0];
    let (position_mm, _, at_mm) = reference(&q, tcp);
    let measured = table_with_orientation(&q, recorded());
    let at_tcp = measured.query_with_joints(&Target::at(at_mm).with_tcp(tcp), &q);
    let at_point = measured.query_with_joints(&Target::at(POINT_MM), &q);
    let moved = method::distance_mm(at_tcp.position_error_mm, at_point.position_error_mm);
    assert!(moved > 0.1, "the lever moved the answer by {moved} mm");
    assert!(
        method::distance_mm(
            at_tcp.position_error_mm,
            [0, 1, 2].map(|a| position_mm[a] + RESIDUAL_MM[a])
        ) < 1e-9
    );
    assert_eq!(at_tcp.evidence, Evidence::WITHIN);

    // The samples measured position alone: the lever is not turned, and the answer says
    // it is beyond what they determine.
    let with_point = table(&q, recorded());
    let unturned = with_point.query_with_joints(&Target::at(at_mm).with_tcp(tcp), &q);
    assert_eq!(unturned.evidence, Evidence::TCP);
    assert_eq!(unturned.orientation_error_rad, [0.0; 3]);
    assert_eq!(unturned.position_error_mm, at_point.position_error_mm);

    let without = table(&q, EvidenceRecord::default());
    let got = without.query_with_joints(&Target::at(POINT_MM).with_tcp(tcp), &q);
    assert_eq!(got.status, Status::Ok);
    assert_eq!(got.evidence, Evidence::TCP);
}

/// Answers at approach axes beyond the samples' cone are flagged, the answer itself
/// unchanged: the served field stays continuous across the cone's edge.
#[test]
fn an_orientation_beyond_the_samples_is_flagged_and_the_answer_stays_continuous() {
    let q = [0.3, -0.8, 1.1, 0.4, 0.9, -0.6];
    let (nominal, _) = chains(&q);
    let r = nominal.tcp_pose(&q).unwrap().rotation;
    let axis = [r[0][2], r[1][2], r[2][2]];
    let cone = |axis| EvidenceRecord {
        approach: ApproachCone::of([axis]),
        point_in_flange: Some(point_in_flange()),
    };
    let inside = table(&q, cone(axis)).query_with_joints(&Target::at(POINT_MM), &q);
    assert_eq!(inside.evidence, Evidence::WITHIN);
    assert_eq!(inside.residual, Residual::Full);

    // The samples' axis turned 10 degrees away from the query's.
    let turn = rotation_from_vector([0.0, 10f64.to_radians(), 0.0]);
    let other = [0, 1, 2].map(|i| (0..3).map(|k| turn[i][k] * axis[k]).sum::<f64>());
    let outside = table(&q, cone(other)).query_with_joints(&Target::at(POINT_MM), &q);
    assert_eq!(outside.status, Status::Ok);
    assert_eq!(outside.evidence, Evidence::ORIENTATION);
    assert_eq!(outside.residual, Residual::Full);
    assert_eq!(outside.position_error_mm, inside.position_error_mm);
    assert_eq!(outside.orientation_error_rad, inside.orientation_error_rad);
}

/// The cone holds its own axes and the margin, and nothing farther.
#[test]
fn the_approach_cone_holds_its_samples_and_the_margin() {
    let tilt = |deg: f64| {
        let r = rotation_from_vector([deg.to_radians(), 0.0, 0.0]);
        [r[0][2], r[1][2], r[2][2]]
    };
    let cone = ApproachCone::of([tilt(0.0), tilt(20.0), tilt(40.0)]).unwrap();
    assert!((cone.spread_rad - 20f64.to_radians()).abs() < 1e-6);
    for deg in [0.0, 10.0, 20.0, 40.0, 42.0] {
        assert!(cone.holds(tilt(deg)), "{deg} deg");
    }
    let margin_deg = ORIENTATION_MARGIN_RAD.to_degrees();
    assert!(!cone.holds(tilt(40.0 + margin_deg + 0.1)));
    assert!(!cone.holds(tilt(-5.0 - margin_deg)));
    // Axes every way round: no direction is beyond them.
    let all = ApproachCone::of([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]).unwrap();
    assert!(all.holds([1.0, 0.0, 0.0]));
}

/// A header's evidence fields are checked at open: a forged one is refused with a reason.
#[test]
fn forged_evidence_is_refused_at_open() {
    let q = [0.3, -0.8, 1.1, 0.4, 0.9, -0.6];
    let good = table_bytes(
        &q,
        EvidenceRecord {
            approach: ApproachCone::of([[0.0, 0.0, 1.0]]),
            point_in_flange: Some(point_in_flange()),
        },
    );
    assert!(Table::from_vec(&good).is_ok());
    let mut bytes = good.clone();
    let reseal = |b: &mut Vec<u8>| {
        let sum = xxhash_rust::xxh3::xxh3_64(&b[..248]);
        b[248..256].copy_from_slice(&sum.to_le_bytes());
    };
    // An axis that is not a unit vector.
    bytes[200..204].copy_from_slice(&2.0f32.to_le_bytes());
    reseal(&mut bytes);
    assert!(Table::from_vec(&bytes).is_err());
    // An unknown evidence flag.
    let mut bytes = good.clone();
    bytes[240..244].copy_from_slice(&(1u32 << 7 | 3).to_le_bytes());
    reseal(&mut bytes);
    assert!(Table::from_vec(&bytes).is_err());
    // A point that is not finite.
    let mut bytes = good.clone();
    bytes[216..220].copy_from_slice(&f32::NAN.to_le_bytes());
    reseal(&mut bytes);
    assert!(Table::from_vec(&bytes).is_err());
}

/// A position-only table checks the orientation the caller gives against its samples'.
#[test]
fn a_position_only_table_flags_an_orientation_its_samples_never_had() {
    let data = data(None);
    // KUKA A, B, C = 0, 90, 0: the approach axis is x.
    let header = Header {
        version: FORMAT_VERSION,
        rkyv_flags: RKYV_FLAGS,
        content_flags: 0,
        payload_len: 0,
        payload_checksum: 0,
        source_hash: 0,
        method: MethodParams::paper(100.0),
        grid: GRID,
        sample_count: 1,
        joint_radius_rad: 0.0,
        joint_count: 0,
        node_set_count: 1,
        tuning: None,
        served_field: ServedField::Method,
        evidence: EvidenceRecord {
            approach: ApproachCone::of([[1.0, 0.0, 0.0]]),
            point_in_flange: None,
        },
        merge_voxel_mm: None,
    };
    let table = Table::from_vec(encode(header, &data).unwrap()).unwrap();
    let at_b = |b_deg: f64| Target::at(POINT_MM).with_rotation([0.0, b_deg.to_radians(), 0.0]);
    assert_eq!(table.query_target(&at_b(90.0)).evidence, Evidence::WITHIN);
    assert_eq!(table.query_target(&at_b(88.0)).evidence, Evidence::WITHIN);
    let tilted = table.query_target(&at_b(45.0));
    assert_eq!(tilted.status, Status::Ok);
    assert_eq!(tilted.evidence, Evidence::ORIENTATION);
    // Not told the orientation, the table cannot check it.
    assert_eq!(
        table.query_target(&Target::at(POINT_MM)).evidence,
        Evidence::WITHIN
    );
    // A TCP it cannot relate to its point.
    let tcp = table.query_target(&Target::at(POINT_MM).with_tcp([0.0, 0.0, 200.0]));
    assert_eq!(tcp.evidence, Evidence::TCP);
    // Absurd values are refused, not answered.
    let absurd = Target::at(POINT_MM).with_rotation([1e300, 0.0, 0.0]);
    assert_eq!(table.query_target(&absurd).status, Status::InvalidInput);
}
