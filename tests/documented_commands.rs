//! Every command of the README and of `docs/*.md` runs as written.
//!
//! The blocks of a document are run in order in one fresh folder where the repository's
//! `tables/` and `tests/` are at hand (read only): `tablec` commands (also as `target/release/tablec` or `cargo
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

use std::collections::BTreeMap;
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

/// Runs the block's commands in `dir`, where the document's earlier blocks ran (a reader
/// follows a document in order: a table built above is queried below).
fn run_block(doc: &Path, block: &Block, dir: &tempfile::TempDir) {
    let started = std::time::Instant::now();
    let place = format!("{}:{}", doc.display(), block.line);
    let mut variables = BTreeMap::new();
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
                for d in words.iter().skip(1).filter(|w| !w.starts_with('-')) {
                    std::fs::create_dir_all(dir.path().join(d)).unwrap();
                }
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
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            // A build another document or test ran as written, in a folder holding the
            // same files, is run once ([`crate::common::tablec_once`]).
            let o = crate::common::tablec_once(&args, dir.path());
            let code = o.status.code();
            let answers = matches!(args.first(), Some(&"query") | Some(&"compensate"));
            assert!(
                code == Some(0) || (answers && code == Some(3)),
                "{place}: tablec {} exited {code:?}:\n{}",
                args.join(" "),
                String::from_utf8_lossy(&o.stderr)
            );
        }
    }
    eprintln!("{place}: {:.1} s", started.elapsed().as_secs_f64());
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

/// Runs one document's blocks in order in a fresh folder, and checks that each test a
/// block names exists. Returns how many blocks ran here.
fn run_document(relative: &str) -> usize {
    let doc = repo(relative);
    let tests = test_sources();
    let text = std::fs::read_to_string(&doc).unwrap();
    let dir = crate::common::repository_folder();
    let mut ran = 0;
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
            None => {
                run_block(&doc, &block, &dir);
                ran += 1;
            }
        }
    }
    ran
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
