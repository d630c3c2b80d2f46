//! G-code (ISO 6983, RS-274) for robotic machining: `.nc`, `.ngc`, `.gcode`, `.tap`.
//!
//! A block is a line of words, a letter and a number each (`N10 G1 X1500.25 Y200 Z980
//! F800`); `( … )` and `; …` are comments, `%` a tape mark, `/` a block-delete mark, all
//! kept byte for byte. The targets are the end points of `G0`, `G1`, `G2` and `G3` in
//! absolute mode (`G90`): X, Y, Z in the unit `G21` (mm) or `G20` (inches) sets, and, where
//! the program writes them, A, B, C — the tool's orientation in the convention
//! [`AbcConvention`] names. An axis not written keeps its value (modal), and a block is
//! corrected only when it writes X, Y and Z itself: the compensated program changes only
//! numbers, so a block that leaves one of them to the previous block is reported
//! `incomplete`, naming it (writing the missing word would change the block's bytes, and
//! the value it inherits is the previous block's *corrected* one). A, B and C may be
//! modal: a block that does not write them is corrected when the correction does not turn
//! the tool (a position-only table) and the block that wrote them was not rewritten.
//!
//! Arcs (`G2` clockwise, `G3` counter-clockwise, seen from the plane's normal: `G17` XY,
//! `G18` ZX, `G19` YZ) with their centre as `I J K` (from the start, or absolute after
//! `G90.1`) or as a radius `R` are corrected by their end point, with the centre moved so
//! that the corrected arc stays within a tolerance of the corrected path ([`Arc`]).
//!
//! Every other motion is reported where it is written, never skipped: `G91` incremental
//! moves (`relative`), `G28`/`G30` returns and `G53` machine coordinates, moves under
//! cutter compensation (`G41`/`G42`), a tool length offset (`G43`), a rotation (`G68`),
//! a scaling, polar coordinates or an offset the program sets as it runs (`G51`, `G16`,
//! `G52`, `G92`, `G10`), canned cycles (`G73`-`G89`), and any other motion-looking code.
//! A `G92` or `G52` that names none of X, Y, Z, A, B, C (a slicer's `G92 E0`) offsets
//! axes the reader does not read, and leaves the moves' frame as it was.
//! `G54`-`G59` select a work offset, which the job's options give; a move in one they do
//! not give is refused by its name (`frame_unknown`).
//!
//! The program is read as the controller runs it where that changes a move's modes: a
//! subprogram's body (`M98`, `M97`, `G65`, LinuxCNC `o… sub`) is not corrected, naming its
//! call, and a call leaves unknown the modes the called program may set; where jumps and
//! loops (`GOTO`, `IF`, `WHILE`/`DO`/`END`), a block-delete block, a G code computed,
//! a system variable written, `G70`/`G71` or a second tool make a mode unknown, the moves
//! in it are reported by that mode, naming what made it so, until the program sets it.

use crate::number::{parse_number, Number};
use crate::program::{
    CartesianTarget, ConfigHint, Format, LengthUnit, Orientation, Program, ProgramTarget, Reason,
    Refusal, TargetKind,
};
use std::collections::HashMap;

use crate::source::Source;
use crate::Error;

/// The default tolerance of a corrected arc against the corrected path, mm.
pub const DEFAULT_ARC_TOLERANCE_MM: f64 = 0.01;

/// How a program's A, B, C (degrees) write the tool's orientation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AbcConvention {
    /// KUKA's: `R = Rz(A)·Ry(B)·Rx(C)` (as KRL and the job's frame options write it).
    #[default]
    Kuka,
    /// Fixed-axis rotations about x by A, then y by B, then z by C: `R = Rz(C)·Ry(B)·Rx(A)`.
    FixedXyz,
}

impl AbcConvention {
    /// The name the command line takes (`kuka`, `xyz`).
    pub fn name(self) -> &'static str {
        match self {
            AbcConvention::Kuka => "kuka",
            AbcConvention::FixedXyz => "xyz",
        }
    }

    /// The convention of a name as [`AbcConvention::name`] gives it.
    pub fn from_name(name: &str) -> Option<AbcConvention> {
        [AbcConvention::Kuka, AbcConvention::FixedXyz]
            .into_iter()
            .find(|c| c.name() == name)
    }
}

/// What a G-code program needs beyond its text.
#[derive(Clone, Debug, PartialEq)]
pub struct GcodeOptions {
    /// The convention of A, B, C.
    pub abc: AbcConvention,
    /// The work offsets `G54`-`G59`: the number (54-59) and the frame in the robot's base
    /// frame, `[X, Y, Z, A, B, C]` (mm, KUKA degrees, as the job's `base` option).
    pub work_offsets: Vec<(u8, [f64; 6])>,
    /// How far a corrected arc may lie from the corrected path, mm.
    pub arc_tolerance_mm: f64,
}

impl Default for GcodeOptions {
    fn default() -> GcodeOptions {
        GcodeOptions {
            abc: AbcConvention::Kuka,
            work_offsets: Vec::new(),
            arc_tolerance_mm: DEFAULT_ARC_TOLERANCE_MM,
        }
    }
}

/// Parses a work offset as the command line writes it: `G54=X,Y,Z` or `G54=X,Y,Z,A,B,C`.
///
/// # Errors
///
/// A message saying what is wrong.
pub fn parse_work_offset(text: &str) -> Result<(u8, [f64; 6]), String> {
    let usage = "a work offset is G54..G59=X,Y,Z[,A,B,C] (mm, KUKA degrees)";
    let (name, values) = text.split_once('=').ok_or_else(|| usage.to_string())?;
    let number = name
        .trim()
        .strip_prefix(['G', 'g'])
        .and_then(|n| n.parse::<u8>().ok())
        .filter(|n| (54..=59).contains(n))
        .ok_or_else(|| format!("'{}': {usage}", name.trim()))?;
    Ok((number, crate::bounds::option_frame(values, usage)?))
}

/// The plane of an arc: its two in-plane axes (u, v) and its normal, as indices of X, Y, Z.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plane {
    /// `G17`: X, Y about Z.
    Xy,
    /// `G18`: Z, X about Y.
    Zx,
    /// `G19`: Y, Z about X.
    Yz,
}

impl Plane {
    /// (u, v, normal), indices of X, Y, Z.
    pub fn axes(self) -> [usize; 3] {
        match self {
            Plane::Xy => [0, 1, 2],
            Plane::Zx => [2, 0, 1],
            Plane::Yz => [1, 2, 0],
        }
    }
}

/// How an arc writes its centre.
#[derive(Clone, Copy, Debug)]
pub enum Centre {
    /// `I J K` of the plane's two axes (u, v), as written (`None`: not written, 0); from the
    /// start, or absolute (`G90.1`).
    Offsets {
        /// The numbers of the u and v axes' offsets.
        numbers: [Option<Number>; 2],
        /// Absolute (`G90.1`) rather than from the start.
        absolute: bool,
    },
    /// `R`: the radius, negative for more than a half turn.
    Radius(Number),
}

/// An arc whose end point is a target: what the job needs to move its centre.
#[derive(Clone, Debug)]
pub struct Arc {
    /// `G2`.
    pub clockwise: bool,
    /// Its plane.
    pub plane: Plane,
    /// The target whose end point is the arc's start.
    pub start_target: usize,
    /// The start, mm, in the program's frame.
    pub start_mm: [f64; 3],
    /// The centre's u, v, mm.
    pub centre_mm: [f64; 2],
    /// How the centre is written.
    pub centre: Centre,
    /// Millimetres per program unit.
    pub unit_mm: f64,
}

/// A G-code program read: its targets, and per target the arc it ends, if any.
#[derive(Clone, Debug)]
pub struct Read {
    /// The program.
    pub program: Program,
    /// Per target (same order), its arc.
    pub arcs: Vec<Option<Box<Arc>>>,
    /// Per target, the work offset it is commanded in (54-59, one the options give), 0 for
    /// none (the job's base): kept beside the targets, whose own frame uses stay empty, so
    /// that a long program's targets take no frame list each.
    pub work_offsets: Vec<u8>,
}

/// A word's value: a number, or an expression (`#1`, `[#2+1]`) known when the program runs.
#[derive(Clone, Copy, Debug)]
enum Value {
    Number(Number),
    Expression,
}

#[derive(Clone, Copy, Debug)]
struct Word {
    letter: u8,
    at: usize,
    value: Value,
}

/// A statement a line holds beyond its words (Fanuc custom macro B, LinuxCNC o-words).
#[derive(Clone, Debug)]
enum Statement {
    /// `#1 = 2`, `#5221 = 100.`, `IF [#1 EQ 0] THEN #2 = 1`: whether the variable may be a
    /// system variable (#1000 and above, or an index computed as the program runs), and
    /// where it is written.
    Assignment { system: bool, at: usize },
    /// `GOTO 10`, `IF [#1 EQ 0] GOTO 20`: the label's number (`None`: computed).
    Jump {
        label: Option<u32>,
        conditional: bool,
    },
    /// `WHILE [#1 LT 5] DO1`, `DO1`: a loop's start, by its number.
    Do { id: u32 },
    /// `END1`: a loop's end.
    End { id: u32 },
    /// LinuxCNC `o100 sub`, `o<name> endsub`, `o100 call`, `o100 return`: the o-word (lower
    /// case) and its keyword (upper case).
    OWord {
        name: String,
        keyword: String,
        at: usize,
    },
}

/// A line read: its words, the statement after them, and whether it is a block-delete
/// (`/`) block.
#[derive(Default)]
struct Parsed {
    words: Vec<Word>,
    statement: Option<Statement>,
    deleted: bool,
}

/// A whole, non-negative number (a label, a program number), `None` beyond.
fn whole(n: &Number) -> Option<u32> {
    (n.value >= 0.0 && n.value < 1e9 && n.value.fract() == 0.0).then_some(n.value as u32)
}

