//! Model-based calibration: identifying a robot's kinematic deviations from measured samples.
//!
//! This is the classical alternative to the non-kinematic table: explain the measured errors
//! by a corrected kinematic model, then predict the error anywhere from that model. It is the
//! `kinematic` method of `tablec eval`, the first stage of the `hybrid` method, which
//! interpolates only what the corrected model leaves unexplained, and `tablec calibrate`.
//!
//! # The model
//!
//! The actual tool centre point (TCP) pose at commanded joint values `q` is the robot's
//! chain with deviated parameters, `B' · (joints with deviations)(q) · T_tool'`. The
//! parameters, in this column order ([`Calibration::parameters`]):
//!
//! - per joint, for a robot described in MD-H, the deviations `(Δa, Δd, Δα, Δθ, Δβ)` of its
//!   MD-H row, mm and rad, as in [`crate::error_model`];
//! - per joint, for any other robot (URDF, TOML chain joints): the deviation of its offset
//!   (`Δoffset`, rad, or mm for a prismatic joint), and for every joint but the first a
//!   small perturbation of its origin, `O' = O · Trans(Δx, Δy, Δz) · Exp(Δrx, Δry, Δrz)`:
//!   three translations (mm) along and three rotations (rad, a rotation vector) about the
//!   axes of the origin's frame. The first joint's origin is the base registration's (a
//!   perturbation of it is one of the base), so it has only its offset. Of the remaining
//!   redundancies — an origin rotation about a revolute joint's own axis is its offset, a
//!   translation along it the next origin's translations, two parallel axes share their
//!   common normal — the pivoted QR below keeps one parameter and reports the others;
//!   columns are ordered so that, of exactly equal columns, the offset is the one kept;
//! - 3 tool translation deviations, mm, in the flange frame (MD-H frame `n`, or the last
//!   joint's frame after its motion), added to the robot file's tool;
//! - 3 tool rotation deviations, a rotation vector in the flange frame, rad
//!   (`R_tool' = Exp(δ) · R_tool`);
//! - 3 base registration translations, mm, added to the base's translation;
//! - 3 base registration rotations, a rotation vector, rad (`R_base' = Exp(δ) · R_base`,
//!   about axes of the frame poses are given in);
//! - with [`CalibrateOptions::compliance`], per revolute joint its gravity compliance
//!   (µrad/(N·m), the deviation from the robot file's; "Gravity compliance" below).
//!
//! The base registration is there because a laser tracker's frame is registered to the
//! robot's base by a measurement of its own, whose error is a rigid transform of every
//! sample; the tool offset because the reflector never sits exactly where the tool file says.
//! The MD-H parameterisation of an MD-H robot is the minimal one that robot file already
//! names; the origin perturbations describe any chain, at the price of more (redundant)
//! columns, which the pivoting removes.
//!
//! The predicted error is `T_actual(q)` against the *nominal* model `T_nominal(q)`, exactly
//! (no linearisation): position `p_actual − p_nominal` (mm) and orientation
//! `log(R_actual · R_nominalᵀ)` (rad), both in the base frame, as samples record them. Both
//! are the runtime's chain ([`adwi_runtime::chain::Chain`]), so a stored model
//! ([`Calibration::chains`]) evaluates exactly what was identified.
//!
//! # Gravity compliance
//!
//! A joint's gear gives under the gravity torque about its axis: commanded `q`, the arm
//! stands at `q_j + c_j · τ_j(q)` ([`adwi_runtime::chain`], "Gravity compliance"), `τ_j`
//! the torque of the links joint `j` carries (the robot file's `mass_kg`, `com_mm`),
//! gravity along −z of the frame poses are given in (the calibrated chain's base frame).
//! With [`CalibrateOptions::compliance`] the compliance `c_j` of every revolute joint is
//! identified with the geometry (a robot file without link masses is refused,
//! [`CalibrateError::NoLinkMasses`]); its value is reported in µrad/(N·m), a joint's
//! stiffness in N·m/µrad inverted. The actual pose is then always the runtime's
//! [`Chain::loaded_tcp_pose`] of the calibrated chain with its compliances, so the stored
//! model reproduces the identification. When the robot file gives compliances
//! (`compliance_urad_per_nm`, [`crate::model`]), the nominal model of where the arm
//! stands carries them: without the option they stay as the file gives them, with it the
//! identified value is the deviation from them, as the geometry's is from the file's
//! geometry. The commanded pose the errors are measured from is the chain without
//! deflection, as the controller computes it.
//!
//! # Identification
//!
//! Levenberg–Marquardt on the residuals `measured error − predicted error` of every sample
//! (3 position rows, and 3 orientation rows when the samples carry orientation errors,
//! weighted by [`CalibrateOptions::orientation_weight_mm_per_rad`]). The Jacobian is
//! analytic, every column a screw of the current parameters: the MD-H columns are the error
//! model's ([`crate::error_model::mdh_screws`]); an offset turns (or slides) about its
//! joint's axis; an origin translation slides along an axis of the origin's frame; an
//! origin rotation `r` turns about `R_O · J_l(r) · e_k` (`J_l` the left Jacobian of SO(3), so
//! that the column is exact at any `r`) through the origin; the tool and base columns are
//! screws of their own. Rotations of the tool and base are updated multiplicatively
//! (`R ← Exp(δ) · R`), so their Jacobian is exact at every step. With compliance every
//! geometric screw is taken at the loaded joints `q + Δq`, and the column of `c_j` is joint
//! `j`'s screw there times `τ_j(q)`. The torques depend on the geometry too (a longer link
//! carries its mass further out); that dependence is left out of the Jacobian (Gauss–Newton
//! on the deflection: it changes the step, not the minimum, and is of the order of the
//! deflection itself, about 1e-3 of a column). A test checks every column against central
//! differences of the exact model (with the torques held, for the geometric columns of a
//! compliant model).
//!
//! Not every parameter can be identified: some are redundant by construction (`Δd_1` and the
//! base z translation move the TCP alike), others because the data do not excite them (a
//! joint that never turns, orientation never measured). Before iterating, the Jacobian at the
//! nominal model is scaled to unit columns and factored by QR with column pivoting (a greedy
//! Gram–Schmidt): columns are kept in order of how much of them is independent of those
//! already kept, and the first column whose independent part falls below
//! [`CalibrateOptions::rank_tolerance`] (relative to the first) ends the selection. The
//! parameters not kept stay at zero and are reported as unidentifiable; the condition number
//! of the kept, scaled Jacobian is reported too. Pivoting on the scaled Jacobian keeps the
//! choice independent of units (mm against rad). Of columns that are exactly redundant
//! (equal independent parts), a tool or base column is kept rather than a joint's: a
//! flange offset along its own axis (`Δd_n`) moves the TCP exactly like a longer tool, a
//! tilt of the last joint's frame (`Δα_n`, `Δβ_n`) like a tool offset across it, `Δd_1`
//! like a base registered higher; what is mounted or registered — the tool, the tracker's
//! registration — deviates more and is known less than what was machined, so the
//! deviation is given to it.
//!
//! # Uncertainty
//!
//! The standard error of each identified parameter is the square root of the diagonal of
//! `σ² (JᵀJ)⁻¹`, with `J` the weighted Jacobian of the identified parameters at the
//! solution and `σ² = |r|² / (m − p)` the residual variance (`m` measured coordinates, `p`
//! identified parameters): the spread the parameter would have over repeated measurements
//! with noise like the residuals', if the model were right. For a rotation updated
//! multiplicatively it is the spread of the small rotation about that axis. The correlation
//! of two parameters is `C_ij / sqrt(C_ii C_jj)` of that covariance `C`; each parameter's
//! strongest one is reported ([`ParameterReport::strongest_correlation`]): near ±1, the
//! data tell the two apart only through the other's value.
//!
//! # Trust
//!
//! A parameter the pivoting keeps is not yet one the data determine. After each fit every
//! kept parameter is assessed ([`CalibrateOptions::hold_untrustworthy`]):
//!
//! - **plausible**: its value must lie within the bound of its kind
//!   ([`Parameter::plausible_bound`]): 5° for an angle of a joint (MD-H Δα, Δθ, Δβ, a joint
//!   offset, an origin rotation), 5 mm for a length of a joint (Δa, Δd, an origin
//!   translation, a prismatic offset), and wider for what is mounted or registered rather
//!   than machined: 25 mm and 10° for the tool, 50 mm and 10° for the base registration.
//!   A robot that left its factory within tolerance deviates far less; a value beyond them
//!   is the fit explaining something else (noise, a compliance, the tool) with a
//!   parameter that happens to correlate with it. A joint's whole compliance (the file's
//!   plus the estimate) must lie within ±100 µrad/(N·m)
//!   ([`MAX_PLAUSIBLE_COMPLIANCE_URAD_PER_NM`]), a stiffness of 10⁴ N·m/rad, softer than
//!   the smallest strain-wave gears of robot arms: the UR5's shoulder carries about
//!   30 N·m, so such a compliance would tilt it by 3 mrad, 2.5 mm at the tool, as much as
//!   the arm's whole uncompensated error (2.7 mm RMS on its laser-tracker data). It must
//!   not be negative either, once determined (a joint does not stiffen under load,
//!   [`HoldReason::NegativeCompliance`]);
//! - **determined**: `|value| > significance · SE`
//!   ([`CalibrateOptions::significance`], 3 by default), or a negligible standard error
//!   (below 0.01 mm, 0.01 mrad or 0.001 µrad/(N·m),
//!   [`Parameter::negligible_standard_error`]: the data pin it down, even at zero).
//!
//! The least trustworthy failing parameter — the implausible one furthest beyond its bound,
//! else the undetermined one with the largest SE / |value| — is held at its nominal value,
//! the pivoting is redone without it (a parameter it had shadowed, such as the tool z
//! translation behind `Δd_n`, may now enter) and the fit is solved again from the previous
//! solution; until every kept parameter passes. Each held parameter's report
//! ([`Calibration::report`]) keeps the estimate, standard error and strongest correlation
//! it had when it was held, and the reason ([`HoldReason`]).

use adwi_runtime::chain::{Chain, JointKind};
use adwi_runtime::kinematics::Transform;
use adwi_runtime::model::PreparedModel;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use crate::error_model::{
    apply_deviations, deviations_from_vector, mdh_screws, transform_pose_error, vector,
    MdhParameter, Screw, PARAMETERS_PER_JOINT,
};
use crate::model::{
    chain_frames, mdh_constant_part, rotation_of, transform_from_parts, Geometry, Robot,
    URAD_PER_NM,
};
use adwi_samples::pose::{rotation_from_vector, rotation_vector};
use adwi_samples::SampleSet;

/// One identifiable quantity of the calibration model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Parameter {
    /// An MD-H parameter of joint `joint` (0-based).
    Mdh {
        /// Joint index, 0-based.
        joint: usize,
        /// Which parameter.
        parameter: MdhParameter,
    },
    /// The offset of a chain joint (0-based): rad, or mm when `prismatic`.
    Offset {
        /// Joint index, 0-based.
        joint: usize,
        /// Whether the joint slides (mm) rather than turns (rad).
        prismatic: bool,
    },
    /// Translation of a chain joint's origin along an axis of its frame (0 = x, 1 = y,
    /// 2 = z), mm.
    OriginTranslation {
        /// Joint index, 0-based.
        joint: usize,
        /// The axis.
        axis: usize,
    },
    /// Rotation of a chain joint's origin about an axis of its frame, rad.
    OriginRotation {
        /// Joint index, 0-based.
        joint: usize,
        /// The axis.
        axis: usize,
    },
    /// Tool translation along a flange axis (0 = x, 1 = y, 2 = z), mm.
    ToolTranslation(usize),
    /// Tool rotation about a flange axis, rad.
    ToolRotation(usize),
    /// Base registration translation along a base axis, mm.
    BaseTranslation(usize),
    /// Base registration rotation about a base axis, rad.
    BaseRotation(usize),
    /// The gravity compliance of a revolute joint (0-based), µrad/(N·m): its deviation
    /// from the robot file's (module docs, "Gravity compliance").
    Compliance {
        /// Joint index, 0-based.
        joint: usize,
    },
}

