//! What a program's numbers may be: every value a target, a frame or a line holds is
//! checked against a bound before any arithmetic, so that an absurd value (`1e308`, a
//! position beyond any cell) is reported where it is written, never iterated on or
//! called corrected.

use adwi_robot::Robot;
use adwi_runtime::chain::JointKind;
use nalgebra::Isometry3;

use crate::number::Number;
use crate::program::{Orientation, TargetKind};
use crate::source::Source;

/// The largest position a target, a tool or a work object may have on any axis, mm: a
/// kilometre, beyond every robot cell, far below where arithmetic loses its digits.
pub const MAX_POSITION_MM: f64 = 1e6;

/// The largest angle a target may write, degrees (a joint, a KUKA A/B/C, a rotation
/// vector's length): four turns, beyond the travel of every robot axis.
pub const MAX_ANGLE_DEG: f64 = 4.0 * 360.0;

/// The largest component of a quaternion: a unit quaternion's are at most 1; a written
/// one may be scaled a little, not by orders of magnitude.
pub const MAX_QUATERNION_COMPONENT: f64 = 2.0;

/// The most joint values a target may carry (as a sample file's `j1..j12`).
pub const MAX_JOINTS: usize = adwi_samples::MAX_JOINTS;

/// The longest line a program may have, bytes: a KRL, RAPID or URScript line, or a CSV
/// row, is a few hundred bytes; a longer one is refused before it is split into tokens
/// (whose list would take some twenty times its length).
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// Why a target's numbers are refused: the number beyond its bound, with its line and
/// column, or `None` when all are within.
///
/// A joint value is bounded as an angle, or as a position when `robot` says the joint is
/// prismatic.
pub fn out_of_range(src: &Source, kind: &TargetKind, robot: Option<&Robot>) -> Option<String> {
    let beyond = |n: &Number, what: &str, value: f64, bound: f64, unit: &str| {
        // NaN is beyond every bound.
        let within = value.abs() <= bound;
        (!within).then(|| {
            let (line, column) = src.location(n.span.0);
            format!(
                "{what} {} at {line}:{column} is beyond ±{bound} {unit}",
                src.text(n.span.0, n.span.1)
            )
        })
    };
    let joint = |i: usize, n: &Number, deg: f64| {
        let prismatic = robot
            .filter(|r| i < r.joint_count())
            .is_some_and(|r| r.joint_kind(i) == JointKind::Prismatic);
        if prismatic {
            beyond(n, "a joint", n.value, MAX_POSITION_MM, "mm")
        } else {
            beyond(n, "a joint", deg, MAX_ANGLE_DEG, "°")
        }
    };
    match kind {
        TargetKind::Cartesian(c) => {
            let scale = c.unit.mm();
            for n in &c.position {
                if let Some(why) = beyond(n, "a position", n.value * scale, MAX_POSITION_MM, "mm") {
                    return Some(why);
                }
            }
            let angles = match &c.orientation {
                None => None,
                Some(Orientation::KukaAbcDeg(abc) | Orientation::XyzIntrinsicDeg(abc)) => abc
                    .iter()
                    .find_map(|n| beyond(n, "an angle", n.value, MAX_ANGLE_DEG, "°")),
                Some(Orientation::QuaternionWxyz(q)) => q.iter().find_map(|n| {
                    beyond(
                        n,
                        "a quaternion component",
                        n.value,
                        MAX_QUATERNION_COMPONENT,
                        "",
                    )
                }),
                Some(Orientation::RotationVectorRad(r)) => r.iter().find_map(|n| {
                    beyond(n, "a rotation", n.value.to_degrees(), MAX_ANGLE_DEG, "°")
                }),
            };
            if angles.is_some() {
                return angles;
            }
            if c.joints.len() > MAX_JOINTS {
                return Some(format!(
                    "{} joint values, more than the {MAX_JOINTS} a robot may have",
                    c.joints.len()
                ));
            }
            c.joints
                .iter()
                .enumerate()
                .find_map(|(i, n)| joint(i, n, n.value))
        }
        TargetKind::Joints(j) => {
            if j.joints.len() > MAX_JOINTS {
                return Some(format!(
                    "{} joint values, more than the {MAX_JOINTS} a robot may have",
                    j.joints.len()
                ));
            }
            j.joints
                .iter()
                .enumerate()
                .find_map(|(i, n)| joint(i, n, (n.value * j.unit.rad()).to_degrees()))
        }
        _ => None,
    }
}

/// Whether a frame (a tool, a work object, an option's) is finite and within
/// [`MAX_POSITION_MM`] of its parent.
pub fn frame_within(frame: &Isometry3<f64>) -> bool {
    frame
        .translation
        .vector
        .iter()
        .all(|v| v.abs() <= MAX_POSITION_MM)
        && frame.rotation.coords.iter().all(|v| v.is_finite())
}

/// Whether an option's frame `X,Y,Z,A,B,C` (mm, degrees) is within the bounds.
pub fn option_frame_within(frame: &[f64; 6]) -> bool {
    frame[..3].iter().all(|v| v.abs() <= MAX_POSITION_MM)
        && frame[3..].iter().all(|v| v.abs() <= MAX_ANGLE_DEG)
}

/// The frame a command-line option writes after its name's `=`: `X,Y,Z` or
/// `X,Y,Z,A,B,C` (mm, degrees; the angles 0 when not written), within the bounds of a
/// frame; the error quotes the values and says `usage`.
///
/// # Errors
///
/// A message saying what is wrong.
pub fn option_frame(values: &str, usage: &str) -> Result<[f64; 6], String> {
    let numbers: Vec<f64> = values
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{values}': {usage}"))?;
    let mut frame = [0.0; 6];
    match numbers.len() {
        3 | 6 => frame[..numbers.len()].copy_from_slice(&numbers),
        _ => return Err(format!("'{values}': {usage}")),
    }
    if !option_frame_within(&frame) {
        return Err(format!(
            "'{values}': within ±{} mm and ±{}°",
            MAX_POSITION_MM, MAX_ANGLE_DEG
        ));
    }
    Ok(frame)
}

/// The first line of `src` longer than [`MAX_LINE_BYTES`]: an error with its line and its
/// length, found by one pass over the bytes before any is split into tokens.
///
/// # Errors
///
/// [`crate::Error::Syntax`] at that line's start.
pub fn check_line_lengths(src: &Source) -> Result<(), crate::Error> {
    let mut start = 0;
    for line in src.bytes.split_inclusive(|b| *b == b'\n' || *b == b'\r') {
        if line.len() > MAX_LINE_BYTES {
            return Err(src.error(
                start,
                format!(
                    "this line is {} bytes long, more than the {MAX_LINE_BYTES} a program's line may have",
                    line.len()
                ),
            ));
        }
        start += line.len();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_option_frame_takes_three_or_six_numbers_within_bounds() {
        let usage = "N=X,Y,Z[,A,B,C]";
        assert_eq!(
            option_frame("1, 2,3", usage),
            Ok([1.0, 2.0, 3.0, 0.0, 0.0, 0.0])
        );
        assert_eq!(
            option_frame("1,2,3,4,5,6", usage),
            Ok([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
        );
        assert_eq!(option_frame("1,2", usage), Err(format!("'1,2': {usage}")));
        assert_eq!(
            option_frame("1,x,3", usage),
            Err(format!("'1,x,3': {usage}"))
        );
        assert!(option_frame("1e9,0,0", usage)
            .unwrap_err()
            .contains("within"));
    }
}
