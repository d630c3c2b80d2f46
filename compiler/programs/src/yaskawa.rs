//! Yaskawa INFORM jobs (`.jbi`), as the pendant saves them and offline tools write them.
//!
//! A job is a `/JOB` header, a `//POS` section of position data and an `//INST` section of
//! instructions:
//!
//! ```text
//! /JOB
//! //NAME WELD1
//! //POS
//! ///NPOS 3,0,0,0,0,0
//! ///TOOL 1
//! ///POSTYPE PULSE
//! ///PULSE
//! C00000=0,0,0,0,-45000,0
//! ///USER 2
//! ///POSTYPE USER
//! ///RECTAN
//! ///RCONF 0,0,0,0,0,0,0,0
//! C00001=250.000,0.000,100.000,180.0000,0.0000,0.0000
//! //INST
//! ///DATE 2024/03/11 09:12
//! ///ATTR SC,RW
//! ///GROUP1 RB1
//! NOP
//! MOVJ C00000 VJ=25.00
//! MOVL C00001 V=100.0 PL=0
//! END
//! ```
//!
//! The targets are the `C` positions. Each takes the frames the `///` lines above it set:
//! `///TOOL n` the tool file, `///POSTYPE` the frame (`ROBOT` and `BASE` the robot's base
//! frame, `USER` the user frame `///USER n`, `PULSE` joint positions in encoder pulses).
//! A Cartesian position is X, Y, Z (mm) and Rx, Ry, Rz (degrees) about the fixed axes x,
//! then y, then z: `R = Rz(Rz)·Ry(Ry)·Rx(Rx)` (KUKA's A, B, C read as Rz, Ry, Rx). The
//! numbered tools and user frames come from the job's options ([`YaskawaOptions`]); a
//! number they do not give is named (`tool TOOL 2 not given`). Pulses need the robot's
//! pulses per degree per axis, from the options; without them a pulse position is
//! reported, never guessed. `///RCONF` is kept as written.
//!
//! Every instruction that moves is accounted for: `MOVJ`, `MOVL`, `MOVC`, `MOVS` to a `C`
//! position are the motions whose targets are corrected; a move to a `P` variable (which
//! the controller holds, and the program may set as it runs), `IMOV` (an increment), a
//! move between `SFTON` and `SFTOF` (a shift added as it runs), a move with a base axis
//! (`BC`), and any other motion-looking instruction are reported where they are written.
//!
//! The table is robot 1's (`RB1`). A motion line moves the job's groups (`///GROUP1
//! RB1,ST1`, `///GROUP2 RB2`) in order, each after a `+` (`MOVJ C00000 EC00000 VJ=10.00
//! +MOVJ C00001 VJ=10.00`): a position another robot's part moves is that robot's, and
//! every position of a job without robot 1 is reported. A station's axis (`EC`) moves the
//! work, not the robot's frames. Frames the job sets as it runs (`MFRAME UF#(n)`,
//! `SETTOOL TL#(n)`) and a base frame a base axis (`BS1`) sets apart leave the positions
//! in them unknown.

use nalgebra::Isometry3;

use crate::frames::kuka_pose;
use crate::number::{parse_number, Number};
use crate::program::{
    AngleUnit, CartesianTarget, ConfigHint, Format, FrameUse, JointTarget, LengthUnit, Orientation,
    Program, ProgramTarget, Reason, Refusal, TargetKind, Undeclared,
};
use crate::source::Source;
use crate::Error;

/// What a Yaskawa job needs beyond its text.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct YaskawaOptions {
    /// The tool files: the number and the TCP in the flange frame, `[X, Y, Z, Rx, Ry, Rz]`
    /// (mm, degrees, Yaskawa's convention).
    pub tools: Vec<(u16, [f64; 6])>,
    /// The user frames: the number and the frame in the robot's base frame, likewise.
    pub users: Vec<(u16, [f64; 6])>,
    /// Encoder pulses per degree, per axis (S, L, U, R, B, T), for `PULSE` positions:
    /// negative for an axis whose pulses count against the robot file's joint.
    pub pulses_per_deg: Option<Vec<f64>>,
}

/// A pose from Yaskawa's `X, Y, Z` (mm) and `Rx, Ry, Rz` (degrees, about the fixed axes x,
/// then y, then z).
pub fn pose(frame: &[f64; 6]) -> Isometry3<f64> {
    kuka_pose(
        [frame[0], frame[1], frame[2]],
        [frame[5], frame[4], frame[3]],
    )
}

/// Parses a numbered frame as the command line writes it: `n=X,Y,Z,Rx,Ry,Rz`.
///
/// # Errors
///
/// A message saying what is wrong.
pub fn parse_numbered_frame(text: &str) -> Result<(u16, [f64; 6]), String> {
    let usage = "a numbered frame is n=X,Y,Z,Rx,Ry,Rz (mm, degrees about fixed x, y, z)";
    let (number, values) = text.split_once('=').ok_or_else(|| usage.to_string())?;
    let number: u16 = number
        .trim()
        .parse()
        .map_err(|_| format!("'{}': {usage}", number.trim()))?;
    let numbers: Vec<f64> = values
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{values}': {usage}"))?;
    let frame: [f64; 6] = numbers
        .try_into()
        .map_err(|_| format!("'{values}': {usage}"))?;
    if !crate::bounds::option_frame_within(&frame) {
        return Err(format!(
            "'{values}': within ±{} mm and ±{}°",
            crate::bounds::MAX_POSITION_MM,
            crate::bounds::MAX_ANGLE_DEG
        ));
    }
    Ok((number, frame))
}

/// Parses pulses per degree as the command line writes them: one finite, non-zero number
/// per axis, `a,b,c,d,e,f`.
///
/// # Errors
///
/// A message saying what is wrong.
pub fn parse_pulses_per_deg(text: &str) -> Result<Vec<f64>, String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{text}': pulses per degree are numbers, one per axis"))?;
    check_pulses_per_deg(&values)?;
    Ok(values)
}

/// Checks pulses per degree: 1 to 12 axes, each finite, non-zero and at most 1e7 in size.
///
/// # Errors
///
/// A message saying what is wrong.
pub fn check_pulses_per_deg(values: &[f64]) -> Result<(), String> {
    if values.is_empty() || values.len() > crate::bounds::MAX_JOINTS {
        return Err(format!(
            "{} pulses per degree: one per axis, at most {}",
            values.len(),
            crate::bounds::MAX_JOINTS
        ));
    }
    if let Some(v) = values
        .iter()
        .find(|v| !(v.is_finite() && **v != 0.0 && v.abs() <= 1e7))
    {
        return Err(format!(
            "{v} pulses per degree: each must be finite, non-zero and within ±1e7"
        ));
    }
    Ok(())
}

/// The rewritten text of a pulse count: `number` is a [`JointTarget`]'s joint in degrees as
/// this reader gives it (its span the written pulses), `new_deg` the joint's new value.
/// `None` when the written pulses already hold it (within half a pulse).
pub fn pulse_text(number: &Number, original: &[u8], new_deg: f64, per_deg: f64) -> Option<String> {
    let written = Number {
        value: (number.value * per_deg).round(),
        ..*number
    };
    crate::number::rewrite(&written, original, (new_deg * per_deg).round(), 0)
}

/// The frame a position's `///POSTYPE` line gives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PosType {
    Pulse,
    Robot,
    Base,
    User,
    Tool,
    MasterTool,
}

/// Reads the targets of a Yaskawa job.
///
/// # Errors
///
/// [`Error::Syntax`] at the first malformed line.
pub fn read(src: &Source, options: &YaskawaOptions) -> Result<Program, Error> {
    read_at_most(src, options, usize::MAX)
}

