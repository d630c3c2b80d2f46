//! Universal Robots URScript.
//!
//! Targets are pose literals `p[x,y,z,rx,ry,rz]` (metres, rotation vector in radians, robot
//! base frame) and joint lists `[q1,…,q6]` (radians) written as the target of `movel`,
//! `movej`, `movep` or `movec` (its first two arguments), or assigned to a variable
//! (`global p1 = p[…]`, `q0 = […]`) that such a move takes: the assignment the move reads
//! is the last one before it in the file (the last in the file when none comes before, for
//! a variable a function uses before the script's end assigns it). A literal that no move
//! reads (an offset given to `pose_trans`, say) is not a target.
//!
//! The TCP of a move is the one the last `set_tcp(p[…])` before it in the file sets (a
//! variable holding a pose literal counts too); before any, the job's `tool` option. A
//! `set_tcp` of another expression leaves the TCP unknown to the reader: the job's `tool`
//! option must give it. Statements are one per line; `#` starts a comment.

use std::collections::{HashMap, HashSet};

use nalgebra::Isometry3;

use crate::lex::{Language, Lexer, Tok, Token};
use crate::number::Number;
use crate::program::{
    AngleUnit, CartesianTarget, ConfigHint, Format, FrameUse, JointTarget, LengthUnit, Orientation,
    Program, ProgramTarget, Reason, Refusal, TargetKind, Undeclared,
};
use crate::source::Source;
use crate::Error;

const URSCRIPT: Language = Language {
    comment: b'#',
    quotes: b"\"'",
    ident_extra: b"",
};

/// A literal the script writes.
#[derive(Clone, Debug)]
enum Literal {
    Pose(Box<[Number; 6]>),
    Joints(Vec<Number>),
}

/// A literal target candidate: where it is written, its name, and the TCPs of its uses.
struct Candidate {
    name: String,
    offset: usize,
    literal: Literal,
    uses: Vec<FrameUse>,
}

/// The TCP as the script has set it so far.
#[derive(Clone, Debug)]
enum Tcp {
    /// No `set_tcp` yet: the job's tool.
    Default,
    Known(Isometry3<f64>),
    Unknown(usize),
}

/// Reads the targets of a URScript program.
///
/// # Errors
///
/// [`Error::Syntax`] at the first malformed pose literal or joint list.
pub fn read(src: &Source) -> Result<Program, Error> {
    read_at_most(src, usize::MAX)
}

/// [`read`], stopping after `limit` literals that may be targets
/// ([`Program::truncated_at`]).
///
/// # Errors
///
/// As [`read`].
pub fn read_at_most(src: &Source, limit: usize) -> Result<Program, Error> {
    let mut script = Script::new(src);
    let mut lexer = Lexer::new(src, URSCRIPT);
    let mut truncated_at = None;
    while let Some(line) = lexer.line() {
        if script.candidates.len() > limit {
            truncated_at = Some(lexer.pos);
            break;
        }
        script.assignment(src, &line)?;
        script.calls(src, &line)?;
    }
    script.resolve_late_uses(src);
    script.refuse_offsets_from_targets();
    Ok(script.program(truncated_at))
}

/// What a script says, line by line: its literals that may be targets and the uses of
/// each, its variables' assignments, the TCP it sets, and the motions refused.
struct Script {
    /// The script's own functions: a call of one is not a motion, whatever its name.
    functions: HashSet<String>,
    candidates: Vec<Candidate>,
    /// Per variable, its last assignment so far.
    last: HashMap<String, Assign>,
    /// Per variable, its last assignment in the file.
    last_in_file: HashMap<String, Assign>,
    /// Uses of variables not yet assigned: resolved to the variable's last assignment.
    late_uses: Vec<(String, FrameUse, Token, String)>,
    /// `pose_trans(F, X)` whose frame is a variable: refused if F is itself a target.
    frames_used: Vec<(String, usize)>,
    refused: Vec<ProgramTarget>,
    tcp: Tcp,
    first_motion: Option<usize>,
}

