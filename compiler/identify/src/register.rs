//! Registration of measurements taken in an instrument's frame: finding where the robot's
//! base lies in a laser tracker's frame and where the measured probe sits on the flange,
//! from the commanded joint values and the measured poses alone.
//!
//! # The model
//!
//! Measurement `i`, at joint values `q_i`, is the probe's position `p_i` (mm), and
//! optionally its orientation `R_i`, in the tracker's frame. The nominal robot predicts
//!
//! ```text
//! p_i = R · (R_f(q_i) · t_probe + p_f(q_i)) + t        R_i = R · R_f(q_i) · R_probe
//! ```
//!
//! with `(R_f, p_f)(q)` the flange pose (the robot's forward kinematics without its tool,
//! in the frame its poses are given in, its base included), `(R, t)` the robot's frame in
//! the tracker's ([`Registration::base_in_tracker`]) and `(R_probe, t_probe)` the probe in
//! the flange frame ([`Registration::probe`]), which replaces the robot file's tool. From
//! positions alone `R_probe` is not observable and stays the robot file's tool rotation.
//!
//! # Method
//!
//! 1. A closed-form start: the rigid transform (Kabsch–Umeyama, no scale) that best maps the
//!    nominal TCP positions (the robot file's tool) onto the measured positions.
//! 2. Alternately, the probe offset and the translation by linear least squares with the
//!    rotation held (`p_i − R·p_f = R·R_f·t_probe + t` is linear in both), and the rotation
//!    and translation by Kabsch–Umeyama with the probe held, until the probe offset stops
//!    moving; with orientations measured, the probe rotation is then the chordal mean of
//!    `(R·R_f(q_i))ᵀ·R_i`.
//! 3. Levenberg–Marquardt on all of them together (rotations updated multiplicatively,
//!    analytic Jacobian), orientation rows weighted like the identification's
//!    ([`RegisterOptions::orientation_weight_mm_per_rad`]).
//!
//! The robot's own errors stay in the residuals of this rigid fit
//! ([`Registration::position_rms_mm`], ...): they are what the identification explains. The
//! identification ([`crate::calibrate::identify`]) of the registered samples
//! ([`Registration::to_samples`]) with the registered robot ([`Registration::robot`])
//! then refines both transforms through its base and tool parameters, linearised around
//! this start; [`Registration::refined`] composes the two.

use adwi_runtime::kinematics::Transform;
use adwi_samples::pose::{orientation_error, rotation_vector};
use adwi_samples::{Measurements, MeasurementsError, SampleSet};
use nalgebra::{Matrix3, Rotation3, SMatrix, SVector, Vector3};

use crate::calibrate::Calibration;
use adwi_robot::model::{rotation_of, transform_from_parts, JointKind};
use adwi_robot::plausible::{check as check_plausible, check_all, Quantity};
use adwi_robot::Robot;

/// How to register.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegisterOptions {
    /// Orientation residuals (rad) are multiplied by this before they join the position
    /// residuals (mm), as in the identification.
    pub orientation_weight_mm_per_rad: f64,
    /// At most this many Levenberg–Marquardt iterations.
    pub max_iterations: u32,
}

impl Default for RegisterOptions {
    fn default() -> Self {
        RegisterOptions {
            orientation_weight_mm_per_rad: 1000.0,
            max_iterations: 200,
        }
    }
}

/// Why measurements cannot be registered.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RegisterError {
    /// The measurements' joint values do not fit the robot.
    #[error("the measurements have {samples} joint values each, the robot {robot} joints")]
    JointCount {
        /// The robot's joint count.
        robot: usize,
        /// Joint values per row.
        samples: usize,
    },
    /// Too few rows, or positions that do not span a plane.
    #[error("{rows} measured positions cannot register the tracker: at least 6, not all on one line, are needed")]
    Degenerate {
        /// The rows.
        rows: usize,
    },
    /// A value is NaN or infinite.
    #[error("measurement row {line} has a non-finite joint value or measured value")]
    NonFinite {
        /// The row's source line.
        line: u64,
    },
    /// A value is beyond any robot's and any tracker's: a measured coordinate beyond 1 km,
    /// a joint beyond ten turns ([`adwi_robot::plausible`]).
    #[error("measurement row {line}: {what}")]
    Implausible {
        /// The row's source line.
        line: u64,
        /// The value, what it is and the bound it crosses.
        what: String,
    },
    /// The measurements' parts do not have one entry per row.
    #[error("the measurements are inconsistent: {0}")]
    Measurements(#[from] MeasurementsError),
}

/// Where the robot stands in the tracker's frame and where the probe sits on the flange: the
/// rigid registration of measurements and how well it fits (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Registration {
    /// The robot's frame (the frame its poses are given in) in the tracker's:
    /// `p_tracker = R · p_robot + t`.
    pub base_in_tracker: Transform,
    /// The probe in the flange frame: the registered robot's tool. Its rotation is the
    /// robot file's tool rotation when no orientation was measured.
    pub probe: Transform,
    /// Whether the orientations were measured (and the probe rotation registered).
    pub orientation: bool,
    /// Rows registered.
    pub rows: usize,
    /// RMS of the position residual norms of the rigid fit, mm.
    pub position_rms_mm: f64,
    /// Largest position residual norm, mm.
    pub position_max_mm: f64,
    /// RMS of the orientation residual norms, rad, when orientations were measured.
    pub orientation_rms_rad: Option<f64>,
    /// Largest orientation residual norm, rad, when orientations were measured.
    pub orientation_max_rad: Option<f64>,
    /// Levenberg–Marquardt iterations made.
    pub iterations: u32,
    /// What about the fit looks wrong, for the caller to tell the user (the library
    /// prints nothing).
    pub warnings: Vec<RegisterWarning>,
}

