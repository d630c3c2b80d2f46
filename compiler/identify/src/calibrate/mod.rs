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
//!   MD-H row, mm and rad, as in [`adwi_robot::error_model`];
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
//! (`compliance_urad_per_nm`, [`adwi_robot::model`]), the nominal model of where the arm
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
//! model's ([`adwi_robot::error_model::mdh_screws`]); an offset turns (or slides) about its
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

mod model;
mod parameters;
mod solver;
#[cfg(test)]
mod tests;
mod trust;

pub use parameters::{Parameter, MAX_PLAUSIBLE_COMPLIANCE_URAD_PER_NM};
pub use trust::{HoldReason, ParameterReport, ParameterStatus};

use adwi_runtime::chain::{Chain, JointKind};
use adwi_runtime::joint_terms::JointTerms;
use adwi_runtime::model::PreparedModel;
use nalgebra::{DMatrix, DVector};

use adwi_robot::error_model::transform_pose_error;
use adwi_robot::model::Robot;
use adwi_robot::plausible::{check, number, Quantity};
use adwi_samples::SampleSet;

use model::{loaded_with_terms, Model};
use solver::{Measurement, Problem};
use trust::Assessment;

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
    /// Stop when an accepted step lowers the cost by less than this fraction of it. The
    /// default, 1e-12, is above the cost's own rounding: the residuals are differences of
    /// poses metres from the base, computed to about 1e-13 mm, so that below it steps
    /// "lower" the cost by rounding alone (decreases of 1e-13 of it, iteration after
    /// iteration), and a step that lowers it by 1e-12 moves the poses by nanometres.
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
    /// Identify each revolute joint's joint-space terms up to this harmonic (0: none, 1:
    /// `sin q, cos q`, 2: and `sin 2q, cos 2q`; module docs, "Joint-space terms"); each
    /// kept only where the likelihood supports it (BIC).
    pub harmonics: u8,
}

impl Default for CalibrateOptions {
    fn default() -> Self {
        CalibrateOptions {
            rank_tolerance: 1e-3,
            orientation_weight_mm_per_rad: 1000.0,
            max_iterations: 100,
            relative_cost_tolerance: 1e-12,
            hold_untrustworthy: true,
            significance: 3.0,
            compliance: false,
            harmonics: 0,
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
    /// no error): the model's Jacobian at the samples is zero.
    #[error("the samples identify no kinematic parameter: their poses do not vary")]
    NothingIdentifiable,
    /// A value is NaN or infinite.
    #[error("sample {index}{}: a joint value or measured error is not finite", line_of(*line))]
    NonFinite {
        /// The sample's index.
        index: usize,
        /// Its source line, when known.
        line: Option<u64>,
    },
    /// A sample's value is beyond what any robot's is: a joint turned more than ten turns
    /// (or slid more than 1 km), an error no kinematic model explains.
    #[error("sample {index}{}: {what}", line_of(*line))]
    ImplausibleSample {
        /// The sample's index.
        index: usize,
        /// Its source line, when known.
        line: Option<u64>,
        /// The value, what it is and the bound it crosses.
        what: String,
    },
    /// The model's prediction or its Jacobian at a sample is not finite, though every
    /// input lies in its range: an input combination no robot has. Found before iterating.
    #[error(
        "the model of {robot} is not finite at sample {index}{} ({what}): its inputs, though \
         each in range, make no robot; check the robot file's lengths, masses and compliances",
        line_of(*line)
    )]
    NonFiniteModel {
        /// The robot.
        robot: String,
        /// The sample's index.
        index: usize,
        /// Its source line, when known.
        line: Option<u64>,
        /// What is not finite: the prediction, or the column of which parameter.
        what: String,
    },
    /// An identified value is not finite: nothing is reported as a calibration.
    #[error("the identification of {robot} gives a non-finite {what}")]
    NonFiniteResult {
        /// The robot.
        robot: String,
        /// Which value.
        what: &'static str,
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

/// `, line L` for a known source line.
fn line_of(line: Option<u64>) -> String {
    line.map(|l| format!(" (line {l})")).unwrap_or_default()
}

/// The largest position error a sample may have for identification, mm: no plausible
/// deviation of a robot's geometry, tool or base registration ([`Parameter::plausible_bound`])
/// moves its TCP a metre; an error that large is a pose measured in another frame (a
/// tracker's: see [`crate::measured`]) or in another unit.
pub const MAX_PLAUSIBLE_ERROR_MM: f64 = 1000.0;

/// The largest orientation error a sample may have for identification, rad (57°), for
/// the same reason.
pub const MAX_PLAUSIBLE_ROTATION_ERROR_RAD: f64 = 1.0;

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
    joint_terms: JointTerms,
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
        let e = transform_pose_error(
            &self.nominal.tcp_transform(q),
            &loaded_with_terms(&self.calibrated, &self.joint_terms, q),
        );
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
            .with_joint_terms(self.joint_terms)
            .expect("identified terms are finite, plausible and on revolute joints")
    }

