//! Universal Robots URScript.
//!
//! Targets are pose literals `p[x,y,z,rx,ry,rz]` (metres, rotation vector in radians, robot
//! base frame) and joint lists `[q1,…,q6]` (radians) written as the target of `movel`,
//! `movej`, `movep` or `movec` (its first two arguments), or assigned to a variable
//! (`global p1 = p[…]`, `q0 = […]`) that such a move takes. A literal that no move reads
//! (an offset given to `pose_trans`, say) is not a target.
//!
//! The script is read as it runs, not in file order: its blocks (`def`, `thread`, `if`,
//! `elif`, `else`, `while`, each closed by `end`), the calls of its functions and the runs
//! of its threads. A move reads the assignments of its variable that can reach it: the
//! last one before it in its block or an enclosing one, those in branches between, those
//! later in a loop around the move (the next pass), those of other functions (a global);
//! a variable assigned once is that assignment wherever it is written. A move that can
//! read two assignments is reported, and so is every literal it can read.
//!
//! The TCP of a move is the one `set_tcp(p[…])` sets on every way the script reaches it (a
//! variable holding a pose literal counts too): through the calls of a function, its
//! branches and loops; before any, the job's `tool` option. A `set_tcp` of another
//! expression leaves the TCP to the job's `tool` option; two TCPs by different ways, or a
//! function never called, leave it unknown. Statements are one per line; `#` starts a
//! comment. A line whose brackets do not close, or a block without its `end`, is refused.

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

/// Blocks nested deeper than this are refused: the reading of each move walks its blocks.
const MAX_DEPTH: usize = 64;

/// How far back a move looks among its variable's assignments in its function for the
/// one that surely runs before it; beyond, every earlier one is taken to reach it.
const MAX_SCAN: usize = 64;

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
    /// Why it is left as written: a move that reads it may read another value.
    refused: Option<Refusal>,
}

/// The TCP as the script has set it on the ways that reach a place.
#[derive(Clone, Debug, PartialEq)]
enum Tcp {
    /// No way reaches the place (a function never called).
    Unreached,
    /// No `set_tcp` yet: the job's tool.
    Default,
    /// Set to a pose literal by the `set_tcp` at the offset.
    Known(Isometry3<f64>, usize),
    /// Set to an expression by the `set_tcp` at the offset.
    Unknown(usize),
    /// Either of two TCPs, by the way the script runs: where each was set (`None`: the
    /// job's tool, before any `set_tcp`).
    Ambiguous(Option<usize>, Option<usize>),
}

impl Tcp {
    fn join(&self, other: &Tcp) -> Tcp {
        match (self, other) {
            (Tcp::Unreached, t) | (t, Tcp::Unreached) => t.clone(),
            (a @ Tcp::Ambiguous(..), _) | (_, a @ Tcp::Ambiguous(..)) => a.clone(),
            (Tcp::Default, Tcp::Default) => Tcp::Default,
            (Tcp::Known(a, at), Tcp::Known(b, _)) if a == b => Tcp::Known(*a, *at),
            (Tcp::Unknown(a), Tcp::Unknown(b)) if a == b => Tcp::Unknown(*a),
            (a, b) => Tcp::Ambiguous(a.set_at(), b.set_at()),
        }
    }

    fn set_at(&self) -> Option<usize> {
        match self {
            Tcp::Known(_, at) | Tcp::Unknown(at) => Some(*at),
            Tcp::Ambiguous(a, _) => *a,
            Tcp::Unreached | Tcp::Default => None,
        }
    }
}

/// What running a piece of the script does to the TCP: `f(x) = x ⊔ value` when a way
/// through it sets none (`passes`), else `value`; `any`, every TCP it sets on the way.
#[derive(Clone, Debug)]
struct Effect {
    passes: bool,
    value: Tcp,
    any: Tcp,
}

impl Effect {
    fn none() -> Effect {
        Effect {
            passes: true,
            value: Tcp::Unreached,
            any: Tcp::Unreached,
        }
    }

    fn apply(&self, x: &Tcp) -> Tcp {
        if self.passes {
            x.join(&self.value)
        } else {
            self.value.clone()
        }
    }

    fn then(&self, next: &Effect) -> Effect {
        Effect {
            passes: self.passes && next.passes,
            value: if next.passes {
                self.value.join(&next.value)
            } else {
                next.value.clone()
            },
            any: self.any.join(&next.any),
        }
    }

    fn or(&self, other: &Effect) -> Effect {
        Effect {
            passes: self.passes || other.passes,
            value: self.value.join(&other.value),
            any: self.any.join(&other.any),
        }
    }
}

/// A statement as the script runs it.
#[derive(Clone, Debug)]
enum Node {
    /// `set_tcp`: its index among the script's.
    SetTcp(usize),
    /// A motion: its index among the script's.
    Move(usize),
    /// A call of a function of the script.
    Call(usize),
    /// `run` of a thread of the script.
    Run(usize),
    /// `break` or `continue`.
    Break,
    /// `if`, `elif`, `else`: the branches, and whether an `else` ends them.
    If(Vec<Vec<Node>>, bool),
    /// `while`: the body, and whether it breaks or continues.
    While(Vec<Node>, bool),
}

/// A block: a function's body, a branch or a loop, over the bytes `start..end`.
#[derive(Clone, Debug)]
struct Block {
    start: usize,
    end: usize,
    parent: Option<usize>,
    is_loop: bool,
    func: usize,
}

/// A function (`def`), a thread, or the script's top level (function 0).
#[derive(Clone, Debug, Default)]
struct Func {
    name: String,
    params: Vec<String>,
    locals: HashSet<String>,
    body: Vec<Node>,
    /// Whether a call or `run` names it.
    called: bool,
    /// Whether it may `return` before its end.
    returns: bool,
    /// Whether it runs as the program (the top level, or a top-level `def` no one calls
    /// in a script of functions alone).
    entry: bool,
}

/// A variable's assignment: a literal (the candidate's index) or an expression (where).
#[derive(Clone, Copy, Debug)]
enum Assign {
    Literal(usize),
    Expression(usize),
}

/// An assignment of the script.
#[derive(Clone, Debug)]
struct AssignRec {
    name: String,
    /// Where its value is written.
    at: usize,
    func: usize,
    block: usize,
    value: Assign,
    /// `local NAME = …`: no other function sees it.
    local: bool,
}

/// A motion of the script.
struct MoveRec {
    line: usize,
    /// The index of its name in the line.
    tok: usize,
    motion: Motion,
    func: usize,
    block: usize,
    tcp: Tcp,
}

/// A `set_tcp` of the script.
struct SetRec {
    line: usize,
    tok: usize,
    func: usize,
    block: usize,
}

/// The assignments a read of a variable can see.
#[derive(Clone, Debug, Default)]
struct Reached {
    /// The first of them (at most three), indices of assignments.
    recs: Vec<usize>,
    /// How many, a parameter counted.
    count: usize,
    /// A parameter of the function the read is in.
    param: bool,
    /// The read's own function's assignments `lo..hi` and those of the other functions.
    span: Option<(usize, usize, bool)>,
}

/// Assignments `lo..hi` of a variable in a function that a move reads ambiguously, and the
/// ambiguity.
type Span = (usize, usize, usize);

/// A move that may read two values of a variable: the literals it may read are reported.
struct Ambiguity {
    call: String,
    at: usize,
    name: String,
    recs: Vec<usize>,
}

