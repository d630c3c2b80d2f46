//! The first-order pose error model: how small deviations of a robot's parameters move the
//! TCP, as Jacobians in the base frame.
//!
//! Each parameter acts on the chain as an elementary motion of everything distal to it: a
//! rotation about a line ([`Screw::Revolute`]) or a translation along a direction
//! ([`Screw::Prismatic`]). For the MD-H parameters of joint `i`, `A_i = Rz(θ)·Tz(d)·Tx(a)·
//! Rx(α)·Ry(β)` with frame `i − 1` at origin `o` with z axis `z`:
//!
//! | parameter | motion                                                             |
//! |-----------|--------------------------------------------------------------------|
//! | θ         | rotation about `z` through `o`                                     |
//! | d         | translation along `z`                                              |
//! | a         | translation along `x' = R_{i−1}·Rz(θ)·x`                             |
//! | α         | rotation about `x'` through frame `i`'s origin                     |
//! | β         | rotation about frame `i`'s y axis through its origin               |
//!
//! A rotation `ω` about a line through `c` moves a point `p` by `ω × (p − c)` and turns the
//! orientation by `ω`; a translation `v` moves it by `v`. This is the paper's differential
//! transform `dT = T · Σ U⁻¹ δA U`, written directly in the base frame, where compensation
//! consumes errors. Rows are `[dx, dy, dz]` in mm, then the orientation error
//! `[δx, δy, δz] = log(R_actual · R_nominalᵀ)` in rad, both in the base frame.
//!
//! Any other parameter (a joint's origin, the tool offset, the base registration) is a screw
//! too, and so is a joint variable: [`joint_jacobian`] is the geometric Jacobian of any
//! chain. Frames come from the runtime's chain ([`crate::model::chain_frames`]), so every
//! Jacobian here differentiates the one forward kinematics.

use adwi_runtime::chain::{Chain, JointKind};
use adwi_runtime::kinematics::{MdhJoint, Transform};
use nalgebra::{DMatrix, DVector, Isometry3, Vector3, Vector6};

use crate::model::{chain_frames, mdh_constant_part, transform_from_isometry};

/// The MD-H parameters that can deviate, in their column order within a joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MdhParameter {
    /// Link length `a`, mm.
    A,
    /// Link offset `d`, mm.
    D,
    /// Twist `α` about x, rad.
    Alpha,
    /// Joint angle offset `θ`, rad.
    Theta,
    /// Hayati twist `β` about y, rad.
    Beta,
}

impl MdhParameter {
    /// Every parameter, in column order.
    pub const ALL: [MdhParameter; PARAMETERS_PER_JOINT] = [
        MdhParameter::A,
        MdhParameter::D,
        MdhParameter::Alpha,
        MdhParameter::Theta,
        MdhParameter::Beta,
    ];

    /// The column of this parameter of joint `joint` (0-based) in the MD-H Jacobian.
    pub const fn column(self, joint: usize) -> usize {
        joint * PARAMETERS_PER_JOINT + self as usize
    }

    /// The parameter's name: `a`, `d`, `alpha`, `theta`, `beta`.
    pub fn name(self) -> &'static str {
        match self {
            MdhParameter::A => "a",
            MdhParameter::D => "d",
            MdhParameter::Alpha => "alpha",
            MdhParameter::Theta => "theta",
            MdhParameter::Beta => "beta",
        }
    }
}

/// Deviating MD-H parameters per joint.
pub const PARAMETERS_PER_JOINT: usize = 5;

/// How far one joint's MD-H parameters are from nominal.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct JointDeviation {
    /// Δa, mm.
    pub a_mm: f64,
    /// Δd, mm.
    pub d_mm: f64,
    /// Δα, rad.
    pub alpha_rad: f64,
    /// Δθ, added to the joint's θ offset, rad.
    pub theta_rad: f64,
    /// Δβ, rad.
    pub beta_rad: f64,
}

/// The actual joint geometry: nominal plus deviations, exactly (no linearisation).
///
/// # Panics
///
/// When the two slices differ in length.
pub fn apply_deviations(nominal: &[MdhJoint], deviations: &[JointDeviation]) -> Vec<MdhJoint> {
    assert_eq!(nominal.len(), deviations.len(), "one deviation per joint");
    nominal
        .iter()
        .zip(deviations)
        .map(|(n, d)| MdhJoint {
            a_mm: n.a_mm + d.a_mm,
            d_mm: n.d_mm + d.d_mm,
            alpha_rad: n.alpha_rad + d.alpha_rad,
            beta_rad: n.beta_rad + d.beta_rad,
            theta_offset_rad: n.theta_offset_rad + d.theta_rad,
        })
        .collect()
}

