//! Model-based calibration: identifying a robot's kinematic deviations from measured samples.
//!
//! This is the classical alternative to the non-kinematic table: explain the measured errors
//! by a corrected kinematic model, then predict the error anywhere from that model. It is the
//! `kinematic` method of `tablec eval`, and the first stage of the `hybrid` method, which
//! interpolates only what the corrected model leaves unexplained.
//!
//! # The model
//!
//! The actual tool centre point (TCP) pose at commanded joint angles `q` is
//!
//! ```text
//! T_actual(q) = B · A_1(q_1; p_1 + Δ_1) · … · A_6(q_6; p_6 + Δ_6) · T_tool'
//! ```
//!
//! with 42 parameters ([`PARAMETER_COUNT`]), in this column order:
//!
//! - 30 MD-H deviations `(Δa, Δd, Δα, Δθ, Δβ)` per joint, mm and rad, as in
//!   [`crate::robot::error_model`];
//! - 3 tool translation deviations, mm, in the flange frame (added to the robot file's tool);
//! - 3 tool rotation deviations, a rotation vector in the flange frame, rad
//!   (`R_tool' = Exp(δ) · R_tool`);
//! - 3 base registration translations, mm, base frame (`B`'s translation);
//! - 3 base registration rotations, a rotation vector, rad (`B`'s rotation).
//!
//! The base registration is there because a laser tracker's frame is registered to the
//! robot's base by a measurement of its own, whose error is a rigid transform of every
//! sample; the tool offset because the reflector never sits exactly where the tool file says.
//!
//! The predicted error is `T_actual(q)` against the *nominal* model `T_nominal(q)`, exactly
//! (no linearisation): position `p_actual − p_nominal` (mm) and orientation
//! `log(R_actual · R_nominalᵀ)` (rad), both in the base frame, as samples record them.
//!
//! # Identification
//!
//! Levenberg–Marquardt on the residuals `measured error − predicted error` of every sample
//! (3 position rows, and 3 orientation rows when the samples carry orientation errors,
//! weighted by [`CalibrateOptions::orientation_weight_mm_per_rad`]). The Jacobian is
//! analytic: the MD-H columns are the error model's screws ([`pose_error_jacobian`]) at the
//! current parameters, and the tool and base columns are screws of their own. Rotations of
//! the tool and base are updated multiplicatively (`R ← Exp(δ) · R`), so their Jacobian is
//! exact at every step.
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
//! choice independent of units (mm against rad).

use adwi_runtime::format::{joint_rows, rows_of};
use adwi_runtime::format::{KinematicModel, ModelParams};
use adwi_runtime::kinematics::{forward, MdhJoint, Transform};
use nalgebra::{DMatrix, DVector, Isometry3, Rotation3, SVector, Vector3};

use crate::error_model::{
    apply_deviations, deviations_from_vector, pose_error_jacobian, DeviationVector, MdhParameter,
    MDH_PARAMETER_COUNT, PARAMETERS_PER_JOINT,
};
use crate::model::{isometry_from_parts, isometry_from_transform, rotation_of};
use crate::{Robot, JOINT_COUNT};
use adwi_compile::pose::{orientation_error, rotation_from_vector, rotation_vector};
use adwi_compile::samples::SampleSet;

/// Identified parameters: 30 MD-H deviations, tool translation and rotation, base
/// translation and rotation (see the module docs for the order and units).
pub const PARAMETER_COUNT: usize = MDH_PARAMETER_COUNT + 12;

/// First column of the tool translation (mm, flange frame).
const TOOL_TRANSLATION: usize = MDH_PARAMETER_COUNT;
/// First column of the tool rotation (rad, flange frame).
const TOOL_ROTATION: usize = MDH_PARAMETER_COUNT + 3;
/// First column of the base translation (mm, base frame).
const BASE_TRANSLATION: usize = MDH_PARAMETER_COUNT + 6;
/// First column of the base rotation (rad, base frame).
const BASE_ROTATION: usize = MDH_PARAMETER_COUNT + 9;

/// The identified parameter vector, in the column order of the module docs (mm and rad).
pub type ParameterVector = SVector<f64, PARAMETER_COUNT>;