/// Reads the targets of a URScript program.
///
/// # Errors
///
/// [`Error::Syntax`] at the first malformed pose literal or joint list, bracket not closed
/// on its line, or block not closed.
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
    let truncated_at = script.parse(src, limit)?;
    script.tcps(src);
    for m in 0..script.moves.len() {
        script.motion(src, m)?;
    }
    script.refuse_handed(src)?;
    script.refuse_ambiguous(src);
    script.refuse_offsets_from_targets();
    Ok(script.program(truncated_at))
}

/// A script: its lines, blocks, functions, assignments, motions and `set_tcp`s, its
/// literals that may be targets and the motions refused.
struct Script {
    lines: Vec<Vec<Token>>,
    blocks: Vec<Block>,
    funcs: Vec<Func>,
    /// Function and thread names, in order: their indices are 1, 2, ….
    names: HashMap<String, usize>,
    assigns: Vec<AssignRec>,
    /// Per variable and function, its assignments in file order.
    by_var_func: HashMap<(String, usize), Vec<usize>>,
    /// Per variable, its assignments other functions see: how many, and per function.
    nonlocal: HashMap<String, usize>,
    nonlocal_in: HashMap<(String, usize), usize>,
    /// Per variable, the first assignment other functions see, and the first in another
    /// function than that one's.
    nonlocal_first: HashMap<String, (usize, Option<usize>)>,
    moves: Vec<MoveRec>,
    sets: Vec<SetRec>,
    candidates: Vec<Candidate>,
    /// `pose_trans(F, X)` whose frame is a variable: refused if F is itself a target.
    frames_used: Vec<(String, usize)>,
    refused: Vec<ProgramTarget>,
    ambiguities: Vec<Ambiguity>,
    /// The calls of the script's functions (not `run`), and per call its line, the index
    /// of its name there and the function called.
    call_sites: Vec<Ctx>,
    call_tokens: Vec<(usize, usize, usize)>,
    /// Per function and parameter, the first motion that moves to the parameter.
    param_moves: HashMap<(usize, usize), (String, usize)>,
    /// Per variable and function, the spans of its assignments moves read ambiguously.
    spans: HashMap<(String, usize), Vec<Span>>,
    /// Per variable, the other functions' assignments a move read ambiguously: from which
    /// function (`None`: from two), and the ambiguity.
    others: HashMap<String, (Option<usize>, usize)>,
    first_motion: Option<usize>,
}

/// A block being read.
struct Open {
    kind: Opened,
    block: usize,
    nodes: Vec<Node>,
    branches: Vec<Vec<Node>>,
    has_else: bool,
    breaks: bool,
    at: usize,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Opened {
    Top,
    Func(usize),
    If,
    While,
}

impl Open {
    /// A block just opened, its header's first word at `at`, nothing read in it yet.
    fn new(kind: Opened, block: usize, at: usize) -> Open {
        Open {
            kind,
            block,
            nodes: Vec::new(),
            branches: Vec::new(),
            has_else: false,
            breaks: false,
            at,
        }
    }
}

impl Script {
    /// A script about to be read, its functions and threads named.
    fn new(src: &Source) -> Script {
        let mut names: HashMap<String, usize> = HashMap::new();
        let mut funcs = vec![Func {
            name: "the script".into(),
            ..Func::default()
        }];
        let mut lexer = Lexer::new(src, URSCRIPT);
        while let Some(line) = lexer.line() {
            if let Some(name) = func_header(src, &line) {
                let n = src.text(name.start, name.end);
                names.entry(n.clone()).or_insert(funcs.len());
                funcs.push(Func {
                    name: n,
                    ..Func::default()
                });
            }
        }
        Script {
            lines: Vec::new(),
            blocks: Vec::new(),
            funcs,
            names,
            assigns: Vec::new(),
            by_var_func: HashMap::new(),
            nonlocal: HashMap::new(),
            nonlocal_in: HashMap::new(),
            nonlocal_first: HashMap::new(),
            moves: Vec::new(),
            sets: Vec::new(),
            candidates: Vec::new(),
            frames_used: Vec::new(),
            refused: Vec::new(),
            ambiguities: Vec::new(),
            call_sites: Vec::new(),
            call_tokens: Vec::new(),
            param_moves: HashMap::new(),
            spans: HashMap::new(),
            others: HashMap::new(),
            first_motion: None,
        }
    }

    /// Reads the lines: the blocks, the assignments, the calls; stops after `limit`
    /// literals (where, returned).
    fn parse(&mut self, src: &Source, limit: usize) -> Result<Option<usize>, Error> {
        self.blocks.push(Block {
            start: 0,
            end: src.bytes.len() + 1,
            parent: None,
            is_loop: false,
            func: 0,
        });
        let mut stack = vec![Open::new(Opened::Top, 0, 0)];
        let mut lexer = Lexer::new(src, URSCRIPT);
        let mut next_func = 1;
        let mut literals = 0usize;
        let mut truncated_at = None;
        loop {
            let line_start = lexer.pos;
            let Some(line) = lexer.line() else { break };
            if literals > limit {
                truncated_at = Some(line_start);
                break;
            }
            if line.is_empty() {
                continue;
            }
            balanced(src, &line)?;
            let top = stack.len() - 1;
            let first = &line[0];
            let header = line.last().is_some_and(|t| t.is(b':'));
            if func_header(src, &line).is_some() && next_func < self.funcs.len() {
                self.funcs[next_func].params = params(src, &line);
                self.open(&mut stack, Opened::Func(next_func), line_start, first.start);
                next_func += 1;
            } else if header
                && (word(src, first, "if") || word(src, first, "while") || word(src, first, "for"))
            {
                let kind = if word(src, first, "if") {
                    Opened::If
                } else {
                    Opened::While
                };
                self.open(&mut stack, kind, line_start, first.start);
            } else if header && (word(src, first, "elif") || word(src, first, "else")) {
                self.next_branch(src, &mut stack, first, line_start)?;
            } else if line.len() == 1 && word(src, first, "end") {
                if top == 0 {
                    return Err(src.error(first.start, "'end' without a block to close"));
                }
                self.close(&mut stack, lexer.pos, true);
            } else {
                refuse_too_deep(src, stack.len(), first.start)?;
                literals += self.statement(src, line, &mut stack[top])?;
                literals = self.candidates.len().max(literals);
                continue;
            }
            refuse_too_deep(src, stack.len(), first.start)?;
            self.lines.push(Vec::new());
        }
        self.close_all(src, stack, truncated_at.is_some())?;
        self.mark_entries();
        self.index_assigns();
        Ok(truncated_at)
    }

    /// Opens a function's body, a branch or a loop at the line starting at `start`, its
    /// header's first word at `at` (where an unclosed block is reported).
    fn open(&mut self, stack: &mut Vec<Open>, kind: Opened, start: usize, at: usize) {
        let parent = stack[stack.len() - 1].block;
        // A function's body is its own; a branch or a loop belongs to the block around.
        let func = match kind {
            Opened::Func(f) => f,
            _ => self.blocks[parent].func,
        };
        self.blocks.push(Block {
            start,
            end: usize::MAX,
            parent: Some(parent),
            is_loop: kind == Opened::While,
            func,
        });
        stack.push(Open::new(kind, self.blocks.len() - 1, at));
    }

