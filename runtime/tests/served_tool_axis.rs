//! The served field that turns with the tool ([`ServedField::KrigingToolAxis`]): four
//! vectors a node, `f, h_x, h_y, h_z`, answering `f + a·h` blended with `a` the nominal
//! TCP's approach axis, plus the model part. Tables are written by hand here (the runtime
//! cannot depend on the compiler) and checked against a slow, obvious reference; then the
//! refusals of tables that break the layout.

use adwi_runtime::chain::Chain;
use adwi_runtime::format::v2::{self, ChainRecord, ModelRecord, NodeSet, QuerySample};
use adwi_runtime::format::{
    encode, Grid, Header, ServedField, CONTENT_MODEL, CONTENT_ORIENTATION, FORMAT_VERSION,
    RKYV_FLAGS,
};
use adwi_runtime::kinematics::{MdhJoint, Transform};
use adwi_runtime::method::{self, MethodParams};
use adwi_runtime::model::PreparedModel;
use adwi_runtime::{OpenError, Payload, Residual, Status, Table, Target};
use proptest::prelude::*;

const GRID: Grid = Grid {
    origin_mm: [500.0, -100.0, 200.0],
    cell_mm: 50.0,
    dims: [2, 2, 1],
};
/// Nodes a set: `(2 + 1)(2 + 1)(1 + 1)`.
const PER_SET: usize = 18;
const NX: usize = 3;
const NY: usize = 3;
/// The node whose value is missing: the grid's maximum corner, so that the last cell
/// fades.
const MISSING: usize = PER_SET - 1;

/// How far two computations of the model's position error may differ, mm: some units in
/// the last place of a TCP coordinate about a metre from the base (one unit there is
/// 1.1e-13 mm).
const ROUNDING_MM: f64 = 4e-12;

/// The nominal and calibrated chains, both bases moved by `shift_mm` (a translation of the
/// base moves both TCPs alike: the model's error does not change).
fn chains_shifted(shift_mm: [f64; 3]) -> (Chain, Chain) {
    let (nominal, calibrated) = chains();
    let shift = |c: Chain| {
        let mut c = c;
        for (t, s) in c.base.translation_mm.iter_mut().zip(shift_mm) {
            *t += s;
        }
        c
    };
    (shift(nominal), shift(calibrated))
}

/// The base shift that puts the nominal TCP at `q` on `position_mm`, so that `q` are joint
/// values for that target (not [`Status::JointsMismatch`]).
fn reaching(position_mm: [f64; 3], q: &[f64; 6]) -> [f64; 3] {
    let tcp = chains().0.tcp_pose(q).unwrap().translation_mm;
    [0, 1, 2].map(|a| position_mm[a] - tcp[a])
}

fn chains() -> (Chain, Chain) {
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
    let nominal = Chain::from_mdh(Transform::IDENTITY, &joints, Transform::IDENTITY, None);
    // A calibrated chain a little off, so that the model part is not zero and its sum with
    // the field is checked too.
    let mut calibrated_joints = joints;
    calibrated_joints[1].theta_offset_rad = 1e-3;
    let base = Transform {
        translation_mm: [0.25, -0.1, 0.4],
        ..Transform::IDENTITY
    };
    let calibrated = Chain::from_mdh(base, &calibrated_joints, Transform::IDENTITY, None);
    (nominal.unwrap(), calibrated.unwrap())
}

/// Term `t` of node `n`, position (`kind` 0) or orientation (1): smooth, distinct values.
fn term(n: usize, t: usize, kind: usize) -> [f64; 3] {
    let scale = [0.3, 1e-4][kind];
    [0, 1, 2]
        .map(|c| scale * (1.7 * n as f64 + 0.9 * t as f64 + 2.3 * c as f64 + kind as f64).sin())
}

/// The node values of a table of `stride` vectors a node: term `t < stride` of node `n`,
/// `h` scaled by `h_scale`, and the missing node NaN throughout.
fn nodes(stride: usize, kind: usize, h_scale: f64) -> Vec<[f64; 3]> {
    (0..PER_SET)
        .flat_map(|n| {
            (0..stride).map(move |t| match (n, t) {
                (MISSING, _) => [v2::NO_NODE_VALUE; 3],
                (_, 0) => term(n, 0, kind),
                _ => term(n, t, kind).map(|v| v * h_scale),
            })
        })
        .collect()
}