/// The deviations as a vector in the Jacobian's column order.
pub fn deviation_vector(deviations: &[JointDeviation]) -> DVector<f64> {
    let mut v = DVector::zeros(deviations.len() * PARAMETERS_PER_JOINT);
    for (joint, d) in deviations.iter().enumerate() {
        let values = [d.a_mm, d.d_mm, d.alpha_rad, d.theta_rad, d.beta_rad];
        for (parameter, value) in MdhParameter::ALL.into_iter().zip(values) {
            v[parameter.column(joint)] = value;
        }
    }
    v
}

/// The deviations of a vector in the Jacobian's column order (e.g. an identified solution);
/// its length is a multiple of [`PARAMETERS_PER_JOINT`].
pub fn deviations_from_vector(v: &[f64]) -> Vec<JointDeviation> {
    (0..v.len() / PARAMETERS_PER_JOINT)
        .map(|joint| {
            let at = |parameter: MdhParameter| v[parameter.column(joint)];
            JointDeviation {
                a_mm: at(MdhParameter::A),
                d_mm: at(MdhParameter::D),
                alpha_rad: at(MdhParameter::Alpha),
                theta_rad: at(MdhParameter::Theta),
                beta_rad: at(MdhParameter::Beta),
            }
        })
        .collect()
}

/// An elementary motion of the distal part of the chain, in the base frame, per unit of
/// its parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Screw {
    /// Rotation about the unit `axis` through `point_mm` (per rad).
    Revolute {
        /// Unit axis, base frame.
        axis: Vector3<f64>,
        /// A point on the axis, base frame, mm.
        point_mm: Vector3<f64>,
    },
    /// Translation along the unit `direction` (per mm).
    Prismatic {
        /// Unit direction, base frame.
        direction: Vector3<f64>,
    },
}

impl Screw {
    /// The pose error `[dp (mm); δ (rad)]` this motion causes at the point `point_mm`
    /// (base frame), per unit parameter.
    pub fn pose_error_column(&self, point_mm: &Vector3<f64>) -> Vector6<f64> {
        match *self {
            Screw::Revolute { axis, point_mm: c } => {
                let dp = axis.cross(&(point_mm - c));
                Vector6::new(dp.x, dp.y, dp.z, axis.x, axis.y, axis.z)
            }
            Screw::Prismatic { direction: v } => Vector6::new(v.x, v.y, v.z, 0.0, 0.0, 0.0),
        }
    }

    /// The motion of joint variable of a chain joint whose frame before its motion is
    /// `before`: about (or along) its axis, through the frame's origin.
    pub fn of_joint(before: &Transform, axis: [f64; 3], kind: JointKind) -> Screw {
        let axis = vector(before.rotate_vector(axis));
        match kind {
            JointKind::Revolute => Screw::Revolute {
                axis,
                point_mm: vector(before.translation_mm),
            },
            JointKind::Prismatic => Screw::Prismatic { direction: axis },
        }
    }
}

pub(crate) fn vector(a: [f64; 3]) -> Vector3<f64> {
    Vector3::from(a)
}

/// The screws of the MD-H parameters of `chain` (an MD-H chain, [`Chain::from_mdh`] of
/// `rows`) at joint angles `q_rad`, indexed `[joint][MdhParameter as usize]`, and the TCP
/// position, base frame.
///
/// # Panics
///
/// When `rows` or `q_rad` does not have one entry per joint of `chain`.
pub fn mdh_screws(
    chain: &Chain,
    rows: &[MdhJoint],
    q_rad: &[f64],
) -> (Vec<[Screw; PARAMETERS_PER_JOINT]>, Vector3<f64>) {
    assert_eq!(rows.len(), chain.joint_count(), "one MD-H row per joint");
    let (frames, tcp) = chain_frames(chain, q_rad);
    let constants: Vec<Transform> = rows.iter().map(mdh_constant_part).collect();
    (
        mdh_screws_from(&frames, &constants),
        vector(tcp.translation_mm),
    )
}