    /// `elif` or `else`: ends the open branch of the `if` at `start` and opens the next as
    /// its sibling, so that a move in one branch does not see the assignments of another.
    fn next_branch(
        &mut self,
        src: &Source,
        stack: &mut [Open],
        first: &Token,
        start: usize,
    ) -> Result<(), Error> {
        let o = &mut stack[stack.len() - 1];
        if o.kind != Opened::If {
            return Err(src.error(first.start, "'elif' or 'else' outside an 'if'"));
        }
        self.blocks[o.block].end = start;
        let Block { parent, func, .. } = self.blocks[o.block];
        self.blocks.push(Block {
            start,
            end: usize::MAX,
            parent,
            is_loop: false,
            func,
        });
        o.block = self.blocks.len() - 1;
        let branch = std::mem::take(&mut o.nodes);
        o.branches.push(branch);
        o.has_else |= word(src, first, "else");
        Ok(())
    }

    /// Closes the innermost open block at `end` and hands what it runs to the block around.
    /// Only a block closed by its `end` (`by_end`) passes a `break` in a branch on to the
    /// loop around; a script read in part closes its open blocks without.
    fn close(&mut self, stack: &mut Vec<Open>, end: usize, by_end: bool) {
        let mut o = stack.pop().unwrap_or_else(|| unreachable!());
        self.blocks[o.block].end = end;
        let parent = stack.last_mut().unwrap_or_else(|| unreachable!());
        match o.kind {
            Opened::If => {
                o.branches.push(o.nodes);
                parent.nodes.push(Node::If(o.branches, o.has_else));
                // A `break` in a branch breaks the loop around.
                if by_end {
                    parent.breaks |= o.breaks;
                }
            }
            Opened::While => parent.nodes.push(Node::While(o.nodes, o.breaks)),
            Opened::Func(f) => self.funcs[f].body = o.nodes,
            Opened::Top => {}
        }
    }

    /// After the last line read: refuses a block left open in a script read whole (one read
    /// in part, `truncated`, ends its open blocks where the reading stopped), and gives the
    /// top level its body.
    fn close_all(
        &mut self,
        src: &Source,
        mut stack: Vec<Open>,
        truncated: bool,
    ) -> Result<(), Error> {
        if !truncated && stack.len() > 1 {
            let o = &stack[stack.len() - 1];
            return Err(src.error(o.at, "this block is not closed: expected 'end'"));
        }
        while stack.len() > 1 {
            self.close(&mut stack, src.bytes.len() + 1, false);
        }
        let top = stack.pop().map(|o| o.nodes).unwrap_or_default();
        self.funcs[0].body = top;
        Ok(())
    }

    /// A line that opens or closes no block, in the open block `open`: its assignment, its
    /// calls, a `return` or `break`. Returns how many literals its motions may write.
    fn statement(
        &mut self,
        src: &Source,
        line: Vec<Token>,
        open: &mut Open,
    ) -> Result<usize, Error> {
        let (func, block) = (self.blocks[open.block].func, open.block);
        let first = &line[0];
        let index = self.lines.len();
        self.assignment(src, &line, func, block)?;
        let mut nodes = Vec::new();
        let literals = self.calls(src, &line, index, func, block, &mut nodes);
        if word(src, first, "return") {
            self.funcs[func].returns = true;
        }
        if line.len() == 1 && (word(src, first, "break") || word(src, first, "continue")) {
            open.breaks = true;
            nodes.push(Node::Break);
        }
        open.nodes.extend(nodes);
        self.lines.push(line);
        Ok(literals)
    }

    /// Marks the functions that run as the program: the top level when it does anything,
    /// else each top-level function no one calls (a script of functions alone).
    fn mark_entries(&mut self) {
        let mut entries = vec![0];
        if self.funcs[0].body.is_empty() {
            entries = (1..self.funcs.len())
                .filter(|&f| {
                    !self.funcs[f].called
                        && self
                            .blocks
                            .iter()
                            .any(|b| b.func == f && b.parent == Some(0))
                })
                .collect();
        }
        for f in entries {
            self.funcs[f].entry = true;
        }
    }

    /// Indexes the assignments by variable and function, and those other functions see,
    /// so that each move's reading of its variable need not scan them all.
    fn index_assigns(&mut self) {
        for (i, a) in self.assigns.iter().enumerate() {
            self.by_var_func
                .entry((a.name.clone(), a.func))
                .or_default()
                .push(i);
            if !a.local {
                *self.nonlocal.entry(a.name.clone()).or_default() += 1;
                *self
                    .nonlocal_in
                    .entry((a.name.clone(), a.func))
                    .or_default() += 1;
                let assigns = &self.assigns;
                self.nonlocal_first
                    .entry(a.name.clone())
                    .and_modify(|(first, second)| {
                        if second.is_none() && assigns[*first].func != a.func {
                            *second = Some(i);
                        }
                    })
                    .or_insert((i, None));
            }
        }
    }

    /// A line's assignment, if it is one: `[global|local] NAME = value`.
    fn assignment(
        &mut self,
        src: &Source,
        line: &[Token],
        func: usize,
        block: usize,
    ) -> Result<(), Error> {
        let mut i = 0;
        let local = line.first().is_some_and(|t| word(src, t, "local"));
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
        let value = match literal(src, line, i + 2)? {
            Some((literal, end)) if end == line.len() => {
                self.candidates.push(Candidate {
                    name: key.clone(),
                    offset: line[i + 2].start,
                    literal,
                    uses: Vec::new(),
                    refused: None,
                });
                Assign::Literal(self.candidates.len() - 1)
            }
            _ => Assign::Expression(line.get(i + 2).map_or(eq.end, |t| t.start)),
        };
        if local {
            self.funcs[func].locals.insert(key.clone());
        }
        self.assigns.push(AssignRec {
            name: key,
            at: line.get(i + 2).map_or(eq.end, |t| t.start),
            func,
            block,
            value,
            local,
        });
        Ok(())
    }

    /// The calls anywhere on a line, in order: `set_tcp`, the motions, calls that look
    /// like motions, calls of the script's functions, runs of its threads. Returns how
    /// many literals the line's motions may write.
    fn calls(
        &mut self,
        src: &Source,
        line: &[Token],
        index: usize,
        func: usize,
        block: usize,
        nodes: &mut Vec<Node>,
    ) -> usize {
        let mut literals = 0;
        let mut k = 0;
        while k + 1 < line.len() {
            let (t, open) = (&line[k], &line[k + 1]);
            if t.kind != Tok::Ident || !open.is(b'(') {
                k += 1;
                continue;
            }
            let call = src.text(t.start, t.end);
            if call == "set_tcp" {
                self.sets.push(SetRec {
                    line: index,
                    tok: k,
                    func,
                    block,
                });
                nodes.push(Node::SetTcp(self.sets.len() - 1));
            } else if let Some(m) = MOTIONS.iter().find(|m| m.name == call) {
                self.first_motion.get_or_insert(t.start);
                literals += line[k..].iter().filter(|t| t.is(b'[')).count();
                self.moves.push(MoveRec {
                    line: index,
                    tok: k,
                    motion: *m,
                    func,
                    block,
                    tcp: Tcp::Unreached,
                });
                nodes.push(Node::Move(self.moves.len() - 1));
            } else if let Some(&f) = self.names.get(&call) {
                self.funcs[f].called = true;
                let run = k > 0 && word(src, &line[k - 1], "run");
                nodes.push(if run { Node::Run(f) } else { Node::Call(f) });
                if !run {
                    self.call_sites.push(Ctx {
                        call: call.clone(),
                        at: t.start,
                        func,
                        block,
                    });
                    self.call_tokens.push((index, k, f));
                }
            } else if call.starts_with("move") || call.starts_with("servo") {
                self.first_motion.get_or_insert(t.start);
                self.refused.push(refused_call(
                    t,
                    &call,
                    Reason::UnknownMotion,
                    format!("{call} is not a URScript motion this reader knows"),
                ));
            }
            k += 1;
        }
        literals
    }

