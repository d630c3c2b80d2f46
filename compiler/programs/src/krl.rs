//! KUKA KRL: `.src` programs and `.dat` data lists.
//!
//! Targets are
//!
//! - declarations with an aggregate, with or without `DECL` (and `GLOBAL`, `CONST`):
//!   `DECL E6POS XP1={X 1500.0,Y 0.0,Z 1200.0,A 0.0,B 90.0,C 0.0,S 6,T 27,E1 0.0}`,
//!   `E6AXIS XHOME={A1 0.0,A2 -90.0,A3 90.0,A4 0.0,A5 0.0,A6 0.0}`, of the types `E6POS`,
//!   `POS` and `E6AXIS`, `AXIS`; a `FRAME` declaration only when the name is the target of
//!   a motion in the file or in its partner (`P.src` for `P.dat` and back): frames are as
//!   often base or tool offsets, which must not change;
//! - aggregates written in a motion: `PTP {A1 0,A2 -90,A3 90,A4 0,A5 0,A6 0}`,
//!   `LIN {X 1500,Y 0,Z 1200,A 0,B 90,C 0}`, `CIRC {…},{…}`.
//!
//! Every motion of [`MOTIONS`] is accounted for: its targets are corrected in the tool and
//! base the controller will apply, or reported (a [`Refusal`]): relative motions
//! (`LIN_REL`), targets computed at run time (`LIN XP1:XOFF`, a function), names declared
//! in neither file of the pair (`XHOME` of `$config.dat`), targets that move an external
//! axis (`E1` of a track), frames not given.
//!
//! The tool and base of a motion are those the controller applies, read in file order:
//! `$TOOL = TOOL_DATA[n]`, `$BASE = BASE_DATA[n]` (or `$NULLFRAME`, or a frame aggregate),
//! `BAS(#TOOL, n)`, `BAS(#BASE, n)`, an inline form's `FDAT_ACT = FPn` (the `FDAT`'s
//! `TOOL_NO` and `BASE_NO`, from either file), its `;FOLD … Tool[n] Base[m]` line, and a
//! spline motion's `WITH $TOOL = STOOL2(FPn), $BASE = SBASE(FPn.BASE_NO)` (for that motion
//! only). `TOOL_DATA[n]` and `BASE_DATA[n]` come from the controller's `$config.dat`
//! ([`read_config`]); number 0 is `$NULLFRAME` (the flange; the world, taken as the
//! robot's base frame). Before any of these, the job's `tool` and `base` options stand for
//! the controller's current `$TOOL` and `$BASE`. An external TCP (`IPO_FRAME #TCP`) is
//! refused.
//!
//! KRL is case-insensitive; statements are one per line; `;` starts a comment.

use std::collections::{HashMap, HashSet};

use nalgebra::Isometry3;

use crate::frames::kuka_pose;
use crate::lex::{Language, Lexer, Tok, Token};
use crate::number::Number;
use crate::program::{
    AngleUnit, CartesianTarget, ConfigHint, Format, FrameUse, JointTarget, LengthUnit, Orientation,
    PartnerPlace, Program, ProgramTarget, Reason, Refusal, TargetKind, Undeclared,
};
use crate::source::{same_name, Source};
use crate::Error;

const KRL: Language = Language {
    comment: b';',
    quotes: b"\"'",
    ident_extra: b"$#",
};

/// A motion instruction of KRL: its name, how many targets it takes (its first
/// arguments), and what becomes of them. KRL motions name no tool or base: those are the
/// controller's `$TOOL` and `$BASE` when the motion runs (module docs).
#[derive(Clone, Copy, Debug)]
pub struct Motion {
    /// The instruction.
    pub name: &'static str,
    /// Its targets: 1, or 2 for a circle (auxiliary point, end point).
    pub targets: usize,
    /// `None`: its targets are corrected; else why they are reported and left unchanged.
    pub refused: Option<Reason>,
}

const fn motion(name: &'static str, targets: usize, refused: Option<Reason>) -> Motion {
    Motion {
        name,
        targets,
        refused,
    }
}

/// The motion instructions of KRL (KSS 8), every one accounted for.
pub const MOTIONS: [Motion; 14] = [
    motion("PTP", 1, None),
    motion("LIN", 1, None),
    motion("CIRC", 2, None),
    motion("SPTP", 1, None),
    motion("SLIN", 1, None),
    motion("SCIRC", 2, None),
    motion("SPL", 1, None),
    motion("PTP_REL", 1, Some(Reason::Relative)),
    motion("LIN_REL", 1, Some(Reason::Relative)),
    motion("CIRC_REL", 2, Some(Reason::Relative)),
    motion("SPTP_REL", 1, Some(Reason::Relative)),
    motion("SLIN_REL", 1, Some(Reason::Relative)),
    motion("SCIRC_REL", 2, Some(Reason::Relative)),
    motion("ASYPTP", 1, Some(Reason::ExternalAxis)),
];

/// Words that may follow a motion's targets (approximation, circle angle, `WITH`).
const AFTER_TARGETS: [&str; 7] = ["C_PTP", "C_DIS", "C_VEL", "C_ORI", "C_SPL", "CA", "WITH"];

/// The target types, and whether each is Cartesian.
const TYPES: [(&str, Kind); 5] = [
    ("E6POS", Kind::Cartesian),
    ("POS", Kind::Cartesian),
    ("FRAME", Kind::Frame),
    ("E6AXIS", Kind::Joints),
    ("AXIS", Kind::Joints),
];

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Cartesian,
    Frame,
    Joints,
}

/// The controller's numbered tools and bases (`TOOL_DATA[n]`, `BASE_DATA[n]`), as its
/// `$config.dat` declares them: frames in the flange and in the world (the robot's base)
/// frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct KrlFrames {
    /// `TOOL_DATA[n]` by n.
    pub tools: HashMap<u32, Isometry3<f64>>,
    /// `BASE_DATA[n]` by n.
    pub bases: HashMap<u32, Isometry3<f64>>,
}

/// Reads the `TOOL_DATA[n]={X …,Y …,Z …,A …,B …,C …}` and `BASE_DATA[n]=…` lines of a
/// `$config.dat` (any other line is skipped).
///
/// # Errors
///
/// [`Error::Syntax`] at a `TOOL_DATA`/`BASE_DATA` line whose index or frame does not read
/// (all six of X, Y, Z, A, B, C are needed), or that gives one frame twice.
pub fn read_config(src: &Source) -> Result<KrlFrames, Error> {
    let mut frames = KrlFrames::default();
    let mut lexer = Lexer::new(src, KRL);
    while let Some(line) = lexer.line() {
        let mut i = 0;
        while ["DECL", "GLOBAL", "FRAME"]
            .iter()
            .any(|w| word_is(src, line.get(i), w))
        {
            i += 1;
        }
        let Some(first) = line.get(i) else { continue };
        let base = if word_is(src, Some(first), "TOOL_DATA") {
            false
        } else if word_is(src, Some(first), "BASE_DATA") {
            true
        } else {
            continue;
        };
        // A declaration of the array alone (`DECL FRAME TOOL_DATA[16]`) has no value.
        let Some(eq) = line.iter().position(|t| t.is(b'=')) else {
            continue;
        };
        let n = match (line.get(i + 1), line.get(i + 2), line.get(i + 3)) {
            (Some(o), Some(n), Some(c))
                if o.is(b'[') && n.kind == Tok::Number && c.is(b']') && eq == i + 4 =>
            {
                let v = src.number(n.start, "an index")?.value;
                if v.fract() != 0.0 || !(1.0..=u32::MAX as f64).contains(&v) {
                    return Err(src.error(n.start, "the index of a frame is an integer from 1"));
                }
                v as u32
            }
            _ => {
                return Err(src.error(
                    first.start,
                    "expected TOOL_DATA[n]={X …,Y …,Z …,A …,B …,C …} (n a number)",
                ))
            }
        };
        if !line.get(eq + 1).is_some_and(|t| t.is(b'{')) {
            return Err(src.error(
                line.get(eq + 1).map_or(line[eq].end, |t| t.start),
                "expected a frame {X …,Y …,Z …,A …,B …,C …}",
            ));
        }
        let pose = frame_aggregate(src, &line, eq + 1)?;
        let map = if base {
            &mut frames.bases
        } else {
            &mut frames.tools
        };
        if map.insert(n, pose).is_some() {
            return Err(src.error(first.start, format!("{} given twice", frame_name(base, n))));
        }
    }
    Ok(frames)
}

/// The frame of a complete `{X,Y,Z,A,B,C}` aggregate at `line[open]`.
fn frame_aggregate(src: &Source, line: &[Token], open: usize) -> Result<Isometry3<f64>, Error> {
    let (kind, _, _) = aggregate(src, line, open, Some(Kind::Frame))?;
    match kind {
        TargetKind::Cartesian(c) => match c.orientation {
            Some(Orientation::KukaAbcDeg(abc)) => {
                Ok(kuka_pose(c.position.map(|n| n.value), abc.map(|n| n.value)))
            }
            _ => Err(src.error(line[open].start, "a frame needs A, B and C")),
        },
        _ => Err(src.error(line[open].start, "a frame needs X, Y, Z, A, B and C")),
    }
}

fn frame_name(base: bool, n: u32) -> String {
    format!("{}[{n}]", if base { "BASE_DATA" } else { "TOOL_DATA" })
}

/// Reads the targets of a KRL file; `partner` is the other file of its `.src`/`.dat`
/// pair, read for the motions that use this file's targets and the `FDAT`s they name.
/// Numbered tools and bases are not known ([`read_with`] takes them).
///
/// # Errors
///
/// [`Error::Syntax`] at the first malformed target aggregate.
pub fn read(src: &Source, partner: Option<&Source>) -> Result<Program, Error> {
    read_with(src, partner, &KrlFrames::default(), usize::MAX)
}

/// [`read`], stopping after `limit` targets ([`Program::truncated_at`]).
///
/// # Errors
///
/// As [`read`].
pub fn read_at_most(
    src: &Source,
    partner: Option<&Source>,
    limit: usize,
) -> Result<Program, Error> {
    read_with(src, partner, &KrlFrames::default(), limit)
}

/// [`read_at_most`] with the controller's numbered tools and bases.
///
/// # Errors
///
/// As [`read`].
pub fn read_with(
    src: &Source,
    partner: Option<&Source>,
    frames: &KrlFrames,
    limit: usize,
) -> Result<Program, Error> {
    // The FDATs and declared names of both files.
    let mut fdats = HashMap::new();
    let mut declared_here = HashSet::new();
    let mut declared_there = HashSet::new();
    let mut arrays = HashMap::new();
    let mut valued = HashSet::new();
    declarations(
        src,
        &mut fdats,
        &mut declared_here,
        &mut arrays,
        &mut valued,
    );
    if let Some(p) = partner {
        declarations(p, &mut fdats, &mut declared_there, &mut arrays, &mut valued);
    }
    let mut assigned = Writes::default();
    writes(src, &arrays, &mut assigned);
    if let Some(p) = partner {
        writes(p, &arrays, &mut assigned);
    }
    let context = Context {
        frames,
        fdats: &fdats,
        declared_here: &declared_here,
        declared_there: &declared_there,
        arrays: &arrays,
        partner_name: partner.map(|p| p.name),
        valued: &valued,
        writes: &assigned,
    };
    let mut scan = Scan::default();
    let truncated_at = scan_file(src, &context, true, limit, &mut scan)?;
    if let Some(p) = partner {
        merge_partner(src, p, &context, &mut scan);
    }
    let named = NamedUses {
        frames: uses_by_name(scan.uses),
        unknown: first_by_name(scan.unknown_uses),
        expressions: first_by_name(scan.expression_uses),
        through: moved_through_parameters(&scan.calls, &scan.moved_parameters),
    };
    let mut targets = Vec::with_capacity(scan.targets.len());
    for (target, key, kind) in scan.targets {
        targets.extend(named.resolve(target, key, kind, context.writes));
    }
    targets.sort_by_key(|t| t.offset);
    // The partner's targets sit at this file's end, in the order they were merged (the
    // sort is stable, and no target of this file is written at its end).
    let in_partner = (targets.iter().enumerate())
        .filter(|(_, t)| t.offset == src.bytes.len())
        .zip(scan.partner_places)
        .map(|((target, _), (line, column))| PartnerPlace {
            target,
            line,
            column,
        })
        .collect();
    Ok(Program {
        format: Format::Krl,
        targets,
        truncated_at,
        first_motion: scan.first_motion,
        in_partner,
    })
}

/// Adds to `scan` what the partner gives this file: the uses of its motions (placed in
/// the partner), its calls and moved parameters, and its own inline targets, reported
/// since this file's output does not hold them. The partner is context only: what does
/// not read there gives nothing.
fn merge_partner(src: &Source, partner: &Source, context: &Context, scan: &mut Scan) {
    let mut other = Scan::default();
    if scan_file(partner, context, false, usize::MAX, &mut other).is_err() {
        return;
    }
    for mut t in other.partner_targets {
        let (line, column) = partner.location(t.offset);
        scan.partner_places.push((line, column));
        let place = format!("{}:{line}:{column}", partner.name);
        match (t.refused.take(), &t.kind) {
            // A motion the partner moves without a target here (`LIN_REL`, a target
            // computed as it runs): what no run corrects is said in this one's report.
            (Some(Refusal { reason, detail }), TargetKind::Motion) => {
                t.refused = Some(Refusal::new(
                    reason,
                    format!("{detail} (written at {place})"),
                ));
            }
            // An inline target the partner writes in part: its own reason, said there.
            (None, TargetKind::Incomplete(why)) => {
                t.kind = TargetKind::Incomplete(format!("{why} (written at {place})"));
            }
            _ => {
                t.refused = Some(Refusal::new(
                    Reason::NotMoved,
                    format!(
                        "{} written at {place}: a target of that file, left as written here; compensate {} for it",
                        t.name, partner.name
                    ),
                ));
                t.kind = TargetKind::Motion;
            }
        }
        t.uses.clear();
        t.offset = src.bytes.len();
        scan.targets.push((t, None, None));
    }
    scan.moved_parameters.extend(other.moved_parameters);
    scan.calls.extend(other.calls);
    scan.unknown_uses.extend(other.unknown_uses);
    scan.expression_uses.extend(other.expression_uses);
    scan.uses
        .extend(other.uses.into_iter().map(|(name, mut u)| {
            let (line, column) = partner.location(u.offset);
            u.elsewhere = Some(format!("{}:{line}:{column}", partner.name));
            (name, u)
        }));
}