impl Parameter {
    /// Whether the parameter is a length (mm) rather than an angle (rad).
    pub fn is_length(self) -> bool {
        match self {
            Parameter::Mdh { parameter, .. } => {
                matches!(parameter, MdhParameter::A | MdhParameter::D)
            }
            Parameter::Offset { prismatic, .. } => prismatic,
            Parameter::OriginTranslation { .. }
            | Parameter::ToolTranslation(_)
            | Parameter::BaseTranslation(_) => true,
            Parameter::OriginRotation { .. }
            | Parameter::ToolRotation(_)
            | Parameter::BaseRotation(_)
            | Parameter::Compliance { .. } => false,
        }
    }

    /// Whether the parameter is a joint's gravity compliance (µrad/(N·m)).
    pub fn is_compliance(self) -> bool {
        matches!(self, Parameter::Compliance { .. })
    }

    /// The unit of its value: `mm`, `rad`, or `µrad/(N·m)` for a compliance.
    pub fn unit(self) -> &'static str {
        if self.is_compliance() {
            "µrad/(N·m)"
        } else if self.is_length() {
            "mm"
        } else {
            "rad"
        }
    }

    /// The gravity compliances of `robot`, one per revolute joint, in column order (they
    /// follow [`Parameter::all_of`] when [`CalibrateOptions::compliance`] asks for them).
    pub fn compliances_of(robot: &Robot) -> Vec<Parameter> {
        (0..robot.joint_count())
            .filter(|&joint| robot.joint_kind(joint) == JointKind::Revolute)
            .map(|joint| Parameter::Compliance { joint })
            .collect()
    }

    /// The parameters of `robot`, in column order (module docs).
    pub fn all_of(robot: &Robot) -> Vec<Parameter> {
        let mut out = Vec::new();
        match robot.geometry() {
            Geometry::Mdh(rows) => {
                for joint in 0..rows.len() {
                    for parameter in MdhParameter::ALL {
                        out.push(Parameter::Mdh { joint, parameter });
                    }
                }
            }
            Geometry::Chain(joints) => {
                for (joint, j) in joints.iter().enumerate() {
                    out.push(Parameter::Offset {
                        joint,
                        prismatic: j.kind == JointKind::Prismatic,
                    });
                    if joint > 0 {
                        for axis in 0..3 {
                            out.push(Parameter::OriginTranslation { joint, axis });
                        }
                        for axis in 0..3 {
                            out.push(Parameter::OriginRotation { joint, axis });
                        }
                    }
                }
            }
        }
        out.extend((0..3).map(Parameter::ToolTranslation));
        out.extend((0..3).map(Parameter::ToolRotation));
        out.extend((0..3).map(Parameter::BaseTranslation));
        out.extend((0..3).map(Parameter::BaseRotation));
        out
    }
}

impl std::fmt::Display for Parameter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        const AXES: [&str; 3] = ["x", "y", "z"];
        match *self {
            Parameter::Mdh { joint, parameter } => {
                write!(f, "Δ{}{}", parameter.name(), joint + 1)
            }
            Parameter::Offset { joint, .. } => write!(f, "Δoffset{}", joint + 1),
            Parameter::OriginTranslation { joint, axis } => {
                write!(f, "Δ{}{}", AXES[axis], joint + 1)
            }
            Parameter::OriginRotation { joint, axis } => {
                write!(f, "Δr{}{}", AXES[axis], joint + 1)
            }
            Parameter::ToolTranslation(a) => write!(f, "tool {}", AXES[a]),
            Parameter::ToolRotation(a) => write!(f, "tool r{}", AXES[a]),
            Parameter::BaseTranslation(a) => write!(f, "base {}", AXES[a]),
            Parameter::BaseRotation(a) => write!(f, "base r{}", AXES[a]),
            Parameter::Compliance { joint } => write!(f, "compliance{}", joint + 1),
        }
    }
}

impl Parameter {
    /// The largest deviation of this kind that is physically plausible (mm, rad or
    /// µrad/(N·m); module docs, "Trust"): 5° and 5 mm for a joint's geometry, 25 mm and
    /// 10° for the tool, 50 mm and 10° for the base registration, 100 µrad/(N·m) for a
    /// joint's compliance (of its whole compliance, not of the deviation).
    pub fn plausible_bound(self) -> f64 {
        let degrees = |d: f64| d.to_radians();
        match self {
            Parameter::Compliance { .. } => MAX_PLAUSIBLE_COMPLIANCE_URAD_PER_NM,
            Parameter::ToolTranslation(_) => 25.0,
            Parameter::ToolRotation(_) => degrees(10.0),
            Parameter::BaseTranslation(_) => 50.0,
            Parameter::BaseRotation(_) => degrees(10.0),
            p if p.is_length() => 5.0,
            _ => degrees(5.0),
        }
    }

    /// A standard error below which the data determine the parameter whatever its value:
    /// 0.01 mm, 0.01 mrad, or 0.001 µrad/(N·m) (10 µrad under the 10 kN·m a 150 kg robot's
    /// shoulder carries).
    pub fn negligible_standard_error(self) -> f64 {
        if self.is_compliance() {
            1e-3
        } else if self.is_length() {
            0.01
        } else {
            1e-5
        }
    }
}

/// The largest plausible gravity compliance of a joint, µrad/(N·m) (module docs, "Trust").
pub const MAX_PLAUSIBLE_COMPLIANCE_URAD_PER_NM: f64 = 100.0;

/// Why a kept parameter was held at its nominal value (module docs, "Trust").
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HoldReason {
    /// Its estimate lies beyond the plausible bound of its kind (for a compliance: the
    /// joint's whole compliance, the file's plus the estimate).
    Implausible {
        /// The estimate, mm, rad or µrad/(N·m).
        value: f64,
        /// The bound, mm, rad or µrad/(N·m).
        bound: f64,
    },
    /// A joint's whole compliance (the file's plus the estimate) is negative, and
    /// determined: the joint would stiffen under load, which no gear does.
    NegativeCompliance {
        /// The joint's whole compliance, µrad/(N·m).
        value: f64,
        /// The estimate's standard error, µrad/(N·m).
        standard_error: f64,
    },
    /// Its estimate is within a few standard errors of zero.
    Undetermined {
        /// The estimate, mm or rad.
        value: f64,
        /// Its standard error, mm or rad.
        standard_error: f64,
    },
}

impl HoldReason {
    /// The reason in words, values in mm, mrad or µrad/(N·m) as `parameter` takes them.
    pub fn describe(&self, parameter: Parameter) -> String {
        let show = |v: f64| {
            if parameter.is_compliance() {
                format!("{v:+.4} µrad/(N·m)")
            } else if parameter.is_length() {
                format!("{v:+.4} mm")
            } else {
                format!("{:+.4} mrad", v * 1e3)
            }
        };
        match *self {
            HoldReason::Implausible { value, bound } => format!(
                "implausible: estimate {} beyond ±{}",
                show(value),
                show(bound).trim_start_matches('+')
            ),
            HoldReason::Undetermined {
                value,
                standard_error,
            } => format!(
                "undetermined: estimate {} within {:.1} standard errors ({}) of zero",
                show(value),
                value.abs() / standard_error,
                show(standard_error).trim_start_matches('+')
            ),
            HoldReason::NegativeCompliance {
                value,
                standard_error,
            } => format!(
                "implausible: compliance {} is negative by {:.1} standard errors ({}): a joint \
                 does not stiffen under load",
                show(value),
                value.abs() / standard_error,
                show(standard_error).trim_start_matches('+')
            ),
        }
    }
}

/// What became of one parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ParameterStatus {
    /// Identified: plausible and determined by the data.
    Identified,
    /// Kept by the pivoting but held at nominal: the estimate it had and why.
    Held {
        /// The estimate when it was held, mm or rad.
        estimate: f64,
        /// Why.
        reason: HoldReason,
    },
    /// Not separable from the identified parameters (pivoted QR), kept at nominal.
    Unidentifiable {
        /// Its independent fraction in the scaled Jacobian (0 for an exact redundancy).
        independent_fraction: f64,
        /// The identified parameter whose column is most like its own (largest |cosine|):
        /// for an exact redundancy of two, the one that took its place.
        most_like: Option<Parameter>,
    },
}

/// One parameter as a calibration engineer reads it: value, standard error, strongest
/// correlation, status and reason.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParameterReport {
    /// The parameter.
    pub parameter: Parameter,
    /// Its identified value (mm or rad), zero unless identified.
    pub value: f64,
    /// Its standard error (mm or rad): of the final fit when identified, of the fit that
    /// held it when held; `None` when unidentifiable.
    pub standard_error: Option<f64>,
    /// The parameter it correlates with most strongly, and the correlation, in the same fit.
    pub strongest_correlation: Option<(Parameter, f64)>,
    /// Identified, held or unidentifiable.
    pub status: ParameterStatus,
}

impl ParameterReport {
    /// `identified`, `held` or `unidentifiable`.
    pub fn status_name(&self) -> &'static str {
        match self.status {
            ParameterStatus::Identified => "identified",
            ParameterStatus::Held { .. } => "held",
            ParameterStatus::Unidentifiable { .. } => "unidentifiable",
        }
    }

    /// Why the parameter is not identified, in words; empty when it is.
    pub fn reason(&self) -> String {
        match self.status {
            ParameterStatus::Identified => String::new(),
            ParameterStatus::Held { reason, .. } => reason.describe(self.parameter),
            ParameterStatus::Unidentifiable {
                independent_fraction,
                most_like,
            } => match most_like {
                Some(p) => format!(
                    "redundant with the identified parameters, most like {p} (independent \
                     fraction {independent_fraction:.1e})"
                ),
                None => format!(
                    "not seen by these data (independent fraction {independent_fraction:.1e})"
                ),
            },
        }
    }
}

/// How to identify.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrateOptions {
    /// A scaled Jacobian column whose part independent of the columns already kept is below
    /// this fraction of the first kept column's norm is unidentifiable (QR with column
    /// pivoting). `1e-3` keeps the kept set's condition number in the low thousands, so
    /// measurement noise of 0.1 mm cannot move a kept parameter by more than a few
    /// hundred times what the data say about it.
    pub rank_tolerance: f64,
    /// Orientation residuals (rad) are multiplied by this before they join the position
    /// residuals (mm): `1000` counts 1 mrad like 1 mm.
    pub orientation_weight_mm_per_rad: f64,
    /// At most this many Levenberg–Marquardt iterations.
    pub max_iterations: u32,
    /// Stop when an accepted step lowers the cost by less than this fraction of it.
    pub relative_cost_tolerance: f64,
    /// Hold at nominal, one at a time, the kept parameters whose estimates are implausible
    /// or undetermined, and fit again (module docs, "Trust").
    pub hold_untrustworthy: bool,
    /// A parameter is determined when `|value| > significance · SE` (or its SE is
    /// negligible).
    pub significance: f64,
    /// Identify each revolute joint's gravity compliance with the geometry (module docs,
    /// "Gravity compliance"): the robot file must give link masses.
    pub compliance: bool,
}

impl Default for CalibrateOptions {
    fn default() -> Self {
        CalibrateOptions {
            rank_tolerance: 1e-3,
            orientation_weight_mm_per_rad: 1000.0,
            max_iterations: 100,
            relative_cost_tolerance: 1e-14,
            hold_untrustworthy: true,
            significance: 3.0,
            compliance: false,
        }
    }
}