impl Script {
    /// A script about to be read, its functions known.
    fn new(src: &Source) -> Script {
        let mut functions: HashSet<String> = HashSet::new();
        let mut lexer = Lexer::new(src, URSCRIPT);
        while let Some(line) = lexer.line() {
            if let [d, name, ..] = line.as_slice() {
                if word(src, d, "def") && name.kind == Tok::Ident {
                    functions.insert(src.text(name.start, name.end));
                }
            }
        }
        Script {
            functions,
            candidates: Vec::new(),
            last: HashMap::new(),
            last_in_file: HashMap::new(),
            late_uses: Vec::new(),
            frames_used: Vec::new(),
            refused: Vec::new(),
            tcp: Tcp::Default,
            first_motion: None,
        }
    }

    /// A line's assignment, if it is one: `[global|local] NAME = value`.
    fn assignment(&mut self, src: &Source, line: &[Token]) -> Result<(), Error> {
        let mut i = 0;
        if line
            .first()
            .is_some_and(|t| word(src, t, "global") || word(src, t, "local"))
        {
            i = 1;
        }
        let (Some(name), Some(eq)) = (line.get(i), line.get(i + 1)) else {
            return Ok(());
        };
        if name.kind != Tok::Ident || !eq.is(b'=') || line.get(i + 2).is_some_and(|t| t.is(b'=')) {
            return Ok(());
        }
        let key = src.text(name.start, name.end);
        let assign = match literal(src, line, i + 2)? {
            Some((literal, end)) if end == line.len() => {
                self.candidates.push(Candidate {
                    name: key.clone(),
                    offset: line[i + 2].start,
                    literal,
                    uses: Vec::new(),
                });
                Assign::Literal(self.candidates.len() - 1)
            }
            _ => Assign::Expression(line.get(i + 2).map_or(eq.end, |t| t.start)),
        };
        self.last.insert(key.clone(), assign);
        self.last_in_file.insert(key, assign);
        Ok(())
    }

    /// The calls anywhere on a line: `set_tcp`, the motions, and calls that look like
    /// motions.
    fn calls(&mut self, src: &Source, line: &[Token]) -> Result<(), Error> {
        let mut k = 0;
        while k + 1 < line.len() {
            let (t, open) = (&line[k], &line[k + 1]);
            if t.kind != Tok::Ident || !open.is(b'(') {
                k += 1;
                continue;
            }
            let call = src.text(t.start, t.end);
            if call == "set_tcp" {
                self.tcp = match argument(src, line, k + 2, &self.candidates, &self.last)? {
                    Some(Literal::Pose(p)) => Tcp::Known(pose_mm(&p)),
                    _ => Tcp::Unknown(t.start),
                };
                k += 2;
                continue;
            }
            let Some(m) = MOTIONS.iter().find(|m| m.name == call) else {
                if (call.starts_with("move") || call.starts_with("servo"))
                    && !self.functions.contains(&call)
                {
                    self.first_motion.get_or_insert(t.start);
                    self.refused.push(refused_call(
                        t,
                        &call,
                        Reason::UnknownMotion,
                        format!("{call} is not a URScript motion this reader knows"),
                    ));
                }
                k += 1;
                continue;
            };
            self.first_motion.get_or_insert(t.start);
            self.motion(src, line, k + 2, m, &call, self.frame_use(src, t.start))?;
            k += 2;
        }
        Ok(())
    }

    /// The frames of a motion at `at`: the TCP `set_tcp` last set, in the robot's base
    /// frame.
    fn frame_use(&self, src: &Source, at: usize) -> FrameUse {
        FrameUse {
            tool: match self.tcp {
                Tcp::Known(t) => Some(t),
                Tcp::Default | Tcp::Unknown(_) => None,
            },
            // URScript poses are in the robot's base frame.
            base: Some(Isometry3::identity()),
            offset: at,
            elsewhere: None,
            undeclared: match self.tcp {
                Tcp::Unknown(set_at) => {
                    let (line, column) = src.location(set_at);
                    vec![Undeclared {
                        base: false,
                        name: format!("set by set_tcp at {line}:{column}"),
                    }]
                }
                _ => Vec::new(),
            },
            unknown: Vec::new(),
        }
    }