/// The frames of the motions to each name. A motion to any element of an array
/// (`NAME[*]`) counts once per frames, so that many such motions and a long array stay
/// linear.
fn uses_by_name(uses: Vec<(String, FrameUse)>) -> HashMap<String, Vec<FrameUse>> {
    let mut by_name: HashMap<String, Vec<FrameUse>> = HashMap::new();
    for (name, u) in uses {
        let list = by_name.entry(name.clone()).or_default();
        let same = |v: &FrameUse| {
            (&v.tool, &v.base, &v.undeclared, &v.unknown)
                == (&u.tool, &u.base, &u.undeclared, &u.unknown)
        };
        if !(name.ends_with("[*]") && list.iter().any(same)) {
            list.push(u);
        }
    }
    by_name
}

/// The first of `pairs` naming each name: one motion or expression is enough to say why.
fn first_by_name(pairs: Vec<(String, String)>) -> HashMap<String, String> {
    let mut first: HashMap<String, String> = HashMap::new();
    for (name, by) in pairs {
        first.entry(name).or_insert(by);
    }
    first
}

/// The names passed to a routine that moves to its parameter, and how: such a target is
/// moved to in the frames of each caller, which no one correction holds for.
fn moved_through_parameters(
    calls: &[Call],
    moved_parameters: &HashMap<(String, usize), String>,
) -> HashMap<String, String> {
    let mut through: HashMap<String, String> = HashMap::new();
    for call in calls {
        let routine = call.routine.to_ascii_uppercase();
        for (k, name) in call.names.iter().enumerate() {
            let (Some(name), Some(param)) = (name, moved_parameters.get(&(routine.clone(), k)))
            else {
                continue;
            };
            through.entry(name.clone()).or_insert_with(|| {
                format!(
                    "moved to through the parameter {param} of {} (called at {}), in the frames of its callers",
                    call.routine, call.place
                )
            });
        }
    }
    through
}

/// How the motions of the pair name the targets, by name (upper case), for each declared
/// target to look up.
struct NamedUses {
    /// The frames of the motions to each name ([`uses_by_name`]).
    frames: HashMap<String, Vec<FrameUse>>,
    /// The first motion not in the table naming each target.
    unknown: HashMap<String, String>,
    /// The first expression naming each target.
    expressions: HashMap<String, String>,
    /// Targets passed to a routine that moves to its parameter ([`moved_through_parameters`]).
    through: HashMap<String, String>,
}

impl NamedUses {
    /// A target of the file with the uses of its declared name (`key`), refused where they
    /// do not give it one correction; `None` for a FRAME no motion moves to.
    fn resolve(
        &self,
        mut target: ProgramTarget,
        key: Option<String>,
        kind: Option<Kind>,
        writes: &Writes,
    ) -> Option<ProgramTarget> {
        let Some(key) = key else {
            return Some(target);
        };
        // An array's element is moved to by its index, or by an index computed at run
        // time (`LIN XPA[I]`: every element).
        let every = key
            .split_once('[')
            .and_then(|(array, _)| self.frames.get(&format!("{array}[*]")));
        let found: Vec<FrameUse> = (self.frames.get(&key))
            .into_iter()
            .chain(every)
            .flatten()
            .cloned()
            .collect();
        // A FRAME no motion moves to is a base or tool offset, not a target.
        if kind == Some(Kind::Frame) && found.is_empty() {
            return None;
        }
        target.uses = found;
        // A motion not in the table moves to it: its frames are not known.
        if let Some(by) = self.unknown.get(&key) {
            target.refused.get_or_insert(Refusal::new(
                Reason::UnknownMotion,
                format!("moved to by {by}, a motion this reader does not know"),
            ));
        }
        // Assigned as the program runs: its declared value is not where it moves.
        let array_any = key.split_once('[').map(|(a, _)| format!("{a}[*]"));
        let variables = &writes.variables;
        let written = (variables.get(&key))
            .or_else(|| array_any.and_then(|a| variables.get(&a)))
            .or_else(|| key.split_once('[').and_then(|(a, _)| variables.get(a)));
        if let Some(place) = written {
            target.refused.get_or_insert(Refusal::new(
                Reason::Dynamic,
                format!("{} is assigned as the program runs ({place}): its declared value is not what the robot moves to", target.name),
            ));
        }
        if let Some(detail) = self.through.get(&key) {
            target
                .refused
                .get_or_insert(Refusal::new(Reason::Dynamic, detail.clone()));
        }
        // Moved to only through an expression: no one correction holds for it.
        if let Some(by) = self.expressions.get(&key) {
            if target.uses.is_empty() {
                target.refused.get_or_insert(Refusal::new(
                    Reason::Dynamic,
                    format!("used only by {by}, computed when the program runs"),
                ));
            }
        }
        Some(target)
    }
}

/// What the files declare: `FDAT`s and target names.
struct Context<'a> {
    frames: &'a KrlFrames,
    fdats: &'a HashMap<String, Fdat>,
    declared_here: &'a HashSet<String>,
    declared_there: &'a HashSet<String>,
    /// Arrays of targets (`DECL E6POS XPA[5]`), by name, with their type.
    arrays: &'a HashMap<String, Kind>,
    partner_name: Option<&'a str>,
    /// Names declared with a value in either file.
    valued: &'a HashSet<String>,
    /// What the program writes as it runs ([`Writes`]).
    writes: &'a Writes,
}

/// What the routines of the pair assign as they run.
#[derive(Default)]
struct Writes {
    /// Variables (upper case; an array's element `XPA[2]`, any element `XPA[*]`), and
    /// where first: `file:line:column`.
    variables: HashMap<String, String>,
    /// Numbered frames (base, number), and where first.
    frames: HashMap<(bool, u32), String>,
    /// A numbered frame of an index computed at run time: tools, bases.
    any_frame: [Option<String>; 2],
}

/// The assignments of the routines of a file (`XP2.Y = XP2.Y + 25.0`, `XP2 = XP1`,
/// `BASE_DATA[1].Z = …`, `TOOL_DATA[4] = {…}`).
fn writes(src: &Source, arrays: &HashMap<String, Kind>, out: &mut Writes) {
    let mut in_routine = false;
    let mut lexer = Lexer::new(src, KRL);
    while let Some(line) = lexer.line() {
        if routine_head(src, &line).is_some() {
            in_routine = true;
            continue;
        }
        let Some(first) = line.first().filter(|t| t.kind == Tok::Ident) else {
            continue;
        };
        if word_is(src, Some(first), "END") || word_is(src, Some(first), "ENDFCT") {
            in_routine = false;
            continue;
        }
        // The designator before `=`: the name, an index, components.
        let Some(eq) = line.iter().position(|t| t.is(b'=')) else {
            continue;
        };
        let designator = &line[1..eq];
        let plain = designator.iter().all(|t| {
            t.kind == Tok::Ident || t.kind == Tok::Number || t.is(b'.') || t.is(b'[') || t.is(b']')
        });
        if !plain || src.bytes[first.start] == b'$' {
            continue;
        }
        let name = src.text(first.start, first.end).to_ascii_uppercase();
        let index = match designator {
            [o, n, c, ..] if o.is(b'[') && n.kind == Tok::Number && c.is(b']') => {
                Some(Some(src.text(n.start, n.end)))
            }
            [o, ..] if o.is(b'[') => Some(None),
            _ => None,
        };
        let (line_no, column) = src.location(first.start);
        let place = format!("{}:{line_no}:{column}", src.name);
        let base = name == "BASE_DATA";
        if base || name == "TOOL_DATA" {
            match index.flatten().and_then(|n| n.parse::<f64>().ok()) {
                Some(n) if n.fract() == 0.0 && (0.0..=u32::MAX as f64).contains(&n) => {
                    out.frames.entry((base, n as u32)).or_insert(place);
                }
                _ => {
                    out.any_frame[usize::from(base)].get_or_insert(place);
                }
            }
            continue;
        }
        // Outside a routine, `XPA[2]={…}` gives an array's element its value.
        if !in_routine || line.get(eq + 1).is_some_and(|t| t.is(b'=')) {
            continue;
        }
        let key = match index {
            Some(Some(n)) if arrays.contains_key(&name) => element_key(&name, &n),
            Some(_) if arrays.contains_key(&name) => format!("{name}[*]"),
            _ => name,
        };
        out.variables.entry(key).or_insert(place);
    }
}

/// An `FDAT`: the tool and base a motion's inline form selects.
#[derive(Clone, Copy, Debug, Default)]
struct Fdat {
    tool_no: Option<u32>,
    base_no: Option<u32>,
    external_tcp: bool,
}

/// A frame as the controller will have it when a motion runs.
#[derive(Clone, Debug)]
enum FrameState {
    /// Nothing in the program set it: the job's option.
    Initial,
    Known(Isometry3<f64>),
    /// A numbered frame the job was not given.
    Undeclared(String),
    /// A frame no input gives.
    Unknown(String),
    /// In the frames a statement sets: the one it leaves as it was.
    Kept,
}

#[derive(Clone, Debug)]
struct State {
    tool: FrameState,
    base: FrameState,
}

/// What a file's scan found.
#[derive(Default)]
struct Scan {
    /// Targets of the file, with their declared name (upper case) and type when declared.
    targets: Vec<(ProgramTarget, Option<String>, Option<Kind>)>,
    /// Named uses: the name (upper case) and the frames.
    uses: Vec<(String, FrameUse)>,
    /// Names moved to by a motion not in [`MOTIONS`]: the name, the motion and its place.
    unknown_uses: Vec<(String, String)>,
    /// Names a motion takes inside an expression (`XP1:XOFF`): the name and the motion.
    expression_uses: Vec<(String, String)>,
    first_motion: Option<usize>,
    /// Targets the partner writes in its motions (inline aggregates) and the motions it
    /// refuses (`LIN_REL`, a target computed as it runs), reported here since this file's
    /// output does not hold them.
    partner_targets: Vec<ProgramTarget>,
    /// Where the partner's targets merged into `targets` are written there (line,
    /// column), in the order they were merged.
    partner_places: Vec<(usize, usize)>,
    /// Parameters a motion moves to: (routine upper case, index) and the parameter.
    moved_parameters: HashMap<(String, usize), String>,
    /// The calls of the file's routines.
    calls: Vec<Call>,
}

impl Scan {
    /// A motion refused: this file's target, or the partner's to report.
    fn refused(&mut self, this_file: bool, target: ProgramTarget) {
        if this_file {
            self.targets.push((target, None, None));
        } else {
            self.partner_targets.push(target);
        }
    }
}

/// The `FDAT`s and declared target names (upper case) of a file; what does not read is
/// skipped (the scan reports it).
fn declarations(
    src: &Source,
    fdats: &mut HashMap<String, Fdat>,
    names: &mut HashSet<String>,
    arrays: &mut HashMap<String, Kind>,
    valued: &mut HashSet<String>,
) {
    let mut lexer = Lexer::new(src, KRL);
    while let Some(line) = lexer.line() {
        let mut i = 0;
        while ["DECL", "GLOBAL", "CONST"]
            .iter()
            .any(|w| word_is(src, line.get(i), w))
        {
            i += 1;
        }
        let (Some(ty), Some(name)) = (line.get(i), line.get(i + 1)) else {
            continue;
        };
        if name.kind != Tok::Ident {
            continue;
        }
        let key = src.text(name.start, name.end).to_ascii_uppercase();
        if let Some(kind) = type_of(src, ty) {
            // `DECL E6POS XPA[5]`: an array, its elements assigned on lines of their own.
            if line.get(i + 2).is_some_and(|t| t.is(b'[')) {
                arrays.insert(key.clone(), kind);
            }
            if line.get(i + 2).is_some_and(|t| t.is(b'=')) {
                valued.insert(key.clone());
            }
            names.insert(key);
        } else if word_is(src, Some(ty), "FDAT") {
            let mut fdat = Fdat::default();
            for (k, t) in line.iter().enumerate() {
                let next = line.get(k + 1);
                let number = || {
                    next.filter(|n| n.kind == Tok::Number)
                        .and_then(|n| crate::number::parse_number(src.bytes, n.start))
                        .filter(|n| {
                            n.value.fract() == 0.0 && (0.0..=u32::MAX as f64).contains(&n.value)
                        })
                        .map(|n| n.value as u32)
                };
                if word_is(src, Some(t), "TOOL_NO") {
                    fdat.tool_no = number();
                } else if word_is(src, Some(t), "BASE_NO") {
                    fdat.base_no = number();
                } else if word_is(src, Some(t), "IPO_FRAME") {
                    fdat.external_tcp = word_is(src, next, "#TCP");
                }
            }
            fdats.insert(key, fdat);
        }
    }
}