/// Text as messages quote it: control characters escaped, quotes as written.
fn shown(text: String) -> String {
    if !text.chars().any(char::is_control) {
        return text;
    }
    text.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

/// The end of the letters from `i` (before `end`).
fn letters_end(bytes: &[u8], i: usize, end: usize) -> usize {
    let mut j = i;
    while j < end && bytes[j].is_ascii_alphabetic() {
        j += 1;
    }
    j
}

/// After the bracketed condition that starts at or after `i` (`[#1 EQ 0]`).
fn after_condition(src: &Source, i: usize, end: usize, keyword: &str) -> Result<usize, Error> {
    let i = src.skip_blanks(i).min(end);
    if src.at(i) != Some(b'[') || i >= end {
        return Err(src.error(
            i,
            format!(
                "{keyword} needs a condition in brackets, found {}",
                shown(src.describe(i))
            ),
        ));
    }
    let mut depth = 0i32;
    for (k, &b) in src.bytes[i..end].iter().enumerate() {
        match b {
            b'[' => depth += 1,
            b']' => {
                depth -= 1;
                if depth == 0 {
                    return Ok(i + k + 1);
                }
            }
            _ => {}
        }
    }
    Err(src.error(i, format!("{keyword}: a '[' without its ']'")))
}

/// The whole number written at or after `i` (blanks skipped), and where it ends.
fn label_at(src: &Source, i: usize, end: usize) -> Option<(u32, usize)> {
    let i = src.skip_blanks(i).min(end);
    let mut j = i;
    while j < end && src.bytes[j].is_ascii_digit() {
        j += 1;
    }
    let n = parse_number(&src.bytes[..j], i).filter(|n| n.span.1 == j)?;
    Some((whole(&n)?, j))
}

/// The statement whose keyword starts at `i` (`GOTO`, `IF`, `WHILE`, `DO`, `END`, or a
/// LinuxCNC o-word's keyword after `o100`), `words` the words before it.
fn statement(src: &Source, i: usize, end: usize, words: &[Word]) -> Result<Statement, Error> {
    let bytes = src.bytes;
    let kw_end = letters_end(bytes, i, end);
    let keyword = src.text(i, kw_end).to_ascii_uppercase();
    if let Some(o) = words.last().filter(|w| w.letter == b'O') {
        let name = match o.value {
            Value::Number(n) => format!("o{}", n.value),
            Value::Expression => src.text(o.at, words_end(src, o.at, end)).to_lowercase(),
        };
        return oword(src, name, keyword, o.at, i);
    }
    let jump = |j: usize, conditional: bool| -> Result<Statement, Error> {
        let k = src.skip_blanks(j).min(end);
        let label = match src.at(k) {
            Some(b'#' | b'[') if k < end => None,
            _ => match label_at(src, k, end) {
                Some((n, _)) => Some(n),
                None => {
                    return Err(src.error(
                        k,
                        format!(
                            "GOTO needs a block number, found {}",
                            shown(src.describe(k))
                        ),
                    ))
                }
            },
        };
        Ok(Statement::Jump { label, conditional })
    };
    let numbered = |j: usize, what: &str| -> Result<u32, Error> {
        label_at(src, j, end).map(|(n, _)| n).ok_or_else(|| {
            src.error(
                j,
                format!(
                    "{what} needs its loop's number (1-3), found {}",
                    shown(src.describe(j))
                ),
            )
        })
    };
    match keyword.as_str() {
        "GOTO" => jump(kw_end, false),
        "IF" => {
            let j = src.skip_blanks(after_condition(src, kw_end, end, "IF")?).min(end);
            let then_end = letters_end(bytes, j, end);
            match src.text(j, then_end).to_ascii_uppercase().as_str() {
                "GOTO" => jump(then_end, true),
                "THEN" => {
                    let k = src.skip_blanks(then_end).min(end);
                    match src.at(k) {
                        Some(b'#') if k < end => Ok(Statement::Assignment {
                            system: system_variable(src, k, end),
                            at: k,
                        }),
                        _ => Err(src.error(
                            k,
                            format!(
                                "IF … THEN takes an assignment (#1 = …) here, found {}",
                                shown(src.describe(k))
                            ),
                        )),
                    }
                }
                _ => Err(src.error(
                    j,
                    format!("IF [ … ] takes GOTO or THEN, found {}", shown(src.describe(j))),
                )),
            }
        }
        "WHILE" => {
            let j = src.skip_blanks(after_condition(src, kw_end, end, "WHILE")?).min(end);
            let do_end = letters_end(bytes, j, end);
            if !src.text(j, do_end).eq_ignore_ascii_case("DO") {
                return Err(src.error(
                    j,
                    format!("WHILE [ … ] takes DO1-DO3, found {}", shown(src.describe(j))),
                ));
            }
            Ok(Statement::Do {
                id: numbered(do_end, "DO")?,
            })
        }
        "DO" => Ok(Statement::Do {
            id: numbered(kw_end, "DO")?,
        }),
        "END" => Ok(Statement::End {
            id: numbered(kw_end, "END")?,
        }),
        _ => Err(src.error(
            i,
            format!(
                "{} is not a word (a letter and a number) or a statement (GOTO, IF, WHILE, DO, END) this reader knows",
                shown(src.describe(i))
            ),
        )),
    }
}

/// A LinuxCNC o-word statement: `sub`, `endsub`, `call`, `return` are read; its control
/// flow (`if`, `while`, `repeat`, …) is refused by name.
fn oword(
    src: &Source,
    name: String,
    keyword: String,
    at: usize,
    kw_at: usize,
) -> Result<Statement, Error> {
    match keyword.as_str() {
        "SUB" | "ENDSUB" | "CALL" | "RETURN" => Ok(Statement::OWord { name, keyword, at }),
        _ => Err(src.error(
            kw_at,
            format!(
                "{name} {}: LinuxCNC o-word control flow, which this reader does not follow",
                keyword.to_lowercase()
            ),
        )),
    }
}

/// Whether the variable assigned at `at` (`#5221`, `#[#1+1]`, `#<depth>`) may be a system
/// variable: #1000 and above (work offsets, tool data, settings), or an index computed as
/// the program runs.
fn system_variable(src: &Source, at: usize, end: usize) -> bool {
    let i = src.skip_blanks(at + 1).min(end);
    match src.at(i) {
        Some(b'[') => true,
        Some(b'<') => false,
        _ => label_at(src, i, end).is_none_or(|(n, _)| n >= 1000),
    }
}

/// The words of the line `start..end`, and the statement after them.
fn parse_line(src: &Source, start: usize, end: usize) -> Result<Parsed, Error> {
    let bytes = src.bytes;
    let mut out = Parsed::default();
    let mut i = start;
    if i == 0 && bytes.starts_with(b"\xef\xbb\xbf") {
        i = 3;
    }
    while i < end {
        let b = bytes[i];
        match b {
            b' ' | b'\t' | b'%' => i += 1,
            // Block delete, `/` or `/2` (the switch's number).
            b'/' => {
                out.deleted = true;
                i += 1;
                while i < end && bytes[i].is_ascii_digit() {
                    i += 1;
                }
            }
            b'(' => {
                let close = bytes[i..end].iter().position(|&c| c == b')');
                i = match close {
                    Some(p) => i + p + 1,
                    None => return Err(src.error(i, "a comment '(' without its ')'")),
                };
            }
            b';' => break,
            // A parameter's assignment (`#1 = 2`, `N5 #<depth> = 3`): no motion.
            b'#' => {
                out.statement = Some(Statement::Assignment {
                    system: system_variable(src, i, end),
                    at: i,
                });
                break;
            }
            _ if b.is_ascii_alphabetic() => {
                let letter = b.to_ascii_uppercase();
                let at = i;
                let next = if i + 1 < end { bytes[i + 1] } else { b' ' };
                if next.is_ascii_alphabetic() {
                    out.statement = Some(statement(src, i, end, &out.words)?);
                    break;
                }
                i = src.skip_blanks(i + 1).min(end);
                let value = match bytes.get(i) {
                    // A LinuxCNC named o-word: `o<probe> sub`.
                    Some(b'<') if letter == b'O' && i < end => {
                        while i < end && bytes[i] != b'>' {
                            i += 1;
                        }
                        i = (i + 1).min(end);
                        Value::Expression
                    }
                    Some(b'#' | b'[') if i < end => {
                        let mut depth = 0i32;
                        while i < end {
                            match bytes[i] {
                                b'[' => depth += 1,
                                b']' => depth -= 1,
                                b' ' | b'\t' | b'(' | b';' if depth <= 0 => break,
                                c if depth <= 0 && c.is_ascii_alphabetic() => break,
                                _ => {}
                            }
                            i += 1;
                        }
                        Value::Expression
                    }
                    _ => {
                        // Sign, digits, point, digits: no exponent (`X10E5` is X 10 and E 5).
                        let mut j = i;
                        if j < end && matches!(bytes[j], b'+' | b'-') {
                            j += 1;
                        }
                        while j < end && (bytes[j].is_ascii_digit() || bytes[j] == b'.') {
                            j += 1;
                        }
                        match parse_number(&bytes[..j], i).filter(|n| n.span.1 == j) {
                            Some(n) => {
                                i = j;
                                Value::Number(n)
                            }
                            None => {
                                return Err(src.error(
                                    at,
                                    format!(
                                        "the word {} has no number: found {}",
                                        letter as char,
                                        shown(src.describe(i))
                                    ),
                                ))
                            }
                        }
                    }
                };
                out.words.push(Word { letter, at, value });
            }
            _ => {
                return Err(src.error(
                    i,
                    format!(
                        "expected a word (a letter and a number), found {}",
                        shown(src.describe(i))
                    ),
                ))
            }
        }
    }
    Ok(out)
}

/// A G or M code's number in tenths (`G1` 10, `G90.1` 901, `G54.1` 541), `None` beyond.
fn code(n: &Number) -> Option<u32> {
    let tenths = n.value * 10.0;
    (n.value >= 0.0 && n.value < 1000.0 && (tenths - tenths.round()).abs() < 1e-6)
        .then(|| tenths.round() as u32)
}

/// The motion mode a block is in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Rapid,
    Linear,
    Arc {
        clockwise: bool,
    },
    /// A canned cycle (G73-G89), by its code in tenths.
    Cycle(u32),
}

impl Mode {
    /// The code that names it in reports (`G0`, `G81`).
    fn name(self) -> String {
        match self {
            Mode::Rapid => "G0".to_string(),
            Mode::Linear => "G1".to_string(),
            Mode::Arc { clockwise: true } => "G2".to_string(),
            Mode::Arc { clockwise: false } => "G3".to_string(),
            Mode::Cycle(g) => format!("G{}", g / 10),
        }
    }
}

/// A group of modes a block inherits: what may become unknown as the program runs (a G
/// code computed, a subprogram's or a jump's modes, a block-delete block's).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Group {
    Motion,
    Units,
    Distance,
    Plane,
    ArcDistance,
    Work,
    Cutter,
    Length,
    Transform,
    RunOffset,
    MacroCall,
    Tool,
}

impl Group {
    const ALL: [Group; 12] = [
        Group::Motion,
        Group::Units,
        Group::Distance,
        Group::Plane,
        Group::ArcDistance,
        Group::Work,
        Group::Cutter,
        Group::Length,
        Group::Transform,
        Group::RunOffset,
        Group::MacroCall,
        Group::Tool,
    ];

    fn bit(self) -> u16 {
        1 << self as u16
    }

    /// What it is, in messages.
    fn what(self) -> &'static str {
        match self {
            Group::Motion => "motion mode (G0-G3, cycles)",
            Group::Units => "units (G20/G21)",
            Group::Distance => "distance mode (G90/G91)",
            Group::Plane => "plane (G17-G19)",
            Group::ArcDistance => "arc centre mode (G90.1/G91.1)",
            Group::Work => "work offset (G54-G59)",
            Group::Cutter => "cutter compensation (G40-G42)",
            Group::Length => "tool length offset (G43/G49)",
            Group::Transform => "rotation, scaling or polar mode (G68, G51, G16)",
            Group::RunOffset => "offsets set as the program runs (G10, G52, G92, system variables)",
            Group::MacroCall => "modal macro call (G66/G67)",
            Group::Tool => "tool",
        }
    }

    /// The status of a move while it is not known: relative where the path may be offset
    /// or incremental, frame_unknown where the frame may be another, dynamic otherwise.
    fn reason(self) -> Reason {
        match self {
            Group::Distance | Group::Cutter => Reason::Relative,
            Group::Work | Group::Length | Group::Transform | Group::RunOffset | Group::Tool => {
                Reason::FrameUnknown
            }
            Group::MacroCall => Reason::UnknownMotion,
            Group::Motion | Group::Units | Group::Plane | Group::ArcDistance => Reason::Dynamic,
        }
    }

    /// Whether a move in `mode` depends on it (the plane and the arc centre mode only an
    /// arc's).
    fn moves(self, mode: Mode) -> bool {
        !matches!(self, Group::Plane | Group::ArcDistance) || matches!(mode, Mode::Arc { .. })
    }
}

/// The group a G code (in tenths) sets, if any.
fn group_of(g: u32) -> Option<Group> {
    Some(match g {
        0 | 10 | 20 | 30 | 730 | 740 | 760 | 800 => Group::Motion,
        810..=890 if g % 10 == 0 => Group::Motion,
        170 | 180 | 190 => Group::Plane,
        200 | 210 | 700 | 710 => Group::Units,
        900 | 910 => Group::Distance,
        901 | 911 => Group::ArcDistance,
        540..=590 if g % 10 == 0 => Group::Work,
        541 | 591 | 592 | 593 => Group::Work,
        400 | 410 | 420 | 411 | 421 => Group::Cutter,
        430..=435 | 440 | 450 | 460 | 470 | 480 | 490 => Group::Length,
        680 | 681 | 682 | 160 | 510 | 511 | 501 | 690 | 150 | 500 => Group::Transform,
        520 | 920 | 100 | 921 | 922 => Group::RunOffset,
        660 | 670 => Group::MacroCall,
        _ => return None,
    })
}

/// Whether `G92` or `G52` (`g` in tenths) on a block of `words` sets the position of
/// axes the reader does not read alone (`G92 E0`, a slicer's extruder reset; `G52 U10`):
/// it writes some value and none of X, Y, Z, A, B, C, whose offsets the controller keeps.
/// A bare `G92` is not (a printer's firmware sets every axis to 0), nor is `G10`, whose
/// `R` and `L` words set tool data and parameters without naming an axis.
fn sets_other_axes_only(g: u32, words: &[Word]) -> bool {
    matches!(g, 520 | 920)
        && words.iter().any(|w| !matches!(w.letter, b'G' | b'N'))
        && !words.iter().any(|w| AXES.contains(&w.letter))
}

/// Why a group's mode is not known where a move is: its status and what made it so.
#[derive(Clone, Debug, PartialEq)]
struct Unknown {
    reason: Reason,
    detail: String,
}

/// The groups of a mask, `u16` by [`Group::bit`].
const ALL_GROUPS: u16 = (1 << 12) - 1;

/// Something that puts the program's moves in a frame the options do not give, or offsets
/// them as the controller runs: what, where, and the reason.
#[derive(Clone, Debug, PartialEq)]
struct Modal {
    what: String,
    reason: Reason,
}

const AXES: &[u8; 6] = b"XYZABC";

/// What the reader has found so far: the targets, and beside each its arc and work offset.
#[derive(Default)]
struct Found {
    targets: Vec<ProgramTarget>,
    arcs: Vec<Option<Box<Arc>>>,
    offsets: Vec<u8>,
    first_motion: Option<usize>,
}

impl Found {
    /// A target and what stands beside it.
    fn push(&mut self, target: ProgramTarget, arc: Option<Box<Arc>>, work_offset: u8) {
        self.targets.push(target);
        self.arcs.push(arc);
        self.offsets.push(work_offset);
    }

    /// A motion reported where it is written and left unchanged.
    fn refuse(&mut self, at: usize, name: String, reason: Reason, detail: String) {
        let target = ProgramTarget {
            name,
            offset: at,
            kind: TargetKind::Motion,
            uses: Vec::new(),
            refused: Some(Refusal::new(reason, detail)),
        };
        self.push(target, None, 0);
    }
}

