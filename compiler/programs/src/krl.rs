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
//!   `LIN {X 1500,Y 0,Z 1200,A 0,B 90,C 0}`, `CIRC {…},{…}` (and `SPTP`, `SLIN`,
//!   `SCIRC`). Relative motions (`PTP_REL`, `LIN_REL`) write offsets: they are left alone.
//!
//! KRL is case-insensitive; statements are one per line; `;` starts a comment. The tool
//! and base (`$TOOL`, `$BASE`, `TOOL_DATA[n]`) live in the controller's configuration, not
//! in the program: the job's `tool` and `base` options give them.

use std::collections::HashSet;

use crate::lex::{Language, Lexer, Tok, Token};
use crate::number::Number;
use crate::program::{
    AngleUnit, CartesianTarget, ConfigHint, Format, JointTarget, LengthUnit, Orientation, Program,
    ProgramTarget, TargetKind,
};
use crate::source::{same_name, Source};
use crate::Error;

const KRL: Language = Language {
    comment: b';',
    quotes: b"\"'",
    ident_extra: b"$#",
};

const MOTIONS: [&str; 6] = ["PTP", "LIN", "CIRC", "SPTP", "SLIN", "SCIRC"];

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

/// Reads the targets of a KRL file; `partner` is the other file of its `.src`/`.dat`
/// pair, read only for the names its motions use.
///
/// # Errors
///
/// [`Error::Syntax`] at the first malformed target aggregate.
pub fn read(src: &Source, partner: Option<&Source>) -> Result<Program, Error> {
    read_at_most(src, partner, usize::MAX)
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
    let mut used = motion_names(src)?;
    if let Some(p) = partner {
        // The partner is context only: a file that does not read gives no names.
        used.extend(motion_names(p).unwrap_or_default());
    }
    let mut targets = Vec::new();
    let mut lexer = Lexer::new(src, KRL);
    while let Some(line) = lexer.line() {
        statement(src, &line, &used, &mut targets)?;
        if targets.len() > limit {
            return Ok(Program {
                format: Format::Krl,
                targets,
                truncated_at: Some(lexer.pos),
            });
        }
    }
    Ok(Program {
        format: Format::Krl,
        targets,
        truncated_at: None,
    })
}

/// The names (upper case) that motions of `src` move to.
fn motion_names(src: &Source) -> Result<HashSet<String>, Error> {
    let mut names = HashSet::new();
    let mut lexer = Lexer::new(src, KRL);
    while let Some(line) = lexer.line() {
        let Some(first) = line.first() else { continue };
        if first.kind == Tok::Ident && is_motion(src, first) {
            for t in &line[1..] {
                match t.kind {
                    Tok::Ident => {
                        names.insert(src.text(t.start, t.end).to_ascii_uppercase());
                    }
                    Tok::Punct(b',') => {}
                    _ => break,
                }
            }
        }
    }
    Ok(names)
}