/// Scans a file in order: its targets (`this_file`), the uses of named targets and the
/// frames of every motion. Returns where reading stopped past `limit` targets.
fn scan_file(
    src: &Source,
    context: &Context,
    this_file: bool,
    limit: usize,
    scan: &mut Scan,
) -> Result<Option<usize>, Error> {
    let lines = lines(src);
    let flow = Flow::new(src, &lines, context);
    for (r, names, at) in &flow.calls {
        let routine = &flow.routines[*r];
        let (line, column) = src.location(*at);
        scan.calls.push(Call {
            routine: routine.name.clone(),
            names: names.clone(),
            place: format!("{}:{line}:{column}", src.name),
        });
    }
    for (idx, line) in lines.iter().enumerate() {
        let here = Here {
            frames: flow.at.get(&idx),
            routine: flow.routine_of[idx].map(|r| &flow.routines[r]),
        };
        statement(src, &line.tokens, context, this_file, &here, scan)?;
        if scan.targets.len() > limit {
            return Ok(Some(line.rest.1));
        }
    }
    Ok(None)
}

/// Where a statement is: the frames the flow finds at a motion's line, and its routine.
struct Here<'f> {
    frames: Option<&'f Frames>,
    routine: Option<&'f Routine>,
}

/// A call of a routine of the file.
struct Call {
    /// The routine as written.
    routine: String,
    /// The names passed, one per argument (`None`: not a name).
    names: Vec<Option<String>>,
    /// `file:line:column`.
    place: String,
}

/// The tool and base a `;FOLD` comment in `from..to` names, applied to `state`.
fn fold_frames(src: &Source, from: usize, to: usize, context: &Context, state: &mut State) {
    let text = &src.bytes[from.min(to)..to];
    let Some(semi) = text.iter().position(|b| *b == b';') else {
        return;
    };
    let comment = &text[semi + 1..];
    let trimmed = comment.trim_ascii_start();
    if !(trimmed.len() >= 5 && same_name(&trimmed[..5], b"FOLD ")) {
        return;
    }
    // Only the fold's title, before its `;%{PE}` parameters.
    let title = trimmed.split(|b| *b == b';').next().unwrap_or(&[]);
    for (word, base) in [(&b"TOOL["[..], false), (&b"BASE["[..], true)] {
        let found = title
            .windows(word.len())
            .position(|w| same_name(w, word))
            .and_then(|at| {
                let digits = &title[at + word.len()..];
                let end = digits.iter().position(|b| !b.is_ascii_digit())?;
                (digits.get(end) == Some(&b']') && end > 0)
                    .then(|| {
                        std::str::from_utf8(&digits[..end])
                            .ok()?
                            .parse::<u32>()
                            .ok()
                    })
                    .flatten()
            });
        if let Some(n) = found {
            let frame = numbered(context, base, n);
            if base {
                state.base = frame;
            } else {
                state.tool = frame;
            }
        }
    }
}

/// A numbered frame: `$NULLFRAME` for 0, else the controller's, unless the program
/// writes it.
fn numbered(context: &Context, base: bool, n: u32) -> FrameState {
    if n == 0 {
        return FrameState::Known(Isometry3::identity());
    }
    let writes = context.writes;
    if let Some(place) = writes
        .frames
        .get(&(base, n))
        .or(writes.any_frame[usize::from(base)].as_ref())
    {
        return FrameState::Unknown(format!(
            "{} is assigned by the program ({place}): not the configuration's value",
            frame_name(base, n)
        ));
    }
    let frames = context.frames;
    let map = if base { &frames.bases } else { &frames.tools };
    match map.get(&n) {
        Some(f) => FrameState::Known(*f),
        None => FrameState::Undeclared(frame_name(base, n)),
    }
}

/// The frames an `FDAT` selects.
fn fdat_frames(context: &Context, name: &str, at: (usize, usize)) -> (FrameState, FrameState) {
    match context.fdats.get(&name.to_ascii_uppercase()) {
        Some(f) => {
            let tool = if f.external_tcp {
                FrameState::Unknown(format!(
                    "an external TCP (IPO_FRAME #TCP in {name}): a stationary tool is not supported"
                ))
            } else {
                f.tool_no
                    .map_or(FrameState::Unknown(format!("{name} has no TOOL_NO")), |n| {
                        numbered(context, false, n)
                    })
            };
            let base = f
                .base_no
                .map_or(FrameState::Unknown(format!("{name} has no BASE_NO")), |n| {
                    numbered(context, true, n)
                });
            (tool, base)
        }
        None => {
            let why = format!(
                "the FDAT {name} named at {}:{} is declared in neither file",
                at.0, at.1
            );
            (FrameState::Unknown(why.clone()), FrameState::Unknown(why))
        }
    }
}

/// The frame an expression `tokens` assigns to `$TOOL` (`base` false) or `$BASE`.
fn frame_expression(
    src: &Source,
    tokens: &[Token],
    context: &Context,
    base: bool,
    at: usize,
) -> FrameState {
    let (line, column) = src.location(at);
    let unknown = || {
        FrameState::Unknown(format!(
            "{} set by an expression at {line}:{column}",
            if base { "$BASE" } else { "$TOOL" }
        ))
    };
    let word = |k: usize, w: &str| word_is(src, tokens.get(k), w);
    match tokens {
        [_] if word(0, "$NULLFRAME") => FrameState::Known(Isometry3::identity()),
        [_, o, n, c]
            if (word(0, "TOOL_DATA") || word(0, "BASE_DATA"))
                && o.is(b'[')
                && n.kind == Tok::Number
                && c.is(b']') =>
        {
            match crate::number::parse_number(src.bytes, n.start) {
                Some(v) if v.value.fract() == 0.0 && (0.0..=u32::MAX as f64).contains(&v.value) => {
                    numbered(context, word(0, "BASE_DATA"), v.value as u32)
                }
                _ => unknown(),
            }
        }
        // A spline motion's `STOOL2(FPn)` and `SBASE(FPn.BASE_NO)`.
        [_, o, f, c] if word(0, "STOOL2") && o.is(b'(') && f.kind == Tok::Ident && c.is(b')') => {
            fdat_frames(context, &src.text(f.start, f.end), (line, column)).0
        }
        [_, o, f, d, _, c]
            if word(0, "SBASE")
                && o.is(b'(')
                && f.kind == Tok::Ident
                && d.is(b'.')
                && word(4, "BASE_NO")
                && c.is(b')') =>
        {
            fdat_frames(context, &src.text(f.start, f.end), (line, column)).1
        }
        [o, ..] if o.is(b'{') => match frame_aggregate(src, tokens, 0) {
            Ok(f) => FrameState::Known(f),
            Err(_) => unknown(),
        },
        _ => unknown(),
    }
}

fn is_motion(src: &Source, t: &Token) -> Option<&'static Motion> {
    let word = &src.bytes[t.start..t.end];
    (t.kind == Tok::Ident)
        .then(|| MOTIONS.iter().find(|m| same_name(word, m.name.as_bytes())))
        .flatten()
}

/// A word that looks like a motion but is not in [`MOTIONS`] (`LIN_ABS`, `SPL_REL`).
fn looks_like_motion(src: &Source, t: &Token) -> bool {
    let word = src.text(t.start, t.end).to_ascii_uppercase();
    // `PTP_SPLINE … ENDSPLINE` opens a block of spline motions; it moves nothing itself.
    word != "PTP_SPLINE"
        && ["PTP_", "LIN_", "CIRC_", "SPTP_", "SLIN_", "SCIRC_", "SPL_"]
            .iter()
            .any(|p| word.starts_with(p))
}

fn word_is(src: &Source, t: Option<&Token>, word: &str) -> bool {
    t.is_some_and(|t| {
        t.kind == Tok::Ident && same_name(&src.bytes[t.start..t.end], word.as_bytes())
    })
}

fn type_of(src: &Source, t: &Token) -> Option<Kind> {
    (t.kind == Tok::Ident)
        .then(|| {
            TYPES
                .iter()
                .find(|(name, _)| same_name(&src.bytes[t.start..t.end], name.as_bytes()))
                .map(|(_, kind)| *kind)
        })
        .flatten()
}

/// The end of the argument starting at `line[i]`: the next top-level `,`, a word that
/// follows a motion's targets, or the line's end.
fn argument_end(src: &Source, line: &[Token], i: usize) -> usize {
    let mut depth = 0i32;
    let mut k = i;
    while let Some(t) = line.get(k) {
        match t.kind {
            Tok::Punct(b'{' | b'(' | b'[') => depth += 1,
            Tok::Punct(b'}' | b')' | b']') => depth -= 1,
            Tok::Punct(b',') if depth <= 0 => return k,
            Tok::Ident
                if depth <= 0
                    && k > i
                    && AFTER_TARGETS.iter().any(|w| word_is(src, Some(t), w)) =>
            {
                return k
            }
            _ => {}
        }
        k += 1;
    }
    k
}

/// A motion's frames, one use per tool and base the paths reaching it may have.
fn frame_uses(frames: &Frames, offset: usize) -> Vec<FrameUse> {
    let mut out = Vec::new();
    for tool in &frames.tool.0 {
        for base in &frames.base.0 {
            let state = State {
                tool: tool.clone(),
                base: base.clone(),
            };
            out.push(frame_use(&state, offset));
        }
    }
    out
}

/// The frames of one path: the state.
fn frame_use(state: &State, offset: usize) -> FrameUse {
    let mut u = FrameUse {
        tool: None,
        base: None,
        offset,
        elsewhere: None,
        note: None,
        undeclared: Vec::new(),
        unknown: Vec::new(),
    };
    for (frame, base) in [(&state.tool, false), (&state.base, true)] {
        match frame {
            FrameState::Initial | FrameState::Kept => {}
            FrameState::Known(f) => {
                if base {
                    u.base = Some(*f);
                } else {
                    u.tool = Some(*f);
                }
            }
            FrameState::Undeclared(name) => u.undeclared.push(Undeclared {
                base,
                name: name.clone(),
            }),
            FrameState::Unknown(why) => u.unknown.push(why.clone()),
        }
    }
    u
}

/// The system-variable assignments of a `WITH` list (or of a statement): `(variable,
/// tokens of its value)`.
fn assignments<'t>(src: &Source, tokens: &'t [Token]) -> Vec<(String, &'t [Token], usize)> {
    let mut out = Vec::new();
    let mut k = 0;
    while k < tokens.len() {
        let end = {
            let mut depth = 0i32;
            let mut e = k;
            while let Some(t) = tokens.get(e) {
                match t.kind {
                    Tok::Punct(b'{' | b'(' | b'[') => depth += 1,
                    Tok::Punct(b'}' | b')' | b']') => depth -= 1,
                    Tok::Punct(b',') if depth <= 0 => break,
                    _ => {}
                }
                e += 1;
            }
            e
        };
        let piece = &tokens[k..end];
        if let [name, eq, value @ ..] = piece {
            if name.kind == Tok::Ident && eq.is(b'=') {
                out.push((
                    src.text(name.start, name.end).to_ascii_uppercase(),
                    value,
                    name.start,
                ));
            }
        }
        k = end + 1;
    }
    out
}

/// Reads one statement: a frame set, a motion, a statement that looks like one, an
/// array's element or a declaration.
fn statement(
    src: &Source,
    line: &[Token],
    context: &Context,
    this_file: bool,
    here: &Here,
    scan: &mut Scan,
) -> Result<(), Error> {
    let Some(first) = line.first() else {
        return Ok(());
    };
    if first.kind != Tok::Ident {
        return Ok(());
    }
    let first_word = src.text(first.start, first.end).to_ascii_uppercase();
    // Frames are followed by the flow ([`Flow`]): here the statement is only recognised.
    let mut scratch = State {
        tool: FrameState::Kept,
        base: FrameState::Kept,
    };
    if frame_statement(src, line, &first_word, context, &mut scratch) {
        return Ok(());
    }
    if let Some(m) = is_motion(src, first) {
        return motion_statement(src, line, m, context, this_file, here, scan);
    }
    if looks_like_motion(src, first) && !line.get(1).is_some_and(|t| t.is(b'(') || t.is(b'=')) {
        unknown_motion(src, line, &first_word, this_file, scan);
        return Ok(());
    }
    if !this_file || array_element(src, line, context, scan)? {
        return Ok(());
    }
    declaration(src, line, scan)
}

/// A statement that sets the controller's frames, as the program sets them (`$TOOL`,
/// `$BASE`, `$IPO_MODE`, `FDAT_ACT`, `BAS`): applied to `state`; `false` for any other.
fn frame_statement(
    src: &Source,
    line: &[Token],
    first_word: &str,
    context: &Context,
    state: &mut State,
) -> bool {
    match first_word {
        // A component changed as the program runs: `$TOOL.Z = 210`.
        "$TOOL" | "$BASE" if line.get(1).is_some_and(|t| t.is(b'.')) => {
            let (l, c) = src.location(line[0].start);
            let frame = FrameState::Unknown(format!("{first_word} changed at {l}:{c}"));
            if first_word == "$BASE" {
                state.base = frame;
            } else {
                state.tool = frame;
            }
        }
        "$TOOL" | "$BASE" | "$IPO_MODE" => {
            for (name, value, at) in assignments(src, line) {
                apply(src, &name, value, at, context, state);
            }
        }
        "FDAT_ACT" => {
            if let (Some(eq), Some(f)) = (line.get(1), line.get(2)) {
                if eq.is(b'=') {
                    let at = src.location(f.start);
                    (state.tool, state.base) = if f.kind == Tok::Ident && line.len() == 3 {
                        fdat_frames(context, &src.text(f.start, f.end), at)
                    } else {
                        let why = format!("FDAT_ACT set by an expression at {}:{}", at.0, at.1);
                        (FrameState::Unknown(why.clone()), FrameState::Unknown(why))
                    };
                }
            }
        }
        "BAS" => bas(src, line, context, state),
        _ => return false,
    }
    true
}

