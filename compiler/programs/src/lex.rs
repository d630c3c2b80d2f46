//! Tokens of the program languages: identifiers, unsigned numbers, strings, punctuation
//! and line ends, with comments skipped. One lexer for KRL, RAPID and URScript, told each
//! language's comment mark and quotes.

use crate::source::Source;

/// A token's kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tok {
    /// An identifier or keyword.
    Ident,
    /// An unsigned number (a sign before it is punctuation: the reader takes the number
    /// from the sign's offset when a value may be signed).
    Number,
    /// A quoted string or literal (`"text"`, KRL's `'B010'`).
    Str,
    /// One byte of punctuation.
    Punct(u8),
    /// A line end: `\n`, `\r\n` (the `\r` is blank) or a `\r` alone.
    Newline,
    /// The end of the file.
    Eof,
}

/// A token and its bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Token {
    /// What it is.
    pub kind: Tok,
    /// Its first byte.
    pub start: usize,
    /// One past its last byte.
    pub end: usize,
}

impl Token {
    /// Whether it is the punctuation `b`.
    pub fn is(&self, b: u8) -> bool {
        self.kind == Tok::Punct(b)
    }
}

/// A language's lexical conventions.
#[derive(Clone, Copy, Debug)]
pub struct Language {
    /// The byte that starts a comment running to the end of the line.
    pub comment: u8,
    /// The bytes that open (and close) a string.
    pub quotes: &'static [u8],
    /// Bytes allowed in identifiers besides letters, digits and `_`.
    pub ident_extra: &'static [u8],
}

/// A lexer over a source.
pub struct Lexer<'s, 'a> {
    src: &'s Source<'a>,
    lang: Language,
    /// The next byte to read.
    pub pos: usize,
}

impl<'s, 'a> Lexer<'s, 'a> {
    /// A lexer at the start of `src`.
    pub fn new(src: &'s Source<'a>, lang: Language) -> Lexer<'s, 'a> {
        Lexer { src, lang, pos: 0 }
    }

    /// The next token.
    pub fn next_token(&mut self) -> Token {
        let src = self.src;
        let mut i = self.pos;
        loop {
            match src.at(i) {
                // A CR before an LF is blank; a CR alone ends a line (old Mac files).
                Some(b'\r') if src.at(i + 1) == Some(b'\n') => i += 1,
                Some(b' ' | b'\t' | 0x0c) => i += 1,
                Some(b) if b == self.lang.comment => {
                    while src.at(i).is_some_and(|b| b != b'\n' && b != b'\r') {
                        i += 1;
                    }
                }
                _ => break,
            }
        }
        let start = i;
        let (kind, end) = match src.at(i) {
            None => (Tok::Eof, i),
            Some(b'\n' | b'\r') => (Tok::Newline, i + 1),
            Some(b) if self.lang.quotes.contains(&b) => {
                let mut j = i + 1;
                while src
                    .at(j)
                    .is_some_and(|c| c != b && c != b'\n' && c != b'\r')
                {
                    j += 1;
                }
                if src.at(j) == Some(b) {
                    j += 1;
                }
                (Tok::Str, j)
            }
            Some(b)
                if b.is_ascii_digit()
                    || (b == b'.' && src.at(i + 1).is_some_and(|c| c.is_ascii_digit())) =>
            {
                let end = crate::number::parse_number(src.bytes, i).map_or(i + 1, |n| n.span.1);
                // Digits running on into letters (`1abc`) are one malformed token, read as
                // an identifier so that no reader takes its digits for a value.
                let run = src.identifier_end(end, self.lang.ident_extra);
                if run > end {
                    (Tok::Ident, run)
                } else {
                    (Tok::Number, end)
                }
            }
            Some(b)
                if b.is_ascii_alphabetic() || b == b'_' || self.lang.ident_extra.contains(&b) =>
            {
                (
                    Tok::Ident,
                    src.identifier_end(i, self.lang.ident_extra).max(i + 1),
                )
            }
            Some(b) => (Tok::Punct(b), i + 1),
        };
        self.pos = end;
        Token { kind, start, end }
    }

    /// A token's text, lossily.
    pub fn text(&self, t: Token) -> String {
        self.src.text(t.start, t.end)
    }

    /// The tokens of the rest of the current line (its line end not included), leaving the
    /// lexer after the line end.
    pub fn line(&mut self) -> Option<Vec<Token>> {
        let mut tokens = Vec::new();
        loop {
            let t = self.next_token();
            match t.kind {
                Tok::Newline => return Some(tokens),
                Tok::Eof => return (!tokens.is_empty()).then_some(tokens),
                _ => tokens.push(t),
            }
        }
    }
}