/// Why identification is impossible, or its model cannot be stored.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrateError {
    /// The samples carry no joint values, so no kinematic model can be evaluated at them.
    #[error("the samples have no joint angles (columns j1..jn): a kinematic calibration needs the commanded joint values of every sample")]
    MissingJoints,
    /// Compliance was asked for, but the robot file gives no link masses: without them
    /// there is no gravity torque to deflect the joints.
    #[error("{robot}: the robot file gives no link masses (mass_kg, com_mm per joint) and no [payload], so gravity compliance cannot be identified: add them, or calibrate without compliance")]
    NoLinkMasses {
        /// The robot.
        robot: String,
    },
    /// The samples' joint values do not fit the robot.
    #[error("the samples have {samples} joint values each, the robot {robot} joints")]
    JointCount {
        /// The robot's joint count.
        robot: usize,
        /// Joint values per sample.
        samples: usize,
    },
    /// An option is out of range.
    #[error("invalid calibration option {name}: {reason}")]
    InvalidOption {
        /// The option.
        name: &'static str,
        /// Its valid range.
        reason: &'static str,
    },
    /// There are fewer measurement rows than twice the identifiable parameters: the fit
    /// would follow the noise.
    #[error("{measurements} measured coordinates cannot identify {parameters} parameters (at least twice as many measurements are needed): add samples, or measure orientation too")]
    TooFewMeasurements {
        /// Measured coordinates (3 per sample, 6 with orientation).
        measurements: usize,
        /// Parameters the data could separate.
        parameters: usize,
    },
    /// The data excite no parameter at all (e.g. every sample at the same joint angles and
    /// no error).
    #[error("the samples identify no kinematic parameter: their poses do not vary")]
    NothingIdentifiable,
    /// A value is NaN or infinite.
    #[error("sample {index} has a non-finite joint angle or error")]
    NonFinite {
        /// The sample's index.
        index: usize,
    },
    /// The calibrated model is not valid (a deviation so large that a rotation is no longer
    /// one): the data do not describe this robot.
    #[error("the identified model of {robot} is not a valid robot: {reason}")]
    InvalidModel {
        /// The robot.
        robot: String,
        /// What the robot model refused.
        reason: String,
    },
}

/// A robot's identified model: what [`identify`] found and how well.
#[derive(Debug, Clone)]
pub struct Calibration {
    /// Every parameter of the model, in column order (module docs).
    pub parameters: Vec<Parameter>,
    /// The identified values, per column (mm, rad, and µrad/(N·m) for compliances); zero
    /// where not identified.
    pub deviations: DVector<f64>,
    /// The standard errors, per column (mm and rad; module docs, "Uncertainty"); `None`
    /// where not identified.
    pub standard_errors: Vec<Option<f64>>,
    /// The parameters that were identified, in pivot order (most independent first).
    pub identified: Vec<Parameter>,
    /// Every parameter, in column order: value, standard error, strongest correlation,
    /// and whether it was identified, held at nominal (and why) or unidentifiable.
    pub report: Vec<ParameterReport>,
    /// The parameters the data cannot separate from the identified ones, each with its
    /// independent fraction (pivot ratio) in the scaled Jacobian: 0 for an exact redundancy.
    /// Parameters held at nominal for want of trust are not among them (see
    /// [`Self::held`]).
    pub unidentifiable: Vec<(Parameter, f64)>,
    /// Condition number of the identified parameters' scaled Jacobian at the solution.
    pub condition_number: f64,
    /// RMS of the position residual norms over the samples before identification (the raw
    /// errors against the nominal model), mm.
    pub initial_position_rms_mm: f64,
    /// RMS of the position residual norms after identification, mm.
    pub position_rms_mm: f64,
    /// RMS of the orientation residual norms after identification, rad, when the samples
    /// carry orientation errors.
    pub orientation_rms_rad: Option<f64>,
    /// The residual standard deviation σ of one weighted measured coordinate (mm; module
    /// docs, "Uncertainty").
    pub residual_sigma_mm: f64,
    /// Levenberg–Marquardt iterations made.
    pub iterations: u32,
    /// Whether the cost stopped decreasing before the iteration limit.
    pub converged: bool,
    nominal: Robot,
    calibrated: Robot,
}

impl Calibration {
    /// The identified value of `parameter` (mm or rad), zero when not identified (or not a
    /// parameter of this robot).
    pub fn value(&self, parameter: Parameter) -> f64 {
        self.column(parameter).map_or(0.0, |c| self.deviations[c])
    }

    /// The standard error of `parameter` (mm or rad), when identified.
    pub fn standard_error(&self, parameter: Parameter) -> Option<f64> {
        self.column(parameter).and_then(|c| self.standard_errors[c])
    }

    /// The parameters held at nominal for want of trust (module docs, "Trust"), in the
    /// column order, with their reports.
    pub fn held(&self) -> Vec<&ParameterReport> {
        self.report
            .iter()
            .filter(|r| matches!(r.status, ParameterStatus::Held { .. }))
            .collect()
    }

    fn column(&self, parameter: Parameter) -> Option<usize> {
        self.parameters.iter().position(|p| *p == parameter)
    }

    /// The robot as its file describes it.
    pub fn nominal_robot(&self) -> &Robot {
        &self.nominal
    }

    /// The identified model as a robot: the nominal one with the identified geometry, tool,
    /// base and compliances (limits, masses and home posture kept). Its robot file
    /// ([`Robot::to_toml_string`]) or URDF ([`Robot::to_urdf_string`]) gives this
    /// calibration's forward kinematics.
    pub fn calibrated_robot(&self) -> &Robot {
        &self.calibrated
    }

    /// The predicted pose error at joint values `q`: the identified model's TCP pose,
    /// deflected by gravity when it has compliance, against the nominal (commanded) one,
    /// position (mm) and orientation (rotation vector, rad), base frame.
    ///
    /// # Panics
    ///
    /// When `q` does not have one value per joint.
    pub fn predict_error(&self, q: &[f64]) -> ([f64; 3], [f64; 3]) {
        let e = transform_pose_error(&self.nominal.tcp_transform(q), &loaded(&self.calibrated, q));
        ([e[0], e[1], e[2]], [e[3], e[4], e[5]])
    }

    /// The nominal and the calibrated model as the runtime's chains (the calibrated one in
    /// the frame the samples are given in, with the base registration, and its gravity
    /// compliance when identified or given by the robot file): what a hybrid table of
    /// chains stores. The runtime's `PreparedModel::new(nominal, calibrated)` error equals
    /// [`Self::predict_error`].
    pub fn chains(&self) -> (Chain, Chain) {
        (*self.nominal.chain(), *self.calibrated.chain())
    }

    /// The model a hybrid table stores: the nominal and the identified chain.
    pub fn prepared_model(&self) -> PreparedModel {
        let (nominal, calibrated) = self.chains();
        PreparedModel::new(nominal, calibrated)
            .expect("one robot's two chains have its joint count")
    }
}

/// The robot and its parameters: the model evaluated at any parameter vector.
#[derive(Debug, Clone)]
struct Model {
    robot: Robot,
    parameters: Vec<Parameter>,
    /// Columns updated multiplicatively (`Exp(δ) · R`): the tool and base rotations.
    multiplicative: [usize; 2],
    /// The first tool translation column; tool rotation, base translation and base
    /// rotation follow.
    tool_translation: usize,
    /// Per compliance column (they follow the base's), its joint.
    compliance_joints: Vec<usize>,
}

/// A parameter state: the calibrated robot it describes.
#[derive(Debug, Clone)]
struct State {
    robot: Robot,
}

impl Model {
    /// The model of `robot`'s geometry, and of its joints' compliances when `compliance`.
    fn new(robot: &Robot, compliance: bool) -> Model {
        let mut parameters = Parameter::all_of(robot);
        let tool_translation = parameters
            .iter()
            .position(|p| *p == Parameter::ToolTranslation(0))
            .expect("every robot has a tool");
        let compliances = if compliance {
            Parameter::compliances_of(robot)
        } else {
            Vec::new()
        };
        let compliance_joints = compliances
            .iter()
            .map(|p| match p {
                Parameter::Compliance { joint } => *joint,
                _ => unreachable!("compliances_of gives compliances"),
            })
            .collect();
        parameters.extend(compliances);
        Model {
            robot: robot.clone(),
            multiplicative: [tool_translation + 3, tool_translation + 9],
            tool_translation,
            compliance_joints,
            parameters,
        }
    }

    /// The first compliance column.
    fn first_compliance(&self) -> usize {
        self.tool_translation + 12
    }

    /// Per column, what the robot file gives for that parameter: the joint's compliance
    /// for a compliance column, zero for the rest (their values are deviations from the
    /// file's geometry).
    fn file_values(&self) -> Vec<f64> {
        let compliances = self.robot.compliances_urad_per_nm();
        self.parameters
            .iter()
            .map(|p| match p {
                Parameter::Compliance { joint } => compliances[*joint],
                _ => 0.0,
            })
            .collect()
    }

    fn len(&self) -> usize {
        self.parameters.len()
    }

    /// The calibrated robot of parameter vector `x` (module-doc order).
    fn state(&self, x: &DVector<f64>) -> Result<State, CalibrateError> {
        let robot = &self.robot;
        let geometry = match robot.geometry() {
            Geometry::Mdh(rows) => {
                let deviations =
                    deviations_from_vector(&x.as_slice()[..rows.len() * PARAMETERS_PER_JOINT]);
                Geometry::Mdh(apply_deviations(rows, &deviations))
            }
            Geometry::Chain(joints) => {
                let mut column = 0;
                let mut out = Vec::with_capacity(joints.len());
                for (i, joint) in joints.iter().enumerate() {
                    let mut j = *joint;
                    j.offset += x[column];
                    column += 1;
                    if i > 0 {
                        let t = [x[column], x[column + 1], x[column + 2]];
                        let r = [x[column + 3], x[column + 4], x[column + 5]];
                        column += 6;
                        j.origin = joint.origin.compose(&origin_perturbation(t, r));
                    }
                    out.push(j);
                }
                Geometry::Chain(out)
            }
        };
        let c = self.tool_translation;
        let three = |start: usize| [x[start], x[start + 1], x[start + 2]];
        let tool = robot.tool();
        let t = tool.translation_mm;
        let tool = transform_from_parts(
            [0, 1, 2].map(|a| t[a] + x[c + a]),
            &(rotation_from_vector(three(c + 3)) * rotation_of(&tool)),
        );
        let base = robot.base();
        let b = base.translation_mm;
        let base = transform_from_parts(
            [0, 1, 2].map(|a| b[a] + x[c + 6 + a]),
            &(rotation_from_vector(three(c + 9)) * rotation_of(&base)),
        );
        let invalid = |e: crate::model::RobotError| CalibrateError::InvalidModel {
            robot: robot.name.clone(),
            reason: e.to_string(),
        };
        let mut calibrated = robot
            .with_geometry(format!("{} (calibrated)", robot.name), geometry, base, tool)
            .map_err(invalid)?;
        if !self.compliance_joints.is_empty() {
            // The file's compliances (zero where it gives none) plus the deviations.
            let mut compliances: Vec<Option<f64>> = robot
                .joints()
                .iter()
                .map(|j| j.compliance_urad_per_nm)
                .collect();
            for (k, &joint) in self.compliance_joints.iter().enumerate() {
                let nominal = compliances[joint].unwrap_or(0.0);
                compliances[joint] = Some(nominal + x[self.first_compliance() + k]);
            }
            calibrated = calibrated.with_compliances(&compliances).map_err(invalid)?;
        }
        Ok(State { robot: calibrated })
    }

    /// The predicted pose error of a state at `q`: `[dp (mm); δ (rad)]`, base frame: the
    /// state's TCP, deflected by gravity ([`Chain::loaded_tcp_pose`]), against the nominal
    /// commanded one.
    fn error(&self, state: &State, q: &[f64]) -> nalgebra::Vector6<f64> {
        transform_pose_error(&self.robot.tcp_transform(q), &loaded(&state.robot, q))
    }

