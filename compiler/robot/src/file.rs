//! Robot files in: TOML robot files (MD-H rows, chain joints, or a URDF file named with a
//! tool and base; the format is described in [`crate::model`]) and URDF files, chosen by
//! extension. Writing them back is [`Robot::to_toml_string`] and [`Robot::to_urdf_string`].

use std::path::{Path, PathBuf};

use adwi_runtime::chain::{ChainJoint, JointKind, MAX_JOINTS};
use adwi_runtime::kinematics::{MdhJoint, Transform};
use serde::Deserialize;

use adwi_samples::pose::rotation_from_kuka_abc_deg;

use crate::model::{
    transform_from_parts, transform_from_xyz_rpy, unit_axis, Geometry, Joint, LinkInertial, Robot,
    RobotError,
};
use crate::plausible::{check, check_all, check_name, Quantity};
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
        Ok(Robot::load_with_files(path, links)?.0)
    }

    /// As [`Robot::load_with`], with every file it read: the named file, then the file it
    /// names (a TOML robot file's `urdf`), and so on, each canonical (absolute, links
    /// resolved), so that a caller can refuse to write over any of them.
    ///
    /// Robot files may name robot files at most [`MAX_ROBOT_FILE_DEPTH`] deep, and never
    /// one already on the way (a file naming itself, two naming each other).
    ///
    /// # Errors
    ///
    /// As [`Robot::load`]; [`RobotError::NamingCycle`] and [`RobotError::NamingTooDeep`]
    /// for files that name each other in a cycle or too deep; an error in a named file
    /// comes as [`RobotError::InNamedFile`], naming the file that named it.
    pub fn load_with_files(
        path: impl AsRef<Path>,
        links: &LinkNames,
    ) -> Result<(Robot, Vec<PathBuf>), RobotError> {
        let mut files = Vec::new();
        let robot = load_naming(path.as_ref(), links, &mut Vec::new(), &mut files)?;
        Ok((robot, files))
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
        Robot::from_toml_naming(text, dir, links, &mut |path, links| {
            load_naming(path, links, &mut Vec::new(), &mut Vec::new())
        })
    }

    /// Parses TOML text, loading the file its `urdf` key names through `load`.
    fn from_toml_naming(
        text: &str,
        dir: &Path,
        links: &LinkNames,
        load: &mut dyn FnMut(&Path, &LinkNames) -> Result<Robot, RobotError>,
    ) -> Result<Robot, RobotError> {
        let file: RobotFile = toml::from_str(text).map_err(|error| RobotError::Parse {
            path: PathBuf::new(),
            source: crate::toml_error::TomlError::new(&error, text),
        })?;
        check_name(&file.name)?;
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
        let flange = file
            .flange
            .map(|f| f.transform("flange"))
            .transpose()?
            .unwrap_or(Transform::IDENTITY);
        if let Some(urdf_path) = &file.urdf {
            if file.flange.is_some() {
                return Err(RobotError::Invalid {
                    field: "flange".into(),
                    reason: "a robot file naming a URDF file takes its flange from the URDF: \
                             name the link as flange_link"
                        .into(),
                });
            }
            if !file.joints.is_empty() {
                return Err(RobotError::Invalid {
                    field: "joints".into(),
                    reason: "a robot file naming a URDF file lists no [[joints]]".into(),
                });
            }
            let links = LinkNames {
                base_link: links.base_link.clone().or(file.base_link),
                tip_link: links.tip_link.clone().or(file.tip_link),
                flange_link: links.flange_link.clone().or(file.flange_link),
            };
            let urdf = load(&dir.join(urdf_path), &links)?;
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
        if file.base_link.is_some() || file.tip_link.is_some() || file.flange_link.is_some() {
            return Err(RobotError::Invalid {
                field: "base_link, tip_link, flange_link".into(),
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
            Robot::with_flange_at(file.name, geometry, joints, base, flange, tool, home)?,
            file.payload,
        )
    }
}

pub use crate::error::MAX_ROBOT_FILE_DEPTH;

/// Loads the robot file `path`, named by the files of `naming` (canonical, outermost
/// first), recording every file read in `files`.
fn load_naming(
    path: &Path,
    links: &LinkNames,
    naming: &mut Vec<(PathBuf, PathBuf)>,
    files: &mut Vec<PathBuf>,
) -> Result<Robot, RobotError> {
    let read_error = |source| RobotError::Read {
        path: path.to_owned(),
        source,
    };
    let canonical = std::fs::canonicalize(path).map_err(read_error)?;
    // The chain as the files name each other, for messages.
    let chain = |naming: &[(PathBuf, PathBuf)]| -> Vec<PathBuf> {
        naming
            .iter()
            .map(|(given, _)| given.clone())
            .chain(std::iter::once(path.to_owned()))
            .collect()
    };
    if naming.iter().any(|(_, c)| *c == canonical) {
        return Err(RobotError::NamingCycle {
            files: chain(naming),
        });
    }
    if naming.len() >= MAX_ROBOT_FILE_DEPTH {
        return Err(RobotError::NamingTooDeep {
            files: chain(naming),
        });
    }
    // Regular files only: a FIFO is never waited on, a device never read without end.
    let text = adwi_runtime::input::read_regular_to_string(path).map_err(read_error)?;
    files.push(canonical.clone());
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
    naming.push((path.to_owned(), canonical));
    let robot = Robot::from_toml_naming(&text, dir, links, &mut |named, links| {
        load_naming(named, links, naming, files).map_err(|error| match error {
            // A cycle or a chain too deep is reported once, whole.
            e @ (RobotError::NamingCycle { .. } | RobotError::NamingTooDeep { .. }) => e,
            e => RobotError::InNamedFile {
                file: path.to_owned(),
                named: named.to_owned(),
                source: Box::new(e),
            },
        })
    });
    naming.pop();
    robot.map_err(|error| match error {
        RobotError::Parse { source, .. } => RobotError::Parse {
            path: path.to_owned(),
            source,
        },
        other => other,
    })
}

/// `robot` with the file's `[payload]`, its centre of mass moved from the file's frame (the
/// last link's) into the model's as a link's is.
fn carrying(robot: Robot, payload: Option<PayloadFile>) -> Result<Robot, RobotError> {
    if let Some(p) = &payload {
        check(p.mass_kg, Quantity::MassKg, || "payload mass_kg".into())?;
        check_all(&p.com_mm, Quantity::LengthMm, || "payload com_mm".into())?;
    }
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
    for (i, (&value, kind)) in values.iter().zip(kinds).enumerate() {
        let quantity = match kind {
            JointKind::Revolute => Quantity::JointLimitDeg,
            JointKind::Prismatic => Quantity::LengthMm,
        };
        check(value, quantity, || format!("home_deg[{i}]"))?;
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
    flange: Option<FrameFile>,
    base: Option<FrameFile>,
    home_deg: Option<Vec<f64>>,
    urdf: Option<PathBuf>,
    base_link: Option<String>,
    tip_link: Option<String>,
    flange_link: Option<String>,
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
        // As the file gives them (degrees or mm); an infinite limit is no limit.
        let (given, quantity) = match kind {
            JointKind::Revolute => (self.limits_deg, Quantity::JointLimitDeg),
            JointKind::Prismatic => (self.limits_mm, Quantity::LengthMm),
        };
        for (i, value) in given.into_iter().flatten().enumerate() {
            if !value.is_infinite() {
                check(value, quantity, || format!("joint {number} {key}[{i}]"))?;
            }
        }
        if let Some(mass_kg) = self.mass_kg {
            check(mass_kg, Quantity::MassKg, || {
                format!("joint {number} mass_kg")
            })?;
        }
        if let Some(com_mm) = self.com_mm {
            check_all(&com_mm, Quantity::LengthMm, || {
                format!("joint {number} com_mm")
            })?;
        }
        if let Some(c) = self.compliance_urad_per_nm {
            check(c, Quantity::ComplianceUradPerNm, || {
                format!("joint {number} compliance_urad_per_nm")
            })?;
        }
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
        let (a_mm, d_mm) = (required(self.a_mm, "a_mm")?, required(self.d_mm, "d_mm")?);
        let alpha_deg = required(self.alpha_deg, "alpha_deg")?;
        let beta_deg = self.beta_deg.unwrap_or(0.0);
        let theta_offset_deg = self.theta_offset_deg.unwrap_or(0.0);
        for (value, key, quantity) in [
            (a_mm, "a_mm", Quantity::LengthMm),
            (d_mm, "d_mm", Quantity::LengthMm),
            (alpha_deg, "alpha_deg", Quantity::AngleDeg),
            (beta_deg, "beta_deg", Quantity::AngleDeg),
            (theta_offset_deg, "theta_offset_deg", Quantity::AngleDeg),
        ] {
            check(value, quantity, || format!("joint {number} {key}"))?;
        }
        let row = MdhJoint {
            a_mm,
            d_mm,
            alpha_rad: alpha_deg.to_radians(),
            beta_rad: beta_deg.to_radians(),
            theta_offset_rad: theta_offset_deg.to_radians(),
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
        check_all(&xyz, Quantity::LengthMm, || {
            format!("joint {number} xyz_mm")
        })?;
        check_all(&rpy, Quantity::AngleDeg, || {
            format!("joint {number} rpy_deg")
        })?;
        match kind {
            JointKind::Revolute => check(offset.to_degrees(), Quantity::AngleDeg, || {
                format!("joint {number} offset_deg")
            })?,
            JointKind::Prismatic => check(offset, Quantity::LengthMm, || {
                format!("joint {number} offset_mm")
            })?,
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
        check_all(&self.translation_mm, Quantity::LengthMm, || {
            format!("{what} translation_mm")
        })?;
        check_all(&self.abc_deg, Quantity::AngleDeg, || {
            format!("{what} abc_deg")
        })?;
        Ok(transform_from_parts(
            self.translation_mm,
            &rotation_from_kuka_abc_deg(self.abc_deg),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::shipped_file;

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    /// Every file a robot file makes the loader read is reported, canonical; files that
    /// name each other, or name too deep, are refused with the chain of files, and an
    /// error in a named file says which file named it.
    #[test]
    fn named_files_are_reported_and_bounded() {
        let dir = tempfile::tempdir().unwrap();
        let urdf = std::fs::canonicalize(shipped_file("ur5", "robot.urdf")).unwrap();
        let toml = write(
            dir.path(),
            "ur5.toml",
            &format!("name = \"UR5\"\nurdf = {:?}\n", urdf.display().to_string()),
        );
        let (robot, files) = Robot::load_with_files(&toml, &LinkNames::default()).unwrap();
        assert_eq!(robot.name, "UR5");
        assert_eq!(files, [std::fs::canonicalize(&toml).unwrap(), urdf.clone()]);
        // A layer on top: three files.
        let tool = write(
            dir.path(),
            "tool.toml",
            "name = \"UR5 with a tool\"\nurdf = \"ur5.toml\"\n[tool]\ntranslation_mm = [0.0, 0.0, 100.0]\n",
        );
        let (_, files) = Robot::load_with_files(&tool, &LinkNames::default()).unwrap();
        assert_eq!(files.len(), 3);
        assert_eq!(files[2], urdf);

        let own = write(
            dir.path(),
            "self.toml",
            "name = \"s\"\nurdf = \"self.toml\"\n",
        );
        let error = Robot::load(&own).unwrap_err();
        assert!(matches!(error, RobotError::NamingCycle { .. }), "{error:?}");
        let expected = format!(
            "robot files name each other in a cycle: {} → {}",
            own.display(),
            own.display()
        );
        assert_eq!(error.to_string(), expected);
        let a = write(dir.path(), "a.toml", "name = \"a\"\nurdf = \"b.toml\"\n");
        write(dir.path(), "b.toml", "name = \"b\"\nurdf = \"a.toml\"\n");
        let b = dir.path().join("b.toml");
        assert_eq!(
            Robot::load(&a).unwrap_err().to_string(),
            format!(
                "robot files name each other in a cycle: {} → {} → {}",
                a.display(),
                b.display(),
                a.display()
            )
        );
        // Ten files naming each other: too deep, though no cycle; eight are not.
        for i in 0..9 {
            write(
                dir.path(),
                &format!("layer{i}.toml"),
                &format!("name = \"{i}\"\nurdf = \"layer{}.toml\"\n", i + 1),
            );
        }
        write(
            dir.path(),
            "layer9.toml",
            &format!("name = \"9\"\nurdf = {:?}\n", urdf.display().to_string()),
        );
        let error = Robot::load(dir.path().join("layer0.toml")).unwrap_err();
        assert!(
            matches!(error, RobotError::NamingTooDeep { ref files } if files.len() == 9),
            "{error:?}"
        );
        assert!(error
            .to_string()
            .starts_with("robot files name robot files more than 8 deep: "));
        assert!(Robot::load(dir.path().join("layer2.toml")).is_err());
        assert!(Robot::load(dir.path().join("layer3.toml")).is_ok());

        // An error in the named file: wrapped, naming both files.
        let bad = write(
            dir.path(),
            "bad.urdf",
            &std::fs::read_to_string(&urdf)
                .unwrap()
                .replace(r#"<mass value="3.7"/>"#, r#"<mass value="NaN"/>"#),
        );
        let wraps = write(
            dir.path(),
            "wraps.toml",
            "name = \"w\"\nurdf = \"bad.urdf\"\n",
        );
        let error = Robot::load(&wraps).unwrap_err();
        assert_eq!(
            error.to_string(),
            format!("{} names {}", wraps.display(), bad.display())
        );
        let source = std::error::Error::source(&error).unwrap().to_string();
        assert_eq!(
            source,
            "link 'shoulder_link' <inertial><mass value> is not a finite number"
        );
    }

    /// Numbers beyond what any robot has are refused where they are read, with the key.
    #[test]
    fn implausible_numbers_in_robot_files_are_refused_with_the_key() {
        let text = std::fs::read_to_string(crate::model::shipped_robot_path("ur5")).unwrap();
        for (from, to, expected) in [
            (
                "mass_kg = 3.7",
                "mass_kg = 1e308",
                "joint 1 mass_kg: a mass (kg) is 1e308, but must be at most 1000000",
            ),
            (
                "mass_kg = 3.7",
                "mass_kg = -5.0",
                "joint 1 mass_kg: a mass (kg) is -5, but must be at least 0",
            ),
            (
                "a_mm = -425.0",
                "a_mm = -1e300",
                "joint 2 a_mm: a length (mm) is -1e300, but must be within ±1000000",
            ),
            (
                "com_mm = [212.5, 0.0, 113.36]",
                "com_mm = [1e308, 0.0, 113.36]",
                "joint 2 com_mm[0]: a length (mm) is 1e308, but must be within ±1000000",
            ),
            (
                "alpha_deg = 90.0",
                "alpha_deg = 1e300",
                "joint 1 alpha_deg: an angle (deg) is 1e300, but must be within ±720",
            ),
            (
                "translation_mm = [0.0, 0.09, 31.0]",
                "translation_mm = [0.0, 0.09, nan]",
                "tool translation_mm[2] is not a finite number",
            ),
            (
                "limits_deg = [-360.0, 360.0]",
                "limits_deg = [-1e9, 360.0]",
                "joint 1 limits_deg[0]: a joint limit (deg) is -1e9, but must be within ±3600",
            ),
        ] {
            let changed = text.replacen(from, to, 1);
            assert_ne!(changed, text, "{from}");
            let error = Robot::from_toml_str(&changed).unwrap_err();
            assert_eq!(error.to_string(), expected);
        }
        let compliant = text.replacen(
            "com_mm = [212.5, 0.0, 113.36]",
            "com_mm = [212.5, 0.0, 113.36]\ncompliance_urad_per_nm = 1e100",
            1,
        );
        let error = Robot::from_toml_str(&compliant).unwrap_err();
        assert_eq!(
            error.to_string(),
            "joint 2 compliance_urad_per_nm: a compliance (µrad/(N·m)) is 1e100, but must be within ±10000"
        );
        let payload = format!("{text}\n[payload]\nmass_kg = 1e308\n");
        let error = Robot::from_toml_str(&payload).unwrap_err();
        assert_eq!(
            error.to_string(),
            "payload mass_kg: a mass (kg) is 1e308, but must be at most 1000000"
        );
        // Continuous joints keep their infinite limits.
        let continuous = text.replacen(
            "limits_deg = [-360.0, 360.0]",
            "limits_deg = [-inf, inf]",
            1,
        );
        assert!(Robot::from_toml_str(&continuous).is_ok());
    }

    /// What the fuzz test found, kept: a TOML error quotes a short excerpt of its line
    /// however long; a robot file with values at the bounds, written back, reads again.
    #[test]
    fn long_lines_and_values_at_the_bounds() {
        let text = std::fs::read_to_string(crate::model::shipped_robot_path("ur5")).unwrap();
        let nested = format!(
            "{text}\nx = {}{}\n",
            "[".repeat(100_000),
            "]".repeat(100_000)
        );
        let error = Robot::from_toml_str(&nested).unwrap_err();
        let message = format!("{error}: {}", std::error::Error::source(&error).unwrap());
        assert!(message.len() < 500, "{} bytes: {message}", message.len());
        let long_name = text.replacen(
            "name = \"Universal Robots UR5\"",
            &format!("name = \"{}\"", "n".repeat(300)),
            1,
        );
        let error = Robot::from_toml_str(&long_name).unwrap_err().to_string();
        assert!(
            error.contains("has 300 characters, more than the 256"),
            "{error}"
        );
        assert!(error.len() < 200, "{error}");
        let at_bounds = text
            .replacen(
                "com_mm = [212.5, 0.0, 113.36]",
                "com_mm = [212.5, -1000000.0, 113.36]",
                1,
            )
            .replacen("mass_kg = 3.7", "mass_kg = 1000000.0", 1);
        let robot = Robot::from_toml_str(&at_bounds).unwrap();
        let again = Robot::from_toml_str(&robot.to_toml_string(&[])).unwrap();
        assert_eq!(again.joint_count(), 6);
    }
}