/// The largest RMS of a rigid fit's position residuals that a robot's own error accounts
/// for, mm: uncalibrated robots deviate by a few millimetres, the largest and most loaded
/// by a few tens.
pub const MAX_PLAUSIBLE_FIT_RMS_MM: f64 = 25.0;

/// Something about a registration that looks wrong, though it could be computed.
#[derive(Debug, Clone, PartialEq)]
pub enum RegisterWarning {
    /// The rigid fit leaves residuals larger than a robot's own error
    /// ([`MAX_PLAUSIBLE_FIT_RMS_MM`]).
    ImplausibleFit {
        /// The fit's position RMS, mm.
        position_rms_mm: f64,
        /// How far the measured positions spread about their centre, over how far the
        /// robot's predicted ones do (RMS distances): 1 when both are in mm.
        spread_ratio: f64,
        /// The unit the measured positions seem to be in, read as mm, when the ratio is
        /// one's (`m`, `cm`, `in`, `µm`).
        likely_unit: Option<&'static str>,
    },
}

impl std::fmt::Display for RegisterWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RegisterWarning::ImplausibleFit {
                position_rms_mm,
                spread_ratio,
                likely_unit,
            } => {
                write!(
                    f,
                    "the rigid fit leaves a position RMS of {position_rms_mm:.1} mm, more than \
                     the {MAX_PLAUSIBLE_FIT_RMS_MM} mm a robot's own error accounts for; the \
                     measured positions spread {spread_ratio:.3e} times as far as the robot's"
                )?;
                match likely_unit {
                    Some(unit) => write!(
                        f,
                        ": they look like {unit} read as mm (give their columns the unit {unit})"
                    ),
                    None => write!(
                        f,
                        ": check the joint columns, the robot file and that the rows are one \
                         tracker frame's"
                    ),
                }
            }
        }
    }
}

/// The units a length might have been written in, and how many of them make a millimetre.
const UNITS_PER_MM: [(&str, f64); 4] = [("m", 1e-3), ("cm", 0.1), ("in", 1.0 / 25.4), ("µm", 1e3)];

/// The warning for a rigid fit of `position_rms_mm` between `predicted` (mm) and
/// `measured` positions, if the fit is implausible.
fn fit_warning(
    position_rms_mm: f64,
    predicted: &[Vector3<f64>],
    measured: &[Vector3<f64>],
) -> Option<RegisterWarning> {
    if position_rms_mm <= MAX_PLAUSIBLE_FIT_RMS_MM {
        return None;
    }
    let spread = |points: &[Vector3<f64>]| {
        let centre = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
        let sum: f64 = points.iter().map(|p| (p - centre).norm_squared()).sum();
        (sum / points.len() as f64).sqrt()
    };
    let spread_ratio = spread(measured) / spread(predicted);
    let likely_unit = UNITS_PER_MM
        .iter()
        .find(|(_, ratio)| (spread_ratio / ratio - 1.0).abs() < 0.1)
        .map(|(unit, _)| *unit);
    Some(RegisterWarning::ImplausibleFit {
        position_rms_mm,
        spread_ratio,
        likely_unit,
    })
}

/// The transforms after the identification refined them, and the residuals of the
/// identified model against the registered samples.
#[derive(Debug, Clone, PartialEq)]
pub struct Refined {
    /// The robot's frame in the tracker's, the registration's with the identified base
    /// deviation.
    pub base_in_tracker: Transform,
    /// The probe in the flange frame: the identified tool.
    pub probe: Transform,
    /// RMS of the position residual norms, mm.
    pub position_rms_mm: f64,
    /// Largest position residual norm, mm.
    pub position_max_mm: f64,
    /// RMS of the orientation residual norms, rad, when measured.
    pub orientation_rms_rad: Option<f64>,
    /// Largest orientation residual norm, rad, when measured.
    pub orientation_max_rad: Option<f64>,
}

/// One row: flange pose at its joints, measured pose in the tracker.
struct Row {
    flange_rotation: Matrix3<f64>,
    flange_mm: Vector3<f64>,
    measured_mm: Vector3<f64>,
    measured_rotation: Option<Rotation3<f64>>,
}

/// The unknowns: robot frame in the tracker `(r, t)`, probe `(rp, tp)`.
#[derive(Debug, Clone, Copy)]
struct Rigid {
    r: Rotation3<f64>,
    t: Vector3<f64>,
    rp: Rotation3<f64>,
    tp: Vector3<f64>,
}

impl Rigid {
    /// The predicted probe position in the tracker.
    fn position(&self, row: &Row) -> Vector3<f64> {
        self.r * (row.flange_rotation * self.tp + row.flange_mm) + self.t
    }

    /// The predicted probe orientation in the tracker.
    fn rotation(&self, row: &Row) -> Rotation3<f64> {
        self.r * Rotation3::from_matrix_unchecked(row.flange_rotation) * self.rp
    }

