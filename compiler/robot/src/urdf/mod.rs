//! URDF robot descriptions: the serial chain between two links of a URDF file as a
//! [`Robot`], and a (calibrated) robot written back as URDF.
//!
//! # Reading
//!
//! The file is parsed with the `urdf-rs` crate. The chain runs from the base link (the
//! file's only root link, or [`LinkNames::base_link`]) to the tip link (the only leaf below
//! the base, or [`LinkNames::tip_link`]). Its `revolute`, `continuous` and `prismatic`
//! joints are the robot's joints, in order from the base; `fixed` joints fold into the next
//! movable joint's origin (or into the tool, after the last movable joint); `floating`,
//! `planar` and `spherical` joints, and joints that `mimic` another, are refused. Origins
//! are `xyz` (m, written here in mm) and `rpy` (`R = Rz(yaw)·Ry(pitch)·Rx(roll)`); axes are
//! normalised.
//!
//! # Base
//!
//! Poses are given in the controller's base frame: link [`BASE_FRAME_LINK`] (`base`,
//! ROS-Industrial's, REP 199) where it hangs from the chain's base link through fixed
//! joints alone, beside the chain (a Fanuc's world at its second axis's height, a UR's
//! turned by π about z); else the base link's frame. Choosing the tip, a leaf so fixed to the base
//! link is a frame, not the chain's end. (A robot file naming the URDF gives another frame
//! by its `[base]`: the base link in it, composed after this one.)
//!
//! # Flange
//!
//! The flange is the frame a controller's tool data (KRL `$TOOL`, RAPID `tooldata`, a
//! `--tool`) and the robot's tool are given in: the link [`LinkNames::flange_link`] names,
//! else the first of [`FLANGE_LINKS`] the file has (`tool0`, ROS-Industrial's mounting
//! flange, `z` out of it; then `flange`). Either must hang from the last movable joint's
//! link through fixed joints alone (a named link that does not is refused; a default one
//! that does not is passed over); without one the flange is the last movable joint's link
//! itself. Its fixed offset is [`Robot::flange`]; the robot's tool is the tip link's frame
//! in the flange's (a TOML robot file naming the URDF file may add a `[tool]` after the tip
//! link). So a ROS-Industrial arm read to `tool0` has no tool, as its controller has none
//! at `$TOOL` 0, however far its last joint's frame lies from the flange.
//!
//! Limits: `revolute` and `prismatic` joints need `lower < upper` (rad; m, read in mm);
//! `continuous` joints have none (`[−∞, ∞]`). The home posture is zero where the limits
//! allow it, else the middle of the limits.
//!
//! Masses: the link a joint moves is its child link together with every link fixed to it
//! (through `fixed` joints, not through movable ones); its mass is their `<inertial>` masses
//! summed and its centre of mass their mass-weighted mean, in the child link's frame (the
//! joint's frame after its motion). Links before the first movable joint do not move and
//! are not counted. A link without `<inertial>` weighs nothing.
//!
//! # Writing
//!
//! [`Robot::to_urdf_string`] writes a robot as URDF. A robot read from a URDF file is
//! written as that file's robot (every link, joint, inertial and mesh kept) with the chain's
//! movable joints' origins replaced by the robot's: each joint's constant offset and, for
//! the first joint, the base are folded into the origin (URDF has neither), and the fixed
//! joints before a movable joint keep their origins. Any other robot (MD-H, or TOML chain
//! joints) is written as a fresh URDF: `base_link`, then per joint `link_i` (masses and
//! centres of mass as `<inertial>`, inertia tensors zero: unknown). Either way a fixed joint
//! `calibrated_tcp_joint` from the tip link to a new link `calibrated_tcp` carries the tool
//! (the TCP in the tip link's frame), so that the written file's only new leaf is the TCP:
//! read again it gives the same forward kinematics to rounding. What the robot file does
//! not give is never written as if it did ([`UrdfOmission`], also listed in the file's
//! header comment): a fresh URDF is URDF 1.2, where effort and velocity limits are optional,
//! and leaves them out; a link without a mass has no `<inertial>`; a link with one is that
//! point mass (inertia zero about its centre of mass). Compliances and a payload have no
//! place in URDF and are left out.
//!
//! # Limits
//!
//! Before it is parsed, the text is scanned once for its size: at most [`MAX_URDF_DEPTH`]
//! levels of nested elements, [`MAX_URDF_ELEMENTS`] elements, [`MAX_URDF_LINKS`] links and
//! [`MAX_URDF_JOINTS`] joints, each far beyond any robot's description, so that a hostile
//! file is refused in one linear pass rather than exhausting the stack or the memory of the
//! parser. Every number of the parsed file, on the chain or off it, must then lie in its
//! plausible range ([`crate::plausible`]), with the element and attribute named; link and
//! joint names must be unique. Messages list at most a few names.

use std::collections::HashMap;

use adwi_runtime::chain::{ChainJoint, JointKind};
use adwi_runtime::kinematics::Transform;
use urdf_rs::{JointType, Pose, Vec3};

use crate::model::{
    rpy_of, transform_from_xyz_rpy, unit_axis, Geometry, Joint, LinkInertial, Robot, RobotError,
    UrdfSource, MAX_JOINTS,
};
use crate::plausible::{first_few, name as shown};

mod check;
mod scan;
mod write;

pub use scan::{MAX_URDF_DEPTH, MAX_URDF_ELEMENTS, MAX_URDF_JOINTS, MAX_URDF_LINKS};
pub use write::UrdfOmission;

pub use crate::error::UrdfParseError;

/// How many names a message lists before "and N more".
const NAMES_SHOWN: usize = 8;

/// The name of the link [`Robot::to_urdf_string`] adds for the TCP.
pub const TCP_LINK: &str = "calibrated_tcp";
/// The name of the fixed joint to [`TCP_LINK`].
pub const TCP_JOINT: &str = "calibrated_tcp_joint";

/// Which links of a URDF file bound the chain; `None` for the file's only root and only
/// leaf.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LinkNames {
    /// The link the chain starts at: the robot's base frame.
    pub base_link: Option<String>,
    /// The link the chain ends at: the frame of the TCP (before any tool a TOML robot file
    /// adds).
    pub tip_link: Option<String>,
    /// The flange, the link a controller's tool data are given in: fixed to the last
    /// movable joint's link (`None`: the first of [`FLANGE_LINKS`] the file has fixed
    /// there, else the last movable joint's own link).
    pub flange_link: Option<String>,
}

/// The links a URDF without [`LinkNames::flange_link`] is read with as its flange, the first
/// the file has fixed to the last movable joint's link: ROS-Industrial's `tool0` (REP 199:
/// the mounting flange in the controller's own convention, where its tool data start),
/// then `flange`, the name other descriptions give the mounting flange.
pub const FLANGE_LINKS: [&str; 2] = ["tool0", "flange"];

/// The link ROS-Industrial's descriptions (REP 199) give the controller's base frame,
/// beside the chain's base link: the frame the controller's programs, and measurements
/// taken from it, give poses in.
pub const BASE_FRAME_LINK: &str = "base";

