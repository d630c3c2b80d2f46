//! What a program file is, before a reader reads it: single-byte text (KRL, RAPID and
//! URScript files are ASCII, Latin-1 or UTF-8; UTF-16 is refused, since the byte-preserving
//! writer cannot keep it), in the dialect the job takes it for (a RAPID module saved as
//! `.src` is refused by name, rather than read as a KRL file that holds nothing).

use crate::program::Format;
use crate::source::Source;
use crate::Error;

/// Checks that `src` is text a reader of `format` can read, and shows no sign of another
/// dialect without one of its own; `given`: the format was given rather than told by the
/// file's extension (for the message).
///
/// # Errors
///
/// [`Error::Syntax`] at the byte-order mark, the first NUL byte, or the first sign of the
/// other dialect.
pub fn check(src: &Source, format: Format, given: bool) -> Result<(), Error> {
    let bytes = src.bytes;
    if let Some(bom) = [&b"\xff\xfe"[..], &b"\xfe\xff"[..]]
        .into_iter()
        .find(|b| bytes.starts_with(b))
    {
        return Err(src.error(
            0,
            format!(
                "UTF-16 text (byte-order mark {:02X} {:02X}): save the program as the controller does, as single-byte text (ANSI, Latin-1 or UTF-8)",
                bom[0], bom[1]
            ),
        ));
    }
    let head = &bytes[..bytes.len().min(4096)];
    let nuls = head.iter().filter(|b| **b == 0).count();
    if nuls * 8 > head.len() {
        let at = head.iter().position(|b| *b == 0).unwrap_or(0);
        return Err(src.error(
            at,
            "NUL bytes: UTF-16 text without a byte-order mark, or not a text file",
        ));
    }
    let signs = signs(src);
    let own = signs.iter().find(|s| s.0 == format);
    let other = signs.iter().filter(|s| s.0 != format).min_by_key(|s| s.1);
    if let (None, Some(&(dialect, at, ref word))) = (own, other) {
        let said = if given {
            "the given format says".to_string()
        } else {
            "its extension says".to_string()
        };
        return Err(src.error(
            at,
            format!(
                "this reads as {} ({word}), not {} as {said}: compensate it as {} (format {})",
                long_name(dialect),
                long_name(format),
                long_name(dialect),
                dialect.name()
            ),
        ));
    }
    Ok(())
}

fn long_name(format: Format) -> &'static str {
    match format {
        Format::Krl => "KUKA KRL",
        Format::Rapid => "ABB RAPID",
        Format::UrScript => "URScript",
        Format::Csv => "a CSV of poses",
        Format::Gcode => "G-code",
        Format::Yaskawa => "Yaskawa INFORM",
        Format::Fanuc => "Fanuc TP",
        Format::Val3 => "Stäubli VAL3",
    }
}

/// The first sign of each dialect in the file: the dialect, where, and the words.
fn signs(src: &Source) -> Vec<(Format, usize, String)> {
    let bytes = src.bytes;
    let mut found: Vec<(Format, usize, String)> = Vec::new();
    let mut start = 0;
    while start < bytes.len() {
        let end = bytes[start..]
            .iter()
            .position(|b| *b == b'\n' || *b == b'\r')
            .map_or(bytes.len(), |p| start + p);
        let mut at = start;
        if at == 0 && bytes.starts_with(b"\xef\xbb\xbf") {
            at = 3;
        }
        while at < end && matches!(bytes[at], b' ' | b'\t') {
            at += 1;
        }
        let line = &bytes[at..end];
        let upper: Vec<u8> = line.iter().take(64).map(u8::to_ascii_uppercase).collect();
        let trimmed = line.trim_ascii_end();
        let starts = |w: &str| upper.starts_with(w.as_bytes());
        let word = |n: usize| src.text(at, (at + n).min(end));
        let sign = if [
            "&ACCESS",
            "&REL ",
            "&PARAM ",
            "DEFDAT ",
            "DEFFCT ",
            ";FOLD",
            "DECL ",
            "ENDDAT",
            "GLOBAL DEF ",
        ]
        .iter()
        .any(|w| starts(w))
            || (starts("DEF ") && !trimmed.ends_with(b":"))
        {
            Some(Format::Krl)
        } else if ["MODULE ", "%%%", "ENDMODULE", "PROC ", "ENDPROC"]
            .iter()
            .any(|w| starts(w))
            || ["ROBTARGET", "JOINTTARGET", "TOOLDATA", "WOBJDATA"]
                .iter()
                .any(|w| upper.windows(w.len()).any(|x| x == w.as_bytes()))
        {
            Some(Format::Rapid)
        } else if (starts("DEF ") && trimmed.ends_with(b":"))
            || ["MOVEJ(", "MOVEL(", "MOVEP(", "MOVEC(", "SET_TCP("]
                .iter()
                .any(|w| starts(w))
        {
            Some(Format::UrScript)
        } else if gcode_block(&upper) {
            Some(Format::Gcode)
        } else if ["/JOB", "//POS", "//INST", "///NPOS", "///POSTYPE"]
            .iter()
            .any(|w| starts(w))
        {
            Some(Format::Yaskawa)
        } else if ["/PROG ", "/ATTR", "/MN", "/POS", "/END"]
            .iter()
            .any(|w| starts(w))
        {
            Some(Format::Fanuc)
        } else if ["<DATABASE", "<DATAS>", "<PROJECT", "<PROGRAMS"]
            .iter()
            .any(|w| starts(w))
        {
            Some(Format::Val3)
        } else {
            None
        };
        if let Some(dialect) = sign {
            if !found.iter().any(|f| f.0 == dialect) {
                let n = line
                    .iter()
                    .position(|b| b.is_ascii_whitespace() || *b == b'(')
                    .unwrap_or(line.len())
                    .clamp(1, 24);
                found.push((
                    dialect,
                    at,
                    format!("'{}' at its line {}", word(n), src.location(at).0),
                ));
            }
        }
        start = end + 1;
    }
    found
}