    /// The TCP of every motion: the script run from its entries, each function entered
    /// with the TCPs of its calls.
    fn tcps(&mut self, src: &Source) {
        let sets: Vec<Tcp> = (0..self.sets.len())
            .map(|i| self.set_value(src, i))
            .collect();
        let bodies: Vec<Vec<Node>> = self
            .funcs
            .iter_mut()
            .map(|f| std::mem::take(&mut f.body))
            .collect();
        let mut run = Run {
            sets: &sets,
            bodies: &bodies,
            returns: self.funcs.iter().map(|f| f.returns).collect(),
            effects: vec![None; bodies.len()],
            in_progress: vec![false; bodies.len()],
            entries: vec![Tcp::Unreached; bodies.len()],
            work: Vec::new(),
            moves: vec![Tcp::Unreached; self.moves.len()],
            concurrent: Tcp::Unreached,
            depth: 0,
        };
        for (f, func) in self.funcs.iter().enumerate() {
            if func.entry {
                run.enter(f, &Tcp::Default);
            }
        }
        while let Some(f) = run.work.pop() {
            let entry = run.entries[f].clone();
            run.walk(&bodies[f], entry);
        }
        for (m, tcp) in self.moves.iter_mut().zip(run.moves) {
            m.tcp = tcp;
        }
    }

    /// The TCP a `set_tcp` sets.
    fn set_value(&mut self, src: &Source, i: usize) -> Tcp {
        let s = &self.sets[i];
        let (line, k, func, block) = (s.line, s.tok, s.func, s.block);
        let tokens = &self.lines[line];
        let at = tokens[k].start;
        let j = k + 2;
        if let (Some(t), Some(close)) = (tokens.get(j), tokens.get(j + 1)) {
            if t.kind == Tok::Ident && close.is(b')') {
                let name = src.text(t.start, t.end);
                let r = self.reach(&name, at, func, block);
                if r.count >= 2 {
                    let a = r.recs.first().map(|&a| self.assigns[a].at);
                    let b = r.recs.get(1).map(|&a| self.assigns[a].at);
                    return Tcp::Ambiguous(a.or(Some(at)), b);
                }
                return match r.recs.first().map(|&a| self.assigns[a].value) {
                    Some(Assign::Literal(c)) if !r.param => match &self.candidates[c].literal {
                        Literal::Pose(p) => Tcp::Known(pose_mm(p), at),
                        Literal::Joints(_) => Tcp::Unknown(at),
                    },
                    _ => Tcp::Unknown(at),
                };
            }
        }
        match literal(src, tokens, j) {
            Ok(Some((Literal::Pose(p), _))) => Tcp::Known(pose_mm(&p), at),
            _ => Tcp::Unknown(at),
        }
    }

    /// The assignments of `name` a read at `at` (in `func`, `block`) can see.
    fn reach(&self, name: &str, at: usize, func: usize, block: usize) -> Reached {
        let f = &self.funcs[func];
        let param = f.params.iter().any(|p| p == name);
        let local = param || f.locals.contains(name);
        let key = (name.to_string(), func);
        let own: &[usize] = self.by_var_func.get(&key).map_or(&[], |v| v);
        let others = if local {
            0
        } else {
            self.nonlocal.get(name).copied().unwrap_or(0)
                - self.nonlocal_in.get(&key).copied().unwrap_or(0)
        };
        let other = || {
            self.nonlocal_first.get(name).and_then(|&(first, second)| {
                if self.assigns[first].func != func {
                    Some(first)
                } else {
                    second
                }
            })
        };
        let total = own.len() + others + usize::from(param);
        if total <= 1 {
            return Reached {
                recs: own.iter().copied().chain(other()).take(1).collect(),
                count: total,
                param: param && own.is_empty(),
                span: None,
            };
        }
        let pos = own.partition_point(|&i| self.assigns[i].at < at);
        // The last assignment before the read that surely runs before it: in the read's
        // block or one around it.
        let mut before = None;
        for k in (pos.saturating_sub(MAX_SCAN)..pos).rev() {
            let b = &self.blocks[self.assigns[own[k]].block];
            if b.start <= at && at < b.end {
                before = Some(k);
                break;
            }
        }
        let before_at = before.map(|k| self.assigns[own[k]].at);
        // The outermost loop around the read that the assignment is not in: its later
        // assignments reach the read on the next pass.
        let mut loop_end = None;
        let mut b = Some(block);
        while let Some(i) = b {
            let blk = &self.blocks[i];
            if blk.func != func {
                break;
            }
            if blk.is_loop && before_at.is_none_or(|a| !(blk.start <= a && a < blk.end)) {
                loop_end = Some(blk.end);
            }
            b = blk.parent;
        }
        let lo = before.unwrap_or(0);
        let hi = if before.is_none() && !self.funcs[func].entry {
            // A function called again sees its own last assignments.
            own.len()
        } else {
            loop_end.map_or(pos, |end| {
                own.partition_point(|&i| self.assigns[i].at < end)
            })
        };
        let hi = hi.max(lo);
        let param = param && before.is_none();
        let count = hi - lo + others + usize::from(param);
        let mut recs: Vec<usize> = own[lo..hi].iter().copied().take(3).collect();
        if others > 0 && recs.len() < 3 {
            recs.extend(other());
        }
        Reached {
            recs,
            count,
            param,
            span: (count >= 2).then_some((lo, hi, others > 0)),
        }
    }

    /// The targets of the motion `m`.
    fn motion(&mut self, src: &Source, m: usize) -> Result<(), Error> {
        let rec = &self.moves[m];
        let (line, mut j, motion, func, block) =
            (rec.line, rec.tok + 2, rec.motion, rec.func, rec.block);
        let line = self.lines[line].clone();
        let at = line[j - 2].start;
        let frame = self.frame_use(src, m);
        let ctx = Ctx {
            call: motion.name.to_string(),
            at,
            func,
            block,
        };
        for _ in 0..motion.targets {
            let end = argument_end(&line, j);
            if end == j {
                break;
            }
            self.target(src, &ctx, &line[j..end], frame.clone())?;
            j = end;
            if line.get(j).is_some_and(|t| t.is(b',')) {
                j += 1;
            } else {
                break;
            }
        }
        Ok(())
    }