fn chain_error(message: String) -> RobotError {
    RobotError::UrdfChain(message)
}

/// A URDF origin as a transform, mm.
fn transform_of_pose(pose: &Pose) -> Transform {
    transform_from_xyz_rpy(pose.xyz.0.map(|v| v * 1000.0), pose.rpy.0)
}

/// A transform as a URDF origin, m.
fn pose_of_transform(t: &Transform) -> Pose {
    Pose {
        xyz: Vec3(t.translation_mm.map(|v| v / 1000.0)),
        rpy: Vec3(rpy_of(t)),
    }
}

/// The product of the origins of `joints` (indices into `robot.joints`), in order.
fn product(robot: &urdf_rs::Robot, joints: &[usize]) -> Transform {
    joints.iter().fold(Transform::IDENTITY, |t, &j| {
        t.compose(&transform_of_pose(&robot.joints[j].origin))
    })
}

/// Reads a robot from URDF text (see the module docs).
pub(crate) fn robot_from_urdf_str(text: &str, links: &LinkNames) -> Result<Robot, RobotError> {
    scan::check_size(text)?;
    let urdf = urdf_rs::read_from_string(text).map_err(|error| RobotError::Urdf {
        path: std::path::PathBuf::new(),
        source: UrdfParseError::new(&error),
    })?;
    robot_from_urdf(&urdf, links)
}

/// The robot of a parsed URDF file's chain between `links` (see the module docs).
///
/// # Errors
///
/// [`RobotError::UrdfChain`] when the file has more links or joints than the module docs
/// allow ("Limits"), two links or two joints of one name, no such chain or a joint on it
/// that cannot be modelled; [`RobotError::NonFinite`] or [`RobotError::Implausible`] for a
/// number outside its range; and the validation errors of [`Robot::new`].
pub fn robot_from_urdf(urdf: &urdf_rs::Robot, links: &LinkNames) -> Result<Robot, RobotError> {
    let tree = Tree::of(urdf)?;
    let base = base_link(urdf, links, &tree)?;
    let tip = tip_link(urdf, links, &tree, &base)?;
    let path = path_between(urdf, &tree, &base, &tip)?;
    let (movable, fixed_before, fixed_after) = split_at_fixed(urdf, &path)?;
    let mut rows = Vec::with_capacity(movable.len());
    let mut joints = Vec::with_capacity(movable.len());
    let mut home = Vec::with_capacity(movable.len());
    for (&j, before) in movable.iter().zip(&fixed_before) {
        let (row, joint) = movable_joint(urdf, &tree, j, before)?;
        home.push(home_within(joint.limits));
        rows.push(row);
        joints.push(joint);
    }
    let last = &urdf.joints[*movable.last().expect("split_at_fixed: one movable joint")];
    let flange = flange_of(urdf, links, &tree, &last.child.link)?;
    let tool = flange.inverse().compose(&product(urdf, &fixed_after));
    let name = if urdf.name.is_empty() {
        "URDF robot".to_owned()
    } else {
        urdf.name.clone()
    };
    let base_frame = base_frame_of(urdf, &tree, &base, &path);
    // The identity's inverse would hold −0.0: a frame where the base link is, exactly,
    // leaves the base as the identity, and the table the same bytes.
    let base_of_chain = if base_frame == Transform::IDENTITY {
        Transform::IDENTITY
    } else {
        base_frame.inverse()
    };
    let mut robot = Robot::with_flange_at(
        name,
        Geometry::Chain(rows),
        joints,
        base_of_chain,
        flange,
        tool,
        home,
    )?;
    robot.set_urdf_source(UrdfSource {
        robot: urdf.clone(),
        tip_link: tip,
        base_frame,
        movable,
        fixed_before,
        fixed_after,
    });
    Ok(robot)
}

/// A URDF file's links and joints as a tree, checked: within the limits, every name once,
/// every link a joint names present, no link the child of two joints.
struct Tree<'a> {
    /// Each link's index, by name.
    link_index: HashMap<&'a str, usize>,
    /// Each link's parent joint.
    parent_joint: HashMap<&'a str, usize>,
    /// Each link's child joints.
    child_joints: HashMap<&'a str, Vec<usize>>,
}

impl<'a> Tree<'a> {
    fn of(urdf: &'a urdf_rs::Robot) -> Result<Tree<'a>, RobotError> {
        for (count, max, what) in [
            (urdf.links.len(), MAX_URDF_LINKS, "links"),
            (urdf.joints.len(), MAX_URDF_JOINTS, "joints"),
        ] {
            if count > max {
                return Err(chain_error(format!(
                    "{count} {what}, more than the {max} a URDF file may have"
                )));
            }
        }
        let mut link_index = HashMap::new();
        for (i, link) in urdf.links.iter().enumerate() {
            if link_index.insert(link.name.as_str(), i).is_some() {
                return Err(chain_error(format!(
                    "two links are named '{}'",
                    shown(&link.name)
                )));
            }
        }
        let mut joint_names = std::collections::HashSet::new();
        for joint in &urdf.joints {
            if !joint_names.insert(joint.name.as_str()) {
                return Err(chain_error(format!(
                    "two joints are named '{}'",
                    shown(&joint.name)
                )));
            }
        }
        crate::plausible::check_name(&urdf.name)?;
        check::check_numbers(urdf)?;
        let mut parent_joint: HashMap<&str, usize> = HashMap::new();
        let mut child_joints: HashMap<&str, Vec<usize>> = HashMap::new();
        for (j, joint) in urdf.joints.iter().enumerate() {
            for end in [&joint.parent.link, &joint.child.link] {
                if !link_index.contains_key(end.as_str()) {
                    return Err(chain_error(format!(
                        "joint '{}' names the link '{}', which the file does not have",
                        shown(&joint.name),
                        shown(end)
                    )));
                }
            }
            if parent_joint.insert(joint.child.link.as_str(), j).is_some() {
                return Err(chain_error(format!(
                    "link '{}' is the child of two joints: not a tree",
                    shown(&joint.child.link)
                )));
            }
            child_joints
                .entry(joint.parent.link.as_str())
                .or_default()
                .push(j);
        }
        Ok(Tree {
            link_index,
            parent_joint,
            child_joints,
        })
    }

    /// `name`, a link the options name as the chain's `role` link, when the file has it.
    fn named<'n>(&self, name: &'n str, role: &str) -> Result<&'n str, RobotError> {
        if self.link_index.contains_key(name) {
            Ok(name)
        } else {
            Err(chain_error(format!(
                "no link named '{}' ({role} link)",
                shown(name)
            )))
        }
    }
}

/// The base link: the one named, or the file's one root.
fn base_link(urdf: &urdf_rs::Robot, links: &LinkNames, tree: &Tree) -> Result<String, RobotError> {
    if let Some(name) = &links.base_link {
        return Ok(tree.named(name, "base")?.to_owned());
    }
    let roots: Vec<&str> = urdf
        .links
        .iter()
        .map(|l| l.name.as_str())
        .filter(|l| !tree.parent_joint.contains_key(l))
        .collect();
    match roots.as_slice() {
        [root] => Ok((*root).to_owned()),
        _ => Err(chain_error(format!(
            "{} root links ({}): name the base link",
            roots.len(),
            first_few(&roots, NAMES_SHOWN)
        ))),
    }
}

