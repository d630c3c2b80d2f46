//! A hybrid table's query evaluates its model from chains folded at open
//! ([`PreparedModel::at`]); the chains' own forward kinematics, joint by joint, are the
//! reference ([`model_at_by_chains`]). For every robot shipped in `tables/`, described by
//! its robot file and by its URDF (axes that are not z, origins with rotations), with a
//! calibrated chain that differs from the nominal one and deflects under gravity, at random
//! joint values within the limits, the two agree to 1e-12 mm (and orientations to their
//! rounding, 4e-15 rad).

use adwi_robot::model::shipped_file;
use adwi_robot::Robot;
use adwi_runtime::chain::{Chain, ChainJoint};
use adwi_runtime::kinematics::Transform;
use adwi_runtime::model::PreparedModel;
use adwi_runtime::testing::model_at_by_chains;
use proptest::prelude::*;

const ROBOTS: [(&str, &str); 6] = [
    ("ur5", "robot.toml"),
    ("ur5", "robot.urdf"),
    ("ur10", "robot.toml"),
    ("ur10", "robot.urdf"),
    ("iiwa14", "robot.toml"),
    ("iiwa14", "robot.urdf"),
];

/// `t` moved by up to a millimetre and turned by up to a milliradian about each axis (by
/// `small` in [-1, 1]³ twice).
fn nudged(t: &Transform, small: [f64; 6]) -> Transform {
    let turn = ChainJoint {
        axis: [1.0, 0.0, 0.0],
        ..ChainJoint::default()
    };
    let mut out = *t;
    for (a, axis) in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        .iter()
        .enumerate()
    {
        let rotation = ChainJoint {
            axis: *axis,
            ..turn
        }
        .motion(1e-3 * small[a]);
        out = out.compose(&rotation);
        out.translation_mm[a] += small[3 + a];
    }
    out
}

/// The robot's chain as a calibration would leave it: every origin, the base and the tool
/// nudged, offsets shifted, and a gravity compliance of up to 20 µrad/(N·m) a joint (5 N·m
/// at 1 m of 1 kg: deflections of a few hundred µrad, as identified ones are) when the
/// robot file has masses.
fn calibrated(robot: &Robot, small: &[[f64; 6]]) -> Chain {
    let nominal = robot.chain();
    let n = nominal.joint_count();
    let joints: Vec<ChainJoint> = (nominal.joints().iter().enumerate())
        .map(|(j, joint)| ChainJoint {
            origin: nudged(&joint.origin, small[j]),
            offset: joint.offset + 1e-3 * small[j][0],
            ..*joint
        })
        .collect();
    let compliance = robot.gravity_model().map(|mut c| {
        for (compliance, s) in c.compliance.iter_mut().zip(&small[..n]) {
            // µrad/(N·m) → rad/(kg·mm²/s²): 1 N·m = 1e6 kg·mm²/s².
            *compliance = 20e-6 / 1e6 * (0.5 + 0.5 * s[1]);
        }
        c
    });
    Chain::new(
        nudged(&nominal.base, small[n]),
        &joints,
        nudged(&nominal.tool, small[n + 1]),
        compliance,
    )
    .expect("a valid chain")
}

/// The largest difference between the folded model and the chains at `q` over every
/// value `ModelAt` holds, position (mm) and direction (unit vectors, rad) apart; `None`
/// if either has no answer.
fn difference(model: &PreparedModel, q: &[f64]) -> Option<(f64, f64)> {
    let fast = model.at(q)?;
    // Without the orientation error: another walk down the chains (from the tool back).
    let position = model.at_position(q)?;
    let reference = model_at_by_chains(model, q)?;
    let off = |x: [f64; 3], y: [f64; 3]| (0..3).map(|a| (x[a] - y[a]).abs()).fold(0.0, f64::max);
    if position.rotation_rad != [0.0; 3] {
        return None;
    }
    Some((
        off(fast.position_mm, reference.position_mm)
            .max(off(fast.nominal_tcp_mm, reference.nominal_tcp_mm))
            .max(off(position.position_mm, reference.position_mm))
            .max(off(position.nominal_tcp_mm, reference.nominal_tcp_mm)),
        off(fast.approach, reference.approach)
            .max(off(fast.rotation_rad, reference.rotation_rad))
            .max(off(position.approach, reference.approach)),
    ))
}

fn model_and_joints(
    robot: usize,
    small: &[[f64; 6]],
    fractions: &[f64],
    half_turn: bool,
) -> (Robot, PreparedModel, Vec<f64>) {
    let (name, file) = ROBOTS[robot];
    let robot = Robot::load(shipped_file(name, file)).expect("a shipped robot");
    let model =
        PreparedModel::new(*robot.chain(), calibrated(&robot, small)).expect("equal joint counts");
    let q: Vec<f64> = (0..robot.joint_count())
        .map(|i| {
            let [mut lower, mut upper] = robot.sampling_range(i);
            if half_turn {
                lower = lower.max(-std::f64::consts::PI);
                upper = upper.min(std::f64::consts::PI);
            }
            lower + fractions[i] * (upper - lower)
        })
        .collect();
    (robot, model, q)
}