    /// Applies a step: `[δ (rotation of r), dt, dtp, ε (rotation of rp, flange axes)]`.
    fn step(&self, dx: &[f64]) -> Rigid {
        let v = |i: usize| Vector3::new(dx[i], dx[i + 1], dx[i + 2]);
        Rigid {
            r: Rotation3::from_scaled_axis(v(0)) * self.r,
            t: self.t + v(3),
            tp: self.tp + v(6),
            rp: if dx.len() > 9 {
                Rotation3::from_scaled_axis(v(9)) * self.rp
            } else {
                self.rp
            },
        }
    }
}

/// Registers `measurements` (joints and measured poses in the tracker's frame; nominal
/// poses, when given, are not used) to `robot` (module docs), starting from the robot
/// file's tool as the probe.
///
/// # Errors
///
/// [`RegisterError::JointCount`] when the joint count is not the robot's,
/// [`RegisterError::NonFinite`] for a non-finite value, [`RegisterError::Degenerate`] for
/// fewer than 6 rows or positions on a line, [`RegisterError::Measurements`] when the
/// measurements' parts do not have one entry per row.
pub fn register(
    robot: &Robot,
    measurements: &Measurements,
    options: &RegisterOptions,
) -> Result<Registration, RegisterError> {
    let rows = rows_of(robot, measurements)?;
    let n = rows.len();
    let orientation = measurements.measured_rotation.is_some();
    let tool = robot.tool();
    let mut x = Rigid {
        r: Rotation3::identity(),
        t: Vector3::zeros(),
        rp: rotation_of(&tool),
        tp: Vector3::from(tool.translation_mm),
    };
    // 1.–2.: Kabsch with the probe held, least squares for the probe with the rotation
    // held, alternately.
    for _ in 0..50 {
        let nominal: Vec<Vector3<f64>> = rows
            .iter()
            .map(|r| r.flange_rotation * x.tp + r.flange_mm)
            .collect();
        let measured: Vec<Vector3<f64>> = rows.iter().map(|r| r.measured_mm).collect();
        let (r, t) = kabsch(&nominal, &measured).ok_or(RegisterError::Degenerate { rows: n })?;
        x.r = r;
        x.t = t;
        let previous = x.tp;
        let mut normal = SMatrix::<f64, 6, 6>::zeros();
        let mut rhs = SVector::<f64, 6>::zeros();
        for row in &rows {
            let mut a = SMatrix::<f64, 3, 6>::zeros();
            a.fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&(x.r.matrix() * row.flange_rotation));
            a.fixed_view_mut::<3, 3>(0, 3)
                .copy_from(&Matrix3::identity());
            let b = row.measured_mm - x.r * row.flange_mm;
            normal += a.transpose() * a;
            rhs += a.transpose() * b;
        }
        let solution = solve(&normal, &rhs);
        x.tp = solution.fixed_rows::<3>(0).into_owned();
        x.t = solution.fixed_rows::<3>(3).into_owned();
        if (x.tp - previous).norm() < 1e-9 {
            break;
        }
    }
    if orientation {
        let mut sum = Matrix3::zeros();
        for row in &rows {
            let measured = row.measured_rotation.expect("every row has one");
            sum += (x.r.matrix() * row.flange_rotation).transpose() * measured.matrix();
        }
        x.rp = nearest_rotation(&sum);
    }
    // 3.: all together.
    let weight = options.orientation_weight_mm_per_rad;
    let unknowns = if orientation { 12 } else { 9 };
    let (mut cost, mut iterations) = (cost_of(&x, &rows, weight), 0);
    let mut mu = 1e-9;
    while iterations < options.max_iterations {
        iterations += 1;
        let (normal, gradient) = normal_equations(&x, &rows, weight, unknowns);
        let mut accepted = None;
        for _ in 0..30 {
            let mut damped = normal.clone();
            for i in 0..unknowns {
                damped[(i, i)] += mu * normal[(i, i)].max(1e-12);
            }
            let dx = damped
                .clone()
                .svd(true, true)
                .solve(&gradient, 0.0)
                .expect("SVD with both factors computed");
            let candidate = x.step(dx.as_slice());
            let candidate_cost = cost_of(&candidate, &rows, weight);
            if candidate_cost.is_finite() && candidate_cost <= cost {
                accepted = Some((candidate, candidate_cost));
                mu = (mu / 10.0).max(1e-15);
                break;
            }
            mu *= 10.0;
        }
        let Some((candidate, candidate_cost)) = accepted else {
            break;
        };
        let decrease = cost - candidate_cost;
        x = candidate;
        cost = candidate_cost;
        if decrease <= 1e-15 * cost || cost == 0.0 {
            break;
        }
    }
    let (position, rotation) = residual_norms(&x, &rows);
    let (position_rms_mm, position_max_mm) = rms_max(&position);
    let (orientation_rms_rad, orientation_max_rad) = match rotation {
        Some(r) => {
            let (rms, max) = rms_max(&r);
            (Some(rms), Some(max))
        }
        None => (None, None),
    };
    let predicted: Vec<Vector3<f64>> = rows
        .iter()
        .map(|r| r.flange_rotation * x.tp + r.flange_mm)
        .collect();
    let measured: Vec<Vector3<f64>> = rows.iter().map(|r| r.measured_mm).collect();
    Ok(Registration {
        base_in_tracker: transform_from_parts([x.t.x, x.t.y, x.t.z], &x.r),
        probe: transform_from_parts([x.tp.x, x.tp.y, x.tp.z], &x.rp),
        orientation,
        rows: n,
        position_rms_mm,
        position_max_mm,
        orientation_rms_rad,
        orientation_max_rad,
        iterations,
        warnings: fit_warning(position_rms_mm, &predicted, &measured)
            .into_iter()
            .collect(),
    })
}