/// `BAS(#TOOL, n)`, `BAS(#BASE, n)`: the numbered frame selected.
fn bas(src: &Source, line: &[Token], context: &Context, state: &mut State) {
    let [first, o, which, comma, n, c] = line else {
        return;
    };
    let base = word_is(src, Some(which), "#BASE");
    if !(o.is(b'(') && comma.is(b',') && c.is(b')') && (base || word_is(src, Some(which), "#TOOL")))
    {
        return;
    }
    let frame = match crate::number::parse_number(src.bytes, n.start) {
        Some(v)
            if n.kind == Tok::Number
                && v.value.fract() == 0.0
                && v.value >= 0.0
                && v.value <= u32::MAX as f64 =>
        {
            numbered(context, base, v.value as u32)
        }
        _ => {
            let (l, c) = src.location(first.start);
            FrameState::Unknown(format!(
                "BAS sets the {} by an expression at {l}:{c}",
                if base { "base" } else { "tool" }
            ))
        }
    };
    if base {
        state.base = frame;
    } else {
        state.tool = frame;
    }
}

/// A statement whose first word looks like a motion this reader does not know: the names
/// it takes kept (their targets are not corrected either), the motion reported.
fn unknown_motion(
    src: &Source,
    line: &[Token],
    first_word: &str,
    this_file: bool,
    scan: &mut Scan,
) {
    let first = &line[0];
    scan.first_motion.get_or_insert(first.start);
    let (l, c) = src.location(first.start);
    for t in line[1..].iter().filter(|t| t.kind == Tok::Ident) {
        scan.unknown_uses.push((
            src.text(t.start, t.end).to_ascii_uppercase(),
            format!("{first_word} ({}:{l}:{c})", src.name),
        ));
    }
    scan.refused(
        this_file,
        refused_motion(
            src,
            first,
            Reason::UnknownMotion,
            format!("{first_word} is not a KRL motion this reader knows"),
        ),
    );
}

/// An array's element given its value: `XPA[2]={X …}`; `false` when the line is none.
fn array_element(
    src: &Source,
    line: &[Token],
    context: &Context,
    scan: &mut Scan,
) -> Result<bool, Error> {
    let [name, open, n, close, eq, brace, ..] = line else {
        return Ok(false);
    };
    let array = src.text(name.start, name.end).to_ascii_uppercase();
    let Some(&kind) = context.arrays.get(&array) else {
        return Ok(false);
    };
    if !(open.is(b'[') && n.kind == Tok::Number && close.is(b']') && eq.is(b'=') && brace.is(b'{'))
    {
        return Ok(false);
    }
    let (target, end, external) = aggregate(src, line, 5, Some(kind))?;
    if let Some(t) = line.get(end) {
        return Err(src.error(t.start, "expected the end of the line after the aggregate"));
    }
    scan.targets.push((
        ProgramTarget {
            name: src.text(name.start, close.end),
            offset: name.start,
            kind: target,
            uses: Vec::new(),
            refused: external.map(|e| Refusal::new(Reason::ExternalAxis, e)),
        },
        Some(element_key(&array, &src.text(n.start, n.end))),
        Some(kind),
    ));
    Ok(true)
}

/// The key of an array's element: the name upper case, the index as a number (`XPA[2]`).
fn element_key(array: &str, index: &str) -> String {
    let n = index
        .parse::<f64>()
        .map_or(index.to_string(), |v| format!("{v}"));
    format!("{array}[{n}]")
}

/// `$TOOL`, `$BASE` or `$IPO_MODE` assigned `value`.
fn apply(
    src: &Source,
    name: &str,
    value: &[Token],
    at: usize,
    context: &Context,
    state: &mut State,
) {
    match name {
        "$TOOL" => state.tool = frame_expression(src, value, context, false, at),
        "$BASE" => state.base = frame_expression(src, value, context, true, at),
        "$IPO_MODE" => {
            let external = match value {
                [t] if word_is(src, Some(t), "#BASE") => false,
                // A spline motion's `SIPO_MODE(FPn.IPO_FRAME)`: the FDAT's.
                [f, o, n, ..] if word_is(src, Some(f), "SIPO_MODE") && o.is(b'(') => context
                    .fdats
                    .get(&src.text(n.start, n.end).to_ascii_uppercase())
                    .is_none_or(|f| f.external_tcp),
                _ => true,
            };
            if external {
                let (l, c) = src.location(at);
                state.tool = FrameState::Unknown(format!(
                    "an external TCP ($IPO_MODE at {l}:{c}): a stationary tool is not supported"
                ));
            }
        }
        _ => {}
    }
}

/// A report entry for a motion whose target is not corrected.
fn refused_motion(src: &Source, at: &Token, reason: Reason, detail: String) -> ProgramTarget {
    ProgramTarget {
        name: src.text(at.start, at.end),
        offset: at.start,
        kind: TargetKind::Motion,
        uses: Vec::new(),
        refused: Some(Refusal::new(reason, detail)),
    }
}

fn motion_statement(
    src: &Source,
    line: &[Token],
    m: &Motion,
    context: &Context,
    this_file: bool,
    here: &Here,
    scan: &mut Scan,
) -> Result<(), Error> {
    let first = &line[0];
    scan.first_motion.get_or_insert(first.start);
    let motion = m.name;
    let args = motion_arguments(src, line, m.targets);
    // Frames given for this motion alone.
    let mut frames = here
        .frames
        .cloned()
        .unwrap_or_else(|| Frames::of(FrameState::Initial, FrameState::Initial));
    if let Some(w) = line.iter().position(|t| word_is(src, Some(t), "WITH")) {
        let mut with = State {
            tool: FrameState::Kept,
            base: FrameState::Kept,
        };
        for (name, value, at) in assignments(src, &line[w + 1..]) {
            apply(src, &name, value, at, context, &mut with);
        }
        frames.set(with);
    }
    let frame = frame_uses(&frames, first.start);
    if let Some(reason) = m.refused {
        let detail = match reason {
            Reason::Relative => {
                format!("{motion}: an offset from where the robot stands when it runs")
            }
            _ => format!("{motion}: an external axis motion; the table has no such axis"),
        };
        scan.refused(this_file, refused_motion(src, first, reason, detail));
        return Ok(());
    }
    let targets = MotionTargets {
        src,
        line,
        motion,
        context,
        this_file,
        frame: &frame,
        routine: here.routine,
    };
    // A circle's angle ends the motion where the angle does, on the circle, not at the
    // end point written: the end point is corrected as a point of the circle, and said so.
    let end_uses: Option<Vec<FrameUse>> = (m.targets == 2)
        .then(|| circle_angle(src, line))
        .flatten()
        .map(|angle| {
            let note = format!(
                "{motion} … CA {angle}: corrected as a point defining the circle; the \
                 motion ends at the angle, a point not corrected on its own"
            );
            (frame.iter().cloned())
                .map(|u| FrameUse {
                    note: Some(note.clone()),
                    ..u
                })
                .collect()
        });
    let end = end_uses
        .as_deref()
        .map(|frame| MotionTargets { frame, ..targets });
    for (k, &(start, stop)) in args.iter().enumerate() {
        match (&end, k) {
            (Some(end), 1) => end.argument(start, stop, scan)?,
            _ => targets.argument(start, stop, scan)?,
        }
    }
    if args.len() < m.targets && this_file {
        return Err(src.error(
            line.last().map_or(first.end, |t| t.end),
            format!("{motion} needs {} target(s)", m.targets),
        ));
    }
    Ok(())
}

/// The angle a circular motion's `CA` gives (`CA 270`, `CA -45.5`, `CA ANGLE`), as
/// written: the words after `CA` up to the next word that follows a motion's targets.
fn circle_angle(src: &Source, line: &[Token]) -> Option<String> {
    let at = line.iter().position(|t| word_is(src, Some(t), "CA"))?;
    let rest = &line[at + 1..];
    let stop = (rest.iter())
        .position(|t| AFTER_TARGETS.iter().any(|w| word_is(src, Some(t), w)))
        .unwrap_or(rest.len());
    let (first, last) = (rest.first()?, rest[..stop].last()?);
    Some(src.text(first.start, last.end).trim().to_string())
}

/// The ranges of a motion's target arguments (at most `count`): up to the first word that
/// follows them (`WITH`), or the line's end.
fn motion_arguments(src: &Source, line: &[Token], count: usize) -> Vec<(usize, usize)> {
    let mut i = 1;
    let mut args: Vec<(usize, usize)> = Vec::new();
    while args.len() < count && i < line.len() {
        if word_is(src, line.get(i), "WITH") {
            break;
        }
        let end = argument_end(src, line, i);
        args.push((i, end));
        i = end;
        if line.get(i).is_some_and(|t| t.is(b',')) {
            i += 1;
        } else {
            break;
        }
    }
    args
}

/// The targets of one motion statement, as the file it is read in sees them: `this_file`
/// when they are reported here (a `.dat`'s partner `.src` only gives its targets' uses).
struct MotionTargets<'m, 'a> {
    src: &'m Source<'a>,
    line: &'m [Token],
    /// The motion's name (`LIN`).
    motion: &'static str,
    context: &'m Context<'m>,
    this_file: bool,
    /// The frames the motion moves in: one use per path's frames.
    frame: &'m [FrameUse],
    /// The routine the motion is in.
    routine: Option<&'m Routine>,
}

impl MotionTargets<'_, '_> {
    /// The target argument `line[start..end]`: an aggregate, an array's element, a system
    /// variable, a declared name, or an expression.
    fn argument(&self, start: usize, end: usize, scan: &mut Scan) -> Result<(), Error> {
        let (src, motion) = (self.src, self.motion);
        let tokens = &self.line[start..end];
        match tokens {
            [t, ..] if t.is(b'{') => self.aggregate(t, start, end, scan)?,
            [t, open, index @ .., close]
                if t.kind == Tok::Ident
                    && open.is(b'[')
                    && close.is(b']')
                    && self
                        .context
                        .arrays
                        .contains_key(&src.text(t.start, t.end).to_ascii_uppercase()) =>
            {
                let array = src.text(t.start, t.end).to_ascii_uppercase();
                let key = match index {
                    [n] if n.kind == Tok::Number => element_key(&array, &src.text(n.start, n.end)),
                    _ => format!("{array}[*]"),
                };
                for u in self.frame {
                    scan.uses.push((key.clone(), u.clone()));
                }
            }
            // A system variable (`$POS_ACT`, `$AXIS_ACT`): where the robot stands when the
            // motion runs (none declares it: the partner's are not reported here).
            [t] if t.kind == Tok::Ident && src.bytes[t.start] == b'$' => {
                let name = src.text(t.start, t.end);
                self.refuse(
                    t,
                    Reason::Dynamic,
                    format!("{motion} {name}: a system variable, read when the program runs"),
                    scan,
                );
            }
            [t] if t.kind == Tok::Ident => self.name(t, scan),
            [t, ..] => {
                let text = src.text(t.start, tokens.last().map_or(t.end, |l| l.end));
                let (l, c) = src.location(t.start);
                for n in tokens.iter().filter(|n| n.kind == Tok::Ident) {
                    scan.expression_uses.push((
                        src.text(n.start, n.end).to_ascii_uppercase(),
                        format!("{motion} {text} ({}:{l}:{c})", src.name),
                    ));
                }
                self.refuse(
                    t,
                    Reason::Dynamic,
                    format!("{motion} {text}: a target computed when the program runs"),
                    scan,
                );
            }
            _ => {}
        }
        Ok(())
    }

    /// An aggregate written inline (`LIN {X 1, Y 2, Z 3}`), its `{` at `line[start]`.
    fn aggregate(&self, t: &Token, start: usize, end: usize, scan: &mut Scan) -> Result<(), Error> {
        let (kind, after, external) = aggregate(self.src, self.line, start, None)?;
        if after != end {
            return Err(self.src.error(
                self.line.get(after).map_or(t.start, |t| t.start),
                "expected ',' or the end of the motion after the aggregate",
            ));
        }
        let target = ProgramTarget {
            name: self.motion.to_string(),
            offset: t.start,
            kind,
            uses: self.frame.to_vec(),
            refused: external.map(|e| Refusal::new(Reason::ExternalAxis, e)),
        };
        if self.this_file {
            scan.targets.push((target, None, None));
        } else {
            scan.partner_targets.push(target);
        }
        Ok(())
    }

    /// A target named: used, when this file or its partner declares it; else reported.
    fn name(&self, t: &Token, scan: &mut Scan) {
        let name = self.src.text(t.start, t.end);
        let key = name.to_ascii_uppercase();
        let context = self.context;
        let motion = self.motion;
        // A parameter of the routine: whatever its callers pass.
        if let Some((routine, k)) = self
            .routine
            .and_then(|r| r.params.iter().position(|p| *p == key).map(|k| (r, k)))
        {
            scan.moved_parameters
                .entry((routine.name.to_ascii_uppercase(), k))
                .or_insert_with(|| name.clone());
            self.refuse(
                t,
                Reason::Dynamic,
                format!(
                    "{motion} {name}: a parameter of {}, whatever its callers pass",
                    routine.name
                ),
                scan,
            );
            return;
        }
        if context.valued.contains(&key) {
            for u in self.frame {
                scan.uses.push((key.clone(), u.clone()));
            }
            return;
        }
        if context.declared_here.contains(&key) || context.declared_there.contains(&key) {
            self.refuse(
                t,
                Reason::Dynamic,
                format!("{motion} {name}: declared without a value, given when the program runs"),
                scan,
            );
            return;
        }
        let partner = context
            .partner_name
            .map_or(String::new(), |p| format!(" nor in {p}"));
        self.refuse(
            t,
            Reason::NotDeclared,
            format!("{motion} {name}: {name} is declared neither in this file{partner} (a global of another module or of $config.dat)"),
            scan,
        );
    }