/// How far the folded and the chained forward kinematics may differ, mm: the same products
/// summed in another order, some units in the last place of a TCP coordinate up to 2 m from
/// the base (one unit there is 2.3e-13 mm; the UR10 has shown 1.14e-12 mm).
const ROUNDING_MM: f64 = 4e-12;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Within half a turn of zero (`tablec bench`'s random poses): equal to the rounding
    /// of two orders of the same products, [`ROUNDING_MM`].
    #[test]
    fn the_folded_model_equals_the_chains(
        which in 0..ROBOTS.len(),
        small in proptest::collection::vec(proptest::array::uniform6(-1.0..1.0f64), 14),
        fractions in proptest::collection::vec(0.0..=1.0f64, 7),
    ) {
        let (robot, model, q) = model_and_joints(which, &small, &fractions, true);
        prop_assert!(robot.within_limits(&q));
        let (mm, rad) = difference(&model, &q).expect("one value per joint");
        // Unit vectors and rotation vectors: their rounding, a few units in the last place
        // of 1.
        prop_assert!(mm <= ROUNDING_MM && rad <= 4e-15, "{:?} at {q:?}: {mm} mm, {rad}", ROBOTS[which]);
    }

    /// Anywhere within the limits (a UR's joints turn ±2π): the chains round each joint's
    /// angle `q + Δq + offset` to the nearest double before its `sin_cos`, an error of half
    /// a unit in the last place of the angle (4.4e-16 rad beyond 4 rad) that the folded
    /// form does not make, so the two may differ by those roundings times the arm's reach
    /// (2 m bounds every shipped robot's) on top of [`ROUNDING_MM`].
    #[test]
    fn the_folded_model_equals_the_chains_within_the_limits(
        which in 0..ROBOTS.len(),
        small in proptest::collection::vec(proptest::array::uniform6(-1.0..1.0f64), 14),
        fractions in proptest::collection::vec(0.0..=1.0f64, 7),
    ) {
        let (robot, model, q) = model_and_joints(which, &small, &fractions, false);
        prop_assert!(robot.within_limits(&q));
        let (mm, rad) = difference(&model, &q).expect("one value per joint");
        let offsets = model.calibrated().joints().iter().map(|j| j.offset.abs());
        let angle_rounding_rad: f64 = q.iter().zip(offsets)
            .map(|(v, o)| f64::EPSILON * (v.abs() + o + 1.0))
            .sum();
        let tolerance_mm = ROUNDING_MM + 2000.0 * angle_rounding_rad;
        prop_assert!(mm <= tolerance_mm && rad <= 4e-15 + angle_rounding_rad,
            "{:?} at {q:?}: {mm} mm, {rad}", ROBOTS[which]);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// A calibrated chain without gravity compliance, as the shipped UR5 measurements
    /// identify it: both chains' TCP frames come from one walk from the tool back, and the
    /// orientation error from their columns by asin's series (`ReachPair::walk_posed`),
    /// held to the chains as the compliant case is, rotations to 4e-15 rad.
    #[test]
    fn the_rigid_model_walked_from_the_tool_back_equals_the_chains(
        which in 0..ROBOTS.len(),
        small in proptest::collection::vec(proptest::array::uniform6(-1.0..1.0f64), 14),
        fractions in proptest::collection::vec(0.0..=1.0f64, 7),
    ) {
        let (robot, model, q) = model_and_joints(which, &small, &fractions, true);
        let mut rigid = *model.calibrated();
        rigid.compliance = None;
        let model = PreparedModel::new(*robot.chain(), rigid).expect("equal joint counts");
        let (mm, rad) = difference(&model, &q).expect("one value per joint");
        prop_assert!(mm <= ROUNDING_MM && rad <= 4e-15, "{:?} at {q:?}: {mm} mm, {rad}", ROBOTS[which]);
        // The frames' rotation too, which a named TCP's lever turns.
        let fast = model.at(&q).expect("one value per joint").nominal_rotation.expect("with the rotation");
        let reference = model_at_by_chains(&model, &q).expect("one value per joint").nominal_rotation.expect("with the rotation");
        let off = (0..3).flat_map(|i| (0..3).map(move |j| (i, j))).map(|(i, j)| (fast[i][j] - reference[i][j]).abs()).fold(0.0, f64::max);
        prop_assert!(off <= 4e-15, "{:?}: rotation off by {off}", ROBOTS[which]);
    }
}

/// The gravity deflection is really exercised: the calibrated chain of a robot with masses
/// deflects by more than the tolerance the fast path is held to, by many orders.
#[test]
fn the_calibrated_chains_deflect_under_gravity() {
    let robot = Robot::load(shipped_file("ur5", "robot.toml")).expect("a shipped robot");
    let chain = calibrated(&robot, &[[0.5; 6]; 14]);
    let q = [0.3, -1.2, 1.4, -0.5, 1.1, 0.2];
    let still = chain.tcp_pose(&q).expect("six values");
    let loaded = chain.loaded_tcp_pose(&q).expect("six values");
    let sag_mm: f64 = (0..3)
        .map(|a| (loaded.translation_mm[a] - still.translation_mm[a]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(sag_mm > 0.01, "{sag_mm} mm");
}
