//! ABB RAPID modules (`.mod`).
//!
//! Targets are `robtarget` declarations (`CONST`, `PERS` or `VAR`, optionally `LOCAL` or
//! `TASK`) with a value, `[[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a,…,eax_f]]` (mm,
//! quaternion w first), `jointtarget` declarations `[[rax_1,…,rax_6],[eax_a,…]]` (degrees),
//! and such values written inline as the target of a `MoveJ`, `MoveL`, `MoveC` (two
//! targets) or `MoveAbsJ` (the pendant shows them as `*`); arrays of targets (`pSeam{n}`,
//! `pGrid{n,m}`, three dimensions) element by element.
//!
//! Frames come from the module: each use of a target is in the move's tool (its fourth
//! positional argument, the fifth of `MoveC`) and work object (`\WObj`, `wobj0` when
//! absent), looked up among the module's `tooldata` and `wobjdata` declarations (`tool0`
//! and `wobj0` are the flange and the world). A name the module does not declare is
//! resolved by the job's `tool` or `base` option, or refused. The robot's base frame is
//! taken as the world frame; a work object is `uframe · oframe`. Stationary tools and
//! robot-held work objects (`robhold` the other way round) are refused.
//!
//! RAPID is case-insensitive; statements end with `;`; `!` starts a comment.

use std::collections::{HashMap, HashSet};

use nalgebra::{Isometry3, Translation3, UnitQuaternion};

use crate::lex::{Language, Lexer, Tok, Token};
use crate::number::Number;
use crate::program::{
    AngleUnit, CartesianTarget, ConfigHint, Format, FrameUse, JointTarget, LengthUnit, Orientation,
    Program, ProgramTarget, Reason, Refusal, TargetKind, Undeclared,
};
use crate::source::{same_name, Source};
use crate::Error;

const RAPID: Language = Language {
    comment: b'!',
    quotes: b"\"",
    ident_extra: b"",
};

/// A value as written: a bracketed list, a (possibly signed) number, or anything else.
#[derive(Clone, Debug)]
enum Value {
    List(Vec<Value>, usize),
    Number(Number),
    Other(usize),
}

impl Value {
    fn offset(&self) -> usize {
        match self {
            Value::List(_, at) | Value::Other(at) => *at,
            Value::Number(n) => n.span.0,
        }
    }
}

/// A frame declared in the module, or why it cannot be used.
type Declared = Result<Isometry3<f64>, String>;

/// Where a move uses a target, and with which frames (names upper-cased).
#[derive(Clone)]
struct Use {
    tool: String,
    tool_at: usize,
    wobj: Option<(String, usize)>,
    at: usize,
    /// Frames the move names that are parameters of its routine: what its callers pass.
    frame_params: Vec<String>,
}

/// Reads the targets of a RAPID module.
///
/// # Errors
///
/// [`Error::Syntax`] at the first malformed target, tool or work object.
pub fn read(src: &Source) -> Result<Program, Error> {
    read_at_most(src, usize::MAX)
}

/// [`read`], stopping after `limit` targets ([`Program::truncated_at`]).
///
/// # Errors
///
/// As [`read`].
pub fn read_at_most(src: &Source, limit: usize) -> Result<Program, Error> {
    let mut lexer = Lexer::new(src, RAPID);
    let mut module = Module::default();
    let mut truncated_at = None;
    loop {
        if module.targets.len() > limit {
            truncated_at = Some(lexer.pos);
            break;
        }
        let statement = next_statement(src, &mut lexer)?;
        if statement.is_empty() {
            if lexer.pos >= src.bytes.len() {
                break;
            }
            continue;
        }
        module.statement(src, &statement)?;
    }
    let moved_by_unknown = module.refuse_unknown_moves(src);
    module.resolve_uses(src);
    module.through_parameters = module.passed_to_moves(src);
    let mut targets: Vec<ProgramTarget> = std::mem::take(&mut module.targets)
        .into_iter()
        .map(|(target, uses)| module.finish(src, target, uses, &moved_by_unknown))
        .collect();
    targets.sort_by_key(|t| t.offset);
    Ok(Program {
        format: Format::Rapid,
        targets,
        truncated_at,
        first_motion: module.first_motion,
        in_partner: Vec::new(),
    })
}

/// A move's use of a target it names, waiting for the module's declarations to be read.
struct PendingUse {
    named: Named,
    used: Use,
    at: Token,
    instruction: &'static str,
}

/// What a module's statements say: its declarations and targets, and the moves that use
/// them, gathered before the uses are resolved.
#[derive(Default)]
struct Module {
    decl: Declarations,
    /// Named targets, with their uses collected as moves are read.
    targets: Vec<(ProgramTarget, Vec<Use>)>,
    pending_uses: Vec<PendingUse>,
    procs: HashSet<String>,
    /// Statements that look like motions but are not in the table, with the names they
    /// take.
    unknown_moves: Vec<(Token, Vec<String>)>,
    first_motion: Option<usize>,
    /// Names a move takes inside an expression (`Offs(p20, …)`): the first such use.
    in_expressions: HashMap<String, (Reason, String)>,
    /// The routine being read and its parameters, as written, positional ones in order,
    /// optional (`\switch`) ones left out.
    routine: Option<(String, Vec<String>)>,
    /// Every routine's parameters, by its name (upper case).
    parameter_lists: HashMap<String, Vec<String>>,
    /// Parameters a move moves to: (routine, positional index) and the move's place.
    moved_parameters: HashMap<(String, usize), usize>,
    /// Calls of a routine: its name (upper case), its positional arguments when a name
    /// (upper case), and the call's place.
    calls: Vec<(String, Vec<Option<String>>, usize)>,
    /// The first statement that displaces the program's positions as it runs (`PDispOn`,
    /// `PDispSet`, `EOffsOn`, `EOffsSet`), as written, and its place.
    displacement: Option<(String, usize)>,
    /// Names a call passes to a parameter a move moves to, with what to say: the first.
    through_parameters: HashMap<String, String>,
}

impl Module {
    /// Reads a statement: a declaration, a routine's head, an assignment, a motion or a
    /// statement that looks like one.
    fn statement(&mut self, src: &Source, statement: &[Token]) -> Result<(), Error> {
        let words: Vec<String> = statement
            .iter()
            .take(6)
            .map(|t| {
                if t.kind == Tok::Ident {
                    src.text(t.start, t.end).to_ascii_uppercase()
                } else {
                    String::new()
                }
            })
            .collect();
        let mut i = 0;
        if matches!(words.first().map(String::as_str), Some("LOCAL" | "TASK")) {
            i += 1;
        }
        match words.get(i).map(String::as_str) {
            Some("CONST" | "PERS" | "VAR") => {
                return declaration(src, &statement[i + 1..], &mut self.decl, &mut self.targets);
            }
            Some(routine @ ("PROC" | "FUNC" | "TRAP")) => {
                let k = if routine == "FUNC" { i + 2 } else { i + 1 };
                if let Some(w) = words.get(k) {
                    self.procs.insert(w.clone());
                    let params = parameters(src, &statement[k + 1..]);
                    self.parameter_lists.insert(w.clone(), params.clone());
                    let written = &statement[k];
                    self.routine = Some((src.text(written.start, written.end), params));
                }
                return Ok(());
            }
            Some("ENDPROC" | "ENDFUNC" | "ENDTRAP") => {
                self.routine = None;
                return Ok(());
            }
            _ => {}
        }
        // A displacement stays on across routines and calls until switched off, so no
        // move of the module is known to run without it.
        if matches!(
            words.get(i).map(String::as_str),
            Some("PDISPON" | "PDISPSET" | "EOFFSON" | "EOFFSSET")
        ) {
            let written = &statement[i];
            self.displacement
                .get_or_insert((src.text(written.start, written.end), written.start));
        }
        // A target assigned as the program runs: `p10 := CRobT();`, `p10.trans.z := 5;`.
        if let Some(name) = assigned(src, statement) {
            self.decl.assigned.entry(name).or_insert(statement[0].start);
            return Ok(());
        }
        // The move may follow a compact IF's condition or a CASE label on its line.
        match statement
            .iter()
            .enumerate()
            .find_map(|(k, t)| motion_of(src, t).map(|m| (k, m)))
        {
            Some((at, m)) => self.motion(src, &statement[at..], m),
            None => {
                self.call(src, statement);
                self.unknown_motion(src, statement);
                Ok(())
            }
        }
    }