    /// The frames of the motion `m`: its TCP, in the robot's base frame.
    fn frame_use(&self, src: &Source, m: usize) -> FrameUse {
        let rec = &self.moves[m];
        let at = self.lines[rec.line][rec.tok].start;
        let place = |set: Option<usize>| match set {
            Some(s) => {
                let (l, c) = src.location(s);
                format!("the set_tcp at {l}:{c}")
            }
            None => "the tool option (no set_tcp before)".to_string(),
        };
        let mut undeclared = Vec::new();
        let mut unknown = Vec::new();
        let tool = match &rec.tcp {
            Tcp::Known(t, _) => Some(*t),
            Tcp::Default => None,
            Tcp::Unknown(set_at) => {
                let (line, column) = src.location(*set_at);
                undeclared.push(Undeclared {
                    base: false,
                    name: format!("set by set_tcp at {line}:{column}"),
                });
                None
            }
            Tcp::Ambiguous(None, None) => {
                unknown.push(format!(
                    "the TCP is not known: it is set in calls nested more than {MAX_DEPTH} deep"
                ));
                None
            }
            Tcp::Ambiguous(a, b) => {
                unknown.push(format!(
                    "the TCP is {} or {}, by the way the script runs to this motion",
                    place(*a),
                    place(*b)
                ));
                None
            }
            Tcp::Unreached => {
                unknown.push(format!(
                    "the TCP is not known: {} is never called or run",
                    self.funcs[rec.func].name
                ));
                None
            }
        };
        FrameUse {
            tool,
            // URScript poses are in the robot's base frame.
            base: Some(Isometry3::identity()),
            offset: at,
            elsewhere: None,
            note: None,
            undeclared,
            unknown,
        }
    }

    /// Records that the motion `ctx` may read any of the assignments `r` of `name`: the
    /// literals among them are reported.
    fn ambiguous(&mut self, ctx: &Ctx, name: &str, r: &Reached) {
        let Some((lo, hi, others)) = r.span else {
            return;
        };
        let a = self.ambiguities.len();
        self.ambiguities.push(Ambiguity {
            call: ctx.call.clone(),
            at: ctx.at,
            name: name.to_string(),
            recs: r.recs.clone(),
        });
        if hi > lo {
            self.spans
                .entry((name.to_string(), ctx.func))
                .or_default()
                .push((lo, hi, a));
        }
        if others {
            self.others
                .entry(name.to_string())
                .and_modify(|(from, _)| {
                    if *from != Some(ctx.func) {
                        *from = None;
                    }
                })
                .or_insert((Some(ctx.func), a));
        }
    }

    /// `a:b or c:d`: where the assignments of `r` are.
    fn places(&self, src: &Source, r: &Reached) -> String {
        let mut places: Vec<String> = r
            .recs
            .iter()
            .take(2)
            .map(|&a| {
                let (l, c) = src.location(self.assigns[a].at);
                format!("{l}:{c}")
            })
            .collect();
        if r.param && places.len() < 2 {
            places.push("the parameter".into());
        }
        let more = r.count.saturating_sub(places.len());
        let mut s = places.join(" or ");
        if more > 0 {
            s.push_str(&format!(" (and {more} more)"));
        }
        s
    }

    /// Reports each literal handed to a function that moves to the parameter it becomes:
    /// the motion is reported as a parameter's, and so is the literal, not corrected.
    fn refuse_handed(&mut self, src: &Source) -> Result<(), Error> {
        if self.param_moves.is_empty() {
            return Ok(());
        }
        for n in 0..self.call_sites.len() {
            let (line, k, f) = self.call_tokens[n];
            let line = self.lines[line].clone();
            let site = &self.call_sites[n];
            let (l, c) = src.location(site.at);
            let mut j = k + 2;
            let mut i = 0;
            loop {
                let end = argument_end(&line, j);
                if end == j {
                    break;
                }
                if let Some((call, at)) = self.param_moves.get(&(f, i)).cloned() {
                    let (ml, mc) = src.location(at);
                    let why = format!(
                        "handed to {} as {} ({l}:{c}), which {call} at {ml}:{mc} moves to: a parameter's value, not corrected",
                        self.funcs[f].name, self.funcs[f].params[i]
                    );
                    let arg = &line[j..end];
                    match literal(src, arg, 0)? {
                        Some((literal, e)) if e == arg.len() => {
                            self.candidates.push(Candidate {
                                name: self.funcs[f].name.clone(),
                                offset: arg[0].start,
                                literal,
                                uses: Vec::new(),
                                refused: Some(Refusal::new(Reason::Dynamic, why)),
                            });
                        }
                        _ => {
                            if let [v] = arg {
                                if v.kind == Tok::Ident {
                                    let name = src.text(v.start, v.end);
                                    let site = Ctx {
                                        call: format!("{call} (through {})", self.funcs[f].name),
                                        ..self.call_sites[n].clone()
                                    };
                                    let r = self.reach(&name, site.at, site.func, site.block);
                                    if r.count >= 2 {
                                        self.ambiguous(&site, &name, &r);
                                    } else if let Some(Assign::Literal(c)) =
                                        r.recs.first().map(|&a| self.assigns[a].value)
                                    {
                                        if !r.param && self.candidates[c].refused.is_none() {
                                            self.candidates[c].refused =
                                                Some(Refusal::new(Reason::Dynamic, why));
                                        }
                                    }
                                }
                            }
                        }
                    }
                }
                j = end;
                i += 1;
                if line.get(j).is_some_and(|t| t.is(b',')) {
                    j += 1;
                } else {
                    break;
                }
            }
        }
        Ok(())
    }

    /// Reports each literal a motion may read besides another value.
    fn refuse_ambiguous(&mut self, src: &Source) {
        let mut marked: Vec<Option<usize>> = vec![None; self.assigns.len()];
        for (key, mut spans) in std::mem::take(&mut self.spans) {
            let own = &self.by_var_func[&key];
            spans.sort_unstable();
            let mut next = 0;
            let mut best: Option<(usize, usize)> = None;
            for (i, &a) in own.iter().enumerate() {
                while next < spans.len() && spans[next].0 <= i {
                    let (_, hi, amb) = spans[next];
                    if best.is_none_or(|(h, _)| hi > h) {
                        best = Some((hi, amb));
                    }
                    next += 1;
                }
                if let Some((hi, amb)) = best {
                    if i < hi {
                        marked[a] = Some(amb);
                    }
                }
            }
        }
        for (i, a) in self.assigns.iter().enumerate() {
            if a.local || marked[i].is_some() {
                continue;
            }
            if let Some(&(from, amb)) = self.others.get(&a.name) {
                if from != Some(a.func) {
                    marked[i] = Some(amb);
                }
            }
        }
        for (i, amb) in marked.into_iter().enumerate() {
            let (Some(amb), Assign::Literal(c)) = (amb, self.assigns[i].value) else {
                continue;
            };
            let amb = &self.ambiguities[amb];
            let (l, col) = src.location(amb.at);
            let other = amb
                .recs
                .iter()
                .find(|&&r| r != i)
                .map(|&r| {
                    let (l, c) = src.location(self.assigns[r].at);
                    format!("{l}:{c}")
                })
                .unwrap_or_else(|| "another value".into());
            self.candidates[c].refused = Some(Refusal::new(
                Reason::Dynamic,
                format!(
                    "{} at {l}:{col} moves to {} as this or as the value of {other}, by the way the script runs",
                    amb.call, amb.name
                ),
            ));
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
            .filter(|c| !c.uses.is_empty() || c.refused.is_some())
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
                uses: if c.refused.is_some() {
                    Vec::new()
                } else {
                    c.uses
                },
                refused: c.refused,
            })
            .collect();
        targets.extend(self.refused);
        targets.sort_by_key(|t| t.offset);
        Program {
            format: Format::UrScript,
            targets,
            truncated_at,
            first_motion: self.first_motion,
            in_partner: Vec::new(),
        }
    }
}

