//! Hybrid tables and joint-aware queries: a calibrated kinematic model plus the interpolated
//! residuals it leaves, served by the same allocation-free query path.
//!
//! A *hybrid* table ([`crate::format::CONTENT_MODEL`]) carries two kinematic models of the
//! robot: the nominal one the controller commands with, and the calibrated one that
//! predicts where the robot really goes. Its samples' errors are the *residuals* the
//! calibrated model leaves (measured error minus the model's predicted error at the
//! sample's joint angles). A correction is then
//!
//! ```text
//! position_error_mm     = p_cal(q) − p_nom(q)            + interpolated residual at the target
//! orientation_error_rad = log(R_cal(q) · R_nom(q)ᵀ)        + interpolated residual at the target
//! ```
//!
//! where `q` are the joint angles the controller will command for the target, and
//! `T_cal(q) = B_cal · A_1(q_1) ⋯ A_6(q_6) · T_tool,cal`, `T_nom(q)` likewise with the
//! nominal parameters (the pose errors are in the base frame, as the samples record them).
//! The model part is a function of the joint angles, which a position alone does not
//! determine (one position has up to eight inverse-kinematics solutions and any tool
//! orientation), so a hybrid table must be queried with the joint angles:
//! [`Table::query_with_joints`]. Queried by position alone ([`Table::query_target`]) it
//! answers [`Status::MissingJoints`] rather than a residual that is not the error.
//!
//! The same joint angles drive the optional joint-space admissibility screen
//! ([`crate::format::Header::joint_radius_rad`]): a sample is admissible only if each of its
//! joint angles is within the radius of the target's ([`joints_within`]). Samples close in
//! Cartesian space but reached with a very different arm posture (another wrist angle, say)
//! then stop standing in for the target, which is the method's own remark that "close"
//! means close joint angles. Position-only tables may use the screen too, when built from
//! samples with joint angles.
//!
//! Everything here is allocation-free and panic-free: two forward kinematics (a few hundred
//! flops) and a 3 × 3 logarithm on top of the ordinary query.

use crate::format::{
    ArchivedKinematicModel, ArchivedModelParams, ArchivedTableData, KinematicModel, ModelParams,
    CONTENT_MODEL,
};
use crate::kinematics::{forward_prepared, MdhJoint, PreparedJoint, Transform};

use crate::table::{Correction, Status, Table, Target};

/// The number of joints of a model in a table.
pub const JOINT_COUNT: usize = 6;

/// Whether every joint angle of `sample_rad` is within `radius_rad` of `target_rad`:
/// `max_i |q_sample,i − q_target,i| ≤ radius_rad`. The one test of the joint-space screen,
/// shared by the runtime, the table builder and the brute-force reference. NaN fails.
#[inline]
pub fn joints_within(
    sample_rad: &[f64; JOINT_COUNT],
    target_rad: &[f64; JOINT_COUNT],
    radius_rad: f64,
) -> bool {
    sample_rad
        .iter()
        .zip(target_rad)
        .all(|(s, t)| (s - t).abs() <= radius_rad)
}

/// The rigid transform of a table's 12-value layout: rotation rows then translation,
/// `[r00, r01, r02, t0, r10, r11, r12, t1, r20, r21, r22, t2]` (mm).
#[inline]
pub fn transform_of(rows: &[f64; 12]) -> Transform {
    Transform {
        rotation: [
            [rows[0], rows[1], rows[2]],
            [rows[4], rows[5], rows[6]],
            [rows[8], rows[9], rows[10]],
        ],
        translation_mm: [rows[3], rows[7], rows[11]],
    }
}

/// A transform in the table's 12-value layout (the inverse of [`transform_of`]).
pub fn rows_of(transform: &Transform) -> [f64; 12] {
    let r = &transform.rotation;
    let t = transform.translation_mm;
    [
        r[0][0], r[0][1], r[0][2], t[0], r[1][0], r[1][1], r[1][2], t[1], r[2][0], r[2][1],
        r[2][2], t[2],
    ]
}

/// The joints of a model in the table's layout `[a (mm), d (mm), α, β, θ offset (rad)]`.
#[inline]
pub fn mdh_joints(params: &ModelParams) -> [MdhJoint; JOINT_COUNT] {
    params.joints.map(
        |[a_mm, d_mm, alpha_rad, beta_rad, theta_offset_rad]| MdhJoint {
            a_mm,
            d_mm,
            alpha_rad,
            beta_rad,
            theta_offset_rad,
        },
    )
}

