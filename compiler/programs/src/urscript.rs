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

use std::collections::HashMap;

use nalgebra::Isometry3;

use crate::lex::{Language, Lexer, Tok, Token};
use crate::number::Number;
use crate::program::{
    AngleUnit, CartesianTarget, ConfigHint, Format, FrameUse, JointTarget, LengthUnit, Orientation,
    Program, ProgramTarget, TargetKind,
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
    let mut lexer = Lexer::new(src, URSCRIPT);
    let mut candidates: Vec<Candidate> = Vec::new();
    // Per variable, its assignments (candidate indices) in file order.
    let mut assignments: HashMap<String, Vec<usize>> = HashMap::new();
    // Uses of variables not yet assigned: resolved to the variable's last assignment.
    let mut late_uses: Vec<(String, FrameUse)> = Vec::new();
    let mut tcp = Tcp::Default;
    let mut truncated_at = None;
    while let Some(line) = lexer.line() {
        if candidates.len() > limit {
            truncated_at = Some(lexer.pos);
            break;
        }
        // An assignment: [global|local] NAME = literal.
        let mut i = 0;
        if line
            .first()
            .is_some_and(|t| word(src, t, "global") || word(src, t, "local"))
        {
            i = 1;
        }
        if let (Some(name), Some(eq)) = (line.get(i), line.get(i + 1)) {
            if name.kind == Tok::Ident
                && eq.is(b'=')
                && !line.get(i + 2).is_some_and(|t| t.is(b'='))
            {
                if let Some((literal, _)) = literal(src, &line, i + 2)? {
                    let key = src.text(name.start, name.end);
                    assignments
                        .entry(key.clone())
                        .or_default()
                        .push(candidates.len());
                    candidates.push(Candidate {
                        name: key,
                        offset: line[i + 2].start,
                        literal,
                        uses: Vec::new(),
                    });
                }
            }
        }
        // Calls anywhere on the line.
        let mut k = 0;
        while k + 1 < line.len() {
            let (t, open) = (&line[k], &line[k + 1]);
            if t.kind != Tok::Ident || !open.is(b'(') {
                k += 1;
                continue;
            }
            let call = src.text(t.start, t.end);
            let slots = match call.as_str() {
                "movel" | "movej" | "movep" => 1,
                "movec" => 2,
                "set_tcp" => {
                    tcp = match argument(src, &line, k + 2, &candidates, &assignments)? {
                        Some(Literal::Pose(p)) => Tcp::Known(pose_mm(&p)),
                        _ => Tcp::Unknown(t.start),
                    };
                    k += 2;
                    continue;
                }
                _ => {
                    k += 1;
                    continue;
                }
            };
            let frame = FrameUse {
                tool: match tcp {
                    Tcp::Known(t) => Some(t),
                    Tcp::Default | Tcp::Unknown(_) => None,
                },
                // URScript poses are in the robot's base frame.
                base: Some(Isometry3::identity()),
                offset: t.start,
                undeclared: match tcp {
                    Tcp::Unknown(at) => {
                        let (line, column) = src.location(at);
                        vec![format!("the TCP set by set_tcp at {line}:{column}")]
                    }
                    _ => Vec::new(),
                },
            };
            let mut j = k + 2;
            for _ in 0..slots {
                match line.get(j) {
                    Some(a)
                        if a.kind == Tok::Ident
                            && !line.get(j + 1).is_some_and(|t| t.is(b'[') || t.is(b'(')) =>
                    {
                        let name = src.text(a.start, a.end);
                        match assignments.get(&name).and_then(|v| v.last()) {
                            Some(&c) => candidates[c].uses.push(frame.clone()),
                            None => late_uses.push((name, frame.clone())),
                        }
                        j += 1;
                    }
                    Some(_) => {
                        if let Some((literal, end)) = literal(src, &line, j)? {
                            candidates.push(Candidate {
                                name: call.clone(),
                                offset: line[j].start,
                                literal,
                                uses: vec![frame.clone()],
                            });
                            j = end;
                        } else {
                            break;
                        }
                    }
                    None => break,
                }
                if line.get(j).is_some_and(|t| t.is(b',')) {
                    j += 1;
                } else {
                    break;
                }
            }
            k += 2;
        }
    }
    for (name, frame) in late_uses {
        if let Some(&c) = assignments.get(&name).and_then(|v| v.last()) {
            candidates[c].uses.push(frame);
        }
    }
    let targets = candidates
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
        })
        .collect();
    Ok(Program {
        format: Format::UrScript,
        targets,
        truncated_at,
    })
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
    assignments: &HashMap<String, Vec<usize>>,
) -> Result<Option<Literal>, Error> {
    if let Some(t) = line.get(i) {
        if t.kind == Tok::Ident && line.get(i + 1).is_some_and(|t| t.is(b')')) {
            let name = src.text(t.start, t.end);
            return Ok(assignments
                .get(&name)
                .and_then(|v| v.last())
                .map(|&c| candidates[c].literal.clone()));
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
        assert_eq!(p.targets.len(), 2);
        assert_eq!(p.targets[0].name, "start");
        assert!(matches!(p.targets[0].kind, TargetKind::Joints(ref j) if j.joints.len() == 6));
        assert_eq!(p.targets[0].uses[0].tool, None);
        assert_eq!(p.targets[1].name, "movel");
        let tool = p.targets[1].uses[0].tool.unwrap();
        assert!((tool.translation.vector.z - 31.0).abs() < 1e-12);
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