    /// The targets of the motion `m` (`call`) whose arguments start at `line[j]`, each used
    /// in `frame`.
    fn motion(
        &mut self,
        src: &Source,
        line: &[Token],
        mut j: usize,
        m: &Motion,
        call: &str,
        frame: FrameUse,
    ) -> Result<(), Error> {
        for _ in 0..m.targets {
            let end = argument_end(line, j);
            if end == j {
                break;
            }
            let mut reader = Reader {
                src,
                candidates: &mut self.candidates,
                last: &self.last,
                late_uses: &mut self.late_uses,
                frames_used: &mut self.frames_used,
                refused: &mut self.refused,
                call,
            };
            reader.target(&line[j..end], frame.clone())?;
            j = end;
            if line.get(j).is_some_and(|t| t.is(b',')) {
                j += 1;
            } else {
                break;
            }
        }
        Ok(())
    }

    /// Gives the uses of variables assigned only later in the file to their last
    /// assignment; a use of an expression or of a name never assigned is refused.
    fn resolve_late_uses(&mut self, src: &Source) {
        for (name, frame, at, call) in std::mem::take(&mut self.late_uses) {
            match self.last_in_file.get(&name) {
                Some(Assign::Literal(c)) => self.candidates[*c].uses.push(frame),
                Some(Assign::Expression(e)) => {
                    let (l, c) = src.location(*e);
                    self.refused.push(refused_call(
                        &at,
                        &call,
                        Reason::Dynamic,
                        format!(
                            "{call}({name}): {name} is computed when the script runs ({l}:{c})"
                        ),
                    ));
                }
                None => self.refused.push(refused_call(
                    &at,
                    &call,
                    Reason::Dynamic,
                    format!(
                        "{call}({name}): {name} is not assigned in the script (given when it runs)"
                    ),
                )),
            }
        }
    }

    /// Refuses the offsets from a frame that is itself a target: the composed pose moves
    /// with the frame's correction, which no correction of the offset can undo.
    fn refuse_offsets_from_targets(&mut self) {
        for (frame, c) in std::mem::take(&mut self.frames_used) {
            let is_target = self.candidates.iter().any(|o| {
                o.name == frame && o.uses.iter().any(|u| u.base == Some(Isometry3::identity()))
            });
            if !is_target {
                continue;
            }
            let candidate = &mut self.candidates[c];
            let uses = std::mem::take(&mut candidate.uses);
            for u in uses {
                self.refused.push(ProgramTarget {
                    name: "pose_trans".into(),
                    offset: u.offset,
                    kind: TargetKind::Motion,
                    uses: Vec::new(),
                    refused: Some(Refusal::new(
                        Reason::Relative,
                        format!(
                            "pose_trans({frame}, {}): an offset from {frame}, itself a target the correction moves",
                            candidate.name
                        ),
                    )),
                });
            }
        }
    }

    /// The program: the literals a motion uses, and the motions refused.
    fn program(self, truncated_at: Option<usize>) -> Program {
        let mut targets: Vec<ProgramTarget> = self
            .candidates
            .into_iter()
            .filter(|c| !c.uses.is_empty())
            .map(|c| ProgramTarget {
                name: c.name,
                offset: c.offset,
                kind: match c.literal {
                    Literal::Pose(pose) => {
                        let [x, y, z, rx, ry, rz] = *pose;
                        TargetKind::Cartesian(Box::new(CartesianTarget {
                            position: [x, y, z],
                            unit: LengthUnit::Metre,
                            orientation: Some(Orientation::RotationVectorRad([rx, ry, rz])),
                            config: ConfigHint::None,
                            joints: Vec::new(),
                        }))
                    }
                    Literal::Joints(joints) => TargetKind::Joints(JointTarget {
                        joints,
                        unit: AngleUnit::Radian,
                    }),
                },
                uses: c.uses,
                refused: None,
            })
            .collect();
        targets.extend(self.refused);
        targets.sort_by_key(|t| t.offset);
        Program {
            format: Format::UrScript,
            targets,
            truncated_at,
            first_motion: self.first_motion,
        }
    }
}