/// A motion a block commands that no target of this reader stands for (a return to a
/// stored position, a G code computed or unknown): reported by its code.
struct OtherMotion {
    name: String,
    at: usize,
    reason: Reason,
    detail: String,
}

/// What a block's G codes say beyond the modes they set.
#[derive(Default)]
struct BlockCodes {
    /// The motion code it writes, and where.
    motion: Option<(Mode, usize)>,
    /// `G53`: its axis words are machine coordinates.
    machine: bool,
    /// Its axis words are data (a dwell's time, an offset set), not a move.
    data: bool,
    /// A motion it commands that is not a target.
    other_motion: Option<OtherMotion>,
}

/// A block's axis words: the numbers of X Y Z A B C it writes, and the first expression
/// among them.
struct Written {
    numbers: [Option<Number>; 6],
    expression: Option<usize>,
}

impl Written {
    fn of(axis_words: &[&Word]) -> Written {
        let mut written = Written {
            numbers: [None; 6],
            expression: None,
        };
        for w in axis_words {
            match (AXES.iter().position(|a| *a == w.letter), w.value) {
                (_, Value::Expression) => {
                    written.expression.get_or_insert(w.at);
                }
                (Some(i), Value::Number(n)) => written.numbers[i] = Some(n),
                _ => {}
            }
        }
        written
    }
}

/// A block as the reader sees it: its words, where it is, and where its line ends.
struct Block<'b, 'a> {
    src: &'b Source<'a>,
    words: &'b [Word],
    line_number: usize,
    end: usize,
}

/// A move a block commands in a motion mode: its axis words, and what names it.
struct Move {
    written: Written,
    /// `G53`: machine coordinates.
    machine: bool,
    mode: Mode,
    /// Whether the block writes its motion code.
    written_mode: bool,
    /// The mode's code (`G1`).
    name: String,
    /// Where the move is written: its motion code, else its first axis word.
    at: usize,
}

/// What becomes of a block's motion.
enum Outcome {
    /// Reported and left unchanged.
    Refused(Reason, String),
    /// A target the block writes only in part.
    Incomplete(String),
    /// A target to correct: its orientation and the arc it ends.
    Target {
        orientation: Option<Orientation>,
        arc: Option<Box<Arc>>,
    },
}

/// The modal state: what a block inherits from the blocks before it.
#[derive(Clone)]
struct State {
    inch: bool,
    absolute: bool,
    arc_absolute: bool,
    plane: Plane,
    mode: Option<Mode>,
    /// The work offset selected: None before any (the job's base), else its name and number.
    work: Option<(String, Option<u8>)>,
    // Cutter compensation, tool length, rotation, scaling…: each by its group.
    cutter: Option<Modal>,
    length: Option<Modal>,
    transform: Option<Modal>,
    run_offset: Option<Modal>,
    /// A modal macro call (`G66`), until `G67`.
    macro_call: Option<Modal>,
    /// The first tool the program selects (`T1`), the one `--tool` describes.
    first_tool: Option<String>,
    /// Another tool selected.
    tool: Option<Modal>,
    /// Per group, why its mode is not known, when it is not.
    unknown: [Option<Box<Unknown>>; 12],
    /// Per axis X Y Z A B C, the number that last wrote it (absolute) and its line.
    modal: [Option<(Number, usize)>; 6],
    /// Per axis, the line after which its value is not known (an incremental move, a
    /// subprogram, a jump), when no number wrote it since.
    lost: [Option<usize>; 6],
    /// Where the tool is, mm (program frame), when known.
    position: [Option<f64>; 3],
    /// The target whose end is where the tool is, when a block wrote it in full.
    at_target: Option<usize>,
}

impl State {
    fn new() -> State {
        State {
            inch: false,
            absolute: true,
            arc_absolute: false,
            plane: Plane::Xy,
            mode: None,
            work: None,
            cutter: None,
            length: None,
            transform: None,
            run_offset: None,
            macro_call: None,
            first_tool: None,
            tool: None,
            unknown: Default::default(),
            modal: [None; 6],
            lost: [None; 6],
            position: [None; 3],
            at_target: None,
        }
    }

    fn unit_mm(&self) -> f64 {
        if self.inch {
            25.4
        } else {
            1.0
        }
    }

    /// Marks the group's mode not known, with why.
    fn mark(&mut self, group: Group, reason: Reason, detail: String) {
        self.unknown[group as usize] = Some(Box::new(Unknown { reason, detail }));
    }

    /// Marks the groups of `mask` not known, each with its own status.
    fn mark_groups(&mut self, mask: u16, detail: &dyn Fn(Group) -> String) {
        for g in Group::ALL {
            if mask & g.bit() != 0 {
                self.mark(g, g.reason(), detail(g));
            }
        }
    }

    /// Whether the group's mode is the same here as in `other`.
    fn same(&self, other: &State, group: Group) -> bool {
        match group {
            Group::Motion => self.mode == other.mode,
            Group::Units => self.inch == other.inch,
            Group::Distance => self.absolute == other.absolute,
            Group::Plane => self.plane == other.plane,
            Group::ArcDistance => self.arc_absolute == other.arc_absolute,
            Group::Work => self.work == other.work,
            Group::Cutter => self.cutter == other.cutter,
            Group::Length => self.length == other.length,
            Group::Transform => self.transform == other.transform,
            Group::RunOffset => self.run_offset == other.run_offset,
            Group::MacroCall => self.macro_call == other.macro_call,
            Group::Tool => self.tool == other.tool && self.first_tool == other.first_tool,
        }
    }

    /// The state where this one and `other` meet (a jump's target, the block after a
    /// block-delete block): a group whose mode differs is not known, `why` says how; the
    /// tool's position where they differ neither.
    fn merge(&mut self, other: &State, line_number: usize, why: &dyn Fn(Group) -> String) {
        for g in Group::ALL {
            let k = g as usize;
            if self.unknown[k].is_some() {
                continue;
            }
            if let Some(u) = &other.unknown[k] {
                self.unknown[k] = Some(u.clone());
            } else if !self.same(other, g) {
                self.mark(g, g.reason(), why(g));
            }
        }
        if self.position != other.position || self.at_target != other.at_target {
            self.position = [None; 3];
            self.at_target = None;
        }
        for i in 0..6 {
            if self.modal[i].map(|m| m.0.value) != other.modal[i].map(|m| m.0.value)
                || other.lost[i].is_some()
            {
                self.modal[i] = None;
                self.lost[i] = Some(line_number);
            }
        }
    }

    /// The block's codes, in the order a controller applies them: the modes they set, and
    /// what they say of the block.
    fn read_codes(&mut self, block: &Block) -> BlockCodes {
        let mut codes = BlockCodes::default();
        for w in block.words {
            let Value::Number(n) = w.value else {
                if w.letter == b'G' {
                    let detail = format!(
                        "{} (line {}): a G code computed when the program runs, so the modes after it are not known",
                        w.text(block.src),
                        block.line_number
                    );
                    for g in Group::ALL {
                        self.mark(g, Reason::Dynamic, detail.clone());
                    }
                    codes.other_motion = Some(OtherMotion {
                        name: w.text(block.src),
                        at: w.at,
                        reason: Reason::Dynamic,
                        detail: "a G code computed when the program runs".into(),
                    });
                }
                continue;
            };
            if w.letter != b'G' {
                continue;
            }
            let name = w.text(block.src);
            match code(&n) {
                Some(g) => self.apply_g(g, name, w.at, block, &mut codes),
                None => {
                    codes.other_motion = Some(OtherMotion {
                        detail: format!("{name} is not a G code this reader knows"),
                        name,
                        at: w.at,
                        reason: Reason::UnknownMotion,
                    });
                }
            }
        }
        codes
    }

    /// Applies the G code `g` (in tenths), written `name` at `at`.
    fn apply_g(&mut self, g: u32, name: String, at: usize, block: &Block, codes: &mut BlockCodes) {
        if sets_other_axes_only(g, block.words) {
            // The offset's values, of axes no move here is read by: the frame of the
            // moves, known or not, stays as it was.
            codes.data = true;
            return;
        }
        if let Some(group) = group_of(g) {
            self.unknown[group as usize] = None;
        }
        match g {
            0 => codes.motion = Some((Mode::Rapid, at)),
            10 => codes.motion = Some((Mode::Linear, at)),
            20 => codes.motion = Some((Mode::Arc { clockwise: true }, at)),
            30 => codes.motion = Some((Mode::Arc { clockwise: false }, at)),
            170 => self.plane = Plane::Xy,
            180 => self.plane = Plane::Zx,
            190 => self.plane = Plane::Yz,
            200 => self.inch = true,
            210 => self.inch = false,
            900 => self.absolute = true,
            910 => self.absolute = false,
            901 => self.arc_absolute = true,
            911 => self.arc_absolute = false,
            530 => codes.machine = true,
            540..=590 if g % 10 == 0 => {
                let number = (g / 10) as u8;
                self.work = Some((format!("G{number}"), Some(number)));
            }
            541 | 591 | 592 | 593 => self.work = Some((name, None)),
            800 => self.mode = None,
            730 | 740 | 760 | 810..=890 if g % 10 == 0 || g == 730 => {
                codes.motion = Some((Mode::Cycle(g), at));
            }
            40 => codes.data = true,
            280 | 300 | 281 | 301 => {
                codes.other_motion = Some(OtherMotion {
                    detail: format!(
                        "{name}: a return to a reference position the controller stores"
                    ),
                    name,
                    at,
                    reason: Reason::Dynamic,
                });
            }
            700 | 710 => {
                self.mark(
                    Group::Units,
                    Reason::UnknownMotion,
                    format!(
                        "{name} (line {}): inches (G70) or millimetres (G71) in ISO 6983 and Sinumerik, a finishing or roughing cycle on a Fanuc lathe: no move is corrected until G20 or G21 sets the units",
                        block.line_number
                    ),
                );
                codes.other_motion = Some(OtherMotion {
                    detail: format!(
                        "{name}: units in ISO 6983 and Sinumerik, a cycle on a Fanuc lathe, which this reader cannot tell apart"
                    ),
                    name,
                    at,
                    reason: Reason::UnknownMotion,
                });
            }
            // A macro call (G65) and a modal one (G66): their words are its arguments.
            650 => codes.data = true,
            660 => {
                self.macro_call = Some(Modal {
                    what: format!(
                        "{name}{} (line {}): a modal macro call, run after each move",
                        block
                            .words
                            .iter()
                            .find(|w| w.letter == b'P')
                            .map(|w| format!(" {}", w.text(block.src)))
                            .unwrap_or_default(),
                        block.line_number
                    ),
                    reason: Reason::UnknownMotion,
                });
                codes.data = true;
            }
            670 => self.macro_call = None,
            // Exact stop, feed and spindle modes, path modes, return levels: no motion.
            610 | 611 | 640 | 930 | 940 | 950 | 960 | 970 | 980 | 990 | 90 => {}
            _ => {
                if !self.apply_offset_code(g, &name, block, codes) {
                    codes.other_motion = Some(OtherMotion {
                        detail: format!("{name} is not a G code this reader corrects"),
                        name,
                        at,
                        reason: Reason::UnknownMotion,
                    });
                }
            }
        }
    }

    /// Applies a code of the groups that offset or transform the moves as the controller
    /// runs (cutter compensation, tool length, rotation and scaling, offsets set by the
    /// program); `false` when `g` is none of them.
    fn apply_offset_code(
        &mut self,
        g: u32,
        name: &str,
        block: &Block,
        codes: &mut BlockCodes,
    ) -> bool {
        let line_number = block.line_number;
        // The word that names the offset's register (`D`, `H`), as written after the code.
        let register = |letter: u8| {
            block
                .words
                .iter()
                .find(|w| w.letter == letter)
                .map(|w| format!(" {}", w.text(block.src)))
                .unwrap_or_default()
        };
        match g {
            400 => self.cutter = None,
            410 | 420 | 411 | 421 => {
                self.cutter = Some(Modal {
                    what: format!(
                        "{name}{} (line {line_number}): the controller offsets the path by the cutter's radius as it runs",
                        register(b'D')
                    ),
                    reason: Reason::Relative,
                });
            }
            430 | 431 | 432 | 433 | 434 | 435 | 440 | 450 | 460 | 470 | 480 => {
                self.length = Some(Modal {
                    what: format!(
                        "the tool length offset {name}{} (line {line_number}), which no option gives",
                        register(b'H')
                    ),
                    reason: Reason::FrameUnknown,
                });
            }
            490 => self.length = None,
            680 | 681 | 682 | 160 | 510 | 511 | 501 => {
                self.transform = Some(Modal {
                    what: format!(
                        "{name} (line {line_number}): a rotation, scaling, mirror or polar coordinates the controller applies as it runs"
                    ),
                    reason: Reason::FrameUnknown,
                });
                // Its words are the transform's centre, angle and factors.
                codes.data = g != 160;
            }
            690 | 150 | 500 => self.transform = None,
            520 | 920 | 100 => {
                self.run_offset = Some(Modal {
                    what: format!(
                        "{name} (line {line_number}): an offset the program sets as it runs"
                    ),
                    reason: Reason::FrameUnknown,
                });
                codes.data = true;
            }
            921 | 922 => self.run_offset = None,
            _ => return false,
        }
        true
    }