    /// The identified joint-space terms ([`JointTerms::NONE`] when none was identified or
    /// asked for; module docs, "Joint-space terms"). A robot file cannot hold them: the
    /// calibrated robot ([`Self::calibrated_robot`]) is the model without them, the
    /// hybrid table's model part ([`Self::prepared_model`]) the model with them.
    pub fn joint_terms(&self) -> &JointTerms {
        &self.joint_terms
    }
}

/// Identifies the kinematic model of `robot` from `samples` (which need joint values, one
/// per joint; their orientation errors are used when present). See the module docs for the
/// model and method.
///
/// # Errors
///
/// [`CalibrateError::MissingJoints`] without joint values, [`CalibrateError::JointCount`]
/// when the samples' joint count is not the robot's, [`CalibrateError::NonFinite`] for a
/// non-finite value, [`CalibrateError::ImplausibleSample`] for a joint value or error
/// beyond any robot's ([`MAX_PLAUSIBLE_ERROR_MM`]), [`CalibrateError::NonFiniteModel`]
/// when the model is not finite at a sample (checked before iterating),
/// [`CalibrateError::NonFiniteResult`] for a non-finite result (never returned as a
/// calibration), [`CalibrateError::NothingIdentifiable`] when the poses do not vary,
/// [`CalibrateError::TooFewMeasurements`] when the samples are too few for the parameters
/// they excite, [`CalibrateError::InvalidOption`] for options out of range,
/// [`CalibrateError::InvalidModel`] when the identified model is not a robot.
pub fn identify(
    robot: &Robot,
    samples: &SampleSet,
    options: &CalibrateOptions,
) -> Result<Calibration, CalibrateError> {
    check_options(robot, options)?;
    let problem = problem_of(robot, samples, options)?;
    let start = Linearised::at_nominal(&problem, robot, samples)?;
    let initial_position_rms_mm = start.position_rms_mm;
    // Fit, assess, hold the least trustworthy parameter at nominal, fit again (module
    // docs, "Trust").
    let file_values = problem.model.file_values();
    let (fit, held) = fit_holding_untrustworthy(&problem, &start, &file_values, options)?;
    let parameters = &problem.model.parameters;
    let report = parameter_report(parameters, &fit, held, &file_values, options);
    let mut standard_errors = vec![None; problem.model.len()];
    for &c in &fit.kept {
        standard_errors[c] = report[c].standard_error;
    }
    let orientation_rms_rad = samples
        .rotation_error_rad
        .as_ref()
        .map(|_| orientation_rms_rad(&problem, &fit));
    let position_rms_mm = problem.position_rms(&fit.r);
    let checks = [
        ("position RMS", position_rms_mm),
        ("initial position RMS", initial_position_rms_mm),
        ("residual σ", fit.residual_sigma_mm),
        ("orientation RMS", orientation_rms_rad.unwrap_or(0.0)),
    ];
    let non_finite = checks
        .iter()
        .find(|(_, v)| !v.is_finite())
        .map(|(what, _)| *what)
        .or_else(|| (!fit.x.iter().all(|v| v.is_finite())).then_some("parameter value"))
        .or_else(|| {
            (!standard_errors.iter().flatten().all(|v| v.is_finite())).then_some("standard error")
        });
    if let Some(what) = non_finite {
        return Err(CalibrateError::NonFiniteResult {
            robot: robot.name.clone(),
            what,
        });
    }
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
        position_rms_mm,
        orientation_rms_rad,
        residual_sigma_mm: fit.residual_sigma_mm,
        iterations: fit.iterations,
        converged: fit.converged,
        deviations: fit.x,
        nominal: robot.clone(),
        joint_terms: with_ranges(fit.state.terms, &problem.measurements),
        calibrated: fit.state.robot,
    })
}

