//! The error simulator: sample databases of a robot whose error sources are known.
//!
//! For every nominal pose of a [`SamplingPlan`] the simulator picks one inverse-kinematics
//! solution of the nominal model (the commanded joint angles) and computes where the robot
//! *actually* goes, exactly — never through the linear error model:
//!
//! 1. the geometry is nominal plus the scenario's MD-H deviations (Δa, Δd, Δα, Δθ, Δβ);
//! 2. each joint deflects under gravity: `Δq = K⁻¹ · τ`, with `τ` the gravity torques of the
//!    payload (and of any link masses) on the actual geometry at the commanded angles;
//! 3. each gear adds a small periodic transmission error `A · sin(n · q + φ)`;
//! 4. the actual pose is the forward kinematics of the actual geometry at the commanded
//!    angles plus both deflections;
//! 5. a laser tracker measures it with isotropic Gaussian noise whose σ grows with the
//!    distance to the tracker.
//!
//! The sample's error is measured − nominal: position in mm and orientation as the rotation
//! vector of `R_measured · R_nominalᵀ`, both in the base frame.
//!
//! Everything random comes from ChaCha8 seeded by the plan's seed (stream 0 for poses,
//! stream 1 for noise), and every number is written with a fixed number of decimals, so the
//! same inputs give the same file byte for byte.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use adwi_runtime::kinematics::{forward, link_frames, MdhJoint};
use nalgebra::{Isometry3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;

use crate::error_model::{apply_deviations, JointDeviation, MdhDeviations};
use crate::model::{isometry_from_parts, isometry_from_transform};
use crate::{Configuration, IkError, InverseKinematics, Robot, JOINT_COUNT};
use adwi_compile::pose::{
    kuka_abc_deg_from_rotation, orientation_error, rotation_from_kuka_abc_deg, rotation_from_vector,
};

/// Standard gravity, m/s².
const GRAVITY_M_PER_S2: f64 = 9.80665;

/// The sample file's header row.
pub const CSV_HEADER: &str = "x,y,z,a,b,c,dx,dy,dz,rx,ry,rz,j1,j2,j3,j4,j5,j6,config";

/// What can go wrong in a simulation.
#[derive(Debug, thiserror::Error)]
pub enum SimulateError {
    /// The scenario file could not be read.
    #[error("cannot read scenario file {path}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: io::Error,
    },
    /// The scenario file is not a valid scenario.
    #[error("scenario file {path} is not a valid error scenario")]
    Parse {
        /// The file (empty when parsed from text).
        path: PathBuf,
        /// The TOML error, with line and column.
        #[source]
        source: toml::de::Error,
    },
    /// A scenario value is unusable.
    #[error("scenario: {0}")]
    InvalidScenario(String),
    /// A sampling plan value is unusable.
    #[error("sampling plan: {0}")]
    InvalidPlan(String),
    /// The robot has no closed-form inverse kinematics.
    #[error(transparent)]
    Kinematics(#[from] IkError),
    /// A nominal pose has no inverse-kinematics solution within the joint limits.
    #[error(
        "pose {index} (x {:.3}, y {:.3}, z {:.3} mm; A {:.3}, B {:.3}, C {:.3} deg) is not \
         reachable within the joint limits{}",
        position_mm[0], position_mm[1], position_mm[2], abc_deg[0], abc_deg[1], abc_deg[2],
        config.map(|c| format!(" in configuration {c}")).unwrap_or_default()
    )]
    Unreachable {
        /// 0-based index in the plan.
        index: usize,
        /// Nominal position, mm.
        position_mm: [f64; 3],
        /// Nominal orientation, KUKA degrees.
        abc_deg: [f64; 3],
        /// The configuration the plan asked for, if any.
        config: Option<Configuration>,
    },
}

// ---------------------------------------------------------------------------------------
// Scenario

/// The error sources of one simulated robot, as read from a scenario TOML file.
///
/// ```toml
/// [[joints]]                    # six of these, joint 1 first
/// delta_a_mm = 0.2              # MD-H deviations
/// delta_d_mm = -0.1
/// delta_alpha_deg = 0.01
/// delta_theta_deg = -0.02
/// delta_beta_deg = 0.0
/// stiffness_nm_per_rad = 8.0e6  # joint stiffness, N·m/rad (absent: rigid)
/// gear_amplitude_deg = 0.003    # periodic transmission error A·sin(n·q + φ)
/// gear_periods_per_rev = 2.0
/// gear_phase_deg = 30.0
///
/// [payload]                     # optional
/// mass_kg = 120.0
/// centre_of_gravity_mm = [0.0, 0.0, 250.0]   # flange frame
///
/// [[link_masses]]               # optional, any number
/// joint = 2                     # the link joint 2 moves, frame 2
/// mass_kg = 250.0
/// centre_of_gravity_mm = [-600.0, 0.0, 0.0]
///
/// [measurement]                 # optional: no noise when absent
/// tracker_position_mm = [4000.0, -1500.0, 0.0]   # base frame
/// sigma_mm = 0.015              # σ per axis = sigma_mm + sigma_per_m_mm · distance in m
/// sigma_per_m_mm = 0.006
/// orientation_sigma_rad = 0.0   # per axis, on the rotation vector
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// Geometric MD-H deviations per joint.
    pub deviations: MdhDeviations,
    /// Per-joint stiffness, N·m/rad; `None` for a rigid joint.
    pub stiffness_nm_per_rad: [Option<f64>; JOINT_COUNT],
    /// Per-joint periodic gear transmission error.
    pub gears: [GearError; JOINT_COUNT],
    /// Point masses loading the joints: the payload and any link masses.
    pub masses: Vec<PointMass>,
    /// The laser tracker's noise model.
    pub measurement: Measurement,
}

