//! A robot written as URDF (module docs of [`crate::urdf`], "Writing"), and what the
//! written file cannot say.

use adwi_runtime::chain::JointKind;
use adwi_runtime::kinematics::Transform;
use urdf_rs::{JointType, Pose, Vec3};

use super::{chain_error, pose_of_transform, product, TCP_JOINT, TCP_LINK};
use crate::model::{LinkInertial, Robot, RobotError};

/// What a URDF written by [`Robot::to_urdf_string`] does not carry, or carries only as
/// the robot file's model has it ([`Robot::urdf_omissions`]); the file's header comment
/// says so too.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UrdfOmission {
    /// The joints' effort and velocity limits: robot files do not give them, so the file
    /// leaves them out (URDF 1.2, where they are optional).
    EffortAndVelocity,
    /// The links' inertia tensors: robot files give masses and centres of mass only, so
    /// each link is written as that point mass (inertia zero about its centre of mass).
    InertiaTensors,
    /// The joints' gravity compliances: URDF has no place for them.
    Compliances,
    /// The payload: URDF has no place for it.
    Payload,
}

impl std::fmt::Display for UrdfOmission {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            UrdfOmission::EffortAndVelocity => {
                "effort and velocity limits: not in the robot file, left out (URDF 1.2)"
            }
            UrdfOmission::InertiaTensors => {
                "inertia tensors: not in the robot file, written as zero (point masses at the \
                 centres of mass)"
            }
            UrdfOmission::Compliances => {
                "gravity compliances: URDF has no place for them, left out (the robot file \
                 carries them)"
            }
            UrdfOmission::Payload => {
                "payload: URDF has no place for it, left out (the robot file carries it)"
            }
        })
    }
}

impl Robot {
    /// This robot as URDF text (see the module docs): `comment` lines in a comment after
    /// the XML declaration.
    ///
    /// # Errors
    ///
    /// [`RobotError::UrdfChain`] when the URDF writer fails.
    pub fn to_urdf_string(&self, comment: &[String]) -> Result<String, RobotError> {
        let omissions = self.urdf_omissions();
        let chain = self.chain();
        // The base in the file's base link: the chain's base, less the controller's base
        // frame the file was read in (`urdf`, "Base"), which the file keeps.
        let base = self
            .urdf_source()
            .map_or(Transform::IDENTITY, |s| s.base_frame)
            .compose(&chain.base);
        // Each movable joint's origin with its offset folded in, the base in the first.
        let origins: Vec<Transform> = chain
            .joints()
            .iter()
            .enumerate()
            .map(|(i, j)| {
                let origin = j.origin.compose(&j.motion(j.offset));
                if i == 0 {
                    base.compose(&origin)
                } else {
                    origin
                }
            })
            .collect();
        let mut urdf = match self.urdf_source() {
            Some(source) if source.movable.len() == origins.len() => {
                let mut urdf = source.robot.clone();
                for ((origin, &j), before) in origins
                    .iter()
                    .zip(&source.movable)
                    .zip(&source.fixed_before)
                {
                    let fixed = product(&source.robot, before);
                    urdf.joints[j].origin = pose_of_transform(&fixed.inverse().compose(origin));
                }
                let after = product(&source.robot, &source.fixed_after);
                let tcp = after.inverse().compose(&chain.tool);
                // A file written here before: its TCP joint is updated, not doubled.
                let last_fixed = source.fixed_after.last().map(|&j| &urdf.joints[j]);
                match last_fixed {
                    Some(joint) if joint.name == TCP_JOINT => {
                        let j = *source.fixed_after.last().expect("matched Some");
                        let before_tcp = product(
                            &source.robot,
                            &source.fixed_after[..source.fixed_after.len() - 1],
                        );
                        urdf.joints[j].origin =
                            pose_of_transform(&before_tcp.inverse().compose(&chain.tool));
                    }
                    _ => add_tcp(&mut urdf, &source.tip_link, &tcp)?,
                }
                urdf
            }
            _ => self.fresh_urdf(&origins)?,
        };
        urdf.name = self.name.clone();
        let body = urdf_rs::write_to_string(&urdf)
            .map_err(|e| chain_error(format!("cannot write the robot as URDF: {e}")))?;
        let body = without_unknown_inertials(&body);
        let mut out = String::from("<?xml version=\"1.0\"?>\n");
        let notes: Vec<String> = (!omissions.is_empty())
            .then(|| "Not in this file:".to_owned())
            .into_iter()
            .chain(omissions.iter().map(|o| format!("- {o}")))
            .collect();
        if !comment.is_empty() || !notes.is_empty() {
            out.push_str("<!--\n");
            for block in comment.iter().chain(&notes) {
                for line in block.lines() {
                    // "--" may not appear inside an XML comment.
                    out.push_str(&format!("  {}\n", line.replace("--", "- -")));
                }
            }
            out.push_str("-->\n");
        }
        out.push_str(&body);
        out.push('\n');
        Ok(out)
    }