/// The options within their ranges, and link masses for a compliance.
fn check_options(robot: &Robot, options: &CalibrateOptions) -> Result<(), CalibrateError> {
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
    if options.harmonics > 2 {
        return Err(CalibrateError::InvalidOption {
            name: "harmonics",
            reason: "must be 0, 1 or 2",
        });
    }
    if options.compliance && robot.gravity_model().is_none() {
        return Err(CalibrateError::NoLinkMasses {
            robot: robot.name.clone(),
        });
    }
    Ok(())
}

/// The least-squares problem of `samples`: one measurement per sample (its joint values,
/// one per joint of the robot), three rows each, six with orientation errors.
fn problem_of(
    robot: &Robot,
    samples: &SampleSet,
    options: &CalibrateOptions,
) -> Result<Problem, CalibrateError> {
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
        .map(|i| measurement(robot, samples, i))
        .collect::<Result<_, _>>()?;
    Ok(Problem {
        model: Model::new(robot, options.compliance, options.harmonics),
        measurements,
        rows_per_sample: if samples.rotation_error_rad.is_some() {
            6
        } else {
            3
        },
        weight: options.orientation_weight_mm_per_rad,
    })
}

/// The problem linearised at the nominal model, where every fit starts.
struct Linearised {
    /// The Jacobian's R factor ([`solver::r_factor`]): what selecting its columns needs.
    jacobian_factor: DMatrix<f64>,
    /// Each column's scale to unit norm (0 for a column of nothing).
    scales: Vec<f64>,
    /// The position RMS before any fit, mm.
    position_rms_mm: f64,
}

impl Linearised {
    /// The nominal model's residuals and Jacobian, every value finite, some column not
    /// nothing.
    fn at_nominal(
        problem: &Problem,
        robot: &Robot,
        samples: &SampleSet,
    ) -> Result<Linearised, CalibrateError> {
        let p = problem.model.len();
        let nominal_x = DVector::zeros(p);
        let nominal_state = problem.model.state(&nominal_x)?;
        let (r0, j0) = problem.linearise(&nominal_x, &nominal_state);
        if let Some((row, column)) = first_non_finite(&r0, &j0) {
            let index = row / problem.rows_per_sample;
            return Err(CalibrateError::NonFiniteModel {
                robot: robot.name.clone(),
                index,
                line: samples.lines.get(index).copied(),
                what: match column {
                    None => "the predicted error".into(),
                    Some(c) => format!("the column of {}", problem.model.parameters[c]),
                },
            });
        }
        let column_norms: Vec<f64> = (0..p).map(|c| j0.column(c).norm()).collect();
        let largest = column_norms.iter().copied().fold(0.0, f64::max);
        if largest == 0.0 {
            return Err(CalibrateError::NothingIdentifiable);
        }
        // Unit columns: pivoting then compares parameters independently of their units. A
        // column of (numerically) nothing cannot be scaled and is unidentifiable outright.
        let scales: Vec<f64> = column_norms
            .iter()
            .map(|&n| if n > 1e-12 * largest { 1.0 / n } else { 0.0 })
            .collect();
        Ok(Linearised {
            position_rms_mm: problem.position_rms(&r0),
            jacobian_factor: solver::r_factor(&j0),
            scales,
        })
    }
}

/// Fits from the nominal model; with `hold_untrustworthy`, holds the least trustworthy
/// parameter at nominal and fits again until every kept one can be trusted. The fit, and
/// the parameters held with their assessment.
fn fit_holding_untrustworthy(
    problem: &Problem,
    start: &Linearised,
    file_values: &[f64],
    options: &CalibrateOptions,
) -> Result<(solver::Fit, Vec<(usize, Assessment)>), CalibrateError> {
    let mut held: Vec<(usize, Assessment)> = Vec::new();
    let mut x = DVector::zeros(problem.model.len());
    loop {
        let held_columns: Vec<usize> = held.iter().map(|(c, _)| *c).collect();
        let fit = problem.solve(
            &start.jacobian_factor,
            &start.scales,
            &held_columns,
            x,
            options,
        )?;
        if !options.hold_untrustworthy {
            return Ok((fit, held));
        }
        let worst = fit
            .kept
            .iter()
            .enumerate()
            .filter_map(|(k, &c)| {
                let a = fit.assess(
                    &problem.model.parameters,
                    file_values,
                    k,
                    options.significance,
                    fit.r.len(),
                );
                a.reason.is_some().then_some((c, a))
            })
            .max_by(|a, b| a.1.severity.total_cmp(&b.1.severity));
        match worst {
            Some((c, assessment)) => {
                held.push((c, assessment));
                x = fit.x.clone();
                x[c] = 0.0;
            }
            None => return Ok((fit, held)),
        }
    }
}

