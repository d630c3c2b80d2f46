//! ABB RAPID modules (`.mod`).
//!
//! Targets are `robtarget` declarations (`CONST`, `PERS` or `VAR`, optionally `LOCAL` or
//! `TASK`) with a value, `[[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a,…,eax_f]]` (mm,
//! quaternion w first), `jointtarget` declarations `[[rax_1,…,rax_6],[eax_a,…]]` (degrees),
//! and such values written inline as the target of a `MoveJ`, `MoveL`, `MoveC` (two
//! targets) or `MoveAbsJ` (the pendant shows them as `*`). Arrays of targets are left
//! alone.
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

use std::collections::HashMap;

use nalgebra::{Isometry3, Translation3, UnitQuaternion};

use crate::lex::{Language, Lexer, Tok, Token};
use crate::number::Number;
use crate::program::{
    AngleUnit, CartesianTarget, ConfigHint, Format, FrameUse, JointTarget, LengthUnit, Orientation,
    Program, ProgramTarget, TargetKind,
};
use crate::source::Source;
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
struct Use {
    tool: String,
    tool_at: usize,
    wobj: Option<(String, usize)>,
    at: usize,
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
    let mut tools: HashMap<String, Declared> = HashMap::new();
    let mut wobjs: HashMap<String, Declared> = HashMap::new();
    // Named targets, with their uses collected as moves are read.
    let mut targets: Vec<(ProgramTarget, Vec<Use>)> = Vec::new();
    let mut by_name: HashMap<String, usize> = HashMap::new();
    let mut pending_uses: Vec<(String, Use)> = Vec::new();
    let mut truncated_at = None;
    loop {
        if targets.len() > limit {
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
        if matches!(
            words.get(i).map(String::as_str),
            Some("CONST" | "PERS" | "VAR")
        ) {
            declaration(
                src,
                &statement[i + 1..],
                &mut tools,
                &mut wobjs,
                &mut targets,
                &mut by_name,
            )?;
            continue;
        }
        // The move may follow a compact IF's condition or a CASE label on its line.
        let slots_of = |t: &Token| -> Option<(&'static [usize], usize, &'static str)> {
            if t.kind != Tok::Ident {
                return None;
            }
            match src.text(t.start, t.end).to_ascii_uppercase().as_str() {
                "MOVEJ" => Some((&[0], 3, "MoveJ")),
                "MOVEL" => Some((&[0], 3, "MoveL")),
                "MOVEABSJ" => Some((&[0], 3, "MoveAbsJ")),
                "MOVEC" => Some((&[0, 1], 4, "MoveC")),
                _ => None,
            }
        };
        let Some((at, (target_slots, tool_slot, instruction))) = statement
            .iter()
            .enumerate()
            .find_map(|(k, t)| slots_of(t).map(|s| (k, s)))
        else {
            continue;
        };
        let statement = &statement[at..];
        let args = arguments(src, &statement[1..])?;
        let positional: Vec<&[Token]> = args
            .iter()
            .filter(|a| !a.positional.is_empty())
            .map(|a| a.positional)
            .collect();
        let Some(tool) = positional
            .get(tool_slot)
            .filter(|t| t.len() == 1 && t[0].kind == Tok::Ident)
        else {
            return Err(src.error(
                statement[0].start,
                format!(
                    "{} needs its tool as argument {} (a tooldata name)",
                    src.text(statement[0].start, statement[0].end),
                    tool_slot + 1
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
        let make_use = || Use {
            tool: src.text(tool[0].start, tool[0].end).to_ascii_uppercase(),
            tool_at: tool[0].start,
            wobj: wobj.clone(),
            at: statement[0].start,
        };
        for &slot in target_slots {
            let Some(arg) = positional.get(slot) else {
                return Err(src.error(
                    statement[0].start,
                    format!("{instruction} needs a target as argument {}", slot + 1),
                ));
            };
            match arg {
                [t] if t.kind == Tok::Ident => {
                    pending_uses.push((src.text(t.start, t.end).to_ascii_uppercase(), make_use()));
                }
                [t, ..] if t.is(b'[') => {
                    let (value, end) = value(src, arg, 0)?;
                    if end != arg.len() {
                        return Err(src.error(arg[end].start, "expected ',' after the target"));
                    }
                    let kind = if instruction == "MoveAbsJ" {
                        joint_target(src, &value)?
                    } else {
                        robtarget(src, &value)?
                    };
                    let name = src.text(statement[0].start, statement[0].end);
                    targets.push((
                        ProgramTarget {
                            name,
                            offset: t.start,
                            kind,
                            uses: Vec::new(),
                        },
                        vec![make_use()],
                    ));
                }
                // An expression (Offs(p10, 0, 0, 100), RelTool(...), an array element):
                // not a target the program writes.
                _ => {}
            }
        }
    }
    for (name, u) in pending_uses {
        if let Some(&k) = by_name.get(&name) {
            targets[k].1.push(u);
        }
    }
    let mut out = Vec::with_capacity(targets.len());
    for (mut target, uses) in targets {
        for u in uses {
            let tool = match u.tool.as_str() {
                "TOOL0" => Some(Isometry3::identity()),
                name => match tools.get(name) {
                    Some(Ok(t)) => Some(*t),
                    Some(Err(why)) => return Err(src.error(u.tool_at, why.clone())),
                    None => None,
                },
            };
            let base = match &u.wobj {
                None => Some(Isometry3::identity()),
                Some((name, _)) if name == "WOBJ0" => Some(Isometry3::identity()),
                Some((name, at)) => match wobjs.get(name) {
                    Some(Ok(t)) => Some(*t),
                    Some(Err(why)) => return Err(src.error(*at, why.clone())),
                    None => None,
                },
            };
            target.uses.push(FrameUse {
                tool,
                base,
                offset: u.at,
                undeclared: [
                    tool.is_none()
                        .then(|| format!("tool {}", src.text(u.tool_at, u.tool_at + u.tool.len()))),
                    base.is_none().then(|| {
                        format!(
                            "work object {}",
                            u.wobj
                                .as_ref()
                                .map_or(String::new(), |(n, at)| src.text(*at, at + n.len()))
                        )
                    }),
                ]
                .into_iter()
                .flatten()
                .collect(),
            });
        }
        out.push(target);
    }
    Ok(Program {
        format: Format::Rapid,
        targets: out,
        truncated_at,
    })
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

/// A robtarget value.
fn robtarget(src: &Source, v: &Value) -> Result<TargetKind, Error> {
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
    Ok(TargetKind::Cartesian(Box::new(CartesianTarget {
        position,
        unit: LengthUnit::Millimetre,
        orientation: Some(Orientation::QuaternionWxyz(rotation)),
        config: ConfigHint::RapidConf(cf),
        joints: Vec::new(),
    })))
}

/// A jointtarget value.
fn joint_target(src: &Source, v: &Value) -> Result<TargetKind, Error> {
    let parts = list(
        src,
        v,
        2,
        "a jointtarget [[rax_1,...,rax_6],[eax_a,...,eax_f]]",
    )?;
    let joints = numbers::<6>(src, &parts[0], "robax [rax_1,...,rax_6]")?;
    Ok(TargetKind::Joints(JointTarget {
        joints: joints.to_vec(),
        unit: AngleUnit::Degree,
    }))
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

/// A declaration after its `CONST`/`PERS`/`VAR`: `type name [:= value]`.
fn declaration(
    src: &Source,
    tokens: &[Token],
    tools: &mut HashMap<String, Declared>,
    wobjs: &mut HashMap<String, Declared>,
    targets: &mut Vec<(ProgramTarget, Vec<Use>)>,
    by_name: &mut HashMap<String, usize>,
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
    // An array (name{n}) or a declaration without a value.
    let (Some(c), Some(e)) = (tokens.get(2), tokens.get(3)) else {
        return Ok(());
    };
    if !(c.is(b':') && e.is(b'=')) {
        return Ok(());
    }
    let (v, end) = value(src, tokens, 4)?;
    if let Some(t) = tokens.get(end) {
        return Err(src.error(t.start, "expected ';' after the value"));
    }
    let key = src.text(name.start, name.end).to_ascii_uppercase();
    match ty_name.as_str() {
        "robtarget" | "jointtarget" => {
            let kind = if ty_name == "robtarget" {
                robtarget(src, &v)?
            } else {
                joint_target(src, &v)?
            };
            by_name.insert(key, targets.len());
            targets.push((
                ProgramTarget {
                    name: src.text(name.start, name.end),
                    offset: name.start,
                    kind,
                    uses: Vec::new(),
                },
                Vec::new(),
            ));
        }
        "tooldata" => {
            let parts = list(
                src,
                &v,
                3,
                "a tooldata [robhold,[[x,y,z],[q1,q2,q3,q4]],tload]",
            )?;
            let frame = pose(src, &parts[1], "tframe [[x,y,z],[q1,q2,q3,q4]]")?;
            let declared = match is_true(src, &parts[0]) {
                Some(true) => Ok(frame),
                Some(false) => Err(format!(
                    "tool {key} is a stationary tool (robhold FALSE): not supported"
                )),
                None => return Err(src.error(parts[0].offset(), "robhold: expected TRUE or FALSE")),
            };
            tools.insert(key, declared);
        }
        _ => {
            let parts = list(
                src,
                &v,
                5,
                "a wobjdata [robhold,ufprog,ufmec,uframe,oframe]",
            )?;
            let uframe = pose(src, &parts[3], "uframe [[x,y,z],[q1,q2,q3,q4]]")?;
            let oframe = pose(src, &parts[4], "oframe [[x,y,z],[q1,q2,q3,q4]]")?;
            let declared = match (is_true(src, &parts[0]), is_true(src, &parts[1])) {
                (Some(false), Some(true)) => Ok(uframe * oframe),
                (Some(true), _) => Err(format!(
                    "work object {key} is held by the robot (robhold TRUE): not supported"
                )),
                (Some(false), Some(false)) => Err(format!(
                    "work object {key} has a moving user frame (ufprog FALSE): not supported"
                )),
                _ => {
                    return Err(
                        src.error(parts[0].offset(), "robhold, ufprog: expected TRUE or FALSE")
                    )
                }
            };
            wobjs.insert(key, declared);
        }
    }
    Ok(())
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
        assert_eq!(p.targets.len(), 3);
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
}