/// One identifiable quantity of the calibration model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Parameter {
    /// An MD-H parameter of joint `joint` (0-based).
    Mdh {
        /// Joint index, 0-based.
        joint: usize,
        /// Which parameter.
        #[serde(serialize_with = "serialize_mdh")]
        parameter: MdhParameter,
    },
    /// Tool translation along a flange axis (0 = x, 1 = y, 2 = z), mm.
    ToolTranslation(usize),
    /// Tool rotation about a flange axis, rad.
    ToolRotation(usize),
    /// Base registration translation along a base axis, mm.
    BaseTranslation(usize),
    /// Base registration rotation about a base axis, rad.
    BaseRotation(usize),
}

fn serialize_mdh<S: serde::Serializer>(p: &MdhParameter, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(mdh_name(*p))
}

fn mdh_name(p: MdhParameter) -> &'static str {
    match p {
        MdhParameter::A => "a",
        MdhParameter::D => "d",
        MdhParameter::Alpha => "alpha",
        MdhParameter::Theta => "theta",
        MdhParameter::Beta => "beta",
    }
}

impl Parameter {
    /// The parameter of column `column` (0 ..< [`PARAMETER_COUNT`]).
    ///
    /// # Panics
    ///
    /// For a column out of range.
    pub fn from_column(column: usize) -> Parameter {
        assert!(column < PARAMETER_COUNT, "column {column} out of range");
        match column {
            c if c < MDH_PARAMETER_COUNT => Parameter::Mdh {
                joint: c / PARAMETERS_PER_JOINT,
                parameter: MdhParameter::ALL[c % PARAMETERS_PER_JOINT],
            },
            c if c < TOOL_ROTATION => Parameter::ToolTranslation(c - TOOL_TRANSLATION),
            c if c < BASE_TRANSLATION => Parameter::ToolRotation(c - TOOL_ROTATION),
            c if c < BASE_ROTATION => Parameter::BaseTranslation(c - BASE_TRANSLATION),
            c => Parameter::BaseRotation(c - BASE_ROTATION),
        }
    }

    /// This parameter's column in the parameter vector.
    pub fn column(self) -> usize {
        match self {
            Parameter::Mdh { joint, parameter } => parameter.column(joint),
            Parameter::ToolTranslation(axis) => TOOL_TRANSLATION + axis,
            Parameter::ToolRotation(axis) => TOOL_ROTATION + axis,
            Parameter::BaseTranslation(axis) => BASE_TRANSLATION + axis,
            Parameter::BaseRotation(axis) => BASE_ROTATION + axis,
        }
    }

    /// Whether the parameter is a length (mm) rather than an angle (rad).
    pub fn is_length(self) -> bool {
        match self {
            Parameter::Mdh { parameter, .. } => {
                matches!(parameter, MdhParameter::A | MdhParameter::D)
            }
            Parameter::ToolTranslation(_) | Parameter::BaseTranslation(_) => true,
            Parameter::ToolRotation(_) | Parameter::BaseRotation(_) => false,
        }
    }
}

impl std::fmt::Display for Parameter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        const AXES: [&str; 3] = ["x", "y", "z"];
        match *self {
            Parameter::Mdh { joint, parameter } => {
                write!(f, "Δ{}{}", mdh_name(parameter), joint + 1)
            }
            Parameter::ToolTranslation(a) => write!(f, "tool {}", AXES[a]),
            Parameter::ToolRotation(a) => write!(f, "tool r{}", AXES[a]),
            Parameter::BaseTranslation(a) => write!(f, "base {}", AXES[a]),
            Parameter::BaseRotation(a) => write!(f, "base r{}", AXES[a]),
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
}

impl Default for CalibrateOptions {
    fn default() -> Self {
        CalibrateOptions {
            rank_tolerance: 1e-3,
            orientation_weight_mm_per_rad: 1000.0,
            max_iterations: 100,
            relative_cost_tolerance: 1e-14,
        }
    }
}