/// Whether a line (upper case) starts as a G-code block: `G` and a digit, or a block
/// number `N10` followed by a `G` or `M` code.
fn gcode_block(upper: &[u8]) -> bool {
    let code = |s: &[u8]| s.len() > 1 && matches!(s[0], b'G' | b'M') && s[1].is_ascii_digit();
    if upper.first() == Some(&b'G') {
        return code(upper);
    }
    match upper.strip_prefix(b"N") {
        Some(rest) => {
            let digits = rest.iter().take_while(|b| b.is_ascii_digit()).count();
            let after = &rest[digits..];
            let blanks = after
                .iter()
                .take_while(|b| matches!(b, b' ' | b'\t'))
                .count();
            digits > 0 && code(&after[blanks..])
        }
        None => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utf16_and_nul_bytes_are_refused_at_their_place() {
        let utf16: Vec<u8> = b"\xff\xfe"
            .iter()
            .copied()
            .chain(
                "DEF a( )\r\nPTP XP1\r\nEND\r\n"
                    .bytes()
                    .flat_map(|b| [b, 0]),
            )
            .collect();
        let err = check(&Source::new("a.src", &utf16), Format::Krl, false).unwrap_err();
        assert!(
            err.to_string()
                .starts_with("a.src:1:1: UTF-16 text (byte-order mark FF FE)"),
            "{err}"
        );
        let err = check(&Source::new("a.src", &utf16[2..]), Format::Krl, false).unwrap_err();
        assert!(err.to_string().contains("NUL bytes"), "{err}");
    }

    #[test]
    fn a_file_in_another_dialect_is_refused_by_name() {
        let rapid = b"%%%\n  VERSION:1\n%%%\nMODULE M\n  PROC main()\n    MoveL p, v1, z1, tool0;\n  ENDPROC\nENDMODULE\n";
        let err = check(&Source::new("m.src", rapid), Format::Krl, false).unwrap_err();
        assert_eq!(
            err.to_string(),
            "m.src:1:1: this reads as ABB RAPID ('%%%' at its line 1), not KUKA KRL as its extension says: compensate it as ABB RAPID (format rapid)"
        );
        let script = b"def pick():\n  movel(p[0.1,0,0.3,0,3.14,0])\nend\n";
        let err = check(&Source::new("p.mod", script), Format::Rapid, false).unwrap_err();
        assert!(err.to_string().contains("reads as URScript"), "{err}");
        let krl = b"&ACCESS RVP\nDEF weld( )\nPTP XP1\nEND\n";
        let err = check(&Source::new("w.script", krl), Format::UrScript, true).unwrap_err();
        assert!(err.to_string().contains("reads as KUKA KRL ('&ACCESS' at its line 1), not URScript as the given format says"), "{err}");
        // Each in its own dialect reads.
        check(&Source::new("m.mod", rapid), Format::Rapid, false).unwrap();
        check(&Source::new("p.script", script), Format::UrScript, false).unwrap();
        check(&Source::new("w.src", krl), Format::Krl, false).unwrap();
    }
}