    /// Reports the motion's target at `t` as left unchanged, when this file reports it.
    fn refuse(&self, t: &Token, reason: Reason, detail: String, scan: &mut Scan) {
        scan.refused(self.this_file, refused_motion(self.src, t, reason, detail));
    }
}

/// `[DECL] [GLOBAL] [CONST] TYPE NAME = {...}`, in any order of the first three.
fn declaration(src: &Source, line: &[Token], scan: &mut Scan) -> Result<(), Error> {
    let mut i = 0;
    while ["DECL", "GLOBAL", "CONST"]
        .iter()
        .any(|w| word_is(src, line.get(i), w))
    {
        i += 1;
    }
    let (Some(ty), Some(name), Some(eq)) = (line.get(i), line.get(i + 1), line.get(i + 2)) else {
        return Ok(());
    };
    let Some(kind) = type_of(src, ty) else {
        return Ok(());
    };
    if name.kind != Tok::Ident || !eq.is(b'=') {
        // An array, or a declaration without a value.
        return Ok(());
    }
    let name_text = src.text(name.start, name.end);
    if !line.get(i + 3).is_some_and(|t| t.is(b'{')) {
        return Err(src.error(
            line.get(i + 3).map_or(eq.end, |t| t.start),
            format!("expected an aggregate {{...}} after '{name_text}='"),
        ));
    }
    let (target, end, external) = aggregate(src, line, i + 3, Some(kind))?;
    if let Some(t) = line.get(end) {
        return Err(src.error(t.start, "expected the end of the line after the aggregate"));
    }
    scan.targets.push((
        ProgramTarget {
            name: name_text.clone(),
            offset: name.start,
            kind: target,
            uses: Vec::new(),
            refused: external.map(|e| Refusal::new(Reason::ExternalAxis, e)),
        },
        Some(name_text.to_ascii_uppercase()),
        Some(kind),
    ));
    Ok(())
}

/// A value of an aggregate component.
enum Value {
    Number(Number),
    /// An integer written as a number or a `'B…'`/`'H…'` literal (Status, Turn).
    Other,
}

/// A component of an aggregate: `X 1500.25`, `S 'B010'`.
struct Component {
    /// Its name, upper case.
    name: String,
    /// Where its name is written.
    at: usize,
    /// Where its value is written.
    value_at: usize,
    value: Value,
    /// Its value as a non-negative integer, when it is one.
    integer: Option<u32>,
}

/// The components of an aggregate, in the order written.
struct Components(Vec<Component>);

impl Components {
    fn get(&self, name: &str) -> Option<&Component> {
        self.0.iter().find(|c| c.name == name)
    }

    fn has(&self, name: &str) -> bool {
        self.get(name).is_some()
    }

    /// The number of the component `name`, if written; an error if it is not a number.
    fn number(&self, src: &Source, name: &str) -> Result<Option<Number>, Error> {
        match self.get(name) {
            None => Ok(None),
            Some(Component {
                value: Value::Number(v),
                ..
            }) => Ok(Some(*v)),
            Some(c) => Err(src.error(c.value_at, format!("{name} must be a number"))),
        }
    }

    /// The integer of the component `name` (Status, Turn), if written.
    fn integer(&self, src: &Source, name: &str) -> Result<Option<u32>, Error> {
        match self.get(name) {
            None => Ok(None),
            Some(c) => c.integer.map(Some).ok_or_else(|| {
                src.error(
                    c.value_at,
                    format!("{name} must be a non-negative integer or a 'B…' literal"),
                )
            }),
        }
    }

    /// An error at the first component a target of `kind` does not have.
    fn check_names(&self, src: &Source, kind: Kind) -> Result<(), Error> {
        let allowed: &[&str] = match kind {
            Kind::Joints => &[
                "A1", "A2", "A3", "A4", "A5", "A6", "E1", "E2", "E3", "E4", "E5", "E6",
            ],
            Kind::Cartesian | Kind::Frame => &[
                "X", "Y", "Z", "A", "B", "C", "S", "T", "E1", "E2", "E3", "E4", "E5", "E6",
            ],
        };
        match self.0.iter().find(|c| !allowed.contains(&c.name.as_str())) {
            Some(c) => Err(src.error(
                c.at,
                format!(
                    "{} is not a component of this target (one of {})",
                    c.name,
                    allowed.join(", ")
                ),
            )),
            None => Ok(()),
        }
    }

    /// The external axes moved (any of E1-E6 not zero), said for a report: a track carries
    /// the robot, a turntable the work; the table knows neither.
    fn external_axes(&self, src: &Source) -> Option<String> {
        let moved: Vec<String> = self
            .0
            .iter()
            .filter(|c| c.name.len() == 2 && c.name.starts_with('E'))
            .filter_map(|c| match &c.value {
                Value::Number(n) if n.value != 0.0 => {
                    Some(format!("{} {}", c.name, src.text(n.span.0, n.span.1)))
                }
                _ => None,
            })
            .collect();
        (!moved.is_empty()).then(|| {
            format!(
                "{}: an external axis (a track, a turntable) the table does not have",
                moved.join(", ")
            )
        })
    }

    /// A joint target: A1 up to the last axis given, none missing between.
    fn joints(&self, src: &Source) -> Result<TargetKind, Error> {
        const AXES: [&str; 6] = ["A1", "A2", "A3", "A4", "A5", "A6"];
        let mut joints = Vec::new();
        for a in AXES {
            match self.number(src, a)? {
                Some(n) => joints.push(n),
                None => break,
            }
        }
        let given = AXES.iter().filter(|a| self.has(a)).count();
        Ok(if joints.len() != given || joints.is_empty() {
            TargetKind::Incomplete("axes missing between A1 and the last one given".into())
        } else {
            TargetKind::Joints(JointTarget {
                joints,
                unit: AngleUnit::Degree,
            })
        })
    }

    /// A Cartesian target: X, Y, Z, and A, B, C, Status and Turn when given.
    fn cartesian(&self, src: &Source) -> Result<TargetKind, Error> {
        let number = |n: &str| self.number(src, n);
        let position = [number("X")?, number("Y")?, number("Z")?];
        let abc = [number("A")?, number("B")?, number("C")?];
        let (status, turn) = (self.integer(src, "S")?, self.integer(src, "T")?);
        let [Some(x), Some(y), Some(z)] = position else {
            return Ok(TargetKind::Incomplete("X, Y and Z not all given".into()));
        };
        let orientation = match abc {
            [Some(a), Some(b), Some(c)] => Some(Orientation::KukaAbcDeg([a, b, c])),
            [None, None, None] => None,
            _ => return Ok(TargetKind::Incomplete("A, B and C given in part".into())),
        };
        Ok(TargetKind::Cartesian(Box::new(CartesianTarget {
            position: [x, y, z],
            unit: LengthUnit::Millimetre,
            orientation,
            config: if status.is_some() || turn.is_some() {
                ConfigHint::KukaStatusTurn { status, turn }
            } else {
                ConfigHint::None
            },
            joints: Vec::new(),
        })))
    }
}

/// The aggregate starting at `line[open]` (a `{`): its target, the index after its `}`,
/// and the external axes it moves (any of E1-E6 not zero), said for a report.
fn aggregate(
    src: &Source,
    line: &[Token],
    open: usize,
    declared: Option<Kind>,
) -> Result<(TargetKind, usize, Option<String>), Error> {
    let (written, first) = aggregate_type(src, line, open + 1)?;
    let (components, after) = components(src, line, first)?;
    let kind = match written.or(declared) {
        Some(k) => k,
        None if components.has("A1") => Kind::Joints,
        None => Kind::Cartesian,
    };
    components.check_names(src, kind)?;
    let external = components.external_axes(src);
    let target = match kind {
        Kind::Joints => components.joints(src)?,
        Kind::Cartesian | Kind::Frame => components.cartesian(src)?,
    };
    Ok((target, after, external))
}

/// An aggregate's optional type prefix at `line[i]` (`{E6POS: X 1, ...}`): the type, and
/// where its components start.
fn aggregate_type(src: &Source, line: &[Token], i: usize) -> Result<(Option<Kind>, usize), Error> {
    let (Some(t), Some(colon)) = (line.get(i), line.get(i + 1)) else {
        return Ok((None, i));
    };
    if !colon.is(b':') {
        return Ok((None, i));
    }
    let kind = type_of(src, t).ok_or_else(|| {
        src.error(
            t.start,
            format!(
                "{} is not a target type (E6POS, POS, FRAME, E6AXIS, AXIS)",
                src.describe(t.start)
            ),
        )
    })?;
    Ok((Some(kind), i + 2))
}

/// The components of an aggregate from `line[i]` to its `}`, and the index after it.
fn components(src: &Source, line: &[Token], mut i: usize) -> Result<(Components, usize), Error> {
    let mut components: Vec<Component> = Vec::new();
    let end_of_line = line.last().map_or(0, |t| t.end);
    loop {
        let Some(t) = line.get(i) else {
            return Err(src.error(end_of_line, "unterminated aggregate: expected '}'"));
        };
        if t.is(b'}') && components.is_empty() {
            return Ok((Components(components), i + 1));
        }
        if t.kind != Tok::Ident {
            return Err(src.error(
                t.start,
                format!(
                    "expected a component name (X, Y, Z, A1, ...), found {}",
                    src.describe(t.start)
                ),
            ));
        }
        let name = src.text(t.start, t.end).to_ascii_uppercase();
        if components.iter().any(|c| c.name == name) {
            return Err(src.error(t.start, format!("component {name} given twice")));
        }
        i += 1;
        let Some(v) = line.get(i) else {
            return Err(src.error(end_of_line, format!("expected a value for {name}")));
        };
        let (value, integer, next) = component_value(src, line, i, &name)?;
        components.push(Component {
            name,
            at: t.start,
            value_at: v.start,
            value,
            integer,
        });
        i = next;
        match line.get(i) {
            Some(t) if t.is(b',') => i += 1,
            Some(t) if t.is(b'}') => return Ok((Components(components), i + 1)),
            Some(t) => {
                return Err(src.error(
                    t.start,
                    format!("expected ',' or '}}', found {}", src.describe(t.start)),
                ))
            }
            None => return Err(src.error(end_of_line, "unterminated aggregate: expected '}'")),
        }
    }
}

/// The value of the component `name` at `line[i]`: the value, its integer when it is a
/// non-negative one, and the index after it.
fn component_value(
    src: &Source,
    line: &[Token],
    i: usize,
    name: &str,
) -> Result<(Value, Option<u32>, usize), Error> {
    let v = &line[i];
    Ok(match v.kind {
        Tok::Number | Tok::Punct(b'-' | b'+') => {
            let n = src.number(v.start, name)?;
            // A signed number is one or two tokens: skip those it covers.
            let mut j = i;
            while line.get(j).is_some_and(|t| t.start < n.span.1) {
                j += 1;
            }
            let integer = (n.value.fract() == 0.0 && (0.0..=u32::MAX as f64).contains(&n.value))
                .then_some(n.value as u32);
            (Value::Number(n), integer, j)
        }
        Tok::Str => (Value::Other, bit_literal(&src.bytes[v.start..v.end]), i + 1),
        Tok::Ident => (Value::Other, None, i + 1),
        Tok::Punct(b'{') => {
            // A nested aggregate: skipped.
            let mut depth = 0;
            let mut j = i;
            while let Some(t) = line.get(j) {
                if t.is(b'{') {
                    depth += 1;
                } else if t.is(b'}') {
                    depth -= 1;
                    if depth == 0 {
                        break;
                    }
                }
                j += 1;
            }
            (Value::Other, None, j + 1)
        }
        _ => {
            return Err(src.error(
                v.start,
                format!(
                    "expected a value for {name}, found {}",
                    src.describe(v.start)
                ),
            ))
        }
    })
}

/// The value of KRL's `'B0110'` (binary) or `'H1F'` (hexadecimal) literal.
fn bit_literal(text: &[u8]) -> Option<u32> {
    let inner = text.strip_prefix(b"'")?.strip_suffix(b"'")?;
    let (radix, digits) = match inner.first()? {
        b'B' | b'b' => (2, &inner[1..]),
        b'H' | b'h' => (16, &inner[1..]),
        _ => return None,
    };
    u32::from_str_radix(std::str::from_utf8(digits).ok()?, radix).ok()
}

/// A line of a file: its tokens, and the bytes from its last token to its end (its
/// comment, if any).
struct Line {
    tokens: Vec<Token>,
    rest: (usize, usize),
}

/// The lines of a file.
fn lines(src: &Source) -> Vec<Line> {
    let mut out = Vec::new();
    let mut lexer = Lexer::new(src, KRL);
    loop {
        let line_start = lexer.pos;
        let Some(tokens) = lexer.line() else { break };
        let from = tokens.last().map_or(line_start, |t| t.end);
        out.push(Line {
            tokens,
            rest: (from, lexer.pos),
        });
    }
    out
}

/// The most values a frame keeps apart along the paths reaching a point of the program;
/// beyond, it is not known.
const MAX_PATHS: usize = 4;

/// The most passes the flow of a file takes to settle; a file whose flow has not settled
/// then leaves its motions' frames not known.
const MAX_PASSES: usize = 16;

const MANY_PATHS: &str =
    "the frame differs on more than four paths through the program (branches, loops, calls)";

impl FrameState {
    fn same(&self, other: &FrameState) -> bool {
        match (self, other) {
            (FrameState::Initial, FrameState::Initial) | (FrameState::Kept, FrameState::Kept) => {
                true
            }
            (FrameState::Known(a), FrameState::Known(b)) => {
                (a.to_homogeneous() - b.to_homogeneous()).abs().max() < 1e-9
            }
            (FrameState::Undeclared(a), FrameState::Undeclared(b))
            | (FrameState::Unknown(a), FrameState::Unknown(b)) => a == b,
            _ => false,
        }
    }
}