/// Why identification is impossible.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrateError {
    /// The samples carry no joint angles, so no kinematic model can be evaluated at them.
    #[error("the samples have no joint angles (columns j1..jn): a kinematic calibration needs the commanded joint angles of every sample")]
    MissingJoints,
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
}

/// A robot's identified model: what [`identify`] found and how well.
#[derive(Debug, Clone)]
pub struct Calibration {
    /// The identified parameters (mm and rad, module-doc order); zero where not identified.
    pub deviations: ParameterVector,
    /// The parameters that were identified, in pivot order (most independent first).
    pub identified: Vec<Parameter>,
    /// The parameters the data cannot separate from the identified ones, each with its
    /// independent fraction (pivot ratio) in the scaled Jacobian: 0 for an exact redundancy.
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
    /// Levenberg–Marquardt iterations made.
    pub iterations: u32,
    /// Whether the cost stopped decreasing before the iteration limit.
    pub converged: bool,
    model: Model,
}

impl Calibration {
    /// The predicted pose error at joint angles `q_rad`: the identified model's TCP pose
    /// against the nominal one, position (mm) and orientation (rotation vector, rad), base
    /// frame.
    ///
    /// # Panics
    ///
    /// When `q_rad` has fewer values than the robot has joints.
    pub fn predict_error(&self, q_rad: &[f64]) -> ([f64; 3], [f64; 3]) {
        self.model.error(&std::array::from_fn(|a| q_rad[a]))
    }

    /// The nominal and the identified model as a table stores them (a hybrid table's
    /// [`KinematicModel`]): plain MD-H rows, tool and base transforms. The nominal base
    /// is the identity; the identified one is the registration.
    ///
    /// [`adwi_runtime::model::model_error`] of this model equals [`Self::predict_error`]
    /// to rounding: both evaluate the same forward kinematics.
    pub fn kinematic_model(&self) -> KinematicModel {
        let m = &self.model;
        let nominal_tool = crate::model::transform_from_isometry(&m.nominal_tool);
        let t = &m.base_translation_mm;
        let base = crate::model::transform_from_parts([t.x, t.y, t.z], &m.base_rotation);
        KinematicModel {
            nominal: ModelParams {
                joints: joint_rows(&m.nominal_joints),
                tool: rows_of(&nominal_tool),
                base: rows_of(&Transform::IDENTITY),
            },
            calibrated: ModelParams {
                joints: joint_rows(&m.joints),
                tool: rows_of(&m.tool),
                base: rows_of(&base),
            },
        }
    }

    /// The identified MD-H deviations (Δa, Δd, Δα, Δθ, Δβ per joint).
    pub fn mdh_deviations(&self) -> DeviationVector {
        self.deviations
            .fixed_rows::<MDH_PARAMETER_COUNT>(0)
            .into_owned()
    }
}

/// The nominal robot and a parameter state, evaluated exactly.
#[derive(Debug, Clone)]
struct Model {
    nominal_joints: [MdhJoint; JOINT_COUNT],
    nominal_tool: Isometry3<f64>,
    joints: [MdhJoint; JOINT_COUNT],
    tool: Transform,
    base_rotation: Rotation3<f64>,
    base_translation_mm: Vector3<f64>,
}

impl Model {
    fn nominal(robot: &Robot) -> Model {
        Model {
            nominal_joints: robot.nominal_joints(),
            nominal_tool: robot.tool,
            joints: robot.nominal_joints(),
            tool: robot.tool_transform(),
            base_rotation: Rotation3::identity(),
            base_translation_mm: Vector3::zeros(),
        }
    }

    /// The state of parameter vector `x` (module-doc order).
    fn with_parameters(&self, x: &ParameterVector) -> Model {
        let mdh: DeviationVector = x.fixed_rows::<MDH_PARAMETER_COUNT>(0).into_owned();
        let joints = apply_deviations(&self.nominal_joints, &deviations_from_vector(&mdh));
        let t =
            self.nominal_tool.translation.vector + x.fixed_rows::<3>(TOOL_TRANSLATION).into_owned();
        let r = rotation_from_vector(three(x, TOOL_ROTATION))
            * self.nominal_tool.rotation.to_rotation_matrix();
        let tool = crate::model::transform_from_isometry(&isometry_from_parts([t.x, t.y, t.z], &r));
        Model {
            joints,
            tool,
            base_rotation: rotation_from_vector(three(x, BASE_ROTATION)),
            base_translation_mm: Vector3::from(three(x, BASE_TRANSLATION)),
            ..self.clone()
        }
    }

