//! Hybrid tables: a calibrated kinematic model and the cell table over what it leaves
//! unexplained, compiled into one file that the runtime serves
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
//! 1. identify the kinematic deviations (`adwi_identify::calibrate::identify`, whose
//!    calibrated model this module takes as a [`PreparedModel`]);
//! 2. compute each sample's *residual*: measured error minus the calibrated model's
//!    predicted error at the sample's joint angles, position and (when measured)
//!    orientation, with the runtime's own [`adwi_runtime::model::model_error`], so that
//!    the table and its queries cannot disagree on the model;
//! 3. compile the residuals into a cell table with the approximation-degree method
//!    ([`crate::build::compile_plan`]), the nominal and calibrated models stored with
//!    it (`TableData::model`, `CONTENT_MODEL`);
//! 4. when asked ([`crate::build::BuildOptions::posture`]), fit the posture term to what
//!    that table leaves at the samples ([`crate::posture`]) and store it (a version-3
//!    table).
//!
//! The residual samples keep their nominal positions; their "actual" positions, which the
//! approximation degree uses, are nominal + residual, i.e. where the calibrated model
//! leaves them.
//!

use adwi_runtime::chain::JointKind;
use adwi_runtime::model::PreparedModel;

use crate::build::{self, BuildError, BuildReport, Plan, Queried};
use adwi_samples::SampleSet;

/// The samples with their errors replaced by the residuals `model` leaves: measured error
/// minus `model.error(q)` at each sample's joint angles, position and (when the
/// samples carry them) orientation.
///
/// # Errors
///
/// [`BuildError::MissingJoints`] when the samples carry no joint angles.
pub fn residual_samples(
    samples: &SampleSet,
    model: &PreparedModel,
) -> Result<SampleSet, BuildError> {
    let joints = samples.joints.as_ref().ok_or(BuildError::MissingJoints)?;
    let mut residual = samples.clone();
    for (i, q) in joints.rows().enumerate() {
        let (position_mm, rotation_rad) = model.error(q).ok_or(BuildError::JointCount {
            model: model.joint_count(),
            samples: joints.count(),
        })?;
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

/// A hybrid build: the table and the residuals it tabulates.
#[derive(Debug, Clone)]
pub struct HybridBuild {
    /// The table file's bytes.
    pub bytes: Vec<u8>,
    /// The residual table's build report.
    pub report: BuildReport,
    /// The RMS of the residual norms stored in the table, position, mm.
    pub residual_position_rms_mm: f64,
}

/// Compiles the hybrid table of `samples` and their identified `model` as `plan` (made by
/// [`build::plan`] from the measured samples) says: the residual table (step 3 of the
/// module docs) carrying the nominal and calibrated models.
///
/// # Errors
///
/// [`BuildError::MissingJoints`] without joint angles, otherwise as
/// [`build::compile_plan`].
pub fn compile(
    samples: &SampleSet,
    model: &PreparedModel,
    plan: &Plan,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<HybridBuild, BuildError> {
    compile_serving(samples, model, plan, Queried::Anywhere, progress)
}

/// `model` with its joint record's ranges the angles `samples` span, as a version-6 table
/// records them: each revolute joint's lowest and highest commanded angle (a prismatic
/// joint's unbounded). Beyond them the model's joint-space terms are held at the nearer end
/// (they were identified from the same samples: the same ranges) and the table's residual
/// fades to zero ([`adwi_runtime::joint_terms::RESIDUAL_FADE_RAD`]).
///
/// # Errors
///
/// [`BuildError::MissingJoints`] for samples without joint values,
/// [`BuildError::JointCount`] for another count than the model's, [`BuildError::Params`]
/// for a model whose terms do not fit its chain (a model identified as this workspace does
/// always fits).
pub fn bounded_by_samples(
    model: &PreparedModel,
    samples: &SampleSet,
) -> Result<PreparedModel, BuildError> {
    let joints = samples.joints.as_ref().ok_or(BuildError::MissingJoints)?;
    if joints.count() != model.joint_count() {
        return Err(BuildError::JointCount {
            model: model.joint_count(),
            samples: joints.count(),
        });
    }
    let mut terms = *model.joint_terms();
    for (j, (range, joint)) in terms
        .range_rad
        .iter_mut()
        .zip(model.calibrated().joints())
        .enumerate()
    {
        *range = [f64::NEG_INFINITY, f64::INFINITY];
        if joint.kind != JointKind::Revolute {
            continue;
        }
        let (lo, hi) = (0..samples.len())
            .map(|i| joints.row(i)[j])
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
                (lo.min(q), hi.max(q))
            });
        if lo <= hi {
            *range = [lo, hi];
        }
    }
    (*model)
        .with_joint_terms(terms)
        .map(PreparedModel::bounding_residual)
        .ok_or(BuildError::Params(
            "the model's joint-space terms do not fit its chain",
        ))
}

/// [`compile`] computing only what a table `queried` there needs.
///
/// # Errors
///
/// As [`compile`].
pub fn compile_serving(
    samples: &SampleSet,
    model: &PreparedModel,
    plan: &Plan,
    queried: Queried<'_>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<HybridBuild, BuildError> {
    let model = &bounded_by_samples(model, samples)?;
    let residual = residual_samples(samples, model)?;
    // The posture term learns what the table serves at each sample: a table computing
    // only some nodes and lists computes those that serve the samples too.
    let serving_samples: Vec<[f64; 3]>;
    let queried = match queried {
        Queried::At { served, exact } if plan.posture != crate::posture::Posture::Off => {
            serving_samples = served.iter().chain(&samples.nominal_mm).copied().collect();
            Queried::At {
                served: &serving_samples,
                exact,
            }
        }
        queried => queried,
    };
    let compiled = build::encode::compile_plan_values(
        &residual,
        plan,
        Some(model),
        samples.source_hash(),
        queried,
        progress,
    )?;
    let (bytes, report) = if plan.posture == crate::posture::Posture::Off {
        (compiled.bytes, compiled.report)
    } else {
        crate::posture::add_term(compiled, samples, model, plan.posture, plan.tuning)?
    };
    let sum: f64 = residual
        .error_mm
        .iter()
        .map(|e| e.iter().map(|v| v * v).sum::<f64>())
        .sum();
    Ok(HybridBuild {
        bytes,
        report,
        residual_position_rms_mm: (sum / residual.len().max(1) as f64).sqrt(),
    })
}