/// A position read: its target index, and the uses refused (a move under `SFTON`, by
/// `REFP`), kept to report a position moved to only through them.
struct Position {
    target: usize,
    refused_uses: Vec<Refusal>,
    direct: bool,
    /// Its frame type, tool and user frame, for the job's groups and the frames it sets
    /// as it runs, known once `//INST` is read.
    kind: PosType,
    tool: u16,
    user: Option<u16>,
    /// Moved by another group's part of a motion (`+MOVJ C00001` of `///GROUP2 RB2`):
    /// another robot's position.
    other_group: Option<Refusal>,
}

/// A `///GROUPn` line of `//INST`: the group's number, what its units (`RB1`, `ST1`,
/// `BS1`) hold, the line as written, and its number.
struct Group {
    number: usize,
    /// Robot 1 (`RB1`), the table's robot.
    robot_one: bool,
    /// Another robot's unit (`RB2`), the first.
    other_robot: Option<String>,
    /// A base axis (`BS1`).
    base_axis: bool,
    text: String,
    line: usize,
}

/// Whether `unit` is `prefix` and digits (`RB2` of `RB`).
fn unit_of(unit: &str, prefix: &str) -> bool {
    unit.len() > prefix.len()
        && unit.is_char_boundary(prefix.len())
        && unit[..prefix.len()].eq_ignore_ascii_case(prefix)
        && unit[prefix.len()..].bytes().all(|b| b.is_ascii_digit())
}

impl Group {
    /// `///GROUP2 RB2 (line 21)`.
    fn describe(&self) -> String {
        format!("{} (line {})", self.text, self.line)
    }
}

/// Frames a job sets as it runs, by kind (a user frame, true, or a tool) and number (`None`:
/// chosen as the job runs): the first instruction that sets each, and its line.
type SetFrames = std::collections::HashMap<(bool, Option<u16>), (String, usize)>;

/// Which group a part of a motion line moves (`MOVJ C00000 … +MOVJ C00001 …`: the parts
/// are the job's groups in their order).
enum PartGroup {
    /// The table's robot, `RB1` (or, in a job without `///GROUP` lines, the job's robot).
    Table,
    /// Another robot of the job's groups.
    OtherRobot(String),
    /// A group without a robot (a station, a base axis alone).
    NoRobot(String),
    /// A part beyond the job's groups, or a second part in a job without `///GROUP`
    /// lines: its group is not known.
    Unknown(String),
}

/// The whitespace-separated words of `start..end`, with their offsets.
fn words(bytes: &[u8], start: usize, end: usize) -> Vec<(usize, &[u8])> {
    let mut out = Vec::new();
    let mut i = start;
    while i < end {
        while i < end && matches!(bytes[i], b' ' | b'\t') {
            i += 1;
        }
        let s = i;
        while i < end && !matches!(bytes[i], b' ' | b'\t') {
            i += 1;
        }
        if i > s {
            out.push((s, &bytes[s..i]));
        }
    }
    out
}

/// Whether `word` names a variable of `prefix` followed by digits (`C00001`, `BC00002`).
fn variable(word: &[u8], prefix: &[u8]) -> bool {
    word.len() > prefix.len()
        && word[..prefix.len()].eq_ignore_ascii_case(prefix)
        && word[prefix.len()..].iter().all(u8::is_ascii_digit)
}

/// A variable's number (`C00012` 12), for matching `C12` with `C00012`.
fn variable_number(word: &[u8], prefix: usize) -> Option<u64> {
    std::str::from_utf8(&word[prefix..]).ok()?.parse().ok()
}

/// [`read`], stopping after `limit` targets ([`Program::truncated_at`]).
///
/// # Errors
///
/// As [`read`].
pub fn read_at_most(
    src: &Source,
    options: &YaskawaOptions,
    limit: usize,
) -> Result<Program, Error> {
    let bytes = src.bytes;
    let mut reader = Reader::new(src, options);
    let mut truncated_at = None;
    let mut section = Section::Header;
    let mut start = 0;
    let mut line_number = 0;
    while start < bytes.len() {
        let (end, next) = src.line_at(start);
        line_number += 1;
        let mut at = start;
        if at == 0 && bytes.starts_with(b"\xef\xbb\xbf") {
            at = 3;
        }
        start = next;
        at = src.skip_blanks(at).min(end);
        let line = &bytes[at..end];
        if line.is_empty() {
            continue;
        }
        if reader.targets.len() > limit {
            truncated_at = Some(at);
            break;
        }
        let upper: Vec<u8> = line.iter().take(16).map(u8::to_ascii_uppercase).collect();
        if upper.starts_with(b"//POS") && !upper.starts_with(b"///") {
            section = Section::Pos;
            continue;
        }
        if upper.starts_with(b"//INST") {
            section = Section::Inst;
            continue;
        }
        if upper.starts_with(b"/") && !upper.starts_with(b"///") {
            // `/JOB`, `//NAME`, and the other sections' headers.
            if section == Section::Pos {
                section = Section::Header;
            }
            continue;
        }
        let line = Line {
            at,
            end,
            number: line_number,
        };
        match section {
            Section::Header => {}
            Section::Pos if upper.starts_with(b"///") => reader.directive(line)?,
            Section::Pos => reader.position(line)?,
            Section::Inst if upper.starts_with(b"///GROUP") => reader.group(line),
            Section::Inst if upper.starts_with(b"///") || upper.starts_with(b"'") => {}
            Section::Inst => reader.instruction(line),
        }
    }
    Ok(reader.finish(truncated_at))
}

/// The part of the job a line is in.
#[derive(PartialEq)]
enum Section {
    Header,
    Pos,
    Inst,
}

/// A line's content: where it starts (after blanks) and ends, and its number.
#[derive(Clone, Copy)]
struct Line {
    at: usize,
    end: usize,
    number: usize,
}

/// The reader as it walks the job: the targets so far, the `//POS` section's frames and
/// configuration in force, and the `//INST` section's shift.
struct Reader<'s, 'a> {
    src: &'s Source<'a>,
    options: &'s YaskawaOptions,
    targets: Vec<ProgramTarget>,
    positions: Vec<Position>,
    /// The positions by their number (`C00012` and `C12` are one).
    by_number: std::collections::HashMap<u64, usize>,
    first_motion: Option<usize>,
    tool: u16,
    user: Option<(u16, usize)>,
    postype: Option<(PosType, usize)>,
    /// The last `///RCONF`'s configuration: it holds for the positions after it.
    rconf: ConfigHint,
    /// The shift in force (`SFTON`) and its line.
    shift: Option<(String, usize)>,
    /// The job's `///GROUPn` lines.
    groups: Vec<Group>,
    /// Frames the job sets as it runs (`MFRAME UF#(1) …`, `SETTOOL TL#(2) …`): a user
    /// frame (true) or a tool, its number (`None`: chosen as the job runs, `UF#(I000)`),
    /// the instruction and its line.
    set_frames: SetFrames,
}

impl<'s, 'a> Reader<'s, 'a> {
    fn new(src: &'s Source<'a>, options: &'s YaskawaOptions) -> Reader<'s, 'a> {
        Reader {
            src,
            options,
            targets: Vec::new(),
            positions: Vec::new(),
            by_number: std::collections::HashMap::new(),
            first_motion: None,
            tool: 0,
            user: None,
            postype: None,
            rconf: ConfigHint::None,
            shift: None,
            groups: Vec::new(),
            set_frames: SetFrames::new(),
        }
    }

