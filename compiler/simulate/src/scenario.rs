//! Error scenarios: what a simulated robot gets wrong (its file format, read and checked),
//! apart from the sampling plans and the simulation that use them.

use super::*;

/// The error sources of one simulated robot, as read from a scenario TOML file.
///
/// ```toml
/// [[joints]]                    # one per joint of the robot, joint 1 first
/// delta_a_mm = 0.2              # MD-H deviations (robots described in MD-H)
/// delta_d_mm = -0.1
/// delta_alpha_deg = 0.01
/// delta_theta_deg = -0.02
/// delta_beta_deg = 0.0
/// # delta_xyz_mm = [0.1, 0.0, -0.2]   # or, for URDF and chain robots, the joint origin's
/// # delta_rpy_deg = [0.01, 0.0, 0.0]  # deviation O' = O·Trans(xyz)·Rot(rpy), and the
/// # delta_offset_deg = 0.02           # offset's (delta_offset_mm for a prismatic joint)
/// stiffness_nm_per_rad = 8.0e6  # joint stiffness, N·m/rad (absent: rigid; revolute only)
/// gear_amplitude_deg = 0.003    # periodic transmission error A·sin(n·q + φ) (revolute only)
/// gear_periods_per_rev = 2.0
/// gear_phase_deg = 30.0
///
/// [payload]                     # optional
/// mass_kg = 120.0
/// centre_of_gravity_mm = [0.0, 0.0, 250.0]   # flange frame
///
/// [[link_masses]]               # optional, any number
/// joint = 2                     # the link joint 2 moves
/// mass_kg = 250.0
/// centre_of_gravity_mm = [-600.0, 0.0, 0.0]
///
/// [measurement]                 # optional: no noise when absent
/// tracker_position_mm = [4000.0, -1500.0, 0.0]   # base frame
/// sigma_mm = 0.015              # σ per axis = sigma_mm + sigma_per_m_mm · distance in m
/// sigma_per_m_mm = 0.006
/// orientation_sigma_rad = 0.0   # per axis, on the rotation vector
/// ```
///
/// A link mass's (and the payload's) centre of gravity is given in its link's frame: MD-H
/// frame `i` for a robot described in MD-H (frame `n`, the flange, for the payload), the
/// joint's frame after its motion for any other robot (the last joint's for the payload).
/// Gravity is −z of the frame poses are given in. Every value must lie in its plausible
/// range ([`adwi_robot::plausible`]). A scenario file names no other file: [`Scenario::load`]
/// reads that one file (a caller checking outputs against inputs needs no more).
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// Geometric MD-H deviations per joint (robots described in MD-H).
    pub deviations: Vec<JointDeviation>,
    /// Geometric origin and offset deviations per joint (any other robot).
    pub origin_deviations: Vec<OriginDeviation>,
    /// Per-joint stiffness, N·m/rad; `None` for a rigid joint.
    pub stiffness_nm_per_rad: Vec<Option<f64>>,
    /// Per-joint periodic gear transmission error.
    pub gears: Vec<GearError>,
    /// Point masses loading the joints: the payload and any link masses.
    pub masses: Vec<PointMass>,
    /// The laser tracker's noise model.
    pub measurement: Measurement,
}

