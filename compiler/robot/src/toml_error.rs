//! A TOML parse error as robot files and scenarios report it: line, column, what is
//! wrong, and a short excerpt, whatever the length of the offending line.

/// A TOML file that does not parse, or whose keys are not the format's: where and why.
///
/// The TOML parser's own message quotes the whole offending line; a line of a few hundred
/// kilobytes (one deeply nested array) would make a message as long. This one quotes at
/// most [`TomlError::EXCERPT_CHARS`] characters around the column.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TomlError {
    /// The 1-based line, when the parser located the error.
    pub line: Option<usize>,
    /// The 1-based column (in characters), when located.
    pub column: Option<usize>,
    /// What is wrong, as the parser says it.
    pub message: String,
    /// The text around the error, at most [`TomlError::EXCERPT_CHARS`] characters.
    pub excerpt: String,
}

impl TomlError {
    /// The most characters of the offending line a message quotes.
    pub const EXCERPT_CHARS: usize = 60;

    /// The error `error` of parsing `text`.
    pub fn new(error: &toml::de::Error, text: &str) -> TomlError {
        let mut message: String = error.message().trim().to_owned();
        if message.chars().count() > 4 * Self::EXCERPT_CHARS {
            message = message
                .chars()
                .take(4 * Self::EXCERPT_CHARS)
                .collect::<String>()
                + "…";
        }
        let Some(start) = error.span().map(|s| s.start.min(text.len())) else {
            return TomlError {
                line: None,
                column: None,
                message,
                excerpt: String::new(),
            };
        };
        let start = (0..=start)
            .rev()
            .find(|&i| text.is_char_boundary(i))
            .unwrap_or(0);
        let line_start = text[..start].rfind('\n').map_or(0, |i| i + 1);
        let line_end = text[start..].find('\n').map_or(text.len(), |i| start + i);
        let line_text = &text[line_start..line_end];
        let column = text[line_start..start].chars().count();
        // Up to a third of the excerpt before the column, the rest after it.
        let skip = column.saturating_sub(Self::EXCERPT_CHARS / 3);
        let mut excerpt: String = line_text
            .chars()
            .skip(skip)
            .take(Self::EXCERPT_CHARS)
            .collect();
        if skip > 0 {
            excerpt.insert(0, '…');
        }
        if line_text.chars().count() > skip + Self::EXCERPT_CHARS {
            excerpt.push('…');
        }
        TomlError {
            line: Some(1 + text[..line_start].matches('\n').count()),
            column: Some(column + 1),
            message,
            excerpt,
        }
    }
}

impl std::fmt::Display for TomlError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let (Some(line), Some(column)) = (self.line, self.column) {
            write!(f, "line {line}, column {column}: ")?;
        }
        write!(f, "{}", self.message)?;
        if !self.excerpt.trim().is_empty() {
            write!(f, " (at '{}')", self.excerpt.trim_end())?;
        }
        Ok(())
    }
}

impl std::error::Error for TomlError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_offending_line_is_quoted_in_part() {
        let text = format!(
            "name = \"r\"\nx = {}{}\n",
            "[".repeat(300_000),
            "]".repeat(300_000)
        );
        let error = toml::from_str::<toml::Value>(&text).unwrap_err();
        let ours = TomlError::new(&error, &text);
        assert_eq!(ours.line, Some(2));
        let shown = ours.to_string();
        assert!(shown.len() < 600, "{} bytes", shown.len());
        assert!(shown.starts_with("line 2, column "), "{shown}");
        let text = "name = \"r\"\nhome_deg = [0.0, nope]\n";
        let error = toml::from_str::<toml::Value>(text).unwrap_err();
        let shown = TomlError::new(&error, text).to_string();
        assert!(shown.starts_with("line 2, column 18: "), "{shown}");
        assert!(shown.ends_with("(at 'home_deg = [0.0, nope]')"), "{shown}");
    }
}
