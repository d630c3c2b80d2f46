//! Robot files in: TOML robot files (MD-H rows, chain joints, or a URDF file named with a
//! tool and base; the format is described in [`crate::model`]) and URDF files, chosen by
//! extension. Writing them back is [`Robot::to_toml_string`] and [`Robot::to_urdf_string`].

use std::path::{Path, PathBuf};

use adwi_runtime::chain::{ChainJoint, JointKind, MAX_JOINTS};
use adwi_runtime::kinematics::{MdhJoint, Transform};
use serde::Deserialize;

use adwi_samples::pose::rotation_from_kuka_abc_deg;

use crate::model::{
    finite, transform_from_parts, transform_from_xyz_rpy, unit_axis, Geometry, Joint, LinkInertial,
    Robot, RobotError,
};
use crate::urdf::LinkNames;

impl Robot {
    /// Reads and validates a robot file: URDF for a `.urdf` extension (the chain from the
    /// root link to the only leaf link), TOML otherwise.
    ///
    /// # Errors
    ///
    /// [`RobotError::Read`] if the file cannot be read, [`RobotError::Parse`] or
    /// [`RobotError::Urdf`] if it is not a robot description, and the validation errors of
    /// [`Robot::new`].
    pub fn load(path: impl AsRef<Path>) -> Result<Robot, RobotError> {
        Robot::load_with(path, &LinkNames::default())
    }

    /// As [`Robot::load`], with the URDF chain between the given links (a TOML file's own
    /// `base_link` and `tip_link` give way to them).
    ///
    /// # Errors
    ///
    /// As [`Robot::load`].
    pub fn load_with(path: impl AsRef<Path>, links: &LinkNames) -> Result<Robot, RobotError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| RobotError::Read {
            path: path.to_owned(),
            source,
        })?;
        let is_urdf = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("urdf"));
        if is_urdf {
            return crate::urdf::robot_from_urdf_str(&text, links).map_err(|e| match e {
                RobotError::Urdf { source, .. } => RobotError::Urdf {
                    path: path.to_owned(),
                    source,
                },
                other => other,
            });
        }
        let dir = path.parent().unwrap_or(Path::new(""));
        Robot::from_toml_in(&text, dir, links).map_err(|error| match error {
            RobotError::Parse { source, .. } => RobotError::Parse {
                path: path.to_owned(),
                source,
            },
            other => other,
        })
    }

    /// Parses and validates a robot description given as TOML text (a `urdf` key is read
    /// relative to the working directory).
    ///
    /// # Errors
    ///
    /// [`RobotError::Parse`] (with an empty path) for malformed TOML or unknown keys, and
    /// the validation errors of [`Robot::new`].
    pub fn from_toml_str(text: &str) -> Result<Robot, RobotError> {
        Robot::from_toml_in(text, Path::new(""), &LinkNames::default())
    }

    fn from_toml_in(text: &str, dir: &Path, links: &LinkNames) -> Result<Robot, RobotError> {
        let file: RobotFile = toml::from_str(text).map_err(|source| RobotError::Parse {
            path: PathBuf::new(),
            source,
        })?;
        let tool = file
            .tool
            .map(|t| t.transform("tool"))
            .transpose()?
            .unwrap_or(Transform::IDENTITY);
        let base = file
            .base
            .map(|b| b.transform("base"))
            .transpose()?
            .unwrap_or(Transform::IDENTITY);
        if let Some(urdf_path) = &file.urdf {
            if !file.joints.is_empty() {
                return Err(RobotError::Invalid {
                    field: "joints".into(),
                    reason: "a robot file naming a URDF file lists no [[joints]]".into(),
                });
            }
            let links = LinkNames {
                base_link: links.base_link.clone().or(file.base_link),
                tip_link: links.tip_link.clone().or(file.tip_link),
            };
            let urdf = Robot::load_with(dir.join(urdf_path), &links)?;
            let kinds: Vec<JointKind> = urdf.chain().joints().iter().map(|j| j.kind).collect();
            let home = match &file.home_deg {
                Some(h) => from_file_units(h, &kinds)?,
                None => urdf.home().to_vec(),
            };
            let robot = urdf.with_parts(
                file.name,
                base.compose(&urdf.base()),
                urdf.tool().compose(&tool),
                home,
            )?;
            return carrying(robot, file.payload);
        }
        if file.base_link.is_some() || file.tip_link.is_some() {
            return Err(RobotError::Invalid {
                field: "base_link, tip_link".into(),
                reason: "only a robot file naming a URDF file has links".into(),
            });
        }
        let n = file.joints.len();
        if n == 0 || n > MAX_JOINTS {
            return Err(RobotError::JointCount { found: n });
        }
        let mdh = joint_style(&file.joints[0], 1)? == Style::Mdh;
        let mut joints = Vec::with_capacity(n);
        let geometry = if mdh {
            let mut rows = Vec::with_capacity(n);
            for (i, spec) in file.joints.iter().enumerate() {
                let (row, joint) = spec.mdh(i + 1)?;
                rows.push(row);
                joints.push(joint);
            }
            Geometry::Mdh(rows)
        } else {
            let mut rows = Vec::with_capacity(n);
            for (i, spec) in file.joints.iter().enumerate() {
                let (row, joint) = spec.chain(i + 1)?;
                rows.push(row);
                joints.push(joint);
            }
            Geometry::Chain(rows)
        };
        let kinds: Vec<JointKind> = match &geometry {
            Geometry::Mdh(rows) => vec![JointKind::Revolute; rows.len()],
            Geometry::Chain(rows) => rows.iter().map(|j| j.kind).collect(),
        };
        let home = match &file.home_deg {
            Some(h) => from_file_units(h, &kinds)?,
            None => vec![0.0; n],
        };
        // The links' centres of mass from the file's frames into the joints' frames after
        // their motion, the model's.
        for (i, joint) in joints.iter_mut().enumerate() {
            if let Some(inertial) = &mut joint.inertial {
                inertial.com_mm = geometry.com_from_file(i, inertial.com_mm);
            }
        }
        carrying(
            Robot::new(file.name, geometry, joints, base, tool, home)?,
            file.payload,
        )
    }
}