impl Registration {
    /// The rigid fit's transforms and residuals, in the shape of its [`Registration::refined`]
    /// ones, so that both are reported alike.
    pub fn fit(&self) -> Refined {
        Refined {
            base_in_tracker: self.base_in_tracker,
            probe: self.probe,
            position_rms_mm: self.position_rms_mm,
            position_max_mm: self.position_max_mm,
            orientation_rms_rad: self.orientation_rms_rad,
            orientation_max_rad: self.orientation_max_rad,
        }
    }

    /// The robot with the registered probe as its tool: the nominal model the registered
    /// samples' errors are taken against, and the start of the identification.
    ///
    /// # Errors
    ///
    /// As [`Robot::with_parts`] (not for a probe this registration found).
    pub fn robot(&self, robot: &Robot) -> Result<Robot, adwi_robot::RobotError> {
        robot.with_parts(
            robot.name.clone(),
            robot.base(),
            self.probe,
            robot.home().to_vec(),
        )
    }

    /// The measurements as base-frame samples: the measured poses expressed in the robot's
    /// frame through this registration, the nominal poses the forward kinematics of the
    /// registered robot ([`Registration::robot`]) at the rows' joints (nominal orientations
    /// only when orientations were measured); errors and folded repeats as
    /// [`Measurements::to_samples`] makes them. The measurements may be other rows than
    /// those registered, taken in the same tracker frame with the same probe.
    ///
    /// # Errors
    ///
    /// As [`register`], for the measurements' consistency and joint count.
    pub fn to_samples(
        &self,
        robot: &Robot,
        measurements: &Measurements,
    ) -> Result<SampleSet, RegisterError> {
        rows_of(robot, measurements)?;
        let registered = self.robot(robot).expect("a registered probe makes a robot");
        let tracker_to_base = self.base_in_tracker.inverse();
        let r_inverse = rotation_of(&tracker_to_base);
        let mut nominal_mm = Vec::with_capacity(measurements.len());
        let mut nominal_rotation = Vec::with_capacity(measurements.len());
        for q in measurements.joints.rows() {
            let pose = registered.tcp_transform(q);
            nominal_mm.push(pose.translation_mm);
            nominal_rotation.push(rotation_of(&pose));
        }
        let measured_mm = measurements
            .measured_mm
            .iter()
            .map(|&p| tracker_to_base.transform_point(p))
            .collect();
        let measured_rotation = measurements
            .measured_rotation
            .as_ref()
            .map(|m| m.iter().map(|r| r_inverse * r).collect::<Vec<_>>());
        let base_frame = Measurements {
            joints: measurements.joints.clone(),
            nominal_mm: Some(nominal_mm),
            nominal_rotation: measured_rotation.is_some().then_some(nominal_rotation),
            measured_mm,
            measured_rotation,
            config: measurements.config.clone(),
            lines: measurements.lines.clone(),
        };
        Ok(base_frame.to_samples()?)
    }

    /// Both transforms after `calibration` (identified from [`Registration::to_samples`]
    /// with [`Registration::robot`]) refined them: the robot's frame in the tracker's is
    /// the registration's composed with the identified base deviation,
    /// `T_registered · B_identified · B_nominal⁻¹`; the probe is the identified tool. The
    /// residuals are the identified model's against `samples` (those it was identified
    /// from).
    pub fn refined(&self, calibration: &Calibration, samples: &SampleSet) -> Refined {
        let nominal_base = calibration.nominal_robot().base();
        let identified = calibration.calibrated_robot();
        let base_in_tracker = self
            .base_in_tracker
            .compose(&identified.base())
            .compose(&nominal_base.inverse());
        let mut position = Vec::with_capacity(samples.len());
        let mut rotation = Vec::with_capacity(samples.len());
        for i in 0..samples.len() {
            let Some(q) = samples.joints_rad(i) else {
                continue;
            };
            let (dp, dr) = calibration.predict_error(q);
            let e = samples.error_mm[i];
            position.push(Vector3::from([0, 1, 2].map(|a| e[a] - dp[a])).norm());
            if let Some(measured) = &samples.rotation_error_rad {
                let m = measured[i];
                rotation.push(Vector3::from([0, 1, 2].map(|a| m[a] - dr[a])).norm());
            }
        }
        let (position_rms_mm, position_max_mm) = rms_max(&position);
        let (orientation_rms_rad, orientation_max_rad) = if rotation.is_empty() {
            (None, None)
        } else {
            let (rms, max) = rms_max(&rotation);
            (Some(rms), Some(max))
        };
        Refined {
            base_in_tracker,
            probe: identified.tool(),
            position_rms_mm,
            position_max_mm,
            orientation_rms_rad,
            orientation_max_rad,
        }
    }
}

/// A transform as its translation (mm) and rotation vector (deg), for reports.
pub fn translation_and_rotation_deg(transform: &Transform) -> ([f64; 3], [f64; 3]) {
    let r = rotation_vector(&rotation_of(transform));
    (transform.translation_mm, r.map(f64::to_degrees))
}