/// [`mdh_screws`] from the chain's frames at the joint values ([`chain_frames`]) and each
/// row's constant part ([`mdh_constant_part`]), computed before: an identification
/// linearising at every sample has the frames already, and the constant parts are the
/// same at every sample (their sines and cosines were a third of its trigonometry).
pub fn mdh_screws_from(
    frames: &[(Transform, Transform)],
    constants: &[Transform],
) -> Vec<[Screw; PARAMETERS_PER_JOINT]> {
    assert_eq!(frames.len(), constants.len(), "one constant part per joint");
    frames
        .iter()
        .zip(constants)
        .map(|((before, after_motion), constant)| {
            // Frame i: after the joint's motion, the link's constant part.
            let after = after_motion.compose(constant);
            let z = vector(before.rotate_vector([0.0, 0.0, 1.0]));
            // x' = R_{i−1}·Rz(θ)·x: the direction `a` translates along and `α` turns about.
            let x_turned = vector(after_motion.rotate_vector([1.0, 0.0, 0.0]));
            // Rx(α)·Ry(β)·y = Rx(α)·y, so frame i's y axis is the axis β turns about.
            let y_after = vector(after.rotate_vector([0.0, 1.0, 0.0]));
            let origin_before = vector(before.translation_mm);
            let origin_after = vector(after.translation_mm);
            let mut screws = [Screw::Prismatic { direction: z }; PARAMETERS_PER_JOINT];
            screws[MdhParameter::A as usize] = Screw::Prismatic {
                direction: x_turned,
            };
            screws[MdhParameter::D as usize] = Screw::Prismatic { direction: z };
            screws[MdhParameter::Alpha as usize] = Screw::Revolute {
                axis: x_turned,
                point_mm: origin_after,
            };
            screws[MdhParameter::Theta as usize] = Screw::Revolute {
                axis: z,
                point_mm: origin_before,
            };
            screws[MdhParameter::Beta as usize] = Screw::Revolute {
                axis: y_after,
                point_mm: origin_after,
            };
            screws
        })
        .collect()
}

/// The 6 × 5n first-order pose error of the TCP with respect to the MD-H deviations of the
/// robot `rows` with tool `tool` (TCP in the flange frame), base frame, at joint angles
/// `q_rad` (see the module docs for rows and columns).
///
/// The linear prediction of the pose error of deviations `Δ` is `jacobian ·
/// deviation_vector(Δ)`; it agrees with the exact error [`pose_error`] of
/// [`apply_deviations`] to second order in `Δ`.
///
/// # Panics
///
/// When the rows are not a valid chain or `q_rad` has not one value per row.
pub fn pose_error_jacobian(rows: &[MdhJoint], tool: &Transform, q_rad: &[f64]) -> DMatrix<f64> {
    let chain = Chain::from_mdh(Transform::IDENTITY, rows, *tool, None).expect("a valid chain");
    let (screws, tcp) = mdh_screws(&chain, rows, q_rad);
    let mut jacobian = DMatrix::zeros(6, rows.len() * PARAMETERS_PER_JOINT);
    for (joint, joint_screws) in screws.iter().enumerate() {
        for (parameter, screw) in MdhParameter::ALL.into_iter().zip(joint_screws) {
            jacobian
                .column_mut(parameter.column(joint))
                .copy_from(&screw.pose_error_column(&tcp));
        }
    }
    jacobian
}

/// The geometric joint Jacobian of a chain's TCP (base frame) at joint values `q`: column
/// `i` is the pose change per unit of joint `i` (rad, or mm when prismatic), rows as in
/// [`pose_error_jacobian`].
///
/// A joint variable enters exactly as its offset does, so for an MD-H robot these are the
/// Δθ columns.
///
/// # Panics
///
/// When `q` does not have one value per joint.
pub fn joint_jacobian(chain: &Chain, q: &[f64]) -> DMatrix<f64> {
    let (frames, tcp) = chain_frames(chain, q);
    let tcp = vector(tcp.translation_mm);
    let mut jacobian = DMatrix::zeros(6, q.len());
    for (i, ((before, _), joint)) in frames.iter().zip(chain.joints()).enumerate() {
        jacobian
            .column_mut(i)
            .copy_from(&Screw::of_joint(before, joint.axis, joint.kind).pose_error_column(&tcp));
    }
    jacobian
}

/// The exact pose error of `actual` with respect to `nominal`, base frame:
/// `[p_actual − p_nominal (mm); log(R_actual · R_nominalᵀ) (rad)]`, computed by the
/// runtime's one definition ([`adwi_runtime::kinematics::pose_error`]).
pub fn pose_error(nominal: &Isometry3<f64>, actual: &Isometry3<f64>) -> Vector6<f64> {
    let (p, r) = adwi_runtime::kinematics::pose_error(
        &transform_from_isometry(nominal),
        &transform_from_isometry(actual),
    );
    Vector6::new(p[0], p[1], p[2], r[0], r[1], r[2])
}