/// A frame's values on the paths that reach a point of the program; none when no path
/// reaches it.
#[derive(Clone, Debug, Default)]
struct Paths(Vec<FrameState>);

impl Paths {
    /// Adds `other`'s values; whether any was new.
    fn join(&mut self, other: &Paths) -> bool {
        let many =
            |p: &Paths| matches!(p.0.as_slice(), [FrameState::Unknown(w)] if w == MANY_PATHS);
        if many(self) {
            return false;
        }
        if many(other) {
            self.0 = other.0.clone();
            return true;
        }
        let mut changed = false;
        for f in &other.0 {
            if !self.0.iter().any(|g| g.same(f)) {
                self.0.push(f.clone());
                changed = true;
            }
        }
        if self.0.len() > MAX_PATHS {
            self.0 = vec![FrameState::Unknown(MANY_PATHS.to_string())];
        }
        changed
    }
}

/// The tool and base along the paths reaching a point of the program.
#[derive(Clone, Debug, Default)]
struct Frames {
    tool: Paths,
    base: Paths,
}

impl Frames {
    fn of(tool: FrameState, base: FrameState) -> Frames {
        Frames {
            tool: Paths(vec![tool]),
            base: Paths(vec![base]),
        }
    }

    fn unknown(why: String) -> Frames {
        Frames::of(FrameState::Unknown(why.clone()), FrameState::Unknown(why))
    }

    fn reached(&self) -> bool {
        !self.tool.0.is_empty() && !self.base.0.is_empty()
    }

    fn join(&mut self, other: &Frames) -> bool {
        let tool = self.tool.join(&other.tool);
        self.base.join(&other.base) | tool
    }

    /// `set`'s frames where a statement set them ([`FrameState::Kept`] elsewhere); which it
    /// set.
    fn set(&mut self, set: State) -> [bool; 2] {
        let mut which = [false; 2];
        for (k, (paths, f)) in [(&mut self.tool, set.tool), (&mut self.base, set.base)]
            .into_iter()
            .enumerate()
        {
            if !matches!(f, FrameState::Kept) {
                which[k] = true;
                if !paths.0.is_empty() {
                    paths.0 = vec![f];
                }
            }
        }
        which
    }
}

/// A routine of a `.src` (`DEF`, `DEFFCT`).
struct Routine {
    /// Its name as written.
    name: String,
    /// Its parameters, upper case.
    params: Vec<String>,
    global: bool,
    /// The first routine of its file: the module's main one, started by the controller.
    main: bool,
    /// Its first `GOTO`'s line: its jumps are not followed.
    goto: Option<usize>,
}

/// A routine's head on `line`, `[GLOBAL] DEF name(p1:IN, …)` or `[GLOBAL] DEFFCT type
/// name(…)`: its name, its parameters (upper case), and whether it is global.
fn routine_head(src: &Source, line: &[Token]) -> Option<(String, Vec<String>, bool)> {
    let global = word_is(src, line.first(), "GLOBAL");
    let k = usize::from(global);
    let name_at = if word_is(src, line.get(k), "DEF") {
        k + 1
    } else if word_is(src, line.get(k), "DEFFCT") {
        k + 2
    } else {
        return None;
    };
    let name = line.get(name_at).filter(|t| t.kind == Tok::Ident)?;
    let mut params = Vec::new();
    if line.get(name_at + 1).is_some_and(|t| t.is(b'(')) {
        let mut expect_name = true;
        for t in &line[name_at + 2..] {
            if t.is(b')') {
                break;
            }
            if t.is(b',') {
                expect_name = true;
            } else if expect_name && t.kind == Tok::Ident {
                params.push(src.text(t.start, t.end).to_ascii_uppercase());
                expect_name = false;
            }
        }
    }
    Some((src.text(name.start, name.end), params, global))
}

/// The routines a line calls (`pick_part( )`, `approach(XP2, 50.0)`, a function in an
/// expression): the routine, the names passed (one per argument, `None` when not a
/// name), where, and whether it runs as an interrupt's or trigger's (after `DO`).
fn calls_of(
    src: &Source,
    line: &[Token],
    by_name: &HashMap<String, usize>,
) -> Vec<(usize, Vec<Option<String>>, usize, bool)> {
    let mut out = Vec::new();
    let mut after_do = false;
    for (k, t) in line.iter().enumerate() {
        if word_is(src, Some(t), "DO") {
            after_do = true;
        }
        if t.kind != Tok::Ident || !line.get(k + 1).is_some_and(|o| o.is(b'(')) {
            continue;
        }
        let Some(&r) = by_name.get(&src.text(t.start, t.end).to_ascii_uppercase()) else {
            continue;
        };
        let mut args = Vec::new();
        let mut depth = 0i32;
        let mut piece: Vec<&Token> = Vec::new();
        for a in &line[k + 2..] {
            match a.kind {
                Tok::Punct(b'(' | b'[' | b'{') => depth += 1,
                Tok::Punct(b')' | b']' | b'}') if depth > 0 => depth -= 1,
                Tok::Punct(b')') => break,
                Tok::Punct(b',') if depth == 0 => {
                    args.push(std::mem::take(&mut piece));
                    continue;
                }
                _ => {}
            }
            piece.push(a);
        }
        if !piece.is_empty() || !args.is_empty() {
            args.push(piece);
        }
        let names = args
            .iter()
            .map(|p| match p.as_slice() {
                [n] if n.kind == Tok::Ident => Some(src.text(n.start, n.end).to_ascii_uppercase()),
                _ => None,
            })
            .collect();
        out.push((r, names, t.start, after_do));
    }
    out
}

/// An open block of the flow.
enum Block {
    If {
        before: Frames,
        done: Frames,
        has_else: bool,
    },
    Switch {
        before: Frames,
        done: Frames,
        started: bool,
        has_default: bool,
    },
    /// A loop opened at a line: its kind (`FOR`, `WHILE`, `LOOP`, `REPEAT`), the frames
    /// before it, and those its `EXIT`s leave with.
    Loop {
        head: usize,
        kind: &'static str,
        entry: Frames,
        exits: Frames,
    },
}

/// The frames at each motion of a file, following its routines, branches and loops.
struct Flow {
    routines: Vec<Routine>,
    /// The routine each line is in.
    routine_of: Vec<Option<usize>>,
    /// The frames at the lines of motions.
    at: HashMap<usize, Frames>,
    /// The calls: routine, names passed, where.
    calls: Vec<(usize, Vec<Option<String>>, usize)>,
}

/// What the passes keep from one to the next.
#[derive(Default)]
struct Memory {
    entry: Vec<Frames>,
    exit: Vec<Frames>,
    /// Whether each routine (or one it calls) sets the tool, the base.
    sets: Vec<[bool; 2]>,
    /// The frames at the end of each loop's body, by its line.
    back: HashMap<usize, Frames>,
    changed: bool,
}

impl Flow {
    fn new(src: &Source, lines: &[Line], context: &Context) -> Flow {
        let mut routines: Vec<Routine> = Vec::new();
        let mut routine_of = Vec::with_capacity(lines.len());
        let mut current = None;
        for line in lines {
            let first = line.tokens.first();
            if let Some((name, params, global)) = routine_head(src, &line.tokens) {
                routines.push(Routine {
                    name,
                    params,
                    global,
                    main: routines.is_empty(),
                    goto: None,
                });
                current = Some(routines.len() - 1);
            } else if word_is(src, first, "END") || word_is(src, first, "ENDFCT") {
                routine_of.push(current);
                current = None;
                continue;
            } else if word_is(src, first, "GOTO") {
                if let Some(r) = current {
                    routines[r]
                        .goto
                        .get_or_insert(src.location(line.tokens[0].start).0);
                }
            }
            routine_of.push(current);
        }
        let by_name: HashMap<String, usize> = routines
            .iter()
            .enumerate()
            .map(|(k, r)| (r.name.to_ascii_uppercase(), k))
            .collect();
        let mut calls = Vec::new();
        for line in lines {
            if routine_head(src, &line.tokens).is_none() {
                for (r, names, at, _) in calls_of(src, &line.tokens, &by_name) {
                    calls.push((r, names, at));
                }
            }
        }
        let mut flow = Flow {
            routines,
            routine_of,
            at: HashMap::new(),
            calls,
        };
        let n = flow.routines.len();
        let mut memory = Memory {
            entry: vec![Frames::default(); n],
            exit: vec![Frames::default(); n],
            sets: vec![[false; 2]; n],
            ..Memory::default()
        };
        let mut settled = false;
        for _ in 0..MAX_PASSES {
            memory.changed = false;
            flow.pass(src, lines, context, &by_name, &mut memory);
            if !memory.changed {
                settled = true;
                break;
            }
        }
        if !settled {
            let why = "the frames of this file's calls and loops did not settle: not known";
            for f in flow.at.values_mut() {
                *f = Frames::unknown(why.to_string());
            }
        }
        flow
    }

    /// The frames a routine starts with.
    fn entry(&self, src: &Source, r: usize, memory: &Memory) -> Frames {
        let routine = &self.routines[r];
        let called = self.calls.iter().any(|c| c.0 == r);
        let mut frames = if called {
            memory.entry[r].clone()
        } else {
            Frames::default()
        };
        if routine.main {
            frames.join(&Frames::of(FrameState::Initial, FrameState::Initial));
        } else if !called {
            frames = Frames::unknown(format!(
                "{} is called from no line of {}: its tool and base are its callers'",
                routine.name, src.name
            ));
        }
        if routine.global && !routine.main {
            frames.join(&Frames::unknown(format!(
                "{} is GLOBAL: other modules may call it in other frames",
                routine.name
            )));
        }
        frames
    }

    fn pass(
        &mut self,
        src: &Source,
        lines: &[Line],
        context: &Context,
        by_name: &HashMap<String, usize>,
        memory: &mut Memory,
    ) {
        let initial = Frames::of(FrameState::Initial, FrameState::Initial);
        let mut walk = Walk {
            current: initial.clone(),
            initial,
            blocks: Vec::new(),
        };
        for (idx, line) in lines.iter().enumerate() {
            let routine = self.routine_of[idx];
            let tokens = &line.tokens;
            let mut set = State {
                tool: FrameState::Kept,
                base: FrameState::Kept,
            };
            fold_frames(src, line.rest.0, line.rest.1, context, &mut set);
            self.apply(&mut walk.current, set, routine, memory);
            let Some(first) = tokens.first() else {
                continue;
            };
            if routine_head(src, tokens).is_some() {
                walk.current = routine.map_or(walk.initial.clone(), |r| self.entry(src, r, memory));
                walk.blocks.clear();
                continue;
            }
            let word = if first.kind == Tok::Ident {
                src.text(first.start, first.end).to_ascii_uppercase()
            } else {
                String::new()
            };
            // The words are exclusive: at most one of these reads the line.
            if walk.leave_routine(&word, routine, memory)
                || walk.follow_if(&word)
                || walk.follow_switch(&word)
                || walk.follow_loop(&word, idx, memory)
            {
                continue;
            }
            if is_motion(src, first).is_some() {
                let at = self.motion_frames(&walk.current, routine);
                self.at.insert(idx, at);
                continue;
            }
            let mut set = State {
                tool: FrameState::Kept,
                base: FrameState::Kept,
            };
            if frame_statement(src, tokens, &word, context, &mut set) {
                self.apply(&mut walk.current, set, routine, memory);
                continue;
            }
            self.follow_calls(src, tokens, by_name, routine, &mut walk.current, memory);
        }
    }

    /// The frames a motion runs in: those reaching it, or unknown where no path followed
    /// reaches it or a `GOTO` of its routine may jump past the frames followed.
    fn motion_frames(&self, current: &Frames, routine: Option<usize>) -> Frames {
        let mut at = current.clone();
        if !at.reached() {
            at = Frames::unknown(
                "no path of the program reaches this motion, as this reader follows it".to_string(),
            );
        }
        if let Some(line) = routine.and_then(|r| self.routines[r].goto) {
            at.join(&Frames::unknown(format!(
                "GOTO at line {line}: jumps this reader does not follow"
            )));
        }
        at
    }

    /// Follows the calls of a line: a callee starts in the caller's frames and hands back
    /// those it sets; one an interrupt or trigger runs (`after_do`) starts anywhere.
    fn follow_calls(
        &self,
        src: &Source,
        tokens: &[Token],
        by_name: &HashMap<String, usize>,
        routine: Option<usize>,
        current: &mut Frames,
        memory: &mut Memory,
    ) {
        for (callee, _, at, after_do) in calls_of(src, tokens, by_name) {
            if after_do {
                let (line, _) = src.location(at);
                let why = format!(
                    "{} runs when an interrupt or trigger fires (line {line}): wherever the robot is",
                    self.routines[callee].name
                );
                memory.changed |= memory.entry[callee].join(&Frames::unknown(why));
                continue;
            }
            memory.changed |= memory.entry[callee].join(current);
            let sets = memory.sets[callee];
            if sets[0] {
                current.tool = memory.exit[callee].tool.clone();
            }
            if sets[1] {
                current.base = memory.exit[callee].base.clone();
            }
            memory.note_sets(routine, sets);
        }
    }

    /// Applies the frames a statement sets, and notes that its routine sets them.
    fn apply(&self, current: &mut Frames, set: State, routine: Option<usize>, memory: &mut Memory) {
        let which = current.set(set);
        memory.note_sets(routine, which);
    }
}

