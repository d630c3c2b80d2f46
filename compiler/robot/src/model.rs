//! A robot described as data: the TOML robot file, its validation, and the nominal model.
//!
//! A robot file names the robot, lists six joints with their MD-H parameters and joint
//! limits, gives the tool (TCP in the flange frame) and a home posture. Units are in the key
//! names: `_mm` for lengths, `_deg` for angles. Adding a robot is writing such a file.
//!
//! ```toml
//! name = "KUKA KR150-2"
//! home_deg = [0.0, -90.0, 90.0, 0.0, 0.0, 0.0]
//!
//! [tool]
//! translation_mm = [0.0, 0.0, 0.0]
//! abc_deg = [0.0, 0.0, 0.0]
//!
//! [[joints]]
//! a_mm = 350.0
//! d_mm = 750.0
//! alpha_deg = -90.0
//! beta_deg = 0.0
//! theta_offset_deg = 0.0
//! limits_deg = [-185.0, 185.0]
//! # … five more [[joints]]
//! ```

use std::path::{Path, PathBuf};

use adwi_runtime::kinematics::{self, MdhJoint, Transform};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::Deserialize;

use adwi_compile::pose::rotation_from_kuka_abc_deg;

/// Number of joints of the robots this crate models.
pub const JOINT_COUNT: usize = 6;

/// What can be wrong with a robot file.
#[derive(Debug, thiserror::Error)]
pub enum RobotError {
    /// The file could not be read.
    #[error("cannot read robot file {path}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid TOML or does not have the robot file's keys.
    #[error("robot file {path} is not a valid robot description")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The TOML error, with line and column.
        #[source]
        source: toml::de::Error,
    },
    /// The file lists a number of joints other than six.
    #[error("the robot must have {JOINT_COUNT} [[joints]], the file lists {found}")]
    JointCount {
        /// How many `[[joints]]` tables the file has.
        found: usize,
    },
    /// A number is NaN or infinite.
    #[error("{field} is not a finite number")]
    NonFinite {
        /// Which value, e.g. `joint 2 a_mm`.
        field: String,
    },
    /// A joint's limits are empty or reversed.
    #[error("joint {joint}: limits_deg = [{lower_deg}, {upper_deg}] must have lower < upper")]
    EmptyLimits {
        /// Joint number, 1-based.
        joint: usize,
        /// Lower limit, degrees.
        lower_deg: f64,
        /// Upper limit, degrees.
        upper_deg: f64,
    },
    /// The home posture lies outside a joint's limits.
    #[error("home_deg[{index}] = {home_deg}° is outside joint {joint}'s limits [{lower_deg}, {upper_deg}]", index = joint - 1)]
    HomeOutsideLimits {
        /// Joint number, 1-based.
        joint: usize,
        /// The home angle, degrees.
        home_deg: f64,
        /// Lower limit, degrees.
        lower_deg: f64,
        /// Upper limit, degrees.
        upper_deg: f64,
    },
}

/// The robot file as written, before validation.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RobotFile {
    name: String,
    joints: Vec<JointFile>,
    #[serde(default)]
    tool: ToolFile,
    home_deg: Option<[f64; JOINT_COUNT]>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct JointFile {
    a_mm: f64,
    d_mm: f64,
    alpha_deg: f64,
    #[serde(default)]
    beta_deg: f64,
    #[serde(default)]
    theta_offset_deg: f64,
    limits_deg: [f64; 2],
}

#[derive(Debug, Clone, Copy, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct ToolFile {
    #[serde(default)]
    translation_mm: [f64; 3],
    #[serde(default)]
    abc_deg: [f64; 3],
}

/// One joint: its nominal MD-H geometry and the range its joint variable may take.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Joint {
    /// Nominal MD-H parameters (mm, rad).
    pub mdh: MdhJoint,
    /// `[lower, upper]` limits of the joint variable `q` (not of `θ = q + θ_offset`), rad.
    pub limits_rad: [f64; 2],
}

/// A validated robot: six joints, a tool and a home posture.
#[derive(Debug, Clone, PartialEq)]
pub struct Robot {
    /// Human-readable name, e.g. "KUKA KR150-2".
    pub name: String,
    /// The joints, base to flange.
    pub joints: [Joint; JOINT_COUNT],
    /// The tool centre point (TCP) in the flange frame.
    pub tool: Isometry3<f64>,
    /// A reference posture (rad): among several inverse-kinematics solutions, the one
    /// closest to it is the default, and joints with more than a turn of travel are wrapped
    /// toward it.
    pub home_rad: [f64; JOINT_COUNT],
}