    /// Forgets where the tool is after line `line_number`: a move the reader cannot
    /// follow. An axis never written stays so (a program without A, B, C).
    fn lose_position(&mut self, line_number: usize) {
        self.position = [None; 3];
        self.at_target = None;
        for i in 0..6 {
            if self.modal[i].take().is_some() || i < 3 {
                self.lost[i] = Some(line_number);
            }
        }
    }

    /// The state after a move that writes `written`, whatever becomes of its target.
    fn advance(&mut self, written: &Written, machine: bool, line_number: usize) {
        self.at_target = None;
        if machine || written.expression.is_some() {
            self.lose_position(line_number);
            return;
        }
        let unit_mm = self.unit_mm();
        for i in 0..6 {
            let Some(n) = written.numbers[i] else {
                continue;
            };
            if self.absolute {
                self.modal[i] = Some((n, line_number));
                self.lost[i] = None;
                if i < 3 {
                    self.position[i] = Some(n.value * unit_mm);
                }
            } else {
                self.modal[i] = None;
                self.lost[i] = Some(line_number);
                if i < 3 {
                    self.position[i] = self.position[i].map(|p| p + n.value * unit_mm);
                }
            }
        }
    }

    /// Why the move `name` is left unchanged, if it is: a value computed as the program
    /// runs, an external axis, machine coordinates, a canned cycle, an offset or transform
    /// in force, incremental mode, or a work offset the options do not give.
    fn refusal(
        &self,
        block: &Block,
        mv: &Move,
        options: &GcodeOptions,
    ) -> Option<(Reason, String)> {
        let (src, name) = (block.src, &mv.name);
        if let Some(e) = mv.written.expression {
            Some((
                Reason::Dynamic,
                format!(
                    "{}: a value computed when the program runs",
                    src.text(e, words_end(src, e, block.end))
                ),
            ))
        } else if let Some(w) = block.words.iter().find(|w| b"UVW".contains(&w.letter)) {
            Some((
                Reason::ExternalAxis,
                format!("{}: an axis beyond the robot's six", w.text(src)),
            ))
        } else if let Some(u) = self.unknown_for(mv) {
            Some((u.reason, format!("{name}: {}", u.detail)))
        } else if mv.machine {
            Some((
                Reason::FrameUnknown,
                "G53: machine coordinates, which no option gives".into(),
            ))
        } else if let Mode::Cycle(g) = mv.mode {
            Some((
                Reason::UnknownMotion,
                format!(
                    "{name}: a canned cycle (G{}), whose moves the controller computes as it runs",
                    if g % 10 == 0 {
                        (g / 10).to_string()
                    } else {
                        format!("{}.{}", g / 10, g % 10)
                    }
                ),
            ))
        } else if let Some(m) = [
            &self.tool,
            &self.macro_call,
            &self.transform,
            &self.run_offset,
            &self.length,
            &self.cutter,
        ]
        .into_iter()
        .flatten()
        .next()
        {
            Some((m.reason, format!("{name} under {}", m.what)))
        } else if !self.absolute {
            Some((
                Reason::Relative,
                format!("{name} in G91: an incremental move from where the previous one ended"),
            ))
        } else {
            self.work_refusal(options)
        }
    }

    /// Why a group the move depends on is not known, if one is: the first, in
    /// [`Group::ALL`]'s order (the motion mode only when the block writes none).
    fn unknown_for(&self, mv: &Move) -> Option<&Unknown> {
        Group::ALL
            .into_iter()
            .filter(|g| g.moves(mv.mode) && (*g != Group::Motion || !mv.written_mode))
            .find_map(|g| self.unknown[g as usize].as_deref())
    }

    /// A work offset selected that the options do not give.
    fn work_refusal(&self, options: &GcodeOptions) -> Option<(Reason, String)> {
        let (wname, number) = self.work.as_ref()?;
        let given = number.and_then(|n| options.work_offsets.iter().find(|b| b.0 == n));
        given.is_none().then(|| {
            let how = match number {
                Some(_) => format!("give it as --work-offset {wname}=X,Y,Z[,A,B,C]"),
                None => "the options give G54-G59 only".to_string(),
            };
            (
                Reason::FrameUnknown,
                format!("work offset {wname} not given: {how}"),
            )
        })
    }

    /// The number of the work offset in force, 0 for the job's base.
    fn work_offset(&self) -> u8 {
        match &self.work {
            Some((_, Some(n))) => *n,
            _ => 0,
        }
    }

    /// X, Y, Z the block leaves to the blocks before it, named with where they were last
    /// written; an empty list when it writes all three.
    fn missing_position(&self, written: &Written) -> Vec<String> {
        (0..3)
            .filter(|i| written.numbers[*i].is_none())
            .map(|i| {
                let axis = AXES[i] as char;
                match (self.modal[i], self.lost[i]) {
                    (Some((_, l)), _) => format!("{axis} (modal from line {l})"),
                    (None, Some(l)) => format!("{axis} (not known after line {l})"),
                    (None, None) => format!("{axis} (never written)"),
                }
            })
            .collect()
    }

    /// A, B, C: written, or modal when the program has written all three; `Err` naming
    /// those never written.
    fn orientation(
        &self,
        written: &Written,
        abc: AbcConvention,
    ) -> Result<Option<Orientation>, String> {
        let used_abc = (3..6).any(|i| {
            written.numbers[i].is_some() || self.modal[i].is_some() || self.lost[i].is_some()
        });
        if !used_abc {
            return Ok(None);
        }
        let values: Vec<Option<Number>> = (3..6)
            .map(|i| written.numbers[i].or(self.modal[i].map(|m| m.0)))
            .collect();
        match (values[0], values[1], values[2]) {
            (Some(a), Some(b), Some(c)) => Ok(Some(match abc {
                AbcConvention::Kuka => Orientation::KukaAbcDeg([a, b, c]),
                AbcConvention::FixedXyz => Orientation::KukaAbcDeg([c, b, a]),
            })),
            _ => {
                let missing: Vec<String> = ["A", "B", "C"]
                    .into_iter()
                    .zip(&values)
                    .zip(&self.lost[3..])
                    .filter(|((_, n), _)| n.is_none())
                    .map(|((a, _), lost)| match lost {
                        Some(l) => format!("{a} (not known after line {l})"),
                        None => format!("{a} (never written)"),
                    })
                    .collect();
                Err(format!(
                    "{} not written on this block: the tool's orientation is not known",
                    missing.join(", ")
                ))
            }
        }
    }

    /// The arc a `G2`/`G3` block ends, from where the tool is; `Err` why it cannot be
    /// followed (several turns, an unknown start, no centre or a radius that does not fit).
    fn arc(&self, words: &[Word], written: &Written, clockwise: bool) -> Result<Arc, String> {
        let plane = self.plane;
        let unit_mm = self.unit_mm();
        let find = |letter: u8| {
            words.iter().find_map(|w| match w.value {
                Value::Number(n) if w.letter == letter => Some(n),
                _ => None,
            })
        };
        let end_mm: [f64; 3] =
            std::array::from_fn(|i| written.numbers[i].map_or(0.0, |n| n.value) * unit_mm);
        let start = match (self.at_target, self.position) {
            (Some(t), [Some(x), Some(y), Some(z)]) => Some((t, [x, y, z])),
            _ => None,
        };
        if let Some(p) = find(b'P').filter(|p| p.value != 1.0) {
            return Err(format!("P{}: an arc of several turns", p.value));
        }
        let Some((start_target, start_mm)) = start else {
            return Err(
                "its start (the previous motion's end) is not a point the program writes in full"
                    .into(),
            );
        };
        let (centre_mm, centre) = match find(b'R') {
            Some(r) => (
                centre_from_radius(start_mm, end_mm, r.value * unit_mm, clockwise, plane)?,
                Centre::Radius(r),
            ),
            None => {
                let [u, v, _] = plane.axes();
                let offset_letter = |axis: usize| b"IJK"[axis];
                let numbers = [find(offset_letter(u)), find(offset_letter(v))];
                let value = |k: usize| numbers[k].map_or(0.0, |n| n.value) * unit_mm;
                let centre_mm = if self.arc_absolute {
                    [value(0), value(1)]
                } else {
                    [start_mm[u] + value(0), start_mm[v] + value(1)]
                };
                if numbers.iter().all(Option::is_none) {
                    return Err("neither a centre (I, J, K of its plane) nor a radius R".into());
                }
                let absolute = self.arc_absolute;
                (centre_mm, Centre::Offsets { numbers, absolute })
            }
        };
        Ok(Arc {
            clockwise,
            plane,
            start_target,
            start_mm,
            centre_mm,
            centre,
            unit_mm,
        })
    }

    /// What becomes of a move in `mode` that writes `written`, by the state before it.
    fn outcome(&self, block: &Block, mv: &Move, options: &GcodeOptions) -> Outcome {
        if let Some((reason, detail)) = self.refusal(block, mv, options) {
            return Outcome::Refused(reason, detail);
        }
        if let Some(why) = duplicate(block) {
            return Outcome::Incomplete(why);
        }
        let written = &mv.written;
        let missing = self.missing_position(written);
        if !missing.is_empty() {
            return Outcome::Incomplete(format!(
                "{} not written on this block: the compensated program changes numbers only, and a modal axis holds the previous block's corrected value",
                missing.join(", ")
            ));
        }
        let orientation = match self.orientation(written, options.abc) {
            Ok(orientation) => orientation,
            Err(why) => return Outcome::Incomplete(why),
        };
        let arc = match mv.mode {
            Mode::Arc { clockwise } => match self.arc(block.words, written, clockwise) {
                Ok(arc) => Some(Box::new(arc)),
                Err(why) => return Outcome::Incomplete(why),
            },
            _ => None,
        };
        Outcome::Target { orientation, arc }
    }
}

/// Why a block that writes an axis or an arc's centre twice (`X-45. X-44.`) is not
/// corrected: a controller alarms on it.
fn duplicate(block: &Block) -> Option<String> {
    let mut first: [Option<&Word>; 26] = [None; 26];
    for w in block.words {
        if !b"XYZABCUVWIJKR".contains(&w.letter) {
            continue;
        }
        let slot = &mut first[(w.letter - b'A') as usize];
        match slot {
            Some(v) => {
                return Some(format!(
                    "{} written twice on this block ({} and {}): a controller alarms on it",
                    w.letter as char,
                    v.text(block.src),
                    w.text(block.src)
                ))
            }
            None => *slot = Some(w),
        }
    }
    None
}

/// A target to correct, or left incomplete, named `name` at `offset`.
fn target(name: String, offset: usize, kind: TargetKind) -> ProgramTarget {
    ProgramTarget {
        name,
        offset,
        kind,
        uses: Vec::new(),
        refused: None,
    }
}

/// The lines a controller reads: up to the closing `%` tape mark (the first `%` line after
/// a line with anything else); what follows it is kept as written, never read.
fn program_lines<'s>(src: &'s Source) -> impl Iterator<Item = crate::source::Line> + 's {
    let mut content = false;
    src.lines().take_while(move |line| {
        let mut text = &src.bytes[line.start..line.end];
        if line.start == 0 {
            text = text.strip_prefix(b"\xef\xbb\xbf").unwrap_or(text);
        }
        match text.iter().find(|b| !matches!(b, b' ' | b'\t')) {
            Some(b'%') => !content,
            Some(_) => {
                content = true;
                true
            }
            None => true,
        }
    })
}

/// The number of a word of `letter` on the block, when whole.
fn number_of(words: &[Word], letter: u8) -> Option<u32> {
    words.iter().find_map(|w| match w.value {
        Value::Number(n) if w.letter == letter => whole(&n),
        _ => None,
    })
}

/// Whether the block writes the M code `m` (in tenths: M30 300).
fn has_m(words: &[Word], m: &[u32]) -> bool {
    words.iter().any(|w| match w.value {
        Value::Number(n) if w.letter == b'M' => code(&n).is_some_and(|c| m.contains(&c)),
        _ => false,
    })
}

/// The codes that end a program or return from a subprogram: M2, M30, M99.
const ENDS: [u32; 3] = [20, 300, 990];

/// A call of a subprogram or macro: `M98 P2000 L3`, `M97 P100`, `G65 P9010`, `G66 P9100`,
/// `M198 P3000`, LinuxCNC `o100 call`.
struct Call {
    /// The called program's key (`o2000`, `n100` for M97's block number, `o<name>`);
    /// `None` when computed as the program runs.
    key: Option<String>,
    /// As messages name it (`O2000`).
    program: String,
    /// The call as written (`M98 P2000`).
    text: String,
    /// Where it is written.
    at: usize,
}