    /// What this robot's URDF ([`Robot::to_urdf_string`]) leaves out or writes only as the
    /// robot file's model has it: for a robot read from a URDF file, its compliances and
    /// payload (the file's own limits and inertias are carried through); for any other,
    /// the effort and velocity limits and the inertia tensors of the links with a mass too.
    pub fn urdf_omissions(&self) -> Vec<UrdfOmission> {
        let mut out = Vec::new();
        if self.urdf_source().is_none() {
            out.push(UrdfOmission::EffortAndVelocity);
            if self.joints().iter().any(|j| j.inertial.is_some()) {
                out.push(UrdfOmission::InertiaTensors);
            }
        }
        if self
            .joints()
            .iter()
            .any(|j| j.compliance_urad_per_nm.is_some())
        {
            out.push(UrdfOmission::Compliances);
        }
        if self.payload().is_some() {
            out.push(UrdfOmission::Payload);
        }
        out
    }

    /// A URDF of this robot's chain alone: `base_link`, `link_1` … (see the module docs).
    fn fresh_urdf(&self, origins: &[Transform]) -> Result<urdf_rs::Robot, RobotError> {
        let link = |name: String, inertial: Option<LinkInertial>| urdf_rs::Link {
            name,
            inertial: inertial
                .map(|i| urdf_rs::Inertial {
                    origin: Pose {
                        xyz: Vec3(i.com_mm.map(|v| v / 1000.0)),
                        rpy: Vec3([0.0; 3]),
                    },
                    mass: urdf_rs::Mass { value: i.mass_kg },
                    inertia: urdf_rs::Inertia::default(),
                })
                .unwrap_or_default(),
            visual: Vec::new(),
            collision: Vec::new(),
        };
        // URDF 1.2: effort and velocity limits, which robot files do not give, are optional.
        let mut urdf = urdf_rs::Robot {
            name: self.name.clone(),
            version: Some("1.2".into()),
            links: vec![link("base_link".into(), None)],
            joints: Vec::new(),
            materials: Vec::new(),
        };
        let mut parent = "base_link".to_owned();
        for (i, (joint, origin)) in self.joints().iter().zip(origins).enumerate() {
            let child = format!("link_{}", i + 1);
            let chain_joint = &self.chain().joints()[i];
            let [lower, upper] = joint.limits;
            let (joint_type, scale) = match chain_joint.kind {
                JointKind::Revolute if lower.is_infinite() && upper.is_infinite() => {
                    (JointType::Continuous, 1.0)
                }
                JointKind::Revolute => (JointType::Revolute, 1.0),
                JointKind::Prismatic => (JointType::Prismatic, 1e-3),
            };
            urdf.links.push(link(child.clone(), joint.inertial));
            urdf.joints.push(urdf_rs::Joint {
                name: joint.name.clone(),
                joint_type,
                origin: pose_of_transform(origin),
                parent: urdf_rs::LinkName { link: parent },
                child: urdf_rs::LinkName {
                    link: child.clone(),
                },
                axis: urdf_rs::Axis {
                    xyz: Vec3(chain_joint.axis),
                },
                // Unknown effort and velocity, and a continuous joint's infinite limits,
                // are infinite: the writer leaves them out.
                limit: urdf_rs::JointLimit {
                    lower: lower * scale,
                    upper: upper * scale,
                    effort: f64::INFINITY,
                    velocity: f64::INFINITY,
                    ..urdf_rs::JointLimit::default()
                },
                calibration: None,
                dynamics: None,
                mimic: None,
                safety_controller: None,
            });
            parent = child;
        }
        add_tcp(&mut urdf, &parent, &self.chain().tool)?;
        Ok(urdf)
    }
}