    /// A `///` line of `//POS`: the tool, user frame, position type or configuration of the
    /// positions after it (`NPOS`, `RECTAN`, `PULSE` and the rest are kept as written).
    fn directive(&mut self, line: Line) -> Result<(), Error> {
        let (src, end) = (self.src, line.end);
        let w = words(src.bytes, line.at + 3, end);
        let Some(&(key_at, key)) = w.first() else {
            return Ok(());
        };
        let key = key.to_ascii_uppercase();
        let value = w.get(1).copied();
        let number = |what: &str| -> Result<u16, Error> {
            value
                .and_then(|(_, v)| std::str::from_utf8(v).ok()?.parse::<u16>().ok())
                .ok_or_else(|| {
                    src.error(
                        value.map_or(end, |v| v.0),
                        format!("///{what} needs its number, 0-65535"),
                    )
                })
        };
        match key.as_slice() {
            b"TOOL" => self.tool = number("TOOL")?,
            b"USER" => self.user = Some((number("USER")?, line.number)),
            b"POSTYPE" => {
                let kind = match value.map(|v| v.1.to_ascii_uppercase()).as_deref() {
                    Some(b"PULSE") => PosType::Pulse,
                    Some(b"ROBOT") => PosType::Robot,
                    Some(b"BASE") => PosType::Base,
                    Some(b"USER") => PosType::User,
                    Some(b"TOOL") => PosType::Tool,
                    Some(b"MTOOL") => PosType::MasterTool,
                    _ => {
                        return Err(src.error(
                            value.map_or(key_at, |v| v.0),
                            "///POSTYPE is PULSE, BASE, ROBOT, USER, TOOL or MTOOL",
                        ))
                    }
                };
                self.postype = Some((kind, line.number));
            }
            b"RCONF" => self.rconf = rconf(src.bytes, key_at + key.len(), end),
            _ => {}
        }
        Ok(())
    }

    /// A position line of `//POS` (`C00001=…`, `BC…`, `P…`): a `C` position is a target in
    /// the frames and configuration in force.
    fn position(&mut self, line: Line) -> Result<(), Error> {
        let (src, at) = (self.src, line.at);
        let text = &src.bytes[at..line.end];
        let Some(eq) = text.iter().position(|b| *b == b'=') else {
            return Err(src.error(
                at,
                format!(
                    "expected a position (C00001=...) or a /// line, found {}",
                    src.describe(at)
                ),
            ));
        };
        let name = &text[..eq];
        let name_ok = [&b"C"[..], b"BC", b"EC", b"P", b"BP", b"EX"]
            .iter()
            .any(|p| variable(name, p));
        if !name_ok {
            return Err(src.error(
                at,
                format!(
                    "'{}' is not a position variable (C, BC, EC, P, BP, EX and digits)",
                    src.text(at, at + eq)
                ),
            ));
        }
        let numbers = values(src, at + eq + 1, line.end)?;
        // Only the robot's C positions are targets; BC, EC (base and station axes) and P
        // values are not.
        if !variable(name, b"C") {
            return Ok(());
        }
        let Some((kind, _)) = self.postype else {
            return Err(src.error(
                at,
                "a position before any ///POSTYPE line: its frame is not known",
            ));
        };
        let frames = Frames {
            kind,
            tool: self.tool,
            user: self.user,
            config: self.rconf,
        };
        let (target_kind, refused, uses) = position(self.options, &numbers, frames, at);
        if let Some(n) = variable_number(name, 1) {
            self.by_number.entry(n).or_insert(self.positions.len());
        }
        self.positions.push(Position {
            target: self.targets.len(),
            refused_uses: Vec::new(),
            direct: false,
            kind,
            tool: self.tool,
            user: self.user.map(|u| u.0),
            other_group: None,
        });
        self.targets.push(ProgramTarget {
            name: src.text(at, at + eq),
            offset: at,
            kind: target_kind,
            uses,
            refused,
        });
        Ok(())
    }

    /// A `///GROUPn RB1,ST1` line of `//INST`: a control group of the job and its units.
    fn group(&mut self, line: Line) {
        let src = self.src;
        let w = words(src.bytes, line.at + 3, line.end);
        let Some(&(_, key)) = w.first() else {
            return;
        };
        let Some(number) = std::str::from_utf8(&key[5.min(key.len())..])
            .ok()
            .and_then(|n| n.parse::<usize>().ok())
        else {
            return;
        };
        // A controller has a few groups; a number beyond, or given twice, is not one.
        if number > 99 || self.groups.iter().any(|g| g.number == number) {
            return;
        }
        let units = w
            .get(1)
            .map(|(_, v)| String::from_utf8_lossy(v).into_owned())
            .unwrap_or_default();
        let units = units.split(',').map(str::trim);
        let mut group = Group {
            number,
            robot_one: false,
            other_robot: None,
            base_axis: false,
            text: src.text(
                line.at,
                line.at + src.bytes[line.at..line.end].trim_ascii_end().len(),
            ),
            line: line.number,
        };
        for u in units {
            if u.eq_ignore_ascii_case("RB1") {
                group.robot_one = true;
            } else if unit_of(u, "RB") {
                group.other_robot.get_or_insert_with(|| u.to_string());
            } else if unit_of(u, "BS") {
                group.base_axis = true;
            }
        }
        self.groups.push(group);
    }

    /// The group the `k`th part of a motion line moves.
    fn part_group(&self, k: usize) -> PartGroup {
        if self.groups.is_empty() {
            return if k == 0 {
                PartGroup::Table
            } else {
                PartGroup::Unknown(
                    "a second motion group, which the job names in no ///GROUP line".into(),
                )
            };
        }
        let Some(g) = self.groups.iter().find(|g| g.number == k + 1) else {
            return PartGroup::Unknown(format!(
                "its part {} of the line names no ///GROUP{} line",
                k + 1,
                k + 1
            ));
        };
        if g.robot_one {
            PartGroup::Table
        } else if g.other_robot.is_some() {
            PartGroup::OtherRobot(g.describe())
        } else {
            PartGroup::NoRobot(g.describe())
        }
    }

    /// `MFRAME UF#(n) …` or `SETTOOL TL#(n) …`: a user frame or a tool set as the job runs.
    fn frame_set(&mut self, user: bool, w: &[(usize, &[u8])], line: Line) {
        let src = self.src;
        let tag: &[u8] = if user { b"UF#(" } else { b"TL#(" };
        let number = w.iter().skip(1).find_map(|(_, t)| {
            let u = t.to_ascii_uppercase();
            let inner = u.strip_prefix(tag)?;
            let close = inner.iter().position(|b| *b == b')')?;
            Some(
                std::str::from_utf8(&inner[..close])
                    .ok()
                    .and_then(|n| n.parse::<u16>().ok()),
            )
        });
        let text = src.text(
            line.at,
            line.at + src.bytes[line.at..line.end].trim_ascii_end().len(),
        );
        // Without its frame number written, or one chosen as the job runs, any frame.
        self.set_frames
            .entry((user, number.flatten()))
            .or_insert((text, line.number));
    }