    /// A statement that may call a routine of the module (`pick pPart, wobj1;`): kept
    /// with the names it passes, resolved once the routines are known.
    fn call(&mut self, src: &Source, statement: &[Token]) {
        let Some(t) = statement.first().filter(|t| t.kind == Tok::Ident) else {
            return;
        };
        let Ok(args) = arguments(src, &statement[1..]) else {
            return;
        };
        let names = args
            .iter()
            .filter(|a| !a.positional.is_empty())
            .map(|a| match a.positional {
                [n] if n.kind == Tok::Ident => Some(src.text(n.start, n.end).to_ascii_uppercase()),
                _ => None,
            })
            .collect();
        self.calls.push((
            src.text(t.start, t.end).to_ascii_uppercase(),
            names,
            t.start,
        ));
    }

    /// The routine being read (as written), and the positional index of `name` among its
    /// parameters.
    fn parameter(&self, name: &str) -> Option<(&str, usize)> {
        let (routine, params) = self.routine.as_ref()?;
        let k = params.iter().position(|p| p.eq_ignore_ascii_case(name))?;
        Some((routine.as_str(), k))
    }

    /// A statement whose first word looks like a motion the table does not hold: kept
    /// with the names it takes, reported once the routines are known.
    fn unknown_motion(&mut self, src: &Source, statement: &[Token]) {
        let Some(t) = statement.first().filter(|t| looks_like_motion(src, t)) else {
            return;
        };
        self.first_motion.get_or_insert(t.start);
        let names = arguments(src, &statement[1..])
            .map(|args| {
                args.iter()
                    .filter_map(|a| match a.positional {
                        [n] if n.kind == Tok::Ident => {
                            Some(src.text(n.start, n.end).to_ascii_uppercase())
                        }
                        _ => None,
                    })
                    .collect()
            })
            .unwrap_or_default();
        self.unknown_moves.push((*t, names));
    }

    /// A motion instruction `m`, the statement's first token: its tool, work object and
    /// targets.
    fn motion(&mut self, src: &Source, statement: &[Token], m: &Motion) -> Result<(), Error> {
        self.first_motion.get_or_insert(statement[0].start);
        let instruction = m.name;
        if let Some(reason) = m.refused {
            self.targets.push((
                refused_motion(
                    instruction,
                    &statement[0],
                    reason,
                    format!("{instruction}: moves external axes only; the table has no such axis"),
                ),
                Vec::new(),
            ));
            return Ok(());
        }
        let args = arguments(src, &statement[1..])?;
        let positional: Vec<&[Token]> = args
            .iter()
            .filter(|a| !a.positional.is_empty())
            .map(|a| a.positional)
            .collect();
        let mut used = motion_use(src, statement, m, &args, &positional)?;
        let frames = [
            (false, Some((used.tool.clone(), used.tool_at))),
            (true, used.wobj.clone()),
        ];
        for (base, name) in frames {
            let Some((name, at)) = name else { continue };
            let name = src.text(at, at + name.len());
            if let Some((routine, _)) = self.parameter(&name) {
                used.frame_params.push(format!(
                    "{} {name} is a parameter of {routine}: whatever its callers pass",
                    if base { "work object" } else { "tool" }
                ));
            }
        }
        // A search's found point is written by the controller.
        if let Some(found) = m.found.and_then(|slot| positional.get(slot)) {
            if let Some(t) = found.first().filter(|t| t.kind == Tok::Ident) {
                self.decl
                    .assigned
                    .entry(src.text(t.start, t.end).to_ascii_uppercase())
                    .or_insert(t.start);
            }
        }
        for &slot in m.targets {
            let Some(arg) = positional.get(slot) else {
                return Err(src.error(
                    statement[0].start,
                    format!("{instruction} needs a target as argument {}", slot + 1),
                ));
            };
            self.motion_target(src, arg, m, &used)?;
        }
        Ok(())
    }

    /// One target argument `arg` of a motion `m`, used with the frames of `used`: a name,
    /// an array's element, a value written inline, or an expression.
    fn motion_target(
        &mut self,
        src: &Source,
        arg: &[Token],
        m: &Motion,
        used: &Use,
    ) -> Result<(), Error> {
        let instruction = m.name;
        match *arg {
            [t] if t.kind == Tok::Ident => {
                let name = src.text(t.start, t.end).to_ascii_uppercase();
                if let Some((routine, k)) = self.parameter(&name) {
                    let routine = routine.to_string();
                    let written = src.text(t.start, t.end);
                    self.moved_parameters
                        .entry((routine.to_ascii_uppercase(), k))
                        .or_insert(t.start);
                    self.targets.push((
                        refused_motion(
                            instruction,
                            &t,
                            Reason::Dynamic,
                            format!("{instruction} {written}: a parameter of {routine}, whatever its callers pass"),
                        ),
                        Vec::new(),
                    ));
                    return Ok(());
                }
                self.pending(Named::One(name), used, t, instruction);
            }
            // An array's element: `seam{2}`, or any of them: `seam{i}`.
            [t, open, ref index @ .., close]
                if t.kind == Tok::Ident && open.is(b'{') && close.is(b'}') =>
            {
                let name = src.text(t.start, t.end).to_ascii_uppercase();
                let named = match constant_index(src, index) {
                    Some(index) => Named::One(format!("{name}{{{index}}}")),
                    None => Named::All(name),
                };
                self.pending(named, used, t, instruction);
            }
            [t, ..] if t.is(b'[') => {
                let (value, end) = value(src, arg, 0)?;
                if end != arg.len() {
                    return Err(src.error(arg[end].start, "expected ',' after the target"));
                }
                let (kind, external) = if m.joints {
                    joint_target(src, &value)?
                } else {
                    robtarget(src, &value)?
                };
                self.targets.push((
                    ProgramTarget {
                        name: instruction.to_string(),
                        offset: t.start,
                        kind,
                        uses: Vec::new(),
                        refused: external.map(|e| Refusal::new(Reason::ExternalAxis, e)),
                    },
                    vec![used.clone()],
                ));
            }
            [t, open, ..] if t.kind == Tok::Ident && open.is(b'(') => {
                self.computed_target(src, arg, instruction);
            }
            [t, ..] => {
                let text = src.text(t.start, arg[arg.len() - 1].end);
                self.targets.push((
                    refused_motion(
                        instruction,
                        &t,
                        Reason::Dynamic,
                        format!("{instruction} {text}: a target computed when the program runs"),
                    ),
                    Vec::new(),
                ));
            }
            [] => {}
        }
        Ok(())
    }

    fn pending(&mut self, named: Named, used: &Use, at: Token, instruction: &'static str) {
        self.pending_uses.push(PendingUse {
            named,
            used: used.clone(),
            at,
            instruction,
        });
    }

    /// A target a function computes (`Offs(p20, 0, 0, 5)`, `RelTool(…)`, `CRobT()`):
    /// refused, and the names it takes remembered for the targets used only so.
    fn computed_target(&mut self, src: &Source, arg: &[Token], instruction: &str) {
        let t = &arg[0];
        let call = src.text(t.start, t.end);
        let text = src.text(t.start, arg[arg.len() - 1].end);
        let (reason, detail) =
            if call.eq_ignore_ascii_case("Offs") || call.eq_ignore_ascii_case("RelTool") {
                (
                    Reason::Relative,
                    format!("{instruction} {text}: an offset computed when the program runs"),
                )
            } else {
                (
                    Reason::Dynamic,
                    format!("{instruction} {text}: a target computed when the program runs"),
                )
            };
        for n in arg.iter().filter(|n| n.kind == Tok::Ident) {
            self.in_expressions
                .entry(src.text(n.start, n.end).to_ascii_uppercase())
                .or_insert((reason, detail.clone()));
        }
        self.targets
            .push((refused_motion(instruction, t, reason, detail), Vec::new()));
    }

