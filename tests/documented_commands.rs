//! Every command of the README and of `docs/*.md` runs as written.
//!
//! The blocks of a document are run in order in a fresh folder where the repository's
//! `tables/` and `tests/` are at hand (read only); blocks that name no file or folder in
//! common run side by side, each group in a folder of its own (a document's cost is then
//! its longest chain of blocks, not their sum): `tablec` commands (also as `target/release/tablec` or `cargo
//! run --release --bin tablec --`) through the binary under test, with shell variables
//! (`NAME=value`, `$NAME`), `&&`, `\` continuations, quotes and `mkdir -p` understood. Each
//! must exit 0 (3 for a `query` or `compensate` that leaves a target unanswered is an
//! answer, not a failure). Commands of other tools are run elsewhere, and named here:
//! `cargo test`/`build`/`install` by CI itself, `pip`, `python` and `python/run-tests` by
//! the Python package's tests, `cc` by `c_abi.rs`.
//!
//! Each document is a test of its own, so documents run side by side. A `build` another
//! document or test runs with the same arguments in a folder holding the same files (the
//! README's and docs/method.md's first table) is run once in the test process, the others
//! getting its output and table (`common::tablec_once`): a build is deterministic.
//!
//! A block too costly to run here carries, on the line before it, a comment naming the
//! test that runs it, `<!-- tested by module::test -->`; that test must exist.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use crate::common::repo;