impl Memory {
    /// Notes that `routine` sets the tool, the base (`which`).
    fn note_sets(&mut self, routine: Option<usize>, which: [bool; 2]) {
        let Some(r) = routine else { return };
        for (noted, set) in self.sets[r].iter_mut().zip(which) {
            if set && !*noted {
                *noted = true;
                self.changed = true;
            }
        }
    }
}

/// Where a pass of [`Flow`] is in a file: the frames along the paths reaching the line,
/// and the branches and loops open around it.
struct Walk {
    /// The frames outside any routine, and at a routine's end.
    initial: Frames,
    current: Frames,
    blocks: Vec<Block>,
}

impl Walk {
    /// Leaves a routine at its `END` or a `RETURN`: its callers continue in the frames it
    /// leaves with. True when `word` is one of these.
    fn leave_routine(&mut self, word: &str, routine: Option<usize>, memory: &mut Memory) -> bool {
        match word {
            "END" | "ENDFCT" => {
                if let Some(r) = routine {
                    memory.changed |= memory.exit[r].join(&self.current);
                }
                self.current = self.initial.clone();
                self.blocks.clear();
            }
            "RETURN" => {
                if let Some(r) = routine {
                    memory.changed |= memory.exit[r].join(&self.current);
                }
                // Nothing falls through a RETURN.
                self.current = Frames::default();
            }
            _ => return false,
        }
        true
    }

    /// Follows an `IF … ELSE … ENDIF`: after it, the frames of either branch, or of none
    /// without an `ELSE`. True when `word` is one of these.
    fn follow_if(&mut self, word: &str) -> bool {
        match word {
            "IF" => {
                self.blocks.push(Block::If {
                    before: self.current.clone(),
                    done: Frames::default(),
                    has_else: false,
                });
            }
            "ELSE" => {
                if let Some(Block::If {
                    before,
                    done,
                    has_else,
                }) = self.blocks.last_mut()
                {
                    done.join(&self.current);
                    self.current = before.clone();
                    *has_else = true;
                }
            }
            "ENDIF" => {
                if let Some(Block::If {
                    before,
                    done,
                    has_else,
                }) = self.blocks.last()
                {
                    self.current.join(done);
                    if !has_else {
                        self.current.join(before);
                    }
                    self.blocks.pop();
                }
            }
            _ => return false,
        }
        true
    }

    /// Follows a `SWITCH … CASE … DEFAULT … ENDSWITCH`: each case starts in the frames
    /// before it; after it, those of any case, or of none without a `DEFAULT`. True when
    /// `word` is one of these.
    fn follow_switch(&mut self, word: &str) -> bool {
        match word {
            "SWITCH" => {
                self.blocks.push(Block::Switch {
                    before: self.current.clone(),
                    done: Frames::default(),
                    started: false,
                    has_default: false,
                });
            }
            "CASE" | "DEFAULT" => {
                if let Some(Block::Switch {
                    before,
                    done,
                    started,
                    has_default,
                }) = self.blocks.last_mut()
                {
                    if *started {
                        done.join(&self.current);
                    }
                    self.current = before.clone();
                    *started = true;
                    *has_default |= word == "DEFAULT";
                }
            }
            "ENDSWITCH" => {
                if let Some(Block::Switch {
                    before,
                    done,
                    started,
                    has_default,
                }) = self.blocks.last()
                {
                    if *started {
                        self.current.join(done);
                    } else {
                        self.current = before.clone();
                    }
                    if !has_default {
                        self.current.join(before);
                    }
                    self.blocks.pop();
                }
            }
            _ => return false,
        }
        true
    }