    /// Reports the motions this reader does not know (a call of the module's own routine
    /// is none), and returns the names they move to, with the motion's word and place: a
    /// target such a motion moves to is not corrected either, its frames not known.
    fn refuse_unknown_moves(&mut self, src: &Source) -> HashMap<String, (String, usize)> {
        let mut moved_by_unknown: HashMap<String, (String, usize)> = HashMap::new();
        for (t, names) in std::mem::take(&mut self.unknown_moves) {
            let word = src.text(t.start, t.end);
            if self.procs.contains(&word.to_ascii_uppercase()) {
                continue;
            }
            for name in names {
                moved_by_unknown
                    .entry(name)
                    .or_insert((word.clone(), t.start));
            }
            self.targets.push((
                refused_motion(
                    &word,
                    &t,
                    Reason::UnknownMotion,
                    format!("{word} is not a RAPID motion this reader knows"),
                ),
                Vec::new(),
            ));
        }
        moved_by_unknown
    }

    /// The names calls pass to a parameter that a move of the called routine moves to
    /// (`pick pPart, wobj1;` with `PROC pick(robtarget pT, …)` doing `MoveL pT, …`), each
    /// with what to say.
    fn passed_to_moves(&self, src: &Source) -> HashMap<String, String> {
        let mut params: HashMap<&str, &[String]> = HashMap::new();
        // The routines' parameter lists, as their heads were read.
        for (routine, list) in &self.parameter_lists {
            params.insert(routine, list);
        }
        let mut out = HashMap::new();
        for (routine, names, at) in &self.calls {
            for (k, name) in names.iter().enumerate() {
                let (Some(name), Some(_)) =
                    (name, self.moved_parameters.get(&(routine.clone(), k)))
                else {
                    continue;
                };
                let param = params
                    .get(routine.as_str())
                    .and_then(|l| l.get(k))
                    .map_or("?", String::as_str);
                let (line, column) = src.location(*at);
                out.entry(name.clone()).or_insert(format!(
                    "moved to through the parameter {param} of {} (called at {line}:{column}), in the frames its callers pass",
                    src.text(*at, *at + routine.len())
                ));
            }
        }
        out
    }

    /// Gives each use to the targets it names; a use of a name no target answers is
    /// reported where it is written.
    fn resolve_uses(&mut self, src: &Source) {
        let by_name: HashMap<String, usize> = self
            .targets
            .iter()
            .enumerate()
            .filter(|(_, (t, _))| !matches!(t.kind, TargetKind::Motion))
            .map(|(k, (t, _))| (t.name.to_ascii_uppercase(), k))
            .collect();
        // A move to any element of an array gives every element its frames: once per tool
        // and work object, so that a module of many such moves and a long array stays
        // linear.
        let mut every: HashSet<(String, String, Option<String>)> = HashSet::new();
        for pending in std::mem::take(&mut self.pending_uses) {
            let PendingUse {
                named,
                used,
                at,
                instruction,
            } = pending;
            if let Named::All(array) = &named {
                let frames = (
                    array.clone(),
                    used.tool.clone(),
                    used.wobj.as_ref().map(|w| w.0.clone()),
                );
                if self.decl.arrays.contains_key(array) && !every.insert(frames) {
                    continue;
                }
            }
            let found: Vec<usize> = match &named {
                Named::One(name) => by_name.get(name).copied().into_iter().collect(),
                Named::All(name) => self
                    .decl
                    .arrays
                    .get(name)
                    .map(|keys| {
                        keys.iter()
                            .filter_map(|k| by_name.get(k).copied())
                            .collect()
                    })
                    .unwrap_or_default(),
            };
            if found.is_empty() {
                let (Named::One(n) | Named::All(n)) = &named;
                let (reason, why) = self.why_unresolved(src, n);
                let written = src.text(at.start, at.end);
                self.targets.push((
                    refused_motion(
                        instruction,
                        &at,
                        reason,
                        format!("{instruction} {written}: {why}"),
                    ),
                    Vec::new(),
                ));
                continue;
            }
            for k in found {
                self.targets[k].1.push(used.clone());
            }
        }
    }

    /// Why a move's target `name` stands for no target read: assigned as the program runs,
    /// declared without a value, or not declared here.
    fn why_unresolved(&self, src: &Source, name: &str) -> (Reason, String) {
        let array = name.split('{').next().unwrap_or(name);
        if let Some(&at) = self.decl.assigned.get(array) {
            let (line, column) = src.location(at);
            (
                Reason::Dynamic,
                format!("assigned as the program runs ({line}:{column})"),
            )
        } else if self.decl.names.contains(array) {
            (
                Reason::Dynamic,
                "declared without a value this reader reads: given when the program runs"
                    .to_string(),
            )
        } else {
            (
                Reason::NotDeclared,
                "not declared in this module (another module's, or the controller's)".to_string(),
            )
        }
    }

    /// A target with its uses' frames, refused when a motion this reader does not know
    /// moves to it, when only expressions use it, or when the program assigns it.
    fn finish(
        &self,
        src: &Source,
        mut target: ProgramTarget,
        uses: Vec<Use>,
        moved_by_unknown: &HashMap<String, (String, usize)>,
    ) -> ProgramTarget {
        if target.refused.is_none() && !matches!(target.kind, TargetKind::Motion) {
            let base_name = target
                .name
                .split('{')
                .next()
                .unwrap_or("")
                .to_ascii_uppercase();
            target.refused = self.refusal(
                src,
                &target.name,
                &base_name,
                uses.is_empty(),
                moved_by_unknown,
            );
        }
        for u in uses {
            target.uses.push(self.frame_use(src, &u));
        }
        target
    }

    /// Why a declared target `name` (its array's name `base_name`) is left unchanged, if
    /// it is; `unused` when no move names it.
    fn refusal(
        &self,
        src: &Source,
        name: &str,
        base_name: &str,
        unused: bool,
        moved_by_unknown: &HashMap<String, (String, usize)>,
    ) -> Option<Refusal> {
        if let Some((word, at)) = moved_by_unknown.get(base_name) {
            let (line, column) = src.location(*at);
            return Some(Refusal::new(
                Reason::UnknownMotion,
                format!("moved to by {word} ({line}:{column}), a motion this reader does not know"),
            ));
        }
        // Passed to a routine that moves to its parameter: in the frames of that move.
        if let Some(detail) = self.through_parameters.get(base_name) {
            return Some(Refusal::new(Reason::Dynamic, detail.clone()));
        }
        // A target moved to only through an expression: no one correction holds for it.
        if unused {
            if let Some((reason, detail)) = self.in_expressions.get(base_name) {
                return Some(Refusal::new(*reason, format!("used only by {detail}")));
            }
        }
        let &at = self.decl.assigned.get(base_name)?;
        let (line, column) = src.location(at);
        Some(Refusal::new(
            Reason::Dynamic,
            format!(
                "{name} is assigned as the program runs ({line}:{column}): its declared value is not what the robot moves to"
            ),
        ))
    }

    /// The frames of a use: its tool and work object as the module declares them (`tool0`
    /// and `wobj0` the flange and the world), or named undeclared.
    fn frame_use(&self, src: &Source, u: &Use) -> FrameUse {
        let mut unknown = u.frame_params.clone();
        if let Some((instruction, at)) = &self.displacement {
            let (line, column) = src.location(*at);
            unknown.push(format!(
                "{instruction} at {line}:{column}: a program displacement, set as the program runs and on until switched off, moves the robot away from the target as written"
            ));
        }
        // A tool or work object the program assigns (`wobj1.oframe := …;`): a PERS keeps
        // the value, a VAR keeps it as main runs again; no move's frame is known.
        let names = [
            (false, Some(&u.tool)),
            (true, u.wobj.as_ref().map(|w| &w.0)),
        ];
        for (base, name) in names {
            if let Some(&at) = name.and_then(|n| self.decl.assigned.get(n)) {
                let (line, column) = src.location(at);
                unknown.push(format!(
                    "{} {} is assigned as the program runs ({line}:{column})",
                    if base { "work object" } else { "tool" },
                    src.text(at, src.identifier_end(at, b""))
                ));
            }
        }
        let mut declared = |found: Option<&Declared>| match found {
            Some(Ok(t)) => Some(*t),
            Some(Err(why)) => {
                unknown.push(why.clone());
                Some(Isometry3::identity())
            }
            None => None,
        };
        let tool = match u.tool.as_str() {
            "TOOL0" => Some(Isometry3::identity()),
            name => declared(self.decl.tools.get(name)),
        };
        let base = match &u.wobj {
            None => Some(Isometry3::identity()),
            Some((name, _)) if name == "WOBJ0" => Some(Isometry3::identity()),
            Some((name, _)) => declared(self.decl.wobjs.get(name)),
        };
        FrameUse {
            tool,
            base,
            offset: u.at,
            elsewhere: None,
            note: None,
            undeclared: [
                tool.is_none().then(|| Undeclared {
                    base: false,
                    name: src.text(u.tool_at, u.tool_at + u.tool.len()),
                }),
                base.is_none().then(|| Undeclared {
                    base: true,
                    name: u
                        .wobj
                        .as_ref()
                        .map_or(String::new(), |(n, at)| src.text(*at, at + n.len())),
                }),
            ]
            .into_iter()
            .flatten()
            .collect(),
            unknown,
        }
    }
}