/// A hybrid table with orientation, one sample in the middle of the grid listed by every
/// cell, and a served field of `field` (its nodes from [`nodes`]).
fn parts(field: ServedField, h_scale: f64) -> (Header, v2::TableData) {
    parts_shifted(field, h_scale, [0.0; 3])
}

/// [`parts`] with the chains of [`chains_shifted`].
fn parts_shifted(field: ServedField, h_scale: f64, shift_mm: [f64; 3]) -> (Header, v2::TableData) {
    let (nominal, calibrated) = chains_shifted(shift_mm);
    let actual_mm = [550.0, -50.0, 225.0];
    let mut cell = [0u16; 32];
    cell[0] = 1;
    let stride = field.node_stride();
    let data = v2::TableData {
        cells: vec![cell; 4],
        samples: vec![QuerySample {
            actual_mm,
            norm_mm: method::norm_mm(actual_mm),
        }],
        errors_mm: vec![[0.1, -0.2, 0.05]],
        orientation_errors_rad: vec![[1e-5, 2e-5, -1e-5]],
        node_sets: vec![NodeSet {
            config: method::CONFIG_UNKNOWN,
            first_node: 0,
        }],
        node_errors_mm: nodes(stride, 0, h_scale),
        node_orientation_errors_rad: nodes(stride, 1, h_scale),
        model: Some(ModelRecord {
            nominal: ChainRecord::from_chain(&nominal),
            calibrated: ChainRecord::from_chain(&calibrated),
        }),
        ..v2::TableData::default()
    };
    let header = Header {
        version: FORMAT_VERSION,
        rkyv_flags: RKYV_FLAGS,
        content_flags: CONTENT_ORIENTATION | CONTENT_MODEL,
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
        served_field: field,
        evidence: Default::default(),
        merge_voxel_mm: None,
    };
    (header, data)
}

fn open(
    header: Header,
    data: &v2::TableData,
) -> Result<Table<adwi_runtime::AlignedBytes>, OpenError> {
    Table::from_vec(encode(header, data).unwrap())
}

fn refusal(header: Header, data: &v2::TableData) -> &'static str {
    match open(header, data) {
        Err(OpenError::Corrupt { what }) => what,
        Err(e) => panic!("refused, but not as corrupt: {e}"),
        Ok(_) => panic!("opened"),
    }
}

/// The served answer by the definition: the 8 corners of the cell of the target's nearest
/// point in the grid box weighted by hand, each `f + a·h` with `a` the nominal TCP's z
/// axis, the missing node counting zero, scaled by the fade outside the box, plus the
/// model part; and the residual flag the answer should carry.
fn reference(position_mm: [f64; 3], q: &[f64; 6]) -> ([f64; 3], [f64; 3], Residual) {
    // The chains the table holds, so that the model part is computed alike.
    let (nominal, calibrated) = chains_shifted(reaching(position_mm, q));
    let r = nominal.tcp_pose(q).unwrap().rotation;
    let a = [r[0][2], r[1][2], r[2][2]];
    let mut cell = [0usize; 3];
    let mut t = [0.0; 3];
    let mut distance2_mm2 = 0.0;
    for axis in 0..3 {
        let low = GRID.origin_mm[axis];
        let high = low + GRID.dims[axis] as f64 * GRID.cell_mm;
        let nearest = position_mm[axis].clamp(low, high);
        distance2_mm2 += (position_mm[axis] - nearest).powi(2);
        let u = (nearest - low) / GRID.cell_mm;
        cell[axis] = (u.floor() as usize).min(GRID.dims[axis] as usize - 1);
        t[axis] = u - cell[axis] as f64;
    }
    let fade_mm = adwi_runtime::served::fade_length_mm(GRID.cell_mm);
    let s = (1.0 - distance2_mm2.sqrt() / fade_mm).max(0.0);
    let fade = s * s * (3.0 - 2.0 * s);
    let (model_p, model_r) = PreparedModel::new(nominal, calibrated)
        .unwrap()
        .error(q)
        .unwrap();
    let mut out = [model_p, model_r];
    let (mut missing, mut contributed) = (false, false);
    for corner in 0..8 {
        let d = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
        let weight: f64 = (0..3)
            .map(|i| if d[i] == 1 { t[i] } else { 1.0 - t[i] })
            .product();
        let n = (cell[0] + d[0]) + NX * ((cell[1] + d[1]) + NY * (cell[2] + d[2]));
        if n == MISSING {
            missing = true;
            continue;
        }
        contributed |= weight > 0.0 && fade > 0.0;
        for (kind, sum) in out.iter_mut().enumerate() {
            for (c, sum) in sum.iter_mut().enumerate() {
                let turned: f64 = (0..3).map(|i| a[i] * term(n, i + 1, kind)[c]).sum();
                *sum += fade * weight * (term(n, 0, kind)[c] + turned);
            }
        }
    }
    let residual = if !contributed {
        Residual::ModelOnly
    } else if missing || distance2_mm2 > 0.0 {
        Residual::Faded
    } else {
        Residual::Full
    };
    (out[0], out[1], residual)
}