/// The call a line makes, if any.
fn call_of(src: &Source, parsed: &Parsed) -> Option<Call> {
    if let Some(Statement::OWord { name, keyword, at }) = &parsed.statement {
        return (keyword == "CALL").then(|| Call {
            key: Some(name.clone()),
            program: name.clone(),
            text: format!("{name} call"),
            at: *at,
        });
    }
    let words = &parsed.words;
    let word = words.iter().find(|w| match w.value {
        Value::Number(n) if w.letter == b'M' => matches!(code(&n), Some(970 | 980 | 1980)),
        Value::Number(n) if w.letter == b'G' => matches!(code(&n), Some(650 | 660)),
        _ => false,
    })?;
    let m97 =
        word.letter == b'M' && matches!(word.value, Value::Number(n) if code(&n) == Some(970));
    let m98 =
        word.letter == b'M' && matches!(word.value, Value::Number(n) if code(&n) == Some(980));
    let p = words.iter().find(|w| w.letter == b'P');
    let text = match p {
        Some(p) => format!("{} {}", word.text(src), p.text(src)),
        None => word.text(src),
    };
    let key = p.and_then(|p| match p.value {
        Value::Number(n) => whole(&n),
        Value::Expression => None,
    });
    let (key, program) = match key {
        // Fanuc's M98 P0032000: three times O2000 (the last four digits the program).
        Some(n) if m98 && n >= 10_000 => {
            (Some(format!("o{}", n % 10_000)), format!("O{}", n % 10_000))
        }
        Some(n) if m97 => (Some(format!("n{n}")), format!("N{n}")),
        Some(n) => (Some(format!("o{n}")), format!("O{n}")),
        None => (None, "a program".to_string()),
    };
    Some(Call {
        key,
        program,
        text,
        at: word.at,
    })
}

/// The groups a line sets: its G codes', a tool's, a system variable's, every group for
/// a call or a G code computed as the program runs.
fn line_mask(src: &Source, parsed: &Parsed) -> u16 {
    if call_of(src, parsed).is_some() {
        return ALL_GROUPS;
    }
    let mut mask = 0;
    if let Some(Statement::Assignment { system: true, .. }) = parsed.statement {
        mask |= Group::RunOffset.bit();
    }
    for w in &parsed.words {
        match (w.letter, w.value) {
            (b'G', Value::Number(n)) => {
                if let Some(g) = code(&n)
                    .filter(|g| !sets_other_axes_only(*g, &parsed.words))
                    .and_then(group_of)
                {
                    mask |= g.bit();
                }
            }
            (b'G', Value::Expression) => return ALL_GROUPS,
            (b'T', _) => mask |= Group::Tool.bit(),
            _ => {}
        }
    }
    mask
}

/// What the reader needs to know of the whole program before it reads a block: the
/// subprograms the file holds and who calls them, and where its jumps and loops go.
#[derive(Default)]
struct Structure {
    /// The programs the file holds (`o2000`; `n100` for a block after the main program's
    /// end), with the groups their blocks set.
    bodies: HashMap<String, u16>,
    /// The first call of each program: `M98 P2000 at line 6`.
    calls: HashMap<String, String>,
    /// Each block number's first line.
    labels: HashMap<u32, usize>,
    /// Block numbers jumped back to: the groups the blocks between set, and the jump.
    backward: HashMap<u32, (u16, String)>,
    /// Loops by their `DO` line: the groups their blocks set, and their `END`'s line.
    loops: HashMap<usize, (u16, usize)>,
    /// A jump to a block number computed as the program runs: where.
    computed_jump: Option<String>,
}

impl Structure {
    fn of(src: &Source) -> Result<Structure, Error> {
        let mut s = Structure::default();
        // Per line (by number), the groups it sets; the intervals to union.
        let mut masks: Vec<u16> = Vec::new();
        let mut intervals: Vec<(usize, usize, Interval)> = Vec::new();
        let mut open_loops: HashMap<u32, Vec<usize>> = HashMap::new();
        let mut section: Option<String> = None;
        let mut first_end: Option<usize> = None;
        for line in program_lines(src) {
            let parsed = parse_line(src, line.start, line.end)?;
            let n = line.number;
            let mask = line_mask(src, &parsed);
            if masks.len() <= n {
                masks.resize(n + 1, 0);
            }
            masks[n] = mask;
            let words = &parsed.words;
            let header = number_of(words, b'O').filter(|_| parsed.statement.is_none());
            if let Some(o) = header {
                section = Some(format!("o{o}"));
            }
            if let Some(Statement::OWord { name, keyword, .. }) = &parsed.statement {
                match keyword.as_str() {
                    "SUB" => section = Some(name.clone()),
                    "ENDSUB" => section = None,
                    _ => {}
                }
            }
            if let Some(label) = number_of(words, b'N') {
                s.labels.entry(label).or_insert(n);
                if first_end.is_some_and(|e| e < n) {
                    s.bodies.insert(format!("n{label}"), ALL_GROUPS);
                }
            }
            if let Some(key) = &section {
                *s.bodies.entry(key.clone()).or_insert(0) |= mask;
            }
            if let Some(call) = call_of(src, &parsed) {
                if let Some(key) = call.key {
                    s.calls
                        .entry(key)
                        .or_insert_with(|| format!("{} at line {n}", call.text));
                }
            }
            match &parsed.statement {
                Some(Statement::Jump { label: Some(l), .. }) => {
                    if let Some(&from) = s.labels.get(l) {
                        intervals.push((
                            from,
                            n,
                            Interval::Back(*l, format!("GOTO {l} at line {n}")),
                        ));
                    }
                }
                Some(Statement::Jump { label: None, .. }) => {
                    s.computed_jump
                        .get_or_insert_with(|| format!("the GOTO at line {n}"));
                }
                Some(Statement::Do { id, .. }) => open_loops.entry(*id).or_default().push(n),
                Some(Statement::End { id, .. }) => {
                    if let Some(from) = open_loops.get_mut(id).and_then(Vec::pop) {
                        intervals.push((from, n, Interval::Loop));
                    }
                }
                _ => {}
            }
            if !parsed.deleted && has_m(words, &ENDS) {
                first_end.get_or_insert(n);
                section = None;
            }
        }
        if !intervals.is_empty() {
            // Per group, how many lines up to each set it: a union over any interval in
            // constant time.
            let mut prefix: Vec<[u32; 12]> = Vec::with_capacity(masks.len() + 1);
            let mut count = [0u32; 12];
            prefix.push(count);
            for m in &masks {
                for (k, c) in count.iter_mut().enumerate() {
                    *c += u32::from(m >> k & 1 == 1);
                }
                prefix.push(count);
            }
            for (from, to, kind) in intervals {
                let mask = (0..12)
                    .filter(|&k| prefix[to + 1][k] > prefix[from][k])
                    .fold(0u16, |m, k| m | 1 << k);
                match kind {
                    Interval::Back(label, jump) => {
                        let entry = s.backward.entry(label).or_insert((0, jump));
                        entry.0 |= mask;
                    }
                    Interval::Loop => {
                        s.loops.insert(from, (mask, to));
                    }
                }
            }
        }
        Ok(s)
    }
}

/// A stretch of lines run again: back to a block number, or a loop.
enum Interval {
    Back(u32, String),
    Loop,
}

/// Where the reader is: the main program, a subprogram's body (and why its moves are not
/// corrected), or past the main program's end.
enum Region {
    Main,
    Body(String),
    After(String),
}

/// The reader: the modal state and what it has found.
struct Reader<'o> {
    options: &'o GcodeOptions,
    state: State,
    found: Found,
    structure: Structure,
    region: Region,
    /// The main program's state while the reader is in a subprogram's body before its end.
    saved: Option<State>,
    /// Where the main program ends (`M30 at line 8`), once read.
    main_end: Option<String>,
    /// Whether a block of the main program has been read.
    started: bool,
    /// Whether the line is reached from the one before (not after an unconditional GOTO).
    reachable: bool,
    /// Forward jumps not yet at their block number: the state at each and the jump.
    pending: HashMap<u32, Vec<(State, String)>>,
    /// Loops by their `END`'s line: the state at their start, and the loop.
    loop_exits: HashMap<usize, (State, String)>,
}