/// A periodic transmission error `amplitude · sin(periods_per_rev · q + phase)`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GearError {
    /// Amplitude, rad.
    pub amplitude_rad: f64,
    /// Periods per revolution of the joint.
    pub periods_per_rev: f64,
    /// Phase, rad.
    pub phase_rad: f64,
}

impl GearError {
    /// The joint angle error at joint angle `q_rad`, rad.
    pub fn deflection_rad(&self, q_rad: f64) -> f64 {
        self.amplitude_rad * (self.periods_per_rev * q_rad + self.phase_rad).sin()
    }
}

/// A point mass riding on one link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointMass {
    /// The link it rides on: 1..=6 is the link moved by that joint, expressed in that
    /// joint's frame (6 is the flange frame, where the payload is).
    pub link: usize,
    /// Mass, kg.
    pub mass_kg: f64,
    /// Centre of gravity in the link's frame, mm.
    pub centre_of_gravity_mm: [f64; 3],
}

/// Laser-tracker noise: isotropic, σ per axis = `sigma_mm + sigma_per_m_mm · distance_m`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Measurement {
    /// Tracker position, base frame, mm.
    pub tracker_position_mm: [f64; 3],
    /// Distance-independent σ per axis, mm.
    pub sigma_mm: f64,
    /// σ per axis added per metre of distance to the tracker, mm/m.
    pub sigma_per_m_mm: f64,
    /// σ per axis of the orientation noise (rotation vector), rad.
    pub orientation_sigma_rad: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ScenarioFile {
    joints: Vec<ScenarioJointFile>,
    payload: Option<MassFile>,
    #[serde(default)]
    link_masses: Vec<LinkMassFile>,
    measurement: Option<MeasurementFile>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct ScenarioJointFile {
    #[serde(default)]
    delta_a_mm: f64,
    #[serde(default)]
    delta_d_mm: f64,
    #[serde(default)]
    delta_alpha_deg: f64,
    #[serde(default)]
    delta_theta_deg: f64,
    #[serde(default)]
    delta_beta_deg: f64,
    stiffness_nm_per_rad: Option<f64>,
    #[serde(default)]
    gear_amplitude_deg: f64,
    #[serde(default)]
    gear_periods_per_rev: f64,
    #[serde(default)]
    gear_phase_deg: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MassFile {
    mass_kg: f64,
    centre_of_gravity_mm: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LinkMassFile {
    joint: usize,
    mass_kg: f64,
    centre_of_gravity_mm: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MeasurementFile {
    tracker_position_mm: [f64; 3],
    sigma_mm: f64,
    #[serde(default)]
    sigma_per_m_mm: f64,
    #[serde(default)]
    orientation_sigma_rad: f64,
}

impl Scenario {
    /// A scenario with no error at all: the simulated robot is the nominal one.
    pub fn perfect() -> Scenario {
        Scenario {
            deviations: [JointDeviation::default(); JOINT_COUNT],
            stiffness_nm_per_rad: [None; JOINT_COUNT],
            gears: [GearError::default(); JOINT_COUNT],
            masses: Vec::new(),
            measurement: Measurement::default(),
        }
    }

    /// Reads a scenario file.
    ///
    /// # Errors
    ///
    /// [`SimulateError::Read`], [`SimulateError::Parse`], or
    /// [`SimulateError::InvalidScenario`] as in [`Scenario::from_toml_str`].
    pub fn load(path: impl AsRef<Path>) -> Result<Scenario, SimulateError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| SimulateError::Read {
            path: path.to_owned(),
            source,
        })?;
        Scenario::from_toml_str(&text).map_err(|error| match error {
            SimulateError::Parse { source, .. } => SimulateError::Parse {
                path: path.to_owned(),
                source,
            },
            other => other,
        })
    }

    /// Parses a scenario given as TOML text (format in the type's docs).
    ///
    /// # Errors
    ///
    /// [`SimulateError::Parse`] for malformed TOML or unknown keys;
    /// [`SimulateError::InvalidScenario`] for a joint count other than six, a non-finite
    /// value, a non-positive stiffness, a negative mass or σ, or a link number outside 1..=6.
    pub fn from_toml_str(text: &str) -> Result<Scenario, SimulateError> {
        let file: ScenarioFile = toml::from_str(text).map_err(|source| SimulateError::Parse {
            path: PathBuf::new(),
            source,
        })?;
        let invalid = |message: String| SimulateError::InvalidScenario(message);
        if file.joints.len() != JOINT_COUNT {
            return Err(invalid(format!(
                "{JOINT_COUNT} [[joints]] needed, the file lists {}",
                file.joints.len()
            )));
        }
        let mut scenario = Scenario::perfect();
        for (i, joint) in file.joints.iter().enumerate() {
            let number = i + 1;
            let values = [
                ("delta_a_mm", joint.delta_a_mm),
                ("delta_d_mm", joint.delta_d_mm),
                ("delta_alpha_deg", joint.delta_alpha_deg),
                ("delta_theta_deg", joint.delta_theta_deg),
                ("delta_beta_deg", joint.delta_beta_deg),
                ("gear_amplitude_deg", joint.gear_amplitude_deg),
                ("gear_periods_per_rev", joint.gear_periods_per_rev),
                ("gear_phase_deg", joint.gear_phase_deg),
            ];
            for (name, value) in values {
                if !value.is_finite() {
                    return Err(invalid(format!("joint {number} {name} is not finite")));
                }
            }
            if let Some(k) = joint.stiffness_nm_per_rad {
                if !(k.is_finite() && k > 0.0) {
                    return Err(invalid(format!(
                        "joint {number} stiffness_nm_per_rad = {k} must be positive \
                         (leave it out for a rigid joint)"
                    )));
                }
            }
            scenario.deviations[i] = JointDeviation {
                a_mm: joint.delta_a_mm,
                d_mm: joint.delta_d_mm,
                alpha_rad: joint.delta_alpha_deg.to_radians(),
                theta_rad: joint.delta_theta_deg.to_radians(),
                beta_rad: joint.delta_beta_deg.to_radians(),
            };
            scenario.stiffness_nm_per_rad[i] = joint.stiffness_nm_per_rad;
            scenario.gears[i] = GearError {
                amplitude_rad: joint.gear_amplitude_deg.to_radians(),
                periods_per_rev: joint.gear_periods_per_rev,
                phase_rad: joint.gear_phase_deg.to_radians(),
            };
        }
        let masses = file
            .payload
            .iter()
            .map(|p| (JOINT_COUNT, "payload", p.mass_kg, p.centre_of_gravity_mm))
            .chain(
                file.link_masses
                    .iter()
                    .map(|m| (m.joint, "link mass", m.mass_kg, m.centre_of_gravity_mm)),
            );
        for (link, what, mass_kg, centre_of_gravity_mm) in masses {
            if !(1..=JOINT_COUNT).contains(&link) {
                return Err(invalid(format!(
                    "{what}: joint = {link} must be 1..={JOINT_COUNT}"
                )));
            }
            let finite_cog = centre_of_gravity_mm.iter().all(|v| v.is_finite());
            if !(mass_kg.is_finite() && mass_kg >= 0.0 && finite_cog) {
                return Err(invalid(format!(
                    "{what}: mass_kg must be finite and ≥ 0, centre_of_gravity_mm finite"
                )));
            }
            scenario.masses.push(PointMass {
                link,
                mass_kg,
                centre_of_gravity_mm,
            });
        }
        if let Some(m) = file.measurement {
            let values = [
                m.sigma_mm,
                m.sigma_per_m_mm,
                m.orientation_sigma_rad,
                m.tracker_position_mm[0],
                m.tracker_position_mm[1],
                m.tracker_position_mm[2],
            ];
            if !values.iter().all(|v| v.is_finite()) || values[..3].iter().any(|v| *v < 0.0) {
                return Err(invalid(
                    "measurement: values must be finite and every σ ≥ 0".into(),
                ));
            }
            scenario.measurement = Measurement {
                tracker_position_mm: m.tracker_position_mm,
                sigma_mm: m.sigma_mm,
                sigma_per_m_mm: m.sigma_per_m_mm,
                orientation_sigma_rad: m.orientation_sigma_rad,
            };
        }
        Ok(scenario)
    }

    /// The actual geometry: nominal plus this scenario's deviations.
    pub fn actual_joints(&self, robot: &Robot) -> [MdhJoint; JOINT_COUNT] {
        apply_deviations(&robot.nominal_joints(), &self.deviations)
    }

    /// The joint deflections (rad) at commanded angles `q_rad` on the actual geometry
    /// `joints`: compliance under the gravity of every mass, plus gear errors.
    ///
    /// A joint yields in the direction gravity pushes it: `Δq_j = τ_j / k_j` with
    /// `τ_j = z_j · ((c − o_j) × m·g)` summed over the masses joint `j` carries.
    pub fn joint_deflections_rad(
        &self,
        joints: &[MdhJoint; JOINT_COUNT],
        q_rad: &[f64; JOINT_COUNT],
    ) -> [f64; JOINT_COUNT] {
        let frames = link_frames(joints, q_rad);
        let mut torque_nm = [0.0; JOINT_COUNT];
        for mass in &self.masses {
            let centre =
                Vector3::from(frames[mass.link - 1].transform_point(mass.centre_of_gravity_mm));
            let weight_n = Vector3::new(0.0, 0.0, -mass.mass_kg * GRAVITY_M_PER_S2);
            for (j, torque) in torque_nm.iter_mut().enumerate().take(mass.link) {
                // Joint j turns about the z axis of the frame before it (the base for j = 0).
                let (axis, origin) = if j == 0 {
                    (Vector3::z(), Vector3::zeros())
                } else {
                    (
                        Vector3::from(frames[j - 1].rotate_vector([0.0, 0.0, 1.0])),
                        Vector3::from(frames[j - 1].translation_mm),
                    )
                };
                // mm · N → N·m.
                *torque += axis.dot(&(centre - origin).cross(&weight_n)) * 1e-3;
            }
        }
        std::array::from_fn(|j| {
            let compliance = self.stiffness_nm_per_rad[j].map_or(0.0, |k| torque_nm[j] / k);
            compliance + self.gears[j].deflection_rad(q_rad[j])
        })
    }

    /// The exact actual TCP pose (before measurement) for commanded angles `q_rad`.
    pub fn actual_pose(&self, robot: &Robot, q_rad: &[f64; JOINT_COUNT]) -> Isometry3<f64> {
        let joints = self.actual_joints(robot);
        let deflection = self.joint_deflections_rad(&joints, q_rad);
        let q_actual: [f64; JOINT_COUNT] = std::array::from_fn(|j| q_rad[j] + deflection[j]);
        isometry_from_transform(&forward(&joints, &robot.tool_transform(), &q_actual))
    }
}

// ---------------------------------------------------------------------------------------
// Sampling plan

/// Where the nominal positions are.
#[derive(Debug, Clone, PartialEq)]
pub enum Positions {
    /// Every point `min + k · step` inside the box `[min, max]` (each axis), x slowest,
    /// z fastest.
    Lattice {
        /// Box corner, mm, base frame.
        min_mm: [f64; 3],
        /// Opposite corner, mm.
        max_mm: [f64; 3],
        /// Spacing, mm.
        step_mm: f64,
    },
    /// `count` points uniformly distributed in the box.
    Random {
        /// How many.
        count: usize,
        /// Box corner, mm, base frame.
        min_mm: [f64; 3],
        /// Opposite corner, mm.
        max_mm: [f64; 3],
    },
}

/// What to sample: positions, the tool orientation, the configuration, the seed.
#[derive(Debug, Clone, PartialEq)]
pub struct SamplingPlan {
    /// The nominal positions.
    pub positions: Positions,
    /// The nominal tool orientation, KUKA A, B, C degrees.
    pub abc_deg: [f64; 3],
    /// When positive, each pose's orientation is the nominal one turned by a random
    /// rotation of angle uniform in `[0, spread]` about a uniformly random axis, degrees.
    pub orientation_spread_deg: f64,
    /// The configuration to use, or `None` for the solution closest to the robot's home
    /// posture.
    pub config: Option<Configuration>,
    /// Seed of every random draw.
    pub seed: u64,
}

/// A nominal pose as written to the file: rounded to the file's decimals first, so that the
/// file's numbers are exactly the pose that was simulated.
#[derive(Debug, Clone, Copy, PartialEq)]
struct NominalPose {
    position_mm: [f64; 3],
    abc_deg: [f64; 3],
}

impl SamplingPlan {
    fn validate(&self) -> Result<(), SimulateError> {
        let invalid = |m: &str| Err(SimulateError::InvalidPlan(m.into()));
        let (min, max) = match &self.positions {
            Positions::Lattice {
                min_mm,
                max_mm,
                step_mm,
            } => {
                if !(step_mm.is_finite() && *step_mm > 0.0) {
                    return invalid("the lattice step must be positive");
                }
                (min_mm, max_mm)
            }
            Positions::Random { min_mm, max_mm, .. } => (min_mm, max_mm),
        };
        if !min.iter().chain(max).all(|v| v.is_finite()) || (0..3).any(|i| min[i] > max[i]) {
            return invalid("the box needs finite corners with min ≤ max on every axis");
        }
        let spread = self.orientation_spread_deg;
        if !(self.abc_deg.iter().all(|v| v.is_finite()) && spread.is_finite() && spread >= 0.0) {
            return invalid("the orientation and its spread must be finite, spread ≥ 0");
        }
        Ok(())
    }

    /// The nominal poses, deterministic in the seed.
    fn poses(&self, rng: &mut ChaCha8Rng) -> Vec<NominalPose> {
        let positions: Vec<[f64; 3]> = match &self.positions {
            Positions::Lattice {
                min_mm,
                max_mm,
                step_mm,
            } => {
                // Counted, not accumulated, so the points are exactly min + k·step; the
                // small slack keeps a max that is a whole number of steps.
                let count =
                    |i: usize| ((max_mm[i] - min_mm[i]) / step_mm + 1e-9).floor() as usize + 1;
                let axis = |i: usize| (0..count(i)).map(move |k| min_mm[i] + k as f64 * step_mm);
                axis(0)
                    .flat_map(|x| axis(1).flat_map(move |y| axis(2).map(move |z| [x, y, z])))
                    .collect()
            }
            Positions::Random {
                count,
                min_mm,
                max_mm,
            } => (0..*count)
                .map(|_| std::array::from_fn(|i| rng.gen_range(min_mm[i]..=max_mm[i])))
                .collect(),
        };
        let nominal_rotation = rotation_from_kuka_abc_deg(self.abc_deg);
        positions
            .into_iter()
            .map(|position| {
                let abc_deg = if self.orientation_spread_deg > 0.0 {
                    let axis = random_unit_vector(rng);
                    let angle = rng
                        .gen_range(0.0..=self.orientation_spread_deg)
                        .to_radians();
                    let turn = rotation_from_vector((axis * angle).into());
                    kuka_abc_deg_from_rotation(&(turn * nominal_rotation))
                } else {
                    self.abc_deg
                };
                NominalPose {
                    position_mm: position.map(round_to_file),
                    abc_deg: abc_deg.map(round_to_file),
                }
            })
            .collect()
    }
}

/// Decimals written for mm and degrees.
const DECIMALS_MM_DEG: usize = 6;
/// Decimals written for radians.
const DECIMALS_RAD: usize = 9;

fn round_to_file(value: f64) -> f64 {
    let scale = 10f64.powi(DECIMALS_MM_DEG as i32);
    (value * scale).round() / scale
}

fn random_unit_vector(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    // Uniform on the sphere: uniform height, uniform azimuth.
    let z: f64 = rng.gen_range(-1.0..=1.0);
    let azimuth: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vector3::new(r * azimuth.cos(), r * azimuth.sin(), z)
}

/// A standard normal draw (Box-Muller), written out so that the stream of numbers depends
/// only on ChaCha8 and this function, not on a distribution crate's version.
fn standard_normal(rng: &mut ChaCha8Rng) -> f64 {
    // 1 − u lies in (0, 1], so the logarithm is finite.
    let u: f64 = 1.0 - rng.gen::<f64>();
    let v: f64 = rng.gen();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

// ---------------------------------------------------------------------------------------
// Simulation

/// One simulated sample: a row of the sample file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulatedSample {
    /// Nominal TCP position, base frame, mm.
    pub position_mm: [f64; 3],
    /// Nominal TCP orientation, KUKA A, B, C degrees.
    pub abc_deg: [f64; 3],
    /// Measured − nominal position, base frame, mm.
    pub error_mm: [f64; 3],
    /// Rotation vector of `R_measured · R_nominalᵀ`, base frame, rad.
    pub orientation_error_rad: [f64; 3],
    /// Commanded joint angles, degrees.
    pub q_deg: [f64; JOINT_COUNT],
    /// Their inverse-kinematics configuration.
    pub config: Configuration,
}

/// Simulates the samples of `plan` on `robot` with the error sources of `scenario`.
///
/// # Errors
///
/// [`SimulateError::InvalidPlan`] for an unusable plan, [`SimulateError::Kinematics`] for a
/// robot without closed-form inverse kinematics, [`SimulateError::Unreachable`] for the
/// first pose that no allowed configuration reaches.
pub fn simulate(
    robot: &Robot,
    scenario: &Scenario,
    plan: &SamplingPlan,
) -> Result<Vec<SimulatedSample>, SimulateError> {
    plan.validate()?;
    let ik = InverseKinematics::new(robot)?;
    let mut pose_rng = ChaCha8Rng::seed_from_u64(plan.seed);
    let mut noise_rng = ChaCha8Rng::seed_from_u64(plan.seed);
    noise_rng.set_stream(1);
    let measurement = &scenario.measurement;
    let tracker = Vector3::from(measurement.tracker_position_mm);

    plan.poses(&mut pose_rng)
        .into_iter()
        .enumerate()
        .map(|(index, nominal)| {
            let rotation = rotation_from_kuka_abc_deg(nominal.abc_deg);
            let target = isometry_from_parts(nominal.position_mm, &rotation);
            let solution =
                ik.solve_one(&target, plan.config)
                    .ok_or(SimulateError::Unreachable {
                        index,
                        position_mm: nominal.position_mm,
                        abc_deg: nominal.abc_deg,
                        config: plan.config,
                    })?;
            let actual = scenario.actual_pose(robot, &solution.q_rad);

            // The tracker's noise, drawn for every sample (even at σ = 0) so that the
            // stream stays aligned whatever the noise levels.
            let position = actual.translation.vector;
            let distance_m = (position - tracker).norm() * 1e-3;
            let sigma_mm = measurement.sigma_mm + measurement.sigma_per_m_mm * distance_m;
            let mut noise = [0.0; 6];
            noise
                .iter_mut()
                .for_each(|n| *n = standard_normal(&mut noise_rng));
            let measured_position =
                position + Vector3::new(noise[0], noise[1], noise[2]) * sigma_mm;
            let turn =
                Vector3::new(noise[3], noise[4], noise[5]) * measurement.orientation_sigma_rad;
            let measured_rotation: Rotation3<f64> =
                rotation_from_vector(turn.into()) * actual.rotation.to_rotation_matrix();

            let error = measured_position - Vector3::from(nominal.position_mm);
            Ok(SimulatedSample {
                position_mm: nominal.position_mm,
                abc_deg: nominal.abc_deg,
                error_mm: error.into(),
                orientation_error_rad: orientation_error(&rotation, &measured_rotation),
                q_deg: solution.q_rad.map(f64::to_degrees),
                config: solution.config,
            })
        })
        .collect()
}

/// Comment lines describing a simulated file: robot, scenario, plan, seed and columns.
///
/// Built from the values, not from a command line, so that the library and the CLI write
/// the same bytes however the command was typed. `scenario_name` is how the scenario is
/// named in the file (e.g. its file name).
pub fn describe(robot: &Robot, scenario_name: &str, plan: &SamplingPlan) -> Vec<String> {
    let range = |min: &[f64; 3], max: &[f64; 3]| {
        format!(
            "x [{}, {}], y [{}, {}], z [{}, {}] mm",
            min[0], max[0], min[1], max[1], min[2], max[2]
        )
    };
    let positions = match &plan.positions {
        Positions::Lattice {
            min_mm,
            max_mm,
            step_mm,
        } => format!("lattice over {}, step {step_mm} mm", range(min_mm, max_mm)),
        Positions::Random {
            count,
            min_mm,
            max_mm,
        } => format!("{count} random poses in {}", range(min_mm, max_mm)),
    };
    let [a, b, c] = plan.abc_deg;
    let config = plan.config.map_or_else(
        || "the configuration closest to the home posture".to_owned(),
        |c| format!("configuration {}", c.bits()),
    );
    vec![
        format!(
            "Simulated samples of the {}, error scenario {scenario_name}, seed {}.",
            robot.name, plan.seed
        ),
        format!(
            "Poses: {positions}; tool A {a}, B {b}, C {c} deg, spread {} deg; {config}.",
            plan.orientation_spread_deg
        ),
        "Columns: nominal x,y,z (mm) and a,b,c (KUKA deg); error = measured - nominal: \
         dx,dy,dz (mm) and rx,ry,rz (rotation vector, rad), base frame; commanded j1..j6 \
         (deg); config (IK branch)."
            .to_owned(),
    ]
}

/// Formats with fixed decimals, writing a rounded negative zero as zero so that a file
/// never depends on the sign of a rounding residue.
fn fixed(value: f64, decimals: usize) -> String {
    let text = format!("{value:.decimals$}");
    match text.strip_prefix('-') {
        Some(rest) if rest.bytes().all(|b| b == b'0' || b == b'.') => rest.to_owned(),
        _ => text,
    }
}

/// Writes samples in the product's sample format ([`CSV_HEADER`]): `#` comment lines
/// first, then the header, then one row per sample with 6 decimals for mm and degrees and
/// 9 for radians.
///
/// # Errors
///
/// Any error of `writer`.
pub fn write_csv(
    samples: &[SimulatedSample],
    comments: &[String],
    mut writer: impl Write,
) -> io::Result<()> {
    for comment in comments {
        for line in comment.lines() {
            writeln!(writer, "# {line}")?;
        }
    }
    writeln!(writer, "{CSV_HEADER}")?;
    for s in samples {
        let mm_deg = s
            .position_mm
            .iter()
            .chain(&s.abc_deg)
            .chain(&s.error_mm)
            .map(|v| fixed(*v, DECIMALS_MM_DEG));
        let rad = s
            .orientation_error_rad
            .iter()
            .map(|v| fixed(*v, DECIMALS_RAD));
        let joints = s.q_deg.iter().map(|v| fixed(*v, DECIMALS_MM_DEG));
        let fields: Vec<String> = mm_deg
            .chain(rad)
            .chain(joints)
            .chain(std::iter::once(s.config.bits().to_string()))
            .collect();
        writeln!(writer, "{}", fields.join(","))?;
    }
    Ok(())
}

/// Position error statistics of samples, mm: `(mean, max)` of `|error|`.
pub fn position_error_stats_mm(samples: &[SimulatedSample]) -> (f64, f64) {
    let norms = samples.iter().map(|s| Vector3::from(s.error_mm).norm());
    let (sum, max) = norms.fold((0.0, 0.0f64), |(sum, max), n| (sum + n, max.max(n)));
    (sum / samples.len().max(1) as f64, max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_model::{deviation_vector, pose_error, pose_error_jacobian};
    use crate::model::shipped_robot_path;

    fn kr150() -> Robot {
        Robot::load(shipped_robot_path("kr150-2")).unwrap()
    }

    fn shipped_scenario() -> Scenario {
        Scenario::load(shipped_robot_path("kr150-2").with_file_name("scenario.toml")).unwrap()
    }

    fn small_lattice() -> SamplingPlan {
        SamplingPlan {
            positions: Positions::Lattice {
                min_mm: [1800.0, 500.0, 900.0],
                max_mm: [2000.0, 700.0, 1100.0],
                step_mm: 100.0,
            },
            abc_deg: [0.0, 90.0, 0.0],
            orientation_spread_deg: 0.0,
            config: None,
            seed: 9,
        }
    }

    fn csv_bytes(robot: &Robot, scenario: &Scenario, plan: &SamplingPlan) -> Vec<u8> {
        let samples = simulate(robot, scenario, plan).unwrap();
        let mut bytes = Vec::new();
        write_csv(&samples, &describe(robot, "test", plan), &mut bytes).unwrap();
        bytes
    }

    #[test]
    fn a_perfect_robot_has_no_error_and_reaches_every_pose() {
        let robot = kr150();
        let samples = simulate(&robot, &Scenario::perfect(), &small_lattice()).unwrap();
        // 3 × 3 × 3, x slowest, z fastest, endpoints included.
        assert_eq!(samples.len(), 27);
        assert_eq!(samples[0].position_mm, [1800.0, 500.0, 900.0]);
        assert_eq!(samples[1].position_mm, [1800.0, 500.0, 1000.0]);
        assert_eq!(samples[26].position_mm, [2000.0, 700.0, 1100.0]);
        for s in &samples {
            assert!(s.error_mm.iter().all(|e| e.abs() < 1e-9), "{s:?}");
            assert!(s.orientation_error_rad.iter().all(|e| e.abs() < 1e-12));
            let pose = robot.tcp_pose(&s.q_deg.map(f64::to_radians));
            let reached = pose.translation.vector;
            assert!((reached - Vector3::from(s.position_mm)).norm() < 1e-9);
        }
    }

    #[test]
    fn the_same_seed_gives_the_same_bytes_and_another_seed_does_not() {
        let robot = kr150();
        let scenario = shipped_scenario();
        let mut plan = small_lattice();
        plan.positions = Positions::Random {
            count: 50,
            min_mm: [1400.0, 100.0, 900.0],
            max_mm: [2100.0, 800.0, 1600.0],
        };
        plan.orientation_spread_deg = 5.0;
        let first = csv_bytes(&robot, &scenario, &plan);
        assert_eq!(first, csv_bytes(&robot, &scenario, &plan));
        plan.seed += 1;
        assert_ne!(first, csv_bytes(&robot, &scenario, &plan));
    }

    #[test]
    fn orientations_stay_within_the_spread() {
        let robot = kr150();
        let mut plan = small_lattice();
        plan.orientation_spread_deg = 3.0;
        let nominal = rotation_from_kuka_abc_deg(plan.abc_deg);
        let samples = simulate(&robot, &Scenario::perfect(), &plan).unwrap();
        let mut largest_deg: f64 = 0.0;
        for s in &samples {
            let turn = rotation_from_kuka_abc_deg(s.abc_deg) * nominal.inverse();
            largest_deg = largest_deg.max(turn.angle().to_degrees());
        }
        assert!(largest_deg <= 3.0 + 1e-5, "{largest_deg}");
        assert!(
            largest_deg > 1.0,
            "the orientations did vary: {largest_deg}"
        );
    }

    #[test]
    fn geometric_errors_follow_the_linear_model_to_second_order() {
        let robot = kr150();
        let mut scenario = Scenario::perfect();
        scenario.deviations = shipped_scenario().deviations;
        let samples = simulate(&robot, &scenario, &small_lattice()).unwrap();
        let delta = deviation_vector(&scenario.deviations);
        for s in &samples {
            let q = s.q_deg.map(f64::to_radians);
            let jacobian =
                pose_error_jacobian(&robot.nominal_joints(), &robot.tool_transform(), &q);
            let linear = jacobian * delta;
            let exact = Vector3::from(s.error_mm);
            let gap = (exact - linear.fixed_rows::<3>(0)).norm();
            // Second order in deviations of ~0.3 mm and ~2e-4 rad: microns.
            assert!(
                gap < 0.005 && exact.norm() > 0.3,
                "gap {gap} of {}",
                exact.norm()
            );
        }
    }

    #[test]
    fn a_payload_makes_the_arm_sag() {
        let robot = kr150();
        let mut scenario = Scenario::perfect();
        scenario.stiffness_nm_per_rad[1] = Some(5.0e6);
        scenario.masses.push(PointMass {
            link: 6,
            mass_kg: 100.0,
            centre_of_gravity_mm: [0.0, 0.0, 0.0],
        });
        let q = [0.0, -45.0, 100.0, 0.0, 30.0, 0.0].map(f64::to_radians);
        let joints = scenario.actual_joints(&robot);
        // Joint 2 (axis along base +y through (350, 0, 750)) carries the weight at the
        // flange: τ = (x_flange − 350 mm) · m·g > 0, and a positive q2 turns the arm down.
        let flange = robot.tcp_pose(&q).translation.vector;
        let shoulder_x_mm = 350.0;
        let expected_nm = (flange.x - shoulder_x_mm) * 1e-3 * 100.0 * GRAVITY_M_PER_S2;
        let deflection = scenario.joint_deflections_rad(&joints, &q);
        assert!(
            (deflection[1] - expected_nm / 5.0e6).abs() < 1e-12,
            "{deflection:?}"
        );
        assert!(deflection
            .iter()
            .enumerate()
            .all(|(j, d)| j == 1 || *d == 0.0));
        let error = pose_error(&robot.tcp_pose(&q), &scenario.actual_pose(&robot, &q));
        assert!(error[2] < -0.1, "the TCP drops: {error:?}");
    }

    #[test]
    fn tracker_noise_has_the_requested_sigma() {
        let robot = kr150();
        let mut scenario = Scenario::perfect();
        scenario.measurement = Measurement {
            tracker_position_mm: [1700.0, 450.0, 1250.0],
            sigma_mm: 0.02,
            sigma_per_m_mm: 0.0,
            orientation_sigma_rad: 1e-5,
        };
        let mut plan = small_lattice();
        plan.positions = Positions::Random {
            count: 2000,
            min_mm: [1400.0, 100.0, 900.0],
            max_mm: [2000.0, 800.0, 1600.0],
        };
        let samples = simulate(&robot, &scenario, &plan).unwrap();
        let n = samples.len() as f64;
        for axis in 0..3 {
            let values = samples.iter().map(|s| s.error_mm[axis]);
            let mean = values.clone().sum::<f64>() / n;
            let sigma = (values.map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
            assert!(mean.abs() < 0.002, "axis {axis}: mean {mean}");
            assert!((sigma - 0.02).abs() < 0.002, "axis {axis}: σ {sigma}");
            let rotation = samples
                .iter()
                .map(|s| s.orientation_error_rad[axis].powi(2));
            let sigma_rad = (rotation.sum::<f64>() / n).sqrt();
            assert!(
                (sigma_rad - 1e-5).abs() < 1e-6,
                "axis {axis}: σ {sigma_rad}"
            );
        }
    }

    #[test]
    fn unreachable_poses_and_bad_scenarios_are_errors_that_say_why() {
        let robot = kr150();
        let mut plan = small_lattice();
        plan.positions = Positions::Lattice {
            min_mm: [4000.0, 0.0, 1000.0],
            max_mm: [4000.0, 0.0, 1000.0],
            step_mm: 100.0,
        };
        let error = simulate(&robot, &Scenario::perfect(), &plan).unwrap_err();
        assert!(matches!(error, SimulateError::Unreachable { index: 0, .. }));
        assert!(error.to_string().contains("x 4000.000"), "{error}");

        let text =
            std::fs::read_to_string(shipped_robot_path("kr150-2").with_file_name("scenario.toml"))
                .unwrap();
        let rigid_is_not_zero = text.replacen(
            "stiffness_nm_per_rad = 6.0e6",
            "stiffness_nm_per_rad = 0.0",
            1,
        );
        let error = Scenario::from_toml_str(&rigid_is_not_zero).unwrap_err();
        assert!(error.to_string().contains("joint 1 stiffness"), "{error}");
        let cut = text.find("[[joints]] # A6").unwrap();
        let error = Scenario::from_toml_str(&text[..cut]).unwrap_err();
        assert!(error.to_string().contains("the file lists 5"), "{error}");
    }

    #[test]
    fn fixed_decimals_never_write_negative_zero() {
        assert_eq!(fixed(-1e-12, 6), "0.000000");
        assert_eq!(fixed(-0.0, 9), "0.000000000");
        assert_eq!(fixed(-0.5, 6), "-0.500000");
        assert_eq!(fixed(1234.5, 6), "1234.500000");
    }
}