impl Robot {
    /// Reads and validates a robot file.
    ///
    /// # Errors
    ///
    /// [`RobotError::Read`] if the file cannot be read, [`RobotError::Parse`] if it is not a
    /// robot description, and the validation errors of [`Robot::from_toml_str`].
    pub fn load(path: impl AsRef<Path>) -> Result<Robot, RobotError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| RobotError::Read {
            path: path.to_owned(),
            source,
        })?;
        Robot::from_toml_str(&text).map_err(|error| match error {
            RobotError::Parse { source, .. } => RobotError::Parse {
                path: path.to_owned(),
                source,
            },
            other => other,
        })
    }

    /// Parses and validates a robot description given as TOML text.
    ///
    /// # Errors
    ///
    /// [`RobotError::Parse`] (with an empty path) for malformed TOML or unknown keys,
    /// [`RobotError::JointCount`], [`RobotError::NonFinite`], [`RobotError::EmptyLimits`]
    /// and [`RobotError::HomeOutsideLimits`] for a description that parses but cannot be
    /// a robot.
    pub fn from_toml_str(text: &str) -> Result<Robot, RobotError> {
        let file: RobotFile = toml::from_str(text).map_err(|source| RobotError::Parse {
            path: PathBuf::new(),
            source,
        })?;
        let joints_file: [JointFile; JOINT_COUNT] =
            file.joints
                .as_slice()
                .try_into()
                .map_err(|_| RobotError::JointCount {
                    found: file.joints.len(),
                })?;

        let mut joints = [Joint {
            mdh: MdhJoint::default(),
            limits_rad: [0.0; 2],
        }; JOINT_COUNT];
        for (index, (joint, spec)) in joints.iter_mut().zip(&joints_file).enumerate() {
            let number = index + 1;
            let values = [
                ("a_mm", spec.a_mm),
                ("d_mm", spec.d_mm),
                ("alpha_deg", spec.alpha_deg),
                ("beta_deg", spec.beta_deg),
                ("theta_offset_deg", spec.theta_offset_deg),
                ("limits_deg[0]", spec.limits_deg[0]),
                ("limits_deg[1]", spec.limits_deg[1]),
            ];
            for (name, value) in values {
                finite(value, || format!("joint {number} {name}"))?;
            }
            let [lower_deg, upper_deg] = spec.limits_deg;
            if lower_deg >= upper_deg {
                return Err(RobotError::EmptyLimits {
                    joint: number,
                    lower_deg,
                    upper_deg,
                });
            }
            *joint = Joint {
                mdh: MdhJoint {
                    a_mm: spec.a_mm,
                    d_mm: spec.d_mm,
                    alpha_rad: spec.alpha_deg.to_radians(),
                    beta_rad: spec.beta_deg.to_radians(),
                    theta_offset_rad: spec.theta_offset_deg.to_radians(),
                },
                limits_rad: [lower_deg.to_radians(), upper_deg.to_radians()],
            };
        }

        for (i, value) in file.tool.translation_mm.iter().enumerate() {
            finite(*value, || format!("tool translation_mm[{i}]"))?;
        }
        for (i, value) in file.tool.abc_deg.iter().enumerate() {
            finite(*value, || format!("tool abc_deg[{i}]"))?;
        }
        let tool = isometry_from_parts(
            file.tool.translation_mm,
            &rotation_from_kuka_abc_deg(file.tool.abc_deg),
        );

        let home_deg = file.home_deg.unwrap_or([0.0; JOINT_COUNT]);
        for (index, (&home, joint)) in home_deg.iter().zip(&joints_file).enumerate() {
            finite(home, || format!("home_deg[{index}]"))?;
            let [lower_deg, upper_deg] = joint.limits_deg;
            if !(lower_deg..=upper_deg).contains(&home) {
                return Err(RobotError::HomeOutsideLimits {
                    joint: index + 1,
                    home_deg: home,
                    lower_deg,
                    upper_deg,
                });
            }
        }

        Ok(Robot {
            name: file.name,
            joints,
            tool,
            home_rad: home_deg.map(f64::to_radians),
        })
    }

    /// The nominal MD-H parameters of the six joints, for [`kinematics::forward`].
    pub fn nominal_joints(&self) -> [MdhJoint; JOINT_COUNT] {
        self.joints.map(|joint| joint.mdh)
    }

    /// The tool (TCP in the flange frame) as a runtime transform.
    pub fn tool_transform(&self) -> Transform {
        transform_from_isometry(&self.tool)
    }

    /// Whether every joint variable lies within its limits (inclusive).
    pub fn within_limits(&self, q_rad: &[f64; JOINT_COUNT]) -> bool {
        self.joints
            .iter()
            .zip(q_rad)
            .all(|(joint, &q)| (joint.limits_rad[0]..=joint.limits_rad[1]).contains(&q))
    }

    /// The nominal TCP pose in the base frame at joint angles `q_rad`.
    pub fn tcp_pose(&self, q_rad: &[f64; JOINT_COUNT]) -> Isometry3<f64> {
        isometry_from_transform(&kinematics::forward(
            &self.nominal_joints(),
            &self.tool_transform(),
            q_rad,
        ))
    }
}