fn is_motion(src: &Source, t: &Token) -> bool {
    let word = &src.bytes[t.start..t.end];
    MOTIONS.iter().any(|m| same_name(word, m.as_bytes()))
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

fn statement(
    src: &Source,
    line: &[Token],
    used: &HashSet<String>,
    targets: &mut Vec<ProgramTarget>,
) -> Result<(), Error> {
    let Some(first) = line.first() else {
        return Ok(());
    };
    if first.kind != Tok::Ident {
        return Ok(());
    }
    if is_motion(src, first) {
        let motion = src.text(first.start, first.end).to_ascii_uppercase();
        let mut i = 1;
        while let Some(t) = line.get(i) {
            if t.is(b'{') {
                let (kind, end) = aggregate(src, line, i, None)?;
                targets.push(ProgramTarget {
                    name: motion.clone(),
                    offset: t.start,
                    kind,
                    uses: Vec::new(),
                });
                i = end;
            } else if t.kind == Tok::Ident {
                i += 1;
            } else {
                break;
            }
            // CIRC and SCIRC take two targets: auxiliary point, end point.
            if line.get(i).is_some_and(|t| t.is(b',')) {
                i += 1;
            } else {
                break;
            }
        }
        return Ok(());
    }
    // [DECL] [GLOBAL] [CONST] TYPE NAME = {...}, in any order of the first three.
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
    if kind == Kind::Frame && !used.contains(&name_text.to_ascii_uppercase()) {
        return Ok(());
    }
    if !line.get(i + 3).is_some_and(|t| t.is(b'{')) {
        return Err(src.error(
            line.get(i + 3).map_or(eq.end, |t| t.start),
            format!("expected an aggregate {{...}} after '{name_text}='"),
        ));
    }
    let (target, end) = aggregate(src, line, i + 3, Some(kind))?;
    if let Some(t) = line.get(end) {
        return Err(src.error(t.start, "expected the end of the line after the aggregate"));
    }
    targets.push(ProgramTarget {
        name: name_text,
        offset: name.start,
        kind: target,
        uses: Vec::new(),
    });
    Ok(())
}

/// A value of an aggregate component.
enum Value {
    Number(Number),
    /// An integer written as a number or a `'B…'`/`'H…'` literal (Status, Turn).
    Other,
}

/// The aggregate starting at `line[open]` (a `{`): its target, and the index after its `}`.
fn aggregate(
    src: &Source,
    line: &[Token],
    open: usize,
    declared: Option<Kind>,
) -> Result<(TargetKind, usize), Error> {
    let mut i = open + 1;
    let mut kind = declared;
    // An optional type prefix: {E6POS: X 1, ...}.
    if let (Some(t), Some(colon)) = (line.get(i), line.get(i + 1)) {
        if colon.is(b':') {
            kind = Some(type_of(src, t).ok_or_else(|| {
                src.error(
                    t.start,
                    format!(
                        "{} is not a target type (E6POS, POS, FRAME, E6AXIS, AXIS)",
                        src.describe(t.start)
                    ),
                )
            })?);
            i += 2;
        }
    }
    let mut components: Vec<(String, usize, usize, Value, Option<u32>)> = Vec::new();
    let end_of_line = line.last().map_or(0, |t| t.end);
    loop {
        let Some(t) = line.get(i) else {
            return Err(src.error(end_of_line, "unterminated aggregate: expected '}'"));
        };
        if t.is(b'}') && components.is_empty() {
            i += 1;
            break;
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
        if components.iter().any(|(n, ..)| *n == name) {
            return Err(src.error(t.start, format!("component {name} given twice")));
        }
        i += 1;
        let Some(v) = line.get(i) else {
            return Err(src.error(end_of_line, format!("expected a value for {name}")));
        };
        let (value, integer, next) = match v.kind {
            Tok::Number | Tok::Punct(b'-' | b'+') => {
                let n = src.number(v.start, &name)?;
                // A signed number is one or two tokens: skip those it covers.
                let mut j = i;
                while line.get(j).is_some_and(|t| t.start < n.span.1) {
                    j += 1;
                }
                let integer = (n.value.fract() == 0.0
                    && (0.0..=u32::MAX as f64).contains(&n.value))
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
        };
        components.push((name, t.start, v.start, value, integer));
        i = next;
        match line.get(i) {
            Some(t) if t.is(b',') => i += 1,
            Some(t) if t.is(b'}') => {
                i += 1;
                break;
            }
            Some(t) => {
                return Err(src.error(
                    t.start,
                    format!("expected ',' or '}}', found {}", src.describe(t.start)),
                ))
            }
            None => return Err(src.error(end_of_line, "unterminated aggregate: expected '}'")),
        }
    }
    let has = |n: &str| components.iter().any(|(c, ..)| c == n);
    let kind = match kind {
        Some(k) => k,
        None if has("A1") => Kind::Joints,
        None => Kind::Cartesian,
    };
    let number = |n: &str| -> Result<Option<Number>, Error> {
        match components.iter().find(|(c, ..)| c == n) {
            None => Ok(None),
            Some((_, _, _, Value::Number(v), _)) => Ok(Some(*v)),
            Some((_, _, at, Value::Other, _)) => {
                Err(src.error(*at, format!("{n} must be a number")))
            }
        }
    };
    let allowed: &[&str] = match kind {
        Kind::Joints => &[
            "A1", "A2", "A3", "A4", "A5", "A6", "E1", "E2", "E3", "E4", "E5", "E6",
        ],
        Kind::Cartesian | Kind::Frame => &[
            "X", "Y", "Z", "A", "B", "C", "S", "T", "E1", "E2", "E3", "E4", "E5", "E6",
        ],
    };
    if let Some((name, at, ..)) = components
        .iter()
        .find(|(c, ..)| !allowed.contains(&c.as_str()))
    {
        return Err(src.error(
            *at,
            format!(
                "{name} is not a component of this target (one of {})",
                allowed.join(", ")
            ),
        ));
    }
    let target = match kind {
        Kind::Joints => {
            let mut joints = Vec::new();
            for a in ["A1", "A2", "A3", "A4", "A5", "A6"] {
                match number(a)? {
                    Some(n) => joints.push(n),
                    None => break,
                }
            }
            let given = ["A1", "A2", "A3", "A4", "A5", "A6"]
                .iter()
                .filter(|a| has(a))
                .count();
            if joints.len() != given || joints.is_empty() {
                TargetKind::Incomplete("axes missing between A1 and the last one given".into())
            } else {
                TargetKind::Joints(JointTarget {
                    joints,
                    unit: AngleUnit::Degree,
                })
            }
        }
        Kind::Cartesian | Kind::Frame => {
            let position = [number("X")?, number("Y")?, number("Z")?];
            let abc = [number("A")?, number("B")?, number("C")?];
            let integer = |n: &str| -> Result<Option<u32>, Error> {
                match components.iter().find(|(c, ..)| c == n) {
                    None => Ok(None),
                    Some((_, _, at, _, None)) => Err(src.error(
                        *at,
                        format!("{n} must be a non-negative integer or a 'B…' literal"),
                    )),
                    Some((.., v)) => Ok(*v),
                }
            };
            let (status, turn) = (integer("S")?, integer("T")?);
            match position {
                [Some(x), Some(y), Some(z)] => TargetKind::Cartesian(Box::new(CartesianTarget {
                    position: [x, y, z],
                    unit: LengthUnit::Millimetre,
                    orientation: match abc {
                        [Some(a), Some(b), Some(c)] => Some(Orientation::KukaAbcDeg([a, b, c])),
                        [None, None, None] => None,
                        _ => {
                            return Ok((
                                TargetKind::Incomplete("A, B and C given in part".into()),
                                i,
                            ))
                        }
                    },
                    config: if status.is_some() || turn.is_some() {
                        ConfigHint::KukaStatusTurn { status, turn }
                    } else {
                        ConfigHint::None
                    },
                    joints: Vec::new(),
                })),
                _ => TargetKind::Incomplete("X, Y and Z not all given".into()),
            }
        }
    };
    Ok((target, i))
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
        assert_eq!(t.len(), 3);
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
}
