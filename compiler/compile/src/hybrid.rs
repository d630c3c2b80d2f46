//! Hybrid tables: kinematic calibration first, then the cell table over what the calibrated
//! model leaves unexplained, compiled into one file that the runtime serves
//! ([`adwi_runtime::Table::query_with_joints`]).
//!
//! A geometric model explains most of a robot's error with a few dozen parameters and
//! extrapolates well, but cannot represent joint compliance, gear errors or thermal drift;
//! interpolation represents anything smooth but needs dense samples and knows nothing of the
//! arm's posture. The hybrid takes the model's prediction and interpolates only the
//! remainder, whose amplitude (and so the interpolation error) is much smaller.
//!
//! Building one:
//!
//! 1. identify the kinematic deviations ([`crate::calibrate::identify`]);
//! 2. compute each sample's *residual*: measured error minus the calibrated model's
//!    predicted error at the sample's joint angles, position and (when measured)
//!    orientation, with the runtime's own [`adwi_runtime::hybrid::model_error`], so that
//!    the table and its queries cannot disagree on the model;
//! 3. compile the residuals into a cell table with the approximation-degree method
//!    ([`crate::build::compile_with_model`]), the nominal and calibrated models stored with
//!    it (`TableData::model`, `CONTENT_MODEL`).
//!
//! The residual samples keep their nominal positions; their "actual" positions, which the
//! approximation degree uses, are nominal + residual, i.e. where the calibrated model
//! leaves them.
//!
//! [`reference_predict`] is the brute-force reference of a hybrid query, computed
//! independently of the table: the compiler's own calibrated forward kinematics
//! ([`Calibration::predict_error`]) plus [`crate::reference`] over every residual.

use adwi_runtime::format::{KinematicModel, SampleRecord};
use adwi_runtime::hybrid::model_error;
use adwi_runtime::method::MethodParams;
use adwi_runtime::Target;

use crate::build::{self, BuildError, BuildOptions, BuildReport};
use crate::calibrate::{self, CalibrateError, CalibrateOptions, Calibration};
use crate::reference::{self, JointScreen};
use crate::robot::Robot;
use crate::samples::SampleSet;