    /// Follows a loop: its body starts in the frames before it and those its last pass
    /// ended with ([`Memory::back`]); after it, those its kind lets through, and its
    /// `EXIT`s'. True when the line is read; false for a `WHILE`, whose condition may
    /// call a function, and for any other word.
    fn follow_loop(&mut self, word: &str, idx: usize, memory: &mut Memory) -> bool {
        match word {
            "FOR" | "WHILE" | "LOOP" | "REPEAT" => {
                let kind = match word {
                    "FOR" => "FOR",
                    "WHILE" => "WHILE",
                    "LOOP" => "LOOP",
                    _ => "REPEAT",
                };
                let entry = self.current.clone();
                if let Some(back) = memory.back.get(&idx) {
                    self.current.join(back);
                }
                self.blocks.push(Block::Loop {
                    head: idx,
                    kind,
                    entry,
                    exits: Frames::default(),
                });
                kind != "WHILE"
            }
            "ENDFOR" | "ENDWHILE" | "ENDLOOP" | "UNTIL" => {
                if let Some(Block::Loop {
                    head,
                    kind,
                    entry,
                    exits,
                }) = self.blocks.pop()
                {
                    let mut current = std::mem::take(&mut self.current);
                    let back = memory.back.entry(head).or_default();
                    memory.changed |= back.join(&current);
                    self.current = match kind {
                        "LOOP" => exits,
                        "REPEAT" => {
                            current.join(&exits);
                            current
                        }
                        _ => {
                            let mut after = entry;
                            after.join(back);
                            after.join(&exits);
                            after
                        }
                    };
                }
                true
            }
            "EXIT" => {
                if let Some(Block::Loop { exits, .. }) = self
                    .blocks
                    .iter_mut()
                    .rev()
                    .find(|b| matches!(b, Block::Loop { .. }))
                {
                    exits.join(&self.current);
                }
                self.current = Frames::default();
                true
            }
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn targets(text: &str) -> Vec<ProgramTarget> {
        read(&Source::new("t.src", text.as_bytes()), None)
            .unwrap()
            .targets
    }

    #[test]
    fn declarations_and_inline_aggregates_are_targets() {
        let t = targets(
            "DEFDAT T\nDECL E6POS XP1={X 1500.0,Y -2.5,Z 1200,A 0.0,B 90.0,C 0.0,S 'B110',T 27,E1 0.0}\n\
             E6AXIS XHOME={A1 0,A2 -90,A3 90,A4 0,A5 0,A6 0} ; home\n\
             DECL FDAT FP1={TOOL_NO 1,BASE_NO 0,IPO_FRAME #BASE,POINT2[] \" \"}\nENDDAT\n\
             PTP {X 1,Y 2,Z 3} C_PTP\nLIN_REL {X 10}\nlin xp1\n",
        );
        // XP1 (used by `lin xp1`), XHOME, the PTP's aggregate, and LIN_REL reported.
        assert_eq!(t.len(), 4);
        assert_eq!(t[0].uses.len(), 1);
        assert_eq!(
            t[3].refused.as_ref().map(|r| r.reason),
            Some(Reason::Relative)
        );
        let TargetKind::Cartesian(c) = &t[0].kind else {
            panic!()
        };
        assert_eq!(c.position.map(|n| n.value), [1500.0, -2.5, 1200.0]);
        assert_eq!(
            c.config,
            ConfigHint::KukaStatusTurn {
                status: Some(6),
                turn: Some(27)
            }
        );
        assert!(matches!(t[1].kind, TargetKind::Joints(ref j) if j.joints.len() == 6));
        assert!(matches!(t[2].kind, TargetKind::Cartesian(ref c) if c.orientation.is_none()));
    }

    #[test]
    fn array_elements_are_targets_moved_to_by_their_index_or_any_index() {
        let text = "DECL E6POS XPA[3]\nXPA[1]={X 1,Y 2,Z 3,A 0,B 90,C 0}\nXPA[2]={X 4,Y 5,Z 6,A 0,B 90,C 0}\n\
                    XPA[3]={X 7,Y 8,Z 9,A 0,B 90,C 0}\n$TOOL = $NULLFRAME\nLIN XPA[2]\nFOR I=1 TO 3\nLIN XPA[I]\nENDFOR\n";
        let t = targets(text);
        assert_eq!(
            t.iter()
                .map(|t| (t.name.as_str(), t.uses.len()))
                .collect::<Vec<_>>(),
            [("XPA[1]", 1), ("XPA[2]", 2), ("XPA[3]", 1)]
        );
        assert!(t.iter().all(|t| t.refused.is_none()));
        assert_eq!(t[0].uses[0].tool, Some(Isometry3::identity()));
        // A system variable is where the robot stands: computed when the program runs.
        let t = targets("PTP $POS_ACT\n");
        assert_eq!(
            t[0].refused.as_ref().map(|r| r.reason),
            Some(Reason::Dynamic)
        );
        // A spline block opens with PTP_SPLINE, which moves nothing; LIN_ABS is no motion
        // this reader knows.
        let t = targets(
            "PTP_SPLINE SB1\nSPTP {A1 0,A2 -90,A3 90,A4 0,A5 0,A6 0}\nENDSPLINE\nLIN_ABS XP1\n",
        );
        let seen: Vec<(&str, Option<Reason>)> = t
            .iter()
            .map(|t| (t.name.as_str(), t.refused.as_ref().map(|r| r.reason)))
            .collect();
        assert_eq!(
            seen,
            [("SPTP", None), ("LIN_ABS", Some(Reason::UnknownMotion))]
        );
    }

    #[test]
    fn motions_take_the_frames_the_program_selects_as_it_runs() {
        let config = read_config(&Source::new(
            "$config.dat",
            b"FRAME TOOL_DATA[16]\nTOOL_DATA[1]={X 0,Y 0,Z 180,A 0,B 0,C 0}\n\
              BASE_DATA[2]={X 1000,Y 0,Z 0,A 0,B 0,C 0}\n",
        ))
        .unwrap();
        let dat = "DEFDAT P\nDECL FDAT FP1={TOOL_NO 1,BASE_NO 2,IPO_FRAME #BASE}\n\
                   DECL FDAT FP2={TOOL_NO 1,BASE_NO 0,IPO_FRAME #TCP}\n\
                   DECL E6POS XA={X 1,Y 2,Z 3,A 0,B 90,C 0}\nDECL E6POS XB={X 1,Y 2,Z 3,A 0,B 90,C 0}\n\
                   DECL E6POS XC={X 1,Y 2,Z 3,A 0,B 90,C 0}\nDECL E6POS XD={X 1,Y 2,Z 3,A 0,B 90,C 0}\n\
                   DECL E6POS XE={X 1,Y 2,Z 3,A 0,B 90,C 0}\nDECL E6POS XF={X 1,Y 2,Z 3,A 0,B 90,C 0}\nENDDAT\n";
        let src = "DEF P( )\n$TOOL = TOOL_DATA[1]\nLIN XA\n\
                   ;FOLD LIN P2 Vel=2 m/s CPDAT1 Tool[0] Base[3];%{PE}\nLIN XB\n;ENDFOLD\n\
                   FDAT_ACT=FP1\nSLIN XC WITH $TOOL = STOOL2(FP2), $IPO_MODE = SIPO_MODE(FP2.IPO_FRAME)\n\
                   LIN XD\nBAS(#TOOL,0)\n$BASE = BASE_DATA[I]\nLIN XE\nEND\n";
        let dat = Source::new("p.dat", dat.as_bytes());
        let src = Source::new("p.src", src.as_bytes());
        let p = read_with(&dat, Some(&src), &config, usize::MAX).unwrap();
        let uses: Vec<&FrameUse> = p.targets[..5].iter().map(|t| &t.uses[0]).collect();
        let z = |f: Option<Isometry3<f64>>| f.map(|f| f.translation.vector.z);
        let x = |f: Option<Isometry3<f64>>| f.map(|f| f.translation.vector.x);
        // $TOOL = TOOL_DATA[1]; $BASE as the options give it.
        assert_eq!((z(uses[0].tool), uses[0].base), (Some(180.0), None));
        // The fold's Tool[0] (the flange) and Base[3] (not in the configuration).
        assert_eq!(z(uses[1].tool), Some(0.0));
        assert_eq!(uses[1].undeclared[0].name, "BASE_DATA[3]");
        // WITH, for XC alone: an external TCP.
        assert!(
            uses[2].unknown[0].starts_with("an external TCP"),
            "{:?}",
            uses[2]
        );
        // FDAT_ACT=FP1 lasts: TOOL_DATA[1] in BASE_DATA[2].
        assert_eq!(
            (z(uses[3].tool), x(uses[3].base)),
            (Some(180.0), Some(1000.0))
        );
        // BAS(#TOOL,0), then a base computed at run time.
        assert_eq!(z(uses[4].tool), Some(0.0));
        assert!(uses[4].unknown[0].starts_with("$BASE set by an expression at 11:1"));
        // XF: no motion moves to it.
        assert!(p.targets[5].uses.is_empty());
    }

    #[test]
    fn frames_are_targets_only_when_a_motion_moves_to_them() {
        let text = "DECL FRAME F1={X 1,Y 2,Z 3,A 0,B 0,C 0}\nDECL FRAME F2={X 1,Y 2,Z 3,A 0,B 0,C 0}\nLIN F2\n";
        let t = targets(text);
        assert_eq!(t.len(), 1);
        assert_eq!(t[0].name, "F2");
    }

    #[test]
    fn malformed_aggregates_are_located() {
        let err = read(
            &Source::new("t.dat", b"DEFDAT T\nDECL E6POS XP1={X 1,Y abc,Z 3}\n"),
            None,
        )
        .unwrap_err();
        assert_eq!(err.to_string(), "t.dat:2:23: Y must be a number");
        let err = read(&Source::new("t.dat", b"DECL E6POS XP1={X 1,Y 2\n"), None).unwrap_err();
        assert!(err.to_string().starts_with("t.dat:1:"), "{err}");
        let err = read(&Source::new("t.dat", b"DECL E6AXIS X={A1 1,Q 2}\n"), None).unwrap_err();
        assert!(err.to_string().contains("Q is not a component"), "{err}");
    }

    /// A `$config.dat` with tools 1, 2 and bases 1, 2.
    fn cell_config() -> KrlFrames {
        read_config(&Source::new(
            "$config.dat",
            b"FRAME TOOL_DATA[16]\nTOOL_DATA[1]={X 0.0,Y 0.0,Z 180.0,A 0.0,B 0.0,C 0.0}\n\
              TOOL_DATA[2]={X 0.0,Y 25.0,Z 120.0,A 0.0,B 0.0,C 0.0}\nFRAME BASE_DATA[32]\n\
              BASE_DATA[1]={X 1700.0,Y 400.0,Z 1100.0,A 0.0,B 0.0,C 0.0}\n\
              BASE_DATA[2]={X 1450.0,Y 150.0,Z 950.0,A 0.0,B 0.0,C 0.0}\n",
        ))
        .unwrap()
    }

    const E6: &str = "={X 100.0,Y 0.0,Z 0.0,A 0.0,B 90.0,C 0.0,S 6,T 50,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}";

    /// The `.dat` declaring `names`, read with `src` as its partner.
    fn pair(names: &[&str], src: &str) -> Program {
        let mut dat = String::from("&ACCESS RVP\n&REL 1\nDEFDAT  cell\n");
        for n in names {
            dat.push_str(&format!("DECL E6POS {n}{E6}\n"));
        }
        dat.push_str("ENDDAT\n");
        let dat = Source::new("cell.dat", dat.as_bytes());
        let src = Source::new("cell.src", src.as_bytes());
        read_with(&dat, Some(&src), &cell_config(), usize::MAX).unwrap()
    }

    /// The targets of `src` read as `cell.src`, without its data list.
    fn src_alone(src: &str) -> Vec<ProgramTarget> {
        read_with(
            &Source::new("cell.src", src.as_bytes()),
            None,
            &cell_config(),
            usize::MAX,
        )
        .unwrap()
        .targets
    }

    /// The x of each use's base (`None`: not known or the options').
    fn bases(t: &ProgramTarget) -> Vec<Option<f64>> {
        t.uses
            .iter()
            .map(|u| u.base.map(|b| b.translation.vector.x))
            .collect()
    }

    #[test]
    fn a_circles_end_point_is_noted_where_its_angle_ends_the_motion() {
        // Named in the data list and inline: the end point of a circle with `CA` carries
        // the note on its use; the auxiliary point and a circle without an angle do not.
        let p = pair(
            &["XP1", "XP2", "XP3", "XP4"],
            "DEF cell( )\n  LIN XP1\n  CIRC XP2, XP3, CA -45.5 C_DIS\n  CIRC XP2, XP4\n\
             \x20 SCIRC {X 1700.0,Y 450.0,Z 1150.0,A 0.0,B 90.0,C 0.0}, \
             {X 1750.0,Y 400.0,Z 1150.0,A 0.0,B 90.0,C 0.0}, CA 270\nEND\n",
        );
        let notes = |name: &str| -> Vec<Option<String>> {
            let t = p.targets.iter().find(|t| t.name == name).unwrap();
            t.uses.iter().map(|u| u.note.clone()).collect()
        };
        assert_eq!(notes("XP1"), [None]);
        assert_eq!(notes("XP2"), [None, None]);
        assert_eq!(
            notes("XP3"),
            [Some(
                "CIRC … CA -45.5: corrected as a point defining the circle; the motion ends at \
                 the angle, a point not corrected on its own"
                    .to_string()
            )]
        );
        assert_eq!(notes("XP4"), [None]);
        // The .src's inline circle, read in the .src itself.
        let src = "DEF cell( )\n  SCIRC {X 1700.0,Y 450.0,Z 1150.0,A 0.0,B 90.0,C 0.0}, \
                   {X 1750.0,Y 400.0,Z 1150.0,A 0.0,B 90.0,C 0.0}, CA 270\nEND\n";
        let t = src_alone(src);
        let inline: Vec<bool> = t
            .iter()
            .map(|t| {
                t.uses.iter().any(|u| {
                    u.note
                        .as_deref()
                        .is_some_and(|n| n.starts_with("SCIRC … CA 270:"))
                })
            })
            .collect();
        assert_eq!(inline, [false, true]);
    }

    #[test]
    fn a_target_the_program_assigns_is_dynamic() {
        let p = pair(
            &["XP1", "XP2", "XP3"],
            "&ACCESS RVP\n&REL 1\nDEF cell( )\n  BAS (#INITMOV,0 )\n  $TOOL = TOOL_DATA[1]\n\
             \x20 $BASE = BASE_DATA[2]\n  XP2.Y = XP2.Y + 25.0\n  LIN XP2\n  XP3 = XP1\n  LIN XP3\n  LIN XP1\nEND\n",
        );
        assert_eq!(
            p.reasons(),
            [
                ("XP1", None),
                ("XP2", Some(Reason::Dynamic)),
                ("XP3", Some(Reason::Dynamic))
            ]
        );
        let detail = &p.targets[1].refused.as_ref().unwrap().detail;
        assert!(
            detail.starts_with("XP2 is assigned as the program runs (cell.src:7:3)"),
            "{detail}"
        );
    }

    #[test]
    fn a_numbered_frame_the_program_writes_is_not_the_configurations() {
        let p = pair(
            &["XP1", "XP2", "XP3"],
            "DEF cell( )\n  $TOOL = TOOL_DATA[1]\n  BASE_DATA[1].Z = BASE_DATA[1].Z + 40.0\n\
             \x20 $BASE = BASE_DATA[1]\n  LIN XP1\n\
             \x20 BASE_DATA[8] = {FRAME: X 1750.0, Y 450.0, Z 1000.0, A 0, B 0, C 0}\n\
             \x20 $BASE = BASE_DATA[8]\n  LIN XP2\n  $BASE = BASE_DATA[2]\n  LIN XP3\nEND\n",
        );
        let unknown = |k: usize| p.targets[k].uses[0].unknown.clone();
        assert_eq!(
            unknown(0),
            ["BASE_DATA[1] is assigned by the program (cell.src:3:3): not the configuration's value"]
        );
        assert!(unknown(1)[0].starts_with("BASE_DATA[8] is assigned by the program (cell.src:6:3)"));
        assert!(unknown(2).is_empty());
        assert_eq!(bases(&p.targets[2]), [Some(1450.0)]);
        // A component of $TOOL changed as the program runs.
        let p = pair(
            &["XP1"],
            "DEF cell( )\n  $TOOL = TOOL_DATA[1]\n  $TOOL.Z = 210\n  LIN XP1\nEND\n",
        );
        assert_eq!(p.targets[0].uses[0].unknown, ["$TOOL changed at 3:3"]);
    }

    #[test]
    fn a_subroutine_moves_in_the_frames_of_its_call_sites() {
        let src = "&ACCESS RVP\n&REL 1\nDEF cell( )\n  BAS (#INITMOV,0 )\n  $TOOL = TOOL_DATA[1]\n\
                   \x20 $BASE = BASE_DATA[1]\n  PTP XP0 C_PTP\n  pick_part( )\n  $TOOL = TOOL_DATA[2]\n\
                   \x20 $BASE = BASE_DATA[2]\n  LIN XP9\nEND\n\nDEF pick_part( )\n  LIN XP1 C_DIS\nEND\n\n\
                   DEF spare( )\n  LIN XP2\nEND\n";
        let p = pair(&["XP0", "XP1", "XP2", "XP9"], src);
        assert_eq!(bases(&p.targets[0]), [Some(1700.0)]);
        // Called while BASE_DATA[1] is active, though written after BASE_DATA[2] is set.
        assert_eq!(bases(&p.targets[1]), [Some(1700.0)]);
        // Called from nowhere in the pair: its frames are its callers'.
        assert!(p.targets[2].uses[0].unknown[0].starts_with("spare is called from no line"));
        assert_eq!(bases(&p.targets[3]), [Some(1450.0)]);
        // Called from two places in different bases: one use in each.
        let src = "DEF cell( )\n  $BASE = BASE_DATA[1]\n  pick_part( )\n  $BASE = BASE_DATA[2]\n\
                   \x20 pick_part( )\nEND\nDEF pick_part( )\n  LIN XP1\nEND\n";
        let p = pair(&["XP1"], src);
        assert_eq!(bases(&p.targets[0]), [Some(1700.0), Some(1450.0)]);
        // A subroutine that sets the base: the caller continues in it.
        let src = "DEF cell( )\n  $BASE = BASE_DATA[1]\n  to_station2( )\n  LIN XP1\nEND\n\
                   DEF to_station2( )\n  $BASE = BASE_DATA[2]\nEND\n";
        assert_eq!(bases(&pair(&["XP1"], src).targets[0]), [Some(1450.0)]);
    }

    #[test]
    fn branches_and_loops_that_set_frames_leave_them_ambiguous() {
        let src = "DEF cell( )\n  INTERRUPT DECL 10 WHEN $IN[12]==FALSE DO retract( )\n\
                   \x20 $TOOL = TOOL_DATA[1]\n  IF $IN[5] THEN\n    $BASE = BASE_DATA[1]\n  ELSE\n\
                   \x20   $BASE = BASE_DATA[2]\n  ENDIF\n  LIN XP1\n  $BASE = BASE_DATA[2]\n\
                   \x20 FOR I = 1 TO 2\n    LIN XP2\n    $BASE = BASE_DATA[1]\n    LIN XP3\n  ENDFOR\n\
                   \x20 SWITCH station\n  CASE 1\n    $BASE = BASE_DATA[2]\n  DEFAULT\n    $BASE = BASE_DATA[2]\n\
                   \x20 ENDSWITCH\n  LIN XP4\nEND\nDEF retract( )\n  LIN XP5\nEND\n";
        let p = pair(&["XP1", "XP2", "XP3", "XP4", "XP5"], src);
        assert_eq!(bases(&p.targets[0]), [Some(1450.0), Some(1700.0)]);
        // Earlier in the loop's body: its first pass, and the passes after the set.
        assert_eq!(bases(&p.targets[1]), [Some(1450.0), Some(1700.0)]);
        assert_eq!(bases(&p.targets[2]), [Some(1700.0)]);
        assert_eq!(bases(&p.targets[3]), [Some(1450.0)]);
        assert!(p.targets[4].uses[0].unknown[0].starts_with("retract runs when an interrupt"));
    }

    #[test]
    fn a_target_passed_to_a_routine_that_moves_to_its_parameter_is_dynamic() {
        let src = "DEF cell( )\n  $TOOL = TOOL_DATA[1]\n  $BASE = BASE_DATA[1]\n  LIN XP1\n\
                   \x20 approach(XP2, 50.0)\nEND\n\nDEF approach(PT:IN, DIST:IN)\n  DECL E6POS PT\n\
                   \x20 DECL REAL DIST\n  DECL E6POS PABOVE\n  PABOVE = PT\n  PABOVE.Z = PABOVE.Z + DIST\n\
                   \x20 LIN PABOVE\n  LIN PT\nEND\n";
        let p = pair(&["XP1", "XP2"], src);
        // The .src's own motions to values given as it runs, reported with the .dat's.
        assert_eq!(
            p.reasons(),
            [
                ("XP1", None),
                ("XP2", Some(Reason::Dynamic)),
                ("PABOVE", Some(Reason::Dynamic)),
                ("PT", Some(Reason::Dynamic))
            ]
        );
        assert_eq!(
            p.targets[1].refused.as_ref().unwrap().detail,
            "moved to through the parameter PT of approach (called at cell.src:5:3), in the frames of its callers"
        );
        // In the .src, the motions to the parameter and to a value given as it runs.
        let t = src_alone(src);
        let seen: Vec<(&str, Option<Reason>)> = t
            .iter()
            .map(|t| (t.name.as_str(), t.refused.as_ref().map(|r| r.reason)))
            .collect();
        assert_eq!(
            seen,
            [
                ("XP1", Some(Reason::NotDeclared)),
                ("PABOVE", Some(Reason::Dynamic)),
                ("PT", Some(Reason::Dynamic))
            ]
        );
    }

    #[test]
    fn the_partners_own_targets_and_refused_motions_are_reported_with_the_data_list() {
        let src = "DEF cell( )\n  $BASE = BASE_DATA[2]\n  LIN XP9\n\
                   \x20 LIN {X 1700.0,Y 450.0,Z 1150.0,A 0.0,B 90.0,C 0.0}\n  LIN_REL {X -30.0}\nEND\n";
        let p = pair(&["XP9"], src);
        // Its inline target, and the motion no run corrects, placed where it is written.
        assert_eq!(
            p.reasons(),
            [
                ("XP9", None),
                ("LIN", Some(Reason::NotMoved)),
                ("LIN_REL", Some(Reason::Relative))
            ]
        );
        assert_eq!(
            p.targets[1].refused.as_ref().unwrap().detail,
            "LIN written at cell.src:4:7: a target of that file, left as written here; compensate cell.src for it"
        );
        assert_eq!(
            p.targets[2].refused.as_ref().unwrap().detail,
            "LIN_REL: an offset from where the robot stands when it runs (written at cell.src:5:3)"
        );
        // Where the .src writes them, by target; the .dat's own target has no such place.
        let place = |target, line, column| PartnerPlace {
            target,
            line,
            column,
        };
        assert_eq!(p.in_partner, [place(1, 4, 7), place(2, 5, 3)]);
        assert_eq!(p.partner_place(0), None);
        assert_eq!(p.partner_place(2), Some(place(2, 5, 3)));
        // An inline target written in part is incomplete here as there, not sent there.
        let p = pair(&["XP9"], &src.replace("LIN_REL {X -30.0}", "LIN {Z 900}"));
        let TargetKind::Incomplete(why) = &p.targets[2].kind else {
            panic!("{:?}", p.targets[2]);
        };
        assert!(p.targets[2].refused.is_none());
        assert!(why.ends_with("(written at cell.src:5:7)"), "{why}");
    }
}