/// The frames a motion `m` (the statement's first token) moves in: its tool argument and
/// its `\WObj`.
fn motion_use(
    src: &Source,
    statement: &[Token],
    m: &Motion,
    args: &[Argument],
    positional: &[&[Token]],
) -> Result<Use, Error> {
    let Some(tool) = positional
        .get(m.tool)
        .filter(|t| t.len() == 1 && t[0].kind == Tok::Ident)
    else {
        return Err(src.error(
            statement[0].start,
            format!(
                "{} needs its tool as argument {} (a tooldata name)",
                src.text(statement[0].start, statement[0].end),
                m.tool + 1
            ),
        ));
    };
    let wobj = args
        .iter()
        .flat_map(|a| &a.options)
        .find(|(name, _)| src.text(name.start, name.end).eq_ignore_ascii_case("WObj"))
        .map(|(_, value)| match value {
            [t] if t.kind == Tok::Ident => {
                Ok((src.text(t.start, t.end).to_ascii_uppercase(), t.start))
            }
            _ => Err(src.error(
                value.first().map_or(statement[0].start, |t| t.start),
                "\\WObj:= takes a wobjdata name",
            )),
        })
        .transpose()?;
    Ok(Use {
        tool: src.text(tool[0].start, tool[0].end).to_ascii_uppercase(),
        tool_at: tool[0].start,
        wobj,
        at: statement[0].start,
        frame_params: Vec::new(),
    })
}

/// A motion instruction of RAPID: its name, which positional arguments are its targets,
/// which its tool (its work object is the `\WObj` option, `wobj0` when absent), and what
/// becomes of them.
#[derive(Clone, Copy, Debug)]
pub struct Motion {
    /// The instruction.
    pub name: &'static str,
    /// The positional arguments that are targets (0-based).
    pub targets: &'static [usize],
    /// The positional argument that is the tool.
    pub tool: usize,
    /// Whether its targets are `jointtarget`s.
    pub joints: bool,
    /// The positional argument the controller writes a found point to (a search's).
    pub found: Option<usize>,
    /// `None`: its targets are corrected; else why it is reported and left unchanged.
    pub refused: Option<Reason>,
}

const fn mv(name: &'static str, targets: &'static [usize], tool: usize) -> Motion {
    Motion {
        name,
        targets,
        tool,
        joints: false,
        found: None,
        refused: None,
    }
}

/// The motion instructions of RAPID (RobotWare 6 and 7, with Arc), every one accounted
/// for: `ToPoint` (and `CirPoint`) corrected in the move's tool and work object.
pub const MOTIONS: [Motion; 29] = [
    mv("MoveJ", &[0], 3),
    mv("MoveL", &[0], 3),
    mv("MoveC", &[0, 1], 4),
    Motion {
        joints: true,
        ..mv("MoveAbsJ", &[0], 3)
    },
    mv("MoveJDO", &[0], 3),
    mv("MoveLDO", &[0], 3),
    mv("MoveCDO", &[0, 1], 4),
    mv("MoveJAO", &[0], 3),
    mv("MoveLAO", &[0], 3),
    mv("MoveCAO", &[0, 1], 4),
    mv("MoveJGO", &[0], 3),
    mv("MoveLGO", &[0], 3),
    mv("MoveCGO", &[0, 1], 4),
    mv("MoveJSync", &[0], 3),
    mv("MoveLSync", &[0], 3),
    mv("MoveCSync", &[0, 1], 4),
    // TriggL ToPoint, Speed, Trigg_1, Zone, Tool.
    mv("TriggJ", &[0], 4),
    mv("TriggL", &[0], 4),
    mv("TriggC", &[0, 1], 5),
    // ArcL ToPoint, Speed, Seam, Weld, Zone, Tool.
    mv("ArcL", &[0], 5),
    mv("ArcLStart", &[0], 5),
    mv("ArcLEnd", &[0], 5),
    mv("ArcC", &[0, 1], 6),
    mv("ArcCStart", &[0, 1], 6),
    mv("ArcCEnd", &[0, 1], 6),
    // SearchL Signal, SearchPoint, ToPoint, Speed, Tool.
    Motion {
        found: Some(1),
        ..mv("SearchL", &[2], 4)
    },
    Motion {
        found: Some(1),
        ..mv("SearchC", &[2, 3], 5)
    },
    Motion {
        found: Some(1),
        ..mv("SearchJ", &[2], 4)
    },
    Motion {
        refused: Some(Reason::ExternalAxis),
        ..mv("MoveExtJ", &[], 0)
    },
];

fn motion_of(src: &Source, t: &Token) -> Option<&'static Motion> {
    (t.kind == Tok::Ident)
        .then(|| {
            MOTIONS
                .iter()
                .find(|m| same_name(&src.bytes[t.start..t.end], m.name.as_bytes()))
        })
        .flatten()
}

/// A statement's first word that looks like a motion but is not in [`MOTIONS`]: `Move…`,
/// `Search…`, or an application's `ArcL…`, `TriggL…`, `SpotL`, `PaintL`, `DispL`, `CapL`
/// (`TriggIO`, `ArcKill` are not motions).
fn looks_like_motion(src: &Source, t: &Token) -> bool {
    if t.kind != Tok::Ident {
        return false;
    }
    let word = src.text(t.start, t.end).to_ascii_uppercase();
    if word.starts_with("MOVE") || word.starts_with("SEARCH") {
        return true;
    }
    ["ARC", "TRIGG", "CAP", "PAINT", "DISP", "SPOT"]
        .iter()
        .any(|p| {
            word.strip_prefix(p).is_some_and(|rest| {
                let mut chars = rest.chars();
                matches!(chars.next(), Some('L' | 'J' | 'C'))
                    && ["", "START", "END", "IOS", "SYNC", "DO", "AO", "GO"]
                        .contains(&chars.as_str())
            })
        })
}

/// The target a statement assigns (`p10 := …`, `p10.trans.z := …`, `seam{2} := …`),
/// upper case.
fn assigned(src: &Source, statement: &[Token]) -> Option<String> {
    let first = statement.first().filter(|t| t.kind == Tok::Ident)?;
    let assign = statement
        .windows(2)
        .position(|w| w[0].is(b':') && w[1].is(b'=') && w[1].start == w[0].end)?;
    let before = &statement[1..assign];
    let plain = before.iter().all(|t| {
        t.kind == Tok::Ident
            || t.kind == Tok::Number
            || t.is(b'.')
            || t.is(b'{')
            || t.is(b'}')
            || t.is(b',')
    });
    (plain && before.first().is_none_or(|t| t.is(b'.') || t.is(b'{')))
        .then(|| src.text(first.start, first.end).to_ascii_uppercase())
}

/// The parameters of a routine's head after its name, `(robtarget pT, PERS wobjdata wo,
/// \switch Fast)`: the positional ones' names, in order.
fn parameters(src: &Source, tokens: &[Token]) -> Vec<String> {
    if !tokens.first().is_some_and(|t| t.is(b'(')) {
        return Vec::new();
    }
    let Some(close) = tokens.iter().rposition(|t| t.is(b')')) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    let mut depth = 0i32;
    let mut piece: Vec<&Token> = Vec::new();
    for t in tokens[1..close]
        .iter()
        .chain(std::iter::once(&tokens[close]))
    {
        match t.kind {
            Tok::Punct(b'(' | b'{' | b'[') => depth += 1,
            Tok::Punct(b')' | b'}' | b']') if depth > 0 => depth -= 1,
            _ => {}
        }
        if (t.is(b',') && depth == 0) || std::ptr::eq(t, &tokens[close]) {
            // `type name`, `PERS type name`, `name{*}`: the name is the last word; an
            // optional one (`\switch Fast`) takes no place among the positional ones.
            if !piece.first().is_some_and(|p| p.is(b'\\')) {
                if let Some(n) = piece.iter().rev().find(|p| p.kind == Tok::Ident) {
                    out.push(src.text(n.start, n.end));
                }
            }
            piece.clear();
        } else {
            piece.push(t);
        }
    }
    out
}