fn position(fraction: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|a| GRID.origin_mm[a] + fraction[a] * GRID.dims[a] as f64 * GRID.cell_mm)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn the_tool_axis_field_answers_f_plus_a_dot_h_blended_plus_the_model(
        fraction in prop::array::uniform3(-1.5..=2.5f64),
        q in prop::array::uniform6(-3.2..3.2f64),
    ) {
        let p = position(fraction);
        let (header, data) = parts_shifted(ServedField::KrigingToolAxis, 1.0, reaching(p, &q));
        let table = open(header, &data).unwrap();
        let got = table.query_with_joints(&Target::at(p), &q);
        let (position_mm, rotation_rad, residual) = reference(p, &q);
        prop_assert_eq!(got.status, Status::Ok, "at {:?}", p);
        prop_assert_eq!(got.residual, residual, "at {:?}", p);
        // The query walks the chains for positions alone, the reference through the folded
        // chains with orientations: the same products summed in another order, some units
        // in the last place of the reach (as `compiler/robot/tests/folded_model.rs` bounds
        // them; 1.3e-12 mm has been seen here).
        for c in 0..3 {
            prop_assert!((got.position_error_mm[c] - position_mm[c]).abs() <= ROUNDING_MM, "{:?} vs {:?}", got, position_mm);
            prop_assert!((got.orientation_error_rad[c] - rotation_rad[c]).abs() <= 1e-12, "{:?} vs {:?}", got, rotation_rad);
        }
    }

    #[test]
    fn without_h_the_tool_axis_field_is_the_kriging_field_and_the_exact_tier_is_unchanged(
        fraction in prop::array::uniform3(-0.1..=1.1f64),
        q in prop::array::uniform6(-3.2..3.2f64),
    ) {
        let target = Target::at(position(fraction));
        let shift = reaching(target.position_mm, &q);
        let (header, data) = parts_shifted(ServedField::KrigingToolAxis, 0.0, shift);
        let turning = open(header, &data).unwrap();
        let (header, data) = parts_shifted(ServedField::Kriging, 0.0, shift);
        let plain = open(header, &data).unwrap();
        prop_assert_eq!(turning.query_with_joints(&target, &q), plain.query_with_joints(&target, &q));
        prop_assert_eq!(turning.exact().query_with_joints(&target, &q), plain.exact().query_with_joints(&target, &q));
    }
}

