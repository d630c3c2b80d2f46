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
//! `G54`-`G59` select a work offset, which the job's options give; a move in one they do
//! not give is refused by its name (`frame_unknown`).

use crate::number::{parse_number, Number};
use crate::program::{
    CartesianTarget, ConfigHint, Format, LengthUnit, Orientation, Program, ProgramTarget, Reason,
    Refusal, TargetKind,
};
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

/// The words of the line `start..end`; `None` for a parameter assignment (`#1 = 2`).
fn words(src: &Source, start: usize, end: usize) -> Result<Option<Vec<Word>>, Error> {
    let bytes = src.bytes;
    let mut out = Vec::new();
    let mut i = start;
    if i == 0 && bytes.starts_with(b"\xef\xbb\xbf") {
        i = 3;
    }
    while i < end {
        let b = bytes[i];
        match b {
            b' ' | b'\t' | b'%' | b'/' => i += 1,
            b'(' => {
                let close = bytes[i..end].iter().position(|&c| c == b')');
                i = match close {
                    Some(p) => i + p + 1,
                    None => return Err(src.error(i, "a comment '(' without its ')'")),
                };
            }
            b';' => break,
            // A parameter's assignment (`#1 = 2`, `N5 #<depth> = 3`): no motion.
            b'#' => return Ok(None),
            _ if b.is_ascii_alphabetic() => {
                let letter = b.to_ascii_uppercase();
                let at = i;
                i = src.skip_blanks(i + 1).min(end);
                let value = match bytes.get(i) {
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
                                        src.describe(i).escape_default()
                                    ),
                                ))
                            }
                        }
                    }
                };
                out.push(Word { letter, at, value });
            }
            _ => {
                return Err(src.error(
                    i,
                    format!(
                        "expected a word (a letter and a number), found {}",
                        src.describe(i).escape_default()
                    ),
                ))
            }
        }
    }
    Ok(Some(out))
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

/// Something that puts the program's moves in a frame the options do not give, or offsets
/// them as the controller runs: what, where, and the reason.
#[derive(Clone, Debug)]
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
    /// Per axis X Y Z A B C, the number that last wrote it (absolute) and its line.
    modal: [Option<(Number, usize)>; 6],
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
            modal: [None; 6],
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

    /// The block's codes, in the order a controller applies them: the modes they set, and
    /// what they say of the block.
    fn read_codes(&mut self, block: &Block) -> BlockCodes {
        let mut codes = BlockCodes::default();
        for w in block.words {
            let Value::Number(n) = w.value else {
                if w.letter == b'G' {
                    codes.other_motion = Some(OtherMotion {
                        name: "G".into(),
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

    /// Forgets where the tool is: a move the reader cannot follow.
    fn lose_position(&mut self) {
        self.position = [None; 3];
        self.at_target = None;
        self.modal = [None; 6];
    }

    /// The state after a move that writes `written`, whatever becomes of its target.
    fn advance(&mut self, written: &Written, machine: bool, line_number: usize) {
        self.at_target = None;
        if machine || written.expression.is_some() {
            self.modal = [None; 6];
            self.position = [None; 3];
            return;
        }
        let unit_mm = self.unit_mm();
        for i in 0..6 {
            let Some(n) = written.numbers[i] else {
                continue;
            };
            if self.absolute {
                self.modal[i] = Some((n, line_number));
                if i < 3 {
                    self.position[i] = Some(n.value * unit_mm);
                }
            } else {
                self.modal[i] = None;
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
                match self.modal[i] {
                    Some((_, l)) => format!("{axis} (modal from line {l})"),
                    None => format!("{axis} (never written)"),
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
        let used_abc = (3..6).any(|i| written.numbers[i].is_some() || self.modal[i].is_some());
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
                let never: Vec<&str> = ["A", "B", "C"]
                    .into_iter()
                    .zip(&values)
                    .filter(|(_, n)| n.is_none())
                    .map(|(a, _)| a)
                    .collect();
                Err(format!(
                    "{} never written: the tool's orientation is not known",
                    never.join(", ")
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

/// The reader: the modal state and what it has found.
struct Reader<'o> {
    options: &'o GcodeOptions,
    state: State,
    found: Found,
}

impl Reader<'_> {
    /// Reads one block (its words, not empty).
    fn block(&mut self, block: &Block) {
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
        if let Some(other) = codes.other_motion {
            self.found.first_motion.get_or_insert(other.at);
            self.found
                .refuse(other.at, other.name, other.reason, other.detail);
            if has_position {
                self.state.lose_position();
            }
            return;
        }
        if let Some((m, _)) = codes.motion {
            self.state.mode = Some(m);
        }
        let Some(first_axis) = axis_words.first() else {
            return;
        };
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
    };
    let mut truncated_at = None;
    for line in src.lines() {
        if reader.found.targets.len() > limit {
            truncated_at = Some(line.start);
            break;
        }
        match words(src, line.start, line.end)? {
            Some(words) if !words.is_empty() => reader.block(&Block {
                src,
                words: &words,
                line_number: line.number,
                end: line.end,
            }),
            _ => {}
        }
    }
    let found = reader.found;
    debug_assert_eq!(found.offsets.len(), found.targets.len());
    Ok(Read {
        program: Program {
            format: Format::Gcode,
            targets: found.targets,
            truncated_at,
            first_motion: found.first_motion,
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
}