    /// The 6 × p Jacobian of the base-frame pose error with respect to the parameters at
    /// `state` (module docs), at the joint values the arm stands at under gravity, the
    /// torques taken as independent of the parameters.
    fn jacobian(&self, x: &DVector<f64>, state: &State, commanded: &[f64]) -> DMatrix<f64> {
        let mut j = DMatrix::zeros(6, self.len());
        let chain = state.robot.chain();
        let n = chain.joint_count();
        let loaded_joints = chain
            .loaded_joints(commanded)
            .expect("one joint value per joint");
        let q = &loaded_joints[..n];
        let (frames, tcp_pose) = chain_frames(chain, q);
        let tcp = vector(tcp_pose.translation_mm);
        let mut put = |column: usize, screw: &Screw| {
            j.column_mut(column)
                .copy_from(&screw.pose_error_column(&tcp));
        };
        // The frame the tool is given in.
        let flange = match state.robot.geometry() {
            Geometry::Mdh(rows) => {
                let (screws, _) = mdh_screws(chain, rows, q);
                for (joint, joint_screws) in screws.iter().enumerate() {
                    for (parameter, screw) in MdhParameter::ALL.into_iter().zip(joint_screws) {
                        put(parameter.column(joint), screw);
                    }
                }
                let last = rows.len() - 1;
                frames[last].1.compose(&mdh_constant_part(&rows[last]))
            }
            Geometry::Chain(joints) => {
                let Geometry::Chain(nominal) = self.robot.geometry() else {
                    unreachable!("a state has its robot's geometry")
                };
                let mut column = 0;
                for (i, joint) in joints.iter().enumerate() {
                    let (before, _) = &frames[i];
                    put(column, &Screw::of_joint(before, joint.axis, joint.kind));
                    column += 1;
                    if i > 0 {
                        // G: the unperturbed origin's frame; the translation slides along
                        // its axes, the rotation turns about R_G·J_l(r)·e_k through G·T(t).
                        let g = frames[i - 1].1.compose(&nominal[i].origin);
                        let r = [x[column + 3], x[column + 4], x[column + 5]];
                        let jl = left_jacobian(Vector3::from(r));
                        let rg = rotation_of(&g);
                        for axis in 0..3 {
                            let e = Vector3::ith(axis, 1.0);
                            put(column + axis, &Screw::Prismatic { direction: rg * e });
                            put(
                                column + 3 + axis,
                                &Screw::Revolute {
                                    axis: rg * (jl * e),
                                    point_mm: vector(before.translation_mm),
                                },
                            );
                        }
                        column += 6;
                    }
                }
                frames[joints.len() - 1].1
            }
        };
        let c = self.tool_translation;
        let rf = rotation_of(&flange);
        let base_origin = vector(chain.base.translation_mm);
        for axis in 0..3 {
            let e = Vector3::ith(axis, 1.0);
            let flange_axis = rf * e;
            // A tool translation moves the TCP along a flange axis.
            put(
                c + axis,
                &Screw::Prismatic {
                    direction: flange_axis,
                },
            );
            // A tool rotation turns the TCP frame about a flange axis, in place.
            put(
                c + 3 + axis,
                &Screw::Revolute {
                    axis: flange_axis,
                    point_mm: tcp,
                },
            );
            put(c + 6 + axis, &Screw::Prismatic { direction: e });
            // A base rotation turns everything about the base's origin.
            put(
                c + 9 + axis,
                &Screw::Revolute {
                    axis: e,
                    point_mm: base_origin,
                },
            );
        }
        // A compliance turns its joint by the gravity torque per unit of compliance.
        if let Some(gravity) = &chain.compliance {
            let torques = chain
                .gravity_torques(commanded, gravity)
                .expect("one joint value per joint");
            for (k, &joint) in self.compliance_joints.iter().enumerate() {
                let column = self.first_compliance() + k;
                let screw = Screw::of_joint(
                    &frames[joint].0,
                    chain.joints()[joint].axis,
                    JointKind::Revolute,
                );
                j.column_mut(column)
                    .copy_from(&(screw.pose_error_column(&tcp) * (torques[joint] * URAD_PER_NM)));
            }
        }
        j
    }

    /// Applies a step `dx` to the state `x`: additive, except that tool and base rotations
    /// compose as `Exp(δ) · R`.
    fn step(&self, x: &DVector<f64>, dx: &DVector<f64>) -> DVector<f64> {
        let mut next = x + dx;
        for start in self.multiplicative {
            let three = |v: &DVector<f64>| [v[start], v[start + 1], v[start + 2]];
            let composed = rotation_from_vector(three(dx)) * rotation_from_vector(three(x));
            let v = rotation_vector(&composed);
            next.rows_mut(start, 3).copy_from(&Vector3::from(v));
        }
        next
    }
}

/// The TCP pose of `robot` at commanded `q`, deflected by gravity when its chain models
/// compliance: exactly the runtime's [`Chain::loaded_tcp_pose`].
fn loaded(robot: &Robot, q: &[f64]) -> Transform {
    robot.chain().loaded_tcp_pose(q).unwrap_or_else(|| {
        panic!(
            "{} joint values for a robot of {} joints",
            q.len(),
            robot.joint_count()
        )
    })
}

/// `Trans(t) · Exp(r)`: a small perturbation of a joint origin (mm, rad).
fn origin_perturbation(t: [f64; 3], r: [f64; 3]) -> Transform {
    transform_from_parts(t, &rotation_from_vector(r))
}

/// The left Jacobian of SO(3): `Exp(r + dr) = Exp(J_l(r)·dr) · Exp(r)` to first order.
fn left_jacobian(r: Vector3<f64>) -> Matrix3<f64> {
    let theta2 = r.norm_squared();
    let k = r.cross_matrix();
    let (a, b) = if theta2 < 1e-8 {
        (0.5 - theta2 / 24.0, 1.0 / 6.0 - theta2 / 120.0)
    } else {
        let theta = theta2.sqrt();
        (
            (1.0 - theta.cos()) / theta2,
            (theta - theta.sin()) / (theta2 * theta),
        )
    };
    Matrix3::identity() + k * a + k * k * b
}

/// The measurements of one sample.
struct Measurement {
    q: Vec<f64>,
    error_mm: [f64; 3],
    rotation_error_rad: Option<[f64; 3]>,
}

/// Identifies the kinematic model of `robot` from `samples` (which need joint values, one
/// per joint; their orientation errors are used when present). See the module docs for the
/// model and method.
///
/// # Errors
///
/// [`CalibrateError::MissingJoints`] without joint values, [`CalibrateError::JointCount`]
/// when the samples' joint count is not the robot's, [`CalibrateError::NonFinite`] for a
/// non-finite value, [`CalibrateError::NothingIdentifiable`] when the poses do not vary,
/// [`CalibrateError::TooFewMeasurements`] when the samples are too few for the parameters
/// they excite, [`CalibrateError::InvalidOption`] for options out of range,
/// [`CalibrateError::InvalidModel`] when the identified model is not a robot.
pub fn identify(
    robot: &Robot,
    samples: &SampleSet,
    options: &CalibrateOptions,
) -> Result<Calibration, CalibrateError> {
    if !(options.rank_tolerance > 0.0 && options.rank_tolerance < 1.0) {
        return Err(CalibrateError::InvalidOption {
            name: "rank_tolerance",
            reason: "must be between 0 and 1 (exclusive)",
        });
    }
    if !(options.orientation_weight_mm_per_rad.is_finite()
        && options.orientation_weight_mm_per_rad > 0.0)
    {
        return Err(CalibrateError::InvalidOption {
            name: "orientation_weight_mm_per_rad",
            reason: "must be finite and positive",
        });
    }
    if options.compliance && robot.gravity_model().is_none() {
        return Err(CalibrateError::NoLinkMasses {
            robot: robot.name.clone(),
        });
    }
    let joints = samples
        .joints
        .as_ref()
        .ok_or(CalibrateError::MissingJoints)?;
    if joints.count() != robot.joint_count() {
        return Err(CalibrateError::JointCount {
            robot: robot.joint_count(),
            samples: joints.count(),
        });
    }
    let measurements: Vec<Measurement> = (0..samples.len())
        .map(|i| {
            let m = Measurement {
                q: joints.row(i).to_vec(),
                error_mm: samples.error_mm[i],
                rotation_error_rad: samples.rotation_error_rad.as_ref().map(|r| r[i]),
            };
            let finite = m.q.iter().chain(&m.error_mm).all(|v| v.is_finite())
                && m.rotation_error_rad
                    .is_none_or(|r| r.iter().all(|v| v.is_finite()));
            if finite {
                Ok(m)
            } else {
                Err(CalibrateError::NonFinite { index: i })
            }
        })
        .collect::<Result<_, _>>()?;
    let problem = Problem {
        model: Model::new(robot, options.compliance),
        measurements,
        rows_per_sample: if samples.rotation_error_rad.is_some() {
            6
        } else {
            3
        },
        weight: options.orientation_weight_mm_per_rad,
    };
    let p = problem.model.len();
    let nominal_x = DVector::zeros(p);
    let nominal_state = problem.model.state(&nominal_x)?;
    let (r0, j0) = problem.linearise(&nominal_x, &nominal_state, true);
    let column_norms: Vec<f64> = (0..p).map(|c| j0.column(c).norm()).collect();
    let largest = column_norms.iter().copied().fold(0.0, f64::max);
    if largest == 0.0 || !largest.is_finite() {
        return Err(CalibrateError::NothingIdentifiable);
    }
    // Unit columns: pivoting then compares parameters independently of their units. A
    // column of (numerically) nothing cannot be scaled and is unidentifiable outright.
    let scales: Vec<f64> = column_norms
        .iter()
        .map(|&n| if n > 1e-12 * largest { 1.0 / n } else { 0.0 })
        .collect();
    let initial_position_rms_mm = problem.position_rms(&r0);

    // Fit, assess, hold the least trustworthy parameter at nominal, fit again (module
    // docs, "Trust").
    let file_values = problem.model.file_values();
    let mut held: Vec<(usize, Assessment)> = Vec::new();
    let mut start = nominal_x;
    let fit = loop {
        let held_columns: Vec<usize> = held.iter().map(|(c, _)| *c).collect();
        let fit = problem.solve(&j0, &scales, &held_columns, start, options)?;
        if !options.hold_untrustworthy {
            break fit;
        }
        let worst = fit
            .kept
            .iter()
            .enumerate()
            .filter_map(|(k, &c)| {
                let a = fit.assess(
                    &problem.model.parameters,
                    &file_values,
                    k,
                    options.significance,
                );
                a.reason.is_some().then_some((c, a))
            })
            .max_by(|a, b| a.1.severity.total_cmp(&b.1.severity));
        match worst {
            Some((c, assessment)) => {
                held.push((c, assessment));
                start = fit.x.clone();
                start[c] = 0.0;
            }
            None => break fit,
        }
    };

    let parameters = &problem.model.parameters;
    let mut report: Vec<ParameterReport> = parameters
        .iter()
        .map(|&parameter| ParameterReport {
            parameter,
            value: 0.0,
            standard_error: None,
            strongest_correlation: None,
            status: ParameterStatus::Identified,
        })
        .collect();
    for (k, &c) in fit.kept.iter().enumerate() {
        let a = fit.assess(parameters, &file_values, k, options.significance);
        report[c].value = fit.x[c];
        report[c].standard_error = Some(a.standard_error);
        report[c].strongest_correlation = a.correlation;
    }
    for (&(c, ratio), like) in fit.dropped.iter().zip(&fit.resembles) {
        report[c].status = ParameterStatus::Unidentifiable {
            independent_fraction: ratio,
            most_like: like.map(|k| parameters[k]),
        };
    }
    for (c, a) in held {
        report[c].standard_error = Some(a.standard_error);
        report[c].strongest_correlation = a.correlation;
        report[c].status = ParameterStatus::Held {
            estimate: a.value,
            reason: a.reason.expect("only failing parameters are held"),
        };
    }
    let mut standard_errors = vec![None; p];
    for &c in &fit.kept {
        standard_errors[c] = report[c].standard_error;
    }
    let orientation_rms_rad = samples.rotation_error_rad.as_ref().map(|_| {
        let sum: f64 = (0..problem.measurements.len())
            .map(|s| {
                fit.r
                    .fixed_rows::<3>(s * problem.rows_per_sample + 3)
                    .norm_squared()
            })
            .sum();
        (sum / problem.measurements.len() as f64).sqrt() / problem.weight
    });
    Ok(Calibration {
        identified: fit.kept.iter().map(|&c| parameters[c]).collect(),
        unidentifiable: fit
            .dropped
            .iter()
            .map(|&(c, ratio)| (parameters[c], ratio))
            .collect(),
        report,
        parameters: parameters.clone(),
        standard_errors,
        condition_number: fit.condition_number,
        initial_position_rms_mm,
        position_rms_mm: problem.position_rms(&fit.r),
        orientation_rms_rad,
        residual_sigma_mm: fit.residual_sigma_mm,
        iterations: fit.iterations,
        converged: fit.converged,
        deviations: fit.x,
        nominal: robot.clone(),
        calibrated: fit.state.robot,
    })
}