/// A motion of URScript: its name and how many targets it takes (its first arguments).
/// A URScript motion names no frame: its poses are in the robot's base frame, its TCP the
/// one `set_tcp` last set.
#[derive(Clone, Copy, Debug)]
pub struct Motion {
    /// The function.
    pub name: &'static str,
    /// Its targets: 1, or 2 for `movec` (via point, end point).
    pub targets: usize,
}

/// The motions of URScript (e-Series and CB3), every one accounted for. A target is a
/// pose literal or joint list, a variable holding one, `get_inverse_kin(pose, …)` of one
/// (`movej` to a pose, as PolyScope writes it) or `pose_trans(feature, pose)` with a
/// feature that holds a pose literal (a waypoint relative to a feature); anything else is
/// reported.
pub const MOTIONS: [Motion; 6] = [
    Motion {
        name: "movej",
        targets: 1,
    },
    Motion {
        name: "movel",
        targets: 1,
    },
    Motion {
        name: "movep",
        targets: 1,
    },
    Motion {
        name: "movec",
        targets: 2,
    },
    Motion {
        name: "servoj",
        targets: 1,
    },
    Motion {
        name: "servoc",
        targets: 1,
    },
];

/// A variable's assignment: a literal (the candidate's index) or an expression (where).
#[derive(Clone, Copy, Debug)]
enum Assign {
    Literal(usize),
    Expression(usize),
}

/// The end of the call argument starting at `line[i]`: its `,` or the call's `)`.
fn argument_end(line: &[Token], i: usize) -> usize {
    let mut depth = 0i32;
    let mut k = i;
    while let Some(t) = line.get(k) {
        match t.kind {
            Tok::Punct(b'(' | b'[') => depth += 1,
            Tok::Punct(b')' | b']') if depth == 0 => return k,
            Tok::Punct(b')' | b']') => depth -= 1,
            Tok::Punct(b',') if depth == 0 => return k,
            _ => {}
        }
        k += 1;
    }
    k
}

fn refused_call(at: &Token, call: &str, reason: Reason, detail: String) -> ProgramTarget {
    ProgramTarget {
        name: call.to_string(),
        offset: at.start,
        kind: TargetKind::Motion,
        uses: Vec::new(),
        refused: Some(Refusal::new(reason, detail)),
    }
}

/// Reads one target argument of a motion.
struct Reader<'r, 's, 'a> {
    src: &'r Source<'a>,
    candidates: &'r mut Vec<Candidate>,
    last: &'r HashMap<String, Assign>,
    late_uses: &'r mut Vec<(String, FrameUse, Token, String)>,
    frames_used: &'r mut Vec<(String, usize)>,
    refused: &'r mut Vec<ProgramTarget>,
    call: &'s str,
}