impl Reader<'_> {
    /// Reads one line.
    fn line(&mut self, parsed: &Parsed, block: &Block) {
        let line = block.line_number;
        let header = number_of(block.words, b'O').filter(|_| parsed.statement.is_none());
        if let Some(o) = header {
            self.enter(format!("o{o}"), format!("O{o}"), false);
        }
        if let Some(Statement::OWord { name, keyword, .. }) = &parsed.statement {
            if keyword == "SUB" {
                self.enter(name.clone(), name.clone(), true);
            }
        }
        let label = number_of(block.words, b'N');
        if let (Region::After(_), Some(n)) = (&self.region, label) {
            if let Some(call) = self.structure.calls.get(&format!("n{n}")) {
                self.region = Region::Body(format!(
                    "in N{n}, run by {call} in the caller's modes: a subprogram's moves are not corrected"
                ));
            }
        }
        if matches!(self.region, Region::Main) {
            self.started = true;
        }
        let ends = !parsed.deleted && has_m(block.words, &ENDS);
        let forced = match &self.region {
            Region::Main => None,
            Region::Body(why) | Region::After(why) => Some(why.clone()),
        };
        match forced {
            None => self.main_line(parsed, block, label),
            Some(why) => {
                self.block(block, Some(&why));
                self.call(parsed, block);
            }
        }
        let endsub = matches!(&parsed.statement, Some(Statement::OWord { keyword, .. }) if keyword == "ENDSUB");
        if ends || endsub {
            self.leave(block, line, endsub);
        }
    }

    /// Enters the program numbered `key` (`o2000`), named `name`: a subprogram's body
    /// unless it is the main program's own number (a LinuxCNC `sub` never is).
    fn enter(&mut self, key: String, name: String, sub: bool) {
        let why = match (self.structure.calls.get(&key), &self.main_end) {
            (Some(call), _) => format!(
                "in {name}, run by {call} in the caller's modes: a subprogram's moves are not corrected"
            ),
            (None, _) if !sub && !self.started && matches!(self.region, Region::Main) => {
                // The main program's own number.
                return;
            }
            (None, Some(end)) => format!(
                "in {name}, after the main program's end ({end}): a subprogram no block of this file calls, run in its caller's modes, is not corrected"
            ),
            (None, None) => format!(
                "in {name}: a program no block of this file calls, run in its caller's modes, is not corrected"
            ),
        };
        if matches!(self.region, Region::Main) {
            self.saved = Some(std::mem::replace(&mut self.state, State::new()));
        }
        self.region = Region::Body(why);
    }

    /// Leaves the main program or a subprogram at its end (`M30`, `M2`, `M99`, `endsub`).
    fn leave(&mut self, block: &Block, line: usize, endsub: bool) {
        let code = block
            .words
            .iter()
            .find(|w| {
                w.letter == b'M'
                    && matches!(w.value, Value::Number(n) if code(&n).is_some_and(|c| ENDS.contains(&c)))
            })
            .map_or_else(|| "endsub".to_string(), |w| w.text(block.src));
        match self.region {
            Region::Main => {
                self.main_end = Some(format!("{code} at line {line}"));
            }
            Region::Body(_) if endsub || code == "M99" => {
                if let Some(saved) = self.saved.take() {
                    self.state = saved;
                }
            }
            Region::Body(_) | Region::After(_) => {
                self.saved = None;
                self.main_end
                    .get_or_insert(format!("{code} at line {line}"));
            }
        }
        self.region = match (&self.main_end, self.saved.is_some()) {
            (Some(end), false) => Region::After(format!(
                "after the main program's end ({end}): run only when called or jumped to, in the caller's modes, not corrected"
            )),
            _ => Region::Main,
        };
    }

    /// A line of the main program: its jumps, loops, tool, the block, its call, and what a
    /// block-delete (`/`) makes of the modes after it.
    fn main_line(&mut self, parsed: &Parsed, block: &Block, label: Option<u32>) {
        let line = block.line_number;
        if let Some(n) = label {
            self.label(n, line);
        }
        let before = parsed.deleted.then(|| self.state.clone());
        match &parsed.statement {
            Some(Statement::Jump {
                label, conditional, ..
            }) => {
                if let Some(n) = label {
                    if self.structure.labels.get(n).is_some_and(|&l| l > line) {
                        let jump = format!("the GOTO {n} at line {line}");
                        self.pending
                            .entry(*n)
                            .or_default()
                            .push((self.state.clone(), jump));
                    }
                }
                if !conditional && !parsed.deleted {
                    self.reachable = false;
                }
            }
            Some(Statement::Do { id, .. }) => {
                if let Some(&(mask, end)) = self.structure.loops.get(&line) {
                    let desc = format!("the loop DO{id} of lines {line}-{end}");
                    self.state.mark_groups(mask, &|g| {
                        format!("{desc} repeats blocks that may set the {}", g.what())
                    });
                    self.state.lose_position(line);
                    self.loop_exits.insert(end, (self.state.clone(), desc));
                }
            }
            Some(Statement::Assignment { system: true, at }) => {
                let src = block.src;
                let name_end = src.bytes[*at..block.end]
                    .iter()
                    .position(|b| matches!(b, b'=' | b' ' | b'\t' | b'(' | b';'))
                    .map_or(block.end, |p| at + p);
                self.state.unknown[Group::RunOffset as usize] = None;
                self.state.run_offset = Some(Modal {
                    what: format!(
                        "{} written at line {line}: a system variable (#1000 and above: work offsets, tool data, settings) set as the program runs",
                        shown(src.text(*at, name_end))
                    ),
                    reason: Reason::FrameUnknown,
                });
            }
            _ => {}
        }
        self.tool(block);
        self.block(block, None);
        self.call(parsed, block);
        if let Some(Statement::End { .. }) = parsed.statement {
            if let Some((start, desc)) = self.loop_exits.remove(&line) {
                self.state.merge(&start, line, &|g| {
                    format!(
                        "{desc} may run no time: the {} after it is not known",
                        g.what()
                    )
                });
            }
        }
        if let Some(before) = before {
            let src = block.src;
            let codes = |g: Group| -> String {
                block
                    .words
                    .iter()
                    .filter(|w| match (w.letter, w.value) {
                        (b'G', Value::Number(n)) => code(&n).and_then(group_of) == Some(g),
                        (b'T', _) => g == Group::Tool,
                        _ => false,
                    })
                    .map(|w| format!(" {}", w.text(src)))
                    .collect()
            };
            self.state.merge(&before, line, &|g| {
                format!(
                    "line {line} is a block-delete (/) block{}: the switch decides whether it runs, so the {} after it is not known",
                    codes(g),
                    g.what()
                )
            });
        }
    }

    /// A block number: where jumps land, the state where they meet.
    fn label(&mut self, n: u32, line: usize) {
        let forward = self.pending.remove(&n);
        let back = self.structure.backward.get(&n).cloned();
        let computed = self.structure.computed_jump.clone();
        if forward.is_none() && back.is_none() && computed.is_none() {
            return;
        }
        let here = format!("N{n} (line {line})");
        let mut sources = forward.unwrap_or_default();
        if !self.reachable && !sources.is_empty() {
            self.state = sources.remove(0).0;
        }
        for (other, jump) in &sources {
            self.state.merge(other, line, &|g| {
                format!("{here} is reached by {jump} in another {}", g.what())
            });
        }
        if let Some((mask, jump)) = back {
            self.state.mark_groups(mask, &|g| {
                format!(
                    "{here} is reached again by {jump}, after blocks that may set the {}",
                    g.what()
                )
            });
            self.state.lose_position(line);
        }
        if let Some(jump) = computed {
            self.state.mark_groups(ALL_GROUPS, &|g| {
                format!(
                    "{here} may be reached by {jump}, to a block number computed as the program runs: the {} is not known",
                    g.what()
                )
            });
            self.state.lose_position(line);
        }
        self.reachable = true;
    }

    /// The tools a block selects: another than the first is a TCP `--tool` does not give.
    fn tool(&mut self, block: &Block) {
        let change = has_m(block.words, &[60]);
        for w in block.words.iter().filter(|w| w.letter == b'T') {
            let key = match w.value {
                Value::Number(n) => whole(&n).map(|t| format!("T{t}")),
                Value::Expression => None,
            };
            let state = &mut self.state;
            match (&state.first_tool, key) {
                (None, key) => state.first_tool = Some(key.unwrap_or_else(|| w.text(block.src))),
                (Some(first), Some(key)) if *first == key => {
                    if change {
                        state.tool = None;
                    }
                }
                _ => {
                    state.tool = Some(Modal {
                        what: format!(
                            "tool {} selected at line {}: --tool gives one TCP, the first tool's",
                            w.text(block.src),
                            block.line_number
                        ),
                        reason: Reason::FrameUnknown,
                    });
                }
            }
            if change {
                state.unknown[Group::Tool as usize] = None;
            }
        }
    }

    /// A call of a subprogram: one the file holds leaves the groups its blocks set not
    /// known; one it does not hold is reported, and leaves every mode not known.
    fn call(&mut self, parsed: &Parsed, block: &Block) {
        let Some(call) = call_of(block.src, parsed) else {
            return;
        };
        let line = block.line_number;
        let held = call
            .key
            .as_ref()
            .and_then(|k| self.structure.bodies.get(k).copied());
        let (mask, what) = match held {
            Some(mask) => (
                mask,
                format!("{}, run by {} at line {line},", call.program, call.text),
            ),
            None => {
                let (reason, detail) = match &call.key {
                    Some(_) => (
                        Reason::NotDeclared,
                        format!(
                            "{}: {} is not in this file; its moves are not corrected here",
                            call.text, call.program
                        ),
                    ),
                    None => (
                        Reason::Dynamic,
                        format!(
                            "{}: a program not named by a number (computed as the program runs, or not written); its moves are not corrected here",
                            call.text
                        ),
                    ),
                };
                self.found.first_motion.get_or_insert(call.at);
                let name = call.text.split(' ').next().unwrap_or("M98").to_string();
                self.found.refuse(call.at, name, reason, detail);
                (
                    ALL_GROUPS,
                    format!(
                        "{} at line {line}, which this file does not hold,",
                        call.text
                    ),
                )
            }
        };
        self.state.mark_groups(mask, &|g| {
            format!("{what} may set the {} the moves after it are in", g.what())
        });
        self.state.lose_position(line);
    }

    /// Reads one block (its words, not empty); `forced` says why its moves are not
    /// corrected, when they are not whatever the modes (a subprogram's body).
    fn block(&mut self, block: &Block, forced: Option<&str>) {
        let work_before = self.state.work.clone();
        let codes = self.state.read_codes(block);
        let axis_words: Vec<&Word> = block
            .words
            .iter()
            .filter(|w| b"XYZABCUVWIJKR".contains(&w.letter))
            .collect();
        let has_position = block.words.iter().any(|w| b"XYZABCUVW".contains(&w.letter));
        if self.state.work != work_before {
            // An arc after the change starts in another frame than the last target's.
            self.state.at_target = None;
        }
        if codes.data {
            return;
        }
        let line = block.line_number;
        if let Some(other) = codes.other_motion {
            self.found.first_motion.get_or_insert(other.at);
            let detail = match forced {
                Some(why) => format!("{} {why}", other.name),
                None => other.detail,
            };
            let reason = if forced.is_some() {
                Reason::Dynamic
            } else {
                other.reason
            };
            self.found.refuse(other.at, other.name, reason, detail);
            if has_position {
                self.state.lose_position(line);
            }
            return;
        }
        if let Some((m, _)) = codes.motion {
            self.state.mode = Some(m);
            self.state.unknown[Group::Motion as usize] = None;
        }
        let Some(first_axis) = axis_words.first() else {
            return;
        };
        let unknown_mode = self.state.unknown[Group::Motion as usize].clone();
        let refused = match (forced, unknown_mode) {
            (Some(why), _) => Some((Reason::Dynamic, why.to_string())),
            (None, Some(u)) => Some((u.reason, u.detail)),
            (None, None) => None,
        };
        if let Some((reason, why)) = refused {
            let at = codes.motion.map_or(first_axis.at, |m| m.1);
            let name = match self.state.mode {
                Some(mode) => mode.name(),
                None => block.src.text(at, at + 1),
            };
            self.found.first_motion.get_or_insert(at);
            self.found
                .refuse(at, name.clone(), reason, format!("{name} {why}"));
            self.state.lose_position(line);
            return;
        }
        let Some(mode) = self.state.mode else {
            let at = first_axis.at;
            self.found.first_motion.get_or_insert(at);
            self.found.refuse(
                at,
                block.src.text(at, at + 1),
                Reason::UnknownMotion,
                "axis words with no motion mode (G0, G1, G2, G3) in force".into(),
            );
            return;
        };
        let mv = Move {
            written: Written::of(&axis_words),
            machine: codes.machine,
            mode,
            written_mode: codes.motion.is_some(),
            name: mode.name(),
            at: codes.motion.map_or(first_axis.at, |m| m.1),
        };
        self.found.first_motion.get_or_insert(mv.at);
        let outcome = self.state.outcome(block, &mv, self.options);
        self.state
            .advance(&mv.written, mv.machine, block.line_number);
        self.push(outcome, mv);
    }

    /// Records what became of a move.
    fn push(&mut self, outcome: Outcome, mv: Move) {
        let work_offset = self.state.work_offset();
        match outcome {
            Outcome::Refused(reason, detail) => {
                self.found.refuse(mv.at, mv.name, reason, detail);
            }
            Outcome::Incomplete(why) => {
                self.found.push(
                    target(mv.name, mv.at, TargetKind::Incomplete(why)),
                    None,
                    work_offset,
                );
            }
            Outcome::Target { orientation, arc } => {
                let [x, y, z] =
                    [0, 1, 2].map(|i| mv.written.numbers[i].expect("all three written"));
                let unit = if self.state.inch {
                    LengthUnit::Inch
                } else {
                    LengthUnit::Millimetre
                };
                let kind = TargetKind::Cartesian(Box::new(CartesianTarget {
                    position: [x, y, z],
                    unit,
                    orientation,
                    config: ConfigHint::None,
                    joints: Vec::new(),
                }));
                self.state.at_target = Some(self.found.targets.len());
                self.found
                    .push(target(mv.name, mv.at, kind), arc, work_offset);
            }
        }
    }
}

/// Reads the targets of a G-code program.
///
/// # Errors
///
/// [`Error::Syntax`] at the first malformed word.
pub fn read(src: &Source, options: &GcodeOptions) -> Result<Read, Error> {
    read_at_most(src, options, usize::MAX)
}

/// [`read`], stopping after `limit` targets ([`Program::truncated_at`]).
///
/// # Errors
///
/// As [`read`].
pub fn read_at_most(src: &Source, options: &GcodeOptions, limit: usize) -> Result<Read, Error> {
    let mut reader = Reader {
        options,
        state: State::new(),
        found: Found::default(),
        structure: Structure::of(src)?,
        region: Region::Main,
        saved: None,
        main_end: None,
        started: false,
        reachable: true,
        pending: HashMap::new(),
        loop_exits: HashMap::new(),
    };
    let mut truncated_at = None;
    for line in program_lines(src) {
        if reader.found.targets.len() > limit {
            truncated_at = Some(line.start);
            break;
        }
        let parsed = parse_line(src, line.start, line.end)?;
        if parsed.words.is_empty() && parsed.statement.is_none() {
            continue;
        }
        reader.line(
            &parsed,
            &Block {
                src,
                words: &parsed.words,
                line_number: line.number,
                end: line.end,
            },
        );
    }
    let found = reader.found;
    debug_assert_eq!(found.offsets.len(), found.targets.len());
    Ok(Read {
        program: Program {
            format: Format::Gcode,
            targets: found.targets,
            truncated_at,
            first_motion: found.first_motion,
            in_partner: Vec::new(),
        },
        arcs: found.arcs,
        work_offsets: found.offsets,
    })
}

impl Word {
    /// The end of the word's text.
    fn value_end(&self, src: &Source) -> usize {
        match self.value {
            Value::Number(n) => n.span.1,
            Value::Expression => words_end(src, self.at, src.bytes.len()),
        }
    }

    /// The word's text, upper case (`G1`, `D12`, `U5.`).
    fn text(&self, src: &Source) -> String {
        src.text(self.at, self.value_end(src)).to_ascii_uppercase()
    }
}

/// The end of the word at `at`: before the next blank, comment or the line's end.
fn words_end(src: &Source, at: usize, end: usize) -> usize {
    let mut i = at + 1;
    while i < end && !matches!(src.bytes[i], b' ' | b'\t' | b'(' | b';' | b'\n' | b'\r') {
        i += 1;
    }
    i
}

/// The centre (u, v) of an arc from `s` to `e` of radius `r` (negative: more than a half
/// turn), turning clockwise or not about the plane's normal.
fn centre_from_radius(
    s: [f64; 3],
    e: [f64; 3],
    r: f64,
    clockwise: bool,
    plane: Plane,
) -> Result<[f64; 2], String> {
    let [u, v, _] = plane.axes();
    let (du, dv) = (e[u] - s[u], e[v] - s[v]);
    let chord = du.hypot(dv);
    if chord < 1e-9 {
        return Err("an arc by its radius R whose start and end are one point".into());
    }
    let half = chord / 2.0;
    if r.abs() < half - 1e-6 {
        return Err(format!(
            "R {:.4} mm is less than half its chord ({half:.4} mm)",
            r.abs()
        ));
    }
    let h = (r * r - half * half).max(0.0).sqrt();
    // The centre left of the chord (seen from the normal) for a counter-clockwise arc of
    // at most a half turn.
    let (lu, lv) = (-dv / chord, du / chord);
    let side = if clockwise { -1.0 } else { 1.0 } * r.signum();
    Ok([
        s[u] + du / 2.0 + side * h * lu,
        s[v] + dv / 2.0 + side * h * lv,
    ])
}

/// The turn of an arc from angle `a0` to `a1` (rad) in its direction, in (0, 2π]: a full
/// circle when they are one.
fn sweep(a0: f64, a1: f64, clockwise: bool) -> f64 {
    let tau = std::f64::consts::TAU;
    let d = if clockwise { a0 - a1 } else { a1 - a0 };
    let d = d.rem_euclid(tau);
    if d < 1e-12 {
        tau
    } else {
        d
    }
}

