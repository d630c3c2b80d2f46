//! Fanuc TP programs in their ASCII form (`.ls`), as a teach pendant saves them and as
//! offline tools (ROBOGUIDE) write them.
//!
//! A program has sections: `/PROG name`, `/ATTR`, optionally `/APPL`, then `/MN` (the
//! statements, `   1:J P[1] 100% FINE    ;`, a circular motion's end point on a
//! continuation line `    :  P[4] 500mm/sec FINE    ;`), `/POS` (the positions) and
//! `/END`. The targets are the positions of `/POS`:
//!
//! ```text
//! P[1:"weld start"]{
//!    GP1:
//!     UF : 1, UT : 2,     CONFIG : 'N U T, 0, 0, 0',
//!     X =  1234.567  mm,  Y =  -100.000  mm,  Z =   500.000  mm,
//!     W =   180.000 deg,  P =      .000 deg,  R =   -90.000 deg
//! };
//! ```
//!
//! X, Y, Z in the user frame `UF` (mm), of the TCP of the tool frame `UT`; W, P, R
//! (degrees) rotations about the fixed x, y and z axes: `R = Rz(R)·Ry(P)·Rx(W)`, KUKA's
//! `A, B, C` read as `R, P, W`. A joint position writes `J1 = … deg` to `J6` instead. Each
//! position carries its own frame numbers, which the controller applies when it moves to
//! it; user frame 0 is the world frame (taken as the robot's base frame) and tool frame 0
//! the faceplate (the flange). Numbered frames come from the job's options or a frame file
//! ([`read_frames`]); a position in a frame neither gives is left unchanged, naming the
//! frame. Its `CONFIG` gives the posture: the wrist, elbow and shoulder, and the turn
//! numbers of the three joints the controller's `$SCR_GRP[1].$TURN_AXIS` names
//! ([`TurnAxes`]: J4, J5, J6 unless the job gives others).
//!
//! Every motion statement of `/MN` is accounted for ([`MOTIONS`]): a position moved to by
//! `J`, `L`, `C` (via and end) or `A` is corrected in its frames; a motion with an offset
//! (`Offset`, `Offset,PR[n]`, `Tool_Offset` or the German `WKZ_Offset`, `VOFFSET`, `INC`,
//! a `Touch Offset` region) is reported `relative`, one
//! to a position register (`PR[n]`) or an indirect position `dynamic`, a remote TCP
//! (`RTCP`) `frame_unknown`, a position the program does not hold `not_declared`. A
//! position that moves a second motion group (`GP2`: a positioner, a rail) or an extended
//! axis (`E1`) is `external_axis`; a position not taught (`X = ********`) `incomplete`; one
//! only copied into a register (`PR[7]=P[30]`) `dynamic`. A frame the program sets
//! (`UFRAME[1]=PR[9]`; any frame, for `UFRAME[R[9]]=…`) leaves the positions in it
//! unknown.

use std::collections::HashMap;

use nalgebra::Isometry3;

use crate::frames::kuka_pose;
use crate::number::{parse_number, Number};
use crate::program::{
    AngleUnit, CartesianTarget, ConfigHint, Format, FrameUse, JointTarget, LengthUnit, Orientation,
    Program, ProgramTarget, Reason, Refusal, TargetKind,
};
use crate::source::Source;
use crate::Error;

/// The motion instructions of `/MN`: the letter, how many positions it moves to, and what
/// it is. Every one is corrected when it moves to positions of `/POS` without an offset.
pub const MOTIONS: [(&str, usize, &str); 4] = [
    ("J", 1, "joint motion"),
    ("L", 1, "linear motion"),
    ("C", 2, "circular motion (via, end)"),
    ("A", 1, "circular arc motion"),
];

/// The options of a motion statement that offset its target as the controller runs, and
/// why such a motion is reported rather than corrected.
const OFFSETS: [(&str, Reason, &str); 6] = [
    (
        "OFFSET",
        Reason::Relative,
        "an offset the controller adds to the position as it runs",
    ),
    (
        "TOOL_OFFSET",
        Reason::Relative,
        "an offset in the tool frame the controller adds as it runs",
    ),
    (
        // `Tool_Offset` on a German pendant.
        "WKZ_OFFSET",
        Reason::Relative,
        "an offset in the tool frame the controller adds as it runs",
    ),
    (
        "VOFFSET",
        Reason::Relative,
        "a vision offset the controller adds as it runs",
    ),
    (
        "INC",
        Reason::Relative,
        "an incremental move: the position is added to where the robot stands",
    ),
    (
        "RTCP",
        Reason::FrameUnknown,
        "a remote TCP (a stationary tool), which no option gives",
    ),
];

/// The numbered frames a Fanuc program's positions use, beyond its text.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FanucOptions {
    /// User frames: the number (1 and up) and `[X, Y, Z, W, P, R]` (mm, degrees) in the
    /// world frame, as the controller's `FRAME` menu writes it.
    pub user_frames: Vec<(u16, [f64; 6])>,
    /// Tool frames: the number and `[X, Y, Z, W, P, R]` of the TCP in the faceplate frame.
    pub tool_frames: Vec<(u16, [f64; 6])>,
    /// A controller's frame file (`SYSFRAME.VA`, [`read_frames`]): the frames the options
    /// do not give are taken from it.
    pub frames_file: Option<std::path::PathBuf>,
}

impl FanucOptions {
    fn user(&self, n: u16) -> Option<&[f64; 6]> {
        self.user_frames.iter().find(|f| f.0 == n).map(|f| &f.1)
    }

    fn tool(&self, n: u16) -> Option<&[f64; 6]> {
        self.tool_frames.iter().find(|f| f.0 == n).map(|f| &f.1)
    }
}

/// A pose from Fanuc `X, Y, Z` (mm) and `W, P, R` (degrees): `R = Rz(R)·Ry(P)·Rx(W)`.
pub fn wpr_pose(frame: &[f64; 6]) -> Isometry3<f64> {
    kuka_pose(
        [frame[0], frame[1], frame[2]],
        [frame[5], frame[4], frame[3]],
    )
}

/// Parses a numbered frame as the command line writes it: `N=X,Y,Z` or `N=X,Y,Z,W,P,R`
/// (mm, degrees), N from 1.
///
/// # Errors
///
/// A message saying what is wrong.
pub fn parse_frame(text: &str) -> Result<(u16, [f64; 6]), String> {
    let usage = "a frame is N=X,Y,Z[,W,P,R] (N from 1; mm, degrees)";
    let (name, values) = text.split_once('=').ok_or_else(|| usage.to_string())?;
    let number = name
        .trim()
        .parse::<u16>()
        .ok()
        .filter(|n| *n >= 1)
        .ok_or_else(|| format!("'{}': {usage}", name.trim()))?;
    Ok((number, crate::bounds::option_frame(values, usage)?))
}

pub use crate::program::{TurnAxes, TurnAxesFrom};

/// The most joints a Fanuc motion group has.
const MAX_GROUP_JOINTS: u8 = 9;

impl TurnAxes {
    /// The job's turn axes: `option` (`--fanuc-turn-axes`), else `controller` (a frame
    /// file's `$TURN_AXIS`, and the file's name), else J4, J5, J6.
    ///
    /// # Errors
    ///
    /// When the option and the frame file are both given and disagree, naming both: a
    /// turn number read on the wrong joint solves another posture.
    pub fn of_job(
        option: Option<[u8; 3]>,
        controller: Option<([u8; 3], String)>,
    ) -> Result<TurnAxes, String> {
        match (option, controller) {
            (Some(o), Some((c, file))) if o != c => Err(format!(
                "--fanuc-turn-axes {} and the frame file {file}'s $SCR_GRP[1].$TURN_AXIS {} disagree: give the controller's",
                list(&o, ","),
                list(&c, ",")
            )),
            (Some(joints), _) => Ok(TurnAxes {
                joints,
                from: TurnAxesFrom::Option,
            }),
            (None, Some((joints, _))) => Ok(TurnAxes {
                joints,
                from: TurnAxesFrom::Controller,
            }),
            (None, None) => Ok(TurnAxes::default()),
        }
    }

    /// Checks that the turn axes given are revolute joints of `robot` (the default ones are
    /// taken where the robot has them, as before any was given).
    ///
    /// # Errors
    ///
    /// A message naming the joint and where the axes came from.
    pub fn fit(&self, robot: Option<&adwi_robot::Robot>) -> Result<(), String> {
        let Some(robot) = robot.filter(|_| self.from != TurnAxesFrom::Default) else {
            return Ok(());
        };
        for &j in self.joints.iter().filter(|j| **j != 0) {
            let index = usize::from(j) - 1;
            let why = if index >= robot.joint_count() {
                format!(
                    "J{j} is not a joint of this robot, which has {}",
                    robot.joint_count()
                )
            } else if robot.prismatic_joints() >> index & 1 == 1 {
                format!("J{j} is prismatic, and a turn number counts a revolute joint's turns")
            } else {
                continue;
            };
            return Err(format!("{}: {why}", self.said()));
        }
        Ok(())
    }

    /// The turn axes and where they came from, for messages.
    fn said(&self) -> String {
        let axes = list(&self.joints, ", ");
        match self.from {
            TurnAxesFrom::Default => format!(
                "turn axes {axes}, the default; --fanuc-turn-axes or the controller's $TURN_AXIS gives others"
            ),
            TurnAxesFrom::Option => format!("turn axes {axes}, --fanuc-turn-axes"),
            TurnAxesFrom::Controller => format!(
                "turn axes {axes}, the controller's $SCR_GRP[1].$TURN_AXIS (--fanuc-frames)"
            ),
        }
    }
}

/// Joint numbers as a list, `sep` between them.
fn list(joints: &[u8; 3], sep: &str) -> String {
    joints.map(|j| j.to_string()).join(sep)
}

/// Checks turn axes as the options give them: three distinct joint numbers from 1.
///
/// # Errors
///
/// A message saying what is wrong.
pub fn check_turn_axes(joints: &[u8; 3]) -> Result<(), String> {
    let distinct = joints[0] != joints[1] && joints[0] != joints[2] && joints[1] != joints[2];
    if distinct && joints.iter().all(|j| (1..=MAX_GROUP_JOINTS).contains(j)) {
        Ok(())
    } else {
        Err(format!(
            "turn axes {}: three distinct joint numbers from 1 to {MAX_GROUP_JOINTS} (1 for J1), as the controller's $SCR_GRP[1].$TURN_AXIS gives them (1,4,6 on an R-2000iB)",
            list(joints, ",")
        ))
    }
}