/// Adds the fixed joint [`TCP_JOINT`] from `tip` to a new link [`TCP_LINK`] at `tcp`.
fn add_tcp(urdf: &mut urdf_rs::Robot, tip: &str, tcp: &Transform) -> Result<(), RobotError> {
    if urdf.links.iter().any(|l| l.name == TCP_LINK) {
        return Err(chain_error(format!(
            "the file already has a link '{TCP_LINK}' that is not the tip of the chain"
        )));
    }
    urdf.links.push(urdf_rs::Link {
        name: TCP_LINK.into(),
        inertial: urdf_rs::Inertial::default(),
        visual: Vec::new(),
        collision: Vec::new(),
    });
    urdf.joints.push(urdf_rs::Joint {
        name: TCP_JOINT.into(),
        joint_type: JointType::Fixed,
        origin: pose_of_transform(tcp),
        parent: urdf_rs::LinkName { link: tip.into() },
        child: urdf_rs::LinkName {
            link: TCP_LINK.into(),
        },
        axis: urdf_rs::Axis::default(),
        limit: fixed_joint_limit(urdf),
        calibration: None,
        dynamics: None,
        mimic: None,
        safety_controller: None,
    });
    Ok(())
}

/// The `<limit>` of a fixed joint, which nothing reads: empty from URDF 1.2 on, where its
/// attributes are optional (the writer leaves infinite ones out); zeros before, where
/// parsers require them.
fn fixed_joint_limit(urdf: &urdf_rs::Robot) -> urdf_rs::JointLimit {
    let version = urdf.version.as_deref().and_then(|v| {
        let (major, minor) = v.trim().split_once('.')?;
        Some((major.parse::<u32>().ok()?, minor.parse::<u32>().ok()?))
    });
    if version.is_some_and(|v| v >= (1, 2)) {
        urdf_rs::JointLimit {
            lower: f64::NEG_INFINITY,
            upper: f64::INFINITY,
            effort: f64::INFINITY,
            velocity: f64::INFINITY,
            ..urdf_rs::JointLimit::default()
        }
    } else {
        urdf_rs::JointLimit::default()
    }
}

/// The URDF writer's text without the `<inertial>` elements of links that weigh nothing
/// (urdf-rs writes one, all zeros, for every link): an absent `<inertial>` says the same
/// and claims no knowledge of a mass of zero.
fn without_unknown_inertials(xml: &str) -> String {
    const UNKNOWN: [&str; 5] = [
        "<inertial>",
        "<origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>",
        "<mass value=\"0\"/>",
        "<inertia ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"/>",
        "</inertial>",
    ];
    let lines: Vec<&str> = xml.lines().collect();
    let mut out = String::with_capacity(xml.len());
    let mut i = 0;
    while i < lines.len() {
        let block = lines.get(i..i + UNKNOWN.len());
        if block.is_some_and(|b| b.iter().zip(UNKNOWN).all(|(l, u)| l.trim() == u)) {
            i += UNKNOWN.len();
            continue;
        }
        // A link left empty closes itself.
        let line = lines[i];
        if line.trim_start().starts_with("<link ") && line.ends_with('>') && !line.ends_with("/>") {
            let mut next = i + 1;
            while lines
                .get(next..next + UNKNOWN.len())
                .is_some_and(|b| b.iter().zip(UNKNOWN).all(|(l, u)| l.trim() == u))
            {
                next += UNKNOWN.len();
            }
            if lines.get(next).is_some_and(|l| l.trim() == "</link>") {
                out.push_str(&line[..line.len() - 1]);
                out.push_str("/>\n");
                i = next + 1;
                continue;
            }
        }
        out.push_str(line);
        out.push('\n');
        i += 1;
    }
    // The writer's text has no final newline; the caller adds one.
    out.pop();
    out
}
