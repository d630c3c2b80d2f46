//! Every number of a parsed URDF file checked against the plausible ranges
//! ([`crate::plausible`]), named by its element: the whole file is carried into the
//! calibrated URDF, so a number off the chain matters as much as one on it.

use urdf_rs::{Geometry, JointType, Pose};

use crate::error::RobotError;
use crate::plausible::{check, check_all, name as shown, Quantity};

/// Checks every number of `urdf` (module docs).
pub(crate) fn check_numbers(urdf: &urdf_rs::Robot) -> Result<(), RobotError> {
    let version_1_2 = declares_version_1_2(urdf);
    for link in &urdf.links {
        check_link(link)?;
    }
    for joint in &urdf.joints {
        check_joint(joint, version_1_2)?;
    }
    for material in &urdf.materials {
        if let Some(color) = &material.color {
            check_all(&color.rgba.0, Quantity::Finite, || {
                format!("material '{}' <color rgba>", shown(&material.name))
            })?;
        }
    }
    Ok(())
}

/// Whether the file declares URDF 1.2 or later. Before 1.2, effort, velocity and the
/// position limits of revolute and prismatic joints are required numbers: infinite, they
/// could not be written back (the writer leaves infinite values out) nor read again.
fn declares_version_1_2(urdf: &urdf_rs::Robot) -> bool {
    urdf.version
        .as_deref()
        .and_then(|v| {
            let (major, minor) = v.trim().split_once('.')?;
            Some((major.parse::<u32>().ok()?, minor.parse::<u32>().ok()?))
        })
        .is_some_and(|v| v >= (1, 2))
}

/// Refuses an infinite required number in a file before URDF 1.2
/// ([`declares_version_1_2`]).
fn infinite(value: f64, version_1_2: bool, field: &dyn Fn() -> String) -> Result<(), RobotError> {
    if value.is_infinite() && !version_1_2 {
        Err(RobotError::Invalid {
            field: field(),
            reason: "infinite, which URDF before 1.2 does not allow (no limit is written \
                     as a number, or the file declares version=\"1.2\")"
                .into(),
        })
    } else {
        Ok(())
    }
}

/// A link's inertial, and its visual and collision shapes.
fn check_link(link: &urdf_rs::Link) -> Result<(), RobotError> {
    let at = |element: &str| format!("link '{}' {element}", shown(&link.name));
    let inertial = &link.inertial;
    pose(&inertial.origin, || at("<inertial><origin>"))?;
    check(inertial.mass.value, Quantity::MassKg, || {
        at("<inertial><mass value>")
    })?;
    let i = &inertial.inertia;
    check_all(
        &[i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz],
        Quantity::InertiaKgM2,
        || at("<inertial><inertia> (ixx, ixy, ixz, iyy, iyz, izz)"),
    )?;
    for visual in &link.visual {
        if let Some(color) = visual.material.as_ref().and_then(|m| m.color.as_ref()) {
            check_all(&color.rgba.0, Quantity::Finite, || {
                at("<visual><material><color rgba>")
            })?;
        }
    }
    let shapes = link
        .visual
        .iter()
        .map(|v| (&v.origin, &v.geometry, "<visual>"))
        .chain(
            link.collision
                .iter()
                .map(|c| (&c.origin, &c.geometry, "<collision>")),
        );
    for (origin, geometry, element) in shapes {
        pose(origin, || at(&format!("{element}<origin>")))?;
        let field = || at(&format!("{element}<geometry>"));
        match geometry {
            Geometry::Box { size } => check_all(&size.0, Quantity::LengthM, field)?,
            Geometry::Cylinder { radius, length } | Geometry::Capsule { radius, length } => {
                check_all(&[*radius, *length], Quantity::LengthM, field)?
            }
            Geometry::Sphere { radius } => check(*radius, Quantity::LengthM, field)?,
            Geometry::Mesh { scale, .. } => {
                if let Some(scale) = scale {
                    check_all(&scale.0, Quantity::Finite, field)?;
                }
            }
        }
    }
    Ok(())
}

/// A joint's origin, axis, limits, dynamics, calibration, mimic and safety controller.
fn check_joint(joint: &urdf_rs::Joint, version_1_2: bool) -> Result<(), RobotError> {
    let at = |element: &str| format!("joint '{}' {element}", shown(&joint.name));
    pose(&joint.origin, || at("<origin>"))?;
    check_all(&joint.axis.xyz.0, Quantity::Finite, || at("<axis xyz>"))?;
    let limit = &joint.limit;
    // Position limits matter (and have a unit) for the joints the chain models; an
    // infinite one is no limit.
    let position = match joint.joint_type {
        JointType::Revolute | JointType::Continuous => Quantity::JointLimitRad,
        JointType::Prismatic => Quantity::LengthM,
        _ => Quantity::Finite,
    };
    let modelled = matches!(joint.joint_type, JointType::Revolute | JointType::Prismatic);
    for (value, name) in [(limit.lower, "lower"), (limit.upper, "upper")] {
        let field = || at(&format!("<limit {name}>"));
        if value.is_infinite() {
            if modelled {
                infinite(value, version_1_2, &field)?;
            }
        } else {
            check(value, position, field)?;
        }
    }
    for (value, name) in [(limit.effort, "effort"), (limit.velocity, "velocity")] {
        infinite(value, version_1_2, &|| at(&format!("<limit {name}>")))?;
    }
    for (value, name) in [
        (limit.effort, "effort"),
        (limit.velocity, "velocity"),
        (limit.acceleration, "acceleration"),
        (limit.deceleration, "deceleration"),
        (limit.jerk, "jerk"),
    ] {
        check(value, Quantity::NonNegative, || {
            at(&format!("<limit {name}>"))
        })?;
    }
    if let Some(d) = &joint.dynamics {
        check(d.damping, Quantity::NonNegative, || {
            at("<dynamics damping>")
        })?;
        check(d.friction, Quantity::NonNegative, || {
            at("<dynamics friction>")
        })?;
    }
    if let Some(c) = &joint.calibration {
        for (value, name) in [(c.rising, "rising"), (c.falling, "falling")] {
            if let Some(v) = value {
                check(v, Quantity::Finite, || at(&format!("<calibration {name}>")))?;
            }
        }
    }
    if let Some(m) = &joint.mimic {
        for (value, name) in [(m.multiplier, "multiplier"), (m.offset, "offset")] {
            if let Some(v) = value {
                check(v, Quantity::Finite, || at(&format!("<mimic {name}>")))?;
            }
        }
    }
    if let Some(s) = &joint.safety_controller {
        check_all(
            &[
                s.soft_lower_limit,
                s.soft_upper_limit,
                s.k_position,
                s.k_velocity,
            ],
            Quantity::Finite,
            || {
                at("<safety_controller> (soft_lower_limit, soft_upper_limit, k_position, k_velocity)")
            },
        )?;
    }
    Ok(())
}

/// An `<origin>`: `xyz` (m) and `rpy` (rad).
fn pose(pose: &Pose, element: impl Fn() -> String) -> Result<(), RobotError> {
    check_all(&pose.xyz.0, Quantity::LengthM, || {
        format!("{} xyz", element())
    })?;
    check_all(&pose.rpy.0, Quantity::AngleRad, || {
        format!("{} rpy", element())
    })
}