/// The least-squares problem: the model and the measurements.
struct Problem {
    model: Model,
    measurements: Vec<Measurement>,
    rows_per_sample: usize,
    weight: f64,
}

/// One solution of [`Problem::solve`].
struct Fit {
    x: DVector<f64>,
    state: State,
    r: DVector<f64>,
    kept: Vec<usize>,
    dropped: Vec<(usize, f64)>,
    /// Per dropped column, the kept column most like it.
    resembles: Vec<Option<usize>>,
    condition_number: f64,
    residual_sigma_mm: f64,
    /// `(JᵀJ)⁻¹` of the kept parameters (unscaled, kept order), times σ².
    covariance: DMatrix<f64>,
    iterations: u32,
    converged: bool,
}

/// What the data say about one kept parameter.
struct Assessment {
    value: f64,
    standard_error: f64,
    correlation: Option<(Parameter, f64)>,
    /// Why it cannot be trusted, if it cannot.
    reason: Option<HoldReason>,
    /// Which failing parameter to hold first: implausible ones (by how far beyond their
    /// bound), then undetermined ones (by standard error over value).
    severity: f64,
}

impl Fit {
    /// The assessment of kept parameter `k` (module docs, "Trust"); `file_values` per
    /// column, added to the estimate where plausibility judges the whole value (a
    /// compliance).
    fn assess(
        &self,
        parameters: &[Parameter],
        file_values: &[f64],
        k: usize,
        significance: f64,
    ) -> Assessment {
        let c = self.kept[k];
        let parameter = parameters[c];
        let value = self.x[c];
        let whole = file_values[c] + value;
        let variance = self.covariance[(k, k)];
        let standard_error = variance.max(0.0).sqrt();
        let correlation = (0..self.kept.len())
            .filter(|&l| l != k)
            .map(|l| {
                let denominator = (variance * self.covariance[(l, l)]).sqrt();
                let rho = if denominator > 0.0 {
                    self.covariance[(k, l)] / denominator
                } else {
                    0.0
                };
                (parameters[self.kept[l]], rho)
            })
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()));
        let bound = parameter.plausible_bound();
        let floor = parameter.negligible_standard_error();
        let determined = standard_error <= floor || value.abs() > significance * standard_error;
        let (reason, severity) = if whole.abs() > bound {
            (
                Some(HoldReason::Implausible {
                    value: whole,
                    bound,
                }),
                1e6 + whole.abs() / bound,
            )
        } else if parameter.is_compliance() && whole < 0.0 && determined {
            (
                Some(HoldReason::NegativeCompliance {
                    value: whole,
                    standard_error,
                }),
                1e6 + whole.abs() / standard_error.max(f64::MIN_POSITIVE),
            )
        } else if !determined {
            (
                Some(HoldReason::Undetermined {
                    value,
                    standard_error,
                }),
                standard_error / value.abs().max(f64::MIN_POSITIVE),
            )
        } else {
            (None, 0.0)
        };
        Assessment {
            value,
            standard_error,
            correlation,
            reason,
            severity,
        }
    }
}

impl Problem {
    /// The weighted residual vector and (when asked) Jacobian, all columns, of a state.
    fn linearise(
        &self,
        x: &DVector<f64>,
        state: &State,
        with_jacobian: bool,
    ) -> (DVector<f64>, DMatrix<f64>) {
        let p = self.model.len();
        let rows = self.measurements.len() * self.rows_per_sample;
        let mut r = DVector::zeros(rows);
        let mut jac = if with_jacobian {
            DMatrix::zeros(rows, p)
        } else {
            DMatrix::zeros(0, 0)
        };
        for (s, m) in self.measurements.iter().enumerate() {
            let e = self.model.error(state, &m.q);
            let row = s * self.rows_per_sample;
            for a in 0..3 {
                r[row + a] = m.error_mm[a] - e[a];
            }
            if let Some(measured) = m.rotation_error_rad {
                for a in 0..3 {
                    r[row + 3 + a] = self.weight * (measured[a] - e[a + 3]);
                }
            }
            if with_jacobian {
                let j = self.model.jacobian(x, state, &m.q);
                for a in 0..self.rows_per_sample {
                    let scale = if a < 3 { 1.0 } else { self.weight };
                    for c in 0..p {
                        jac[(row + a, c)] = scale * j[(a, c)];
                    }
                }
            }
        }
        (r, jac)
    }

    /// RMS of the position residual norms.
    fn position_rms(&self, r: &DVector<f64>) -> f64 {
        let n = self.measurements.len();
        let sum: f64 = (0..n)
            .map(|s| r.fixed_rows::<3>(s * self.rows_per_sample).norm_squared())
            .sum();
        (sum / n as f64).sqrt()
    }

    /// Selects the identifiable columns of the nominal Jacobian `j0` (scaled by `scales`)
    /// other than `held`, and fits them from `start` (whose held columns are zero).
    fn solve(
        &self,
        j0: &DMatrix<f64>,
        scales: &[f64],
        held: &[usize],
        start: DVector<f64>,
        options: &CalibrateOptions,
    ) -> Result<Fit, CalibrateError> {
        let p = self.model.len();
        let mut scaled = j0.clone();
        for (c, s) in scales.iter().enumerate() {
            let s = if held.contains(&c) { 0.0 } else { *s };
            scaled.column_mut(c).scale_mut(s);
        }
        // Of exactly redundant columns the tool's or the base's is kept (module docs).
        let preferred: Vec<bool> = self
            .model
            .parameters
            .iter()
            .map(|p| {
                matches!(
                    p,
                    Parameter::ToolTranslation(_)
                        | Parameter::ToolRotation(_)
                        | Parameter::BaseTranslation(_)
                        | Parameter::BaseRotation(_)
                )
            })
            .collect();
        let (kept, mut dropped) = pivot_columns(&scaled, options.rank_tolerance, &preferred);
        dropped.retain(|(c, _)| !held.contains(c));
        // The kept column most like each dropped one (largest |cosine| of the unit columns).
        let resembles: Vec<Option<usize>> = dropped
            .iter()
            .map(|&(c, _)| {
                kept.iter()
                    .map(|&k| (k, scaled.column(c).dot(&scaled.column(k)).abs()))
                    .filter(|&(_, cosine)| cosine > 0.0)
                    .max_by(|a, b| a.1.total_cmp(&b.1))
                    .map(|(k, _)| k)
            })
            .collect();
        if kept.is_empty() {
            return Err(CalibrateError::NothingIdentifiable);
        }
        let rows = self.measurements.len() * self.rows_per_sample;
        if rows < 2 * kept.len() {
            return Err(CalibrateError::TooFewMeasurements {
                measurements: rows,
                parameters: kept.len(),
            });
        }

        // Levenberg–Marquardt in the scaled, kept coordinates: solve
        // [J; √μ·I] δ = [r; 0] by SVD, accept the step if the cost falls.
        let reduced = |jac: &DMatrix<f64>| {
            DMatrix::from_fn(rows, kept.len(), |i, k| jac[(i, kept[k])] * scales[kept[k]])
        };
        let mut x = start;
        let mut state = self.model.state(&x)?;
        let (mut r, mut jac) = self.linearise(&x, &state, true);
        let mut cost = r.norm_squared();
        let mut mu: f64 = 1e-6;
        let mut iterations = 0;
        let mut converged = false;
        while iterations < options.max_iterations {
            iterations += 1;
            let jk = reduced(&jac);
            let mut accepted = false;
            for _ in 0..30 {
                let mut augmented = DMatrix::zeros(rows + kept.len(), kept.len());
                augmented.rows_mut(0, rows).copy_from(&jk);
                for k in 0..kept.len() {
                    augmented[(rows + k, k)] = mu.sqrt();
                }
                let mut rhs = DVector::zeros(rows + kept.len());
                rhs.rows_mut(0, rows).copy_from(&r);
                let step = augmented
                    .svd(true, true)
                    .solve(&rhs, 0.0)
                    .expect("SVD with both factors computed");
                let mut dx = DVector::zeros(p);
                for (k, &c) in kept.iter().enumerate() {
                    dx[c] = step[k] * scales[c];
                }
                let candidate_x = self.model.step(&x, &dx);
                // A step so large that the model stops being a robot is refused like one
                // that raises the cost.
                let Ok(candidate) = self.model.state(&candidate_x) else {
                    mu *= 10.0;
                    continue;
                };
                let (candidate_r, _) = self.linearise(&candidate_x, &candidate, false);
                let candidate_cost = candidate_r.norm_squared();
                if candidate_cost.is_finite() && candidate_cost <= cost {
                    let decrease = cost - candidate_cost;
                    x = candidate_x;
                    state = candidate;
                    mu = (mu / 10.0).max(1e-15);
                    accepted = true;
                    if decrease <= options.relative_cost_tolerance * cost || candidate_cost == 0.0 {
                        converged = true;
                    }
                    cost = candidate_cost;
                    break;
                }
                mu *= 10.0;
            }
            if !accepted {
                // No step lowers the cost any more: a minimum to working precision.
                converged = true;
            }
            let (next_r, next_jac) = self.linearise(&x, &state, true);
            r = next_r;
            jac = next_jac;
            if converged {
                break;
            }
        }

        let jk = reduced(&jac);
        let svd = jk.svd(false, true);
        let singular = &svd.singular_values;
        let condition_number = singular.max() / singular.min();
        let residual_sigma_mm = (r.norm_squared() / (rows - kept.len()) as f64).sqrt();
        // σ² (JᵀJ)⁻¹ of the unscaled parameters: with J_s = J·S = U Σ Vᵀ,
        // (JᵀJ)⁻¹ = S V Σ⁻² Vᵀ S.
        let n = kept.len();
        let mut covariance = DMatrix::zeros(n, n);
        if let Some(v_t) = &svd.v_t {
            for k in 0..n {
                for l in k..n {
                    let m: f64 = (0..singular.len())
                        .map(|i| v_t[(i, k)] * v_t[(i, l)] / singular[i].powi(2))
                        .sum();
                    let value = residual_sigma_mm.powi(2) * m * scales[kept[k]] * scales[kept[l]];
                    covariance[(k, l)] = value;
                    covariance[(l, k)] = value;
                }
            }
        }
        Ok(Fit {
            x,
            state,
            r,
            kept,
            dropped,
            resembles,
            condition_number,
            residual_sigma_mm,
            covariance,
            iterations,
            converged,
        })
    }
}