/// Parses turn axes as the command line writes them: `J,J,J` (`1,4,6`).
///
/// # Errors
///
/// A message saying what is wrong.
pub fn parse_turn_axes(text: &str) -> Result<[u8; 3], String> {
    let numbers: Vec<u8> = text
        .split(',')
        .map(|t| t.trim().parse::<u8>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{text}': turn axes are J,J,J (three joint numbers, 1 for J1)"))?;
    let joints: [u8; 3] = numbers
        .try_into()
        .map_err(|_| format!("'{text}': turn axes are J,J,J (three joint numbers, 1 for J1)"))?;
    check_turn_axes(&joints)?;
    Ok(joints)
}

/// The turn each joint of a robot of `joints` joints must keep, by the three turn
/// numbers `turns` of `axes`' joints.
pub(crate) fn joint_turns(
    turns: &[Option<i8>; 3],
    axes: &TurnAxes,
    joints: usize,
) -> Vec<crate::correct::Turn> {
    (0..joints)
        .map(|i| {
            axes.joints
                .iter()
                .position(|j| usize::from(*j) == i + 1)
                .and_then(|place| turns[place])
                .map_or(crate::correct::Turn::Any, |k| {
                    crate::correct::Turn::Revolution(i64::from(k))
                })
        })
        .collect()
}

/// Why a Fanuc CONFIG's turn number cannot be kept on `robot`: its joint's limits hold no
/// angle of that turn, or it is written where the turn axes give no joint. The turn axes
/// are named: read on another joint than the controller's, a turn number asks a posture
/// the program never meant. `None` for any other configuration.
pub(crate) fn unheld_turn(
    hint: &crate::program::ConfigHint,
    robot: &adwi_robot::Robot,
) -> Option<String> {
    let ConfigHint::FanucConfig {
        turns, turn_axes, ..
    } = *hint
    else {
        return None;
    };
    let places = ["first", "second", "third"];
    for ((turn, &joint), place) in turns.iter().zip(&turn_axes.joints).zip(places) {
        let Some(k) = *turn else { continue };
        if joint == 0 {
            if k != 0 {
                return Some(format!(
                    "turn number {k}, the {place}, is of no joint ({})",
                    turn_axes.said()
                ));
            }
            continue;
        }
        // Joints the robot has not, or prismatic: taken as before for the default axes
        // (the ones given were checked against the robot).
        let index = usize::from(joint) - 1;
        if index >= robot.joint_count() || robot.prismatic_joints() >> index & 1 == 1 {
            continue;
        }
        // Degrees as a robot file writes them, not 124.99999999999999.
        let [lower, upper] = robot.joints()[index]
            .limits
            .map(|r| (r.to_degrees() * 1e6).round() / 1e6);
        let (from, to) = (-180.0 + 360.0 * f64::from(k), 180.0 + 360.0 * f64::from(k));
        if to < lower || from >= upper {
            return Some(format!(
                "turn number {k} of J{joint} ({}): J{joint} in ({from}°, {to}°], beyond its limits [{lower}°, {upper}°]",
                turn_axes.said()
            ));
        }
    }
    None
}

/// Reads a controller's frame file: the ASCII dump of its system variables
/// `$MNUFRAME` (user frames) and `$MNUTOOL` (tool frames), as `SYSFRAME.VA` holds them:
///
/// ```text
/// [*SYSTEM*]$MNUFRAME  Storage: SHADOW  Access: RW  : ARRAY[1,9] OF POSITION
///     [1,1] =
///   Group: 1   Config: N D B, 0, 0, 0
///   X:  1500.000   Y:   200.000   Z:  -300.000
///   W:     0.000   P:     0.000   R:    30.000
///     [1,2] = Uninitialized
/// ```
///
/// Group 1's frames are read (`[1,n]`, frame n); an uninitialized one is not given.
/// Every other variable of the file is skipped.
///
/// # Errors
///
/// [`Error::Syntax`] at a frame whose six numbers do not read, or beyond the bounds.
pub fn read_frames(src: &Source) -> Result<FanucOptions, Error> {
    let bytes = src.bytes;
    let mut out = FanucOptions::default();
    // The variable being read: user frames (true), tool frames (false), or another.
    let mut variable: Option<bool> = None;
    let mut start = 0;
    while start < bytes.len() {
        let (end, next) = src.line_at(start);
        let line = (start, end);
        start = next;
        let at = skip_space(bytes, line.0, line.1);
        let text = &bytes[at..line.1];
        if text.starts_with(b"[") && !text.starts_with(b"[1,") && !text.starts_with(b"[2,") {
            variable = frame_variable(text);
            continue;
        }
        let Some(user) = variable else { continue };
        // An element: `[g,n] =` and, unless uninitialized, its lines.
        let Some(close) = text.iter().position(|b| *b == b']') else {
            continue;
        };
        if !text.starts_with(b"[") {
            continue;
        }
        let index = String::from_utf8_lossy(&text[1..close]).into_owned();
        let Some((group, number)) = index.split_once(',') else {
            continue;
        };
        let (Ok(group), Ok(number)) = (group.trim().parse::<u16>(), number.trim().parse::<u16>())
        else {
            return Err(src.error(at, format!("[{index}]: expected [group,frame]")));
        };
        if text
            .windows(13)
            .any(|w| w.eq_ignore_ascii_case(b"uninitialized"))
        {
            continue;
        }
        let (values, scan) = frame_values(src, start)?;
        start = scan;
        if group != 1 {
            continue;
        }
        let frame = match values {
            [Some(x), Some(y), Some(z), Some(w), Some(p), Some(r)] => [x, y, z, w, p, r],
            _ => {
                return Err(src.error(
                    at,
                    format!("[{index}]: a frame needs all six of X, Y, Z, W, P, R"),
                ))
            }
        };
        if !crate::bounds::option_frame_within(&frame) {
            return Err(src.error(
                at,
                format!(
                    "[{index}]: a frame within ±{} mm and ±{}°",
                    crate::bounds::MAX_POSITION_MM,
                    crate::bounds::MAX_ANGLE_DEG
                ),
            ));
        }
        let list = if user {
            &mut out.user_frames
        } else {
            &mut out.tool_frames
        };
        if list.iter().any(|f| f.0 == number) {
            return Err(src.error(at, format!("[{index}]: frame {number} given twice")));
        }
        list.push((number, frame));
    }
    Ok(out)
}

/// Reads the turn axes of motion group 1 from a controller's system variables, as its
/// `SYMOTN.VA` holds them:
///
/// ```text
///      Field: $SCR_GRP[1].$TURN_AXIS  ARRAY[3] OF INTEGER
///       [1] = 1
///       [2] = 4
///       [3] = 6
/// ```
///
/// `None` when the file does not hold the variable (a `SYSFRAME.VA`).
///
/// # Errors
///
/// [`Error::Syntax`] at the variable when its three joint numbers do not read as the
/// controller's (0 to 9, 0 for none, the others distinct), or when it is given twice.
pub fn read_turn_axes(src: &Source) -> Result<Option<[u8; 3]>, Error> {
    const NAME: &[u8] = b"$SCR_GRP[1].$TURN_AXIS";
    let bytes = src.bytes;
    let mut found: Option<(usize, [u8; 3])> = None;
    let mut start = 0;
    while start < bytes.len() {
        let (end, next) = src.line_at(start);
        let at = skip_space(bytes, start, end);
        start = next;
        let text = &bytes[at..end];
        let field = text
            .get(..6)
            .is_some_and(|t| t.eq_ignore_ascii_case(b"Field:"));
        let name_at = if field {
            skip_space(bytes, at + 6, end)
        } else {
            at
        };
        let name_end = (name_at..end)
            .find(|i| bytes[*i].is_ascii_whitespace())
            .unwrap_or(end);
        if !bytes[name_at..name_end].eq_ignore_ascii_case(NAME) {
            continue;
        }
        if let Some((first, _)) = found {
            let (line, _) = src.location(first);
            return Err(src.error(
                name_at,
                format!("$SCR_GRP[1].$TURN_AXIS twice (first at line {line})"),
            ));
        }
        let usage = "$SCR_GRP[1].$TURN_AXIS: expected its [1], [2] and [3], each a joint number from 0 to 9 (0 for none), the joints distinct";
        // Its elements, `[i] = j`, on the lines that follow.
        let mut joints: [Option<u8>; 3] = [None; 3];
        while start < bytes.len() {
            let (end, next) = src.line_at(start);
            let at = skip_space(bytes, start, end);
            let line = String::from_utf8_lossy(&bytes[at..end]);
            let Some((index, value)) = line
                .strip_prefix('[')
                .and_then(|l| l.split_once(']'))
                .and_then(|(i, v)| Some((i.trim(), v.trim().strip_prefix('=')?.trim())))
            else {
                break;
            };
            start = next;
            let place = index
                .parse::<usize>()
                .ok()
                .and_then(|i| i.checked_sub(1))
                .filter(|i| *i < 3);
            let joint = value.parse::<u8>().ok().filter(|j| *j <= MAX_GROUP_JOINTS);
            match (place, joint) {
                (Some(place), Some(joint)) if joints[place].is_none() => {
                    joints[place] = Some(joint);
                }
                _ => return Err(src.error(at, usage)),
            }
        }
        let [Some(a), Some(b), Some(c)] = joints else {
            return Err(src.error(name_at, usage));
        };
        if (a != 0 && (a == b || a == c)) || (b != 0 && b == c) {
            return Err(src.error(name_at, usage));
        }
        found = Some((name_at, [a, b, c]));
    }
    Ok(found.map(|f| f.1))
}

/// Which frames a variable's header names (`[*SYSTEM*]$MNUFRAME  Storage: …`): user
/// frames (true), tool frames (false), or neither.
fn frame_variable(text: &[u8]) -> Option<bool> {
    let name_end = text
        .iter()
        .position(|b| b.is_ascii_whitespace())
        .unwrap_or(text.len());
    let name = text[..name_end].to_ascii_uppercase();
    if name.ends_with(b"$MNUFRAME") {
        Some(true)
    } else if name.ends_with(b"$MNUTOOL") {
        Some(false)
    } else {
        None
    }
}

/// X, Y, Z, W, P, R of a frame element, as `X:  1500.000` pairs on the lines from `start`
/// up to the next element or variable; and where that one starts.
fn frame_values(src: &Source, start: usize) -> Result<([Option<f64>; 6], usize), Error> {
    let bytes = src.bytes;
    let mut values: [Option<f64>; 6] = [None; 6];
    let mut scan = start;
    while scan < bytes.len() {
        let (end, n) = src.line_at(scan);
        let l = (scan, end);
        let first = skip_space(bytes, l.0, l.1);
        if bytes.get(first) == Some(&b'[') {
            break;
        }
        let mut i = first;
        while i < l.1 {
            let b = bytes[i].to_ascii_uppercase();
            let axis = b"XYZWPR".iter().position(|a| *a == b);
            let colon = skip_blanks(bytes, i + 1, l.1);
            let word_start = i == l.0 || !bytes[i - 1].is_ascii_alphanumeric();
            match axis {
                Some(k) if word_start && bytes.get(colon) == Some(&b':') => {
                    let v = skip_blanks(bytes, colon + 1, l.1);
                    let number = parse_number(&bytes[..l.1], v)
                        .ok_or_else(|| src.error(v, format!("{}: expected a number", b as char)))?;
                    values[k] = Some(number.value);
                    i = number.span.1;
                }
                _ => i += 1,
            }
        }
        scan = n;
    }
    Ok((values, scan))
}

fn skip_space(bytes: &[u8], mut i: usize, end: usize) -> usize {
    while i < end && bytes[i].is_ascii_whitespace() {
        i += 1;
    }
    i
}

fn skip_blanks(bytes: &[u8], mut i: usize, end: usize) -> usize {
    while i < end && matches!(bytes[i], b' ' | b'\t') {
        i += 1;
    }
    i
}

/// A position designator of a statement: `P[3]`, `P[3:label]`, `PR[2]`, `PR[R[1]]`.
#[derive(Clone, Debug)]
struct Designator {
    /// Where `P` or `PR` starts.
    at: usize,
    /// Past its `]`.
    end: usize,
    /// A position register rather than a position.
    register: bool,
    /// Its number, when written directly (`None`: indirect, `P[R[1]]`).
    number: Option<u32>,
    /// An option's argument (`Offset,PR[1]`), not a target.
    argument: bool,
}

/// A word at bracket depth 0 of a statement.
#[derive(Clone, Copy, Debug)]
struct StatementWord {
    start: usize,
    end: usize,
}

/// A statement of `/MN`, over its line and continuation lines: its text's ranges up to its
/// `;`.
struct Statement {
    ranges: Vec<(usize, usize)>,
}

impl Statement {
    /// Its words and designators at bracket depth 0.
    fn scan(&self, src: &Source) -> Result<(Vec<StatementWord>, Vec<Designator>), Error> {
        let bytes = src.bytes;
        let mut words = Vec::new();
        let mut designators = Vec::new();
        // The last non-blank byte seen before a word, across ranges.
        let mut before: u8 = b' ';
        for &(start, end) in &self.ranges {
            let mut i = start;
            while i < end {
                let b = bytes[i];
                if b.is_ascii_alphabetic() || b == b'_' || b == b'$' {
                    let w = src.identifier_end(i, b"$").min(end).max(i + 1);
                    let word = &bytes[i..w];
                    if bytes.get(w) == Some(&b'[') && w < end {
                        let close = matching_bracket(bytes, w, end)
                            .ok_or_else(|| src.error(w, "a '[' without its ']'"))?;
                        if word.eq_ignore_ascii_case(b"P") || word.eq_ignore_ascii_case(b"PR") {
                            let inside = &bytes[w + 1..close];
                            let digits = inside.iter().take_while(|b| b.is_ascii_digit()).count();
                            let direct = digits > 0
                                && matches!(inside.get(digits), None | Some(b':'))
                                && digits <= 9;
                            let number = direct
                                .then(|| std::str::from_utf8(&inside[..digits]).ok())
                                .flatten()
                                .and_then(|t| t.parse().ok());
                            designators.push(Designator {
                                at: i,
                                end: close + 1,
                                register: word.len() == 2,
                                number,
                                argument: before == b',',
                            });
                        } else {
                            words.push(StatementWord { start: i, end: w });
                        }
                        before = b']';
                        i = close + 1;
                        continue;
                    }
                    words.push(StatementWord { start: i, end: w });
                    before = bytes[w - 1];
                    i = w;
                    continue;
                }
                if b == b'[' {
                    let close = matching_bracket(bytes, i, end)
                        .ok_or_else(|| src.error(i, "a '[' without its ']'"))?;
                    i = close + 1;
                    before = b']';
                    continue;
                }
                if !matches!(b, b' ' | b'\t') {
                    before = b;
                }
                i += 1;
            }
        }
        Ok((words, designators))
    }
}

/// The `]` closing the `[` at `open`, before `end`.
fn matching_bracket(bytes: &[u8], open: usize, end: usize) -> Option<usize> {
    let mut depth = 0usize;
    for (k, b) in bytes[open..end].iter().enumerate() {
        match b {
            b'[' => depth += 1,
            b']' => {
                depth -= 1;
                if depth == 0 {
                    return Some(open + k);
                }
            }
            _ => {}
        }
    }
    None
}

/// The statements of the `/MN` section `start..end`, and where each line of it starts.
fn statements(src: &Source, start: usize, end: usize) -> Vec<Statement> {
    let bytes = src.bytes;
    let mut out: Vec<Statement> = Vec::new();
    // Whether the last statement is still open (no `;` yet).
    let mut open = false;
    let mut at = start;
    while at < end {
        let s = at;
        let (e, next) = src.line_at(at);
        at = next;
        let e = e.min(end);
        let first = skip_blanks(bytes, s, e);
        let digits = bytes[first..e]
            .iter()
            .take_while(|b| b.is_ascii_digit())
            .count();
        let content = if digits > 0 && bytes.get(first + digits) == Some(&b':') {
            open = true;
            out.push(Statement { ranges: Vec::new() });
            first + digits + 1
        } else if bytes.get(first) == Some(&b':') && open {
            first + 1
        } else {
            // Not a statement's line (a `------ ;` closing a time-before block).
            continue;
        };
        let semicolon = bytes[content..e].iter().position(|b| *b == b';');
        let stop = semicolon.map_or(e, |p| content + p);
        if let Some(last) = out.last_mut() {
            last.ranges.push((content, stop));
        }
        if semicolon.is_some() {
            open = false;
        }
    }
    out
}

/// What a `/MN` motion does to a position.
#[derive(Clone, Debug)]
struct Use {
    /// Where the motion is written.
    at: usize,
    /// The motion's words (`L P[5]`), for messages.
    motion: String,
    /// Why it is reported rather than corrected, when it is.
    refused: Option<(Reason, String)>,
}

/// Reads the targets of a Fanuc `.ls` program.
///
/// # Errors
///
/// [`Error::Syntax`] at the first malformed position or statement.
pub fn read(src: &Source, options: &FanucOptions) -> Result<Program, Error> {
    read_at_most(src, options, TurnAxes::default(), usize::MAX)
}

/// [`read`], the CONFIGs' turn numbers of `turn_axes`' joints, stopping after `limit`
/// targets ([`Program::truncated_at`]).
///
/// # Errors
///
/// As [`read`].
pub fn read_at_most(
    src: &Source,
    options: &FanucOptions,
    turn_axes: TurnAxes,
    limit: usize,
) -> Result<Program, Error> {
    let sections = Sections::of(src)?;
    let mut motions = Motions::default();
    if let Some((s, e)) = sections.mn {
        for statement in statements(src, s, e) {
            motions.statement(src, &statement, limit)?;
            if motions.truncated_at.is_some() {
                break;
            }
        }
    }
    let mut positions: Vec<(u32, ProgramTarget)> = Vec::new();
    if let (Some((s, e)), None) = (sections.pos, motions.truncated_at) {
        let frames = FrameFields {
            src,
            options,
            set_frames: &motions.set_frames,
            turn_axes,
        };
        motions.truncated_at =
            read_positions(src, (s, e), &frames, &motions, limit, &mut positions)?;
    }
    Ok(motions.program(src, positions))
}

/// The sections of a program the reader reads: `/MN` and `/POS`, each's byte range.
struct Sections {
    mn: Option<(usize, usize)>,
    pos: Option<(usize, usize)>,
}

impl Sections {
    /// The sections of `src`; a second `/MN` or `/POS` is an error.
    fn of(src: &Source) -> Result<Sections, Error> {
        let bytes = src.bytes;
        let mut sections = Sections {
            mn: None,
            pos: None,
        };
        let mut current: Option<(&str, usize)> = None;
        let mut at = 0;
        loop {
            let done = at >= bytes.len();
            let (s, (e, next)) = if done {
                (bytes.len(), (bytes.len(), bytes.len()))
            } else {
                (at, src.line_at(at))
            };
            at = next;
            let first = skip_blanks(bytes, s, e);
            let header = bytes.get(first) == Some(&b'/')
                && bytes.get(first + 1).is_some_and(u8::is_ascii_uppercase);
            if header || done {
                match current.take() {
                    Some(("MN", start)) => sections.mn = Some((start, s)),
                    Some(("POS", start)) => sections.pos = Some((start, s)),
                    _ => {}
                }
            }
            if done {
                return Ok(sections);
            }
            if header {
                let word_end = src.identifier_end(first + 1, b"").min(e);
                let name = match &bytes[first + 1..word_end] {
                    b"MN" => "MN",
                    b"POS" => "POS",
                    _ => "",
                };
                if (name == "MN" && sections.mn.is_some())
                    || (name == "POS" && sections.pos.is_some())
                {
                    return Err(src.error(first, format!("a second /{name} section")));
                }
                current = Some((name, next.min(bytes.len())));
            }
        }
    }
}

/// Frames a program sets as it runs, by kind (a user frame, true, or a tool) and number
/// (`None`: chosen as it runs, `UFRAME[R[9]]`): the first statement that sets each.
type SetFrames = HashMap<(bool, Option<u16>), usize>;

/// What the `/MN` section says: the motions reported, the uses of each position, and the
/// frames the program sets as it runs.
#[derive(Default)]
struct Motions {
    targets: Vec<ProgramTarget>,
    first_motion: Option<usize>,
    truncated_at: Option<usize>,
    /// Per position number, the motions that use it.
    uses: HashMap<u32, Vec<Use>>,
    /// Frames the program sets as it runs: (user, number) and the statement's place; the
    /// number `None` when the program chooses it as it runs (`UFRAME[R[9]]=PR[71]`).
    set_frames: SetFrames,
    /// Motions to positions `/POS` may not hold, checked once it is read.
    pending: Vec<(u32, Use)>,
    /// The `Touch Offset PR[n]` region in force: the statement and its place.
    touch_offset: Option<(String, usize)>,
}

impl Motions {
    /// Reads a statement of `/MN`: a frame set, a motion, or neither.
    fn statement(
        &mut self,
        src: &Source,
        statement: &Statement,
        limit: usize,
    ) -> Result<(), Error> {
        let bytes = src.bytes;
        let Some(&(first_start, first_end)) = statement.ranges.first() else {
            return Ok(());
        };
        let at = skip_blanks(bytes, first_start, first_end);
        if at >= first_end || bytes[at] == b'!' || bytes[at..first_end].starts_with(b"//") {
            // An empty line, a comment, a statement commented out.
            return Ok(());
        }
        let (words, designators) = statement.scan(src)?;
        let starts_with_word = words.first().is_some_and(|w| w.start == at);
        if !starts_with_word {
            // An assignment (`PR[7]=P[30]`): a position it names is used, as the program
            // runs, through what it is assigned to.
            self.values_used(src, at, statement, &designators);
            return Ok(());
        }
        let Some(first) = words.first() else {
            return Ok(());
        };
        let word = &bytes[first.start..first.end];
        // `UFRAME[2]=PR[1]`, `UTOOL[1]=…`: a frame set as the program runs (the German
        // pendant's `BENUTZER[…]` and `WKZ[…]`, as its `BENUTZER_NUM` and `WKZ_NUM`); an
        // index computed as it runs (`UFRAME[R[9]]`, `UTOOL[AR[1]]`) may be any frame.
        let user_frame =
            word.eq_ignore_ascii_case(b"UFRAME") || word.eq_ignore_ascii_case(b"BENUTZER");
        if user_frame || word.eq_ignore_ascii_case(b"UTOOL") || word.eq_ignore_ascii_case(b"WKZ") {
            let open = first.end;
            if bytes.get(open) == Some(&b'[') {
                let digits_end = (open + 1..first_end)
                    .find(|i| !bytes[*i].is_ascii_digit())
                    .unwrap_or(first_end);
                let direct = matches!(bytes.get(digits_end), Some(b']' | b':'));
                let number = src.text(open + 1, digits_end).parse::<u16>().ok();
                self.set_frames
                    .entry((user_frame, number.filter(|_| direct)))
                    .or_insert(at);
            }
            return Ok(());
        }
        // `Touch Offset PR[10]` … `Touch Offset End`: the motions between are offset by
        // what touch sensing found.
        if word.eq_ignore_ascii_case(b"TOUCH")
            && words
                .get(1)
                .is_some_and(|w| bytes[w.start..w.end].eq_ignore_ascii_case(b"OFFSET"))
        {
            let end = words
                .get(2)
                .is_some_and(|w| bytes[w.start..w.end].eq_ignore_ascii_case(b"END"));
            self.touch_offset = if end {
                None
            } else {
                let last = statement.ranges.last().map_or(first_end, |r| r.1);
                let text = src.text(at, at + bytes[at..last.max(at)].trim_ascii_end().len());
                Some((text, at))
            };
            return Ok(());
        }
        let letter = word.len() == 1 && word[0].is_ascii_uppercase();
        let target = designators.first().filter(|d| !d.argument);
        // A motion: one letter, a blank, and the position (`L P[2]`), never an
        // assignment such as `R[1]=PR[1,3]`.
        let motion = target.is_some_and(|d| {
            letter
                && first.start == at
                && d.at > first.end
                && bytes[first.end..d.at]
                    .iter()
                    .all(|b| matches!(b, b' ' | b'\t'))
        });
        if motion {
            self.motion(src, at, &words, &designators, limit);
        }
        Ok(())
    }

    /// The positions an assignment at `at` names (`PR[7]=P[30]`): used as the program runs
    /// through the register (or whatever it assigns), not moved to as written.
    fn values_used(
        &mut self,
        src: &Source,
        at: usize,
        statement: &Statement,
        designators: &[Designator],
    ) {
        let last = statement.ranges.last().map_or(at, |r| r.1);
        let text = src.text(at, at + src.bytes[at..last.max(at)].trim_ascii_end().len());
        for d in designators.iter().filter(|d| !d.register && d.at > at) {
            if let Some(n) = d.number {
                self.uses.entry(n).or_default().push(Use {
                    at,
                    motion: text.clone(),
                    refused: Some((
                        Reason::Dynamic,
                        "the position is copied as the program runs, and moved to through what it is copied into (a position register the program may change), not as written".to_string(),
                    )),
                });
            }
        }
    }

    /// A motion at `at` (its words and designators): each position it moves to, used or
    /// reported.
    fn motion(
        &mut self,
        src: &Source,
        at: usize,
        words: &[StatementWord],
        designators: &[Designator],
        limit: usize,
    ) {
        self.first_motion.get_or_insert(at);
        let word = &src.bytes[words[0].start..words[0].end];
        let letter = word[0] as char;
        let moves: Vec<&Designator> = designators.iter().filter(|d| !d.argument).collect();
        let motion_text = |d: &Designator| format!("{letter} {}", src.text(d.at, d.end));
        let known = MOTIONS.iter().find(|m| m.0.as_bytes() == word);
        let count = known.map_or(1, |m| m.1);
        if moves.len() < count {
            let d = moves[0];
            self.targets.push(ProgramTarget {
                name: motion_text(d),
                offset: at,
                kind: TargetKind::Incomplete(format!(
                    "{letter}: a circular motion needs its via and its end point, and writes {}",
                    moves.len()
                )),
                uses: Vec::new(),
                refused: None,
            });
            return;
        }
        let offset = motion_offset(src, words, designators).or_else(|| {
            self.touch_offset.as_ref().map(|(text, place)| {
                let (line, column) = src.location(*place);
                (
                    Reason::Relative,
                    format!("inside {text} ({line}:{column}): the offset touch sensing finds, which the controller adds as it runs"),
                )
            })
        });
        for d in moves.iter().take(count) {
            let u = Use {
                at: d.at,
                motion: motion_text(d),
                refused: if known.is_none() {
                    Some((
                        Reason::UnknownMotion,
                        format!("{letter} is not a Fanuc motion this reader knows"),
                    ))
                } else {
                    position_refusal(d).or_else(|| offset.clone())
                },
            };
            self.use_position(d, u);
            if self.targets.len() > limit {
                self.truncated_at = Some(d.at);
                return;
            }
        }
    }

    /// A motion's use `u` of the position `d`: reported when refused (and kept among the
    /// position's uses), else waiting for `/POS`.
    fn use_position(&mut self, d: &Designator, u: Use) {
        match (u.refused.clone(), d.number) {
            (Some((reason, why)), number) => {
                self.targets.push(ProgramTarget {
                    name: u.motion.clone(),
                    offset: d.at,
                    kind: TargetKind::Motion,
                    uses: Vec::new(),
                    refused: Some(Refusal::new(reason, why)),
                });
                if let (Some(n), false) = (number, d.register) {
                    self.uses.entry(n).or_default().push(u);
                }
            }
            (None, Some(n)) => self.pending.push((n, u)),
            (None, None) => {}
        }
    }

    /// The program: the positions with their uses, and the motions reported.
    fn program(mut self, src: &Source, positions: Vec<(u32, ProgramTarget)>) -> Program {
        // Motions to positions: each position's uses, or the motion said not declared.
        for (n, u) in std::mem::take(&mut self.pending) {
            if positions.iter().any(|p| p.0 == n) {
                self.uses.entry(n).or_default().push(u);
            } else {
                self.targets.push(ProgramTarget {
                    name: u.motion.clone(),
                    offset: u.at,
                    kind: TargetKind::Motion,
                    uses: Vec::new(),
                    refused: Some(Refusal::new(
                        Reason::NotDeclared,
                        format!("P[{n}] is not in the program's /POS section"),
                    )),
                });
            }
        }
        for (n, mut target) in positions {
            let list = self.uses.remove(&n).unwrap_or_default();
            let plain = list.iter().find(|u| u.refused.is_none());
            match (plain, list.first()) {
                (Some(u), _) => {
                    if let Some(first) = target.uses.first_mut() {
                        first.offset = u.at;
                    }
                }
                (None, Some(u)) if target.refused.is_none() => {
                    let (reason, why) = u.refused.clone().expect("a refused use");
                    let (line, column) = src.location(u.at);
                    target.refused = Some(Refusal::new(
                        reason,
                        format!("used only by {} ({line}:{column}): {why}", u.motion),
                    ));
                }
                _ => {}
            }
            self.targets.push(target);
        }
        self.targets.sort_by_key(|t| t.offset);
        Program {
            format: Format::Fanuc,
            targets: self.targets,
            truncated_at: self.truncated_at,
            first_motion: self.first_motion,
            in_partner: Vec::new(),
        }
    }
}

/// Why a known motion's position `d` is not corrected, by the position itself: a
/// register, or a number chosen as the program runs.
fn position_refusal(d: &Designator) -> Option<(Reason, String)> {
    if d.register {
        return Some((
            Reason::Dynamic,
            "a position register, whose value the controller holds or the program sets as it runs"
                .to_string(),
        ));
    }
    if d.number.is_none() {
        return Some((
            Reason::Dynamic,
            "a position chosen as the program runs".to_string(),
        ));
    }
    None
}

/// The motion's offset, found among its words (`Offset,PR[1]`, `Tool_Offset`, `INC`…),
/// with its argument when it has one.
fn motion_offset(
    src: &Source,
    words: &[StatementWord],
    designators: &[Designator],
) -> Option<(Reason, String)> {
    words.iter().skip(1).find_map(|w| {
        let text = src.bytes[w.start..w.end].to_ascii_uppercase();
        // Any other option named an offset (another pendant language's `Tool_Offset`).
        let other = (text.ends_with(b"_OFFSET") || text.ends_with(b"OFFSET")).then_some((
            "",
            Reason::Relative,
            "an offset option: an offset the controller adds as it runs",
        ));
        let known = OFFSETS.iter().find(|o| o.0.as_bytes() == text).copied();
        known.or(other).map(|o| {
            let argument = designators
                .iter()
                .find(|d| d.argument && d.at > w.end && d.at <= w.end + 2);
            let end = argument.map_or(w.end, |d| d.end);
            (o.1, format!("{}: {}", src.text(w.start, end), o.2))
        })
    })
}

/// Reads the positions of `/POS` (`s..e`) into `positions`; where reading stopped, when
/// the targets reach `limit`.
fn read_positions(
    src: &Source,
    (s, e): (usize, usize),
    frames: &FrameFields,
    motions: &Motions,
    limit: usize,
    positions: &mut Vec<(u32, ProgramTarget)>,
) -> Result<Option<usize>, Error> {
    let bytes = src.bytes;
    let mut i = s;
    while i < e {
        i = skip_space(bytes, i, e);
        if i >= e {
            break;
        }
        if !(bytes[i..e].starts_with(b"P[")) {
            return Err(src.error(
                i,
                format!("expected a position P[n]{{…}}; found {}", src.describe(i)),
            ));
        }
        let (n, target, next) = position(src, i, e, frames)?;
        if let Some(first) = positions.iter().find(|p| p.0 == n) {
            let (line, _) = src.location(first.1.offset);
            return Err(src.error(i, format!("P[{n}] twice (first at line {line})")));
        }
        positions.push((n, target));
        i = next;
        if motions.targets.len() + positions.len() > limit {
            return Ok(Some(i.min(bytes.len())));
        }
    }
    Ok(None)
}

/// A field of a position: its name (upper case), where, and its value.
struct Field {
    name: String,
    value: FieldValue,
}

enum FieldValue {
    /// `UF : 1`: a word.
    Word(String),
    /// `CONFIG : 'N U T, 0, 0, 0'`: the text between the quotes.
    Text(usize, usize),
    /// `X =  1234.567  mm`.
    Number(Number),
    /// `X = ********  mm`: not taught; where the stars start.
    Untaught(usize),
}

/// A position's fields, by group: the group's number, where it is written, its fields.
type Group = (u32, usize, Vec<Field>);

/// The position `P[n]{ … };` at `at`: its number, its target and where the next starts.
fn position(
    src: &Source,
    at: usize,
    end: usize,
    frames: &FrameFields,
) -> Result<(u32, ProgramTarget, usize), Error> {
    let (number, brace, body_end) = position_head(src, at, end)?;
    let mut next = body_end + 1;
    if src.bytes.get(next) == Some(&b';') {
        next += 1;
    }
    let name = format!("P[{number}]");
    let groups = groups(src, &name, brace + 1, body_end)?;
    Ok((number, frames.target(name, at, &groups), next))
}

/// A position's number, its `{` and its `}`.
fn position_head(src: &Source, at: usize, end: usize) -> Result<(u32, usize, usize), Error> {
    let bytes = src.bytes;
    let open = at + 1;
    let close = matching_bracket(bytes, open, end)
        .ok_or_else(|| src.error(open, "a '[' without its ']'"))?;
    let inside = &bytes[open + 1..close];
    let digits = inside.iter().take_while(|b| b.is_ascii_digit()).count();
    let number: u32 = std::str::from_utf8(&inside[..digits])
        .ok()
        .filter(|_| digits > 0 && digits <= 9 && matches!(inside.get(digits), None | Some(b':')))
        .and_then(|t| t.parse().ok())
        .ok_or_else(|| src.error(open + 1, "a position's number: P[n] or P[n:\"comment\"]"))?;
    let name = format!("P[{number}]");
    let brace = skip_space(bytes, close + 1, end);
    if bytes.get(brace) != Some(&b'{') || brace >= end {
        return Err(src.error(brace, format!("{name}: expected '{{'")));
    }
    let body_end = (brace..end)
        .find(|i| bytes[*i] == b'}')
        .ok_or_else(|| src.error(brace, format!("{name}: its '{{' has no '}}'")))?;
    Ok((number, brace, body_end))
}

/// The fields of the position `name`'s body `i..body_end`, by group (`GP1:`).
fn groups(src: &Source, name: &str, mut i: usize, body_end: usize) -> Result<Vec<Group>, Error> {
    let bytes = src.bytes;
    let mut groups: Vec<Group> = Vec::new();
    loop {
        while i < body_end && (bytes[i].is_ascii_whitespace() || bytes[i] == b',') {
            i += 1;
        }
        if i >= body_end {
            return Ok(groups);
        }
        let word_end = src.identifier_end(i, b"").min(body_end);
        if word_end == i {
            return Err(src.error(
                i,
                format!(
                    "{name}: expected a field (UF, X, J1…), found {}",
                    src.describe(i)
                ),
            ));
        }
        let word = src.text(i, word_end).to_ascii_uppercase();
        let field_at = i;
        i = skip_blanks(bytes, word_end, body_end);
        if let Some(g) = word.strip_prefix("GP") {
            if bytes.get(i) == Some(&b':') && i < body_end {
                let g: u32 = g
                    .parse()
                    .map_err(|_| src.error(field_at, format!("{name}: a group GPn")))?;
                groups.push((g, field_at, Vec::new()));
                i += 1;
                continue;
            }
        }
        let Some(group) = groups.last_mut() else {
            return Err(src.error(field_at, format!("{name}: a field before its group (GP1:)")));
        };
        let (value, after) = field_value(src, name, &word, i, body_end)?;
        i = after;
        group.2.push(Field { name: word, value });
    }
}

/// The value of the field `word` whose `:` or `=` is at `i`, and where it ends.
fn field_value(
    src: &Source,
    name: &str,
    word: &str,
    mut i: usize,
    body_end: usize,
) -> Result<(FieldValue, usize), Error> {
    let bytes = src.bytes;
    match bytes.get(i) {
        Some(b':') if i < body_end => {
            i = skip_blanks(bytes, i + 1, body_end);
            if bytes.get(i) == Some(&b'\'') {
                let q = (i + 1..body_end)
                    .find(|k| bytes[*k] == b'\'')
                    .ok_or_else(|| src.error(i, format!("{name}: a quote without its end")))?;
                Ok((FieldValue::Text(i + 1, q), q + 1))
            } else {
                let s = i;
                while i < body_end && !(bytes[i].is_ascii_whitespace() || bytes[i] == b',') {
                    i += 1;
                }
                Ok((FieldValue::Word(src.text(s, i)), i))
            }
        }
        Some(b'=') if i < body_end => {
            let v = skip_blanks(bytes, i + 1, body_end);
            if bytes.get(v) == Some(&b'*') && v < body_end {
                // `X = ********  mm`: a position not taught.
                let stars = bytes[v..body_end]
                    .iter()
                    .take_while(|b| **b == b'*')
                    .count();
                i = skip_blanks(bytes, v + stars, body_end);
                i = src.identifier_end(i, b"").min(body_end).max(i);
                return Ok((FieldValue::Untaught(v), i));
            }
            let n = parse_number(&bytes[..body_end], v).ok_or_else(|| {
                src.error(
                    v,
                    format!("{name}: {word} must be a number, found {}", src.describe(v)),
                )
            })?;
            i = skip_blanks(bytes, n.span.1, body_end);
            // Its unit: `mm`, `deg`.
            i = src.identifier_end(i, b"").min(body_end).max(i);
            Ok((FieldValue::Number(n), i))
        }
        _ => Err(src.error(
            i.min(body_end),
            format!("{name}: expected ':' or '=' after {word}"),
        )),
    }
}

/// The number a group's field `key` holds.
fn number_of(fields: &[Field], key: &str) -> Option<Number> {
    fields.iter().find_map(|f| match &f.value {
        FieldValue::Number(n) if f.name == key => Some(*n),
        _ => None,
    })
}

/// A second motion group, or an extended axis of group 1 (a rail integrated with the
/// robot): the position is read, and reported.
fn group_refusal(src: &Source, groups: &[Group], fields: &[Field]) -> Option<Refusal> {
    if let Some((g, gat, _)) = groups.iter().find(|g| g.0 != 1) {
        let (line, _) = src.location(*gat);
        return Some(Refusal::new(
            Reason::ExternalAxis,
            format!("GP{g} (line {line}): a second motion group (a positioner, a rail, another robot) moves with it, which the table does not have"),
        ));
    }
    fields.iter().find_map(|f| match &f.value {
        FieldValue::Number(n) if f.name.starts_with('E') && n.value != 0.0 => Some(Refusal::new(
            Reason::ExternalAxis,
            format!(
                "{} {}: an extended axis (a rail, a positioner) the table does not have",
                f.name,
                src.text(n.span.0, n.span.1)
            ),
        )),
        _ => None,
    })
}

/// What a position's frame numbers (`UF`, `UT`) stand for: the options, and the frames
/// the program sets as it runs; and the joints of its CONFIG's turn numbers.
struct FrameFields<'s, 'a> {
    src: &'s Source<'a>,
    options: &'s FanucOptions,
    set_frames: &'s SetFrames,
    turn_axes: TurnAxes,
}

impl FrameFields<'_, '_> {
    /// The target of the position `name` at `at`, from its groups' fields.
    fn target(&self, name: String, at: usize, groups: &[Group]) -> ProgramTarget {
        let target = |kind: TargetKind| ProgramTarget {
            name,
            offset: at,
            kind,
            uses: Vec::new(),
            refused: None,
        };
        let Some((_, _, fields)) = groups.iter().find(|g| g.0 == 1) else {
            let kind = TargetKind::Incomplete("no group 1 (GP1) data".into());
            // Another group alone (a second robot's program, `GP2:`): not the robot the
            // table and the robot file describe.
            let refused = groups.first().map(|(g, gat, _)| {
                let (line, _) = self.src.location(*gat);
                Refusal::new(
                    Reason::ExternalAxis,
                    format!("GP{g} (line {line}) alone: the position moves motion group {g} (another robot, a positioner), not group 1, the robot the table and the robot file describe"),
                )
            });
            return ProgramTarget {
                refused,
                ..target(kind)
            };
        };
        if let Some((f, place)) = fields.iter().find_map(|f| match f.value {
            FieldValue::Untaught(place) => Some((f, place)),
            _ => None,
        }) {
            let (line, column) = self.src.location(place);
            return target(TargetKind::Incomplete(format!(
                "not taught: {} = ******** ({line}:{column}), as the pendant writes a position never recorded",
                f.name
            )));
        }
        let refused = group_refusal(self.src, groups, fields);
        let cartesian: Vec<Option<Number>> = ["X", "Y", "Z", "W", "P", "R"]
            .iter()
            .map(|k| number_of(fields, k))
            .collect();
        let joints: Vec<Number> = (1..=9)
            .map_while(|k| number_of(fields, &format!("J{k}")))
            .collect();
        if cartesian.iter().all(Option::is_none) {
            if joints.is_empty() {
                // Name what is written instead (a pendant's `RX =`, `KONFIG`), so that the
                // reason is not taken for a position left empty.
                let known = ["UF", "UT", "CONFIG"];
                let others: Vec<&str> = fields
                    .iter()
                    .map(|f| f.name.as_str())
                    .filter(|n| !known.contains(n))
                    .collect();
                let why = if others.is_empty() {
                    "neither X, Y, Z, W, P, R nor J1… written".to_string()
                } else {
                    format!(
                        "written as {}, which this reader does not read (it reads X, Y, Z, W, P, R or J1…)",
                        others.join(", ")
                    )
                };
                return target(TargetKind::Incomplete(why));
            }
            let kind = TargetKind::Joints(JointTarget {
                joints,
                unit: AngleUnit::Degree,
            });
            return ProgramTarget {
                refused,
                ..target(kind)
            };
        }
        let missing: Vec<&str> = ["X", "Y", "Z", "W", "P", "R"]
            .into_iter()
            .zip(&cartesian)
            .filter(|(_, n)| n.is_none())
            .map(|(k, _)| k)
            .collect();
        if !missing.is_empty() {
            return target(TargetKind::Incomplete(format!(
                "{} not written",
                missing.join(", ")
            )));
        }
        let c: Vec<Number> = cartesian.into_iter().flatten().collect();
        let mut unknown = Vec::new();
        let base = self.frame(fields, "UF", true, &mut unknown);
        let tool = self.frame(fields, "UT", false, &mut unknown);
        let config = fields
            .iter()
            .find_map(|f| match f.value {
                FieldValue::Text(s, e) if f.name == "CONFIG" => {
                    Some(config_hint(&self.src.bytes[s..e], (s, e), self.turn_axes))
                }
                _ => None,
            })
            .unwrap_or(ConfigHint::None);
        let kind = TargetKind::Cartesian(Box::new(CartesianTarget {
            position: [c[0], c[1], c[2]],
            unit: LengthUnit::Millimetre,
            orientation: Some(Orientation::KukaAbcDeg([c[5], c[4], c[3]])),
            config,
            joints: Vec::new(),
        }));
        ProgramTarget {
            uses: vec![FrameUse {
                tool,
                base,
                offset: at,
                elsewhere: None,
                note: None,
                undeclared: Vec::new(),
                unknown,
            }],
            refused,
            ..target(kind)
        }
    }

    /// The frame the field `key` numbers (a user frame, or else a tool frame); `None`,
    /// with why said in `unknown`, when it is not known.
    fn frame(
        &self,
        fields: &[Field],
        key: &str,
        user: bool,
        unknown: &mut Vec<String>,
    ) -> Option<Isometry3<f64>> {
        let what = if user { "user frame" } else { "tool frame" };
        let Some(f) = fields.iter().find(|f| f.name == key) else {
            unknown.push(format!("{key} not written: its {what} is not known"));
            return None;
        };
        let FieldValue::Word(text) = &f.value else {
            unknown.push(format!("{key}: its {what} is not a number"));
            return None;
        };
        let Ok(n) = text.parse::<u16>() else {
            unknown.push(format!("{what} {text}: not a frame number"));
            return None;
        };
        let set = self
            .set_frames
            .get(&(user, Some(n)))
            .map(|place| (true, place))
            .or_else(|| {
                // Frame 0 (the world, the faceplate) is never set.
                (n != 0)
                    .then(|| self.set_frames.get(&(user, None)))
                    .flatten()
                    .map(|place| (false, place))
            });
        if let Some((direct, place)) = set {
            let (line, column) = self.src.location(*place);
            unknown.push(if direct {
                format!("{what} {n} is set as the program runs ({line}:{column})")
            } else {
                format!(
                    "{what} {n} may be set as the program runs: the {what} set at {line}:{column} is chosen by a register"
                )
            });
            return None;
        }
        if n == 0 {
            // The world frame, and the faceplate.
            return Some(Isometry3::identity());
        }
        let given = if user {
            self.options.user(n)
        } else {
            self.options.tool(n)
        };
        match given {
            Some(f) => Some(wpr_pose(f)),
            None => {
                let option = if user { "uframe" } else { "utool" };
                unknown.push(format!(
                    "{what} {n} not given: give it as --fanuc-{option} {n}=X,Y,Z,W,P,R or in the frame file (--fanuc-frames)"
                ));
                None
            }
        }
    }
}

/// A position's `CONFIG : 'N U T, 0, 0, 0'`: the wrist (`N` no flip, `F` flip), the elbow
/// (`U` up, `D` down), the shoulder (`T` front, `B` back), and the turn numbers of
/// `turn_axes`' joints (turn k: −180° + 360°k < J ≤ 180° + 360°k; J4, J5 and J6 unless the
/// controller says otherwise). `span` is where the text is written.
///
/// A CONFIG that is not one letter of each pair and three whole turn numbers (a SCARA's,
/// a misspelt one) is [`ConfigHint::Unreadable`]: the controller reads it in a way this
/// reader does not, so a target solved in any posture would be a guess.
fn config_hint(text: &[u8], span: (usize, usize), turn_axes: TurnAxes) -> ConfigHint {
    const EXPECTED: &str =
        "a Fanuc CONFIG is 'N|F U|D T|B, t1, t2, t3' (one letter of each pair, three turn numbers from -4 to 4)";
    let unreadable = ConfigHint::Unreadable {
        span,
        expected: EXPECTED,
    };
    let text = String::from_utf8_lossy(text).to_ascii_uppercase();
    let mut parts = text.split(',');
    let letters = parts.next().unwrap_or("");
    let mut bits: u8 = 0;
    // Which of wrist, elbow and shoulder a letter has given.
    let mut given = [false; 3];
    for word in letters.split_whitespace() {
        let (which, bit) = match word {
            "N" => (0, 0),
            "F" => (0, 4),
            "U" => (1, 0),
            "D" => (1, 2),
            "T" => (2, 0),
            "B" => (2, 1),
            _ => return unreadable,
        };
        if given[which] {
            return unreadable;
        }
        given[which] = true;
        bits |= bit;
    }
    if given != [true; 3] {
        return unreadable;
    }
    let turns: Vec<i8> = match parts
        .map(|t| t.trim().parse::<i8>().ok().filter(|k| (-4..=4).contains(k)))
        .collect::<Option<Vec<i8>>>()
    {
        Some(turns) if turns.len() == 3 => turns,
        _ => return unreadable,
    };
    ConfigHint::FanucConfig {
        configuration: Some(bits),
        turns: [Some(turns[0]), Some(turns[1]), Some(turns[2])],
        turn_axes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const WELD: &str = "/PROG  WELD\n/ATTR\nOWNER\t\t= MNEDITOR;\n/MN\n   1:  UTOOL_NUM=1 ;\n\
        \x20  2:J P[1] 100% FINE    ;\n   3:L P[2:seam start] 500mm/sec CNT100    ;\n\
        \x20  4:C P[3]    \n    :  P[4] 200mm/sec FINE    ;\n   5:L P[2:seam start] 100mm/sec FINE Offset,PR[1]    ;\n\
        \x20  6:L PR[3] 100mm/sec FINE    ;\n   7:  !back home ;\n   8:  //L P[9] 100mm/sec FINE    ;\n\
        \x20  9:L P[5] 100mm/sec FINE Tool_Offset,PR[2:tool z]    ;\n  10:J P[6] 50% FINE    ;\n  11:L P[8] 100mm/sec FINE    ;\n\
        /POS\nP[1]{\n   GP1:\n\tUF : 0, UT : 1,\n\tJ1=    0.000 deg,\tJ2=   10.000 deg,\tJ3=  -20.000 deg,\n\
        \tJ4=    0.000 deg,\tJ5=  -70.000 deg,\tJ6=    0.000 deg\n};\n\
        P[2:\"seam start\"]{\n   GP1:\n\tUF : 1, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',\n\
        \tX =   100.000  mm,\tY =   -50.000  mm,\tZ =    20.000  mm,\n\tW =  -180.000 deg,\tP =      .000 deg,\tR =    90.000 deg\n};\n\
        P[3]{\n   GP1:\n\tUF : 1, UT : 1,\t\tCONFIG : 'F D B, 0, 1, -1',\n\
        \tX =   150.000  mm,\tY =   -50.000  mm,\tZ =    20.000  mm,\n\tW =  -180.000 deg,\tP =      .000 deg,\tR =    90.000 deg\n};\n\
        P[4]{\n   GP1:\n\tUF : 4, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',\n\
        \tX =   200.000  mm,\tY =   -50.000  mm,\tZ =    20.000  mm,\n\tW =  -180.000 deg,\tP =      .000 deg,\tR =    90.000 deg\n};\n\
        P[5]{\n   GP1:\n\tUF : 1, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',\n\
        \tX =   250.000  mm,\tY =   -50.000  mm,\tZ =    20.000  mm,\n\tW =  -180.000 deg,\tP =      .000 deg,\tR =    90.000 deg\n};\n\
        P[6]{\n   GP1:\n\tUF : 1, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',\n\
        \tX =   250.000  mm,\tY =   -50.000  mm,\tZ =    20.000  mm,\n\tW =  -180.000 deg,\tP =      .000 deg,\tR =    90.000 deg\n\
        \x20  GP2:\n\tUF : 0, UT : 1,\n\tJ1=    90.000 deg\n};\n/END\n";

    fn options() -> FanucOptions {
        FanucOptions {
            user_frames: vec![(1, [1500.0, 0.0, 500.0, 0.0, 0.0, 30.0])],
            tool_frames: vec![(1, [0.0, 0.0, 200.0, 0.0, 0.0, 0.0])],
            frames_file: None,
        }
    }

    fn status(t: &ProgramTarget) -> String {
        match (&t.refused, &t.kind) {
            (Some(r), _) => r.reason.as_str().to_string(),
            (None, TargetKind::Cartesian(_)) if t.uses.iter().any(|u| !u.unknown.is_empty()) => {
                "frame_unknown".into()
            }
            (None, TargetKind::Cartesian(_)) => "cartesian".into(),
            (None, TargetKind::Joints(_)) => "joints".into(),
            (None, TargetKind::Incomplete(_)) => "incomplete".into(),
            (None, TargetKind::Motion) => "motion".into(),
        }
    }

    #[test]
    fn every_motion_and_position_is_accounted_for() {
        let p = read(&Source::new("weld.ls", WELD.as_bytes()), &options()).unwrap();
        let seen: Vec<(String, String)> = p
            .targets
            .iter()
            .map(|t| (t.name.clone(), status(t)))
            .collect();
        let want = [
            ("L P[2:seam start]", "relative"),
            ("L PR[3]", "dynamic"),
            ("L P[5]", "relative"),
            ("L P[8]", "not_declared"),
            ("P[1]", "joints"),
            ("P[2]", "cartesian"),
            ("P[3]", "cartesian"),
            ("P[4]", "frame_unknown"),
            ("P[5]", "relative"),
            ("P[6]", "external_axis"),
        ];
        let want: Vec<(String, String)> = want
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect();
        assert_eq!(seen, want);
        let p4 = &p.targets[7].uses[0].unknown[0];
        assert!(p4.starts_with("user frame 4 not given"), "{p4}");
        let p5 = p.targets[8].refused.as_ref().unwrap();
        assert!(
            p5.detail
                .starts_with("used only by L P[5] (14:8): Tool_Offset,PR[2:tool z]: an offset"),
            "{}",
            p5.detail
        );
        // W, P, R read as KUKA's A, B, C in reverse: R, P, W.
        let TargetKind::Cartesian(c) = &p.targets[5].kind else {
            unreachable!()
        };
        let Some(Orientation::KukaAbcDeg(abc)) = c.orientation else {
            unreachable!()
        };
        assert_eq!(abc.map(|n| n.value), [90.0, 0.0, -180.0]);
        // P[3]'s configuration: flip, elbow down, shoulder back; turns 0, 1, -1.
        let TargetKind::Cartesian(c) = &p.targets[6].kind else {
            unreachable!()
        };
        assert_eq!(
            c.config,
            ConfigHint::FanucConfig {
                configuration: Some(7),
                turns: [Some(0), Some(1), Some(-1)],
                turn_axes: TurnAxes::default(),
            }
        );
        // The user frame is its base, the tool frame its tool.
        let base = p.targets[5].uses[0].base.unwrap();
        assert!((base.translation.vector.x - 1500.0).abs() < 1e-9);
        assert_eq!(p.first_motion, Some(WELD.find("J P[1]").unwrap()));
    }

    #[test]
    fn a_frame_the_program_sets_as_it_runs_is_named() {
        let text = WELD.replace("   1:  UTOOL_NUM=1 ;", "   1:  UFRAME[1]=PR[9] ;");
        let p = read(&Source::new("weld.ls", text.as_bytes()), &options()).unwrap();
        let p2 = p.targets.iter().find(|t| t.name == "P[2]").unwrap();
        assert_eq!(
            p2.uses[0].unknown,
            ["user frame 1 is set as the program runs (5:8)"]
        );
    }

    /// A position whose coordinates are written under labels the reader does not read (a
    /// pendant's `RX =` … `RR =`) is incomplete, naming them; one with nothing written says
    /// so.
    #[test]
    fn coordinates_under_labels_not_read_are_named() {
        let labelled = program("", &["L P[1] 100mm/sec FINE"], 1)
            .replace("\tX =", "\tRX =")
            .replace("\tY =", "\tRY =")
            .replace("\tZ =", "\tRZ =")
            .replace("\tW =", "\tRW =")
            .replace("\tP =", "\tRP =")
            .replace("\tR =", "\tRR =");
        let seen = statuses(&labelled);
        assert_eq!(seen[0].1, "incomplete", "{seen:?}");
        assert_eq!(
            seen[0].2,
            "written as RX, RY, RZ, RW, RP, RR, which this reader does not read (it reads X, Y, Z, W, P, R or J1…)"
        );
        let empty = "/PROG  T\n/MN\n   1:L P[1] 100mm/sec FINE ;\n/POS\nP[1]{\n   GP1:\n\tUF : 0, UT : 1,\n};\n/END\n";
        let seen = statuses(empty);
        assert_eq!(
            seen[0].2, "neither X, Y, Z, W, P, R nor J1… written",
            "{seen:?}"
        );
    }

    fn statuses(text: &str) -> Vec<(String, String, String)> {
        let p = read(&Source::new("t.ls", text.as_bytes()), &options()).unwrap();
        p.targets
            .iter()
            .map(|t| {
                let detail = match (&t.refused, &t.kind) {
                    (Some(r), _) => r.detail.clone(),
                    (None, TargetKind::Incomplete(why)) => why.clone(),
                    _ => t
                        .uses
                        .first()
                        .map(|u| u.unknown.join("; "))
                        .unwrap_or_default(),
                };
                (t.name.clone(), status(t), detail)
            })
            .collect()
    }

    /// A program's `/MN` statements over positions `P[1]`-`P[n]`, each in user frame 1 and
    /// tool frame 1 but `P[1]` in user frame 0, as a pendant saves it.
    fn program(head: &str, mn: &[&str], n: u32) -> String {
        let mut text = format!("/PROG  T\n/ATTR\n{head}/MN\n");
        for (k, m) in mn.iter().enumerate() {
            text.push_str(&format!("{:>4}:{m} ;\n", k + 1));
        }
        text.push_str("/POS\n");
        for k in 1..=n {
            let uf = u32::from(k != 1);
            text.push_str(&format!(
                "P[{k}]{{\n   GP1:\n\tUF : {uf}, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',\n\
                 \tX =   {}.000  mm,\tY =   -50.000  mm,\tZ =    20.000  mm,\n\
                 \tW =  -180.000 deg,\tP =      .000 deg,\tR =    90.000 deg\n}};\n",
                100 + k
            ));
        }
        text.push_str("/END\n");
        text
    }

    #[test]
    fn a_german_pendants_tool_offset_is_relative() {
        let head = "EIGN.\t\t= AUROM;\nKOMMENTAR\t= \"Posicion\";\nDEFAULT_GRUP\t= 1,*,*,*,*;\n";
        let text = program(
            head,
            &[
                "  WKZ_NUM=1",
                "  BENUTZER_NUM=0",
                "L P[1] 100mm/sek CNT0 ACC100",
                "L P[2] 100mm/sek CNT0 ACC100 WKZ_Offset ,PR[2]",
                "L P[3] 100mm/sek CNT0 ACC100 Interrupt,LABEL[1]",
                "L P[4] 100mm/sek FINE Werkzeug_Offset,PR[3]",
            ],
            4,
        );
        let s = statuses(&text);
        let p: Vec<(&str, &str)> = s.iter().map(|t| (t.0.as_str(), t.1.as_str())).collect();
        assert_eq!(
            p,
            [
                ("L P[2]", "relative"),
                ("L P[4]", "relative"),
                ("P[1]", "cartesian"),
                ("P[2]", "relative"),
                ("P[3]", "cartesian"),
                ("P[4]", "relative"),
            ]
        );
        assert_eq!(
            s[0].2,
            "WKZ_Offset ,PR[2]: an offset in the tool frame the controller adds as it runs"
        );
    }

    #[test]
    fn a_second_groups_position_alone_is_not_the_tables_robots() {
        // A program of robot 2 on a two-robot controller, as ROBOGUIDE writes it.
        let text = program(
            "DEFAULT_GROUP\t= *,1,*,*,*;\n",
            &["L P[1] 100mm/sec FINE"],
            1,
        )
        .replace("   GP1:", "   GP2:");
        let s = statuses(&text);
        assert_eq!(s[0].1, "external_axis");
        assert_eq!(
            s[0].2,
            "GP2 (line 8) alone: the position moves motion group 2 (another robot, a positioner), not group 1, the robot the table and the robot file describe"
        );
    }

    #[test]
    fn a_frame_chosen_by_a_register_may_be_any() {
        let mn = [
            "  UFRAME_NUM=0",
            "L P[1] 100mm/sec FINE",
            "  UFRAME[R[9]]=PR[71:newFRAME]",
            "L P[2] 100mm/sec FINE",
        ];
        let s = statuses(&program("", &mn, 2));
        // User frame 0, the world, is never set; user frame 1 may be the one set.
        assert_eq!(s[0].1, "cartesian");
        assert_eq!(s[1].1, "frame_unknown");
        assert_eq!(
            s[1].2,
            "user frame 1 may be set as the program runs: the user frame set at 6:8 is chosen by a register"
        );
        let mut mn = mn;
        mn[2] = "  UTOOL[AR[1]]=PR[8]";
        let s = statuses(&program("", &mn, 2));
        assert!(s.iter().all(|t| t.1 == "frame_unknown"), "{s:?}");
        assert!(s[0].2.starts_with("tool frame 1 may be set"), "{}", s[0].2);
    }

    #[test]
    fn an_untaught_position_is_incomplete_and_the_others_read() {
        let text = program("", &["L P[1] 100mm/sec FINE", "L P[2] 100mm/sec FINE"], 2)
            .replacen(
                "\tX =   102.000  mm,\tY =   -50.000  mm,\tZ =    20.000  mm,\n\
                 \tW =  -180.000 deg,\tP =      .000 deg,\tR =    90.000 deg",
                "\tX = ********  mm,\tY = ********  mm,\tZ = ********  mm,\n\
                 \tW = ******** deg,\tP = ******** deg,\tR = ******** deg",
                1,
            )
            .replacen("UF : 1, UT : 1", "UF : F, UT : F", 1);
        let s = statuses(&text);
        assert_eq!(s[0].1, "cartesian");
        assert_eq!(s[1].1, "incomplete");
        assert_eq!(
            s[1].2,
            "not taught: X = ******** (16:6), as the pendant writes a position never recorded"
        );
    }

    #[test]
    fn touch_offset_regions_and_copies_into_registers_are_reported() {
        let mn = [
            "L P[1] 100mm/sec FINE",
            "  Touch Offset PR[10]",
            "L P[2] 100mm/sec FINE",
            "  Touch Offset End",
            "L P[3] 100mm/sec FINE",
            "  PR[7]=P[4]",
            "  PR[7,3]=PR[7,3]+50",
            "L PR[7] 100mm/sec FINE",
            "  PR[8]=P[3]",
        ];
        let s = statuses(&program("", &mn, 4));
        let p: Vec<(&str, &str)> = s.iter().map(|t| (t.0.as_str(), t.1.as_str())).collect();
        assert_eq!(
            p,
            [
                ("L P[2]", "relative"),
                ("L PR[7]", "dynamic"),
                ("P[1]", "cartesian"),
                ("P[2]", "relative"),
                // Moved to directly as well: corrected.
                ("P[3]", "cartesian"),
                ("P[4]", "dynamic"),
            ]
        );
        assert_eq!(
            s[0].2,
            "inside Touch Offset PR[10] (5:8): the offset touch sensing finds, which the controller adds as it runs"
        );
        assert!(
            s[5].2
                .starts_with("used only by PR[7]=P[4] (9:8): the position is copied"),
            "{}",
            s[5].2
        );
    }

    #[test]
    fn the_frame_file_gives_group_one_frames() {
        let va = "[*SYSTEM*]$MNUFRAME  Storage: SHADOW  Access: RW  : ARRAY[1,9] OF POSITION Reg\n\
                  \x20   [1,1] = \n  Group: 1   Config: N D B, 0, 0, 0\n  X:  1500.000   Y:   200.000   Z:  -300.000\n\
                  \x20 W:     0.000   P:     0.000   R:    30.000\n    [1,2] = Uninitialized\n\
                  \x20   [2,1] = \n  Group: 2   Config: N D B, 0, 0, 0\n  X:     1.000   Y:     2.000   Z:     3.000\n\
                  \x20 W:     0.000   P:     0.000   R:     0.000\n\
                  [*SYSTEM*]$MNUFRAMENUM  Storage: SHADOW  Access: RW  : ARRAY[2] OF BYTE\n  [1] = 1\n\
                  [*SYSTEM*]$MNUTOOL  Storage: SHADOW  Access: RW  : ARRAY[1,10] OF POSITION Reg\n\
                  \x20   [1,1] = 'torch'\n  Group: 1   Config: N D B, 0, 0, 0\n  X:     0.000   Y:     0.000   Z:   180.000\n\
                  \x20 W:     0.000   P:   -45.000   R:     0.000\n";
        let f = read_frames(&Source::new("SYSFRAME.VA", va.as_bytes())).unwrap();
        assert_eq!(
            f.user_frames,
            [(1, [1500.0, 200.0, -300.0, 0.0, 0.0, 30.0])]
        );
        assert_eq!(f.tool_frames, [(1, [0.0, 0.0, 180.0, 0.0, -45.0, 0.0])]);
        let bad = va.replace("R:    30.000", "R:    x");
        let err = read_frames(&Source::new("SYSFRAME.VA", bad.as_bytes())).unwrap_err();
        assert!(err.to_string().starts_with("SYSFRAME.VA:5:"), "{err}");
    }

    #[test]
    fn the_turn_axes_are_read_from_the_controllers_variables() {
        // As SYMOTN.VA holds them: group 1's, not group 2's; a frame file holds none.
        let va = "[*SYSTEM*]$SCR_GRP  Storage: SHADOW  Access: FP  : ARRAY[4] OF SCR_GRP_T\n\
                  \x20    Field: $SCR_GRP[1].$NUM_AXES Access: RO: BYTE = 6\n\
                  \x20    Field: $SCR_GRP[1].$TURN_AXIS  ARRAY[3] OF INTEGER\n\
                  \x20     [1] = 1\n      [2] = 4\n      [3] = 6\n\
                  \x20    Field: $SCR_GRP[1].$AXS_AMP_NUM  ARRAY[9] OF BYTE\n      [1] = 1\n\
                  \x20    Field: $SCR_GRP[2].$TURN_AXIS  ARRAY[3] OF INTEGER\n\
                  \x20     [1] = 4\n      [2] = 0\n      [3] = 6\n";
        let read = |text: &str| read_turn_axes(&Source::new("SYMOTN.VA", text.as_bytes()));
        assert_eq!(read(va).unwrap(), Some([1, 4, 6]));
        assert_eq!(
            read(&va.replace("[2] = 4", "[2] = 0")).unwrap(),
            Some([1, 0, 6])
        );
        assert_eq!(
            read("[*SYSTEM*]$MNUFRAME  Storage: SHADOW\n").unwrap(),
            None
        );
        for (bad, line) in [
            (va.replace("[2] = 4", "[2] = 6"), 3),
            (va.replace("[2] = 4", "[2] = 12"), 5),
            (va.replace("[2] = 4", "[2] = x"), 5),
            (va.replace("      [3] = 6\n", ""), 3),
        ] {
            let err = read(&bad).unwrap_err().to_string();
            assert!(
                err.starts_with(&format!("SYMOTN.VA:{line}:"))
                    && err.contains("$TURN_AXIS: expected"),
                "{err}"
            );
        }
        let twice = format!(
            "{va}{}",
            &va[va.find("     Field: $SCR_GRP[1].$TURN").unwrap()..]
        );
        assert!(read(&twice)
            .unwrap_err()
            .to_string()
            .contains("twice (first at line 3)"));
    }

    #[test]
    fn turn_axes_are_three_distinct_joints_and_the_option_stands_with_the_controller() {
        assert_eq!(parse_turn_axes("1,4,6").unwrap(), [1, 4, 6]);
        assert_eq!(parse_turn_axes(" 4, 5 ,6").unwrap(), [4, 5, 6]);
        for bad in [
            "1,4", "1,4,6,7", "1,4,4", "0,4,6", "1,4,10", "1,4,x", "-1,4,6",
        ] {
            let err = parse_turn_axes(bad).unwrap_err();
            assert!(err.contains("turn axes"), "{bad}: {err}");
        }
        let file = || Some(([1, 4, 6], "SYMOTN.VA".to_string()));
        let axes = TurnAxes::of_job(None, file()).unwrap();
        assert_eq!(
            (axes.joints, axes.from),
            ([1, 4, 6], TurnAxesFrom::Controller)
        );
        let axes = TurnAxes::of_job(Some([1, 4, 6]), file()).unwrap();
        assert_eq!(axes.from, TurnAxesFrom::Option);
        assert_eq!(
            TurnAxes::of_job(Some([4, 5, 6]), file()).unwrap_err(),
            "--fanuc-turn-axes 4,5,6 and the frame file SYMOTN.VA's $SCR_GRP[1].$TURN_AXIS 1,4,6 disagree: give the controller's"
        );
        assert_eq!(TurnAxes::of_job(None, None).unwrap(), TurnAxes::default());
        // Each joint keeps the turn its axis is given; the others any.
        let turns = joint_turns(&[Some(-1), Some(1), Some(0)], &axes, 6);
        use crate::correct::Turn;
        assert_eq!(
            turns,
            [
                Turn::Revolution(-1),
                Turn::Any,
                Turn::Any,
                Turn::Revolution(1),
                Turn::Any,
                Turn::Revolution(0)
            ]
        );
    }

    #[test]
    fn frames_parse_as_the_command_line_writes_them() {
        assert_eq!(
            parse_frame("2=1,2,3").unwrap(),
            (2, [1.0, 2.0, 3.0, 0.0, 0.0, 0.0])
        );
        assert_eq!(parse_frame("1=0,0,200,0,-90,0").unwrap().1[4], -90.0);
        assert!(parse_frame("0=1,2,3").is_err());
        assert!(parse_frame("1=1,2").is_err());
        assert!(parse_frame("1=1,2,nan").is_err());
    }

    #[test]
    fn wpr_turns_about_fixed_x_then_y_then_z() {
        // W 90 alone: about x, y goes to z.
        let pose = wpr_pose(&[0.0, 0.0, 0.0, 90.0, 0.0, 0.0]);
        let y = pose.rotation * nalgebra::Vector3::y();
        assert!((y - nalgebra::Vector3::z()).norm() < 1e-12, "{y}");
        // W 90 then R 90 (about the fixed z): x stays x under W, then goes to y.
        let pose = wpr_pose(&[0.0, 0.0, 0.0, 90.0, 0.0, 90.0]);
        let x = pose.rotation * nalgebra::Vector3::x();
        assert!((x - nalgebra::Vector3::y()).norm() < 1e-12, "{x}");
        let z = pose.rotation * nalgebra::Vector3::z();
        // z goes to -y under W 90, then to x under R 90.
        assert!((z - nalgebra::Vector3::x()).norm() < 1e-12, "{z}");
    }

    #[test]
    fn a_malformed_position_is_located() {
        let text = "/PROG A\n/MN\n   1:L P[1] 100mm/sec FINE    ;\n/POS\nP[1]{\n   GP1:\n\tUF : 0, UT : 1,\n\tX = abc mm\n};\n/END\n";
        let err = read(&Source::new("a.ls", text.as_bytes()), &options()).unwrap_err();
        assert_eq!(
            err.to_string(),
            "a.ls:8:6: P[1]: X must be a number, found 'abc mm'"
        );
        let text = "/PROG A\n/MN\n   1:L P[1 100mm/sec FINE    ;\n/END\n";
        let err = read(&Source::new("a.ls", text.as_bytes()), &options()).unwrap_err();
        assert!(
            err.to_string()
                .starts_with("a.ls:3:9: a '[' without its ']'"),
            "{err}"
        );
    }
}