/// The table layout of MD-H joints (the inverse of [`mdh_joints`]).
pub fn joint_rows(joints: &[MdhJoint; JOINT_COUNT]) -> [[f64; 5]; JOINT_COUNT] {
    joints.map(|j| [j.a_mm, j.d_mm, j.alpha_rad, j.beta_rad, j.theta_offset_rad])
}

/// The tool centre point's pose in the measurement (world) frame at joint angles `q_rad`:
/// `base · A_1(q_1) ⋯ A_6(q_6) · tool`.
pub fn tcp_pose(params: &ModelParams, q_rad: &[f64; JOINT_COUNT]) -> Transform {
    PreparedChain::new(params).tcp_pose(&q_rad.map(f64::sin_cos))
}

/// The pose error a kinematic model predicts at joint angles `q_rad`: the calibrated TCP
/// against the nominal one, position (mm) and orientation (rotation vector of
/// `R_cal · R_nomᵀ`, rad), both in the base frame. The compiler computes a hybrid table's
/// residuals with this, and queries with the same arithmetic ([`PreparedModel::error`]).
pub fn model_error(model: &KinematicModel, q_rad: &[f64; JOINT_COUNT]) -> ([f64; 3], [f64; 3]) {
    PreparedModel::new(model).error(q_rad)
}

/// One model's chain with its constant sines and cosines computed.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PreparedChain {
    joints: [PreparedJoint; JOINT_COUNT],
    tool: Transform,
    base: Transform,
}

impl PreparedChain {
    fn new(params: &ModelParams) -> PreparedChain {
        PreparedChain {
            joints: mdh_joints(params).map(|j| j.prepare()),
            tool: transform_of(&params.tool),
            base: transform_of(&params.base),
        }
    }

    #[inline]
    fn tcp_pose(&self, sin_cos_q: &[(f64, f64); JOINT_COUNT]) -> Transform {
        self.base
            .compose(&forward_prepared(&self.joints, &self.tool, sin_cos_q))
    }
}

/// A [`KinematicModel`] ready for queries: the sines and cosines of every constant angle
/// computed once (at open), so that a prediction costs six `sin_cos` (of the joint angles,
/// shared by both models) and two chains of 3 × 4 products.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreparedModel {
    nominal: PreparedChain,
    calibrated: PreparedChain,
}

impl PreparedModel {
    /// Prepares `model`.
    pub fn new(model: &KinematicModel) -> PreparedModel {
        PreparedModel {
            nominal: PreparedChain::new(&model.nominal),
            calibrated: PreparedChain::new(&model.calibrated),
        }
    }

    /// The predicted pose error at joint angles `q_rad`, as [`model_error`].
    #[inline]
    pub fn error(&self, q_rad: &[f64; JOINT_COUNT]) -> ([f64; 3], [f64; 3]) {
        let sin_cos_q = q_rad.map(f64::sin_cos);
        let nominal = self.nominal.tcp_pose(&sin_cos_q);
        let calibrated = self.calibrated.tcp_pose(&sin_cos_q);
        let position_mm =
            [0, 1, 2].map(|a| calibrated.translation_mm[a] - nominal.translation_mm[a]);
        // R_cal · R_nomᵀ: the rotation part of calibrated · nominal⁻¹.
        let relative = calibrated.compose(&nominal.inverse());
        (position_mm, rotation_vector(&relative.rotation))
    }
}

/// The prepared model of a validated archive, if it carries one.
pub(crate) fn prepared_model(archive: &ArchivedTableData) -> Option<PreparedModel> {
    Some(PreparedModel::new(&native_model(archive.model.as_ref()?)))
}

/// A kinematic model out of the archive.
pub(crate) fn native_model(model: &ArchivedKinematicModel) -> KinematicModel {
    KinematicModel {
        nominal: native(&model.nominal),
        calibrated: native(&model.calibrated),
    }
}

