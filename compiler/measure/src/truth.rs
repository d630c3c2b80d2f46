//! How close an identification is to a simulated robot's truth.
//!
//! On a simulated robot the error sources are known ([`Scenario`]), so an identification
//! can be judged against them rather than only against held-out measurements, whose noise
//! hides what the identification got wrong. Two figures:
//!
//! - **Parameter error**, identified − true, over the parameters the reference below
//!   identifies (one the calibration held at nominal or could not identify counts with
//!   its nominal zero: the model carries that error): RMS of the lengths (mm) and of the
//!   angles (mrad) apart, since no single unit weighs one against the other.
//! - **Position error over the workspace**: at the given poses, the identified model's TCP
//!   position against the true robot's, noise-free, non-geometric errors (gears,
//!   compliance) included: `|p̂(q) − p(q)|`, mean, RMS and largest (mm). It folds every
//!   parameter error, and what no kinematic parameter explains, into the millimetres a
//!   user of the model gets: the honest single figure.
//!
//! The true parameters must be given in the identification's own parameterisation, which
//! is not the scenario's: redundant parameters carry a deviation on the one the pivoting
//! keeps (`Δd₁` on the base's z, `Δd_n` on the tool's), and the base and tool are
//! parameters a scenario has no deviation for. The reference is therefore what the same
//! identification (same options) finds from the scenario's exact, noise-free errors at
//! the workspace poses (position, and orientation when the calibration measured it, so
//! that both see the same redundancies): for a scenario with geometric errors only that fit is
//! exact, and its values are the scenario's deviations up to those redundancies (tested);
//! with non-geometric errors it is the best kinematic model of that workspace, and the
//! parameter error measures what the noise and the choice of poses cost, not what the
//! kinematic model cannot explain (the position error measures that too).

use adwi_identify::calibrate::{
    identify, CalibrateError, CalibrateOptions, Calibration, Parameter,
};
use adwi_robot::error_model::pose_error;
use adwi_robot::Robot;
use adwi_samples::{Joints, SampleSet};
use adwi_simulate::{Scenario, SimulateError};
use nalgebra::Vector3;

/// The most workspace poses a comparison takes (each costs a reference identification's
/// row and a forward kinematics).
pub const MAX_POSES: usize = 100_000;

/// Why an identification cannot be compared with the truth.
#[derive(Debug, thiserror::Error)]
pub enum TruthError {
    /// The scenario does not fit the robot.
    #[error(transparent)]
    Scenario(#[from] Box<SimulateError>),
    /// The reference identification failed.
    #[error("identifying the scenario's exact errors: {0}")]
    Reference(#[from] Box<CalibrateError>),
    /// Too few or too many workspace poses, or poses of another joint count.
    #[error("{0}")]
    Poses(String),
    /// A figure came out non-finite.
    #[error("the comparison with the truth is not finite ({0})")]
    NonFinite(&'static str),
}

/// One parameter, identified against true. Serialized as `{"parameter": its name,
/// "unit": its unit, "identified", "truth"}`.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterError {
    /// The parameter.
    pub parameter: Parameter,
    /// Its identified value (mm or rad).
    pub identified: f64,
    /// Its true value in the identification's parameterisation (mm or rad).
    pub truth: f64,
}

impl serde::Serialize for ParameterError {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut s = serializer.serialize_struct("ParameterError", 4)?;
        s.serialize_field("parameter", &self.parameter.to_string())?;
        s.serialize_field("unit", self.parameter.unit())?;
        s.serialize_field("identified", &self.identified)?;
        s.serialize_field("truth", &self.truth)?;
        s.end()
    }
}

/// An identification against the truth (module docs); serialized with these field names,
/// as `tablec calibrate --json` writes it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TruthComparison {
    /// Every parameter the reference identifies, in column order, with the calibration's
    /// value (zero where it held the parameter at nominal or could not identify it).
    pub parameters: Vec<ParameterError>,
    /// Of them, the parameters the calibration did not identify (counted at zero).
    pub missed: usize,
    /// Parameters the calibration identified and the reference did not: not compared.
    pub not_compared: usize,
    /// RMS of identified − true over the compared lengths, mm; `None` without one.
    pub length_rms_mm: Option<f64>,
    /// RMS of identified − true over the compared angles, mrad; `None` without one.
    pub angle_rms_mrad: Option<f64>,
    /// Workspace poses.
    pub poses: usize,
    /// Mean of `|p̂(q) − p(q)|` over the poses, mm.
    pub position_mean_mm: f64,
    /// RMS of `|p̂(q) − p(q)|`, mm.
    pub position_rms_mm: f64,
    /// Largest `|p̂(q) − p(q)|`, mm.
    pub position_max_mm: f64,
}