    /// An instruction of `//INST`: a shift begun or ended, a frame set, or a motion, whose
    /// parts (`MOVJ C00000 EC00000 VJ=10.00  +MOVJ C00001 VJ=10.00`) move the job's groups
    /// in order: the table's robot's part uses its `C` position or is reported with its
    /// reason; another robot's position is that robot's.
    fn instruction(&mut self, line: Line) {
        let src = self.src;
        let w = words(src.bytes, line.at, line.end);
        let Some(&(_, op)) = w.first() else {
            return;
        };
        let op_upper = op.to_ascii_uppercase();
        match op_upper.as_slice() {
            b"SFTON" => {
                // The instruction as written, its shift and frame (`SFTON P010 UF#(1)`).
                let text = &src.bytes[line.at..line.end];
                let what = src.text(line.at, line.at + text.trim_ascii_end().len());
                self.shift = Some((what, line.number));
                return;
            }
            b"SFTOF" => {
                self.shift = None;
                return;
            }
            b"MFRAME" => return self.frame_set(true, &w, line),
            b"SETTOOL" => return self.frame_set(false, &w, line),
            _ => {}
        }
        if !(motion_like(&op_upper) || op_upper.as_slice() == b"REFP") {
            return;
        }
        // The parts: each `+MOVJ` (or `+ MOVJ`) starts one.
        let mut parts: Vec<Vec<(usize, &[u8])>> = vec![Vec::new()];
        for &(s, t) in &w {
            if let Some(rest) = t.strip_prefix(b"+") {
                parts.push(Vec::new());
                if !rest.is_empty() {
                    parts.last_mut().expect("a part").push((s + 1, rest));
                }
            } else {
                parts.last_mut().expect("a part").push((s, t));
            }
        }
        let groups: Vec<PartGroup> = (0..parts.len()).map(|k| self.part_group(k)).collect();
        let robot_part = |k: usize| {
            matches!(groups[k], PartGroup::Table | PartGroup::OtherRobot(_))
                || parts[k].iter().skip(1).any(|(_, t)| variable(t, b"C"))
        };
        let any_robot = (0..parts.len()).any(robot_part);
        // In a job without ///GROUP lines, a second part's group is not known: the line is
        // reported as before, whole.
        let unknown_second = match (parts.get(1), groups.get(1)) {
            (Some(p), Some(PartGroup::Unknown(why))) if self.groups.is_empty() => p
                .first()
                .map(|(s, t)| (format!("+{}", src.text(*s, *s + t.len())), why.clone())),
            _ => None,
        };
        for (k, part) in parts.iter().enumerate() {
            let Some(&(op_at, op)) = part.first() else {
                continue;
            };
            let op_upper = op.to_ascii_uppercase();
            let op_name = src.text(op_at, op_at + op.len());
            let c = part.iter().skip(1).find(|(_, t)| variable(t, b"C"));
            let declared = c.and_then(|(_, t)| {
                variable_number(t, 1).and_then(|n| self.by_number.get(&n).copied())
            });
            match &groups[k] {
                PartGroup::Table => {
                    if op_upper.as_slice() != b"REFP" {
                        self.first_motion.get_or_insert(op_at);
                    }
                    let reason = match &unknown_second {
                        Some((word, why)) => {
                            Some((Reason::ExternalAxis, format!("{word}: {why} moves with it")))
                        }
                        None => self.move_reason(&op_name, &op_upper, part, c.is_some()),
                    };
                    self.table_move(op_at, &op_name, &op_upper, c.copied(), reason);
                }
                PartGroup::OtherRobot(group) | PartGroup::Unknown(group) => {
                    self.first_motion.get_or_insert(op_at);
                    let why = if matches!(groups[k], PartGroup::OtherRobot(_)) {
                        "another robot than robot 1 (RB1), the robot the table and the robot file describe".to_string()
                    } else {
                        String::new()
                    };
                    if let Some(p) = declared {
                        let (line_number, _) = src.location(op_at);
                        let detail = if why.is_empty() {
                            format!("moved by {op_name} (line {line_number}): {group}")
                        } else {
                            format!("moved by {op_name} (line {line_number}) of {group}: {why}")
                        };
                        self.positions[p]
                            .other_group
                            .get_or_insert(Refusal::new(Reason::ExternalAxis, detail));
                    }
                }
                PartGroup::NoRobot(group) => {
                    if let Some(p) = declared {
                        let (line_number, _) = src.location(op_at);
                        self.positions[p].other_group.get_or_insert(Refusal::new(
                            Reason::ExternalAxis,
                            format!("moved by {op_name} (line {line_number}) of {group}, a group without a robot"),
                        ));
                    } else if !any_robot && op_upper.as_slice() != b"REFP" {
                        // A job's station or base axis moved alone: no robot position, and
                        // not the robot's motion.
                        let axes: Vec<String> = part
                            .iter()
                            .skip(1)
                            .filter(|(_, t)| {
                                variable(t, b"EC") || variable(t, b"BC") || variable(t, b"EX")
                            })
                            .map(|(s, t)| src.text(*s, *s + t.len()))
                            .collect();
                        self.targets.push(ProgramTarget {
                            name: op_name.clone(),
                            offset: op_at,
                            kind: TargetKind::Motion,
                            uses: Vec::new(),
                            refused: Some(Refusal::new(
                                Reason::ExternalAxis,
                                format!(
                                    "{op_name} {}moves {group} alone: a station or base axis, no robot position the table corrects",
                                    if axes.is_empty() { String::new() } else { format!("{} ", axes.join(" ")) }
                                ),
                            )),
                        });
                    }
                }
            }
        }
    }

    /// The table's robot's part of a motion line: its position used, or the motion
    /// reported with `reason`.
    fn table_move(
        &mut self,
        op_at: usize,
        op_name: &str,
        op_upper: &[u8],
        c: Option<(usize, &[u8])>,
        reason: Option<(Reason, String)>,
    ) {
        let src = self.src;
        let refp = op_upper == b"REFP";
        let found = c.map(|(s, t)| {
            let p = variable_number(t, 1).and_then(|n| self.by_number.get(&n).copied());
            (s, t, p)
        });
        let refuse = |targets: &mut Vec<ProgramTarget>, reason: Reason, detail: String| {
            targets.push(ProgramTarget {
                name: op_name.to_string(),
                offset: op_at,
                kind: TargetKind::Motion,
                uses: Vec::new(),
                refused: Some(Refusal::new(reason, detail)),
            });
        };
        match (found, reason) {
            (Some((s, t, None)), _) => {
                if !refp {
                    let place = src.text(s, s + t.len());
                    refuse(
                        &mut self.targets,
                        Reason::NotDeclared,
                        format!("{op_name} {place}: not in the job's //POS section"),
                    );
                }
            }
            (Some((_, _, Some(p))), Some((reason, detail))) => {
                self.positions[p]
                    .refused_uses
                    .push(Refusal::new(reason, detail.clone()));
                if !refp {
                    refuse(&mut self.targets, reason, detail);
                }
            }
            (Some((_, _, Some(p))), None) => {
                let target = &mut self.targets[self.positions[p].target];
                // The position's frames, now used by a motion (the first).
                let own = target.offset;
                if let Some(first) = target.uses.first_mut() {
                    if first.offset == own {
                        first.offset = op_at;
                    }
                }
                // Moved to directly: corrected, whatever else moves to it.
                self.positions[p].direct = true;
            }
            (None, Some((reason, detail))) => refuse(&mut self.targets, reason, detail),
            (None, None) => {}
        }
    }