    fn nominal_pose(&self, q_rad: &[f64; JOINT_COUNT]) -> Isometry3<f64> {
        let tool = crate::model::transform_from_isometry(&self.nominal_tool);
        isometry_from_transform(&forward(&self.nominal_joints, &tool, q_rad))
    }

    /// The TCP in the robot's own base frame (before registration) and in the base frame.
    fn pose(&self, q_rad: &[f64; JOINT_COUNT]) -> (Transform, Vector3<f64>, Rotation3<f64>) {
        let robot_frame = forward(&self.joints, &self.tool, q_rad);
        let p = self.base_rotation * Vector3::from(robot_frame.translation_mm)
            + self.base_translation_mm;
        let r = self.base_rotation * rotation_of(&robot_frame);
        (robot_frame, p, r)
    }

    fn error(&self, q_rad: &[f64; JOINT_COUNT]) -> ([f64; 3], [f64; 3]) {
        let nominal = self.nominal_pose(q_rad);
        let (_, p, r) = self.pose(q_rad);
        let dp = p - nominal.translation.vector;
        let dr = orientation_error(&nominal.rotation.to_rotation_matrix(), &r);
        ([dp.x, dp.y, dp.z], dr)
    }

    /// The 6 × 42 Jacobian of the base-frame pose error with respect to the parameters at
    /// this state: additive for MD-H and tool translation, multiplicative (`Exp(δ) · R`)
    /// for the tool and base rotations.
    fn jacobian(&self, q_rad: &[f64; JOINT_COUNT]) -> nalgebra::SMatrix<f64, 6, PARAMETER_COUNT> {
        let mut j = nalgebra::SMatrix::<f64, 6, PARAMETER_COUNT>::zeros();
        let mdh = pose_error_jacobian(&self.joints, &self.tool, q_rad);
        let rb = self.base_rotation.matrix();
        for c in 0..MDH_PARAMETER_COUNT {
            let col = mdh.column(c);
            let dp = rb * col.fixed_rows::<3>(0);
            let dr = rb * col.fixed_rows::<3>(3);
            j.fixed_view_mut::<3, 1>(0, c).copy_from(&dp);
            j.fixed_view_mut::<3, 1>(3, c).copy_from(&dr);
        }
        let flange = forward(&self.joints, &Transform::IDENTITY, q_rad);
        let rf = rb * rotation_of(&flange).matrix();
        let (_, p, _) = self.pose(q_rad);
        let arm = p - self.base_translation_mm;
        for axis in 0..3 {
            let e = Vector3::ith(axis, 1.0);
            // A tool translation moves the TCP along a flange axis.
            j.fixed_view_mut::<3, 1>(0, TOOL_TRANSLATION + axis)
                .copy_from(&rf.column(axis));
            // A tool rotation turns the TCP frame about a flange axis, in place.
            j.fixed_view_mut::<3, 1>(3, TOOL_ROTATION + axis)
                .copy_from(&rf.column(axis));
            j.fixed_view_mut::<3, 1>(0, BASE_TRANSLATION + axis)
                .copy_from(&e);
            // A base rotation turns everything about the base origin of the registration.
            j.fixed_view_mut::<3, 1>(0, BASE_ROTATION + axis)
                .copy_from(&e.cross(&arm));
            j.fixed_view_mut::<3, 1>(3, BASE_ROTATION + axis)
                .copy_from(&e);
        }
        j
    }

    /// Applies a step `dx` (module-doc order) to the state `x`: additive, except that tool
    /// and base rotations compose as `Exp(δ) · R`.
    fn step(&self, x: &ParameterVector, dx: &ParameterVector) -> ParameterVector {
        let mut next = x + dx;
        for start in [TOOL_ROTATION, BASE_ROTATION] {
            let composed =
                rotation_from_vector(three(dx, start)) * rotation_from_vector(three(x, start));
            let v = rotation_vector(&composed);
            next.fixed_rows_mut::<3>(start).copy_from(&Vector3::from(v));
        }
        next
    }
}