#[test]
fn statuses_and_inspection_of_a_tool_axis_table() {
    let (header, data) = parts(ServedField::KrigingToolAxis, 1.0);
    let table = open(header, &data).unwrap();
    let inside = position([0.25, 0.5, 0.5]);
    assert_eq!(table.query(inside).status, Status::MissingJoints);
    assert_eq!(
        table
            .query_with_joints(&Target::at(inside), &[0.0; 5])
            .status,
        Status::InvalidInput
    );
    let q = [0.1, -0.7, 1.2, 0.3, -0.4, 1.1];
    let outside = position([1.5, 0.5, 0.5]);
    let served = |p| {
        let (header, data) = parts_shifted(ServedField::KrigingToolAxis, 1.0, reaching(p, &q));
        let c = open(header, &data)
            .unwrap()
            .query_with_joints(&Target::at(p), &q);
        (c.status, c.residual)
    };
    // Joint values that put the tool elsewhere are refused.
    let c = table.query_with_joints(&Target::at(inside), &q);
    assert_eq!(c.status, Status::JointsMismatch);
    // A hybrid table: the model answers everywhere, the residual fading where it ends.
    assert_eq!(served(outside), (Status::Ok, Residual::Faded));
    let far = position([5.0, 0.5, 0.5]);
    assert_eq!(served(far), (Status::Ok, Residual::ModelOnly));
    assert_eq!(
        served(position([0.75, 0.75, 0.5])),
        (Status::Ok, Residual::Faded)
    );
    assert_eq!(served(inside), (Status::Ok, Residual::Full));
    let Some(Payload::V2(archive)) = table.payload() else {
        panic!("a version-2 table")
    };
    let node = 1 + NX * (2 + NY);
    let (p, r) = adwi_runtime::served::node_terms(table.header(), archive, 0, [1, 2, 1]).unwrap();
    assert_eq!(p, [0, 1, 2, 3].map(|t| term(node, t, 0)));
    assert_eq!(r, Some([0, 1, 2, 3].map(|t| term(node, t, 1))));
    let (f, f_rad) = adwi_runtime::served::node(table.header(), archive, 0, [1, 2, 1]).unwrap();
    assert_eq!((f, f_rad), (term(node, 0, 0), Some(term(node, 0, 1))));
    let (missing, _) = adwi_runtime::served::node(table.header(), archive, 0, [2, 2, 1]).unwrap();
    assert!(adwi_runtime::served::is_missing(&missing));
    assert!(adwi_runtime::served::node(table.header(), archive, 0, [3, 0, 0]).is_none());
    // A field of one vector a node does not turn: its h terms read as zero.
    let (header, data) = parts(ServedField::Kriging, 1.0);
    let plain = open(header, &data).unwrap();
    let Some(Payload::V2(archive)) = plain.payload() else {
        panic!("a version-2 table")
    };
    let (p, _) = adwi_runtime::served::node_terms(plain.header(), archive, 0, [1, 2, 1]).unwrap();
    assert_eq!(p, [term(node, 0, 0), [0.0; 3], [0.0; 3], [0.0; 3]]);
}

#[test]
fn tool_axis_tables_breaking_the_layout_are_refused() {
    let (header, data) = parts(ServedField::KrigingToolAxis, 1.0);
    assert!(open(header, &data).is_ok());

    // Without a model: no axis to turn with.
    let mut position_only = data.clone();
    position_only.model = None;
    let mut h = header;
    h.content_flags &= !CONTENT_MODEL;
    h.joint_count = 0;
    assert_eq!(
        refusal(h, &position_only),
        "a tool-axis served field without a kinematic model"
    );

    // One vector a node, or some nodes' worth more than whole node sets of four.
    let (_, one_vector) = parts(ServedField::Kriging, 1.0);
    let mut five = data.clone();
    five.node_errors_mm.extend(&one_vector.node_errors_mm);
    five.node_orientation_errors_rad
        .extend(&one_vector.node_orientation_errors_rad);
    for broken in [&one_vector, &five] {
        assert_eq!(
            refusal(header, broken),
            "node values do not fill whole node sets"
        );
    }
    let mut short = data.clone();
    short.node_errors_mm.pop();
    short.node_orientation_errors_rad.pop();
    assert_eq!(
        refusal(header, &short),
        "node values do not fill whole node sets"
    );

    // A set's nodes are counted in nodes: a second set's worth of vectors is not there.
    let mut beyond = data.clone();
    beyond.node_sets[0].first_node = PER_SET as u32;
    assert_eq!(refusal(header, &beyond), "a node set is out of bounds");

    // A node is missing in all of its vectors or none, in either array.
    for (kind, t) in [(0, 0), (0, 3), (1, 2)] {
        let mut part = data.clone();
        let values = [
            &mut part.node_errors_mm,
            &mut part.node_orientation_errors_rad,
        ];
        let node = 4;
        values[kind][node * 4 + t] = [v2::NO_NODE_VALUE; 3];
        assert_eq!(
            refusal(header, &part),
            "a node's vectors are marked missing in part, not all or none"
        );
        let mut partial = data.clone();
        let values = [
            &mut partial.node_errors_mm,
            &mut partial.node_orientation_errors_rad,
        ];
        values[kind][node * 4 + t][1] = f64::INFINITY;
        assert_eq!(
            refusal(header, &partial),
            "a node value is neither finite nor marked missing"
        );
    }
    // The missing node's other vectors holding values.
    let mut revived = data.clone();
    revived.node_errors_mm[MISSING * 4 + 1] = [0.0; 3];
    assert_eq!(
        refusal(header, &revived),
        "a node's vectors are marked missing in part, not all or none"
    );
}