/// A pose error: position (mm) and orientation (rotation vector, rad), base frame.
pub type PoseError = ([f64; 3], [f64; 3]);

/// The true robot's exact pose error at each of `poses`, noise-free: position
/// (actual − nominal, mm) and orientation (`log(R_actual · R_nominalᵀ)`, rad), base frame,
/// as `tablec simulate` measures it.
///
/// # Errors
///
/// [`TruthError::Scenario`] when the scenario does not fit the robot.
pub fn true_errors(
    robot: &Robot,
    scenario: &Scenario,
    poses: &[Vec<f64>],
) -> Result<Vec<PoseError>, TruthError> {
    let actual = scenario.actual_robot(robot).map_err(Box::new)?;
    Ok(poses
        .iter()
        .map(|q| {
            let e = pose_error(&robot.tcp_pose(q), &scenario.actual_pose(&actual, q));
            ([e[0], e[1], e[2]], [e[3], e[4], e[5]])
        })
        .collect())
}

/// The reference identification: `options`' identification of the scenario's exact
/// errors at `poses` (module docs), position only, or with orientation when the
/// calibration it is for measured orientation too.
///
/// # Errors
///
/// As [`true_errors`] and [`identify`].
pub fn reference(
    robot: &Robot,
    scenario: &Scenario,
    poses: &[Vec<f64>],
    orientation: bool,
    options: &CalibrateOptions,
) -> Result<Calibration, TruthError> {
    let errors = true_errors(robot, scenario, poses)?;
    let nominal: Vec<_> = poses.iter().map(|q| robot.tcp_pose(q)).collect();
    let samples = SampleSet {
        nominal_mm: nominal
            .iter()
            .map(|pose| pose.translation.vector.into())
            .collect(),
        error_mm: errors.iter().map(|(p, _)| *p).collect(),
        nominal_rotation: orientation.then(|| {
            nominal
                .iter()
                .map(|pose| pose.rotation.to_rotation_matrix())
                .collect()
        }),
        rotation_error_rad: orientation.then(|| errors.iter().map(|(_, r)| *r).collect()),
        joints: Some(Joints::from_flat(
            robot.joint_count(),
            poses.iter().flatten().copied().collect(),
        )),
        config: None,
        lines: (1..=poses.len() as u64).collect(),
        repeats: None,
    };
    identify(robot, &samples, options).map_err(|e| Box::new(e).into())
}