/// As [`pose_error`], of runtime transforms.
pub fn transform_pose_error(nominal: &Transform, actual: &Transform) -> Vector6<f64> {
    let (p, r) = adwi_runtime::kinematics::pose_error(nominal, actual);
    Vector6::new(p[0], p[1], p[2], r[0], r[1], r[2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{shipped_robot_path, Robot};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn kr150() -> Robot {
        Robot::load(shipped_robot_path("kr150-2")).unwrap()
    }

    /// A non-trivial tool, so the Jacobian is checked away from the flange too.
    fn tool() -> Transform {
        let iso = crate::model::isometry_from_parts(
            [30.0, -20.0, 250.0],
            &adwi_samples::pose::rotation_from_kuka_abc_deg([10.0, 20.0, 30.0]),
        );
        crate::model::transform_from_isometry(&iso)
    }

    fn fk(rows: &[MdhJoint], q: &[f64]) -> Transform {
        Chain::from_mdh(Transform::IDENTITY, rows, tool(), None)
            .unwrap()
            .tcp_pose(q)
            .unwrap()
    }

    fn exact_error(nominal: &[MdhJoint], deviations: &[JointDeviation], q: &[f64]) -> DVector<f64> {
        let e = transform_pose_error(
            &fk(nominal, q),
            &fk(&apply_deviations(nominal, deviations), q),
        );
        DVector::from_column_slice(e.as_slice())
    }

    #[test]
    fn vector_and_deviations_round_trip_in_column_order() {
        let mut deviations = vec![JointDeviation::default(); 6];
        deviations[1].beta_rad = 7.0;
        deviations[5].a_mm = 3.0;
        let v = deviation_vector(&deviations);
        assert_eq!(v[MdhParameter::Beta.column(1)], 7.0);
        assert_eq!(v[25], 3.0);
        assert_eq!(v.iter().filter(|x| **x != 0.0).count(), 2);
        assert_eq!(deviations_from_vector(v.as_slice()), deviations);
    }

    #[test]
    fn jacobian_equals_central_finite_differences_of_exact_fk() {
        let robot = kr150();
        let mut nominal = robot.mdh().unwrap().to_vec();
        // A non-zero β2 and a pose with no special angles: nothing hides behind a zero.
        nominal[1].beta_rad = 0.01;
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..5 {
            let q: Vec<f64> = (0..6)
                .map(|i| {
                    let [lo, hi] = robot.joints()[i].limits;
                    rng.gen_range(lo..hi)
                })
                .collect();
            let jacobian = pose_error_jacobian(&nominal, &tool(), &q);
            let h = 1e-6;
            for column in 0..jacobian.ncols() {
                let mut step = DVector::zeros(jacobian.ncols());
                step[column] = h;
                let plus = exact_error(&nominal, &deviations_from_vector(step.as_slice()), &q);
                let minus = exact_error(&nominal, &deviations_from_vector((-&step).as_slice()), &q);
                let numeric = (plus - minus) / (2.0 * h);
                let analytic = jacobian.column(column);
                let scale = analytic.norm().max(1.0);
                let gap = (&numeric - analytic).norm();
                assert!(
                    gap <= 1e-6 * scale,
                    "column {column}: analytic {analytic:?} numeric {numeric:?}"
                );
            }
        }
    }

    #[test]
    fn joint_jacobian_is_the_theta_columns() {
        let robot = kr150();
        let q = [0.3, -1.2, 1.4, 0.5, 0.9, -0.4];
        let rows = robot.mdh().unwrap();
        let full = pose_error_jacobian(rows, &tool(), &q);
        let chain = Chain::from_mdh(Transform::IDENTITY, rows, tool(), None).unwrap();
        let j = joint_jacobian(&chain, &q);
        for i in 0..6 {
            assert_eq!(j.column(i), full.column(MdhParameter::Theta.column(i)));
        }
    }

    /// The linear model's gap to the exact error is second order: halving every deviation
    /// quarters it.
    #[test]
    fn linear_model_is_exact_to_second_order() {
        let robot = kr150();
        let nominal = robot.mdh().unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let base = DVector::from_fn(30, |i, _| {
            // mm for a and d, rad for the angles: realistic magnitudes of 0.5 mm and 0.5 mrad.
            let magnitude = if i % PARAMETERS_PER_JOINT < 2 {
                0.5
            } else {
                5e-4
            };
            rng.gen_range(-magnitude..magnitude)
        });
        let q = [0.4, -0.9, 1.7, -0.6, 0.8, 1.2];
        let jacobian = pose_error_jacobian(nominal, &tool(), &q);
        let gap = |scale: f64| {
            let delta = &base * scale;
            let exact = exact_error(nominal, &deviations_from_vector(delta.as_slice()), &q);
            (exact - &jacobian * delta).norm()
        };
        let (full, half, quarter) = (gap(1.0), gap(0.5), gap(0.25));
        let linear = (&jacobian * &base).norm();
        // The gap is small against the error itself, and shrinks as Δ².
        assert!(full < 0.01 * linear, "gap {full} vs error {linear}");
        for ratio in [full / half, half / quarter] {
            assert!((ratio - 4.0).abs() < 0.1, "ratio {ratio}");
        }
    }
}