/// Every parameter's value, standard error, strongest correlation and status.
fn parameter_report(
    parameters: &[Parameter],
    fit: &solver::Fit,
    held: Vec<(usize, Assessment)>,
    file_values: &[f64],
    options: &CalibrateOptions,
) -> Vec<ParameterReport> {
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
        let a = fit.assess(
            parameters,
            file_values,
            k,
            options.significance,
            fit.r.len(),
        );
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
    report
}

/// The RMS of the fit's orientation residuals, rad.
fn orientation_rms_rad(problem: &Problem, fit: &solver::Fit) -> f64 {
    let sum: f64 = (0..problem.measurements.len())
        .map(|s| {
            fit.r
                .fixed_rows::<3>(s * problem.rows_per_sample + 3)
                .norm_squared()
        })
        .sum();
    (sum / problem.measurements.len() as f64).sqrt() / problem.weight
}

/// The identification's position Jacobians at the nominal model, for choosing poses to
/// measure: per joint vector a 3 × k block (position rows), over the k parameters that
/// the QR pivoting of [`identify`] keeps on all these poses together (at `rank_tolerance`),
/// each column scaled by the inverse of its norm over all poses, so that a design
/// criterion compares parameters independently of their units. The parameters are
/// returned in the blocks' column order.
///
/// # Errors
///
/// [`CalibrateError::JointCount`] for a joint vector of another length,
/// [`CalibrateError::InvalidModel`] for a robot the model cannot describe,
/// [`CalibrateError::NothingIdentifiable`] when the poses do not vary.
pub fn design_jacobians(
    robot: &Robot,
    joints: &[Vec<f64>],
    rank_tolerance: f64,
) -> Result<(Vec<Parameter>, Vec<DMatrix<f64>>), CalibrateError> {
    design_jacobians_scaled(robot, joints, rank_tolerance)
        .map(|(parameters, blocks, _)| (parameters, blocks))
}

/// The parameters, their position Jacobian blocks and each column's scale
/// ([`design_jacobians_scaled`]).
pub type ScaledDesign = (Vec<Parameter>, Vec<DMatrix<f64>>, Vec<f64>);

/// [`design_jacobians`], with each kept column's scale: a block's column is the physical
/// derivative (mm per mm, mm per rad) times its scale, so that a design can weigh the
/// parameters in their own units too.
///
/// # Errors
///
/// As [`design_jacobians`].
pub fn design_jacobians_scaled(
    robot: &Robot,
    joints: &[Vec<f64>],
    rank_tolerance: f64,
) -> Result<ScaledDesign, CalibrateError> {
    if let Some(q) = joints.iter().find(|q| q.len() != robot.joint_count()) {
        return Err(CalibrateError::JointCount {
            robot: robot.joint_count(),
            samples: q.len(),
        });
    }
    let model = Model::new(robot, false, 0);
    let x = DVector::zeros(model.len());
    let state = model.state(&x)?;
    let blocks: Vec<DMatrix<f64>> = joints
        .iter()
        .map(|q| model.jacobian(&x, &state, q).rows(0, 3).into_owned())
        .collect();
    let p = model.len();
    let mut stacked = DMatrix::zeros(3 * blocks.len(), p);
    for (k, b) in blocks.iter().enumerate() {
        stacked.rows_mut(3 * k, 3).copy_from(b);
    }
    let norms: Vec<f64> = (0..p).map(|c| stacked.column(c).norm()).collect();
    let largest = norms.iter().copied().fold(0.0, f64::max);
    if !(largest > 0.0 && largest.is_finite()) {
        return Err(CalibrateError::NothingIdentifiable);
    }
    let scales: Vec<f64> = norms
        .iter()
        .map(|&n| if n > 1e-12 * largest { 1.0 / n } else { 0.0 })
        .collect();
    for (c, s) in scales.iter().enumerate() {
        stacked.column_mut(c).scale_mut(*s);
    }
    let preferred: Vec<bool> = (0..p).map(|c| c >= model.tool_translation).collect();
    let (mut kept, _) =
        solver::pivot_columns(&solver::r_factor(&stacked), rank_tolerance, &preferred);
    kept.sort_unstable();
    let parameters = kept.iter().map(|&c| model.parameters[c]).collect();
    let blocks = blocks
        .iter()
        .map(|b| DMatrix::from_fn(3, kept.len(), |r, k| b[(r, kept[k])] * scales[kept[k]]))
        .collect();
    Ok((
        parameters,
        blocks,
        kept.iter().map(|&c| scales[c]).collect(),
    ))
}