/// The tip link: the one named, or the one leaf below `base`.
fn tip_link(
    urdf: &urdf_rs::Robot,
    links: &LinkNames,
    tree: &Tree,
    base: &str,
) -> Result<String, RobotError> {
    if let Some(name) = &links.tip_link {
        return Ok(tree.named(name, "tip")?.to_owned());
    }
    // The leaves below the base, depth first, and whether a movable joint leads to each:
    // a leaf fixed to the base (ROS-Industrial's `base` frame beside the chain) is a frame,
    // not the chain's end.
    let mut leaves = Vec::new();
    let mut stack = vec![(base, false)];
    let mut visited = 0;
    while let Some((link, moved)) = stack.pop() {
        visited += 1;
        if visited > urdf.links.len() {
            return Err(chain_error("the joints form a cycle".into()));
        }
        match tree.child_joints.get(link) {
            Some(children) if !children.is_empty() => {
                for &j in children.iter().rev() {
                    let joint = &urdf.joints[j];
                    let movable = joint.joint_type != JointType::Fixed;
                    stack.push((joint.child.link.as_str(), moved || movable));
                }
            }
            _ => leaves.push((link, moved)),
        }
    }
    let moved: Vec<&str> = leaves.iter().filter(|l| l.1).map(|l| l.0).collect();
    let leaves = if moved.is_empty() {
        leaves.iter().map(|l| l.0).collect()
    } else {
        moved
    };
    match leaves.as_slice() {
        [leaf] => Ok((*leaf).to_owned()),
        _ => Err(chain_error(format!(
            "{} leaf links below '{}' ({}): name the tip link",
            leaves.len(),
            shown(base),
            first_few(&leaves, NAMES_SHOWN)
        ))),
    }
}

/// The controller's base frame in the chain's base link `base` (module docs, "Base"):
/// link [`BASE_FRAME_LINK`] where it hangs from `base` through fixed joints alone, beside
/// the chain (`path`), not on it.
fn base_frame_of(urdf: &urdf_rs::Robot, tree: &Tree, base: &str, path: &[usize]) -> Transform {
    let on_chain = base == BASE_FRAME_LINK
        || path
            .iter()
            .any(|&j| urdf.joints[j].child.link == BASE_FRAME_LINK);
    if on_chain {
        return Transform::IDENTITY;
    }
    fixed_below(urdf, tree, base, BASE_FRAME_LINK).unwrap_or(Transform::IDENTITY)
}

/// The flange in the last movable joint's link `end` (module docs, "Flange"): the origins of
/// the fixed joints from `end` down to the flange link.
fn flange_of(
    urdf: &urdf_rs::Robot,
    links: &LinkNames,
    tree: &Tree,
    end: &str,
) -> Result<Transform, RobotError> {
    if let Some(name) = &links.flange_link {
        return fixed_below(urdf, tree, end, tree.named(name, "flange")?).ok_or_else(|| {
            chain_error(format!(
                "the flange link '{}' is not fixed to '{}', the last movable joint's link",
                shown(name),
                shown(end)
            ))
        });
    }
    Ok(FLANGE_LINKS
        .iter()
        .find_map(|name| fixed_below(urdf, tree, end, name))
        .unwrap_or(Transform::IDENTITY))
}

/// Link `name` in link `end`'s frame when it hangs from `end` through fixed joints alone
/// (`end` itself: the identity); `None` when it does not or the file has no such link.
fn fixed_below(urdf: &urdf_rs::Robot, tree: &Tree, end: &str, name: &str) -> Option<Transform> {
    let mut joints = Vec::new();
    let mut link = tree.link_index.get(name).map(|_| name)?;
    while link != end {
        let j = *tree.parent_joint.get(link)?;
        let joint = &urdf.joints[j];
        if joint.joint_type != JointType::Fixed || joints.len() >= urdf.joints.len() {
            return None;
        }
        joints.push(j);
        link = joint.parent.link.as_str();
    }
    joints.reverse();
    Some(product(urdf, &joints))
}

/// The joints from `base` down to `tip`, in order.
fn path_between(
    urdf: &urdf_rs::Robot,
    tree: &Tree,
    base: &str,
    tip: &str,
) -> Result<Vec<usize>, RobotError> {
    // The joints from the tip up to the base, then reversed.
    let mut path = Vec::new();
    let mut link = tip;
    while link != base {
        let Some(&j) = tree.parent_joint.get(link) else {
            return Err(chain_error(format!(
                "link '{}' is not below link '{}'",
                shown(tip),
                shown(base)
            )));
        };
        if path.len() > urdf.joints.len() {
            return Err(chain_error("the joints form a cycle".into()));
        }
        path.push(j);
        link = urdf.joints[j].parent.link.as_str();
    }
    path.reverse();
    Ok(path)
}

/// The movable joints of `path`, the fixed joints before each, and those after the last.
type SplitChain = (Vec<usize>, Vec<Vec<usize>>, Vec<usize>);

/// `path` split at its fixed joints ([`SplitChain`]), every joint one a serial chain can
/// hold, and as many movable joints as a table takes.
fn split_at_fixed(urdf: &urdf_rs::Robot, path: &[usize]) -> Result<SplitChain, RobotError> {
    let mut movable = Vec::new();
    let mut fixed_before = Vec::new();
    let mut pending = Vec::new();
    for &j in path {
        let joint = &urdf.joints[j];
        if joint.mimic.is_some() {
            return Err(chain_error(format!(
                "joint '{}' mimics another joint: not a serial chain of independent joints",
                shown(&joint.name)
            )));
        }
        match joint.joint_type {
            JointType::Fixed => pending.push(j),
            JointType::Revolute | JointType::Continuous | JointType::Prismatic => {
                movable.push(j);
                fixed_before.push(std::mem::take(&mut pending));
            }
            ref other => {
                return Err(chain_error(format!(
                    "joint '{}' is {other:?}: only revolute, continuous, prismatic and fixed \
                     joints make a serial chain",
                    shown(&joint.name)
                )))
            }
        }
    }
    if movable.is_empty() || movable.len() > MAX_JOINTS {
        return Err(RobotError::JointCount {
            found: movable.len(),
        });
    }
    Ok((movable, fixed_before, pending))
}