/// The rotation vector (axis × angle, rad) of a rotation matrix: the logarithm map,
/// allocation-free.
///
/// The skew part of `R` is `sin θ · axis` to full precision, so for the small rotations
/// that pose errors are the angle comes from `atan2(sin θ, cos θ)` and the vector from the
/// skew part (an angle from `acos` would lose half its digits). Near θ = π the skew part
/// vanishes; the axis then comes from the largest column of `R + I = 2 · axis · axisᵀ`
/// (for θ = π exactly), its sign from the skew part. Finite for every finite input.
#[inline]
pub fn rotation_vector(r: &[[f64; 3]; 3]) -> [f64; 3] {
    let sin_axis = [
        0.5 * (r[2][1] - r[1][2]),
        0.5 * (r[0][2] - r[2][0]),
        0.5 * (r[1][0] - r[0][1]),
    ];
    let sin_angle = norm(sin_axis);
    let cos_angle = 0.5 * (r[0][0] + r[1][1] + r[2][2] - 1.0);
    let angle = sin_angle.atan2(cos_angle);
    if cos_angle > -0.9 {
        // θ / sin θ → 1 as θ → 0; the series keeps it exact when sin θ underflows to 0.
        let scale = if sin_angle > 1e-8 {
            angle / sin_angle
        } else {
            1.0 + angle * angle / 6.0
        };
        return sin_axis.map(|v| v * scale);
    }
    // Near π: R + Rᵀ = 2 cos θ I + 2 (1 − cos θ) a aᵀ, so the symmetric part gives a aᵀ.
    let one_minus_cos = 1.0 - cos_angle;
    let outer = |i: usize, j: usize| {
        let delta = if i == j { 1.0 } else { 0.0 };
        (0.5 * (r[i][j] + r[j][i]) - cos_angle * delta) / one_minus_cos
    };
    let diagonal = [outer(0, 0), outer(1, 1), outer(2, 2)];
    let mut k = 0;
    for i in 1..3 {
        if diagonal[i] > diagonal[k] {
            k = i;
        }
    }
    let mut axis = [outer(0, k), outer(1, k), outer(2, k)];
    let length = norm(axis);
    if length > 0.0 {
        axis = axis.map(|v| v / length);
    }
    // The symmetric part fixes the axis up to sign; the skew part (sin θ · axis) the sign.
    let dot = axis[0] * sin_axis[0] + axis[1] * sin_axis[1] + axis[2] * sin_axis[2];
    if dot < 0.0 {
        axis = axis.map(|v| -v);
    }
    axis.map(|v| v * angle)
}

#[inline]
fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// A model's parameters out of the archive.
#[inline]
fn native(a: &ArchivedModelParams) -> ModelParams {
    ModelParams {
        joints: a.joints.map(|j| j.map(|v| v.to_native())),
        tool: a.tool.map(|v| v.to_native()),
        base: a.base.map(|v| v.to_native()),
    }
}

impl<D: AsRef<[u8]>> Table<D> {
    /// Whether this is a hybrid table (a kinematic model plus residuals): it then needs the
    /// target's joint angles ([`Table::query_with_joints`]).
    pub fn is_hybrid(&self) -> bool {
        self.header().content_flags & CONTENT_MODEL != 0
    }

    /// The joint-space admissibility radius, rad; 0 when the screen is off.
    pub fn joint_radius_rad(&self) -> f64 {
        self.header().joint_radius_rad
    }

    /// The kinematic model of a hybrid table (nominal and calibrated parameters).
    pub fn kinematic_model(&self) -> Option<KinematicModel> {
        Some(native_model(self.data()?.model.as_ref()?))
    }