/// The TCP analysis: the script run from its entries.
struct Run<'r> {
    sets: &'r [Tcp],
    bodies: &'r [Vec<Node>],
    /// Per function, whether it may return before its end.
    returns: Vec<bool>,
    effects: Vec<Option<Effect>>,
    in_progress: Vec<bool>,
    /// Per function, the TCPs its calls enter it with.
    entries: Vec<Tcp>,
    /// Functions to run again: their entry changed.
    work: Vec<usize>,
    moves: Vec<Tcp>,
    /// The TCPs threads running beside may set.
    concurrent: Tcp,
    /// How deep the calls being followed are.
    depth: usize,
}

impl Run<'_> {
    fn enter(&mut self, f: usize, tcp: &Tcp) {
        let joined = self.entries[f].join(tcp);
        if joined != self.entries[f] {
            self.entries[f] = joined;
            self.work.push(f);
        }
    }

    /// What a function does to the TCP.
    fn func_effect(&mut self, f: usize) -> Effect {
        if let Some(e) = &self.effects[f] {
            return e.clone();
        }
        if self.in_progress[f] {
            // A recursive call: what it sets is in the function's own effect.
            return Effect::none();
        }
        if self.depth >= MAX_DEPTH {
            // Calls nested deeper than blocks may be: whatever TCP they set is not known.
            return Effect {
                passes: true,
                value: Tcp::Ambiguous(None, None),
                any: Tcp::Ambiguous(None, None),
            };
        }
        self.in_progress[f] = true;
        self.depth += 1;
        let mut e = self.effect(&self.bodies[f]);
        if self.returns[f] {
            // A `return` leaves with any TCP set before it, or none.
            e = Effect {
                passes: true,
                value: e.any.join(&e.value),
                any: e.any,
            };
        }
        self.depth -= 1;
        self.in_progress[f] = false;
        self.effects[f] = Some(e.clone());
        e
    }

    /// What running `nodes` does to the TCP.
    fn effect(&mut self, nodes: &[Node]) -> Effect {
        let mut e = Effect::none();
        for n in nodes {
            let step = match n {
                Node::SetTcp(i) => Effect {
                    passes: false,
                    value: self.sets[*i].clone(),
                    any: self.sets[*i].clone(),
                },
                Node::Call(f) => self.func_effect(*f),
                Node::Run(f) => {
                    let any = self.func_effect(*f).any;
                    Effect {
                        passes: true,
                        value: any.clone(),
                        any,
                    }
                }
                Node::Move(_) | Node::Break => continue,
                Node::If(branches, has_else) => {
                    let mut out: Option<Effect> = (!has_else).then(Effect::none);
                    for b in branches {
                        let be = self.effect(b);
                        out = Some(match out {
                            Some(o) => o.or(&be),
                            None => be,
                        });
                    }
                    out.unwrap_or_else(Effect::none)
                }
                Node::While(body, breaks) => {
                    let be = self.effect(body);
                    Effect {
                        passes: true,
                        value: if *breaks { be.any.clone() } else { be.value },
                        any: be.any,
                    }
                }
            };
            e = e.then(&step);
        }
        e
    }

    /// Runs `nodes` from the TCP `state`: the TCP of each motion, the TCPs functions are
    /// entered with. Returns the TCP after.
    fn walk(&mut self, nodes: &[Node], mut state: Tcp) -> Tcp {
        for n in nodes {
            match n {
                Node::SetTcp(i) => state = self.sets[*i].clone(),
                Node::Move(m) => self.moves[*m] = state.join(&self.concurrent),
                Node::Call(f) => {
                    self.enter(*f, &state);
                    state = self.func_effect(*f).apply(&state);
                }
                Node::Run(f) => {
                    self.enter(*f, &state);
                    let any = self.func_effect(*f).any;
                    self.concurrent = self.concurrent.join(&any);
                    state = state.join(&any);
                }
                Node::Break => {}
                Node::If(branches, has_else) => {
                    let mut out = if *has_else {
                        Tcp::Unreached
                    } else {
                        state.clone()
                    };
                    for b in branches {
                        let after = self.walk(b, state.clone());
                        out = out.join(&after);
                    }
                    state = out;
                }
                Node::While(body, breaks) => {
                    let e = self.effect(body);
                    let head = state.join(if *breaks { &e.any } else { &e.value });
                    self.walk(body, head.clone());
                    state = head;
                }
            }
        }
        state
    }
}

/// A motion being read: its call, where, and its function and block.
#[derive(Clone, Debug)]
struct Ctx {
    call: String,
    at: usize,
    func: usize,
    block: usize,
}

/// Refuses a statement inside more than [`MAX_DEPTH`] blocks (`depth` open, the top level
/// counted), at `at`.
fn refuse_too_deep(src: &Source, depth: usize, at: usize) -> Result<(), Error> {
    if depth > MAX_DEPTH {
        return Err(src.error(at, format!("blocks nested deeper than {MAX_DEPTH}")));
    }
    Ok(())
}

/// Refuses a line whose brackets do not close on it.
fn balanced(src: &Source, line: &[Token]) -> Result<(), Error> {
    let mut open: Vec<&Token> = Vec::new();
    for t in line {
        match t.kind {
            Tok::Punct(b'(' | b'[') => open.push(t),
            Tok::Punct(c @ (b')' | b']')) => {
                let want = if c == b')' { b'(' } else { b'[' };
                match open.pop() {
                    Some(o) if o.is(want) => {}
                    Some(o) => {
                        let (l, col) = src.location(t.start);
                        let (opened, close) = if o.is(b'(') { ('(', ')') } else { ('[', ']') };
                        return Err(src.error(
                            o.start,
                            format!(
                                "'{opened}' not closed: expected '{close}' before the '{}' at {l}:{col}",
                                c as char
                            ),
                        ));
                    }
                    None => {
                        return Err(
                            src.error(t.start, format!("'{}' without its opening", c as char))
                        )
                    }
                }
            }
            _ => {}
        }
    }
    if let Some(o) = open.last() {
        let close = if o.is(b'(') { ')' } else { ']' };
        return Err(src.error(
            o.start,
            format!("not closed on its line: expected '{close}'"),
        ));
    }
    Ok(())
}

/// The name of a `def NAME(…):` or `thread NAME():` line.
fn func_header<'t>(src: &Source, line: &'t [Token]) -> Option<&'t Token> {
    match line {
        [d, name, .., colon]
            if (word(src, d, "def") || word(src, d, "thread"))
                && name.kind == Tok::Ident
                && colon.is(b':') =>
        {
            Some(name)
        }
        _ => None,
    }
}