/// Movable joint `j` as a row of the chain (its origin after the fixed joints `before`)
/// and as a joint description (limits, in mm for a prismatic joint; the inertial of the
/// body it moves).
fn movable_joint(
    urdf: &urdf_rs::Robot,
    tree: &Tree,
    j: usize,
    before: &[usize],
) -> Result<(ChainJoint, Joint), RobotError> {
    let joint = &urdf.joints[j];
    let axis = unit_axis(joint.axis.xyz.0).ok_or_else(|| {
        chain_error(format!(
            "joint '{}' has an axis of zero length",
            shown(&joint.name)
        ))
    })?;
    let (kind, limits) = match joint.joint_type {
        JointType::Continuous => (JointKind::Revolute, [f64::NEG_INFINITY, f64::INFINITY]),
        JointType::Revolute => (JointKind::Revolute, [joint.limit.lower, joint.limit.upper]),
        _ => (
            JointKind::Prismatic,
            [joint.limit.lower * 1000.0, joint.limit.upper * 1000.0],
        ),
    };
    // A missing <limit> reads as [0, 0]; NaN never compares less.
    if limits[0].partial_cmp(&limits[1]) != Some(std::cmp::Ordering::Less) {
        return Err(chain_error(format!(
            "joint '{}' has limits lower {} upper {}: a {} joint needs lower < upper",
            shown(&joint.name),
            joint.limit.lower,
            joint.limit.upper,
            if kind == JointKind::Revolute {
                "revolute"
            } else {
                "prismatic"
            }
        )));
    }
    let row = ChainJoint {
        origin: product(urdf, before).compose(&transform_of_pose(&joint.origin)),
        axis,
        kind,
        offset: 0.0,
    };
    let description = Joint {
        name: joint.name.clone(),
        limits,
        inertial: body_inertial(
            urdf,
            &joint.child.link,
            &tree.link_index,
            &tree.child_joints,
        ),
        compliance_urad_per_nm: None,
    };
    Ok((row, description))
}

/// A home value within `limits`: zero when they hold it, else their middle, else the
/// finite end.
fn home_within(limits: [f64; 2]) -> f64 {
    if (limits[0]..=limits[1]).contains(&0.0) {
        0.0
    } else if limits[0].is_finite() && limits[1].is_finite() {
        0.5 * (limits[0] + limits[1])
    } else if limits[0].is_finite() {
        limits[0]
    } else {
        limits[1]
    }
}