    /// The predicted correction at a target that the controller will reach with joint
    /// angles `joints_rad` (rad, the controller's joint variables, in the robot file's
    /// order). Never allocates, locks or panics.
    ///
    /// - On a hybrid table: the calibrated model's predicted error at `joints_rad` plus
    ///   the interpolated residual at the target (see the module docs).
    /// - On any table with a joint radius ([`Table::joint_radius_rad`]): only samples
    ///   whose joint angles are all within that radius of `joints_rad` are admissible.
    /// - Otherwise the answer equals [`Table::query_target`]'s.
    ///
    /// `neighbours` counts the interpolated residuals' neighbours. Non-finite joint angles
    /// give [`Status::InvalidInput`]. The joint angles are taken as given: they are not
    /// checked against the target position (the controller's inverse kinematics is the
    /// authority on them).
    pub fn query_with_joints(
        &self,
        target: &Target,
        joints_rad: &[f64; JOINT_COUNT],
    ) -> Correction {
        if !joints_rad.iter().all(|q| q.is_finite()) {
            return Correction::failed(Status::InvalidInput);
        }
        let mut correction = self.interpolate(target, Some(joints_rad));
        if correction.status != Status::Ok {
            return correction;
        }
        if let Some(model) = &self.prepared_model {
            let (position_mm, rotation_rad) = model.error(joints_rad);
            for (out, model) in correction.position_error_mm.iter_mut().zip(position_mm) {
                *out += model;
            }
            // Position-only samples: the table predicts no orientation, the model does.
            if self.has_orientation() {
                let orientation = correction.orientation_error_rad.iter_mut();
                for (out, model) in orientation.zip(rotation_rad) {
                    *out += model;
                }
            }
        }
        correction.finite_or_failure()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `Exp(v)` by Rodrigues' formula, for checking the logarithm.
    fn exp(v: [f64; 3]) -> [[f64; 3]; 3] {
        let theta = norm(v);
        let k = if theta > 0.0 {
            v.map(|x| x / theta)
        } else {
            [0.0; 3]
        };
        let (s, c) = theta.sin_cos();
        let mut r = [[0.0; 3]; 3];
        let skew = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
        for i in 0..3 {
            for j in 0..3 {
                let delta = if i == j { 1.0 } else { 0.0 };
                r[i][j] = c * delta + s * skew[i][j] + (1.0 - c) * k[i] * k[j];
            }
        }
        r
    }

    #[test]
    fn logarithm_inverts_the_exponential_from_tiny_angles_to_pi() {
        let axes = [[1.0, 0.0, 0.0], [0.3, -0.5, 0.8], [-0.2, 0.9, 0.1]];
        for axis in axes {
            let unit = axis.map(|v| v / norm(axis));
            for angle in [
                0.0,
                1e-12,
                1e-6,
                1e-3,
                0.5,
                2.0,
                2.9,
                3.1,
                std::f64::consts::PI - 1e-7,
            ] {
                let v = unit.map(|x| x * angle);
                let back = rotation_vector(&exp(v));
                for a in 0..3 {
                    assert!(
                        (back[a] - v[a]).abs() < 1e-9 * angle.max(1e-3) + 1e-15,
                        "angle {angle}, axis {unit:?}: {back:?} vs {v:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn joint_screen_is_a_max_norm_and_refuses_nan() {
        let target = [0.0, 0.5, -0.5, 1.0, 0.0, 0.0];
        let mut sample = target;
        sample[3] += 0.1;
        assert!(joints_within(&sample, &target, 0.1 + 1e-12));
        assert!(!joints_within(&sample, &target, 0.099));
        sample[0] = f64::NAN;
        assert!(!joints_within(&sample, &target, 10.0));
    }

    #[test]
    fn identical_models_predict_no_error_and_a_shifted_base_predicts_the_shift() {
        use std::f64::consts::FRAC_PI_2;
        let joint = |a_mm, d_mm, alpha_rad| [a_mm, d_mm, alpha_rad, 0.0, 0.0];
        let identity = rows_of(&Transform::IDENTITY);
        let nominal = ModelParams {
            joints: [
                joint(350.0, 750.0, -FRAC_PI_2),
                joint(1250.0, 0.0, 0.0),
                joint(55.0, 0.0, FRAC_PI_2),
                joint(0.0, 1100.0, -FRAC_PI_2),
                joint(0.0, 0.0, FRAC_PI_2),
                joint(0.0, 230.0, 0.0),
            ],
            tool: identity,
            base: identity,
        };
        let q = [0.1, -0.7, 1.2, 0.3, -0.4, 1.1];
        let same = KinematicModel {
            nominal,
            calibrated: nominal,
        };
        assert_eq!(model_error(&same, &q), ([0.0; 3], [0.0; 3]));
        let mut shifted = nominal;
        shifted.base[3] = 0.25;
        shifted.base[11] = -0.5;
        let (p, r) = model_error(
            &KinematicModel {
                nominal,
                calibrated: shifted,
            },
            &q,
        );
        for (got, want) in p.iter().zip([0.25, 0.0, -0.5]) {
            assert!((got - want).abs() < 1e-12, "{p:?}");
        }
        assert!(r.iter().all(|v| v.abs() < 1e-15), "{r:?}");
    }
}