/// An array index written as numbers, `2` or `2,3`: as the key writes it.
fn constant_index(src: &Source, index: &[Token]) -> Option<String> {
    let mut out = String::new();
    for (k, t) in index.iter().enumerate() {
        match (k % 2, t.kind) {
            (0, Tok::Number) => out.push_str(&src.text(t.start, t.end)),
            (1, _) if t.is(b',') => out.push(','),
            _ => return None,
        }
    }
    (index.len() % 2 == 1).then_some(out)
}

/// What a move names as its target.
enum Named {
    One(String),
    /// Every element of an array (an index computed at run time).
    All(String),
}

/// A report entry for a move (`instruction`, at `at`) whose target is not corrected.
fn refused_motion(instruction: &str, at: &Token, reason: Reason, detail: String) -> ProgramTarget {
    ProgramTarget {
        name: instruction.to_string(),
        offset: at.start,
        kind: TargetKind::Motion,
        uses: Vec::new(),
        refused: Some(Refusal::new(reason, detail)),
    }
}

/// What the module declares besides its targets.
#[derive(Default)]
struct Declarations {
    tools: HashMap<String, Declared>,
    wobjs: HashMap<String, Declared>,
    /// Every robtarget and jointtarget name declared, with or without a value.
    names: HashSet<String>,
    /// Per array, its elements' names (`SEAM{1}`…).
    arrays: HashMap<String, Vec<String>>,
    /// Targets the program assigns as it runs, and where first.
    assigned: HashMap<String, usize>,
}

/// Words that open or close a block: a line starting with one is a statement of its own
/// (`MODULE m`, `PROC main()`, `IF a THEN`), which no `;` ends.
const BLOCK_WORDS: [&str; 25] = [
    "MODULE",
    "ENDMODULE",
    "PROC",
    "ENDPROC",
    "FUNC",
    "ENDFUNC",
    "TRAP",
    "ENDTRAP",
    "IF",
    "ELSEIF",
    "ELSE",
    "ENDIF",
    "FOR",
    "ENDFOR",
    "WHILE",
    "ENDWHILE",
    "TEST",
    "CASE",
    "DEFAULT",
    "ENDTEST",
    "ERROR",
    "BACKWARD",
    "UNDO",
    "RECORD",
    "ENDRECORD",
];

/// The most tokens a statement may have: a robtarget has some sixty, an array of a
/// thousand targets sixty thousand; a statement without its `;` running on through a huge
/// file is refused before its token list takes some twenty times the file's size.
pub const MAX_STATEMENT_TOKENS: usize = 1 << 20;

/// The tokens up to the next `;` (line ends skipped), the `;` excluded; or up to the line
/// end, for a line opening or closing a block.
fn next_statement(src: &Source, lexer: &mut Lexer) -> Result<Vec<Token>, Error> {
    let mut tokens: Vec<Token> = Vec::new();
    let mut block = false;
    let mut line_start = true;
    loop {
        if tokens.len() >= MAX_STATEMENT_TOKENS {
            return Err(src.error(
                tokens[0].start,
                format!("a statement of more than {MAX_STATEMENT_TOKENS} tokens: a ';' missing?"),
            ));
        }
        let t = lexer.next_token();
        match t.kind {
            Tok::Newline if block => return Ok(tokens),
            Tok::Newline => line_start = true,
            Tok::Eof => return Ok(tokens),
            Tok::Punct(b';') => return Ok(tokens),
            _ => {
                // A line opening or closing a block, or a `%%%` header line, also ends
                // whatever came before it without a `;`.
                let opens = line_start
                    && (t.is(b'%')
                        || (t.kind == Tok::Ident
                            && BLOCK_WORDS.contains(&lexer.text(t).to_ascii_uppercase().as_str())));
                if opens && !tokens.is_empty() {
                    lexer.pos = t.start;
                    return Ok(tokens);
                }
                if opens {
                    block = true;
                }
                line_start = false;
                tokens.push(t)
            }
        }
    }
}

/// One argument of an instruction: its positional part and its `\Name[:=value]` options.
struct Argument<'t> {
    positional: &'t [Token],
    options: Vec<(Token, &'t [Token])>,
}