/// How a chain joint's origin and offset deviate: `O' = O · Trans(xyz) · Rot(rpy)`, offset
/// plus `offset`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct OriginDeviation {
    /// Translation, mm, in the origin's frame.
    pub xyz_mm: [f64; 3],
    /// Roll, pitch, yaw, rad (`Rz(yaw)·Ry(pitch)·Rx(roll)`).
    pub rpy_rad: [f64; 3],
    /// Added to the joint's offset, rad (mm for a prismatic joint).
    pub offset: f64,
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
    /// The link it rides on: `1..=n` is the link moved by that joint, expressed in that
    /// link's frame ([`Scenario`]; `n` is the flange, where the payload is).
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
    #[serde(default)]
    delta_xyz_mm: [f64; 3],
    #[serde(default)]
    delta_rpy_deg: [f64; 3],
    delta_offset_deg: Option<f64>,
    delta_offset_mm: Option<f64>,
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
    /// A scenario with no error at all for a robot of `joints` joints: the simulated robot
    /// is the nominal one.
    pub fn perfect(joints: usize) -> Scenario {
        Scenario {
            deviations: vec![JointDeviation::default(); joints],
            origin_deviations: vec![OriginDeviation::default(); joints],
            stiffness_nm_per_rad: vec![None; joints],
            gears: vec![GearError::default(); joints],
            masses: Vec::new(),
            measurement: Measurement::default(),
        }
    }

    /// The number of joints the scenario describes.
    pub fn joint_count(&self) -> usize {
        self.gears.len()
    }

    /// Reads a scenario file.
    ///
    /// # Errors
    ///
    /// [`SimulateError::Read`], [`SimulateError::Parse`], or
    /// [`SimulateError::InvalidScenario`] as in [`Scenario::from_toml_str`].
    pub fn load(path: impl AsRef<Path>) -> Result<Scenario, SimulateError> {
        let path = path.as_ref();
        let text = adwi_runtime::input::read_regular_to_string(path).map_err(|source| {
            SimulateError::Read {
                path: path.to_owned(),
                source,
            }
        })?;
        Scenario::from_toml_str(&text).map_err(|error| match error {
            SimulateError::Parse { source, .. } => SimulateError::Parse {
                path: path.to_owned(),
                source,
            },
            SimulateError::InvalidScenario(message) => {
                SimulateError::InvalidScenario(format!("{}: {message}", path.display()))
            }
            other => other,
        })
    }

    /// Parses a scenario given as TOML text (format in the type's docs).
    ///
    /// # Errors
    ///
    /// [`SimulateError::Parse`] for malformed TOML or unknown keys;
    /// [`SimulateError::InvalidScenario`] for a joint count outside 1 to 12, a value
    /// outside its plausible range ([`adwi_robot::plausible`]: a deviation beyond 1 km or 720°,
    /// a stiffness below 100 N·m/rad, a mass beyond 10⁶ kg, a σ beyond 1 m, ...), with the
    /// joint and key, or a link number outside the joints.
    pub fn from_toml_str(text: &str) -> Result<Scenario, SimulateError> {
        let file: ScenarioFile = toml::from_str(text).map_err(|error| SimulateError::Parse {
            path: PathBuf::new(),
            source: adwi_robot::toml_error::TomlError::new(&error, text),
        })?;
        let invalid = |message: String| SimulateError::InvalidScenario(message);
        let n = file.joints.len();
        if n == 0 || n > MAX_JOINTS {
            return Err(invalid(format!(
                "1 to {MAX_JOINTS} [[joints]] needed, the file lists {n}"
            )));
        }
        let mut scenario = Scenario::perfect(n);
        for (i, joint) in file.joints.iter().enumerate() {
            let number = i + 1;
            let offset = match (joint.delta_offset_deg, joint.delta_offset_mm) {
                (Some(_), Some(_)) => {
                    return Err(invalid(format!(
                        "joint {number}: delta_offset_deg or delta_offset_mm, not both"
                    )))
                }
                (Some(deg), None) => deg.to_radians(),
                (None, Some(mm)) => mm,
                (None, None) => 0.0,
            };
            let (offset_key, offset_given, offset_quantity) = match joint.delta_offset_mm {
                Some(mm) => ("delta_offset_mm", mm, Quantity::LengthMm),
                None => (
                    "delta_offset_deg",
                    joint.delta_offset_deg.unwrap_or(0.0),
                    Quantity::AngleDeg,
                ),
            };
            let values = [
                ("delta_a_mm", joint.delta_a_mm, Quantity::LengthMm),
                ("delta_d_mm", joint.delta_d_mm, Quantity::LengthMm),
                ("delta_alpha_deg", joint.delta_alpha_deg, Quantity::AngleDeg),
                ("delta_theta_deg", joint.delta_theta_deg, Quantity::AngleDeg),
                ("delta_beta_deg", joint.delta_beta_deg, Quantity::AngleDeg),
                (offset_key, offset_given, offset_quantity),
                (
                    "gear_amplitude_deg",
                    joint.gear_amplitude_deg,
                    Quantity::GearAmplitudeDeg,
                ),
                (
                    "gear_periods_per_rev",
                    joint.gear_periods_per_rev,
                    Quantity::GearPeriodsPerRev,
                ),
                ("gear_phase_deg", joint.gear_phase_deg, Quantity::AngleDeg),
            ]
            .into_iter()
            .chain(
                joint
                    .delta_xyz_mm
                    .map(|v| ("delta_xyz_mm", v, Quantity::LengthMm)),
            )
            .chain(
                joint
                    .delta_rpy_deg
                    .map(|v| ("delta_rpy_deg", v, Quantity::AngleDeg)),
            );
            for (name, value, quantity) in values {
                check(value, quantity, || format!("joint {number} {name}"))
                    .map_err(|e| invalid(e.to_string()))?;
            }
            if let Some(k) = joint.stiffness_nm_per_rad {
                check(k, Quantity::StiffnessNmPerRad, || {
                    format!("joint {number} stiffness_nm_per_rad (leave it out for a rigid joint)")
                })
                .map_err(|e| invalid(e.to_string()))?;
            }
            scenario.deviations[i] = JointDeviation {
                a_mm: joint.delta_a_mm,
                d_mm: joint.delta_d_mm,
                alpha_rad: joint.delta_alpha_deg.to_radians(),
                theta_rad: joint.delta_theta_deg.to_radians(),
                beta_rad: joint.delta_beta_deg.to_radians(),
            };
            scenario.origin_deviations[i] = OriginDeviation {
                xyz_mm: joint.delta_xyz_mm,
                rpy_rad: joint.delta_rpy_deg.map(f64::to_radians),
                offset,
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
            .map(|p| (n, "payload", p.mass_kg, p.centre_of_gravity_mm))
            .chain(
                file.link_masses
                    .iter()
                    .map(|m| (m.joint, "link mass", m.mass_kg, m.centre_of_gravity_mm)),
            );
        for (link, what, mass_kg, centre_of_gravity_mm) in masses {
            if !(1..=n).contains(&link) {
                return Err(invalid(format!("{what}: joint = {link} must be 1..={n}")));
            }
            check(mass_kg, Quantity::MassKg, || format!("{what} mass_kg"))
                .and_then(|()| {
                    check_all(&centre_of_gravity_mm, Quantity::LengthMm, || {
                        format!("{what} centre_of_gravity_mm")
                    })
                })
                .map_err(|e| invalid(e.to_string()))?;
            scenario.masses.push(PointMass {
                link,
                mass_kg,
                centre_of_gravity_mm,
            });
        }
        if let Some(m) = file.measurement {
            check_all(&m.tracker_position_mm, Quantity::LengthMm, || {
                "measurement tracker_position_mm".into()
            })
            .and_then(|()| {
                check(m.sigma_mm, Quantity::SigmaMm, || {
                    "measurement sigma_mm".into()
                })
            })
            .and_then(|()| {
                check(m.sigma_per_m_mm, Quantity::SigmaMm, || {
                    "measurement sigma_per_m_mm".into()
                })
            })
            .and_then(|()| {
                check(m.orientation_sigma_rad, Quantity::SigmaRad, || {
                    "measurement orientation_sigma_rad".into()
                })
            })
            .map_err(|e| invalid(e.to_string()))?;
            scenario.measurement = Measurement {
                tracker_position_mm: m.tracker_position_mm,
                sigma_mm: m.sigma_mm,
                sigma_per_m_mm: m.sigma_per_m_mm,
                orientation_sigma_rad: m.orientation_sigma_rad,
            };
        }
        Ok(scenario)
    }

    /// The actual robot: nominal plus this scenario's geometric deviations.
    ///
    /// # Errors
    ///
    /// [`SimulateError::InvalidScenario`] when the scenario's joint count is not the
    /// robot's, when it gives MD-H deviations for a robot not described in MD-H (or origin
    /// deviations for one that is), when a prismatic joint has a stiffness or a gear error,
    /// or when the deviated robot is not valid.
    pub fn actual_robot(&self, robot: &Robot) -> Result<Robot, SimulateError> {
        let invalid = |message: String| SimulateError::InvalidScenario(message);
        let n = robot.joint_count();
        if self.joint_count() != n {
            return Err(invalid(format!(
                "the scenario has {} [[joints]], the robot {n} joints",
                self.joint_count()
            )));
        }
        for i in 0..n {
            if robot.joint_kind(i) == JointKind::Prismatic
                && (self.stiffness_nm_per_rad[i].is_some() || self.gears[i].amplitude_rad != 0.0)
            {
                return Err(invalid(format!(
                    "joint {}: stiffness and gear errors model revolute joints; joint {} is prismatic",
                    i + 1,
                    i + 1
                )));
            }
        }
        let geometry = match robot.geometry() {
            Geometry::Mdh(rows) => {
                if self
                    .origin_deviations
                    .iter()
                    .any(|d| *d != OriginDeviation::default())
                {
                    return Err(invalid(format!(
                        "{} is described in MD-H: give its deviations as delta_a_mm, \
                         delta_d_mm, delta_alpha_deg, delta_theta_deg, delta_beta_deg",
                        robot.name
                    )));
                }
                Geometry::Mdh(apply_deviations(rows, &self.deviations))
            }
            Geometry::Chain(joints) => {
                if self
                    .deviations
                    .iter()
                    .any(|d| *d != JointDeviation::default())
                {
                    return Err(invalid(format!(
                        "{}'s joints are not MD-H rows: give its deviations as delta_xyz_mm, \
                         delta_rpy_deg, delta_offset_deg (delta_offset_mm)",
                        robot.name
                    )));
                }
                Geometry::Chain(
                    joints
                        .iter()
                        .zip(&self.origin_deviations)
                        .map(|(j, d)| {
                            let mut j = *j;
                            j.origin = j
                                .origin
                                .compose(&transform_from_xyz_rpy(d.xyz_mm, d.rpy_rad));
                            j.offset += d.offset;
                            j
                        })
                        .collect(),
                )
            }
        };
        robot
            .with_geometry(robot.name.clone(), geometry, robot.base(), robot.tool())
            .map_err(|e| invalid(format!("the deviated robot is invalid: {e}")))
    }

    /// The actual MD-H geometry of an MD-H robot: nominal plus this scenario's deviations.
    ///
    /// # Panics
    ///
    /// When the robot is not described in MD-H or the joint counts differ.
    pub fn actual_joints(&self, robot: &Robot) -> Vec<MdhJoint> {
        apply_deviations(robot.mdh().expect("an MD-H robot"), &self.deviations)
    }

    /// The joint deflections (rad) at commanded values `q` on the actual robot `actual`
    /// ([`Scenario::actual_robot`]): compliance under the gravity of every mass, plus gear
    /// errors.
    ///
    /// A joint yields in the direction gravity pushes it: `Δq_j = τ_j / k_j` with
    /// `τ_j = z_j · ((c − o_j) × m·g)` summed over the masses joint `j` carries.
    ///
    /// # Panics
    ///
    /// When `q` does not have one value per joint.
    pub fn joint_deflections_rad(&self, actual: &Robot, q: &[f64]) -> Vec<f64> {
        let (frames, _) = chain_frames(actual.chain(), q);
        // Each link's frame, in which its masses are given.
        let link_frames: Vec<Transform> = match actual.geometry() {
            Geometry::Mdh(rows) => frames
                .iter()
                .zip(rows)
                .map(|((_, after), row)| after.compose(&mdh_constant_part(row)))
                .collect(),
            Geometry::Chain(_) => frames.iter().map(|(_, after)| *after).collect(),
        };
        let joints = actual.chain().joints();
        let mut torque_nm = vec![0.0; q.len()];
        for mass in &self.masses {
            let centre = Vector3::from(
                link_frames[mass.link - 1].transform_point(mass.centre_of_gravity_mm),
            );
            let weight_n = Vector3::new(0.0, 0.0, -mass.mass_kg * GRAVITY_M_PER_S2);
            for (j, torque) in torque_nm.iter_mut().enumerate().take(mass.link) {
                if joints[j].kind != JointKind::Revolute {
                    continue;
                }
                // Joint j turns about its axis through its frame's origin.
                let before = &frames[j].0;
                let axis = Vector3::from(before.rotate_vector(joints[j].axis));
                let origin = Vector3::from(before.translation_mm);
                // mm · N → N·m.
                *torque += axis.dot(&(centre - origin).cross(&weight_n)) * 1e-3;
            }
        }
        (0..q.len())
            .map(|j| {
                let compliance = self.stiffness_nm_per_rad[j].map_or(0.0, |k| torque_nm[j] / k);
                compliance + self.gears[j].deflection_rad(q[j])
            })
            .collect()
    }

    /// The exact actual TCP pose (before measurement) of the actual robot `actual`
    /// ([`Scenario::actual_robot`]) for commanded values `q`.
    ///
    /// # Panics
    ///
    /// When `q` does not have one value per joint.
    pub fn actual_pose(&self, actual: &Robot, q: &[f64]) -> Isometry3<f64> {
        let deflection = self.joint_deflections_rad(actual, q);
        let q_actual: Vec<f64> = q.iter().zip(&deflection).map(|(q, d)| q + d).collect();
        isometry_from_transform(&actual.tcp_transform(&q_actual))
    }
}

// ---------------------------------------------------------------------------------------
// Sampling plan