fn three(x: &ParameterVector, start: usize) -> [f64; 3] {
    [x[start], x[start + 1], x[start + 2]]
}

/// The measurements of one sample.
struct Measurement {
    q_rad: [f64; JOINT_COUNT],
    error_mm: [f64; 3],
    rotation_error_rad: Option<[f64; 3]>,
}

/// Identifies the kinematic model of `robot` from `samples` (which need joint angles; their
/// orientation errors are used when present). See the module docs for the model and method.
///
/// # Errors
///
/// [`CalibrateError::MissingJoints`] without joint angles,
/// [`CalibrateError::NonFinite`] for a non-finite value,
/// [`CalibrateError::NothingIdentifiable`] when the poses do not vary,
/// [`CalibrateError::TooFewMeasurements`] when the samples are too few for the parameters
/// they excite, [`CalibrateError::InvalidOption`] for options out of range.
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
    let joints = samples
        .joints
        .as_ref()
        .ok_or(CalibrateError::MissingJoints)?;
    if joints.count() != JOINT_COUNT {
        return Err(CalibrateError::JointCount {
            robot: JOINT_COUNT,
            samples: joints.count(),
        });
    }
    let measurements: Vec<Measurement> = (0..samples.len())
        .map(|i| {
            let q = joints.row(i);
            let m = Measurement {
                q_rad: std::array::from_fn(|a| q[a]),
                error_mm: samples.error_mm[i],
                rotation_error_rad: samples.rotation_error_rad.as_ref().map(|r| r[i]),
            };
            let finite = m.q_rad.iter().chain(&m.error_mm).all(|v| v.is_finite())
                && m.rotation_error_rad
                    .is_none_or(|r| r.iter().all(|v| v.is_finite()));
            if finite {
                Ok(m)
            } else {
                Err(CalibrateError::NonFinite { index: i })
            }
        })
        .collect::<Result<_, _>>()?;
    let rows_per_sample = if samples.rotation_error_rad.is_some() {
        6
    } else {
        3
    };
    let weight = options.orientation_weight_mm_per_rad;
    let nominal = Model::nominal(robot);

    // The weighted residual vector and Jacobian (all 42 columns) of a state.
    let linearise = |model: &Model, with_jacobian: bool| {
        let rows = measurements.len() * rows_per_sample;
        let mut r = DVector::zeros(rows);
        let mut jac = if with_jacobian {
            DMatrix::zeros(rows, PARAMETER_COUNT)
        } else {
            DMatrix::zeros(0, 0)
        };
        for (s, m) in measurements.iter().enumerate() {
            let (dp, dr) = model.error(&m.q_rad);
            let row = s * rows_per_sample;
            for a in 0..3 {
                r[row + a] = m.error_mm[a] - dp[a];
            }
            if let Some(measured) = m.rotation_error_rad {
                for a in 0..3 {
                    r[row + 3 + a] = weight * (measured[a] - dr[a]);
                }
            }
            if with_jacobian {
                let j = model.jacobian(&m.q_rad);
                for a in 0..rows_per_sample {
                    let scale = if a < 3 { 1.0 } else { weight };
                    for c in 0..PARAMETER_COUNT {
                        jac[(row + a, c)] = scale * j[(a, c)];
                    }
                }
            }
        }
        (r, jac)
    };

    let (r0, j0) = linearise(&nominal, true);
    let column_norms: Vec<f64> = (0..PARAMETER_COUNT).map(|c| j0.column(c).norm()).collect();
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
    let mut scaled = j0.clone();
    for (c, s) in scales.iter().enumerate() {
        scaled.column_mut(c).scale_mut(*s);
    }
    let (kept, dropped) = pivot_columns(&scaled, options.rank_tolerance);
    if kept.is_empty() {
        return Err(CalibrateError::NothingIdentifiable);
    }
    let rows = measurements.len() * rows_per_sample;
    if rows < 2 * kept.len() {
        return Err(CalibrateError::TooFewMeasurements {
            measurements: rows,
            parameters: kept.len(),
        });
    }

    let position_rms = |r: &DVector<f64>| {
        let sum: f64 = (0..measurements.len())
            .map(|s| r.fixed_rows::<3>(s * rows_per_sample).norm_squared())
            .sum();
        (sum / measurements.len() as f64).sqrt()
    };
    let initial_position_rms_mm = position_rms(&r0);

    // Levenberg–Marquardt in the scaled, kept coordinates: solve
    // [J; √μ·I] δ = [r; 0] by SVD, accept the step if the cost falls.
    let reduced = |jac: &DMatrix<f64>| {
        DMatrix::from_fn(rows, kept.len(), |i, k| jac[(i, kept[k])] * scales[kept[k]])
    };
    let mut x = ParameterVector::zeros();
    let mut model = nominal.clone();
    let (mut r, mut jac) = (r0, j0);
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
            let mut dx = ParameterVector::zeros();
            for (k, &c) in kept.iter().enumerate() {
                dx[c] = step[k] * scales[c];
            }
            let candidate_x = model.step(&x, &dx);
            let candidate = nominal.with_parameters(&candidate_x);
            let (candidate_r, _) = linearise(&candidate, false);
            let candidate_cost = candidate_r.norm_squared();
            if candidate_cost.is_finite() && candidate_cost <= cost {
                let decrease = cost - candidate_cost;
                x = candidate_x;
                model = candidate;
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
        let (next_r, next_jac) = linearise(&model, true);
        r = next_r;
        jac = next_jac;
        if converged {
            break;
        }
    }

    let jk = reduced(&jac);
    let singular = jk.singular_values();
    let condition_number = singular.max() / singular.min();
    let orientation_rms_rad = samples.rotation_error_rad.as_ref().map(|_| {
        let sum: f64 = (0..measurements.len())
            .map(|s| r.fixed_rows::<3>(s * rows_per_sample + 3).norm_squared())
            .sum();
        (sum / measurements.len() as f64).sqrt() / weight
    });
    Ok(Calibration {
        deviations: x,
        identified: kept.iter().map(|&c| Parameter::from_column(c)).collect(),
        unidentifiable: dropped
            .into_iter()
            .map(|(c, ratio)| (Parameter::from_column(c), ratio))
            .collect(),
        condition_number,
        initial_position_rms_mm,
        position_rms_mm: position_rms(&r),
        orientation_rms_rad,
        iterations,
        converged,
        model,
    })
}