/// `robot` with the file's `[payload]`, its centre of mass moved from the file's frame (the
/// last link's) into the model's as a link's is.
fn carrying(robot: Robot, payload: Option<PayloadFile>) -> Result<Robot, RobotError> {
    let payload = payload.map(|p| LinkInertial {
        mass_kg: p.mass_kg,
        com_mm: robot
            .geometry()
            .com_from_file(robot.joint_count() - 1, p.com_mm),
    });
    robot.with_payload(payload)
}

/// Joint values in file units (deg, mm) to the model's (rad, mm).
fn from_file_units(values: &[f64], kinds: &[JointKind]) -> Result<Vec<f64>, RobotError> {
    if values.len() != kinds.len() {
        return Err(RobotError::HomeLength {
            expected: kinds.len(),
            found: values.len(),
        });
    }
    Ok(values
        .iter()
        .zip(kinds)
        .map(|(&v, k)| match k {
            JointKind::Revolute => v.to_radians(),
            JointKind::Prismatic => v,
        })
        .collect())
}

/// The robot file as written, before validation.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RobotFile {
    name: String,
    #[serde(default)]
    joints: Vec<JointFile>,
    tool: Option<FrameFile>,
    base: Option<FrameFile>,
    home_deg: Option<Vec<f64>>,
    urdf: Option<PathBuf>,
    base_link: Option<String>,
    tip_link: Option<String>,
    payload: Option<PayloadFile>,
}