/// Why a hybrid table could not be built.
#[derive(Debug, thiserror::Error)]
pub enum HybridError {
    /// The kinematic identification failed (no joint angles, too few samples, ...).
    #[error("cannot identify the kinematic model")]
    Calibrate(#[from] CalibrateError),
    /// The residual table could not be built.
    #[error("cannot build the residual table")]
    Build(#[from] BuildError),
}

/// What a hybrid build produced.
#[derive(Debug, Clone)]
pub struct HybridBuild {
    /// The table file's bytes.
    pub bytes: Vec<u8>,
    /// The residual table's build report.
    pub report: BuildReport,
    /// What identification found: identified and unidentifiable parameters, condition
    /// number, RMS before and after.
    pub calibration: Calibration,
    /// The RMS of the residual norms stored in the table, position, mm (equal to the
    /// identification's final RMS, recomputed through the runtime's model).
    pub residual_position_rms_mm: f64,
}

/// The samples with their errors replaced by the residuals `model` leaves: measured error
/// minus `model_error(model, q)` at each sample's joint angles, position and (when the
/// samples carry them) orientation.
///
/// # Errors
///
/// [`CalibrateError::MissingJoints`] when the samples carry no joint angles.
pub fn residual_samples(
    samples: &SampleSet,
    model: &KinematicModel,
) -> Result<SampleSet, CalibrateError> {
    let joints = samples
        .joints_deg
        .as_ref()
        .ok_or(CalibrateError::MissingJoints)?;
    let mut residual = samples.clone();
    for (i, q_deg) in joints.iter().enumerate() {
        let (position_mm, rotation_rad) = model_error(model, &q_deg.map(f64::to_radians));
        for (e, p) in residual.error_mm[i].iter_mut().zip(position_mm) {
            *e -= p;
        }
        if let Some(r) = &mut residual.rotation_error_rad {
            for (e, p) in r[i].iter_mut().zip(rotation_rad) {
                *e -= p;
            }
        }
    }
    Ok(residual)
}

/// Compiles a hybrid table from samples and their identified model: the residual table
/// (step 3 of the module docs) carrying `calibration`'s nominal and calibrated models.
///
/// # Errors
///
/// [`HybridError::Calibrate`] without joint angles, [`HybridError::Build`] as
/// [`build::compile`].
pub fn compile(
    samples: &SampleSet,
    calibration: &Calibration,
    options: &BuildOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Vec<u8>, BuildReport), HybridError> {
    let model = calibration.kinematic_model();
    let residual = residual_samples(samples, &model)?;
    Ok(build::compile_with_model(
        &residual,
        options,
        Some(model),
        samples.source_hash(),
        progress,
    )?)
}

/// Identifies `robot`'s kinematic model from `samples`, then compiles the hybrid table:
/// what `tablec build --robot ROBOT.toml --hybrid` does.
///
/// # Errors
///
/// As [`calibrate::identify`] and [`compile`].
pub fn identify_and_compile(
    robot: &Robot,
    samples: &SampleSet,
    build_options: &BuildOptions,
    calibrate_options: &CalibrateOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<HybridBuild, HybridError> {
    let calibration = calibrate::identify(robot, samples, calibrate_options)?;
    let (bytes, report) = compile(samples, &calibration, build_options, progress)?;
    let residual = residual_samples(samples, &calibration.kinematic_model())?;
    let sum: f64 = residual
        .error_mm
        .iter()
        .map(|e| e.iter().map(|v| v * v).sum::<f64>())
        .sum();
    let residual_position_rms_mm = (sum / residual.len().max(1) as f64).sqrt();
    Ok(HybridBuild {
        bytes,
        report,
        calibration,
        residual_position_rms_mm,
    })
}

/// The brute-force reference of a hybrid query at `target` reached with joint angles
/// `joints_rad`: the calibrated model's predicted error by the compiler's own forward
/// kinematics ([`Calibration::predict_error`]), plus the reference prediction
/// ([`reference::predict_screened`]) over every residual in `residual_records` (with the
/// joint-space screen when `joint_radius_rad > 0`). Position (mm) and orientation (rad,
/// zero without `orientation`), or `None` when no residual sample is admissible.
///
/// `residual_records` and `sample_joints_rad` are the residual samples
/// ([`residual_samples`] computed with `calibration.predict_error`, or any other
/// independent way) and their joint angles, in sample order.
#[allow(clippy::too_many_arguments)]
pub fn reference_predict(
    residual_records: &[SampleRecord],
    sample_joints_rad: &[[f64; 6]],
    params: &MethodParams,
    joint_radius_rad: f64,
    calibration: &Calibration,
    orientation: bool,
    target: &Target,
    joints_rad: &[f64; 6],
) -> Option<([f64; 3], [f64; 3])> {
    let screen = JointScreen {
        samples_rad: sample_joints_rad,
        target_rad: *joints_rad,
        radius_rad: joint_radius_rad,
    };
    let screen = (joint_radius_rad > 0.0).then_some(&screen);
    let rest = reference::predict_screened(residual_records, params, target, screen)?;
    let (p, r) = calibration.predict_error(joints_rad);
    let position = [0, 1, 2].map(|a| p[a] + rest.position_error_mm[a]);
    let rotation = if orientation {
        [0, 1, 2].map(|a| r[a] + rest.orientation_error_rad[a])
    } else {
        [0.0; 3]
    };
    Some((position, rotation))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::model::shipped_robot_path;
    use crate::samples::{read_samples, ColumnMap};

    /// The stored model reproduces the identification's predictions through the runtime's
    /// forward kinematics, and the residuals it leaves are the identification's.
    #[test]
    fn stored_model_agrees_with_the_identification() {
        let dir = shipped_robot_path("kr150-2");
        let robot = Robot::load(&dir).unwrap();
        let samples = read_samples(
            &dir.parent().unwrap().join("samples.csv"),
            &ColumnMap::default(),
        )
        .unwrap();
        let c = calibrate::identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
        let model = c.kinematic_model();
        let joints = samples.joints_deg.as_ref().unwrap();
        for q_deg in joints.iter().step_by(37) {
            let q = q_deg.map(f64::to_radians);
            let (p, r) = model_error(&model, &q);
            let (p_ref, r_ref) = c.predict_error(&q);
            for a in 0..3 {
                assert!((p[a] - p_ref[a]).abs() < 1e-9, "{p:?} vs {p_ref:?}");
                assert!((r[a] - r_ref[a]).abs() < 1e-12, "{r:?} vs {r_ref:?}");
            }
        }
        let residual = residual_samples(&samples, &model).unwrap();
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