    /// Why a motion's `C` position is not corrected as moved to by it (an increment, a
    /// base axis, a variable, a shift, a reference point), or `None`. A station's axis
    /// (`EC00001`) moves the work, not the robot's frames: it leaves the robot's position
    /// as it is.
    fn move_reason(
        &self,
        op_name: &str,
        op_upper: &[u8],
        w: &[(usize, &[u8])],
        has_c: bool,
    ) -> Option<(Reason, String)> {
        let src = self.src;
        let motion = matches!(op_upper, b"MOVJ" | b"MOVL" | b"MOVC" | b"MOVS");
        let refp = op_upper == b"REFP";
        let external = w.iter().skip(1).find(|(_, t)| variable(t, b"BC"));
        let station = w
            .iter()
            .skip(1)
            .find(|(_, t)| variable(t, b"EC") || variable(t, b"EX"));
        let variable_word = w.iter().skip(1).find(|(_, t)| {
            let u = t.to_ascii_uppercase();
            variable(&u, b"P")
                || variable(&u, b"LP")
                || u.starts_with(b"P[")
                || u.starts_with(b"LP[")
        });
        let place = |s: usize, t: &[u8]| src.text(s, s + t.len());
        if op_upper.starts_with(b"IMOV") {
            Some((
                Reason::Relative,
                format!("{op_name}: an increment from where the robot stands when it runs"),
            ))
        } else if !motion && !refp {
            Some((
                Reason::UnknownMotion,
                format!("{op_name} is not a Yaskawa motion this reader corrects"),
            ))
        } else if let Some((s, t)) = external {
            Some((
                Reason::ExternalAxis,
                format!(
                    "{}: a base axis (a track) the table does not have moves the robot",
                    place(*s, t)
                ),
            ))
        } else if let (false, Some((s, t))) = (has_c, variable_word) {
            Some((
                Reason::Dynamic,
                format!(
                    "{op_name} {}: a position variable the controller holds, which the program may set as it runs",
                    place(*s, t)
                ),
            ))
        } else if let (false, Some((s, t))) = (has_c, station) {
            Some((
                Reason::ExternalAxis,
                format!(
                    "{op_name} {}: a station axis moved, no robot position the table corrects",
                    place(*s, t)
                ),
            ))
        } else if !has_c {
            Some((Reason::Dynamic, format!("{op_name}: no C position written")))
        } else if let Some((what, l)) = &self.shift {
            Some((
                Reason::Relative,
                format!(
                    "{op_name} under {what} (line {l}): a shift the controller adds as it runs"
                ),
            ))
        } else if refp {
            Some((
                Reason::UnknownMotion,
                format!("{op_name}: a reference point (weaving, a wall), not a motion target"),
            ))
        } else {
            None
        }
    }
    /// The program: a position moved to only through refused uses is refused with the
    /// first; one moved to directly is corrected.
    fn finish(mut self, truncated_at: Option<usize>) -> Program {
        // The job's robot when it is not robot 1 (`///GROUP1 RB2`): the table and the robot
        // file describe one robot, robot 1.
        let no_robot_one = !self.groups.is_empty() && !self.groups.iter().any(|g| g.robot_one);
        let foreign = no_robot_one.then(|| {
            self.groups
                .iter()
                .find_map(|g| Some((g.other_robot.as_ref()?, g)))
                .map_or_else(
                    || "the job's groups hold no robot".to_string(),
                    |(unit, g)| {
                        format!(
                            "the job moves {unit} of {}, not robot 1 (RB1), the robot the table and the robot file describe",
                            g.describe()
                        )
                    },
                )
        });
        // A base axis in the robot's group sets the base frame (and the user frames, given
        // in it) apart from the robot's by where it stands as the job runs.
        let base_axis = self
            .groups
            .iter()
            .find(|g| g.robot_one && g.base_axis)
            .map(Group::describe);
        for p in &self.positions {
            let target = &mut self.targets[p.target];
            if let Some(r) = &p.other_group {
                target.refused = Some(r.clone());
                continue;
            }
            if let (Some(why), None) = (&foreign, &target.refused) {
                target.refused = Some(Refusal::new(Reason::ExternalAxis, why.clone()));
                continue;
            }
            if let Some(u) = target.uses.first_mut() {
                if p.kind != PosType::Pulse {
                    frames_set_as_the_job_runs(&self.set_frames, p, u);
                    if let (Some(g), PosType::Base | PosType::User) = (&base_axis, p.kind) {
                        let what = if p.kind == PosType::Base {
                            "POSTYPE BASE"
                        } else {
                            "POSTYPE USER (a user frame given in the base frame)"
                        };
                        u.base = None;
                        u.undeclared.retain(|d| !d.base);
                        u.unknown.push(format!(
                            "{what} in a job whose group {g} has a base axis: the base frame stands where the base axis puts it as the job runs"
                        ));
                    }
                }
            }
            if p.direct {
                continue;
            }
            if let Some(r) = p.refused_uses.first() {
                if target.refused.is_none() {
                    target.refused = Some(Refusal::new(
                        r.reason,
                        format!("moved to only as {}", r.detail),
                    ));
                }
            }
        }
        Program {
            format: Format::Yaskawa,
            targets: self.targets,
            truncated_at,
            first_motion: self.first_motion,
            in_partner: Vec::new(),
        }
    }
}

/// A position's frames the job sets as it runs (`MFRAME UF#(1) …`, `SETTOOL TL#(2) …`):
/// the controller's tool file and user frame file hold the value set, in this run and the
/// next, so every use of the position is in a frame no option gives.
fn frames_set_as_the_job_runs(set_frames: &SetFrames, p: &Position, u: &mut FrameUse) {
    let user = match (p.kind, p.user) {
        (PosType::User, Some(n)) => Some(n),
        _ => None,
    };
    let sets = [
        user.map(|n| (true, n, format!("USER {n}"))),
        Some((false, p.tool, format!("TOOL {}", p.tool))),
    ];
    for (is_user, n, what) in sets.into_iter().flatten() {
        let set = set_frames
            .get(&(is_user, Some(n)))
            .or_else(|| set_frames.get(&(is_user, None)));
        let Some((text, line)) = set else {
            continue;
        };
        if is_user {
            u.base = None;
        } else {
            u.tool = None;
        }
        u.undeclared.retain(|d| d.base != is_user);
        u.unknown.push(format!(
            "{what} is set as the job runs: {text} (line {line})"
        ));
    }
}

/// Whether an instruction starts as a motion does (`MOVJ`, `IMOV`, `SMOVL`, `EIMOVL`…).
fn motion_like(op_upper: &[u8]) -> bool {
    op_upper.starts_with(b"MOV")
        || op_upper.starts_with(b"IMOV")
        || op_upper.starts_with(b"SMOV")
        || op_upper.starts_with(b"EIMOV")
        || op_upper.starts_with(b"SYMOV")
}

/// A position's values: numbers separated by commas, to the end of the line.
fn values(src: &Source, from: usize, end: usize) -> Result<Vec<Number>, Error> {
    let bytes = src.bytes;
    let mut numbers: Vec<Number> = Vec::new();
    let mut i = from;
    loop {
        i = src.skip_blanks(i).min(end);
        let n = parse_number(&bytes[..end], i)
            .ok_or_else(|| src.error(i, format!("expected a number, found {}", src.describe(i))))?;
        numbers.push(n);
        i = src.skip_blanks(n.span.1).min(end);
        if i >= end {
            break;
        }
        if bytes[i] != b',' {
            return Err(src.error(
                i,
                format!(
                    "expected ',' or the end of the line, found {}",
                    src.describe(i)
                ),
            ));
        }
        i += 1;
        if numbers.len() > crate::bounds::MAX_JOINTS {
            return Err(src.error(i, format!("more than {} values", crate::bounds::MAX_JOINTS)));
        }
    }
    Ok(numbers)
}

/// `///RCONF l,m,n,o,p,q[,…]` (after `RCONF`, `from..end`), as Yaskawa's job data format
/// gives it: `l` 0 flip, 1 no flip; `m` 0 upper arm, 1 lower arm; `n` 0 front, 1 rear;
/// `o`, `p`, `q` the R, T and S axes under 180° (0) or at 180° or more (1); the fields
/// after them unused (0) on the controllers whose format this reader knows. Anything else
/// is [`ConfigHint::Unreadable`]: a field out of range, missing, or set that this reader
/// does not map.
fn rconf(bytes: &[u8], from: usize, end: usize) -> ConfigHint {
    let mut fields: Vec<((usize, usize), Option<i64>)> = Vec::new();
    let mut i = from;
    while i <= end {
        let stop = bytes[i..end]
            .iter()
            .position(|b| *b == b',')
            .map_or(end, |p| i + p);
        let (mut s, mut e) = (i, stop);
        while s < e && matches!(bytes[s], b' ' | b'\t') {
            s += 1;
        }
        while e > s && matches!(bytes[e - 1], b' ' | b'\t') {
            e -= 1;
        }
        let value = std::str::from_utf8(&bytes[s..e])
            .ok()
            .and_then(|t| t.parse::<i64>().ok());
        fields.push(((s, e), value));
        i = stop + 1;
    }
    if fields.len() < 6 {
        let span = fields.last().map_or((end, end), |f| f.0);
        return ConfigHint::Unreadable {
            span: (span.1, span.1),
            expected: "///RCONF has six fields or more (flip, arm, front, R, T, S)",
        };
    }
    let mut bit = [false; 6];
    for (k, (span, value)) in fields.iter().enumerate() {
        let expected = if k < 6 {
            "a ///RCONF field is 0 or 1"
        } else {
            "a ///RCONF field after the sixth is 0 (unused), a setting this reader does not map"
        };
        match value {
            Some(0) => {}
            Some(1) if k < 6 => bit[k] = true,
            _ => {
                return ConfigHint::Unreadable {
                    span: *span,
                    expected,
                }
            }
        }
    }
    ConfigHint::YaskawaRconf {
        no_flip: bit[0],
        lower_arm: bit[1],
        rear: bit[2],
        at_least_180: [bit[3], bit[4], bit[5]],
    }
}