fn finite(value: f64, field: impl FnOnce() -> String) -> Result<(), RobotError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(RobotError::NonFinite { field: field() })
    }
}

/// The pose with the given translation (mm) and rotation.
pub fn isometry_from_parts(translation_mm: [f64; 3], rotation: &Rotation3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(Vector3::from(translation_mm)),
        UnitQuaternion::from_rotation_matrix(rotation),
    )
}

/// A runtime transform as a nalgebra isometry.
///
/// The rotation is re-orthonormalised through a quaternion; for a transform that came out of
/// [`kinematics::forward`] that changes it by rounding noise only.
pub fn isometry_from_transform(transform: &Transform) -> Isometry3<f64> {
    let r = &transform.rotation;
    let matrix = Matrix3::new(
        r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
    );
    isometry_from_parts(
        transform.translation_mm,
        &Rotation3::from_matrix_unchecked(matrix),
    )
}

/// A nalgebra isometry as a runtime transform.
pub fn transform_from_isometry(isometry: &Isometry3<f64>) -> Transform {
    let t = &isometry.translation.vector;
    transform_from_parts([t.x, t.y, t.z], &isometry.rotation.to_rotation_matrix())
}

/// The runtime transform with the given translation (mm) and rotation matrix, exactly.
pub fn transform_from_parts(translation_mm: [f64; 3], rotation: &Rotation3<f64>) -> Transform {
    let m = rotation.matrix();
    Transform {
        rotation: [0, 1, 2].map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]),
        translation_mm,
    }
}

/// The rotation part of a runtime transform, as a nalgebra rotation.
pub fn rotation_of(transform: &Transform) -> Rotation3<f64> {
    let r = &transform.rotation;
    Rotation3::from_matrix_unchecked(Matrix3::new(
        r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
    ))
}