/// The parameters of a `def NAME(a, b=1):` line.
fn params(src: &Source, line: &[Token]) -> Vec<String> {
    let mut names = Vec::new();
    let mut depth = 0;
    for (k, t) in line.iter().enumerate() {
        match t.kind {
            Tok::Punct(b'(' | b'[') => depth += 1,
            Tok::Punct(b')' | b']') => depth -= 1,
            Tok::Ident if depth == 1 => {
                let prev = &line[k - 1];
                if prev.is(b'(') || prev.is(b',') {
                    names.push(src.text(t.start, t.end));
                }
            }
            _ => {}
        }
    }
    names
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

impl Script {
    /// Reads one target argument `arg` of the motion `ctx`, used in `frame`.
    fn target(
        &mut self,
        src: &Source,
        ctx: &Ctx,
        arg: &[Token],
        frame: FrameUse,
    ) -> Result<(), Error> {
        let text = src.text(arg[0].start, arg[arg.len() - 1].end);
        // A literal.
        if let Some((literal, end)) = literal(src, arg, 0)? {
            if end == arg.len() {
                self.candidates.push(Candidate {
                    name: ctx.call.clone(),
                    offset: arg[0].start,
                    literal,
                    uses: vec![frame],
                    refused: None,
                });
                return Ok(());
            }
        }
        match arg {
            // A variable.
            [t] if t.kind == Tok::Ident => {
                let name = src.text(t.start, t.end);
                let r = self.reach(&name, ctx.at, ctx.func, ctx.block);
                if r.count >= 2 {
                    let places = self.places(src, &r);
                    self.ambiguous(ctx, &name, &r);
                    self.refuse_target(
                        src,
                        ctx,
                        arg,
                        Reason::Dynamic,
                        &format!("{name} holds the value of {places}, by the way the script runs"),
                    );
                } else if r.param {
                    if let Some(i) = self.funcs[ctx.func].params.iter().position(|p| *p == name) {
                        self.param_moves
                            .entry((ctx.func, i))
                            .or_insert_with(|| (ctx.call.clone(), ctx.at));
                    }
                    self.refuse_target(
                        src,
                        ctx,
                        arg,
                        Reason::Dynamic,
                        &format!(
                            "{name} is a parameter of {}, given when it is called",
                            self.funcs[ctx.func].name
                        ),
                    );
                } else {
                    match r.recs.first().map(|&a| self.assigns[a].value) {
                        Some(Assign::Literal(c)) => self.candidates[c].uses.push(frame),
                        Some(Assign::Expression(at)) => {
                            let (l, c) = src.location(at);
                            self.refuse_target(
                                src,
                                ctx,
                                arg,
                                Reason::Dynamic,
                                &format!("{name} is computed when the script runs ({l}:{c})"),
                            );
                        }
                        None => self.refuse_target(
                            src,
                            ctx,
                            arg,
                            Reason::Dynamic,
                            &format!(
                                "{name} is not assigned before this motion in the script (given when it runs)"
                            ),
                        ),
                    }
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
                        src,
                        ctx,
                        arg,
                        Reason::Dynamic,
                        "a pose computed when the script runs",
                    );
                    return Ok(());
                }
                self.target(src, ctx, &inner[..end], frame)?;
            }
            // A waypoint relative to a feature: `pose_trans(Plane_1, p[…])`.
            [f, open, inner @ .., close]
                if word(src, f, "pose_trans") && open.is(b'(') && close.is(b')') =>
            {
                self.feature_target(src, ctx, arg, inner, frame)?;
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
                        src,
                        ctx,
                        arg,
                        Reason::Relative,
                        "an offset from where the robot stands when the script runs",
                    );
                } else {
                    self.refuse_target(
                        src,
                        ctx,
                        arg,
                        Reason::Dynamic,
                        "a target computed when the script runs",
                    );
                }
            }
        }
        Ok(())
    }

    /// The single literal `name` holds at the motion `ctx`, if it surely holds one.
    fn held(&self, ctx: &Ctx, name: &str) -> Option<usize> {
        let r = self.reach(name, ctx.at, ctx.func, ctx.block);
        if r.count != 1 || r.param {
            return None;
        }
        match self.assigns[*r.recs.first()?].value {
            Assign::Literal(c) => Some(c),
            Assign::Expression(_) => None,
        }
    }

    /// A waypoint relative to a feature, `pose_trans(feature, pose)` (`inner` its
    /// arguments): the pose a target in the feature's frame, when the feature is a pose
    /// literal; else refused.
    fn feature_target(
        &mut self,
        src: &Source,
        ctx: &Ctx,
        arg: &[Token],
        inner: &[Token],
        frame: FrameUse,
    ) -> Result<(), Error> {
        let text = src.text(arg[0].start, arg[arg.len() - 1].end);
        let split = argument_end(inner, 0);
        let (Some(feature), Some(pose)) = (
            Some(&inner[..split]).filter(|s| !s.is_empty()),
            inner.get(split + 1..).filter(|s| !s.is_empty()),
        ) else {
            self.refuse_target(
                src,
                ctx,
                arg,
                Reason::Dynamic,
                "a pose computed when the script runs",
            );
            return Ok(());
        };
        let feature_pose = match feature {
            [v] if v.kind == Tok::Ident => {
                let name = src.text(v.start, v.end);
                let r = self.reach(&name, ctx.at, ctx.func, ctx.block);
                if r.count >= 2 {
                    let places = self.places(src, &r);
                    self.refuse_target(
                        src,
                        ctx,
                        arg,
                        Reason::Dynamic,
                        &format!(
                            "an offset from {name}, which holds the pose of {places}, by the way the script runs"
                        ),
                    );
                    return Ok(());
                }
                match self.held(ctx, &name).map(|c| &self.candidates[c].literal) {
                    Some(Literal::Pose(p)) => Some((pose_mm(p), Some(name))),
                    _ => None,
                }
            }
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
                src,
                ctx,
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
        self.target(src, ctx, pose, in_feature)?;
        // The offset's candidate, to refuse should the feature be a target itself.
        if let Some(name) = feature_name {
            if self.refused.len() == before {
                let c = if self.candidates.len() > count {
                    Some(count)
                } else {
                    match pose {
                        [v] if v.kind == Tok::Ident => self.held(ctx, &src.text(v.start, v.end)),
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

    /// Refuses the target `arg` of the motion `ctx`, with the reason.
    fn refuse_target(&mut self, src: &Source, ctx: &Ctx, arg: &[Token], reason: Reason, why: &str) {
        let text = src.text(arg[0].start, arg[arg.len() - 1].end);
        self.refused.push(refused_call(
            &arg[0],
            &ctx.call,
            reason,
            format!("{}({text}): {why}", ctx.call),
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
        let seen = p.reasons();
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

    /// The tool each target is used with: its z in mm (`None`: the job's), or why unknown.
    fn tools(p: &Program) -> Vec<(String, String)> {
        p.targets
            .iter()
            .map(|t| {
                let tool = match (t.uses.first(), &t.refused) {
                    (_, Some(r)) => format!("{}: {}", r.reason.as_str(), r.detail),
                    (Some(u), None) if !u.unknown.is_empty() => u.unknown[0].clone(),
                    (Some(u), None) => match u.tool {
                        Some(t) => format!("{:.0}", t.translation.vector.z),
                        None => "option".into(),
                    },
                    (None, None) => "none".into(),
                };
                (t.name.clone(), tool)
            })
            .collect()
    }

    const POLYSCOPE_SUB: &str = "def Program():\n  set_tcp(p[0.0,0.00009,0.031,0.0,0.0,0.0])\n\
        global Waypoint_1_p=p[-.4822, -.1177, .2971, 1.1312, -.7841, -1.0500]\n\
        global Waypoint_3_p=p[-.4604, -.0575, -.0980, 1.1888, -1.0520, -.9707]\n\
        def Subprogram_1():\n    $ 20 \"Subprogram_1\" \"noBreak\"\n    movel(Waypoint_3_p, a=1.2, v=0.25)\n  end\n\
        while (True):\n    $ 2 \"Robot Program\"\n    movel(Waypoint_1_p, a=1.2, v=0.25)\n\
        set_tcp(p[0.0,0.0,0.2,0.0,0.0,0.0])\n    Subprogram_1()\n\
        set_tcp(p[0.0,0.00009,0.031,0.0,0.0,0.0])\n  end\nend\n";

    #[test]
    fn a_function_runs_with_the_tcp_of_its_calls_not_of_where_it_is_written() {
        let p = read(&Source::new("p.script", POLYSCOPE_SUB.as_bytes())).unwrap();
        assert_eq!(
            tools(&p),
            [
                ("Waypoint_1_p".to_string(), "31".to_string()),
                ("Waypoint_3_p".to_string(), "200".to_string()),
            ]
        );
        // A set_tcp inside the function holds after each call, not for the moves written
        // after the function.
        let text = "def Program():\n  set_tcp(p[0,0,0.031,0,0,0])\n  def tool_b():\n\
                    set_tcp(p[0,0,0.2,0,0,0])\n  end\n  movel(p[0.4,0,0.3,0,3.14,0])\n  tool_b()\n\
                    movel(p[0.5,0,0.3,0,3.14,0])\nend\n";
        let p = read(&Source::new("p.script", text.as_bytes())).unwrap();
        let z: Vec<String> = tools(&p).into_iter().map(|t| t.1).collect();
        assert_eq!(z, ["31", "200"]);
        // Called with two TCPs, or never called: the TCP is not known.
        let text = "def Program():\n  def pick():\n    movel(p[0.4,0,0.3,0,3.14,0])\n  end\n\
                    def unused():\n    movel(p[0.6,0,0.3,0,3.14,0])\n  end\n  pick()\n\
                    if (get_standard_digital_in(0)):\n    set_tcp(p[0,0,0.2,0,0,0])\n  end\n  pick()\nend\n";
        let p = read(&Source::new("p.script", text.as_bytes())).unwrap();
        let z: Vec<String> = tools(&p).into_iter().map(|t| t.1).collect();
        assert_eq!(
            z,
            [
                "the TCP is the tool option (no set_tcp before) or the set_tcp at 10:5, by the way the script runs to this motion",
                "the TCP is not known: unused is never called or run",
            ]
        );
    }

    #[test]
    fn an_assignment_later_in_a_loop_reaches_the_moves_before_it() {
        let text = "def Program():\n  global Plane_1=p[-.45,-.2,.02,0,0,.4]\n\
                    global pick_pt=p[-.4822, -.1177, .2971, 1.1312, -.7841, -1.0500]\n\
                    global home=[0, -1.5, 1.5, 0, 1.5, 0]\n  while (True):\n    movej(home)\n\
                    movel(pick_pt, a=1.2, v=0.25)\n\
                    movel(pose_trans(Plane_1, p[-.06, -.07, .05, .91, -1.44, -1.55]), a=1.2, v=0.25)\n\
                    $ 7 \"Assignment\"\n    pick_pt = p[-.4764, -.2924, .0693, 1.1232, -1.1676, -1.2504]\n\
                    Plane_1 = p[-.42,-.25,.02,0,0,.4]\n  end\nend\n";
        let p = read(&Source::new("p.script", text.as_bytes())).unwrap();
        let seen: Vec<(&str, usize, Option<Reason>)> = p
            .targets
            .iter()
            .map(|t| {
                let src = Source::new("p.script", text.as_bytes());
                (
                    t.name.as_str(),
                    src.location(t.offset).0,
                    t.refused.as_ref().map(|r| r.reason),
                )
            })
            .collect();
        assert_eq!(
            seen,
            [
                ("pick_pt", 3, Some(Reason::Dynamic)),
                ("home", 4, None),
                ("movel", 7, Some(Reason::Dynamic)),
                ("movel", 8, Some(Reason::Dynamic)),
                ("pick_pt", 10, Some(Reason::Dynamic)),
            ]
        );
        let detail = |i: usize| p.targets[i].refused.as_ref().unwrap().detail.clone();
        assert_eq!(
            detail(2),
            "movel(pick_pt): pick_pt holds the value of 3:16 or 10:15, by the way the script runs"
        );
        assert!(detail(3).contains("Plane_1, which holds the pose of 2:18 or 11:11"));
        assert_eq!(
            detail(4),
            "movel at 7:1 moves to pick_pt as this or as the value of 3:16, by the way the script runs"
        );
        // Assigned again before the move in the loop: the move reads that one alone.
        let text = "def Program():\n  global pick_pt=p[-.48, -.11, .29, 1.13, -.78, -1.05]\n\
                    while (True):\n    pick_pt = p[-.47, -.29, .06, 1.12, -1.16, -1.25]\n\
                    movel(pick_pt)\n  end\nend\n";
        let p = read(&Source::new("p.script", text.as_bytes())).unwrap();
        assert_eq!(p.targets.len(), 1);
        assert!(p.targets[0].refused.is_none());
        assert_eq!(
            Source::new("", text.as_bytes())
                .location(p.targets[0].offset)
                .0,
            4
        );
    }

    #[test]
    fn an_unclosed_pose_or_block_is_refused_with_its_place() {
        let err = read(&Source::new(
            "bad.script",
            b"def Program():\n  movel(p[-.47, -.29, .069, 1.12, -1.16, a=1.2, v=0.25)\nend\n",
        ))
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "bad.script:2:10: '[' not closed: expected ']' before the ')' at 2:55"
        );
        let err = read(&Source::new(
            "bad.script",
            b"def Program():\n  while (True):\n    movel(p[0.4,0,0.3,0,3.14,0])\nend\n",
        ))
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "bad.script:1:1: this block is not closed: expected 'end'"
        );
    }

    #[test]
    fn a_literal_handed_to_a_function_that_moves_to_its_parameter_is_reported() {
        let text = "def Program():\n  global Waypoint_1_p=p[-.4822, -.1177, .2971, 1.1312, -.7841, -1.0500]\n\
                    def pick(pt, v=0.25):\n    movel(pt, a=1.2, v=v)\n  end\n  pick(Waypoint_1_p)\n\
                    pick(p[-.4764, -.2924, .0693, 1.1232, -1.1676, -1.2504], 0.1)\nend\n";
        let p = read(&Source::new("p.script", text.as_bytes())).unwrap();
        let seen = p.reasons();
        assert_eq!(
            seen,
            [
                ("Waypoint_1_p", Some(Reason::Dynamic)),
                ("movel", Some(Reason::Dynamic)),
                ("pick", Some(Reason::Dynamic)),
            ]
        );
        assert_eq!(
            p.targets[0].refused.as_ref().unwrap().detail,
            "handed to pick as pt (6:3), which movel at 4:5 moves to: a parameter's value, not corrected"
        );
    }

    #[test]
    fn a_return_leaves_a_function_with_the_tcp_set_before_it() {
        let text = "def Program():\n  def tool():\n    if (get_standard_digital_in(0)):\n\
                    set_tcp(p[0,0,0.2,0,0,0])\n      return\n    end\n    set_tcp(p[0,0,0.031,0,0,0])\n  end\n\
                    tool()\n  movel(p[0.4,0,0.3,0,3.14,0])\nend\n";
        let p = read(&Source::new("p.script", text.as_bytes())).unwrap();
        let z: Vec<String> = tools(&p).into_iter().map(|t| t.1).collect();
        assert_eq!(
            z,
            ["the TCP is the set_tcp at 4:1 or the set_tcp at 7:5, by the way the script runs to this motion"]
        );
    }
}