/// QR with column pivoting by modified Gram–Schmidt: returns the kept columns in pivot
/// order, and the dropped ones with their independent fraction (relative to the first
/// pivot), in column order. Selection stops at the first pivot below `tolerance`.
fn pivot_columns(a: &DMatrix<f64>, tolerance: f64) -> (Vec<usize>, Vec<(usize, f64)>) {
    let mut residual = a.clone();
    let mut kept = Vec::new();
    let mut remaining: Vec<usize> = (0..a.ncols()).collect();
    let mut first = None;
    while !remaining.is_empty() {
        let (position, norm) = remaining
            .iter()
            .enumerate()
            .map(|(i, &c)| (i, residual.column(c).norm()))
            .fold((0, -1.0), |best, x| if x.1 > best.1 { x } else { best });
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
    use crate::model::shipped_robot_path;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn kr150() -> Robot {
        Robot::load(shipped_robot_path("kr150-2")).unwrap()
    }

    /// Random joint angles inside the limits.
    fn poses(robot: &Robot, n: usize, seed: u64) -> Vec<[f64; 6]> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                std::array::from_fn(|i| {
                    let [lo, hi] = robot.joints[i].limits_rad;
                    rng.gen_range(lo * 0.8..hi * 0.8)
                })
            })
            .collect()
    }

    /// Samples of a robot whose true model is `truth`, simulated with the exact forward
    /// kinematics (nominal positions from the nominal model).
    fn simulate(
        robot: &Robot,
        truth: &ParameterVector,
        q: &[[f64; 6]],
        orientation: bool,
    ) -> SampleSet {
        let model = Model::nominal(robot).with_parameters(truth);
        let mut set = SampleSet {
            rotation_error_rad: orientation.then(Vec::new),
            joints: Some(adwi_compile::samples::Joints::new(JOINT_COUNT)),
            ..SampleSet::default()
        };
        for (i, q) in q.iter().enumerate() {
            let nominal = robot.tcp_pose(q).translation.vector;
            let (dp, dr) = model.error(q);
            set.nominal_mm.push([nominal.x, nominal.y, nominal.z]);
            set.error_mm.push(dp);
            if let Some(r) = &mut set.rotation_error_rad {
                r.push(dr);
            }
            set.joints.as_mut().unwrap().push(q);
            set.lines.push(i as u64 + 2);
        }
        set
    }

    /// Realistic deviations on the given columns: 0.5 mm for lengths, 1 mrad for angles.
    fn deviations_on(columns: &[usize], seed: u64) -> ParameterVector {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut x = ParameterVector::zeros();
        for &c in columns {
            let m = if Parameter::from_column(c).is_length() {
                0.5
            } else {
                1e-3
            };
            x[c] = rng.gen_range(-m..m);
        }
        x
    }

    #[test]
    fn parameter_columns_round_trip() {
        for c in 0..PARAMETER_COUNT {
            assert_eq!(Parameter::from_column(c).column(), c);
        }
        assert_eq!(Parameter::from_column(42 - 1), Parameter::BaseRotation(2));
        assert_eq!(Parameter::from_column(3).to_string(), "Δtheta1");
    }

    #[test]
    fn jacobian_matches_finite_differences_of_the_exact_model() {
        let robot = kr150();
        let x = deviations_on(&(0..PARAMETER_COUNT).collect::<Vec<_>>(), 3);
        let base = Model::nominal(&robot);
        let model = base.with_parameters(&x);
        let q = [0.3, -1.1, 1.3, 0.4, 0.7, -0.5];
        let j = model.jacobian(&q);
        let h = 1e-6;
        for c in 0..PARAMETER_COUNT {
            let mut d = ParameterVector::zeros();
            d[c] = h;
            let plus = base.with_parameters(&model.step(&x, &d)).error(&q);
            let minus = base.with_parameters(&model.step(&x, &(-d))).error(&q);
            for a in 0..3 {
                let numeric_p = (plus.0[a] - minus.0[a]) / (2.0 * h);
                assert!(
                    (numeric_p - j[(a, c)]).abs() < 1e-5 * j.column(c).norm().max(1.0),
                    "{} row {a}: {numeric_p} vs {}",
                    Parameter::from_column(c),
                    j[(a, c)]
                );
                let numeric_r = (plus.1[a] - minus.1[a]) / (2.0 * h);
                // log(R_actual R_nominalᵀ) differs from the rotation perturbation by the
                // inverse left Jacobian of SO(3): I + O(|δ|), here |δ| ≈ 1e-3.
                assert!(
                    (numeric_r - j[(a + 3, c)]).abs() < 5e-3 * j.column(c).norm().max(1.0),
                    "{} row {}: {numeric_r} vs {}",
                    Parameter::from_column(c),
                    a + 3,
                    j[(a + 3, c)]
                );
            }
        }
    }

    /// Noise-free data from a known model: the identifiable deviations come back to 1e-6.
    #[test]
    fn recovers_known_deviations_from_noise_free_data() {
        let robot = kr150();
        let q = poses(&robot, 60, 1);
        for orientation in [true, false] {
            // Which parameters these poses identify: a fit of error-free data.
            let zero = simulate(&robot, &ParameterVector::zeros(), &q, orientation);
            let structure = identify(&robot, &zero, &CalibrateOptions::default()).unwrap();
            let columns: Vec<usize> = structure.identified.iter().map(|p| p.column()).collect();
            let truth = deviations_on(&columns, 2);
            let samples = simulate(&robot, &truth, &q, orientation);
            let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
            assert!(c.converged, "not converged after {}", c.iterations);
            assert_eq!(c.identified, structure.identified);
            for i in 0..PARAMETER_COUNT {
                assert!(
                    (c.deviations[i] - truth[i]).abs() < 1e-6,
                    "orientation {orientation}, {}: identified {} true {}",
                    Parameter::from_column(i),
                    c.deviations[i],
                    truth[i]
                );
            }
            assert!(c.position_rms_mm < 1e-9, "{}", c.position_rms_mm);
            assert!(c.initial_position_rms_mm > 0.1);
            // Predictions at unseen poses equal the simulated errors.
            for q in poses(&robot, 10, 9) {
                let truth_model = Model::nominal(&robot).with_parameters(&truth);
                let (expected, _) = truth_model.error(&q);
                let (got, _) = c.predict_error(&q);
                for a in 0..3 {
                    assert!((expected[a] - got[a]).abs() < 1e-6);
                }
            }
        }
    }

    /// Known redundancies are found: Δd1 moves the TCP exactly like the base z
    /// translation, Δθ1 like the base rotation about z; without orientation data the tool
    /// rotation cannot be seen at all.
    #[test]
    fn structural_redundancies_are_reported_unidentifiable() {
        let robot = kr150();
        let q = poses(&robot, 60, 4);
        let samples = simulate(&robot, &ParameterVector::zeros(), &q, false);
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
    }

    /// Data that excite almost nothing are refused, and data without joints too.
    #[test]
    fn refuses_data_that_cannot_identify_the_model() {
        let robot = kr150();
        // Only joint 1 turns: a circle, far too little for the parameters it excites
        // when there are only four samples.
        let q: Vec<[f64; 6]> = (0..4)
            .map(|i| [0.2 * f64::from(i), -1.0, 1.2, 0.0, 0.5, 0.0])
            .collect();
        let samples = simulate(&robot, &ParameterVector::zeros(), &q, false);
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
        // Many samples on that circle: identification runs, but a circular arc has only
        // seven degrees of freedom (centre 3, axis 2, radius 1, phase 1), so at most seven
        // parameters are identified and the rest are reported unidentifiable.
        let q: Vec<[f64; 6]> = (0..40)
            .map(|i| [0.05 * f64::from(i), -1.0, 1.2, 0.0, 0.5, 0.0])
            .collect();
        let samples = simulate(&robot, &ParameterVector::zeros(), &q, false);
        let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
        assert!(c.identified.len() <= 7, "{:?}", c.identified);
        assert_eq!(c.unidentifiable.len(), PARAMETER_COUNT - c.identified.len());
        let dropped = |p| c.unidentifiable.iter().any(|(q, _)| *q == p);
        // Joint 2 never turns: its angle offset cannot be told from the base rotation.
        assert!(dropped(Parameter::Mdh {
            joint: 1,
            parameter: MdhParameter::Theta
        }));
    }

    /// The stored model reproduces the identification's predictions through the runtime's
    /// forward kinematics, and the residuals it leaves are the identification's.
    #[test]
    fn stored_model_agrees_with_the_identification() {
        let dir = shipped_robot_path("kr150-2");
        let robot = Robot::load(&dir).unwrap();
        let samples = adwi_compile::samples::read_samples(
            &dir.parent().unwrap().join("samples.csv"),
            &adwi_compile::samples::ColumnMap::default(),
        )
        .unwrap();
        let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
        let model = c.kinematic_model();
        let joints = samples.joints.as_ref().unwrap();
        for q in joints.rows().step_by(37) {
            let q: [f64; 6] = std::array::from_fn(|a| q[a]);
            let (p, r) = adwi_runtime::model::model_error(&model, &q);
            let (p_ref, r_ref) = c.predict_error(&q);
            for a in 0..3 {
                assert!((p[a] - p_ref[a]).abs() < 1e-9, "{p:?} vs {p_ref:?}");
                assert!((r[a] - r_ref[a]).abs() < 1e-12, "{r:?} vs {r_ref:?}");
            }
        }
        let prepared = adwi_runtime::model::PreparedModel::from_mdh(&model);
        let residual = adwi_compile::hybrid::residual_samples(&samples, &prepared).unwrap();
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
    }
}