fn rows_of(robot: &Robot, measurements: &Measurements) -> Result<Vec<Row>, RegisterError> {
    let n = measurements.len();
    let check = |part: &'static str, found: usize| {
        if found == n {
            Ok(())
        } else {
            Err(MeasurementsError::Length {
                part,
                found,
                rows: n,
            })
        }
    };
    check("measured positions", measurements.measured_mm.len())?;
    check("joint rows", measurements.joints.len())?;
    if let Some(r) = &measurements.measured_rotation {
        check("measured orientations", r.len())?;
    }
    if n > 0 && measurements.joint_count() != robot.joint_count() {
        return Err(RegisterError::JointCount {
            robot: robot.joint_count(),
            samples: measurements.joint_count(),
        });
    }
    if n < 6 {
        return Err(RegisterError::Degenerate { rows: n });
    }
    let flange = robot
        .with_parts(
            robot.name.clone(),
            robot.base(),
            Transform::IDENTITY,
            robot.home().to_vec(),
        )
        .expect("a robot without a tool is a robot");
    (0..n)
        .map(|i| {
            let q = measurements.joints.row(i);
            let p = measurements.measured_mm[i];
            let rotation = measurements.measured_rotation.as_ref().map(|r| r[i]);
            let finite = q.iter().chain(&p).all(|v| v.is_finite())
                && rotation.is_none_or(|r| r.matrix().iter().all(|v| v.is_finite()));
            let line = measurements.lines[i];
            if !finite {
                return Err(RegisterError::NonFinite { line });
            }
            let implausible = |e: adwi_robot::RobotError| RegisterError::Implausible {
                line,
                what: e.to_string(),
            };
            check_all(&p, Quantity::LengthMm, || "measured position (mm)".into())
                .map_err(implausible)?;
            for (j, &value) in q.iter().enumerate() {
                let (shown, quantity) = match robot.joint_kind(j) {
                    JointKind::Revolute => (value.to_degrees(), Quantity::JointValueDeg),
                    JointKind::Prismatic => (value, Quantity::LengthMm),
                };
                check_plausible(shown, quantity, || format!("joint {}", j + 1))
                    .map_err(implausible)?;
            }
            let pose = flange.tcp_transform(q);
            Ok(Row {
                flange_rotation: *rotation_of(&pose).matrix(),
                flange_mm: Vector3::from(pose.translation_mm),
                measured_mm: Vector3::from(p),
                measured_rotation: rotation,
            })
        })
        .collect()
}

/// The registration of measurements taken after the tracker moved (another series with
/// the same probe): the robot's frame in the new tracker frame, fitted (Kabsch on
/// positions) to the TCP positions `calibrated` predicts — a calibration made from
/// `reference`'s samples — so that the registered errors are in the frame that
/// calibration was made in. Fitting to the nominal robot instead would let the rigid
/// transform absorb part of the robot's own error, differently from the reference's fit.
/// The probe is `reference`'s; the residuals are the calibrated model's, positions only.
///
/// # Errors
///
/// As [`register`], for the measurements' consistency and joint count, and
/// [`RegisterError::Degenerate`] when the TCP positions lie on a line.
pub fn register_moved(
    reference: &Registration,
    calibrated: &Robot,
    measurements: &Measurements,
) -> Result<Registration, RegisterError> {
    let rows = rows_of(calibrated, measurements)?;
    let tool = calibrated.tool();
    let predicted: Vec<Vector3<f64>> = rows
        .iter()
        .map(|row| row.flange_rotation * Vector3::from(tool.translation_mm) + row.flange_mm)
        .collect();
    let measured: Vec<Vector3<f64>> = rows.iter().map(|row| row.measured_mm).collect();
    let (r, t) =
        kabsch(&predicted, &measured).ok_or(RegisterError::Degenerate { rows: rows.len() })?;
    let residuals: Vec<f64> = predicted
        .iter()
        .zip(&measured)
        .map(|(p, m)| (r * p + t - m).norm())
        .collect();
    let (position_rms_mm, position_max_mm) = rms_max(&residuals);
    Ok(Registration {
        base_in_tracker: transform_from_parts(t.into(), &r),
        probe: reference.probe,
        orientation: reference.orientation,
        rows: rows.len(),
        position_rms_mm,
        position_max_mm,
        orientation_rms_rad: None,
        orientation_max_rad: None,
        iterations: 0,
        warnings: fit_warning(position_rms_mm, &predicted, &measured)
            .into_iter()
            .collect(),
    })
}