/// Compares `calibration` of `robot` with the truth of `scenario` at the workspace poses
/// `poses` (joint values, rad; mm for prismatic joints), the reference identified with
/// `options` (those of the calibration).
///
/// # Errors
///
/// [`TruthError::Poses`] for no pose, more than [`MAX_POSES`], or a pose of another joint
/// count; as [`reference`](fn@reference); [`TruthError::NonFinite`] for a non-finite figure.
pub fn compare(
    robot: &Robot,
    scenario: &Scenario,
    calibration: &Calibration,
    poses: &[Vec<f64>],
    options: &CalibrateOptions,
) -> Result<TruthComparison, TruthError> {
    if poses.is_empty() || poses.len() > MAX_POSES {
        return Err(TruthError::Poses(format!(
            "{} workspace poses: give 1 to {MAX_POSES}",
            poses.len()
        )));
    }
    if let Some(q) = poses.iter().find(|q| q.len() != robot.joint_count()) {
        return Err(TruthError::Poses(format!(
            "a workspace pose has {} joint values, the {} {} joints",
            q.len(),
            robot.name,
            robot.joint_count()
        )));
    }
    let orientation = calibration.orientation_rms_rad.is_some();
    let truth = reference(robot, scenario, poses, orientation, options)?;
    let parameters: Vec<ParameterError> = truth
        .parameters
        .iter()
        .filter(|p| truth.identified.contains(p))
        .map(|&parameter| ParameterError {
            parameter,
            identified: calibration.value(parameter),
            truth: truth.value(parameter),
        })
        .collect();
    let missed = parameters
        .iter()
        .filter(|p| !calibration.identified.contains(&p.parameter))
        .count();
    let not_compared = calibration
        .identified
        .iter()
        .filter(|p| !truth.identified.contains(p))
        .count();
    let rms = |lengths: bool, unit: f64| {
        let d: Vec<f64> = parameters
            .iter()
            .filter(|p| p.parameter.is_length() == lengths)
            .map(|p| (p.identified - p.truth) * unit)
            .collect();
        (!d.is_empty()).then(|| (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt())
    };
    let length_rms_mm = rms(true, 1.0);
    let angle_rms_mrad = rms(false, 1e3);
    let norms: Vec<f64> = true_errors(robot, scenario, poses)?
        .iter()
        .zip(poses)
        .map(|((e, _), q)| {
            let (predicted, _) = calibration.predict_error(q);
            (Vector3::from(predicted) - Vector3::from(*e)).norm()
        })
        .collect();
    let n = norms.len() as f64;
    let comparison = TruthComparison {
        parameters,
        missed,
        not_compared,
        length_rms_mm,
        angle_rms_mrad,
        poses: poses.len(),
        position_mean_mm: norms.iter().sum::<f64>() / n,
        position_rms_mm: (norms.iter().map(|v| v * v).sum::<f64>() / n).sqrt(),
        position_max_mm: norms.iter().copied().fold(0.0, f64::max),
    };
    let figures = [
        comparison.length_rms_mm.unwrap_or(0.0),
        comparison.angle_rms_mrad.unwrap_or(0.0),
        comparison.position_rms_mm,
        comparison.position_max_mm,
    ];
    if !figures.iter().all(|v| v.is_finite()) {
        return Err(TruthError::NonFinite("a parameter or position error"));
    }
    Ok(comparison)
}

#[cfg(test)]
mod tests {
    use super::*;
    use adwi_robot::error_model::MdhParameter;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn kr150() -> Robot {
        Robot::load(adwi_robot::model::shipped_robot_path("kr150-2")).unwrap()
    }

    fn scenario(name: &str) -> Scenario {
        let path = adwi_robot::model::shipped_robot_path("kr150-2")
            .parent()
            .unwrap()
            .join(name);
        Scenario::load(path).unwrap()
    }

    /// Joint vectors drawn within the sampling ranges.
    fn poses(robot: &Robot, n: usize, seed: u64) -> Vec<Vec<f64>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                (0..robot.joint_count())
                    .map(|i| {
                        let [lo, hi] = robot.sampling_range(i);
                        rng.gen_range(lo..=hi)
                    })
                    .collect()
            })
            .collect()
    }

    /// On a geometric-only scenario the reference finds the scenario's deviations where
    /// the model has no redundancy, and an identification from exact errors at other
    /// poses has next to no parameter or position error.
    #[test]
    fn the_reference_of_a_geometric_scenario_is_its_deviations() {
        let robot = kr150();
        let s = scenario("scenario_geometric.toml");
        let options = CalibrateOptions::default();
        let workspace = poses(&robot, 300, 1);
        let truth = reference(&robot, &s, &workspace, false, &options).unwrap();
        assert!(truth.position_rms_mm < 1e-4, "{}", truth.position_rms_mm);
        for (joint, parameter, expected) in [
            (1, MdhParameter::A, s.deviations[1].a_mm),
            (2, MdhParameter::A, s.deviations[2].a_mm),
            (1, MdhParameter::Alpha, s.deviations[1].alpha_rad),
            (2, MdhParameter::Theta, s.deviations[2].theta_rad),
        ] {
            let p = Parameter::Mdh { joint, parameter };
            assert!(truth.identified.contains(&p), "{p}");
            let value = truth.value(p);
            let tolerance = if p.is_length() { 1e-4 } else { 1e-7 };
            assert!(
                (value - expected).abs() < tolerance,
                "{p}: {value} vs {expected}"
            );
        }
        let other = poses(&robot, 200, 2);
        let c = reference(&robot, &s, &other, false, &options).unwrap();
        let t = compare(&robot, &s, &c, &workspace, &options).unwrap();
        assert!(t.parameters.len() > 20, "{}", t.parameters.len());
        // Exact data leave micrometres at most, and the parameters no other parameter can
        // stand in for come out as they are; which of a pair of exactly redundant ones is
        // kept (Δd₁ or the base's z) may differ between pose sets, and the comparison then
        // counts the one not kept at zero: the position error is the figure that does not
        // depend on the parameterisation.
        assert!(t.position_max_mm < 1e-3, "{}", t.position_max_mm);
        for p in &t.parameters {
            if let Parameter::Mdh {
                joint: 1..=3,
                parameter: MdhParameter::A | MdhParameter::Alpha,
            } = p.parameter
            {
                let tolerance = if p.parameter.is_length() { 1e-4 } else { 1e-7 };
                assert!((p.identified - p.truth).abs() < tolerance, "{p:?}");
            }
        }
        let same = compare(&robot, &s, &truth, &workspace, &options).unwrap();
        assert_eq!(same.length_rms_mm, Some(0.0));
        assert_eq!(same.not_compared, 0);
    }

    /// The position error is `|p̂ − p|` computed outright from the two robots, and the
    /// nominal model (nothing identified) leaves the scenario's whole error.
    #[test]
    fn the_position_error_is_the_models_distance_to_the_true_robot() {
        let robot = kr150();
        let s = scenario("scenario.toml");
        let options = CalibrateOptions::default();
        let workspace = poses(&robot, 100, 3);
        let c = reference(&robot, &s, &poses(&robot, 150, 4), true, &options).unwrap();
        let t = compare(&robot, &s, &c, &workspace, &options).unwrap();
        let actual = s.actual_robot(&robot).unwrap();
        let direct: Vec<f64> = workspace
            .iter()
            .map(|q| {
                let truth = s.actual_pose(&actual, q).translation.vector;
                let model =
                    robot.tcp_pose(q).translation.vector + Vector3::from(c.predict_error(q).0);
                (model - truth).norm()
            })
            .collect();
        let mean = direct.iter().sum::<f64>() / direct.len() as f64;
        assert!((t.position_mean_mm - mean).abs() < 1e-9);
        // Gears and compliance remain: the best kinematic model leaves some of them.
        assert!(t.position_mean_mm > 1e-3, "{}", t.position_mean_mm);
        let raw: f64 = true_errors(&robot, &s, &workspace)
            .unwrap()
            .iter()
            .map(|(e, _)| Vector3::from(*e).norm())
            .sum::<f64>()
            / workspace.len() as f64;
        assert!(
            t.position_mean_mm < 0.5 * raw,
            "{} vs {raw}",
            t.position_mean_mm
        );
    }

    #[test]
    fn poses_are_counted_and_checked() {
        let robot = kr150();
        let s = scenario("scenario_geometric.toml");
        let options = CalibrateOptions::default();
        let c = reference(&robot, &s, &poses(&robot, 50, 5), false, &options).unwrap();
        let e = compare(&robot, &s, &c, &[], &options).unwrap_err();
        assert!(e.to_string().contains("0 workspace poses"), "{e}");
        let e = compare(&robot, &s, &c, &[vec![0.0; 5]], &options).unwrap_err();
        assert!(e.to_string().contains("5 joint values"), "{e}");
    }
}