/// An arc's shape in its plane: centre (u, v), start and end, radii at each end, its sweep.
struct Shape {
    centre: [f64; 2],
    start: [f64; 3],
    end: [f64; 3],
    angle0: f64,
    radius0: f64,
    radius1: f64,
    sweep: f64,
    clockwise: bool,
    plane: Plane,
}

impl Shape {
    fn new(
        centre: [f64; 2],
        start: [f64; 3],
        end: [f64; 3],
        clockwise: bool,
        plane: Plane,
    ) -> Shape {
        let [u, v, _] = plane.axes();
        let polar = |p: [f64; 3]| {
            let (du, dv) = (p[u] - centre[0], p[v] - centre[1]);
            (dv.atan2(du), du.hypot(dv))
        };
        let (angle0, radius0) = polar(start);
        let (angle1, radius1) = polar(end);
        Shape {
            centre,
            start,
            end,
            angle0,
            radius0,
            radius1,
            sweep: sweep(angle0, angle1, clockwise),
            clockwise,
            plane,
        }
    }

    /// The point at fraction `f` of the way (radius and height in proportion).
    fn at(&self, f: f64) -> [f64; 3] {
        let [u, v, n] = self.plane.axes();
        let turn = if self.clockwise { -1.0 } else { 1.0 } * self.sweep * f;
        let angle = self.angle0 + turn;
        let radius = self.radius0 + (self.radius1 - self.radius0) * f;
        let mut p = [0.0; 3];
        p[u] = self.centre[0] + radius * angle.cos();
        p[v] = self.centre[1] + radius * angle.sin();
        p[n] = self.start[n] + (self.end[n] - self.start[n]) * f;
        p
    }

    /// The distance from `p` to the arc: to its point at `p`'s angle, or to its nearer end.
    fn distance(&self, p: [f64; 3]) -> f64 {
        let [u, v, _] = self.plane.axes();
        let angle = (p[v] - self.centre[1]).atan2(p[u] - self.centre[0]);
        let from_start = if self.clockwise {
            self.angle0 - angle
        } else {
            angle - self.angle0
        }
        .rem_euclid(std::f64::consts::TAU);
        let dist = |q: [f64; 3]| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        };
        if from_start <= self.sweep {
            dist(self.at(from_start / self.sweep))
        } else {
            dist(self.at(0.0)).min(dist(self.at(1.0)))
        }
    }
}

/// How many points along an arc its correction is checked at, ends included: one every
/// 2 mm of its length, 9 to 65.
fn samples(shape: &Shape) -> usize {
    let length = shape.sweep * shape.radius0.max(shape.radius1);
    ((length / 2.0).ceil() as usize).clamp(8, 64) + 1
}

/// The new numbers of a corrected arc's centre: each number and its value in program
/// units.
pub type CentreEdits = Vec<(Number, f64)>;