impl Reader<'_, '_, '_> {
    fn target(&mut self, arg: &[Token], frame: FrameUse) -> Result<(), Error> {
        let src = self.src;
        let call = self.call.to_string();
        let text = src.text(arg[0].start, arg[arg.len() - 1].end);
        // A literal.
        if let Some((literal, end)) = literal(src, arg, 0)? {
            if end == arg.len() {
                self.candidates.push(Candidate {
                    name: call.clone(),
                    offset: arg[0].start,
                    literal,
                    uses: vec![frame],
                });
                return Ok(());
            }
        }
        match arg {
            // A variable.
            [t] if t.kind == Tok::Ident => {
                let name = src.text(t.start, t.end);
                match self.last.get(&name) {
                    Some(Assign::Literal(c)) => self.candidates[*c].uses.push(frame),
                    Some(Assign::Expression(at)) => {
                        let (l, c) = src.location(*at);
                        self.refuse_target(
                            arg,
                            Reason::Dynamic,
                            &format!("{name} is computed when the script runs ({l}:{c})"),
                        );
                    }
                    None => self.late_uses.push((name, frame, *t, call.clone())),
                }
            }
            // PolyScope's `movej(get_inverse_kin(Waypoint_1_p, qnear=Waypoint_1_q))`: the
            // TCP goes to the pose.
            [f, open, inner @ .., close]
                if word(src, f, "get_inverse_kin") && open.is(b'(') && close.is(b')') =>
            {
                let end = argument_end(inner, 0);
                if end == 0 {
                    self.refuse_target(
                        arg,
                        Reason::Dynamic,
                        "a pose computed when the script runs",
                    );
                    return Ok(());
                }
                self.target(&inner[..end], frame)?;
            }
            // A waypoint relative to a feature: `pose_trans(Plane_1, p[…])`.
            [f, open, inner @ .., close]
                if word(src, f, "pose_trans") && open.is(b'(') && close.is(b')') =>
            {
                self.feature_target(arg, inner, frame)?;
            }
            _ => {
                let relative = [
                    "pose_add",
                    "pose_sub",
                    "get_actual_tcp_pose",
                    "get_target_tcp_pose",
                    "get_actual_joint_positions",
                ]
                .iter()
                .any(|w| text.contains(w));
                if relative {
                    self.refuse_target(
                        arg,
                        Reason::Relative,
                        "an offset from where the robot stands when the script runs",
                    );
                } else {
                    self.refuse_target(
                        arg,
                        Reason::Dynamic,
                        "a target computed when the script runs",
                    );
                }
            }
        }
        Ok(())
    }

    /// A waypoint relative to a feature, `pose_trans(feature, pose)` (`inner` its
    /// arguments): the pose a target in the feature's frame, when the feature is a pose
    /// literal; else refused.
    fn feature_target(
        &mut self,
        arg: &[Token],
        inner: &[Token],
        frame: FrameUse,
    ) -> Result<(), Error> {
        let src = self.src;
        let text = src.text(arg[0].start, arg[arg.len() - 1].end);
        let split = argument_end(inner, 0);
        let (Some(feature), Some(pose)) = (
            Some(&inner[..split]).filter(|s| !s.is_empty()),
            inner.get(split + 1..).filter(|s| !s.is_empty()),
        ) else {
            self.refuse_target(arg, Reason::Dynamic, "a pose computed when the script runs");
            return Ok(());
        };
        let feature_pose = match feature {
            [v] if v.kind == Tok::Ident => match self.last.get(&src.text(v.start, v.end)) {
                Some(Assign::Literal(c)) => match &self.candidates[*c].literal {
                    Literal::Pose(p) => Some((pose_mm(p), Some(src.text(v.start, v.end)))),
                    Literal::Joints(_) => None,
                },
                _ => None,
            },
            _ => match literal(src, feature, 0)? {
                Some((Literal::Pose(p), end)) if end == feature.len() => Some((pose_mm(&p), None)),
                _ => None,
            },
        };
        let Some((base, feature_name)) = feature_pose else {
            let reason =
                if text.contains("get_actual_tcp_pose") || text.contains("get_target_tcp_pose") {
                    Reason::Relative
                } else {
                    Reason::Dynamic
                };
            self.refuse_target(
                arg,
                reason,
                "an offset from a pose the script computes when it runs",
            );
            return Ok(());
        };
        let mut in_feature = frame.clone();
        in_feature.base = Some(base);
        let count = self.candidates.len();
        let before = self.refused.len();
        self.target(pose, in_feature)?;
        // The offset's candidate, to refuse should the feature be a target itself.
        if let Some(name) = feature_name {
            if self.refused.len() == before {
                let c = if self.candidates.len() > count {
                    Some(count)
                } else {
                    match pose {
                        [v] if v.kind == Tok::Ident => {
                            match self.last.get(&src.text(v.start, v.end)) {
                                Some(Assign::Literal(c)) => Some(*c),
                                _ => None,
                            }
                        }
                        _ => None,
                    }
                };
                if let Some(c) = c {
                    self.frames_used.push((name, c));
                }
            }
        }
        Ok(())
    }

    /// Refuses the current call's target `arg`, with the reason.
    fn refuse_target(&mut self, arg: &[Token], reason: Reason, why: &str) {
        let call = self.call.to_string();
        let text = self.src.text(arg[0].start, arg[arg.len() - 1].end);
        self.refused.push(refused_call(
            &arg[0],
            &call,
            reason,
            format!("{call}({text}): {why}"),
        ));
    }
}