/// `terms` with each joint's range the commanded angles of `measurements` span: beyond
/// it the terms are held at the nearer end ([`adwi_runtime::joint_terms`]), which changes
/// nothing at the measurements themselves.
fn with_ranges(mut terms: JointTerms, measurements: &[Measurement]) -> JointTerms {
    if terms.is_none() {
        return JointTerms::NONE;
    }
    for (j, range) in terms.range_rad.iter_mut().enumerate() {
        let angles = measurements.iter().filter_map(|m| m.q.get(j).copied());
        let (lo, hi) = angles.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
            (lo.min(q), hi.max(q))
        });
        if lo <= hi {
            *range = [lo, hi];
        }
    }
    terms
}

/// Sample `i` as a measurement, its values checked finite and plausible: joints within
/// ten turns (1 km when prismatic, [`adwi_robot::plausible`]), errors within
/// [`MAX_PLAUSIBLE_ERROR_MM`] and [`MAX_PLAUSIBLE_ROTATION_ERROR_RAD`].
fn measurement(
    robot: &Robot,
    samples: &SampleSet,
    i: usize,
) -> Result<Measurement, CalibrateError> {
    let joints = samples.joints.as_ref().expect("checked by the caller");
    let q = joints.row(i).to_vec();
    let error_mm = samples.error_mm[i];
    let rotation_error_rad = samples.rotation_error_rad.as_ref().map(|r| r[i]);
    let line = samples.lines.get(i).copied();
    let finite = q.iter().chain(&error_mm).all(|v| v.is_finite())
        && rotation_error_rad.is_none_or(|r| r.iter().all(|v| v.is_finite()));
    if !finite {
        return Err(CalibrateError::NonFinite { index: i, line });
    }
    let implausible = |what: String| CalibrateError::ImplausibleSample {
        index: i,
        line,
        what,
    };
    for (j, &value) in q.iter().enumerate() {
        let (shown, quantity) = match robot.joint_kind(j) {
            JointKind::Revolute => (value.to_degrees(), Quantity::JointValueDeg),
            JointKind::Prismatic => (value, Quantity::LengthMm),
        };
        check(shown, quantity, || format!("joint {}", j + 1))
            .map_err(|e| implausible(e.to_string()))?;
    }
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let error = norm(error_mm);
    if error > MAX_PLAUSIBLE_ERROR_MM {
        return Err(implausible(format!(
            "a position error of {} mm, more than the {MAX_PLAUSIBLE_ERROR_MM} mm any \
             calibration explains: are the measured poses in another frame (a tracker's) or \
             another unit?",
            number(error)
        )));
    }
    if let Some(r) = rotation_error_rad {
        let angle = norm(r);
        if angle > MAX_PLAUSIBLE_ROTATION_ERROR_RAD {
            return Err(implausible(format!(
                "an orientation error of {} rad, more than the \
                 {MAX_PLAUSIBLE_ROTATION_ERROR_RAD} rad any calibration explains: are the \
                 measured poses in another frame or convention?",
                number(angle)
            )));
        }
    }
    Ok(Measurement {
        nominal_tcp: robot.tcp_transform(&q),
        q,
        error_mm,
        rotation_error_rad,
    })
}

/// The first non-finite entry of the residuals `r` or the Jacobian `j`: its row, and its
/// column (`None` for a residual).
fn first_non_finite(r: &DVector<f64>, j: &DMatrix<f64>) -> Option<(usize, Option<usize>)> {
    if let Some(row) = r.iter().position(|v| !v.is_finite()) {
        return Some((row, None));
    }
    // Row by row, so that the first sample is found first.
    (0..j.nrows()).find_map(|row| {
        (0..j.ncols())
            .find(|&c| !j[(row, c)].is_finite())
            .map(|c| (row, Some(c)))
    })
}