/// `[payload]`: what the flange carries, its centre of mass in the frame of the last
/// joint's `com_mm` (MD-H frame `n`, the flange, for MD-H joints; the last joint's frame
/// after its motion otherwise).
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct PayloadFile {
    mass_kg: f64,
    #[serde(default)]
    com_mm: [f64; 3],
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct JointFile {
    name: Option<String>,
    // MD-H
    a_mm: Option<f64>,
    d_mm: Option<f64>,
    alpha_deg: Option<f64>,
    beta_deg: Option<f64>,
    theta_offset_deg: Option<f64>,
    // Chain
    #[serde(rename = "type")]
    kind: Option<KindFile>,
    xyz_mm: Option<[f64; 3]>,
    rpy_deg: Option<[f64; 3]>,
    axis: Option<[f64; 3]>,
    offset_deg: Option<f64>,
    offset_mm: Option<f64>,
    // Both
    limits_deg: Option<[f64; 2]>,
    limits_mm: Option<[f64; 2]>,
    mass_kg: Option<f64>,
    com_mm: Option<[f64; 3]>,
    compliance_urad_per_nm: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum KindFile {
    Revolute,
    Prismatic,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Style {
    Mdh,
    Chain,
}

fn joint_style(spec: &JointFile, number: usize) -> Result<Style, RobotError> {
    let mdh = spec.a_mm.is_some()
        || spec.d_mm.is_some()
        || spec.alpha_deg.is_some()
        || spec.beta_deg.is_some()
        || spec.theta_offset_deg.is_some();
    let chain = spec.kind.is_some()
        || spec.xyz_mm.is_some()
        || spec.rpy_deg.is_some()
        || spec.axis.is_some()
        || spec.offset_deg.is_some()
        || spec.offset_mm.is_some();
    let style = |reason: &str| RobotError::JointStyle {
        joint: number,
        reason: reason.into(),
    };
    match (mdh, chain) {
        (true, false) => Ok(Style::Mdh),
        (false, true) => Ok(Style::Chain),
        (true, true) => Err(style(
            "MD-H keys (a_mm, d_mm, alpha_deg, …) and chain keys (type, xyz_mm, rpy_deg, axis, …) \
             in one joint: a joint is one or the other",
        )),
        (false, false) => Err(style(
            "neither MD-H keys (a_mm, d_mm, alpha_deg) nor chain keys (xyz_mm, rpy_deg, axis)",
        )),
    }
}

impl JointFile {
    fn common(&self, number: usize, kind: JointKind) -> Result<Joint, RobotError> {
        let (limits, key, other) = match kind {
            JointKind::Revolute => (
                self.limits_deg.map(|l| l.map(f64::to_radians)),
                "limits_deg",
                self.limits_mm.map(|_| "limits_mm"),
            ),
            JointKind::Prismatic => (
                self.limits_mm,
                "limits_mm",
                self.limits_deg.map(|_| "limits_deg"),
            ),
        };
        if let Some(other) = other {
            return Err(RobotError::JointStyle {
                joint: number,
                reason: format!("{other} given for a joint whose limits are {key}"),
            });
        }
        let limits = limits.ok_or_else(|| RobotError::JointStyle {
            joint: number,
            reason: format!("{key} missing"),
        })?;
        let inertial = match (self.mass_kg, self.com_mm) {
            (Some(mass_kg), com) => Some(LinkInertial {
                mass_kg,
                com_mm: com.unwrap_or([0.0; 3]),
            }),
            (None, Some(_)) => {
                return Err(RobotError::JointStyle {
                    joint: number,
                    reason: "com_mm given without mass_kg".into(),
                })
            }
            (None, None) => None,
        };
        Ok(Joint {
            name: self
                .name
                .clone()
                .unwrap_or_else(|| format!("joint_{number}")),
            limits,
            inertial,
            compliance_urad_per_nm: self.compliance_urad_per_nm,
        })
    }

    fn mdh(&self, number: usize) -> Result<(MdhJoint, Joint), RobotError> {
        if joint_style(self, number)? != Style::Mdh {
            return Err(RobotError::JointStyle {
                joint: number,
                reason: "a chain joint in a robot whose joint 1 is MD-H: one style for all joints"
                    .into(),
            });
        }
        let required = |value: Option<f64>, key: &str| {
            value.ok_or_else(|| RobotError::JointStyle {
                joint: number,
                reason: format!("{key} missing"),
            })
        };
        let row = MdhJoint {
            a_mm: required(self.a_mm, "a_mm")?,
            d_mm: required(self.d_mm, "d_mm")?,
            alpha_rad: required(self.alpha_deg, "alpha_deg")?.to_radians(),
            beta_rad: self.beta_deg.unwrap_or(0.0).to_radians(),
            theta_offset_rad: self.theta_offset_deg.unwrap_or(0.0).to_radians(),
        };
        // The centre of mass stays in the file's MD-H frame i until the geometry is whole
        // (`Geometry::com_from_file`).
        Ok((row, self.common(number, JointKind::Revolute)?))
    }

    fn chain(&self, number: usize) -> Result<(ChainJoint, Joint), RobotError> {
        if joint_style(self, number)? != Style::Chain {
            return Err(RobotError::JointStyle {
                joint: number,
                reason: "an MD-H joint in a robot whose joint 1 is a chain joint: one style for all joints"
                    .into(),
            });
        }
        let kind = match self.kind.unwrap_or(KindFile::Revolute) {
            KindFile::Revolute => JointKind::Revolute,
            KindFile::Prismatic => JointKind::Prismatic,
        };
        let offset = match (kind, self.offset_deg, self.offset_mm) {
            (JointKind::Revolute, offset, None) => offset.unwrap_or(0.0).to_radians(),
            (JointKind::Prismatic, None, offset) => offset.unwrap_or(0.0),
            _ => {
                return Err(RobotError::JointStyle {
                    joint: number,
                    reason: "offset_deg is a revolute joint's offset, offset_mm a prismatic one's"
                        .into(),
                })
            }
        };
        let xyz = self.xyz_mm.unwrap_or([0.0; 3]);
        let rpy = self.rpy_deg.unwrap_or([0.0; 3]);
        for (key, values) in [("xyz_mm", xyz), ("rpy_deg", rpy)] {
            for (a, v) in values.iter().enumerate() {
                finite(*v, || format!("joint {number} {key}[{a}]"))?;
            }
        }
        let axis =
            unit_axis(self.axis.unwrap_or([0.0, 0.0, 1.0])).ok_or_else(|| RobotError::Invalid {
                field: format!("joint {number} axis"),
                reason: "must be a finite, non-zero vector".into(),
            })?;
        let row = ChainJoint {
            origin: transform_from_xyz_rpy(xyz, rpy.map(f64::to_radians)),
            axis,
            kind,
            offset,
        };
        Ok((row, self.common(number, kind)?))
    }
}

#[derive(Debug, Clone, Copy, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct FrameFile {
    #[serde(default)]
    translation_mm: [f64; 3],
    #[serde(default)]
    abc_deg: [f64; 3],
}

impl FrameFile {
    fn transform(&self, what: &str) -> Result<Transform, RobotError> {
        for (i, value) in self.translation_mm.iter().enumerate() {
            finite(*value, || format!("{what} translation_mm[{i}]"))?;
        }
        for (i, value) in self.abc_deg.iter().enumerate() {
            finite(*value, || format!("{what} abc_deg[{i}]"))?;
        }
        Ok(transform_from_parts(
            self.translation_mm,
            &rotation_from_kuka_abc_deg(self.abc_deg),
        ))
    }
}