/// The path of a robot shipped in this repository's `tables/` folder, e.g.
/// `shipped_robot_path("kr150-2")`.
pub fn shipped_robot_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tables")
        .join(name)
        .join("robot.toml")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_kr150_matches_the_method_table() {
        let robot = Robot::load(shipped_robot_path("kr150-2")).unwrap();
        let a: Vec<f64> = robot.joints.iter().map(|j| j.mdh.a_mm).collect();
        let d: Vec<f64> = robot.joints.iter().map(|j| j.mdh.d_mm).collect();
        let alpha: Vec<f64> = robot
            .joints
            .iter()
            .map(|j| j.mdh.alpha_rad.to_degrees())
            .collect();
        assert_eq!(a, [350.0, 1250.0, 55.0, 0.0, 0.0, 0.0]);
        assert_eq!(d, [750.0, 0.0, 0.0, 1100.0, 0.0, 230.0]);
        for (got, want) in alpha.iter().zip([-90.0, 0.0, 90.0, -90.0, 90.0, 0.0]) {
            assert!((got - want).abs() < 1e-12);
        }
        assert!(robot.within_limits(&robot.home_rad));
        assert_eq!(robot.tool, Isometry3::identity());
    }

    #[test]
    fn shipped_ur5_loads() {
        let robot = Robot::load(shipped_robot_path("ur5")).unwrap();
        assert_eq!(robot.joints[1].mdh.a_mm, -425.0);
        assert!(robot.tool.translation.vector.z > 25.0);
    }

    fn kr150_text() -> String {
        std::fs::read_to_string(shipped_robot_path("kr150-2")).unwrap()
    }

    #[test]
    fn five_joints_are_refused() {
        let text = kr150_text();
        let cut = text.rfind("[[joints]]").unwrap();
        let error = Robot::from_toml_str(&text[..cut]).unwrap_err();
        assert!(
            matches!(error, RobotError::JointCount { found: 5 }),
            "{error}"
        );
    }

    #[test]
    fn reversed_limits_and_unknown_keys_are_refused() {
        let text = kr150_text().replacen(
            "limits_deg = [-185.0, 185.0]",
            "limits_deg = [10.0, -10.0]",
            1,
        );
        let error = Robot::from_toml_str(&text).unwrap_err();
        assert!(
            matches!(error, RobotError::EmptyLimits { joint: 1, .. }),
            "{error}"
        );

        let text = kr150_text().replacen("a_mm = 350.0", "a_mm = 350.0\nlength = 3", 1);
        let error = Robot::from_toml_str(&text).unwrap_err();
        assert!(matches!(error, RobotError::Parse { .. }), "{error}");
    }

    #[test]
    fn transform_conversions_round_trip() {
        let robot = Robot::load(shipped_robot_path("kr150-2")).unwrap();
        let q = [0.2, -1.1, 1.9, 0.4, 0.7, -2.0];
        let pose = robot.tcp_pose(&q);
        let back = isometry_from_transform(&transform_from_isometry(&pose));
        assert!((back.translation.vector - pose.translation.vector).norm() < 1e-12);
        assert!(back.rotation.angle_to(&pose.rotation) < 1e-14);
    }

    /// The UR5 data set's targets are the nominal forward kinematics of its commanded joint
    /// angles with a tool offset along the flange. With `R`, `p` the flange pose, the target
    /// is `p + R·τ`, linear in the tool translation `τ`; since `RᵀR = I`, its least-squares
    /// estimate is the mean of `Rᵀ·(target − p)`.
    #[test]
    fn ur5_tool_offset_fits_the_data_set_targets() {
        let robot = Robot::load(shipped_robot_path("ur5")).unwrap();
        let data = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../tables/ur5/measurements/3D_UR5_uncalibrated_grid_cleaned.csv");
        let mut reader = csv::Reader::from_path(&data).unwrap();
        let mut flanges = Vec::new();
        let mut targets = Vec::new();
        for record in reader.records() {
            let record = record.unwrap();
            let value = |i: usize| record[i].parse::<f64>().unwrap();
            let q_rad: [f64; 6] = std::array::from_fn(|j| value(7 + j).to_radians());
            let flange = kinematics::forward(&robot.nominal_joints(), &Transform::IDENTITY, &q_rad);
            flanges.push(isometry_from_transform(&flange));
            targets.push(Vector3::new(value(1), value(2), value(3)));
        }
        assert_eq!(flanges.len(), 1000);

        let fitted: Vector3<f64> = flanges
            .iter()
            .zip(&targets)
            .map(|(f, t)| f.rotation.inverse() * (t - f.translation.vector))
            .sum::<Vector3<f64>>()
            / flanges.len() as f64;
        let rms = |tool: &Vector3<f64>| {
            let sum: f64 = flanges
                .iter()
                .zip(&targets)
                .map(|(f, t)| {
                    (f * nalgebra::Point3::from(*tool) - nalgebra::Point3::from(*t)).norm_squared()
                })
                .sum();
            (sum / flanges.len() as f64).sqrt()
        };
        let shipped = robot.tool.translation.vector;
        println!(
            "UR5 tool fit: fitted {:.4?} mm, residual RMS {:.4} mm; shipped {:.4?} mm, residual RMS {:.4} mm",
            fitted.as_slice(),
            rms(&fitted),
            shipped.as_slice(),
            rms(&shipped)
        );
        // The tool is about 31 mm out along the flange z axis (and 0.09 mm along y).
        assert!(fitted.x.abs() < 0.2 && fitted.y.abs() < 0.2, "{fitted:?}");
        assert!((fitted.z - 31.0).abs() < 1.0, "{fitted:?}");
        // The targets are the model's FK to within rounding of the published joint angles.
        assert!(rms(&fitted) < 0.02, "residual RMS {} mm", rms(&fitted));
        // The shipped robot file carries the fitted tool to its printed precision.
        assert!(
            (shipped - fitted).norm() < 0.01,
            "shipped {shipped:?} vs fitted {fitted:?}"
        );
        assert!(rms(&shipped) < 0.02);
    }
}