/// The mass and centre of mass (mm, in `link`'s frame) of `link` and every link fixed to
/// it; `None` when they weigh nothing.
fn body_inertial(
    urdf: &urdf_rs::Robot,
    link: &str,
    link_index: &HashMap<&str, usize>,
    child_joints: &HashMap<&str, Vec<usize>>,
) -> Option<LinkInertial> {
    let mut mass = 0.0;
    let mut moment = [0.0; 3];
    let mut stack = vec![(link, Transform::IDENTITY)];
    let mut visited = 0;
    while let Some((name, frame)) = stack.pop() {
        visited += 1;
        if visited > urdf.links.len() {
            break;
        }
        if let Some(l) = link_index.get(name).map(|&i| &urdf.links[i]) {
            let m = l.inertial.mass.value;
            if m > 0.0 {
                let com = frame.transform_point(l.inertial.origin.xyz.0.map(|v| v * 1000.0));
                mass += m;
                for a in 0..3 {
                    moment[a] += m * com[a];
                }
            }
        }
        for &j in child_joints.get(name).map(Vec::as_slice).unwrap_or(&[]) {
            let joint = &urdf.joints[j];
            if joint.joint_type == JointType::Fixed {
                let child = frame.compose(&transform_of_pose(&joint.origin));
                stack.push((joint.child.link.as_str(), child));
            }
        }
    }
    (mass > 0.0).then(|| LinkInertial {
        mass_kg: mass,
        com_mm: moment.map(|v| v / mass),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{isometry_from_transform, shipped_file, transform_from_xyz_rpy};
    use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A URDF that exercises everything: fixed joints before, between and after movable
    /// ones, axes that are no coordinate axis (one not even unit length), a prismatic and a
    /// continuous joint, arbitrary rpy, inertials on fixed-on links, and a side branch.
    const TEST_URDF: &str = r#"<?xml version="1.0"?>
<robot name="test arm">
  <link name="world"/>
  <link name="base"><inertial><origin xyz="0 0 0.1"/><mass value="50"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="l1"><inertial><origin xyz="0.1 0 0.2" rpy="0.3 0 0"/><mass value="4"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="l1_cover"><inertial><origin xyz="0 0.05 0"/><mass value="1"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="l2"/>
  <link name="l2b"/>
  <link name="l3"/>
  <link name="l4"/>
  <link name="camera"/>
  <link name="flange"/>
  <link name="tool0"/>
  <joint name="world_base" type="fixed">
    <parent link="world"/><child link="base"/>
    <origin xyz="0.5 -0.2 0.01" rpy="0 0 0.7"/>
  </joint>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3" rpy="0.1 -0.2 0.3"/>
    <axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
  <joint name="cover" type="fixed">
    <parent link="l1"/><child link="l1_cover"/>
    <origin xyz="0.02 0 0" rpy="0 1.5707963267948966 0"/>
  </joint>
  <joint name="j2" type="revolute">
    <parent link="l1"/><child link="l2"/>
    <origin xyz="0.05 0.1 0.25" rpy="1.5707963267948966 0 0"/>
    <axis xyz="0 1 -1"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/>
  </joint>
  <joint name="l2_fixed" type="fixed">
    <parent link="l2"/><child link="l2b"/>
    <origin xyz="0.4 0 0" rpy="0 0 -0.4"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="l2b"/><child link="l3"/>
    <origin xyz="0 0 0.02" rpy="0.2 0.1 0"/>
    <axis xyz="1 0 0"/>
    <limit lower="-0.1" upper="0.3" effort="1" velocity="1"/>
  </joint>
  <joint name="spin" type="continuous">
    <parent link="l3"/><child link="l4"/>
    <origin xyz="0.1 0 0" rpy="-1.2 0.4 2.5"/>
    <axis xyz="0.3 -0.4 0.866"/>
  </joint>
  <joint name="camera_mount" type="fixed">
    <parent link="l2"/><child link="camera"/>
    <origin xyz="0 0.1 0"/>
  </joint>
  <joint name="l4_flange" type="fixed">
    <parent link="l4"/><child link="flange"/>
    <origin xyz="0 0 0.08" rpy="3.141592653589793 0 0"/>
  </joint>
  <joint name="flange_tool0" type="fixed">
    <parent link="flange"/><child link="tool0"/>
    <origin xyz="0.01 0.02 0.15" rpy="0 -1.5707963267948966 -1.5707963267948966"/>
  </joint>
</robot>
"#;

    /// The TCP pose by a walk of the parsed file, independent of the import: from the tip
    /// up to the base through the parent joints, each origin `Translation(xyz)·Rz·Ry·Rx`
    /// and each motion a nalgebra rotation about (or translation along) the normalised
    /// axis. Metres, joint values in metres for prismatic joints.
    fn walk(urdf: &urdf_rs::Robot, base: &str, tip: &str, q: &[f64]) -> Isometry3<f64> {
        let mut path = Vec::new();
        let mut link = tip.to_owned();
        while link != base {
            let joint = urdf
                .joints
                .iter()
                .find(|j| j.child.link == link)
                .expect("a parent joint");
            path.push(joint);
            link = joint.parent.link.clone();
        }
        path.reverse();
        let mut values = q.iter();
        let mut pose = Isometry3::identity();
        for joint in path {
            let [x, y, z] = joint.origin.xyz.0;
            let [roll, pitch, yaw] = joint.origin.rpy.0;
            pose *= Isometry3::from_parts(
                Translation3::new(x, y, z),
                UnitQuaternion::from_euler_angles(roll, pitch, yaw),
            );
            let axis = Unit::new_normalize(Vector3::from(joint.axis.xyz.0));
            match joint.joint_type {
                JointType::Fixed => {}
                JointType::Prismatic => {
                    let v = *values.next().unwrap();
                    pose *= Translation3::from(axis.into_inner() * v);
                }
                _ => {
                    let v = *values.next().unwrap();
                    pose *= UnitQuaternion::from_axis_angle(&axis, v);
                }
            }
        }
        assert!(values.next().is_none());
        pose
    }

    /// Random joint values within the sampling ranges, in the robot's units (rad, mm).
    fn random_q(robot: &Robot, rng: &mut ChaCha8Rng) -> Vec<f64> {
        (0..robot.joint_count())
            .map(|i| {
                let [lo, hi] = robot.sampling_range(i);
                rng.gen_range(lo..hi)
            })
            .collect()
    }

    /// Compares the imported robot's FK with the walk over 1000 random joint vectors and
    /// returns the largest position difference, mm.
    fn largest_walk_difference(
        text: &str,
        links: &LinkNames,
        base: &str,
        tip: &str,
        seed: u64,
    ) -> f64 {
        let robot = robot_from_urdf_str(text, links).unwrap();
        let urdf = urdf_rs::read_from_string(text).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut largest: f64 = 0.0;
        for _ in 0..1000 {
            let q = random_q(&robot, &mut rng);
            // The walk takes metres for prismatic joints.
            let q_si: Vec<f64> = q
                .iter()
                .enumerate()
                .map(|(i, v)| match robot.joint_kind(i) {
                    JointKind::Prismatic => v / 1000.0,
                    JointKind::Revolute => *v,
                })
                .collect();
            let want = walk(&urdf, base, tip, &q_si);
            let got = robot.tcp_pose(&q);
            let dp = (got.translation.vector - want.translation.vector * 1000.0).norm();
            let dr = got.rotation.angle_to(&want.rotation);
            assert!(dr < 1e-12, "rotation differs by {dr} rad");
            largest = largest.max(dp);
        }
        largest
    }

    #[test]
    fn imported_chains_equal_a_direct_walk_of_the_file() {
        let links = LinkNames {
            base_link: None,
            tip_link: Some("tool0".into()),
            flange_link: None,
        };
        let test = largest_walk_difference(TEST_URDF, &links, "world", "tool0", 1);
        let mut largest = test;
        for robot in ["ur10", "iiwa14"] {
            let text = std::fs::read_to_string(shipped_file(robot, "robot.urdf")).unwrap();
            let urdf = urdf_rs::read_from_string(&text).unwrap();
            let tip = urdf
                .links
                .iter()
                .find(|l| !urdf.joints.iter().any(|j| j.parent.link == l.name))
                .unwrap()
                .name
                .clone();
            let d = largest_walk_difference(&text, &LinkNames::default(), "base_link", &tip, 2);
            println!("{robot}: largest URDF-walk difference {d:.3e} mm");
            largest = largest.max(d);
        }
        println!("test arm: largest URDF-walk difference {test:.3e} mm");
        assert!(largest < 1e-9, "{largest} mm");
        // Between other links: the chain from l1 to the camera is one revolute joint.
        let links = LinkNames {
            base_link: Some("l1".into()),
            tip_link: Some("camera".into()),
            flange_link: None,
        };
        let d = largest_walk_difference(TEST_URDF, &links, "l1", "camera", 3);
        assert!(d < 1e-9, "{d}");
    }

    /// The flange, where tool data start, is the link named, else `tool0` (then `flange`)
    /// where it hangs from the last movable joint's link by fixed joints; the robot's tool
    /// is the tip in the flange's frame, so the chain's end never moves. A named link
    /// that is not so fixed, or not there, is refused.
    #[test]
    fn the_flange_is_tool0_or_the_link_named() {
        let urdf = urdf_rs::read_from_string(TEST_URDF).unwrap();
        let joint = |name: &str| urdf.joints.iter().position(|j| j.name == name).unwrap();
        let origins =
            |names: &[&str]| product(&urdf, &names.iter().map(|n| joint(n)).collect::<Vec<_>>());
        let close = |a: &Transform, b: &Transform| {
            let (a, b) = (isometry_from_transform(a), isometry_from_transform(b));
            (a.translation.vector - b.translation.vector).norm() < 1e-9
                && a.rotation.angle_to(&b.rotation) < 1e-12
        };
        let read = |tip: &str, flange: Option<&str>| {
            robot_from_urdf_str(
                TEST_URDF,
                &LinkNames {
                    base_link: None,
                    tip_link: Some(tip.into()),
                    flange_link: flange.map(Into::into),
                },
            )
        };
        let l4_to_tool0 = origins(&["l4_flange", "flange_tool0"]);
        let cases = [
            // (tip, flange named, the flange, the tool)
            ("tool0", None, l4_to_tool0, Transform::IDENTITY),
            (
                "flange",
                None,
                l4_to_tool0,
                origins(&["flange_tool0"]).inverse(),
            ),
            (
                "tool0",
                Some("flange"),
                origins(&["l4_flange"]),
                origins(&["flange_tool0"]),
            ),
            ("tool0", Some("l4"), Transform::IDENTITY, l4_to_tool0),
        ];
        for (tip, named, flange, tool) in cases {
            let robot = read(tip, named).unwrap();
            assert!(
                close(&robot.flange(), &flange),
                "{tip} {named:?}: {:?}",
                robot.flange()
            );
            assert!(
                close(&robot.tool(), &tool),
                "{tip} {named:?}: {:?}",
                robot.tool()
            );
            let links = LinkNames {
                base_link: None,
                tip_link: Some(tip.into()),
                flange_link: named.map(Into::into),
            };
            let d = largest_walk_difference(TEST_URDF, &links, "world", tip, 4);
            assert!(d < 1e-9, "{tip} {named:?}: {d} mm");
        }
        // A chain to the camera, which hangs from l2: its last movable joint is j2, from
        // whose link no tool0 hangs, so the flange is l2's frame.
        let camera = robot_from_urdf_str(
            TEST_URDF,
            &LinkNames {
                base_link: Some("l1".into()),
                tip_link: Some("camera".into()),
                flange_link: None,
            },
        )
        .unwrap();
        assert_eq!(camera.flange(), Transform::IDENTITY);
        for (named, words) in [
            ("l3", "is not fixed to 'l4'"),
            ("camera", "is not fixed to 'l4'"),
            ("nowhere", "no link named 'nowhere' (flange link)"),
        ] {
            let error = read("tool0", Some(named)).unwrap_err().to_string();
            assert!(error.contains(words), "{named}: {error}");
        }
    }

    /// A ROS-Industrial layout (REP 199) of the UR5: its `base_link` turned by π about z
    /// from the controller's `base`, which hangs beside the chain, and `tool0` beyond the
    /// last joint. Read with no link named it is the shipped UR5 (whose base link is the
    /// controller's base): poses in `base`, the flange at `tool0`, no tool; written as URDF
    /// with a base deviation and read again, the same robot.
    #[test]
    fn a_ros_industrial_layout_reads_in_the_controllers_base_and_flange() {
        let shipped = std::fs::read_to_string(shipped_file("ur5", "robot.urdf")).unwrap();
        let turn = r#"<origin xyz="0 0 0" rpy="0 0 3.141592653589793"/>"#;
        let ros = shipped.replacen(
            r#"<link name="base_link"/>"#,
            &format!(
                r#"<link name="base_link"/>
  <link name="ros_base_link"/>
  <link name="base"/>
  <joint name="ros_base_link-base_link" type="fixed"><parent link="ros_base_link"/><child link="base_link"/>{turn}</joint>
  <joint name="ros_base_link-base" type="fixed"><parent link="ros_base_link"/><child link="base"/>{turn}</joint>"#
            ),
            1,
        );
        let plain = robot_from_urdf_str(&shipped, &LinkNames::default()).unwrap();
        let read = robot_from_urdf_str(&ros, &LinkNames::default()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let same = |a: &Robot, b: &Robot, rng: &mut ChaCha8Rng| {
            for _ in 0..50 {
                let q = random_q(a, rng);
                let (p, r) = (a.tcp_pose(&q), b.tcp_pose(&q));
                assert!((p.translation.vector - r.translation.vector).norm() < 1e-9);
                assert!(p.rotation.angle_to(&r.rotation) < 1e-12);
            }
        };
        same(&plain, &read, &mut rng);
        assert_eq!(read.tool(), Transform::IDENTITY);
        assert!((read.flange().translation_mm[2] - 82.3).abs() < 1e-9);
        // A calibrated base (a deviation before the nominal one) survives the round trip.
        let deviated = read
            .with_parts(
                "deviated".into(),
                transform_from_xyz_rpy([1.5, -0.7, 0.3], [0.001, -0.002, 0.003])
                    .compose(&read.base()),
                read.tool(),
                read.home().to_vec(),
            )
            .unwrap();
        let written = deviated.to_urdf_string(&[]).unwrap();
        let again = robot_from_urdf_str(
            &written,
            &LinkNames {
                base_link: None,
                tip_link: Some(TCP_LINK.into()),
                flange_link: None,
            },
        )
        .unwrap();
        same(&deviated, &again, &mut rng);
    }

    #[test]
    fn joints_limits_and_masses_of_the_test_arm() {
        let links = LinkNames {
            base_link: None,
            tip_link: Some("tool0".into()),
            flange_link: None,
        };
        let robot = robot_from_urdf_str(TEST_URDF, &links).unwrap();
        assert_eq!(robot.joint_count(), 4);
        let names: Vec<&str> = robot.joints().iter().map(|j| j.name.as_str()).collect();
        assert_eq!(names, ["j1", "j2", "slide", "spin"]);
        assert_eq!(robot.joint_kind(2), JointKind::Prismatic);
        assert_eq!(robot.joints()[2].limits, [-100.0, 300.0]);
        assert_eq!(robot.joints()[3].limits, [f64::NEG_INFINITY, f64::INFINITY]);
        let axis = robot.chain().joints()[1].axis;
        let s = std::f64::consts::FRAC_1_SQRT_2;
        assert!((axis[1] - s).abs() < 1e-15 && (axis[2] + s).abs() < 1e-15);
        // Link 1 with its cover: 4 kg at (100, 0, 200) mm, and 1 kg at the cover's COM
        // (0, 50, 0) mm turned by Ry(90°) (which leaves it) and moved 20 mm along x: the sum
        // is 5 kg at ((400 + 20)/5, 50/5, 800/5) mm.
        let inertial = robot.joints()[0].inertial.unwrap();
        assert!((inertial.mass_kg - 5.0).abs() < 1e-12);
        for (got, want) in inertial.com_mm.iter().zip([84.0, 10.0, 160.0]) {
            assert!((got - want).abs() < 1e-9, "{inertial:?}");
        }
        assert!(robot.joints()[1].inertial.is_none());
        // The world → base link is fixed before the first joint: the base weighs nothing.
        let gravity = robot.gravity_model().unwrap();
        assert_eq!(gravity.link_mass_kg[0], 5.0);
        assert_eq!(robot.home(), [0.0, 0.0, 0.0, 0.0]);
    }

    #[test]
    fn chains_that_cannot_be_modelled_are_refused_with_the_reason() {
        // Two leaves below the root (camera and tool0): the tip must be named.
        let error = robot_from_urdf_str(TEST_URDF, &LinkNames::default()).unwrap_err();
        assert!(error.to_string().contains("leaf links"), "{error}");
        let error = robot_from_urdf_str(
            TEST_URDF,
            &LinkNames {
                base_link: Some("l4".into()),
                tip_link: Some("camera".into()),
                flange_link: None,
            },
        )
        .unwrap_err();
        assert!(error.to_string().contains("not below"), "{error}");
        let floating = TEST_URDF.replace(
            r#"name="spin" type="continuous""#,
            r#"name="spin" type="floating""#,
        );
        let error = robot_from_urdf_str(
            &floating,
            &LinkNames {
                base_link: None,
                tip_link: Some("tool0".into()),
                flange_link: None,
            },
        )
        .unwrap_err();
        assert!(error.to_string().contains("Floating"), "{error}");
        let no_limits = TEST_URDF.replace(r#"lower="-2" upper="2""#, r#"lower="0" upper="0""#);
        let error = robot_from_urdf_str(
            &no_limits,
            &LinkNames {
                base_link: None,
                tip_link: Some("tool0".into()),
                flange_link: None,
            },
        )
        .unwrap_err();
        assert!(error.to_string().contains("'j2'"), "{error}");
        // Only fixed joints: no robot.
        let error = robot_from_urdf_str(
            TEST_URDF,
            &LinkNames {
                base_link: Some("l4".into()),
                tip_link: Some("tool0".into()),
                flange_link: None,
            },
        )
        .unwrap_err();
        assert!(
            matches!(error, RobotError::JointCount { found: 0 }),
            "{error}"
        );
    }

    /// A robot written as URDF and read again has the same forward kinematics, whether it
    /// came from a URDF file (origins replaced in the file's own robot) or from MD-H.
    #[test]
    fn written_urdf_reads_back_as_the_same_chain() {
        let links = LinkNames {
            base_link: None,
            tip_link: Some("tool0".into()),
            flange_link: None,
        };
        let robot = robot_from_urdf_str(TEST_URDF, &links).unwrap();
        // A changed model of it: offsets, a moved origin, a base and a tool.
        let Geometry::Chain(mut rows) = robot.geometry().clone() else {
            unreachable!()
        };
        rows[0].offset = 0.01;
        rows[2].offset = 3.0;
        rows[3].origin = rows[3].origin.compose(&transform_from_xyz_rpy(
            [0.5, -0.2, 0.1],
            [1e-3, -2e-3, 5e-4],
        ));
        let base = transform_from_xyz_rpy([1.0, 2.0, -0.5], [1e-3, 2e-3, -3e-3]);
        let tool = robot
            .tool()
            .compose(&transform_from_xyz_rpy([0.1, 0.0, 0.3], [0.0, 1e-3, 0.0]));
        let changed = robot
            .with_geometry("changed".into(), Geometry::Chain(rows), base, tool)
            .unwrap();
        let text = changed
            .to_urdf_string(&["written -- by a test".into()])
            .unwrap();
        assert!(text.contains("- - by a test"));
        // The file's other links are kept; the TCP is the new link, reached from tool0.
        let back = robot_from_urdf_str(
            &text,
            &LinkNames {
                base_link: None,
                tip_link: Some(TCP_LINK.into()),
                flange_link: None,
            },
        )
        .unwrap();
        assert!(text.contains("camera_mount"));
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for _ in 0..200 {
            let q = random_q(&robot, &mut rng);
            let (a, b) = (changed.tcp_pose(&q), back.tcp_pose(&q));
            assert!((a.translation.vector - b.translation.vector).norm() < 1e-9);
            assert!(a.rotation.angle_to(&b.rotation) < 1e-12);
        }
        // Written again, the TCP joint is updated rather than doubled.
        let again = back.to_urdf_string(&[]).unwrap();
        assert_eq!(again.matches(TCP_JOINT).count(), 1);

        // An MD-H robot as a fresh URDF.
        let kr150 = Robot::load(crate::model::shipped_robot_path("kr150-2")).unwrap();
        let kr150 = kr150
            .with_parts(
                kr150.name.clone(),
                base,
                transform_from_xyz_rpy([10.0, 0.0, 250.0], [0.0, 0.5, 0.0]),
                kr150.home().to_vec(),
            )
            .unwrap();
        let text = kr150.to_urdf_string(&[]).unwrap();
        let back = robot_from_urdf_str(&text, &LinkNames::default()).unwrap();
        for _ in 0..200 {
            let q = random_q(&kr150, &mut rng);
            let (a, b) = (kr150.tcp_pose(&q), back.tcp_pose(&q));
            assert!((a.translation.vector - b.translation.vector).norm() < 1e-9);
        }
        assert_eq!(back.joints()[1].limits, kr150.joints()[1].limits);
    }

    /// What the writer cannot know it does not write as if it did: a fresh URDF (from a
    /// robot file) is URDF 1.2 without effort and velocity limits, a massless link has no
    /// `<inertial>`, and the header says what is left out; read again it is the same robot.
    /// A URDF-sourced robot keeps its file's limits, and its massless links stay without
    /// an `<inertial>`.
    #[test]
    fn written_urdf_never_invents_values() {
        let ur5 = Robot::load(crate::model::shipped_robot_path("ur5")).unwrap();
        assert_eq!(
            ur5.urdf_omissions(),
            [
                UrdfOmission::EffortAndVelocity,
                UrdfOmission::InertiaTensors
            ]
        );
        let text = ur5.to_urdf_string(&["calibrated".into()]).unwrap();
        assert!(text.contains("<robot name=\"Universal Robots UR5\" version=\"1.2\">"));
        assert!(!text.contains("effort="), "{text}");
        assert!(!text.contains("velocity="), "{text}");
        assert!(text.contains("<link name=\"base_link\"/>"), "{text}");
        assert!(!text.contains("<mass value=\"0\"/>"), "{text}");
        assert!(text.contains("- effort and velocity limits: not in the robot file, left out"));
        assert!(text.contains("- inertia tensors: not in the robot file, written as zero"));
        let back = robot_from_urdf_str(&text, &LinkNames::default()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..50 {
            let q = random_q(&ur5, &mut rng);
            let (a, b) = (ur5.tcp_pose(&q), back.tcp_pose(&q));
            assert!((a.translation.vector - b.translation.vector).norm() < 1e-9);
        }
        for (a, b) in ur5.joints().iter().zip(back.joints()) {
            assert_eq!(a.limits, b.limits);
            let (a, b) = (a.inertial.unwrap(), b.inertial.unwrap());
            assert!((a.mass_kg - b.mass_kg).abs() < 1e-12);
        }
        // A continuous joint's infinite limits are left out, and read back infinite.
        let mut joints = ur5.joints().to_vec();
        joints[5].limits = [f64::NEG_INFINITY, f64::INFINITY];
        let continuous = Robot::new(
            "c".into(),
            ur5.geometry().clone(),
            joints,
            ur5.base(),
            ur5.tool(),
            ur5.home().to_vec(),
        )
        .unwrap();
        let text = continuous.to_urdf_string(&[]).unwrap();
        assert!(text.contains("type=\"continuous\""), "{text}");
        let back = robot_from_urdf_str(&text, &LinkNames::default()).unwrap();
        assert_eq!(back.joints()[5].limits, [f64::NEG_INFINITY, f64::INFINITY]);

        let urdf = Robot::load(shipped_file("ur5", "robot.urdf")).unwrap();
        assert!(urdf.urdf_omissions().is_empty());
        let text = urdf.to_urdf_string(&[]).unwrap();
        assert!(!text.contains("<mass value=\"0\"/>"), "{text}");
        assert!(text.contains("effort=\"150\""), "{text}");
        assert!(!text.contains("Not in this file"), "{text}");
        let with_payload = urdf
            .with_payload(Some(LinkInertial {
                mass_kg: 2.0,
                com_mm: [0.0; 3],
            }))
            .unwrap();
        assert_eq!(with_payload.urdf_omissions(), [UrdfOmission::Payload]);
        let text = with_payload.to_urdf_string(&[]).unwrap();
        assert!(
            text.contains("- payload: URDF has no place for it"),
            "{text}"
        );
    }

    /// Hostile files are refused with what is wrong, in time and memory proportional to
    /// their size, and messages list a few names only.
    #[test]
    fn hostile_urdf_files_are_refused_with_the_reason() {
        let tip = LinkNames {
            base_link: None,
            tip_link: Some("tool0".into()),
            flange_link: None,
        };
        let refused = |text: &str| robot_from_urdf_str(text, &tip).unwrap_err().to_string();
        // Masses that are not a mass, on the chain or off it.
        for (value, expected) in [
            ("NaN", "link 'l1' <inertial><mass value> is not a finite number"),
            ("-inf", "link 'l1' <inertial><mass value> is not a finite number"),
            ("-5", "link 'l1' <inertial><mass value>: a mass (kg) is -5, but must be at least 0"),
            ("1e308", "link 'l1' <inertial><mass value>: a mass (kg) is 1e308, but must be at most 1000000"),
        ] {
            let text = TEST_URDF.replace(r#"<mass value="4"/>"#, &format!(r#"<mass value="{value}"/>"#));
            assert_eq!(refused(&text), format!("{expected}"), "{value}");
        }
        let text = TEST_URDF.replace(
            r#"<origin xyz="0 0.1 0"/>"#,
            r#"<origin xyz="1e290 0.1 0"/>"#,
        );
        assert!(
            refused(&text)
                .starts_with("joint 'camera_mount' <origin> xyz[0]: a length (m) is 1e290"),
            "{}",
            refused(&text)
        );
        // Two joints of one name.
        let text = TEST_URDF.replace(r#"name="j2""#, r#"name="j1""#);
        assert_eq!(refused(&text), "URDF: two joints are named 'j1'");
        // Nested far too deep, and far too many joints: refused before parsing.
        let deep = TEST_URDF.replace(
            "<link name=\"l2\"/>",
            &format!(
                "<link name=\"l2\">{}{}</link>",
                "<a>".repeat(20_000),
                "</a>".repeat(20_000)
            ),
        );
        assert!(
            refused(&deep).contains("nested more than 64 deep (line"),
            "{}",
            refused(&deep)
        );
        let mut many = String::from("<robot name=\"r\"><link name=\"l0\"/>");
        for i in 0..200_000 {
            many += &format!(
                "<link name=\"l{}\"/><joint name=\"f{i}\" type=\"fixed\"><parent link=\"l{i}\"/>\
                 <child link=\"l{}\"/></joint>",
                i + 1,
                i + 1
            );
        }
        many += "</robot>";
        let start = std::time::Instant::now();
        assert!(
            refused(&many).contains("more than 200000 elements"),
            "{}",
            refused(&many)
        );
        assert!(start.elapsed().as_secs_f64() < 1.0);
        // A hundred roots: the message names eight.
        let roots: String = (0..100).map(|i| format!("<link name=\"r{i}\"/>")).collect();
        let error = robot_from_urdf_str(
            &format!("<robot name=\"r\">{roots}</robot>"),
            &LinkNames::default(),
        )
        .unwrap_err()
        .to_string();
        assert_eq!(
            error,
            "URDF: 100 root links (r0, r1, r2, r3, r4, r5, r6, r7 and 92 more): name the base link"
        );
    }

    /// What the fuzz test found, kept: the parser's message quoting a megabyte attribute,
    /// names of a megabyte, and infinite limits a URDF 1.0 file cannot carry back.
    #[test]
    fn messages_stay_short_and_limits_stay_writable() {
        let tip = LinkNames {
            base_link: None,
            tip_link: Some("tool0".into()),
            flange_link: None,
        };
        let refused = |text: &str| {
            let error = robot_from_urdf_str(text, &tip).unwrap_err();
            match std::error::Error::source(&error) {
                Some(source) => format!("{error}: {source}"),
                None => error.to_string(),
            }
        };
        let text = TEST_URDF.replace(
            r#"<origin xyz="0 0 0.3""#,
            &format!(r#"<origin xyz="0 0.3{}""#, "<a>".repeat(300_000)),
        );
        let message = refused(&text);
        assert!(message.ends_with("more characters)"), "{message}");
        assert!(message.len() < 500, "{} bytes", message.len());
        let text = TEST_URDF.replace(
            r#"name="j1""#,
            &format!(r#"name="{}""#, "j".repeat(1_000_000)),
        );
        let text = text.replace(r#"<axis xyz="0 0 1"/>"#, r#"<axis xyz="0 0 0"/>"#);
        let message = refused(&text);
        assert!(message.contains("… (999960 more characters)"), "{message}");
        assert!(message.len() < 200, "{message}");
        // Infinite velocity: not in URDF 1.0 (it could not be written back), in 1.2.
        let text = TEST_URDF.replace(
            r#"<limit lower="-2" upper="2" effort="1" velocity="1"/>"#,
            r#"<limit lower="-2" upper="2" effort="1" velocity="inf"/>"#,
        );
        assert!(
            refused(&text).starts_with("joint 'j2' <limit velocity>: infinite"),
            "{}",
            refused(&text)
        );
        let text = text.replace(
            r#"<robot name="test arm">"#,
            r#"<robot name="test arm" version="1.2">"#,
        );
        let robot = robot_from_urdf_str(&text, &tip).unwrap();
        let written = robot.to_urdf_string(&[]).unwrap();
        assert!(robot_from_urdf_str(
            &written,
            &LinkNames {
                base_link: None,
                tip_link: Some(TCP_LINK.into()),
                flange_link: None,
            }
        )
        .is_ok());
    }

    /// An axis is a direction: a vector whose length overflows or underflows is still one;
    /// only a zero vector is refused.
    #[test]
    fn axes_of_any_finite_length_are_directions() {
        let tip = LinkNames {
            base_link: None,
            tip_link: Some("tool0".into()),
            flange_link: None,
        };
        for axis in ["1e200 0 0", "1e-200 0 0", "1 0 0"] {
            let text = TEST_URDF.replace(
                r#"<axis xyz="1 0 0"/>"#,
                &format!(r#"<axis xyz="{axis}"/>"#),
            );
            let robot = robot_from_urdf_str(&text, &tip).unwrap();
            assert_eq!(robot.chain().joints()[2].axis, [1.0, 0.0, 0.0], "{axis}");
        }
        let text = TEST_URDF.replace(r#"<axis xyz="1 0 0"/>"#, r#"<axis xyz="0 0 0"/>"#);
        let error = robot_from_urdf_str(&text, &tip).unwrap_err();
        assert_eq!(
            error.to_string(),
            "URDF: joint 'slide' has an axis of zero length"
        );
    }

    /// Each shipped robot's URDF and its MD-H robot file are the same robot: the same
    /// forward kinematics (the UR5's file adds its tool) and the same gravity torques from
    /// their masses, although the two put their joint frames in different places.
    #[test]
    fn shipped_urdf_and_mdh_files_are_the_same_robot() {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        for name in ["ur5", "ur10", "iiwa14"] {
            let urdf = Robot::load(shipped_file(name, "robot.urdf")).unwrap();
            let mdh = Robot::load(shipped_file(name, "robot.toml")).unwrap();
            let mdh = mdh
                .with_parts(
                    mdh.name.clone(),
                    mdh.base(),
                    Transform::IDENTITY,
                    mdh.home().to_vec(),
                )
                .unwrap();
            assert_eq!(urdf.joint_count(), mdh.joint_count());
            let (gu, gm) = (urdf.gravity_model().unwrap(), mdh.gravity_model().unwrap());
            assert_eq!(gu.link_mass_kg, gm.link_mass_kg);
            let mut largest: f64 = 0.0;
            for _ in 0..1000 {
                let q = random_q(&urdf, &mut rng);
                let (a, b) = (urdf.tcp_pose(&q), mdh.tcp_pose(&q));
                largest = largest.max((a.translation.vector - b.translation.vector).norm());
                assert!(a.rotation.angle_to(&b.rotation) < 1e-12);
                let tu = urdf.chain().gravity_torques(&q, &gu).unwrap();
                let tm = mdh.chain().gravity_torques(&q, &gm).unwrap();
                for j in 0..q.len() {
                    // kg·mm²/s²: 1e-6 of a N·m.
                    assert!(
                        (tu[j] - tm[j]).abs() < 1e-3,
                        "{name} joint {}: {} vs {}",
                        j + 1,
                        tu[j],
                        tm[j]
                    );
                }
            }
            println!("{name}: URDF and MD-H files agree to {largest:.2e} mm");
            assert!(largest < 1e-9);
        }
    }
}