fn word(src: &Source, t: &Token, w: &str) -> bool {
    t.kind == Tok::Ident && &src.bytes[t.start..t.end] == w.as_bytes()
}

/// The pose of a `p[…]` literal, in mm.
fn pose_mm(p: &[Number; 6]) -> Isometry3<f64> {
    let v = p.map(|n| n.value);
    Isometry3::new(
        nalgebra::Vector3::new(v[0], v[1], v[2]) * 1000.0,
        nalgebra::Vector3::new(v[3], v[4], v[5]),
    )
}

/// The literal of a call's argument at `line[i]`: written there, or held by the variable
/// named there (its last assignment so far).
fn argument(
    src: &Source,
    line: &[Token],
    i: usize,
    candidates: &[Candidate],
    last: &HashMap<String, Assign>,
) -> Result<Option<Literal>, Error> {
    if let Some(t) = line.get(i) {
        if t.kind == Tok::Ident && line.get(i + 1).is_some_and(|t| t.is(b')')) {
            let name = src.text(t.start, t.end);
            return Ok(match last.get(&name) {
                Some(Assign::Literal(c)) => Some(candidates[*c].literal.clone()),
                _ => None,
            });
        }
    }
    Ok(literal(src, line, i)?.map(|(l, _)| l))
}

/// A pose literal `p[6 numbers]` or a joint list `[numbers]` at `line[i]`, and the index
/// after it; `None` for anything else (an expression). A literal whose items are not all
/// numbers is an expression too.
fn literal(src: &Source, line: &[Token], i: usize) -> Result<Option<(Literal, usize)>, Error> {
    let (pose, open) = match (line.get(i), line.get(i + 1)) {
        (Some(p), Some(b)) if word(src, p, "p") && b.is(b'[') && b.start == p.end => (true, i + 1),
        (Some(b), _) if b.is(b'[') => (false, i),
        _ => return Ok(None),
    };
    let mut numbers = Vec::new();
    let mut j = open + 1;
    let end_offset = line.last().map_or(0, |t| t.end);
    loop {
        let Some(t) = line.get(j) else {
            return Err(src.error(end_offset, "unterminated list: expected ']'"));
        };
        match t.kind {
            Tok::Number | Tok::Punct(b'-' | b'+') => {
                let Some(n) = crate::number::parse_number(src.bytes, t.start) else {
                    return Ok(None);
                };
                numbers.push(n);
                while line.get(j).is_some_and(|t| t.start < n.span.1) {
                    j += 1;
                }
            }
            _ => return Ok(None),
        }
        match line.get(j) {
            Some(t) if t.is(b',') => j += 1,
            Some(t) if t.is(b']') => break,
            Some(_) => return Ok(None),
            None => return Err(src.error(end_offset, "unterminated list: expected ']'")),
        }
    }
    let end = j + 1;
    if pose {
        let Ok(p) = <[Number; 6]>::try_from(numbers.as_slice()) else {
            return Err(src.error(
                line[i].start,
                format!(
                    "a pose p[x,y,z,rx,ry,rz] has 6 numbers, not {}",
                    numbers.len()
                ),
            ));
        };
        Ok(Some((Literal::Pose(Box::new(p)), end)))
    } else if numbers.is_empty() {
        Ok(None)
    } else {
        Ok(Some((Literal::Joints(numbers), end)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moves_variables_and_the_tcp() {
        let text = "def prog():\n  # start\n  global start = [0.1, -1.57, 1.2, -1.2, -1.57, 0]\n\
                    offset = p[0, 0, 0.1, 0, 0, 0]\n  movej(start, a=1.4, v=1.05)\n\
                    set_tcp(p[0, 0, 0.031, 0, 0, 0])\n  movel(p[0.4, -0.2, 0.3, 0, 3.14159, 0], a=1.2, v=0.25)\n\
                    movel(pose_trans(p[0.4, -0.2, 0.3, 0, 3.14159, 0], offset))\nend\n";
        let p = read(&Source::new("p.script", text.as_bytes())).unwrap();
        // `offset` is a target too: in the frame pose_trans puts it in.
        assert_eq!(p.targets.len(), 3);
        assert_eq!(p.targets[1].name, "offset");
        let base = p.targets[1].uses[0].base.unwrap();
        assert!((base.translation.vector.x - 400.0).abs() < 1e-9);
        let p = Program {
            targets: vec![p.targets[0].clone(), p.targets[2].clone()],
            ..p
        };
        assert_eq!(p.targets[0].name, "start");
        assert!(matches!(p.targets[0].kind, TargetKind::Joints(ref j) if j.joints.len() == 6));
        assert_eq!(p.targets[0].uses[0].tool, None);
        assert_eq!(p.targets[1].name, "movel");
        let tool = p.targets[1].uses[0].tool.unwrap();
        assert!((tool.translation.vector.z - 31.0).abs() < 1e-12);
    }

    #[test]
    fn polyscope_forms_are_targets_and_every_other_motion_is_reported() {
        let text = "def p():\n  global Plane_1=p[0.1,0,0,0,0,0]\n  global W_p=p[0.4,-0.2,0.3,0,3.14,0]\n\
                    global W_q=[0,-1.5,1.5,0,1.5,0]\n  set_tcp(get_tcp_offset())\n\
                    movej(get_inverse_kin(W_p, qnear=W_q), a=1.4)\n\
                    movel(pose_trans(Plane_1, p[0,0,0.1,0,3.14,0]))\n  x = get_actual_tcp_pose()\n\
                    movel(x)\n  movel(pose_add(get_actual_tcp_pose(), p[0,0,0.01,0,0,0]))\n  moveq(W_p)\nend\n";
        let p = read(&Source::new("p.script", text.as_bytes())).unwrap();
        let seen: Vec<(&str, Option<Reason>)> = p
            .targets
            .iter()
            .map(|t| (t.name.as_str(), t.refused.as_ref().map(|r| r.reason)))
            .collect();
        assert_eq!(
            seen,
            [
                ("W_p", None),
                ("movel", None),
                ("movel", Some(Reason::Dynamic)),
                ("movel", Some(Reason::Relative)),
                ("moveq", Some(Reason::UnknownMotion)),
            ]
        );
        // The TCP set_tcp sets from an expression: the tool option must stand for it.
        let w = &p.targets[0].uses[0];
        assert_eq!(w.undeclared[0].name, "set by set_tcp at 5:3");
        // The waypoint on Plane_1 is in its frame.
        let on_plane = p.targets[1].uses[0].base.unwrap();
        assert!((on_plane.translation.vector.x - 100.0).abs() < 1e-9);
        // W_q, only the IK's seed, is not a target.
        assert!(p.targets.iter().all(|t| t.name != "W_q"));
    }

    #[test]
    fn a_pose_of_five_numbers_is_located() {
        let err = read(&Source::new("p.script", b"movel(p[1,2,3,4,5])\n")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "p.script:1:7: a pose p[x,y,z,rx,ry,rz] has 6 numbers, not 5"
        );
    }
}