/// The documents whose commands are run.
fn documents() -> Vec<PathBuf> {
    let mut docs = vec![repo("README.md")];
    let mut more: Vec<PathBuf> = std::fs::read_dir(repo("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    more.sort();
    docs.extend(more);
    docs
}

/// A `sh` block: its commands (continuations joined), the line it starts at, and the test
/// that runs it instead, when one is named.
struct Block {
    line: usize,
    commands: Vec<String>,
    tested_by: Option<String>,
}

fn blocks(text: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut current: Option<Block> = None;
    let mut previous = "";
    let mut pending = String::new();
    for (i, line) in text.lines().enumerate() {
        match &mut current {
            None if line.trim() == "```sh" => {
                let tested_by = previous
                    .trim()
                    .strip_prefix("<!-- tested by ")
                    .and_then(|r| r.strip_suffix("-->"))
                    .map(|t| t.trim().to_string());
                current = Some(Block {
                    line: i + 1,
                    commands: Vec::new(),
                    tested_by,
                });
            }
            None => {}
            Some(block) if line.trim_start().starts_with("```") => {
                if !pending.is_empty() {
                    block.commands.push(std::mem::take(&mut pending));
                }
                out.push(current.take().unwrap());
            }
            Some(block) => {
                let line = line.trim();
                if let Some(head) = line.strip_suffix('\\') {
                    pending.push_str(head);
                    pending.push(' ');
                } else {
                    pending.push_str(line);
                    block.commands.push(std::mem::take(&mut pending));
                }
            }
        }
        previous = line;
    }
    out
}

/// The words of a command line, quotes removed, `$NAME` and `"$NAME"` replaced; a `#`
/// outside quotes starts a comment.
fn words(line: &str, variables: &BTreeMap<String, String>) -> Vec<String> {
    let mut out = Vec::new();
    let mut word = String::new();
    let mut in_word = false;
    let mut chars = line.chars().peekable();
    let mut quote: Option<char> = None;
    while let Some(c) = chars.next() {
        match (quote, c) {
            (None, '#') if !in_word => break,
            (None, ' ') | (None, '\t') => {
                if in_word {
                    out.push(std::mem::take(&mut word));
                    in_word = false;
                }
            }
            (None, '\'') | (None, '"') => {
                quote = Some(c);
                in_word = true;
            }
            (Some(q), c) if c == q => quote = None,
            (q, '$') if q != Some('\'') => {
                let mut name = String::new();
                while let Some(&n) = chars.peek() {
                    if n.is_ascii_alphanumeric() || n == '_' {
                        name.push(n);
                        chars.next();
                    } else {
                        break;
                    }
                }
                word.push_str(
                    variables
                        .get(&name)
                        .unwrap_or_else(|| panic!("${name} is not set in: {line}")),
                );
                in_word = true;
            }
            (_, c) => {
                word.push(c);
                in_word = true;
            }
        }
    }
    if in_word {
        out.push(word);
    }
    out
}

/// The commands of other tools, and the test or script that runs them.
const ELSEWHERE: [(&str, &str); 9] = [
    ("cargo test", "CI (.ci/run)"),
    (".ci/run", "CI itself, on a clean clone"),
    (
        ". .venv/bin/activate",
        "python/run-tests (its own virtual environment)",
    ),
    ("cargo build", "CI (.ci/run)"),
    ("cargo install", "CI builds the same crate"),
    ("pip", "python/run-tests"),
    ("python", "python/run-tests"),
    ("python/run-tests", "CI (.ci/run)"),
    ("cc", "c_abi.rs"),
];

/// The arguments of a `tablec` command however the documents spell it, or `None` for
/// another tool's.
fn tablec_args(words: &[String]) -> Option<&[String]> {
    let first = words.first()?.as_str();
    if first == "tablec" || first == "target/release/tablec" {
        return Some(&words[1..]);
    }
    if first == "cargo" && words.get(1).is_some_and(|w| w == "run") {
        let at = words.iter().position(|w| w == "--")?;
        return Some(&words[at + 1..]);
    }
    None
}

/// One command of a block, its words with the block's shell variables replaced: `tablec`'s
/// arguments or `mkdir`'s operands. Commands of other tools (run elsewhere) are left out.
enum Command {
    Tablec(Vec<String>),
    Mkdir(Vec<String>),
}

/// The block's commands in order, as a shell would read them.
fn commands(doc: &Path, block: &Block) -> Vec<Command> {
    let place = format!("{}:{}", doc.display(), block.line);
    let mut variables = BTreeMap::new();
    let mut out = Vec::new();
    for line in &block.commands {
        for command in line.split("&&") {
            let command = command.trim();
            if command.is_empty() || command.starts_with('#') {
                continue;
            }
            // NAME=value (no spaces): a shell variable.
            if let Some((name, value)) = command.split_once('=') {
                if !name.contains(' ') && name == name.to_uppercase() {
                    let value = words(value, &variables).join(" ");
                    variables.insert(name.to_string(), value);
                    continue;
                }
            }
            if ELSEWHERE.iter().any(|(p, _)| command.starts_with(p)) {
                continue;
            }
            let words = words(command, &variables);
            if words.is_empty() {
                continue;
            }
            if words[0] == "mkdir" {
                let folders = words.iter().skip(1).filter(|w| !w.starts_with('-'));
                out.push(Command::Mkdir(folders.cloned().collect()));
                continue;
            }
            let Some(args) = tablec_args(&words) else {
                panic!(
                    "{place}: '{}' is neither tablec nor a command run elsewhere",
                    words.join(" ")
                );
            };
            for a in args {
                assert!(
                    !(a.starts_with('[') || a.ends_with(']')),
                    "{place}: '{a}' is not a literal argument: write each command as it runs"
                );
            }
            out.push(Command::Tablec(args.to_vec()));
        }
    }
    out
}

/// Runs the block's commands in `dir`, where the earlier blocks it depends on ran (a
/// reader follows a document in order: a table built above is queried below).
fn run_block(doc: &Path, block: &Block, dir: &Path) {
    let started = std::time::Instant::now();
    let place = format!("{}:{}", doc.display(), block.line);
    for command in commands(doc, block) {
        let args = match command {
            Command::Mkdir(folders) => {
                for d in folders {
                    std::fs::create_dir_all(dir.join(d)).unwrap();
                }
                continue;
            }
            Command::Tablec(args) => args,
        };
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        // A deterministic command another document or test ran as written, in a folder
        // holding the same files, is run once ([`crate::common::tablec_once`]).
        let o = crate::common::tablec_once(&args, dir);
        let code = o.status.code();
        let answers = matches!(args.first(), Some(&"query") | Some(&"compensate"));
        assert!(
            code == Some(0) || (answers && code == Some(3)),
            "{place}: tablec {} exited {code:?}:\n{}",
            args.join(" "),
            String::from_utf8_lossy(&o.stderr)
        );
    }
    eprintln!("{place}: {:.1} s", started.elapsed().as_secs_f64());
}

/// The files and folders a block names outside the repository's `tables/` and `tests/`
/// (which no command changes): `(paths, words)`, `paths` the words written as a path (with
/// a `.` or a `/`, and `mkdir`'s operands) and their first component, `words` those and
/// every other word with a letter (a folder named bare, `--report out`, that a later block
/// reads as `out/index.html`). Options' names, numbers and coordinates are not names.
fn names(doc: &Path, block: &Block) -> (BTreeSet<String>, BTreeSet<String>) {
    let (mut paths, mut words) = (BTreeSet::new(), BTreeSet::new());
    for command in commands(doc, block) {
        let (operands, all_paths) = match &command {
            Command::Tablec(args) => (args, false),
            Command::Mkdir(folders) => (folders, true),
        };
        for word in operands {
            // `--option=value`: the value.
            let word = match word.strip_prefix('-') {
                Some(option) => match option.split_once('=') {
                    Some((_, value)) => value,
                    None => continue,
                },
                None => word.as_str(),
            };
            let first = word.split('/').next().unwrap_or_default();
            if !word.chars().any(|c| c.is_ascii_alphabetic())
                || ["tables", "tests"].contains(&first)
            {
                continue;
            }
            if all_paths || word.contains(['.', '/']) {
                paths.extend([word.to_string(), first.to_string()]);
            }
            words.extend([word.to_string(), first.to_string()]);
        }
    }
    (paths, words)
}

/// The blocks in groups that name no file or folder in common: each group in document
/// order, the groups in the order of their first block. A block that names a file an
/// earlier block names (wrote or read) is in its group, so it runs after it, in its folder.
fn independent_groups(doc: &Path, blocks: &[Block]) -> Vec<Vec<usize>> {
    let names: Vec<_> = blocks.iter().map(|b| names(doc, b)).collect();
    let mut group_of: Vec<usize> = (0..blocks.len()).collect();
    for i in 0..blocks.len() {
        for j in 0..i {
            let ((paths_i, words_i), (paths_j, words_j)) = (&names[i], &names[j]);
            let shared = !paths_i.is_disjoint(words_j) || !words_i.is_disjoint(paths_j);
            let (gi, gj) = (group_of[i], group_of[j]);
            if shared && gi != gj {
                // Merge into the earlier block's group (the smaller index).
                let (keep, gone) = (gi.min(gj), gi.max(gj));
                for g in group_of.iter_mut() {
                    if *g == gone {
                        *g = keep;
                    }
                }
            }
        }
    }
    let mut groups: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (i, g) in group_of.into_iter().enumerate() {
        groups.entry(g).or_default().push(i);
    }
    groups.into_values().collect()
}

/// The names of the tests a `tested by` comment may name: every `fn` of `tests/*.rs`.
fn test_sources() -> String {
    std::fs::read_dir(repo("tests"))
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension()? == "rs").then(|| std::fs::read_to_string(p).unwrap())
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Runs one document's blocks, and checks that each test a block names exists. Blocks that
/// name no file in common ([`independent_groups`]) run side by side, each group in order in
/// a fresh folder of its own: a block that read a file an earlier block wrote without
/// either naming it would fail here, not pass. Returns how many blocks ran here.
fn run_document(relative: &str) -> usize {
    let doc = repo(relative);
    let tests = test_sources();
    let text = std::fs::read_to_string(&doc).unwrap();
    let mut here = Vec::new();
    for block in blocks(&text) {
        match &block.tested_by {
            Some(test) => {
                let name = test.rsplit("::").next().unwrap();
                assert!(
                    tests.contains(&format!("fn {name}()")),
                    "{}:{}: the test {test} named for this block does not exist",
                    doc.display(),
                    block.line
                );
            }
            None => here.push(block),
        }
    }
    let groups = independent_groups(&doc, &here);
    std::thread::scope(|scope| {
        for group in &groups {
            let (doc, here) = (&doc, &here);
            scope.spawn(move || {
                let dir = crate::common::repository_folder();
                for &i in group {
                    run_block(doc, &here[i], dir.path());
                }
            });
        }
    });
    here.len()
}

/// One test per document, so that the test harness runs documents side by side (each
/// document's blocks stay in order: a table built above is queried below).
macro_rules! documents_run_as_written {
    ($($test:ident => $path:literal,)*) => {
        /// The documents with a test of their own.
        const DOCUMENTS: &[&str] = &[$($path),*];
        $(
            #[test]
            fn $test() {
                run_document($path);
            }
        )*
    };
}

documents_run_as_written! {
    readme_commands_run_as_written => "README.md",
    cli_commands_run_as_written => "docs/cli.md",
    evaluation_commands_run_as_written => "docs/evaluation.md",
    measure_commands_run_as_written => "docs/measure.md",
    method_commands_run_as_written => "docs/method.md",
    programs_commands_run_as_written => "docs/programs.md",
    python_commands_run_as_written => "docs/python.md",
    runtime_commands_run_as_written => "docs/runtime.md",
    samples_commands_run_as_written => "docs/samples.md",
    tracker_commands_run_as_written => "docs/tracker.md",
}

#[test]
fn every_document_has_its_test_and_commands_are_run() {
    let listed: Vec<PathBuf> = DOCUMENTS.iter().map(|p| repo(p)).collect();
    assert_eq!(
        documents(),
        listed,
        "each document needs its line in documents_run_as_written!"
    );
    let run_here: usize = DOCUMENTS
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(repo(p)).unwrap();
            blocks(&text)
                .iter()
                .filter(|b| b.tested_by.is_none())
                .count()
        })
        .sum();
    assert!(run_here >= 5, "{run_here} blocks run");
}

/// Blocks that name a file or folder in common, written or read, are in one group in
/// document order, whichever block names it first and however it is spelled (bare, as a
/// path, through a variable, as an option's value); repository files, options, numbers
/// and column maps do not join blocks.
#[test]
fn blocks_naming_a_file_in_common_run_in_order_in_one_folder() {
    let text = "\
```sh
tablec build tables/kr150-2/samples.csv --cell 30 --posture off -o kr150.tbl
```
```sh
tablec eval tables/kr150-2/samples.csv --cell 30 --posture off --report report
```
```sh
mkdir -p sim
tablec simulate --robot tables/kr150-2/robot.toml --random 10 --seed 1 -o sim/samples.csv
```
```sh
T=kr150.tbl
tablec query $T 2000 700 1000 0 90 0
```
```sh
tablec eval sim/samples.csv --validation tables/kr150-2/validation.csv --columns x=x,y=y
```
```sh
tablec continuity --json=report/continuity.json tables/kr150-2/robot.toml
```
";
    let doc = Path::new("doc.md");
    let blocks = blocks(text);
    assert_eq!(blocks.len(), 6);
    assert_eq!(
        independent_groups(doc, &blocks),
        vec![vec![0, 3], vec![1, 5], vec![2, 4]]
    );
}