/// QR with column pivoting by modified Gram–Schmidt: returns the kept columns in pivot
/// order, and the dropped ones with their independent fraction (relative to the first
/// pivot), in column order. Selection stops at the first pivot below `tolerance`; of
/// columns whose independent parts are equal (to 1e-9), a `preferred` one is kept, else the
/// first.
fn pivot_columns(
    a: &DMatrix<f64>,
    tolerance: f64,
    preferred: &[bool],
) -> (Vec<usize>, Vec<(usize, f64)>) {
    let mut residual = a.clone();
    let mut kept = Vec::new();
    let mut remaining: Vec<usize> = (0..a.ncols()).collect();
    let mut first = None;
    while !remaining.is_empty() {
        let norms: Vec<f64> = remaining
            .iter()
            .map(|&c| residual.column(c).norm())
            .collect();
        let largest = norms.iter().copied().fold(-1.0, f64::max);
        let tied = |i: &usize| norms[*i] >= largest * (1.0 - 1e-9);
        let position = (0..remaining.len())
            .filter(tied)
            .find(|&i| preferred[remaining[i]])
            .or_else(|| (0..remaining.len()).find(tied))
            .expect("the largest is among the remaining");
        let norm = norms[position];
        let first_norm = *first.get_or_insert(norm);
        if first_norm <= 0.0 || norm < tolerance * first_norm {
            break;
        }
        let pivot = remaining.remove(position);
        let q = residual.column(pivot) / norm;
        for &c in &remaining {
            // Twice, so the projection stays orthogonal to working precision.
            for _ in 0..2 {
                let dot = q.dot(&residual.column(c));
                let mut col = residual.column_mut(c);
                col.axpy(-dot, &q, 1.0);
            }
        }
        kept.push(pivot);
    }
    let first_norm = first.unwrap_or(1.0_f64).max(f64::MIN_POSITIVE);
    let mut dropped: Vec<(usize, f64)> = remaining
        .into_iter()
        .map(|c| (c, residual.column(c).norm() / first_norm))
        .collect();
    dropped.sort_by_key(|&(c, _)| c);
    (kept, dropped)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{shipped_file, shipped_robot_path};
    use adwi_samples::Joints;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn kr150() -> Robot {
        Robot::load(shipped_robot_path("kr150-2")).unwrap()
    }

    fn iiwa() -> Robot {
        Robot::load(shipped_file("iiwa14", "robot.urdf")).unwrap()
    }

    /// Random joint values inside 80 % of the limits.
    fn poses(robot: &Robot, n: usize, seed: u64) -> Vec<Vec<f64>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                (0..robot.joint_count())
                    .map(|i| {
                        let [lo, hi] = robot.sampling_range(i);
                        rng.gen_range(lo * 0.8..hi * 0.8)
                    })
                    .collect()
            })
            .collect()
    }

    /// Samples of a robot whose true parameters are `truth`, simulated with the exact
    /// forward kinematics (nominal positions from the nominal model), with Gaussian noise of
    /// σ `noise_mm` per position axis drawn from `seed`.
    fn simulate(
        robot: &Robot,
        truth: &DVector<f64>,
        q: &[Vec<f64>],
        orientation: bool,
        noise_mm: f64,
        seed: u64,
    ) -> SampleSet {
        simulate_model(
            &Model::new(robot, false),
            truth,
            q,
            orientation,
            noise_mm,
            seed,
        )
    }

    /// As [`simulate`], of any model (one with compliances among them): the measured poses
    /// are the runtime chain's deflected poses ([`Chain::loaded_tcp_pose`]) of the true
    /// robot.
    fn simulate_model(
        model: &Model,
        truth: &DVector<f64>,
        q: &[Vec<f64>],
        orientation: bool,
        noise_mm: f64,
        seed: u64,
    ) -> SampleSet {
        let robot = &model.robot;
        let state = model.state(truth).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut set = SampleSet {
            rotation_error_rad: orientation.then(Vec::new),
            joints: Some(Joints::new(robot.joint_count())),
            ..SampleSet::default()
        };
        for (i, q) in q.iter().enumerate() {
            let nominal = robot.tcp_pose(q).translation.vector;
            let e = model.error(&state, q);
            let mut noise = || {
                // Box-Muller.
                let (u, v): (f64, f64) = (1.0 - rng.gen::<f64>(), rng.gen());
                (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos() * noise_mm
            };
            set.nominal_mm.push([nominal.x, nominal.y, nominal.z]);
            set.error_mm
                .push([e[0] + noise(), e[1] + noise(), e[2] + noise()]);
            if let Some(r) = &mut set.rotation_error_rad {
                r.push([e[3], e[4], e[5]]);
            }
            set.joints.as_mut().unwrap().push(q);
            set.lines.push(i as u64 + 2);
        }
        set
    }

    /// Realistic deviations on the given columns: 0.5 mm for lengths, 1 mrad for angles.
    fn deviations_on(parameters: &[Parameter], columns: &[usize], seed: u64) -> DVector<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut x = DVector::zeros(parameters.len());
        for &c in columns {
            let m = if parameters[c].is_length() { 0.5 } else { 1e-3 };
            x[c] = rng.gen_range(-m..m);
        }
        x
    }

    fn columns_of(c: &Calibration) -> Vec<usize> {
        c.identified
            .iter()
            .map(|p| c.parameters.iter().position(|q| q == p).unwrap())
            .collect()
    }

    #[test]
    fn parameters_of_mdh_and_chain_robots() {
        let mdh = Parameter::all_of(&kr150());
        assert_eq!(mdh.len(), 42);
        assert_eq!(mdh[3].to_string(), "Δtheta1");
        assert_eq!(mdh[41], Parameter::BaseRotation(2));
        // The iiwa from URDF: joint 1 has its offset only, joints 2-7 offset and origin.
        let chain = Parameter::all_of(&iiwa());
        assert_eq!(chain.len(), 1 + 6 * 7 + 12);
        assert_eq!(chain[1].to_string(), "Δoffset2");
        assert_eq!(chain[2].to_string(), "Δx2");
        assert_eq!(chain[7].to_string(), "Δrz2");
        assert!(chain[2].is_length() && !chain[7].is_length());
    }

    /// Every analytic column equals central differences of the exact model, at a state
    /// away from nominal, for an MD-H robot and a URDF chain.
    #[test]
    fn jacobian_matches_finite_differences_of_the_exact_model() {
        for robot in [kr150(), iiwa()] {
            let model = Model::new(&robot, false);
            let all: Vec<usize> = (0..model.len()).collect();
            let x = deviations_on(&model.parameters, &all, 3);
            let state = model.state(&x).unwrap();
            let q = &poses(&robot, 1, 5)[0];
            let j = model.jacobian(&x, &state, q);
            let h = 1e-6;
            for c in 0..model.len() {
                let mut d = DVector::zeros(model.len());
                d[c] = h;
                let plus = model.error(&model.state(&model.step(&x, &d)).unwrap(), q);
                let minus = model.error(&model.state(&model.step(&x, &(-&d))).unwrap(), q);
                let numeric = (plus - minus) / (2.0 * h);
                let scale = j.column(c).norm().max(1.0);
                for a in 0..3 {
                    assert!(
                        (numeric[a] - j[(a, c)]).abs() < 1e-6 * scale,
                        "{}: {} row {a}: {} vs {}",
                        robot.name,
                        model.parameters[c],
                        numeric[a],
                        j[(a, c)]
                    );
                    // log(R_actual R_nominalᵀ) differs from the rotation perturbation by
                    // the inverse left Jacobian of SO(3): I + O(|δ|), here |δ| ≈ 1e-2.
                    assert!(
                        (numeric[a + 3] - j[(a + 3, c)]).abs() < 2e-2 * scale,
                        "{}: {} row {}: {} vs {}",
                        robot.name,
                        model.parameters[c],
                        a + 3,
                        numeric[a + 3],
                        j[(a + 3, c)]
                    );
                }
            }
        }
    }

    fn ur5() -> Robot {
        Robot::load(shipped_robot_path("ur5")).unwrap()
    }

    /// Realistic deviations on the given columns, as [`deviations_on`], and compliances of
    /// 5 to 40 µrad/(N·m) (stiffnesses of 2.5·10⁴ to 2·10⁵ N·m/rad, a UR5's range).
    fn compliant_deviations_on(
        parameters: &[Parameter],
        columns: &[usize],
        seed: u64,
    ) -> DVector<f64> {
        let mut x = deviations_on(parameters, columns, seed);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 1000);
        for &c in columns {
            if parameters[c].is_compliance() {
                x[c] = rng.gen_range(5.0..40.0);
            }
        }
        x
    }

    /// With compliance, every column against central differences of the exact model: a
    /// compliance column exactly (the torques do not depend on the compliances); a
    /// geometric column exactly when the torques are held at the state's (the Jacobian's
    /// definition, module docs), and to the neglected torque term, `c · ∂τ/∂x`, when they
    /// follow the geometry as the model does.
    #[test]
    fn compliance_jacobian_matches_finite_differences() {
        for robot in [ur5(), iiwa()] {
            let model = Model::new(&robot, true);
            let all: Vec<usize> = (0..model.len()).collect();
            let x = compliant_deviations_on(&model.parameters, &all, 3);
            let state = model.state(&x).unwrap();
            let chain = state.robot.chain();
            let q = &poses(&robot, 1, 5)[0];
            let held_joints = chain.loaded_joints(q).unwrap();
            let held_joints = &held_joints[..robot.joint_count()];
            // The pose error of x + d with the torques held at the state's: each joint
            // deflected as at x, plus the compliance deviation's own turn.
            let torques = chain
                .gravity_torques(q, chain.compliance.as_ref().unwrap())
                .unwrap();
            let held = |d: &DVector<f64>| {
                let s = model.state(&model.step(&x, d)).unwrap();
                let mut joints = held_joints.to_vec();
                for (k, &joint) in model.compliance_joints.iter().enumerate() {
                    joints[joint] += d[model.first_compliance() + k] * URAD_PER_NM * torques[joint];
                }
                transform_pose_error(
                    &robot.tcp_transform(q),
                    &s.robot.chain().tcp_pose(&joints).unwrap(),
                )
            };
            let exact =
                |d: &DVector<f64>| model.error(&model.state(&model.step(&x, d)).unwrap(), q);
            let j = model.jacobian(&x, &state, q);
            let mut largest_neglected: f64 = 0.0;
            for c in 0..model.len() {
                let compliance = model.parameters[c].is_compliance();
                let h = if compliance { 1e-3 } else { 1e-6 };
                let mut d = DVector::zeros(model.len());
                d[c] = h;
                let held_numeric = (held(&d) - held(&(-&d))) / (2.0 * h);
                let numeric = (exact(&d) - exact(&(-&d))) / (2.0 * h);
                let scale = j.column(c).norm().max(1.0);
                if compliance {
                    // The same deflection, summed in another order.
                    assert!((held_numeric - numeric).norm() < 1e-9 * scale);
                }
                for a in 0..3 {
                    assert!(
                        (held_numeric[a] - j[(a, c)]).abs() < 1e-6 * scale,
                        "{}: {} row {a}: {} vs {}",
                        robot.name,
                        model.parameters[c],
                        held_numeric[a],
                        j[(a, c)]
                    );
                    // As in the test without compliance: the orientation rows differ by
                    // the inverse left Jacobian of SO(3).
                    assert!((held_numeric[a + 3] - j[(a + 3, c)]).abs() < 2e-2 * scale);
                    largest_neglected =
                        largest_neglected.max((numeric[a] - j[(a, c)]).abs() / scale);
                }
            }
            // The deflections are a few mrad at most (compliances of ≤ 40 µrad/(N·m),
            // torques of ≤ 100 N·m): the torques' dependence on the geometry changes a
            // column by that fraction of it at most.
            println!(
                "{}: torque term left out of the Jacobian ≤ {largest_neglected:.2e} of a column",
                robot.name
            );
            assert!(largest_neglected < 5e-3, "{largest_neglected}");
        }
    }

    /// Noise-free data from a robot with known geometric deviations and known joint
    /// compliances, simulated as the runtime chain deflects: the compliances come back to
    /// 1e-6 of their values, the geometry to 1e-6 mm or rad, and the stored model predicts
    /// the deflected poses.
    #[test]
    fn recovers_known_compliances_from_noise_free_data() {
        for robot in [ur5(), iiwa()] {
            let model = Model::new(&robot, true);
            let q = poses(&robot, 120, 1);
            let options = CalibrateOptions {
                compliance: true,
                ..CalibrateOptions::default()
            };
            let p = model.len();
            let zero = simulate_model(&model, &DVector::zeros(p), &q, false, 0.0, 0);
            let structure = identify(&robot, &zero, &options).unwrap();
            let columns = columns_of(&structure);
            let compliances: Vec<usize> = columns
                .iter()
                .copied()
                .filter(|&c| model.parameters[c].is_compliance())
                .collect();
            // Joint 1 turns about gravity and carries no torque: not seen. The others are.
            assert!(compliances.len() >= 3, "{:?}", structure.identified);
            let truth = compliant_deviations_on(&model.parameters, &columns, 2);
            let samples = simulate_model(&model, &truth, &q, false, 0.0, 0);
            let c = identify(&robot, &samples, &options).unwrap();
            assert!(c.converged, "not converged after {}", c.iterations);
            assert_eq!(c.identified, structure.identified);
            for i in 0..p {
                let parameter = c.parameters[i];
                let gap = (c.deviations[i] - truth[i]).abs();
                let tolerance = if parameter.is_compliance() {
                    1e-6 * truth[i].abs()
                } else {
                    1e-6
                };
                assert!(
                    gap <= tolerance,
                    "{}, {parameter}: identified {} true {}",
                    robot.name,
                    c.deviations[i],
                    truth[i]
                );
            }
            for &k in &compliances {
                let r = &c.report[k];
                assert_eq!(r.status, ParameterStatus::Identified);
                assert_eq!(r.parameter.unit(), "µrad/(N·m)");
            }
            assert!(c.position_rms_mm < 1e-9, "{}", c.position_rms_mm);
            let truth_state = model.state(&truth).unwrap();
            let stored = c.prepared_model();
            for q in poses(&robot, 10, 9) {
                let expected = model.error(&truth_state, &q);
                let got = stored.error(&q).unwrap();
                for a in 0..3 {
                    assert!((expected[a] - got.0[a]).abs() < 1e-6);
                }
            }
            println!(
                "{}: compliances {:?} µrad/(N·m) recovered",
                robot.name,
                compliances
                    .iter()
                    .map(|&k| (c.parameters[k].to_string(), c.deviations[k]))
                    .collect::<Vec<_>>()
            );
        }
    }

    /// Compliance needs link masses; a compliance beyond 100 µrad/(N·m) or a determined
    /// negative one is held at nominal with its reason.
    #[test]
    fn implausible_compliances_are_held_and_massless_robots_refused() {
        let options = CalibrateOptions {
            compliance: true,
            ..CalibrateOptions::default()
        };
        let robot = kr150();
        let q = poses(&robot, 60, 4);
        let samples = simulate(&robot, &DVector::zeros(42), &q, false, 0.0, 0);
        let error = identify(&robot, &samples, &options).unwrap_err();
        assert!(matches!(error, CalibrateError::NoLinkMasses { .. }));
        assert!(
            error.to_string().contains("gives no link masses"),
            "{error}"
        );

        let robot = ur5();
        let model = Model::new(&robot, true);
        let q = poses(&robot, 120, 4);
        let column = |joint| {
            model
                .parameters
                .iter()
                .position(|p| *p == Parameter::Compliance { joint })
                .unwrap()
        };
        for (value, negative) in [(-20.0, true), (400.0, false)] {
            let mut truth = DVector::zeros(model.len());
            truth[column(1)] = value;
            truth[column(2)] = 15.0;
            let samples = simulate_model(&model, &truth, &q, false, 0.01, 3);
            let c = identify(&robot, &samples, &options).unwrap();
            let report = &c.report[column(1)];
            match report.status {
                ParameterStatus::Held {
                    reason: HoldReason::NegativeCompliance { value, .. },
                    ..
                } if negative => assert!(value < 0.0),
                ParameterStatus::Held {
                    reason: HoldReason::Implausible { bound, .. },
                    ..
                } if !negative => assert_eq!(bound, 100.0),
                status => panic!("{value}: {status:?}"),
            }
            assert!(
                report.reason().contains("µrad/(N·m)"),
                "{}",
                report.reason()
            );
            assert_eq!(c.value(Parameter::Compliance { joint: 1 }), 0.0);
        }
    }

    /// Noise-free data from a known model: the identifiable deviations come back to 1e-6.
    fn recovers(robot: &Robot, samples: usize) -> f64 {
        let q = poses(robot, samples, 1);
        let mut largest: f64 = 0.0;
        for orientation in [true, false] {
            // Which parameters these poses identify: a fit of error-free data.
            let p = Parameter::all_of(robot).len();
            let zero = simulate(robot, &DVector::zeros(p), &q, orientation, 0.0, 0);
            let structure = identify(robot, &zero, &CalibrateOptions::default()).unwrap();
            let truth = deviations_on(&structure.parameters, &columns_of(&structure), 2);
            let samples = simulate(robot, &truth, &q, orientation, 0.0, 0);
            let c = identify(robot, &samples, &CalibrateOptions::default()).unwrap();
            assert!(c.converged, "not converged after {}", c.iterations);
            assert_eq!(c.identified, structure.identified);
            for i in 0..p {
                let gap = (c.deviations[i] - truth[i]).abs();
                largest = largest.max(gap);
                assert!(
                    gap < 1e-6,
                    "{}, orientation {orientation}, {}: identified {} true {}",
                    robot.name,
                    c.parameters[i],
                    c.deviations[i],
                    truth[i]
                );
            }
            assert!(c.position_rms_mm < 1e-9, "{}", c.position_rms_mm);
            assert!(c.initial_position_rms_mm > 0.1);
            // Predictions at unseen poses equal the simulated errors.
            let model = Model::new(robot, false);
            let truth_state = model.state(&truth).unwrap();
            for q in poses(robot, 10, 9) {
                let expected = model.error(&truth_state, &q);
                let (got, _) = c.predict_error(&q);
                for a in 0..3 {
                    assert!((expected[a] - got[a]).abs() < 1e-6);
                }
            }
            println!(
                "{}: orientation {orientation}: {} of {} parameters identified, largest \
                 recovery error {largest:.2e}",
                robot.name,
                c.identified.len(),
                p
            );
        }
        largest
    }

    #[test]
    fn recovers_known_deviations_from_noise_free_data() {
        recovers(&kr150(), 60);
    }

    /// The seven-axis iiwa read from URDF, parameterised by origin perturbations and
    /// offsets: every parameter the data identify comes back to 1e-6 (mm, rad).
    #[test]
    fn recovers_a_seven_axis_urdf_robot_from_noise_free_data() {
        let largest = recovers(&iiwa(), 120);
        println!("iiwa 14 (URDF): largest recovery error {largest:.2e} (mm or rad)");
    }

    /// The standard errors are what repeated noisy measurements spread the estimates by:
    /// over 40 noise draws, each parameter's empirical spread agrees with the mean reported
    /// standard error to within 35 %.
    #[test]
    fn standard_errors_match_the_spread_over_noise_draws() {
        let robot = kr150();
        let q = poses(&robot, 60, 4);
        let p = Parameter::all_of(&robot).len();
        let zero = simulate(&robot, &DVector::zeros(p), &q, false, 0.0, 0);
        // Every parameter the pivoting keeps, trusted or not: the spread of each is compared.
        let options = CalibrateOptions {
            hold_untrustworthy: false,
            ..CalibrateOptions::default()
        };
        let structure = identify(&robot, &zero, &options).unwrap();
        let truth = deviations_on(&structure.parameters, &columns_of(&structure), 5);
        let draws = 40;
        let mut estimates = Vec::new();
        let mut reported = DVector::<f64>::zeros(p);
        for seed in 0..draws {
            let samples = simulate(&robot, &truth, &q, false, 0.02, 100 + seed);
            let c = identify(&robot, &samples, &options).unwrap();
            assert_eq!(c.identified, structure.identified);
            assert!(
                (c.residual_sigma_mm - 0.02).abs() < 0.005,
                "{}",
                c.residual_sigma_mm
            );
            for k in 0..p {
                reported[k] += c.standard_errors[k].unwrap_or(0.0) / draws as f64;
            }
            estimates.push(c.deviations);
        }
        for k in columns_of(&structure) {
            let mean = estimates.iter().map(|e| e[k]).sum::<f64>() / draws as f64;
            let spread = (estimates.iter().map(|e| (e[k] - mean).powi(2)).sum::<f64>()
                / (draws - 1) as f64)
                .sqrt();
            let ratio = spread / reported[k];
            assert!(
                (0.65..1.35).contains(&ratio),
                "{}: spread {spread:.3e}, reported {:.3e}",
                structure.parameters[k],
                reported[k]
            );
        }
        // Unidentified parameters have none.
        for (parameter, _) in &structure.unidentifiable {
            assert_eq!(structure.standard_error(*parameter), None);
        }
    }

    /// The trust rules (module docs, "Trust"): with noise and no deviation at all, the
    /// parameters whose estimates are noise are held at nominal as undetermined, every one
    /// left passes the rules, and the reports carry value, SE and strongest correlation.
    /// A deviation far beyond its plausible bound is held as implausible. Of exactly
    /// redundant joint and tool parameters, the tool's is kept.
    #[test]
    fn untrustworthy_parameters_are_held_with_a_reason() {
        let robot = kr150();
        let q = poses(&robot, 80, 6);
        let p = Parameter::all_of(&robot).len();
        let truth = {
            let zero = simulate(&robot, &DVector::zeros(p), &q, false, 0.0, 0);
            let structure = identify(&robot, &zero, &CalibrateOptions::default()).unwrap();
            deviations_on(&structure.parameters, &columns_of(&structure), 8)
        };
        // Half of the deviations zero, so that noise alone makes their estimates.
        let mut sparse = truth.clone();
        for c in (0..p).step_by(2) {
            sparse[c] = 0.0;
        }
        let samples = simulate(&robot, &sparse, &q, false, 0.05, 11);
        let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
        let held = c.held();
        assert!(!held.is_empty());
        for r in &held {
            let ParameterStatus::Held { estimate, reason } = r.status else {
                unreachable!()
            };
            let HoldReason::Undetermined {
                value,
                standard_error,
            } = reason
            else {
                panic!("{}: {reason:?}", r.parameter)
            };
            assert_eq!(value, estimate);
            assert!(value.abs() <= 3.0 * standard_error);
            assert_eq!(c.value(r.parameter), 0.0);
            assert!(r.reason().starts_with("undetermined"), "{}", r.reason());
        }
        for r in &c.report {
            if r.status == ParameterStatus::Identified {
                let se = r.standard_error.unwrap();
                assert!(r.value.abs() > 3.0 * se || se <= r.parameter.negligible_standard_error());
                assert!(r.value.abs() <= r.parameter.plausible_bound());
                let (partner, rho) = r.strongest_correlation.unwrap();
                assert_ne!(partner, r.parameter);
                assert!(rho.abs() <= 1.0 + 1e-9);
                assert!(c.identified.contains(&r.parameter));
            }
        }
        // The held parameters' deviations were zero in truth: holding them loses nothing,
        // the fit leaves the noise (RMS norm √3 σ).
        let noise_rms = 0.05 * 3f64.sqrt();
        assert!(
            c.position_rms_mm < 1.05 * noise_rms,
            "{}",
            c.position_rms_mm
        );

        // A joint angle 10° off: implausible, held, and the reason says so.
        let theta2 = Parameter::Mdh {
            joint: 1,
            parameter: MdhParameter::Theta,
        };
        let column = c.parameters.iter().position(|p| *p == theta2).unwrap();
        let mut absurd = truth.clone();
        absurd[column] = 10f64.to_radians();
        let samples = simulate(&robot, &absurd, &q, false, 0.0, 0);
        let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
        let report = &c.report[column];
        assert!(
            matches!(
                report.status,
                ParameterStatus::Held {
                    reason: HoldReason::Implausible { .. },
                    ..
                }
            ),
            "{report:?}"
        );
        assert!(
            report.reason().contains("beyond ±87.2665 mrad"),
            "{}",
            report.reason()
        );
        assert_eq!(c.value(theta2), 0.0);

        // On the UR5, Δd of the last joint moves the TCP exactly as the tool's z does: the
        // tool keeps it.
        let robot = Robot::load(shipped_robot_path("ur5")).unwrap();
        let q = poses(&robot, 80, 6);
        let samples = simulate(&robot, &DVector::zeros(42), &q, false, 0.0, 0);
        let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
        assert!(c.identified.contains(&Parameter::ToolTranslation(2)));
        let d6 = Parameter::Mdh {
            joint: 5,
            parameter: MdhParameter::D,
        };
        let status = c.report[c.parameters.iter().position(|p| *p == d6).unwrap()].status;
        assert!(
            matches!(
                status,
                ParameterStatus::Unidentifiable {
                    most_like: Some(Parameter::ToolTranslation(2)),
                    ..
                }
            ),
            "{status:?}"
        );
    }

    /// Known redundancies are found: Δd1 moves the TCP exactly like the base z
    /// translation, Δθ1 like the base rotation about z; without orientation data the tool
    /// rotation cannot be seen at all.
    #[test]
    fn structural_redundancies_are_reported_unidentifiable() {
        let robot = kr150();
        let q = poses(&robot, 60, 4);
        let samples = simulate(&robot, &DVector::zeros(42), &q, false, 0.0, 0);
        let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
        let dropped: Vec<Parameter> = c.unidentifiable.iter().map(|(p, _)| *p).collect();
        for axis in 0..3 {
            assert!(dropped.contains(&Parameter::ToolRotation(axis)));
        }
        let either = |a: Parameter, b: Parameter| dropped.contains(&a) || dropped.contains(&b);
        let d1 = Parameter::Mdh {
            joint: 0,
            parameter: MdhParameter::D,
        };
        let theta1 = Parameter::Mdh {
            joint: 0,
            parameter: MdhParameter::Theta,
        };
        assert!(either(d1, Parameter::BaseTranslation(2)));
        assert!(either(theta1, Parameter::BaseRotation(2)));
        assert!(c.condition_number.is_finite() && c.condition_number < 1e4);

        // A URDF chain: the rotation of an origin about its joint's own axis (z for every
        // iiwa joint) is the joint's offset, and of the two equal columns the offset comes
        // first: the rotation is never the one kept. The rest of the redundancies (an
        // offset is also a constant turn between two joints, which the next origin's
        // perturbation holds) leave the minimal count.
        let robot = iiwa();
        let q = poses(&robot, 120, 4);
        let p = Parameter::all_of(&robot).len();
        let samples = simulate(&robot, &DVector::zeros(p), &q, true, 0.0, 0);
        let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
        for joint in 1..7 {
            assert!(!c
                .identified
                .contains(&Parameter::OriginRotation { joint, axis: 2 }));
        }
        // 4 per revolute joint and 6 for base and tool: the minimal parameter count of a
        // serial chain measured in position and orientation (Everett, Driels, Mooring).
        assert_eq!(c.identified.len(), 4 * 7 + 6, "{:?}", c.identified);
        assert_eq!(c.unidentifiable.len(), p - 34);
        assert!(c.condition_number.is_finite() && c.condition_number < 1e4);
        // Without orientation the tool's rotation is not seen (three fewer), and since the
        // measured point, the flange centre, lies on axis 7, which way that axis points is
        // not seen either (two fewer).
        let samples = simulate(&robot, &DVector::zeros(p), &q, false, 0.0, 0);
        let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
        assert_eq!(c.identified.len(), 4 * 7 + 6 - 3 - 2, "{:?}", c.identified);
    }

    /// Data that excite almost nothing are refused, and data without joints too.
    #[test]
    fn refuses_data_that_cannot_identify_the_model() {
        let robot = kr150();
        // Only joint 1 turns: a circle, far too little for the parameters it excites
        // when there are only four samples.
        let q: Vec<Vec<f64>> = (0..4)
            .map(|i| vec![0.2 * f64::from(i), -1.0, 1.2, 0.0, 0.5, 0.0])
            .collect();
        let samples = simulate(&robot, &DVector::zeros(42), &q, false, 0.0, 0);
        let error = identify(&robot, &samples, &CalibrateOptions::default()).unwrap_err();
        assert!(
            matches!(
                error,
                CalibrateError::TooFewMeasurements {
                    measurements: 12,
                    ..
                }
            ),
            "{error}"
        );
        let mut no_joints = samples.clone();
        no_joints.joints = None;
        assert_eq!(
            identify(&robot, &no_joints, &CalibrateOptions::default()).unwrap_err(),
            CalibrateError::MissingJoints
        );
        // Joint values of another robot.
        let error = identify(&iiwa(), &samples, &CalibrateOptions::default()).unwrap_err();
        assert_eq!(
            error,
            CalibrateError::JointCount {
                robot: 7,
                samples: 6
            }
        );
        // Many samples on that circle: identification runs, but a circular arc has only
        // seven degrees of freedom (centre 3, axis 2, radius 1, phase 1), so at most seven
        // parameters are identified and the rest are reported unidentifiable.
        let q: Vec<Vec<f64>> = (0..40)
            .map(|i| vec![0.05 * f64::from(i), -1.0, 1.2, 0.0, 0.5, 0.0])
            .collect();
        let samples = simulate(&robot, &DVector::zeros(42), &q, false, 0.0, 0);
        let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
        assert!(c.identified.len() <= 7, "{:?}", c.identified);
        assert_eq!(c.unidentifiable.len(), 42 - c.identified.len());
        let dropped = |p| c.unidentifiable.iter().any(|(q, _)| *q == p);
        // Joint 2 never turns: its angle offset cannot be told from the base rotation.
        assert!(dropped(Parameter::Mdh {
            joint: 1,
            parameter: MdhParameter::Theta
        }));
    }

    /// The stored model reproduces the identification's predictions through the runtime's
    /// model, and the residuals it leaves are the identification's.
    #[test]
    fn stored_model_agrees_with_the_identification() {
        let dir = shipped_robot_path("kr150-2");
        let robot = Robot::load(&dir).unwrap();
        let samples = adwi_samples::read_samples(
            &dir.parent().unwrap().join("samples.csv"),
            &adwi_samples::ColumnMap::default(),
        )
        .unwrap();
        let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
        let model = c.prepared_model();
        let joints = samples.joints.as_ref().unwrap();
        for q in joints.rows().step_by(37) {
            assert_eq!(model.error(q).unwrap(), c.predict_error(q));
        }
        let residual = adwi_compile::hybrid::residual_samples(&samples, &model).unwrap();
        let rms = (residual
            .error_mm
            .iter()
            .map(|e| e.iter().map(|v| v * v).sum::<f64>())
            .sum::<f64>()
            / residual.len() as f64)
            .sqrt();
        assert!(
            (rms - c.position_rms_mm).abs() < 1e-9,
            "{rms} vs {}",
            c.position_rms_mm
        );

        // With compliance identified, the stored calibrated chain carries it and predicts
        // the same deflected poses.
        let robot = ur5();
        let model = Model::new(&robot, true);
        let q = poses(&robot, 80, 12);
        let all: Vec<usize> = (0..model.len()).collect();
        let truth = compliant_deviations_on(&model.parameters, &all, 4);
        let samples = simulate_model(&model, &truth, &q, false, 0.01, 5);
        let options = CalibrateOptions {
            compliance: true,
            ..CalibrateOptions::default()
        };
        let c = identify(&robot, &samples, &options).unwrap();
        let model = c.prepared_model();
        let stored = model.calibrated().compliance.unwrap();
        for joint in 1..3 {
            let identified = c.value(Parameter::Compliance { joint });
            assert!(identified > 0.0);
            assert_eq!(stored.compliance[joint], identified * URAD_PER_NM);
        }
        for q in &q {
            assert_eq!(model.error(q).unwrap(), c.predict_error(q));
        }
        let residual = adwi_compile::hybrid::residual_samples(&samples, &model).unwrap();
        let rms = (residual
            .error_mm
            .iter()
            .map(|e| e.iter().map(|v| v * v).sum::<f64>())
            .sum::<f64>()
            / residual.len() as f64)
            .sqrt();
        assert!((rms - c.position_rms_mm).abs() < 1e-9);
    }

    /// A seven-joint robot is identified and stored as its chains.
    #[test]
    fn seven_joint_robots_are_stored_as_chains() {
        let robot = iiwa();
        let q = poses(&robot, 60, 6);
        let p = Parameter::all_of(&robot).len();
        let x = deviations_on(&Parameter::all_of(&robot), &[0, 3, 9], 1);
        let samples = simulate(&robot, &x, &q, true, 0.0, 0);
        let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
        assert_eq!(c.parameters.len(), p);
        let model = c.prepared_model();
        assert_eq!(model.joint_count(), 7);
        for q in &q[..5] {
            assert_eq!(model.error(q).unwrap(), c.predict_error(q));
        }
    }

    /// The calibrated robot written as a robot file and as URDF, read again, has the
    /// calibrated forward kinematics to 1e-9 mm: for an MD-H robot and a URDF chain.
    #[test]
    fn written_calibrated_robots_reproduce_the_calibrated_model() {
        for robot in [
            kr150(),
            iiwa(),
            Robot::load(shipped_file("ur10", "robot.urdf")).unwrap(),
        ] {
            let q = poses(&robot, 80, 7);
            let p = Parameter::all_of(&robot).len();
            let all: Vec<usize> = (0..p).collect();
            let truth = deviations_on(&Parameter::all_of(&robot), &all, 8);
            let samples = simulate(&robot, &truth, &q, true, 0.0, 0);
            let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
            let calibrated = c.calibrated_robot();
            let dir = tempfile_dir();
            let toml_path = dir.join(format!("{}.toml", robot.joint_count()));
            std::fs::write(&toml_path, calibrated.to_toml_string(&["test".into()])).unwrap();
            let urdf_path = dir.join(format!("{}.urdf", robot.joint_count()));
            std::fs::write(
                &urdf_path,
                calibrated.to_urdf_string(&["test".into()]).unwrap(),
            )
            .unwrap();
            let from_toml = Robot::load(&toml_path).unwrap();
            let from_urdf = Robot::load_with(
                &urdf_path,
                &crate::urdf::LinkNames {
                    base_link: None,
                    tip_link: Some(crate::urdf::TCP_LINK.into()),
                },
            )
            .unwrap();
            let mut largest: f64 = 0.0;
            for q in poses(&robot, 200, 10) {
                let want = calibrated.tcp_pose(&q);
                for back in [&from_toml, &from_urdf] {
                    let got = back.tcp_pose(&q);
                    largest =
                        largest.max((got.translation.vector - want.translation.vector).norm());
                    assert!(got.rotation.angle_to(&want.rotation) < 1e-12);
                }
            }
            println!(
                "{}: written calibrated robot files agree to {largest:.2e} mm",
                robot.name
            );
            assert!(largest < 1e-9, "{}: {largest} mm", robot.name);
            std::fs::remove_dir_all(dir).unwrap();
        }

        // With compliance identified, the robot file carries it: read again, it deflects
        // as the calibrated model does, and so does the file read a second time.
        for robot in [ur5(), iiwa()] {
            let model = Model::new(&robot, true);
            let q = poses(&robot, 120, 7);
            let all: Vec<usize> = (0..model.len()).collect();
            let truth = compliant_deviations_on(&model.parameters, &all, 8);
            let samples = simulate_model(&model, &truth, &q, false, 0.0, 0);
            let options = CalibrateOptions {
                compliance: true,
                ..CalibrateOptions::default()
            };
            let c = identify(&robot, &samples, &options).unwrap();
            let calibrated = c.calibrated_robot();
            let text = calibrated.to_toml_string(&["test".into()]);
            assert!(text.contains("compliance_urad_per_nm = "), "{text}");
            let back = Robot::from_toml_str(&text).unwrap();
            assert_eq!(
                back.gravity_model().unwrap().compliance,
                calibrated.gravity_model().unwrap().compliance
            );
            let mut largest: f64 = 0.0;
            for q in poses(&robot, 200, 10) {
                let want = loaded(calibrated, &q);
                let got = loaded(&back, &q);
                largest =
                    largest.max((vector(got.translation_mm) - vector(want.translation_mm)).norm());
                // The deflection is there: the loaded pose is not the commanded one.
                let still = calibrated.tcp_transform(&q);
                assert!((vector(still.translation_mm) - vector(want.translation_mm)).norm() > 1e-3);
            }
            println!(
                "{}: written calibrated robot file with compliances agrees to {largest:.2e} mm",
                robot.name
            );
            assert!(largest < 1e-9, "{}: {largest} mm", robot.name);
            // A calibration from that file starts from its compliances: errors that are
            // the deflection alone are what its nominal model already predicts.
            let mut deflections = samples.clone();
            for (i, q) in q.iter().enumerate() {
                let e = transform_pose_error(&back.tcp_transform(q), &loaded(&back, q));
                deflections.error_mm[i] = [e[0], e[1], e[2]];
            }
            let again = identify(&back, &deflections, &CalibrateOptions::default()).unwrap();
            assert!(
                again.initial_position_rms_mm < 1e-9,
                "{}",
                again.initial_position_rms_mm
            );
        }
    }

    /// A fresh folder under the system's temporary folder.
    fn tempfile_dir() -> std::path::PathBuf {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let dir = std::env::temp_dir().join(format!(
            "adwi-robot-test-{}-{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }
}