/// The top-level comma-separated arguments of an instruction.
fn arguments<'t>(src: &Source, tokens: &'t [Token]) -> Result<Vec<Argument<'t>>, Error> {
    let mut pieces = Vec::new();
    let mut depth = 0i32;
    let mut start = 0;
    for (i, t) in tokens.iter().enumerate() {
        match t.kind {
            Tok::Punct(b'[' | b'(' | b'{') => depth += 1,
            Tok::Punct(b']' | b')' | b'}') => depth -= 1,
            Tok::Punct(b',') if depth == 0 => {
                pieces.push(&tokens[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    pieces.push(&tokens[start..]);
    let mut out = Vec::new();
    for piece in pieces {
        let split = piece
            .iter()
            .position(|t| t.is(b'\\'))
            .unwrap_or(piece.len());
        let mut options = Vec::new();
        let mut i = split;
        while i < piece.len() {
            // \Name, or \Name := value up to the next backslash.
            let Some(name) = piece.get(i + 1).filter(|t| t.kind == Tok::Ident) else {
                return Err(src.error(
                    piece[i].start,
                    "expected an optional argument's name after '\\'",
                ));
            };
            let mut j = i + 2;
            let mut value: &[Token] = &[];
            if piece.get(j).is_some_and(|t| t.is(b':'))
                && piece.get(j + 1).is_some_and(|t| t.is(b'='))
            {
                let end = piece[j + 2..]
                    .iter()
                    .position(|t| t.is(b'\\'))
                    .map_or(piece.len(), |p| j + 2 + p);
                value = &piece[j + 2..end];
                j = end;
            }
            options.push((*name, value));
            i = j;
        }
        out.push(Argument {
            positional: &piece[..split],
            options,
        });
    }
    Ok(out)
}

/// How deep lists may nest in a value: a robtarget nests two deep, a record of records a
/// few more; a deeper value is refused where it passes the bound, never read by a recursion
/// as deep as the file is long.
pub const MAX_NESTING: usize = 32;

/// The value starting at `tokens[i]`: a list, a signed number, or a single other token.
fn value(src: &Source, tokens: &[Token], i: usize) -> Result<(Value, usize), Error> {
    nested_value(src, tokens, i, 0)
}

/// [`value`] inside `depth` lists.
fn nested_value(
    src: &Source,
    tokens: &[Token],
    i: usize,
    depth: usize,
) -> Result<(Value, usize), Error> {
    let end_offset = tokens.last().map_or(0, |t| t.end);
    let Some(t) = tokens.get(i) else {
        return Err(src.error(end_offset, "expected a value"));
    };
    match t.kind {
        Tok::Punct(b'[') => {
            if depth >= MAX_NESTING {
                return Err(src.error(
                    t.start,
                    format!("lists nested more than {MAX_NESTING} deep"),
                ));
            }
            let mut items = Vec::new();
            let mut j = i + 1;
            if tokens.get(j).is_some_and(|t| t.is(b']')) {
                return Ok((Value::List(items, t.start), j + 1));
            }
            loop {
                let (item, next) = nested_value(src, tokens, j, depth + 1)?;
                items.push(item);
                match tokens.get(next) {
                    Some(t) if t.is(b',') => j = next + 1,
                    Some(t) if t.is(b']') => {
                        return Ok((Value::List(items, tokens[i].start), next + 1))
                    }
                    Some(t) => {
                        return Err(src.error(
                            t.start,
                            format!("expected ',' or ']', found {}", src.describe(t.start)),
                        ))
                    }
                    None => return Err(src.error(end_offset, "unterminated list: expected ']'")),
                }
            }
        }
        Tok::Number | Tok::Punct(b'-' | b'+') => {
            let n = src.number(t.start, "a list item")?;
            let mut j = i;
            while tokens.get(j).is_some_and(|t| t.start < n.span.1) {
                j += 1;
            }
            Ok((Value::Number(n), j))
        }
        Tok::Ident | Tok::Str => Ok((Value::Other(t.start), i + 1)),
        _ => Err(src.error(
            t.start,
            format!("expected a value, found {}", src.describe(t.start)),
        )),
    }
}

/// The numbers of a list of `n` numbers.
fn numbers<const N: usize>(src: &Source, v: &Value, what: &str) -> Result<[Number; N], Error> {
    let Value::List(items, at) = v else {
        return Err(src.error(
            v.offset(),
            format!("expected {what}: a list of {N} numbers"),
        ));
    };
    if items.len() != N {
        return Err(src.error(
            *at,
            format!(
                "expected {what}: a list of {N} numbers, found {}",
                items.len()
            ),
        ));
    }
    let mut out = Vec::with_capacity(N);
    for item in items {
        match item {
            Value::Number(n) => out.push(*n),
            other => return Err(src.error(other.offset(), format!("{what}: not a number"))),
        }
    }
    Ok(out.try_into().expect("N numbers"))
}

fn list<'v>(src: &Source, v: &'v Value, n: usize, what: &str) -> Result<&'v [Value], Error> {
    match v {
        Value::List(items, _) if items.len() == n => Ok(items),
        Value::List(items, at) => Err(src.error(
            *at,
            format!("expected {what}: {n} items, found {}", items.len()),
        )),
        other => Err(src.error(
            other.offset(),
            format!("expected {what}: a list of {n} items"),
        )),
    }
}

/// A robtarget value, and the external axes it moves.
fn robtarget(src: &Source, v: &Value) -> Result<(TargetKind, Option<String>), Error> {
    let parts = list(
        src,
        v,
        4,
        "a robtarget [[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a,...,eax_f]]",
    )?;
    let position = numbers::<3>(src, &parts[0], "trans [x,y,z]")?;
    let rotation = numbers::<4>(src, &parts[1], "rot [q1,q2,q3,q4]")?;
    let conf = numbers::<4>(src, &parts[2], "robconf [cf1,cf4,cf6,cfx]")?;
    let mut cf = [0i64; 4];
    for (out, n) in cf.iter_mut().zip(&conf) {
        if n.value.fract() != 0.0 || n.value.abs() > 1e6 {
            return Err(src.error(n.span.0, "robconf: not an integer"));
        }
        *out = n.value as i64;
    }
    if !matches!(parts[3], Value::List(..)) {
        return Err(src.error(parts[3].offset(), "expected extax [eax_a,...,eax_f]"));
    }
    Ok((
        TargetKind::Cartesian(Box::new(CartesianTarget {
            position,
            unit: LengthUnit::Millimetre,
            orientation: Some(Orientation::QuaternionWxyz(rotation)),
            config: ConfigHint::RapidConf(cf),
            joints: Vec::new(),
        })),
        external_axes(src, &parts[3]),
    ))
}

/// The external axes an `extax` list moves (any value but 9E9, "not used"), said for a
/// report.
fn external_axes(src: &Source, extax: &Value) -> Option<String> {
    let Value::List(items, _) = extax else {
        return None;
    };
    let moved: Vec<String> = items
        .iter()
        .zip(["eax_a", "eax_b", "eax_c", "eax_d", "eax_e", "eax_f"])
        .filter_map(|(v, name)| match v {
            Value::Number(n) if n.value.abs() < 8.9e9 => {
                Some(format!("{name} {}", src.text(n.span.0, n.span.1)))
            }
            _ => None,
        })
        .collect();
    (!moved.is_empty()).then(|| {
        format!(
            "{}: an external axis (a track, a positioner) the table does not have",
            moved.join(", ")
        )
    })
}

/// A jointtarget value, and the external axes it moves.
fn joint_target(src: &Source, v: &Value) -> Result<(TargetKind, Option<String>), Error> {
    let parts = list(
        src,
        v,
        2,
        "a jointtarget [[rax_1,...,rax_6],[eax_a,...,eax_f]]",
    )?;
    let joints = numbers::<6>(src, &parts[0], "robax [rax_1,...,rax_6]")?;
    Ok((
        TargetKind::Joints(JointTarget {
            joints: joints.to_vec(),
            unit: AngleUnit::Degree,
        }),
        external_axes(src, &parts[1]),
    ))
}

/// A pose `[[x,y,z],[q1,q2,q3,q4]]` (mm, quaternion w first).
fn pose(src: &Source, v: &Value, what: &str) -> Result<Isometry3<f64>, Error> {
    let parts = list(src, v, 2, what)?;
    let t = numbers::<3>(src, &parts[0], "trans [x,y,z]")?.map(|n| n.value);
    let q = numbers::<4>(src, &parts[1], "rot [q1,q2,q3,q4]")?;
    let rotation = adwi_samples::pose::rotation_from_quaternion_wxyz(q.map(|n| n.value))
        .ok_or_else(|| src.error(q[0].span.0, "rot: a zero quaternion is no rotation"))?;
    Ok(Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_rotation_matrix(&rotation),
    ))
}

fn is_true(src: &Source, v: &Value) -> Option<bool> {
    let Value::Other(at) = v else { return None };
    let end = src.identifier_end(*at, b"");
    let word = src.text(*at, end).to_ascii_uppercase();
    match word.as_str() {
        "TRUE" => Some(true),
        "FALSE" => Some(false),
        _ => None,
    }
}

/// A declaration after its `CONST`/`PERS`/`VAR`: `type name [{n}] [:= value]`.
fn declaration(
    src: &Source,
    tokens: &[Token],
    decl: &mut Declarations,
    targets: &mut Vec<(ProgramTarget, Vec<Use>)>,
) -> Result<(), Error> {
    let (Some(ty), Some(name)) = (tokens.first(), tokens.get(1)) else {
        return Ok(());
    };
    if ty.kind != Tok::Ident || name.kind != Tok::Ident {
        return Ok(());
    }
    let ty_name = src.text(ty.start, ty.end).to_ascii_lowercase();
    if !matches!(
        ty_name.as_str(),
        "robtarget" | "jointtarget" | "tooldata" | "wobjdata"
    ) {
        return Ok(());
    }
    let key = src.text(name.start, name.end).to_ascii_uppercase();
    let is_target = matches!(ty_name.as_str(), "robtarget" | "jointtarget");
    if is_target {
        decl.names.insert(key.clone());
    }
    // An array of targets, `name{n} := [t1, …, tn]`, `name{n,m} := [[…], …]` (up to
    // three dimensions).
    let mut at = 2;
    let mut length = None;
    if tokens.get(2).is_some_and(|t| t.is(b'{')) {
        let close = tokens.iter().position(|t| t.is(b'}'));
        match close.and_then(|c| constant_index(src, &tokens[3..c]).map(|i| (c, i))) {
            Some((c, dims)) if is_target && c <= 8 => {
                length = Some(dims);
                at = c + 1;
            }
            // Arrays of frames, or sized by a constant: their targets are not read (a move
            // to them is reported).
            _ => return Ok(()),
        }
    }
    // A declaration without a value.
    let (Some(c), Some(e)) = (tokens.get(at), tokens.get(at + 1)) else {
        return Ok(());
    };
    if !(c.is(b':') && e.is(b'=')) {
        return Ok(());
    }
    let (v, end) = value(src, tokens, at + 2)?;
    if let Some(t) = tokens.get(end) {
        return Err(src.error(t.start, "expected ';' after the value"));
    }
    match ty_name.as_str() {
        "robtarget" | "jointtarget" => {
            let is_robtarget = ty_name == "robtarget";
            let name_text = src.text(name.start, name.end);
            match length {
                None => targets.push((
                    declared_target(src, is_robtarget, name_text, name.start, &v)?,
                    Vec::new(),
                )),
                Some(n) => {
                    let elements = array_targets(src, is_robtarget, &name_text, &n, &v)?;
                    let keys = elements
                        .iter()
                        .map(|t| t.name.to_ascii_uppercase())
                        .collect();
                    decl.arrays.insert(key, keys);
                    targets.extend(elements.into_iter().map(|t| (t, Vec::new())));
                }
            }
        }
        "tooldata" => {
            let declared = tooldata(src, &key, &v)?;
            decl.tools.insert(key, declared);
        }
        _ => {
            let declared = wobjdata(src, &key, &v)?;
            decl.wobjs.insert(key, declared);
        }
    }
    Ok(())
}

/// The target a `robtarget` (`is_robtarget`, or else a `jointtarget`) declaration's value `v` writes,
/// named `name` at `offset`.
fn declared_target(
    src: &Source,
    is_robtarget: bool,
    name: String,
    offset: usize,
    v: &Value,
) -> Result<ProgramTarget, Error> {
    let (kind, external) = if is_robtarget {
        robtarget(src, v)?
    } else {
        joint_target(src, v)?
    };
    Ok(ProgramTarget {
        name,
        offset,
        kind,
        uses: Vec::new(),
        refused: external.map(|e| Refusal::new(Reason::ExternalAxis, e)),
    })
}

/// The targets of an array `name{n}`'s value `v`, `[t1, …, tn]`: `name{1}` to `name{n}`;
/// of `name{n,m}`'s, `[[t11, …, t1m], …]`: `name{1,1}` to `name{n,m}` (`dims` as written).
fn array_targets(
    src: &Source,
    is_robtarget: bool,
    name: &str,
    dims: &str,
    v: &Value,
) -> Result<Vec<ProgramTarget>, Error> {
    let sizes: Vec<&str> = dims.split(',').collect();
    let mut out = Vec::new();
    // (value, its index so far, its dimension)
    let mut stack = vec![(v, String::new(), 0usize)];
    while let Some((v, index, d)) = stack.pop() {
        let Some(n) = sizes.get(d) else {
            let element = format!("{name}{{{index}}}");
            out.push(declared_target(src, is_robtarget, element, v.offset(), v)?);
            continue;
        };
        let Value::List(items, list_at) = v else {
            return Err(src.error(v.offset(), format!("expected {n} items in [ ]")));
        };
        if n.parse::<usize>().ok() != Some(items.len()) {
            return Err(src.error(
                *list_at,
                format!("{name}{{{dims}}} holds {} items here, not {n}", items.len()),
            ));
        }
        for (k, item) in items.iter().enumerate().rev() {
            let index = if index.is_empty() {
                format!("{}", k + 1)
            } else {
                format!("{index},{}", k + 1)
            };
            stack.push((item, index, d + 1));
        }
    }
    Ok(out)
}

/// The tool a `tooldata` value `v` declares as `key`, or why it cannot be used.
fn tooldata(src: &Source, key: &str, v: &Value) -> Result<Declared, Error> {
    let parts = list(
        src,
        v,
        3,
        "a tooldata [robhold,[[x,y,z],[q1,q2,q3,q4]],tload]",
    )?;
    let frame = pose(src, &parts[1], "tframe [[x,y,z],[q1,q2,q3,q4]]")?;
    match is_true(src, &parts[0]) {
        Some(true) => Ok(Ok(frame)),
        Some(false) => Ok(Err(format!(
            "tool {key} is a stationary tool (robhold FALSE): not supported"
        ))),
        None => Err(src.error(parts[0].offset(), "robhold: expected TRUE or FALSE")),
    }
}

/// The work object a `wobjdata` value `v` declares as `key` (`uframe · oframe`), or why
/// it cannot be used.
fn wobjdata(src: &Source, key: &str, v: &Value) -> Result<Declared, Error> {
    let parts = list(src, v, 5, "a wobjdata [robhold,ufprog,ufmec,uframe,oframe]")?;
    let uframe = pose(src, &parts[3], "uframe [[x,y,z],[q1,q2,q3,q4]]")?;
    let oframe = pose(src, &parts[4], "oframe [[x,y,z],[q1,q2,q3,q4]]")?;
    match (is_true(src, &parts[0]), is_true(src, &parts[1])) {
        (Some(false), Some(true)) => Ok(Ok(uframe * oframe)),
        (Some(true), _) => Ok(Err(format!(
            "work object {key} is held by the robot (robhold TRUE): not supported"
        ))),
        (Some(false), Some(false)) => Ok(Err(format!(
            "work object {key} has a moving user frame (ufprog FALSE): not supported"
        ))),
        _ => Err(src.error(parts[0].offset(), "robhold, ufprog: expected TRUE or FALSE")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MODULE: &str = "MODULE M\n\
        ! a comment with [1,2,3]\n\
        PERS tooldata gun:=[TRUE,[[0,0,200],[1,0,0,0]],[5,[0,0,100],[1,0,0,0],0,0,0]];\n\
        TASK PERS wobjdata table1:=[FALSE,TRUE,\"\",[[1000,0,500],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n\
        CONST robtarget p10:=[[600,-0.5,800],[0,0,1,0],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];\n\
        CONST jointtarget home:=[[0,0,0,0,30,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n\
        PROC main()\n\
          MoveAbsJ home\\NoEOffs, v1000, z50, tool0;\n\
          MoveL p10, v100, fine, gun\\WObj:=table1;\n\
          MoveJ [[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, z10, gun;\n\
          MoveL Offs(p10,0,0,100), v100, z10, gun;\n\
        ENDPROC\nENDMODULE\n";

    #[test]
    fn targets_with_their_frames() {
        let p = read(&Source::new("m.mod", MODULE.as_bytes())).unwrap();
        // p10, home, MoveJ's inline target, and the move to Offs(p10, …) reported.
        assert_eq!(p.targets.len(), 4);
        assert_eq!(
            p.targets[3].refused.as_ref().map(|r| r.reason),
            Some(Reason::Relative)
        );
        assert_eq!(p.targets[0].name, "p10");
        assert_eq!(p.targets[0].uses.len(), 1);
        let u = &p.targets[0].uses[0];
        assert_eq!(u.tool.unwrap().translation.vector.z, 200.0);
        assert_eq!(u.base.unwrap().translation.vector.x, 1000.0);
        assert!(matches!(p.targets[1].kind, TargetKind::Joints(_)));
        assert_eq!(p.targets[2].name, "MoveJ");
        assert_eq!(p.targets[2].uses[0].base.unwrap(), Isometry3::identity());
    }

    #[test]
    fn every_motion_of_the_table_takes_its_tool_and_work_object() {
        let t = |x: i32| format!("[[{x},0,500],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]");
        let text = format!(
            "MODULE M\n\
             PERS tooldata gun:=[TRUE,[[0,0,200],[1,0,0,0]],[5,[0,0,100],[1,0,0,0],0,0,0]];\n\
             TASK PERS wobjdata fix:=[FALSE,TRUE,\"\",[[1000,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n\
             CONST robtarget a:={};\nCONST robtarget b:={};\nCONST robtarget s{{2}}:=[{},{}];\n\
             VAR robtarget found;\n\
             PROC main()\n\
               TriggL a,v500,gunon\\T2:=gunoff,z10,gun\\WObj:=fix;\n\
               ArcL s{{i}},v100,seam1,weld1\\Weave:=w1,z1,gun\\WObj:=fix;\n\
               SearchL\\Stop,di1,found,b,v50,gun\\WObj:=fix;\n\
               MoveL found,v50,fine,gun\\WObj:=fix;\n\
               MoveToHome;\n  SpotL b,vmax,gun1,gun;\n\
             ENDPROC\nPROC MoveToHome()\nENDPROC\nENDMODULE\n",
            t(1),
            t(2),
            t(3),
            t(4)
        );
        let p = read(&Source::new("m.mod", text.as_bytes())).unwrap();
        let seen: Vec<(&str, Option<Reason>, usize)> = p
            .targets
            .iter()
            .map(|t| {
                (
                    t.name.as_str(),
                    t.refused.as_ref().map(|r| r.reason),
                    t.uses.len(),
                )
            })
            .collect();
        assert_eq!(
            seen,
            [
                ("a", None, 1),
                // SearchL moves to b; SpotL too, which this reader does not know.
                ("b", Some(Reason::UnknownMotion), 1),
                ("s{1}", None, 1),
                ("s{2}", None, 1),
                ("MoveL", Some(Reason::Dynamic), 0),
                ("SpotL", Some(Reason::UnknownMotion), 0),
            ]
        );
        // TriggL's tool is its fifth argument; the work object its \WObj.
        let u = &p.targets[0].uses[0];
        assert_eq!(u.tool.unwrap().translation.vector.z, 200.0);
        assert_eq!(u.base.unwrap().translation.vector.x, 1000.0);
    }

    #[test]
    fn malformed_targets_are_located() {
        let err = read(&Source::new(
            "m.mod",
            b"MODULE M\nCONST robtarget p:=[[1,2],[1,0,0,0],[0,0,0,0],[0]];\n",
        ))
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "m.mod:2:21: expected trans [x,y,z]: a list of 3 numbers, found 2"
        );
        let err = read(&Source::new(
            "m.mod",
            b"CONST robtarget p:=[[1,2,3],[1,0,0,0],[0,0,0,0],[0]]\nMoveL p, v1, z1, t;",
        ))
        .unwrap_err();
        assert!(
            err.to_string().starts_with("m.mod:2:1: expected ';'"),
            "{err}"
        );
    }

    fn statuses(text: &str) -> Vec<(String, Option<Reason>, usize)> {
        read(&Source::new("m.mod", text.as_bytes()))
            .unwrap()
            .targets
            .iter()
            .map(|t| {
                (
                    t.name.clone(),
                    t.refused.as_ref().map(|r| r.reason),
                    t.uses.len(),
                )
            })
            .collect()
    }

    const P: &str =
        "[[50,0,0],[0.707106781,0,0.707106781,0],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]";

    #[test]
    fn a_tool_or_work_object_the_program_assigns_leaves_its_moves_frame_unknown() {
        let text = format!(
            "MODULE PalletModule\n\
             \x20   PERS tooldata tGrip:=[TRUE,[[0,0,150],[1,0,0,0]],[5,[0,0,75],[1,0,0,0],0,0,0]];\n\
             \x20   TASK PERS wobjdata wStation:=[FALSE,TRUE,\"\",[[1750,450,1200],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n\
             \x20   PERS pose poseStation2:=[[-350,350,300],[1,0,0,0]];\n\
             \x20   CONST robtarget pPick:={P};\n    CONST robtarget pPlace:={P};\n\
             \x20   PROC main()\n\
             \x20       MoveL pPlace,v500,fine,tGrip;\n\
             \x20       wStation.oframe:=poseStation2;\n\
             \x20       MoveL pPick,v500,fine,tool0\\WObj:=wStation;\n\
             \x20       tGrip.tframe.trans.z:=210;\n\
             \x20   ENDPROC\nENDMODULE\n"
        );
        let p = read(&Source::new("m.mod", text.as_bytes())).unwrap();
        // The tool is assigned after the move: main runs again with it.
        let tool = &p.targets[1].uses[0].unknown;
        assert_eq!(p.targets[1].name, "pPlace");
        assert_eq!(tool.len(), 1);
        assert!(tool[0].starts_with("tool tGrip is assigned as the program runs (11:9)"));
        let wobj = &p.targets[0].uses[0].unknown;
        assert!(wobj[0].starts_with("work object wStation is assigned as the program runs (9:9)"));
    }

    /// A program displacement (`PDispSet`, `PDispOn`; the external axes' `EOffsOn`,
    /// `EOffsSet`) stays on across routines until switched off: every move of its module,
    /// before it in the text too (a routine runs again, or is called, while it is on), is
    /// left frame_unknown with the statement named; a module without one keeps its moves.
    #[test]
    fn a_program_displacement_leaves_every_move_of_its_module_frame_unknown() {
        let module = |displace: &str| {
            format!(
                "MODULE Disp\n\
                 \x20   CONST robtarget p10:={P};\n    CONST robtarget p20:={P};\n\
                 \x20   CONST pose peTurn:=[[0,0,0],[0.707106781,0,0,0.707106781]];\n\
                 \x20   PROC first()\n        MoveL p10,v100,fine,tool0;\n    ENDPROC\n\
                 \x20   PROC main()\n\
                 \x20       {displace}\n\
                 \x20       MoveL p20,v100,fine,tool0;\n\
                 \x20       PDispOff;\n\
                 \x20   ENDPROC\nENDMODULE\n"
            )
        };
        for (statement, named) in [
            ("PDispSet peTurn;", "PDispSet at 9:9"),
            ("pdispon \\ExeP:=p10, p20, tool0;", "pdispon at 9:9"),
            ("EOffsSet [100,9E9,9E9,9E9,9E9,9E9];", "EOffsSet at 9:9"),
        ] {
            let p = read(&Source::new("m.mod", module(statement).as_bytes())).unwrap();
            assert_eq!(p.targets.len(), 2, "{statement}");
            for t in &p.targets {
                let unknown = &t.uses[0].unknown;
                assert_eq!(unknown.len(), 1, "{statement}: {unknown:?}");
                assert!(unknown[0].starts_with(named), "{statement}: {unknown:?}");
            }
        }
        let p = read(&Source::new("m.mod", module("WaitTime 1;").as_bytes())).unwrap();
        assert!(p.targets.iter().all(|t| t.uses[0].unknown.is_empty()));
    }

    #[test]
    fn a_target_passed_to_a_routine_that_moves_to_its_parameter_is_not_corrected() {
        let text = format!(
            "MODULE Cell\n\
             \x20   TASK PERS wobjdata wobj1:=[FALSE,TRUE,\"\",[[1700,400,1100],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n\
             \x20   CONST robtarget pParam:={P};\n    CONST robtarget p10:={P};\n\
             \x20   PROC main()\n        pick pParam, wobj1;\n        place p10;\n    ENDPROC\n\
             \x20   PROC pick(robtarget pT, PERS wobjdata wo)\n\
             \x20       MoveL Offs(pT,0,0,100), v1000, z50, tool0\\WObj:=wo;\n\
             \x20       MoveL pT, v200, fine, tool0\\WObj:=wo;\n\
             \x20       MoveL p10, v200, fine, tool0\\WObj:=wo;\n    ENDPROC\n\
             \x20   PROC place(robtarget pT, \\switch Slow)\n\
             \x20       MoveL p10, v200, fine, tool0\\WObj:=wobj1;\n    ENDPROC\nENDMODULE\n"
        );
        let p = read(&Source::new("m.mod", text.as_bytes())).unwrap();
        let seen = p.reasons();
        assert_eq!(
            seen,
            [
                ("pParam", Some(Reason::Dynamic)),
                ("p10", None),
                ("MoveL", Some(Reason::Relative)),
                ("MoveL", Some(Reason::Dynamic)),
            ]
        );
        let detail = &p.targets[0].refused.as_ref().unwrap().detail;
        assert!(
            detail.starts_with("moved to through the parameter pT of pick (called at 6:9)"),
            "{detail}"
        );
        assert!(p.targets[3]
            .refused
            .as_ref()
            .unwrap()
            .detail
            .contains("a parameter of pick"));
        // A work object that is a parameter is whatever the callers pass.
        let u = &p.targets[1].uses;
        assert_eq!(u.len(), 2);
        assert!(u[0].unknown[0].starts_with("work object wo is a parameter of pick"));
        assert!(u[1].unknown.is_empty());
    }

    #[test]
    fn arrays_of_two_and_three_dimensions_are_read() {
        let text = format!(
            "MODULE M\n    CONST robtarget pGrid{{2,3}}:=[[{P},{P},{P}],[{P},{P},{P}]];\n\
             \x20   CONST robtarget pCube{{1,1,2}}:=[[[{P},{P}]]];\n\
             \x20   PROC main()\n        MoveL pGrid{{2,3}}, v500, fine, tool0;\n\
             \x20       MoveL pCube{{1,1,i}}, v500, fine, tool0;\n    ENDPROC\nENDMODULE\n"
        );
        let seen = statuses(&text);
        let names: Vec<(&str, usize)> = seen.iter().map(|(n, _, u)| (n.as_str(), *u)).collect();
        assert_eq!(
            names,
            [
                ("pGrid{1,1}", 0),
                ("pGrid{1,2}", 0),
                ("pGrid{1,3}", 0),
                ("pGrid{2,1}", 0),
                ("pGrid{2,2}", 0),
                ("pGrid{2,3}", 1),
                ("pCube{1,1,1}", 1),
                ("pCube{1,1,2}", 1),
            ]
        );
        assert!(seen.iter().all(|s| s.1.is_none()));
    }
}
