//! A program's bytes with their line starts, for locating errors and targets by line and
//! column, and the small lexical pieces every format shares.

use crate::number::{parse_number, Number};
use crate::Error;

/// A program file's bytes.
pub struct Source<'a> {
    /// The file's name as the user gave it, for messages.
    pub name: &'a str,
    /// Its bytes, as read (never decoded: KRL files are often Latin-1).
    pub bytes: &'a [u8],
    line_starts: Vec<usize>,
}

impl<'a> Source<'a> {
    /// The source of `bytes`, called `name` in messages.
    pub fn new(name: &'a str, bytes: &'a [u8]) -> Source<'a> {
        // Lines end with LF, CRLF or a CR alone (as the lexer reads them).
        let mut line_starts = vec![0];
        line_starts.extend(
            bytes
                .iter()
                .enumerate()
                .filter(|&(i, b)| *b == b'\n' || (*b == b'\r' && bytes.get(i + 1) != Some(&b'\n')))
                .map(|(i, _)| i + 1),
        );
        Source {
            name,
            bytes,
            line_starts,
        }
    }

    /// The 1-based line and column (in bytes) of `offset`.
    pub fn location(&self, offset: usize) -> (usize, usize) {
        let line = self.line_starts.partition_point(|&s| s <= offset);
        let start = self.line_starts[line.saturating_sub(1)];
        (line, offset - start + 1)
    }

    /// Its lines, first to last: each line's content without its line end (LF, CRLF or a
    /// CR alone); a line end at the end of the file starts no line.
    pub fn lines(&self) -> Lines<'_> {
        Lines {
            bytes: self.bytes,
            start: 0,
            number: 0,
        }
    }

    /// The line starting at `start`: where its content ends and where the next line
    /// starts.
    pub fn line_at(&self, start: usize) -> (usize, usize) {
        line_at(self.bytes, start)
    }

    /// A syntax error at `offset`.
    pub fn error(&self, offset: usize, message: impl Into<String>) -> Error {
        let (line, column) = self.location(offset);
        Error::Syntax {
            file: self.name.to_string(),
            line,
            column,
            message: message.into(),
        }
    }

    /// The byte at `i`, if any.
    pub fn at(&self, i: usize) -> Option<u8> {
        self.bytes.get(i).copied()
    }

    /// The text of `start..end`, lossily (for names and messages; bytes outside ASCII show
    /// as replacement characters).
    pub fn text(&self, start: usize, end: usize) -> String {
        String::from_utf8_lossy(&self.bytes[start..end.min(self.bytes.len())]).into_owned()
    }

    /// The end of the identifier starting at `i` (letters, digits, `_`, and `$` and `#`
    /// when `extra` allows them), `i` itself when none starts there.
    pub fn identifier_end(&self, i: usize, extra: &[u8]) -> usize {
        let mut j = i;
        while let Some(b) = self.at(j) {
            let first = j == i;
            let ok = b.is_ascii_alphabetic()
                || b == b'_'
                || extra.contains(&b)
                || (!first && b.is_ascii_digit());
            if !ok {
                break;
            }
            j += 1;
        }
        j
    }

    /// The first non-blank (space, tab) byte at or after `i`; newlines are not blank.
    pub fn skip_blanks(&self, mut i: usize) -> usize {
        while matches!(self.at(i), Some(b' ' | b'\t')) {
            i += 1;
        }
        i
    }

    /// A number at `i`, or an error naming `what` was expected there.
    pub fn number(&self, i: usize, what: &str) -> Result<Number, Error> {
        parse_number(self.bytes, i).ok_or_else(|| {
            self.error(
                i,
                format!("expected a number ({what}), found {}", self.describe(i)),
            )
        })
    }

    /// What stands at `i`, for messages: a short quote, or the end of the file.
    pub fn describe(&self, i: usize) -> String {
        if i >= self.bytes.len() {
            return "the end of the file".to_string();
        }
        let end = (i + 12).min(self.bytes.len());
        let end = self.bytes[i..end]
            .iter()
            .position(|b| *b == b'\n' || *b == b'\r')
            .map_or(end, |p| i + p);
        if end == i {
            return "the end of the line".to_string();
        }
        format!("'{}'", self.text(i, end))
    }
}

/// A line of a source.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Line {
    /// Its number, from 1.
    pub number: usize,
    /// Its first byte.
    pub start: usize,
    /// One past its content's last byte (where its line end is).
    pub end: usize,
}

/// The lines of a source ([`Source::lines`]).
pub struct Lines<'a> {
    bytes: &'a [u8],
    start: usize,
    number: usize,
}

impl Iterator for Lines<'_> {
    type Item = Line;

    fn next(&mut self) -> Option<Line> {
        if self.start >= self.bytes.len() {
            return None;
        }
        let (end, next) = line_at(self.bytes, self.start);
        self.number += 1;
        let line = Line {
            number: self.number,
            start: self.start,
            end,
        };
        self.start = next;
        Some(line)
    }
}

/// The end of the content of the line starting at `start`, and where the next starts.
fn line_at(bytes: &[u8], start: usize) -> (usize, usize) {
    let end = bytes[start..]
        .iter()
        .position(|b| *b == b'\n' || *b == b'\r')
        .map_or(bytes.len(), |p| start + p);
    let next = if bytes.get(end) == Some(&b'\r') && bytes.get(end + 1) == Some(&b'\n') {
        end + 2
    } else {
        end + 1
    };
    (end, next)
}

/// Whether two identifiers are equal ignoring ASCII case (KRL and RAPID are
/// case-insensitive).
pub fn same_name(a: &[u8], b: &[u8]) -> bool {
    a.eq_ignore_ascii_case(b)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines_of(text: &str) -> Vec<(usize, &str)> {
        let src = Source::new("t", text.as_bytes());
        src.lines()
            .map(|l| (l.number, &text[l.start..l.end]))
            .collect()
    }

    #[test]
    fn lines_end_at_lf_crlf_or_a_lone_cr_and_a_final_line_end_starts_none() {
        assert_eq!(
            lines_of("a\nbb\r\nc\rd"),
            [(1, "a"), (2, "bb"), (3, "c"), (4, "d")]
        );
        assert_eq!(lines_of("a\n"), [(1, "a")]);
        assert_eq!(lines_of("\n\r\n"), [(1, ""), (2, "")]);
        assert!(lines_of("").is_empty());
        // The lines' numbers are those errors are located by.
        let text = "x\r\ny\rz\n";
        let src = Source::new("t", text.as_bytes());
        for line in src.lines() {
            assert_eq!(src.location(line.start), (line.number, 1));
        }
    }
}