/// The rotation and translation `(R, t)` minimising `Σ |R·a_i + t − b_i|²`
/// (Kabsch–Umeyama without scale); `None` when the points `a` lie on a line.
fn kabsch(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> Option<(Rotation3<f64>, Vector3<f64>)> {
    let n = a.len() as f64;
    let ca = a.iter().sum::<Vector3<f64>>() / n;
    let cb = b.iter().sum::<Vector3<f64>>() / n;
    let mut h = Matrix3::zeros();
    for (p, q) in a.iter().zip(b) {
        h += (p - ca) * (q - cb).transpose();
    }
    let svd = h.svd(true, true);
    let s = &svd.singular_values;
    let largest = s.max();
    // Points on a line leave a rotation about it free.
    let mut sorted = [s[0], s[1], s[2]];
    sorted.sort_by(f64::total_cmp);
    if largest.is_nan() || largest <= 0.0 || sorted[1] <= 1e-12 * largest {
        return None;
    }
    let (u, v_t) = (svd.u?, svd.v_t?);
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    let r = Rotation3::from_matrix_unchecked(r);
    Some((r, cb - r * ca))
}

/// The rotation nearest a matrix (Frobenius norm).
fn nearest_rotation(m: &Matrix3<f64>) -> Rotation3<f64> {
    let svd = m.svd(true, true);
    let (u, v_t) = (svd.u.expect("computed"), svd.v_t.expect("computed"));
    let d = (u * v_t).determinant().signum();
    Rotation3::from_matrix_unchecked(u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t)
}

/// Solves a symmetric system by SVD, dropping directions the data do not determine.
fn solve(normal: &SMatrix<f64, 6, 6>, rhs: &SVector<f64, 6>) -> SVector<f64, 6> {
    let eps = 1e-12 * normal.diagonal().max();
    normal
        .svd(true, true)
        .solve(rhs, eps)
        .expect("SVD with both factors computed")
}

/// The weighted cost `Σ |p_i − p̂_i|² + w² |log(R_i R̂_iᵀ)|²`.
fn cost_of(x: &Rigid, rows: &[Row], weight: f64) -> f64 {
    rows.iter()
        .map(|row| {
            let p = (row.measured_mm - x.position(row)).norm_squared();
            let o = row.measured_rotation.map_or(0.0, |m| {
                Vector3::from(orientation_error(&x.rotation(row), &m)).norm_squared()
            });
            p + weight * weight * o
        })
        .sum()
}

/// `JᵀJ` and `Jᵀr` of the weighted residuals `r = measured − predicted` at `x`, `J` the
/// derivative of the prediction with respect to the step of [`Rigid::step`].
fn normal_equations(
    x: &Rigid,
    rows: &[Row],
    weight: f64,
    unknowns: usize,
) -> (nalgebra::DMatrix<f64>, nalgebra::DVector<f64>) {
    let mut normal = nalgebra::DMatrix::zeros(unknowns, unknowns);
    let mut gradient = nalgebra::DVector::zeros(unknowns);
    let mut j = nalgebra::DMatrix::zeros(6, unknowns);
    let mut r = nalgebra::DVector::zeros(6);
    for row in rows {
        j.fill(0.0);
        r.fill(0.0);
        let rf = x.r.matrix() * row.flange_rotation;
        let v = x.r * (row.flange_rotation * x.tp + row.flange_mm);
        // Exp(δ)·R turns the prediction by δ × v.
        j.view_mut((0, 0), (3, 3)).copy_from(&(-v.cross_matrix()));
        j.view_mut((0, 3), (3, 3)).copy_from(&Matrix3::identity());
        j.view_mut((0, 6), (3, 3)).copy_from(&rf);
        r.rows_mut(0, 3)
            .copy_from(&(row.measured_mm - x.position(row)));
        let used = if let Some(m) = row.measured_rotation {
            j.view_mut((3, 0), (3, 3))
                .copy_from(&(Matrix3::identity() * weight));
            j.view_mut((3, 9), (3, 3)).copy_from(&(rf * weight));
            let e = Vector3::from(orientation_error(&x.rotation(row), &m));
            r.rows_mut(3, 3).copy_from(&(e * weight));
            6
        } else {
            3
        };
        let jr = j.rows(0, used);
        normal += jr.transpose() * jr;
        gradient += jr.transpose() * r.rows(0, used);
    }
    (normal, gradient)
}

/// Per row, the position residual norm (mm) and the orientation residual norm (rad).
fn residual_norms(x: &Rigid, rows: &[Row]) -> (Vec<f64>, Option<Vec<f64>>) {
    let position = rows
        .iter()
        .map(|row| (row.measured_mm - x.position(row)).norm())
        .collect();
    let rotation = rows
        .first()
        .is_some_and(|r| r.measured_rotation.is_some())
        .then(|| {
            rows.iter()
                .map(|row| {
                    let m = row.measured_rotation.expect("every row has one");
                    Vector3::from(orientation_error(&x.rotation(row), &m)).norm()
                })
                .collect()
        });
    (position, rotation)
}

fn rms_max(values: &[f64]) -> (f64, f64) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    let rms = (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt();
    (rms, values.iter().copied().fold(0.0, f64::max))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibrate::{identify, CalibrateOptions, Parameter};
    use adwi_robot::error_model::{apply_deviations, deviations_from_vector, PARAMETERS_PER_JOINT};
    use adwi_robot::model::{shipped_robot_path, Geometry};
    use adwi_samples::pose::rotation_from_vector;
    use adwi_samples::Joints;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

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

    /// A tracker far from the robot, turned 120° about a skew axis.
    fn tracker() -> Transform {
        let axis = Vector3::new(1.0, 2.0, 3.0).normalize() * 120f64.to_radians();
        transform_from_parts([2000.0, -1500.0, 800.0], &rotation_from_vector(axis.into()))
    }

    /// A probe off the flange axis, turned 30° about another skew axis.
    fn probe() -> Transform {
        let axis = Vector3::new(-1.0, 0.5, 2.0).normalize() * 30f64.to_radians();
        transform_from_parts([30.0, -20.0, 150.0], &rotation_from_vector(axis.into()))
    }

    /// The poses `actual` reaches at `q`, as `frame` sees them.
    fn measure(
        actual: &Robot,
        frame: &Transform,
        q: &[Vec<f64>],
        orientation: bool,
    ) -> Measurements {
        let mut joints = Joints::new(actual.joint_count());
        let (mut measured_mm, mut rotations) = (Vec::new(), Vec::new());
        for q in q {
            let pose = frame.compose(&actual.tcp_transform(q));
            joints.push(q);
            measured_mm.push(pose.translation_mm);
            rotations.push(rotation_of(&pose));
        }
        Measurements {
            joints,
            measured_mm,
            measured_rotation: orientation.then_some(rotations),
            lines: (2..q.len() as u64 + 2).collect(),
            ..Measurements::default()
        }
    }

    fn translation_gap(a: &Transform, b: &Transform) -> f64 {
        (Vector3::from(a.translation_mm) - Vector3::from(b.translation_mm)).norm()
    }

    fn rotation_gap(a: &Transform, b: &Transform) -> f64 {
        Vector3::from(orientation_error(&rotation_of(a), &rotation_of(b))).norm()
    }

    fn with_tool(robot: &Robot, tool: Transform) -> Robot {
        robot
            .with_parts(
                robot.name.clone(),
                robot.base(),
                tool,
                robot.home().to_vec(),
            )
            .unwrap()
    }

    #[test]
    fn a_perfect_robot_registers_exactly() {
        for (name, orientation) in [("ur10", true), ("ur10", false), ("kr150-2", false)] {
            let robot = Robot::load(shipped_robot_path(name)).unwrap();
            let actual = with_tool(&robot, probe());
            let m = measure(&actual, &tracker(), &poses(&robot, 40, 3), orientation);
            let r = register(&robot, &m, &RegisterOptions::default()).unwrap();
            assert!(
                translation_gap(&r.base_in_tracker, &tracker()) < 1e-6,
                "{r:?}"
            );
            assert!(rotation_gap(&r.base_in_tracker, &tracker()) < 1e-9, "{r:?}");
            assert!(translation_gap(&r.probe, &probe()) < 1e-6, "{r:?}");
            if orientation {
                assert!(rotation_gap(&r.probe, &probe()) < 1e-9, "{r:?}");
                assert!(r.orientation_max_rad.unwrap() < 1e-9);
            } else {
                assert_eq!(r.probe.rotation, robot.tool().rotation);
                assert!(r.orientation_rms_rad.is_none());
            }
            assert!(r.position_max_mm < 1e-6, "{r:?}");
            // The registered samples have no errors.
            let samples = r.to_samples(&robot, &m).unwrap();
            assert!(samples.error_mm.iter().flatten().all(|e| e.abs() < 1e-6));
        }
    }

    /// A robot with kinematic errors, seen from a far, turned tracker through an unknown
    /// probe: registration and identification together find the same calibrated robot as
    /// the identification of the same robot's base-frame errors (its poses at other joint
    /// values in the base frame, and the deviations of the joints between the first and
    /// the last), noise-free to 1e-6 mm and 1e-9 rad.
    #[test]
    fn registered_identification_equals_the_base_frame_one() {
        let robot = Robot::load(shipped_robot_path("ur10")).unwrap();
        let Geometry::Mdh(rows) = robot.geometry().clone() else {
            unreachable!("the UR10 file is MD-H")
        };
        let with_probe = with_tool(&robot, probe());
        let q = poses(&robot, 80, 5);
        let options = CalibrateOptions::default();
        for orientation in [true, false] {
            // Which kinematic parameters these poses identify: a fit of error-free data.
            let perfect = measure(&with_probe, &Transform::IDENTITY, &q, orientation);
            let mut zero = perfect.clone();
            zero.nominal_mm = Some(zero.measured_mm.clone());
            zero.nominal_rotation = zero.measured_rotation.clone();
            let structure = identify(&with_probe, &zero.to_samples().unwrap(), &options).unwrap();
            let mut rng = ChaCha8Rng::seed_from_u64(7);
            let mut truth = vec![0.0; rows.len() * PARAMETERS_PER_JOINT];
            // Deviations of the joints between the first and the last: the first joint's
            // and the last one's can be taken up by the base and the tool (Δd1 is a base
            // translation, Δd6 a tool one), so how they split between the two would depend
            // on where the registration started.
            let last = rows.len() - 1;
            for p in &structure.identified {
                if let Parameter::Mdh { joint, parameter } = *p {
                    if joint == 0 || joint == last {
                        continue;
                    }
                    let m = if p.is_length() { 0.5 } else { 1e-3 };
                    truth[parameter.column(joint)] = rng.gen_range(-m..m);
                }
            }
            let geometry = Geometry::Mdh(apply_deviations(&rows, &deviations_from_vector(&truth)));
            let actual = with_probe
                .with_geometry("actual".into(), geometry, robot.base(), probe())
                .unwrap();

            // Base frame: errors against the nominal robot with the true probe.
            let mut base = measure(&actual, &Transform::IDENTITY, &q, orientation);
            base.nominal_mm = perfect.measured_mm.clone().into();
            base.nominal_rotation = orientation.then(|| perfect.measured_rotation.clone().unwrap());
            let in_base = identify(&with_probe, &base.to_samples().unwrap(), &options).unwrap();

            // Tracker frame, probe unknown.
            let m = measure(&actual, &tracker(), &q, orientation);
            let r = register(&robot, &m, &RegisterOptions::default()).unwrap();
            assert!(
                r.position_rms_mm > 0.1,
                "the robot's errors stay in the rigid fit"
            );
            let samples = r.to_samples(&robot, &m).unwrap();
            let c = identify(&r.robot(&robot).unwrap(), &samples, &options).unwrap();
            let refined = r.refined(&c, &samples);
            if orientation {
                assert!(refined.orientation_max_rad.unwrap() < 1e-9, "{refined:?}");
            }
            assert!(refined.position_max_mm < 1e-6, "{refined:?}");
            // The same deviations of the joints between the first and the last.
            for p in in_base.identified.iter().chain(&c.identified) {
                if let Parameter::Mdh { joint, parameter } = *p {
                    if joint == 0 || joint == last {
                        continue;
                    }
                    let t = truth[parameter.column(joint)];
                    for (name, got) in [("base frame", in_base.value(*p)), ("tracker", c.value(*p))]
                    {
                        assert!((got - t).abs() < 1e-8, "{name}, {p}: {got} against {t}");
                    }
                }
            }
            // The same calibrated poses at other joint values, in the base frame.
            let to_base = tracker().inverse().compose(&r.base_in_tracker);
            for q in poses(&robot, 10, 11) {
                let a = in_base.calibrated_robot().tcp_transform(&q);
                let b = to_base.compose(&c.calibrated_robot().tcp_transform(&q));
                let (dt, dr) = (translation_gap(&a, &b), rotation_gap(&a, &b));
                // Positions alone leave the probe's rotation where the robot file has it.
                let dr = if orientation { dr } else { 0.0 };
                assert!(
                    dt < 1e-6 && dr < 1e-9,
                    "orientation {orientation}: {dt:e} mm, {dr:e} rad"
                );
            }
        }
    }

    /// Positions in metres read as millimetres register, with a warning that names the
    /// unit; a plausible fit has none; an implausible coordinate is refused with its line.
    #[test]
    fn implausible_fits_are_flagged_and_implausible_values_refused() {
        let robot = Robot::load(shipped_robot_path("ur10")).unwrap();
        let actual = with_tool(&robot, probe());
        let good = measure(&actual, &tracker(), &poses(&robot, 60, 3), false);
        let r = register(&robot, &good, &RegisterOptions::default()).unwrap();
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        for (scale, unit) in [(1e-3, Some("m")), (1.0 / 25.4, Some("in")), (0.5, None)] {
            let mut scaled = good.clone();
            for p in &mut scaled.measured_mm {
                *p = p.map(|v| v * scale);
            }
            let r = register(&robot, &scaled, &RegisterOptions::default()).unwrap();
            let [RegisterWarning::ImplausibleFit {
                position_rms_mm,
                spread_ratio,
                likely_unit,
            }] = r.warnings.as_slice()
            else {
                panic!("{scale}: {:?}", r.warnings)
            };
            assert!(*position_rms_mm > MAX_PLAUSIBLE_FIT_RMS_MM);
            assert!((spread_ratio / scale - 1.0).abs() < 0.05, "{spread_ratio}");
            assert_eq!(*likely_unit, unit);
            let text = r.warnings[0].to_string();
            match unit {
                Some(u) => assert!(
                    text.ends_with(&format!(
                        "they look like {u} read as mm (give their columns the unit {u})"
                    )),
                    "{text}"
                ),
                None => assert!(text.ends_with("one tracker frame's"), "{text}"),
            }
        }
        let mut outlier = good.clone();
        outlier.measured_mm[7][0] = 1e300;
        let error = register(&robot, &outlier, &RegisterOptions::default()).unwrap_err();
        assert_eq!(
            error.to_string(),
            "measurement row 9: measured position (mm)[0]: a length (mm) is 1e300, but must be \
             within ±1000000"
        );
    }

    /// The UR10's series C, measured in mm: a plausible fit; its measured positions in
    /// metres read as millimetres: flagged, with the unit.
    #[test]
    fn the_ur10_series_in_metres_is_flagged() {
        let folder =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tables/ur10/measurements");
        let readme = std::fs::read_to_string(folder.join("README.md")).unwrap();
        let line = readme
            .lines()
            .find_map(|l| l.trim().strip_prefix("--columns "))
            .unwrap();
        let columns = adwi_samples::ColumnMap::parse(line.trim()).unwrap();
        let mut m = adwi_samples::read_measurements(
            &folder.join("Series_C/measurements_random_poses.csv"),
            &columns,
            &adwi_samples::ReadOptions::default(),
        )
        .unwrap();
        let robot = Robot::load(shipped_robot_path("ur10")).unwrap();
        let r = register(&robot, &m, &RegisterOptions::default()).unwrap();
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        for p in &mut m.measured_mm {
            *p = p.map(|v| v * 1e-3);
        }
        let r = register(&robot, &m, &RegisterOptions::default()).unwrap();
        assert!(
            matches!(
                &r.warnings[..],
                [RegisterWarning::ImplausibleFit {
                    likely_unit: Some("m"),
                    ..
                }]
            ),
            "{:?}",
            r.warnings
        );
        println!("{}", r.warnings[0]);
    }
}