/// What a position takes from the `///` lines above it.
#[derive(Clone, Copy)]
struct Frames {
    kind: PosType,
    tool: u16,
    user: Option<(u16, usize)>,
    config: ConfigHint,
}

/// A `C` position's target: what it is, why it is refused, and its frames.
fn position(
    options: &YaskawaOptions,
    numbers: &[Number],
    frames: Frames,
    at: usize,
) -> (TargetKind, Option<Refusal>, Vec<FrameUse>) {
    let Frames {
        kind,
        tool,
        user,
        config,
    } = frames;
    if kind == PosType::Pulse {
        let target = match &options.pulses_per_deg {
            None => TargetKind::Incomplete(
                "a PULSE position: its encoder pulses need the robot's pulses per degree per axis, which no option gives (--yaskawa-pulses-per-deg a,b,c,d,e,f)".into(),
            ),
            Some(per) if per.len() != numbers.len() => TargetKind::Incomplete(format!(
                "{} pulse values, and pulses per degree for {} axes",
                numbers.len(),
                per.len()
            )),
            Some(per) => TargetKind::Joints(JointTarget {
                joints: numbers
                    .iter()
                    .zip(per)
                    .map(|(n, p)| Number {
                        value: n.value / p,
                        ..*n
                    })
                    .collect(),
                unit: AngleUnit::Degree,
            }),
        };
        return (target, None, Vec::new());
    }
    let mut refused = None;
    let target = if numbers.len() != 6 {
        if numbers.len() == 7 {
            refused = Some(Refusal::new(
                Reason::ExternalAxis,
                "a seventh value (Re, a seven-axis arm's elbow), beyond the six the table's robot has",
            ));
        }
        TargetKind::Incomplete(format!(
            "{} values: a Cartesian position is X, Y, Z, Rx, Ry, Rz",
            numbers.len()
        ))
    } else {
        TargetKind::Cartesian(Box::new(CartesianTarget {
            position: [numbers[0], numbers[1], numbers[2]],
            unit: LengthUnit::Millimetre,
            orientation: Some(Orientation::KukaAbcDeg([
                numbers[5], numbers[4], numbers[3],
            ])),
            config,
            joints: Vec::new(),
        }))
    };
    let mut frame = FrameUse {
        tool: None,
        base: None,
        offset: at,
        elsewhere: None,
        note: None,
        undeclared: Vec::new(),
        unknown: Vec::new(),
    };
    match options.tools.iter().find(|t| t.0 == tool) {
        Some((_, f)) => frame.tool = Some(pose(f)),
        None => frame.undeclared.push(Undeclared {
            base: false,
            name: format!("TOOL {tool}"),
        }),
    }
    match kind {
        PosType::Robot | PosType::Base => frame.base = Some(Isometry3::identity()),
        PosType::User => match user {
            None => frame
                .unknown
                .push("///POSTYPE USER with no ///USER line before it".into()),
            Some((n, _)) => match options.users.iter().find(|u| u.0 == n) {
                Some((_, f)) => frame.base = Some(pose(f)),
                None => frame.undeclared.push(Undeclared {
                    base: true,
                    name: format!("USER {n}"),
                }),
            },
        },
        PosType::Tool => frame.unknown.push(
            "POSTYPE TOOL: a position in the tool's frame, where the robot stands when it runs"
                .into(),
        ),
        PosType::MasterTool => frame
            .unknown
            .push("POSTYPE MTOOL: a position in a stationary (external) tool's frame".into()),
        PosType::Pulse => {}
    }
    (target, refused, vec![frame])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options() -> YaskawaOptions {
        YaskawaOptions {
            tools: vec![(1, [0.0, 0.0, 180.0, 0.0, 0.0, 0.0])],
            users: vec![(1, [1600.0, 250.0, 750.0, 0.0, 0.0, 30.0])],
            pulses_per_deg: None,
        }
    }

    fn statuses(p: &Program) -> Vec<(String, &'static str)> {
        p.targets
            .iter()
            .map(|t| {
                (
                    t.name.clone(),
                    match (&t.refused, &t.kind) {
                        (Some(r), _) => r.reason.as_str(),
                        (None, TargetKind::Incomplete(_)) => "incomplete",
                        (None, TargetKind::Cartesian(_)) => "cartesian",
                        (None, TargetKind::Joints(_)) => "joints",
                        (None, TargetKind::Motion) => "motion",
                    },
                )
            })
            .collect()
    }

    const JOB: &str = "/JOB\r\n//NAME T\r\n//POS\r\n///NPOS 4,0,0,0,0,0\r\n///TOOL 1\r\n\
        ///POSTYPE PULSE\r\n///PULSE\r\nC00000=1000,-2000,3000,0,0,0\r\n///POSTYPE ROBOT\r\n///RECTAN\r\n\
        ///RCONF 0,0,0,0,0,0,0,0\r\nC00001=1950.000,380.000,1300.000,10.0000,80.0000,-5.0000\r\n\
        ///USER 1\r\n///POSTYPE USER\r\n///RECTAN\r\nC00002=300.000,100.000,450.000,0.0000,90.0000,-30.0000\r\n\
        ///USER 3\r\nC00003=1.000,2.000,3.000,0.0000,0.0000,0.0000\r\n//INST\r\n///DATE 2026/11/20 14:32\r\n\
        ///ATTR SC,RW\r\n///GROUP1 RB1\r\nNOP\r\n'A COMMENT MOVL C00009\r\nMOVJ C00000 VJ=25.00\r\n\
        MOVL C00001 V=100.0 PL=0\r\nSFTON P001\r\nMOVL C00002 V=50.0\r\nSFTOF\r\nIMOV P002 V=10.0\r\n\
        MOVL P003 V=10.0\r\nMOVL C00003 BC00000 V=10.0\r\nMOVL C00007 V=10.0\r\nSMOVL C00001 V=10.0\r\nEND\r\n";

    #[test]
    fn rconf_holds_for_the_positions_after_it_and_is_read_field_by_field() {
        let job = |rconf: &str| {
            format!(
                "/JOB\r\n//POS\r\n///NPOS 3,0,0,0,0,0\r\n///TOOL 1\r\n///POSTYPE ROBOT\r\n///RECTAN\r\n\
                 C00000=1.000,2.000,3.000,0.0000,90.0000,0.0000\r\n{rconf}\r\n\
                 C00001=1.000,2.000,3.000,0.0000,90.0000,0.0000\r\n\
                 C00002=1.000,2.000,3.000,0.0000,90.0000,0.0000\r\n//INST\r\nNOP\r\nEND\r\n"
            )
        };
        let configs = |rconf: &str| -> Vec<ConfigHint> {
            let text = job(rconf);
            let p = read(&Source::new("t.jbi", text.as_bytes()), &options()).unwrap();
            p.targets
                .iter()
                .map(|t| match &t.kind {
                    TargetKind::Cartesian(c) => c.config,
                    other => panic!("{other:?}"),
                })
                .collect()
        };
        // Before any ///RCONF nothing is written; after it, every position takes it.
        let written = ConfigHint::YaskawaRconf {
            no_flip: true,
            lower_arm: false,
            rear: true,
            at_least_180: [false, true, false],
        };
        assert_eq!(
            configs("///RCONF 1,0,1,0,1,0,0,0"),
            [ConfigHint::None, written, written]
        );
        // The six fields of an older controller's job alone.
        assert_eq!(configs("///RCONF 1,0,1,0,1,0")[1], written);
        // A field out of range, a field beyond the sixth set, or too few: unreadable,
        // located at the field.
        let unreadable = |rconf: &str| -> (String, &'static str) {
            let text = job(rconf);
            match configs(rconf)[1] {
                ConfigHint::Unreadable { span, expected } => {
                    (text[span.0..span.1].to_string(), expected)
                }
                other => panic!("{rconf}: {other:?}"),
            }
        };
        assert_eq!(
            unreadable("///RCONF 0,2,0,0,0,0,0,0"),
            ("2".to_string(), "a ///RCONF field is 0 or 1")
        );
        assert_eq!(
            unreadable("///RCONF 0,0,0,0,0,0,1,0"),
            (
                "1".to_string(),
                "a ///RCONF field after the sixth is 0 (unused), a setting this reader does not map"
            )
        );
        assert_eq!(unreadable("///RCONF 0,0,x,0,0,0").0, "x".to_string());
        assert_eq!(
            unreadable("///RCONF 0,0,0").1,
            "///RCONF has six fields or more (flip, arm, front, R, T, S)"
        );
    }

    #[test]
    fn positions_take_their_frames_and_every_move_is_accounted_for() {
        let p = read(&Source::new("t.jbi", JOB.as_bytes()), &options()).unwrap();
        let s: Vec<&str> = statuses(&p).into_iter().map(|s| s.1).collect();
        assert_eq!(
            s,
            [
                "incomplete",     // C00000: pulses, no pulses per degree given
                "cartesian",      // C00001
                "relative",       // C00002: moved to only under SFTON
                "external_axis",  // C00003: moved to only with a base axis
                "relative",       // MOVL C00002 under SFTON
                "relative",       // IMOV
                "dynamic",        // MOVL P003
                "external_axis",  // MOVL C00003 BC00000
                "not_declared",   // MOVL C00007
                "unknown_motion", // SMOVL
            ]
        );
        // Rx, Ry, Rz about fixed x, y, z: KUKA's A, B, C are Rz, Ry, Rx.
        let TargetKind::Cartesian(c) = &p.targets[1].kind else {
            unreachable!()
        };
        let Some(Orientation::KukaAbcDeg(abc)) = c.orientation else {
            unreachable!()
        };
        assert_eq!(abc.map(|n| n.value), [-5.0, 80.0, 10.0]);
        // Robot frame: the base frame; the torch of tool 1; user frame 1 from the options.
        let u = &p.targets[1].uses[0];
        assert_eq!(u.base, Some(Isometry3::identity()));
        assert_eq!(u.tool, Some(pose(&[0.0, 0.0, 180.0, 0.0, 0.0, 0.0])));
        assert_eq!(u.offset, JOB.find("MOVL C00001").unwrap());
        let u = &p.targets[2].uses[0];
        assert_eq!(u.base, Some(pose(&[1600.0, 250.0, 750.0, 0.0, 0.0, 30.0])));
        assert!(p.targets[2]
            .refused
            .as_ref()
            .unwrap()
            .detail
            .contains("under SFTON P001 (line 27)"));
        // User frame 3 is not given: named.
        assert_eq!(
            p.targets[3].uses[0].undeclared,
            vec![Undeclared {
                base: true,
                name: "USER 3".into()
            }]
        );
        assert_eq!(p.first_motion, JOB.find("MOVJ C00000"));
    }

    /// A job's targets and, for each, its status and detail (a frame not known counted as
    /// `frame_unknown`).
    fn report(text: &str) -> Vec<(String, String, String)> {
        let p = read(&Source::new("t.jbi", text.as_bytes()), &options()).unwrap();
        p.targets
            .iter()
            .zip(statuses(&p))
            .map(|(t, (name, status))| {
                let unknown = t
                    .uses
                    .first()
                    .map(|u| u.unknown.join("; "))
                    .unwrap_or_default();
                match (&t.refused, unknown.is_empty()) {
                    (Some(r), _) => (name, status.to_string(), r.detail.clone()),
                    (None, false) => (name, "frame_unknown".to_string(), unknown),
                    (None, true) => (name, status.to_string(), String::new()),
                }
            })
            .collect()
    }

    #[test]
    fn another_robot_groups_positions_are_that_robots() {
        // Two robots and a station, as the pendant saves such a job: each line moves group
        // 1 (RB1 and its station) and, after `+`, group 2 (RB2).
        let job = "/JOB\r\n//NAME R1-R2-S1\r\n//POS\r\n///NPOS 4,0,2,0,0,0\r\n///TOOL 0\r\n\
            ///POSTYPE ROBOT\r\n///RECTAN\r\n///RCONF 0,0,0,0,0,0,0,0\r\n\
            C00000=1900.000,300.000,1200.000,0.0000,90.0000,0.0000\r\n///TOOL 1\r\n\
            C00001=1910.000,285.000,1205.000,0.0000,90.0000,0.0000\r\n///TOOL 0\r\n\
            C00002=1920.000,270.000,1210.000,0.0000,90.0000,0.0000\r\n///TOOL 1\r\n\
            C00003=1930.000,255.000,1215.000,0.0000,90.0000,0.0000\r\n///TOOL 0\r\n///POSTYPE PULSE\r\n\
            ///PULSE\r\nEC00000=-28898,221232\r\nEC00001=10741,151008\r\n//INST\r\n\
            ///DATE 2023/02/06 16:23\r\n///ATTR SC,RW\r\n///GROUP1 RB1,ST1\r\n///GROUP2 RB2\r\nNOP\r\n\
            MOVJ C00000 EC00000 VJ=10.00  +MOVJ C00001 VJ=10.00\r\n\
            MOVL C00002 EC00001 V=11.0  +MOVL C00003 V=11.0\r\nEND\r\n";
        let r = report(job);
        let s: Vec<&str> = r.iter().map(|t| t.1.as_str()).collect();
        // Robot 1's positions are corrected, its station's axis beside them moving the work,
        // not the robot; robot 2's are robot 2's.
        assert_eq!(
            s,
            ["cartesian", "external_axis", "cartesian", "external_axis"]
        );
        assert_eq!(
            r[1].2,
            "moved by MOVJ (line 27) of ///GROUP2 RB2 (line 25): another robot than robot 1 (RB1), the robot the table and the robot file describe"
        );
        // A job whose only robot is robot 2: none of its positions is the table's robot's.
        let r2 = job
            .replace(
                "///GROUP1 RB1,ST1\r\n///GROUP2 RB2\r\n",
                "///GROUP1 RB2\r\n",
            )
            .replace("  +MOVJ C00001 VJ=10.00", "")
            .replace("  +MOVL C00003 V=11.0", "");
        let r = report(&r2);
        assert!(r.iter().all(|t| t.1 == "external_axis"), "{r:?}");
        assert!(
            r[0].2.contains("of ///GROUP1 RB2 (line 24): another robot"),
            "{}",
            r[0].2
        );
        assert!(
            r[1].2
                .starts_with("the job moves RB2 of ///GROUP1 RB2 (line 24), not robot 1 (RB1)"),
            "{}",
            r[1].2
        );
    }

    #[test]
    fn a_station_moved_alone_is_no_robot_motion() {
        let job = "/JOB\r\n//NAME S1-MOV\r\n//POS\r\n///NPOS 0,0,2,0,0,0\r\n///TOOL 0\r\n\
            ///POSTYPE PULSE\r\n///PULSE\r\nEC00000=-28898,221232\r\nEC00001=70924,108240\r\n//INST\r\n\
            ///DATE 2023/02/06 16:42\r\n///ATTR SC,RW\r\n///GROUP1 ST1\r\nNOP\r\n\
            MOVJ EC00000 VJ=10.00\r\nMOVJ EC00001 VJ=10.00\r\nEND\r\n";
        let p = read(&Source::new("t.jbi", job.as_bytes()), &options()).unwrap();
        // Not a robot's motion: the job is not said to move the robot.
        assert_eq!(p.first_motion, None);
        let r = report(job);
        assert_eq!(r.len(), 2);
        assert_eq!(
            r[0].2,
            "MOVJ EC00000 moves ///GROUP1 ST1 (line 13) alone: a station or base axis, no robot position the table corrects"
        );
    }

    #[test]
    fn frames_the_job_sets_as_it_runs_are_not_known() {
        // As RoboDK's Motoman post writes a job: the user frame and the tool set by the job.
        let job = "/JOB\r\n//NAME PROG1\r\n//POS\r\n///NPOS 3,0,0,0,0,0\r\n///USER 1\r\n///TOOL 1\r\n\
            ///POSTYPE USER\r\n///RECTAN\r\n///RCONF 0,0,0,0,0,0,0,0\r\n\
            C00000=300.000,100.000,450.000,0.00,90.00,-30.00\r\n///TOOL 2\r\n///POSTYPE ROBOT\r\n\
            C00001=1900.000,300.000,1200.000,0.0000,90.0000,0.0000\r\n///TOOL 1\r\n\
            C00002=1910.000,285.000,1205.000,0.0000,90.0000,0.0000\r\n//INST\r\n///DATE 2024/01/10 10:00\r\n\
            ///COMM Generated using RoboDK\r\n///ATTR SC,RW,RJ\r\n///FRAME USER 1\r\n///GROUP1 RB1\r\nNOP\r\n\
            SETE P00095 (1) 1600000\r\nMFRAME UF#(1) P00095 P00096 P00097\r\nSETE P00095 (3) 180000\r\n\
            SETTOOL TL#(2) P00095\r\nMOVL C00000 V=100.0 PL=0\r\nMOVL C00001 V=100.0 PL=0\r\n\
            MOVL C00002 V=100.0 PL=0\r\nEND\r\n";
        let r = report(job);
        assert_eq!(
            r.iter().map(|t| t.1.as_str()).collect::<Vec<_>>(),
            ["frame_unknown", "frame_unknown", "cartesian"]
        );
        assert_eq!(
            r[0].2,
            "USER 1 is set as the job runs: MFRAME UF#(1) P00095 P00096 P00097 (line 24)"
        );
        assert_eq!(
            r[1].2,
            "TOOL 2 is set as the job runs: SETTOOL TL#(2) P00095 (line 26)"
        );
        // A frame number chosen as the job runs may be any.
        let r = report(&job.replace("TL#(2)", "TL#(I001)"));
        assert_eq!(r[2].1, "frame_unknown");
    }

    #[test]
    fn a_base_axis_sets_the_base_frame_apart() {
        let job = "/JOB\r\n//NAME TRACK\r\n//POS\r\n///NPOS 2,1,0,0,0,0\r\n///TOOL 1\r\n\
            ///POSTYPE BASE\r\n///RECTAN\r\n///RCONF 0,0,0,0,0,0,0,0\r\n\
            C00000=1900.000,300.000,1200.000,0.0000,90.0000,0.0000\r\n///POSTYPE ROBOT\r\n\
            C00001=1910.000,285.000,1205.000,0.0000,90.0000,0.0000\r\n///POSTYPE PULSE\r\n///PULSE\r\n\
            BC00000=500000\r\n//INST\r\n///DATE 2024/01/10 10:00\r\n///ATTR SC,RW\r\n///GROUP1 RB1,BS1\r\n\
            NOP\r\nMOVJ C00001 BC00000 VJ=50.00\r\nMOVL C00000 V=100.0\r\nMOVL C00001 V=100.0\r\nEND\r\n";
        let r = report(job);
        assert_eq!(r[0].1, "frame_unknown");
        assert!(
            r[0].2.starts_with(
                "POSTYPE BASE in a job whose group ///GROUP1 RB1,BS1 (line 18) has a base axis"
            ),
            "{}",
            r[0].2
        );
        // In the robot's own frame the position stands with the robot.
        assert_eq!(r[1].1, "cartesian");
        // Without the base axis in the group, the base frame is the robot's.
        let r = report(&job.replace("RB1,BS1", "RB1"));
        assert_eq!(r[0].1, "cartesian");
    }

    #[test]
    fn pulses_are_degrees_by_the_options_pulses_per_degree() {
        let mut o = options();
        o.pulses_per_deg = Some(vec![100.0, -200.0, 1000.0, 1.0, 1.0, 1.0]);
        let p = read(&Source::new("t.jbi", JOB.as_bytes()), &o).unwrap();
        let TargetKind::Joints(j) = &p.targets[0].kind else {
            panic!("{:?}", p.targets[0].kind)
        };
        assert_eq!(
            j.joints.iter().map(|n| n.value).collect::<Vec<_>>(),
            [10.0, 10.0, 3.0, 0.0, 0.0, 0.0]
        );
        // Written back as whole pulses, kept within half a pulse.
        let n = j.joints[1];
        assert_eq!(pulse_text(&n, b"-2000", 10.001, -200.0), None);
        assert_eq!(
            pulse_text(&n, b"-2000", 10.5, -200.0).as_deref(),
            Some("-2100")
        );
        o.pulses_per_deg = Some(vec![100.0; 5]);
        let p = read(&Source::new("t.jbi", JOB.as_bytes()), &o).unwrap();
        let TargetKind::Incomplete(why) = &p.targets[0].kind else {
            unreachable!()
        };
        assert_eq!(why, "6 pulse values, and pulses per degree for 5 axes");
    }

    #[test]
    fn malformed_lines_are_located() {
        let err = |text: &str| {
            read(&Source::new("t.jbi", text.as_bytes()), &options())
                .unwrap_err()
                .to_string()
        };
        let head = "/JOB\n//NAME T\n//POS\n///NPOS 1,0,0,0,0,0\n///POSTYPE ROBOT\n";
        assert_eq!(
            err(&format!("{head}C00001=1.0,2.0,x,0,0,0\n")),
            "t.jbi:6:16: expected a number, found 'x,0,0,0'"
        );
        assert_eq!(
            err(&format!("{head}C00001=1.0 2.0\n")),
            "t.jbi:6:12: expected ',' or the end of the line, found '2.0'"
        );
        assert_eq!(
            err(&format!("{head}Q00001=1.0\n")),
            "t.jbi:6:1: 'Q00001' is not a position variable (C, BC, EC, P, BP, EX and digits)"
        );
        assert_eq!(
            err("/JOB\n//POS\nC00001=1,2,3,4,5,6\n"),
            "t.jbi:3:1: a position before any ///POSTYPE line: its frame is not known"
        );
        assert_eq!(
            err("/JOB\n//POS\n///POSTYPE JOINT\n"),
            "t.jbi:3:12: ///POSTYPE is PULSE, BASE, ROBOT, USER, TOOL or MTOOL"
        );
        assert_eq!(
            err("/JOB\n//POS\n///TOOL x\n"),
            "t.jbi:3:9: ///TOOL needs its number, 0-65535"
        );
    }

    #[test]
    fn options_parse_as_the_command_line_writes_them() {
        assert_eq!(
            parse_numbered_frame("2=1,2,3,0,90,0").unwrap(),
            (2, [1.0, 2.0, 3.0, 0.0, 90.0, 0.0])
        );
        assert!(parse_numbered_frame("2=1,2,3").is_err());
        assert!(parse_numbered_frame("x=1,2,3,4,5,6").is_err());
        assert!(parse_numbered_frame("1=1,2,3,4,5,nan").is_err());
        assert_eq!(parse_pulses_per_deg("1,-2.5").unwrap(), [1.0, -2.5]);
        assert!(parse_pulses_per_deg("1,0").is_err());
        assert!(parse_pulses_per_deg("1,inf").is_err());
        assert!(parse_pulses_per_deg("").is_err());
    }
}