/// Moves an arc's centre for its corrected ends: `end_mm` its written end, `start_out` and
/// `end_out` where the compensated program's start and end are (mm), and `correct` the
/// command for a point of the written path (mm, program frame; `Err` why none). The
/// corrected path is the commands of points along the written arc; the new centre is the
/// one, on the corrected chord's bisector, nearest the written centre moved by the mean
/// correction, and the corrected arc it makes must lie within `tolerance_mm` of every
/// one of those commands.
///
/// # Errors
///
/// Why the arc cannot be corrected: a point of the path the table does not correct, the
/// corrected arc beyond the tolerance, or an offset the new centre needs but the block
/// does not write.
pub fn correct_arc(
    arc: &Arc,
    end_mm: [f64; 3],
    start_out: [f64; 3],
    end_out: [f64; 3],
    tolerance_mm: f64,
    correct: &mut dyn FnMut([f64; 3]) -> Result<[f64; 3], String>,
) -> Result<CentreEdits, String> {
    let [u, v, _] = arc.plane.axes();
    let written = Shape::new(
        arc.centre_mm,
        arc.start_mm,
        end_mm,
        arc.clockwise,
        arc.plane,
    );
    let n = samples(&written);
    let mut path = Vec::with_capacity(n);
    let mut mean = [0.0; 2];
    for k in 0..n {
        let f = k as f64 / (n - 1) as f64;
        let p = written.at(f);
        let c = correct(p).map_err(|why| {
            format!(
                "no correction at {:.0}% of the arc ({:.3}, {:.3}, {:.3}): {why}",
                f * 100.0,
                p[0],
                p[1],
                p[2]
            )
        })?;
        mean[0] += (c[u] - p[u]) / n as f64;
        mean[1] += (c[v] - p[v]) / n as f64;
        path.push((f, c));
    }
    let guess = [arc.centre_mm[0] + mean[0], arc.centre_mm[1] + mean[1]];
    let (du, dv) = (end_out[u] - start_out[u], end_out[v] - start_out[v]);
    let chord = du.hypot(dv);
    // A full circle's ends are one point: its centre moves by the mean correction.
    let full = written.sweep >= std::f64::consts::TAU;
    if full && chord > 1e-6 {
        return Err(format!(
            "a full circle (its written start and end one point) whose corrected start and end are {chord:.4} mm apart: the controller would not turn it full"
        ));
    }
    let end_out = if full { start_out } else { end_out };
    let centre = if chord > 1e-9 && !full {
        let mid = [start_out[u] + du / 2.0, start_out[v] + dv / 2.0];
        let (nu, nv) = (-dv / chord, du / chord);
        let t = (guess[0] - mid[0]) * nu + (guess[1] - mid[1]) * nv;
        [mid[0] + t * nu, mid[1] + t * nv]
    } else {
        guess
    };
    let corrected = Shape::new(centre, start_out, end_out, arc.clockwise, arc.plane);
    if (corrected.sweep - written.sweep).abs() > std::f64::consts::PI {
        return Err("the corrected ends turn the arc the other way round its centre".into());
    }
    let (worst, at) = path
        .iter()
        .map(|(f, c)| (corrected.distance(*c), *f))
        .fold((0.0f64, 0.0), |a, b| if b.0 > a.0 { b } else { a });
    if worst.is_nan() || worst > tolerance_mm {
        return Err(format!(
            "the corrected arc is {worst:.4} mm from the corrected path at {:.0}% of its sweep (tolerance {tolerance_mm} mm)",
            at * 100.0
        ));
    }
    let mut edits = Vec::new();
    match arc.centre {
        Centre::Radius(r) => {
            let radius = (centre[0] - start_out[u]).hypot(centre[1] - start_out[v]);
            edits.push((r, radius.copysign(r.value) / arc.unit_mm));
        }
        Centre::Offsets { numbers, absolute } => {
            let values = if absolute {
                centre
            } else {
                [centre[0] - start_out[u], centre[1] - start_out[v]]
            };
            for (k, number) in numbers.iter().enumerate() {
                let value = values[k] / arc.unit_mm;
                match number {
                    Some(n) => edits.push((*n, value)),
                    None if value.abs() < 0.5e-4 / arc.unit_mm => {}
                    None => {
                        let letter = b"IJK"[[u, v][k]] as char;
                        return Err(format!(
                            "{letter} is not written on this block, and the corrected centre needs {letter}{value:.4}"
                        ));
                    }
                }
            }
        }
    }
    Ok(edits)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_text(text: &str, options: &GcodeOptions) -> Read {
        read(&Source::new("p.nc", text.as_bytes()), options).unwrap()
    }

    fn statuses(r: &Read) -> Vec<(String, &'static str)> {
        r.program
            .targets
            .iter()
            .map(|t| {
                (
                    t.name.clone(),
                    match (&t.refused, &t.kind) {
                        (Some(r), _) => r.reason.as_str(),
                        (None, TargetKind::Incomplete(_)) => "incomplete",
                        (None, TargetKind::Cartesian(_)) => "target",
                        _ => "other",
                    },
                )
            })
            .collect()
    }

    #[test]
    fn blocks_comments_and_modal_axes() {
        let text = "%\n(POCKET, POST 1.2)\nN10 G21 G90 G17\nN20 G0 X1500. Y400. Z1300. A0 B90 C0 (rapid)\n\
                    N30 G1 Z1250.5 F800 ; plunge\nN40 X1520 Y400 Z1250.5\nN50 G2 X1540 Y400 Z1250.5 I10 J0\n\
                    N60 M30\n%\n";
        let r = read_text(text, &GcodeOptions::default());
        assert_eq!(
            statuses(&r),
            [
                ("G0".to_string(), "target"),
                ("G1".to_string(), "incomplete"),
                ("G1".to_string(), "target"),
                ("G2".to_string(), "target"),
            ]
        );
        let TargetKind::Incomplete(why) = &r.program.targets[1].kind else {
            unreachable!()
        };
        assert!(
            why.starts_with("X (modal from line 4), Y (modal from line 4) not written"),
            "{why}"
        );
        // The modal A, B, C of line 4 give the orientation of line 6.
        let TargetKind::Cartesian(c) = &r.program.targets[2].kind else {
            unreachable!()
        };
        let Some(Orientation::KukaAbcDeg(abc)) = c.orientation else {
            unreachable!()
        };
        assert_eq!(abc.map(|n| n.value), [0.0, 90.0, 0.0]);
        // The arc starts where line 6 ends, its centre 10 mm along X.
        let arc = r.arcs[3].as_ref().unwrap();
        assert_eq!(arc.start_target, 2);
        assert_eq!(arc.centre_mm, [1530.0, 400.0]);
    }

    #[test]
    fn every_other_motion_is_reported_by_its_reason() {
        let text = "G21 G90 G54\nG0 X1 Y2 Z3\nG28 X0 Y0 Z0\nG53 G0 Z0\nG91 G1 X1 Y1 Z1\nG90\n\
                    G41 D1 G1 X1 Y2 Z3\nG40\nG81 X1 Y2 Z-3 R1\nG80\nG68 X0 Y0 R30\nG1 X1 Y2 Z3\nG69\n\
                    G1 X1 Y2 U4 Z1\nG1 X#1 Y2 Z3\nG5.1 X1 Y2 Z3\nG59.1\nG1 X1 Y2 Z3\nG55\nG1 X1 Y2 Z3\n";
        let options = GcodeOptions {
            work_offsets: vec![(54, [0.0; 6])],
            ..GcodeOptions::default()
        };
        let r = read_text(text, &options);
        let s: Vec<&str> = statuses(&r).into_iter().map(|s| s.1).collect();
        assert_eq!(
            s,
            [
                "target",
                "dynamic",
                "frame_unknown",
                "relative",
                "relative",
                "unknown_motion",
                "frame_unknown",
                "external_axis",
                "dynamic",
                "unknown_motion",
                "frame_unknown",
                "frame_unknown",
            ]
        );
        let extended = r.program.targets[r.program.targets.len() - 2]
            .refused
            .as_ref()
            .unwrap();
        assert_eq!(
            extended.detail,
            "work offset G59.1 not given: the options give G54-G59 only"
        );
        let last = r.program.targets.last().unwrap().refused.as_ref().unwrap();
        assert_eq!(
            last.detail,
            "work offset G55 not given: give it as --work-offset G55=X,Y,Z[,A,B,C]"
        );
    }

    #[test]
    fn a_radius_gives_the_centre_on_the_side_its_sign_and_direction_say() {
        // A quarter turn counter-clockwise from (10, 0) to (0, 10) about the origin.
        let c =
            centre_from_radius([10.0, 0.0, 0.0], [0.0, 10.0, 0.0], 10.0, false, Plane::Xy).unwrap();
        assert!(c[0].abs() < 1e-9 && c[1].abs() < 1e-9, "{c:?}");
        // Clockwise, three quarters (R negative): the same centre.
        let c =
            centre_from_radius([10.0, 0.0, 0.0], [0.0, 10.0, 0.0], -10.0, true, Plane::Xy).unwrap();
        assert!(c[0].abs() < 1e-9 && c[1].abs() < 1e-9, "{c:?}");
        assert!(centre_from_radius([0.0; 3], [30.0, 0.0, 0.0], 10.0, false, Plane::Xy).is_err());
    }

    #[test]
    fn a_uniform_correction_moves_the_centre_with_it_and_a_bent_one_is_refused() {
        let arc = Arc {
            clockwise: true,
            plane: Plane::Xy,
            start_target: 0,
            start_mm: [1500.0, 400.0, 1250.0],
            centre_mm: [1510.0, 400.0],
            centre: Centre::Offsets {
                numbers: [parse_number(b"10", 0), parse_number(b"0", 0)],
                absolute: false,
            },
            unit_mm: 1.0,
        };
        let end = [1520.0, 400.0, 1250.0];
        let shift = [0.3, -0.2, 0.1];
        let moved = |p: [f64; 3]| [p[0] + shift[0], p[1] + shift[1], p[2] + shift[2]];
        let edits = correct_arc(&arc, end, moved(arc.start_mm), moved(end), 0.01, &mut |p| {
            Ok(moved(p))
        })
        .unwrap();
        assert!(
            edits.iter().all(|(n, v)| (n.value - v).abs() < 1e-9),
            "{edits:?}"
        );
        // A correction that grows along x by 1e-3 per mm: the arc bends by more than the
        // tolerance.
        let bent = |p: [f64; 3]| [p[0], p[1] + 1e-3 * (p[0] - 1500.0).powi(2), p[2]];
        let err = correct_arc(&arc, end, bent(arc.start_mm), bent(end), 0.01, &mut |p| {
            Ok(bent(p))
        })
        .unwrap_err();
        assert!(err.starts_with("the corrected arc is"), "{err}");
    }

    #[test]
    fn work_offsets_parse_as_the_command_line_writes_them() {
        assert_eq!(
            parse_work_offset("G54=1,2,3").unwrap(),
            (54, [1.0, 2.0, 3.0, 0.0, 0.0, 0.0])
        );
        assert_eq!(parse_work_offset("G59=1,2,3,0,90,0").unwrap().1[4], 90.0);
        assert!(parse_work_offset("G60=1,2,3").is_err());
        assert!(parse_work_offset("G54=1,2").is_err());
        assert!(parse_work_offset("G54=1,2,nan").is_err());
    }

    #[test]
    fn a_malformed_word_is_located() {
        let err = read(
            &Source::new("p.nc", b"G1 X10 Y\n"),
            &GcodeOptions::default(),
        )
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "p.nc:1:8: the word Y has no number: found the end of the line"
        );
        let err = read(
            &Source::new("p.nc", b"G1 X10 (open\n"),
            &GcodeOptions::default(),
        )
        .unwrap_err();
        assert!(err.to_string().starts_with("p.nc:1:8: a comment"), "{err}");
    }

    fn g54() -> GcodeOptions {
        GcodeOptions {
            work_offsets: vec![(54, [1750.0, 450.0, 1200.0, 0.0, 0.0, 0.0])],
            ..GcodeOptions::default()
        }
    }

    fn detail(r: &Read, k: usize) -> String {
        match (&r.program.targets[k].refused, &r.program.targets[k].kind) {
            (Some(refusal), _) => refusal.detail.clone(),
            (None, TargetKind::Incomplete(why)) => why.clone(),
            _ => String::new(),
        }
    }

    fn only_statuses(r: &Read) -> Vec<&'static str> {
        statuses(r).into_iter().map(|s| s.1).collect()
    }

    #[test]
    fn a_subprograms_moves_are_reported_by_its_call_and_a_call_out_of_the_file_too() {
        let text = "%\nO1000 (MAIN)\nG21 G90 G17 G54\nG0 X-60. Y-50. Z50. A0. B90. C0.\nG91\n\
                    M98 P2000 L3\nG90\nG0 X-60. Y-50. Z50. A0. B90. C0.\nM98 P9000\n\
                    G0 X-60. Y-50. Z50. A0. B90. C0.\nG90 G21 G54 G17 G40 G49 G69 G92.1 G67 G91.1 T1 M6\n\
                    G0 X-60. Y-50. Z50. A0. B90. C0.\nM30\nO2000 (SUB - RELATIVE STEP)\n\
                    G1 X10. Y0. Z-1. A0. B90. C0. F300.\nM99\nO3000\nG1 X1. Y2. Z3. A0. B90. C0.\nM99\n%\n";
        let r = read_text(text, &g54());
        assert_eq!(
            only_statuses(&r),
            [
                "target",
                "target",
                "not_declared",
                "dynamic",
                "target",
                "dynamic",
                "dynamic"
            ]
        );
        assert_eq!(
            detail(&r, 2),
            "M98 P9000: O9000 is not in this file; its moves are not corrected here"
        );
        assert!(
            detail(&r, 3).contains("M98 P9000 at line 9, which this file does not hold,"),
            "{}",
            detail(&r, 3)
        );
        assert_eq!(
            detail(&r, 5),
            "G1 in O2000, run by M98 P2000 at line 6 in the caller's modes: a subprogram's moves are not corrected"
        );
        assert!(
            detail(&r, 6).starts_with("G1 in O3000, after the main program's end (M30 at line 13)")
        );
        // A subprogram before the main program, and its G55 the caller's after the call.
        let text = "O2000\nG55 G1 X10. Y0. Z-1. A0. B90. C0.\nM99\nO1000\nG21 G90 G54\n\
                    G0 X-60. Y-50. Z50. A0. B90. C0.\nM98 P2000\nG0 X-60. Y-50. Z50. A0. B90. C0.\nM30\n";
        let r = read_text(text, &g54());
        assert_eq!(only_statuses(&r), ["dynamic", "target", "frame_unknown"]);
        // G65's words are its arguments; LinuxCNC's o-word subroutines read alike.
        let text = "o100 sub\nG1 X1 Y2 Z3\no100 endsub\nG21 G90\nG0 X1 Y2 Z3\nG65 P9010 A1. B2. X3.\no100 call\n\
                    G1 X1 Y2 Z3\nM2\n";
        let r = read_text(text, &GcodeOptions::default());
        assert_eq!(
            only_statuses(&r),
            ["dynamic", "target", "not_declared", "dynamic"]
        );
    }

    #[test]
    fn after_g70_or_g71_no_move_is_corrected_until_g20_or_g21() {
        let text = "; SINUMERIK inch\nN10 G17 G90 G54 G70\nN20 G0 X-2.3622 Y-1.9685 Z1.9685 A0. B90. C0.\n\
                    N30 G20\nN40 G0 X-2.3622 Y-1.9685 Z1.9685 A0. B90. C0.\nN50 M30\n";
        let r = read_text(text, &g54());
        assert_eq!(
            only_statuses(&r),
            ["unknown_motion", "unknown_motion", "target"]
        );
        assert!(
            detail(&r, 1).starts_with("G0: G70 (line 2): inches (G70)"),
            "{}",
            detail(&r, 1)
        );
    }

    #[test]
    fn a_computed_g_code_or_a_system_variable_leaves_the_modes_after_it_unknown() {
        let text = "%\nG90 G17 G21 G54\n#100=91\nG0 X-60. Y-50. Z50. A0. B90. C0.\nG#100\n\
                    G1 X-45. Y-35. Z5. A0. B90. C0.\n%\n";
        let r = read_text(text, &g54());
        assert_eq!(only_statuses(&r), ["target", "dynamic", "dynamic"]);
        assert!(
            detail(&r, 2).contains("G#100 (line 5)"),
            "{}",
            detail(&r, 2)
        );
        let text = "G90 G17 G21 G54\n#1=2.\n#5221=100.\nG1 X-45. Y-35. Z5. A0. B90. C0. F300.\n";
        let r = read_text(text, &g54());
        assert_eq!(only_statuses(&r), ["frame_unknown"]);
        assert!(
            detail(&r, 0).contains("#5221 written at line 3"),
            "{}",
            detail(&r, 0)
        );
        let r = read_text("G90 G54\n#1=2.\n#999=1\nG1 X1 Y2 Z3\n", &g54());
        assert_eq!(only_statuses(&r), ["target"]);
    }

    #[test]
    fn a_block_delete_block_leaves_either_mode_after_it() {
        let text = "%\nG21 G91 G17 G54\n/G90\nG1 X10. Y0. Z-1. A0. B90. C0. F300.\nG90\n\
                    G1 X10. Y0. Z-1.\n/G55\nG1 X10. Y0. Z-1.\n/G54\nG1 X10. Y0. Z-1.\nM30\n%\n";
        let r = read_text(text, &g54());
        assert_eq!(
            only_statuses(&r),
            ["relative", "target", "frame_unknown", "frame_unknown"]
        );
        assert!(
            detail(&r, 0).contains("line 3 is a block-delete (/) block G90"),
            "{}",
            detail(&r, 0)
        );
    }

    #[test]
    fn a_word_written_twice_leaves_its_block_incomplete() {
        let text = "G90 G17 G21 G54\nG1 X-45. Y-35. Z5. A0. B90. C0. F300.\nG1 X-45. X-44. Y-35. Z5. A0. B90. C0.\n";
        let r = read_text(text, &g54());
        assert_eq!(only_statuses(&r), ["target", "incomplete"]);
        assert_eq!(
            detail(&r, 1),
            "X written twice on this block (X-45. and X-44.): a controller alarms on it"
        );
    }

    #[test]
    fn moves_after_a_second_tool_are_frame_unknown() {
        let text = "G90 G17 G21 G54\nT1 D1 M6\nG1 X-45. Y-35. Z5. A0. B90. C0. F300.\nT2\n\
                    G1 X-45. Y-35. Z5.\nM6 T1\nG1 X-45. Y-35. Z5.\n";
        let r = read_text(text, &g54());
        assert_eq!(only_statuses(&r), ["target", "frame_unknown", "target"]);
        assert!(detail(&r, 1).contains("tool T2 selected at line 4: --tool gives one TCP"));
    }

    #[test]
    fn messages_quote_text_as_written() {
        let err = read(
            &Source::new("p.nc", b"G1 X10 Y'5\n"),
            &GcodeOptions::default(),
        )
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "p.nc:1:8: the word Y has no number: found ''5'"
        );
    }

    #[test]
    fn jumps_and_loops_leave_unknown_only_the_modes_that_differ() {
        // An unconditional GOTO: the block after it is not run, N10 is in G91.
        let text = "%\nG21 G90 G17 G54\nG0 X-60. Y-50. Z50. A0. B90. C0.\nG91\nGOTO 10\nG90\n\
                    N10 G1 X10. Y0. Z-1. A0. B90. C0. F300.\nG90\nG1 X10. Y0. Z-1. A0. B90. C0.\nM30\n%\nafter the tape's end X1 Y2 Z3\n";
        let r = read_text(text, &g54());
        assert_eq!(only_statuses(&r), ["target", "relative", "target"]);
        // A conditional one: N20 in G54 or G55.
        let text = "G21 G90 G17 G54\n#1=0\nG0 X-60. Y-50. Z50. A0. B90. C0.\nIF [#1 EQ 0] GOTO 20\nG55\n\
                    N20 G1 X10. Y0. Z-1. A0. B90. C0. F300.\nN30 G1 X10. Y0. Z-1.\nIF [#1 EQ 1] GOTO 30\n\
                    G54 G1 X10. Y0. Z-1. A0. B90. C0.\nM30\n";
        let r = read_text(text, &g54());
        assert_eq!(
            only_statuses(&r),
            ["target", "frame_unknown", "frame_unknown", "target"]
        );
        assert!(detail(&r, 1).contains("N20 (line 6) is reached by the GOTO 20 at line 4"));
        // N30 is run again after line 8, still in G54 or G55 from N20.
        assert!(detail(&r, 2).contains("N20 (line 6)"), "{}", detail(&r, 2));
        // A loop whose blocks change the distance mode; one that does not leaves it known.
        let text = "G21 G90 G54\n#1=0\nWHILE [#1 LT 3] DO1\nG1 X10. Y0. Z-1.\nG91\n#1=#1+1\nEND1\n\
                    G1 X10. Y0. Z-1.\nWHILE [#1 LT 6] DO2\nG1 X10. Y0. Z-1.\n#1=#1+1\nEND2\nG90 G1 X10. Y0. Z-1.\n";
        let r = read_text(text, &g54());
        assert_eq!(
            only_statuses(&r),
            ["relative", "relative", "relative", "target"]
        );
        assert!(
            detail(&r, 0).contains("the loop DO1 of lines 3-7"),
            "{}",
            detail(&r, 0)
        );
        // LinuxCNC's o-word control flow is refused by name.
        let err = read(
            &Source::new("p.nc", b"o101 if [#1 GT 0]\nG1 X1 Y2 Z3\no101 endif\n"),
            &GcodeOptions::default(),
        )
        .unwrap_err();
        assert!(
            err.to_string().starts_with("p.nc:1:6: o101 if: LinuxCNC"),
            "{err}"
        );
    }

    #[test]
    fn a_full_circle_whose_corrected_ends_part_is_refused_as_such() {
        let arc = Arc {
            clockwise: true,
            plane: Plane::Xy,
            start_target: 0,
            start_mm: [0.0, 40.0, 0.0],
            centre_mm: [0.0, 20.0],
            centre: Centre::Offsets {
                numbers: [parse_number(b"0", 0), parse_number(b"-20", 0)],
                absolute: false,
            },
            unit_mm: 1.0,
        };
        let moved = |p: [f64; 3]| [p[0] + 1.0, p[1], p[2]];
        let end = arc.start_mm;
        let err = correct_arc(&arc, end, arc.start_mm, moved(end), 0.01, &mut |p| {
            Ok(moved(p))
        })
        .unwrap_err();
        assert!(err.starts_with("a full circle"), "{err}");
        // Moved alike at both ends, it stays a full circle about the moved centre.
        let edits = correct_arc(&arc, end, moved(end), moved(end), 0.01, &mut |p| {
            Ok(moved(p))
        })
        .unwrap();
        assert!(
            edits.iter().all(|(n, v)| (n.value - v).abs() < 1e-9),
            "{edits:?}"
        );
    }
}
