//! A pre-scan of URDF text before it is parsed: how deep its elements nest and how many
//! there are, refused beyond the limits of the module docs ("Limits") in one linear pass.
//!
//! The XML parser and the deserializer behind `urdf-rs` recurse once per level of nesting
//! (and so do the parsed tree's formatting and dropping): 20 000 nested elements overflow
//! the main thread's stack, fewer a smaller thread's. The scan follows the XML grammar
//! only as far as nesting needs (start, end and empty tags, quoted attribute values,
//! comments, CDATA, processing instructions, declarations), so that it counts at least the
//! depth the parser reaches: where the two read malformed text differently, the parser
//! refuses the text at that point, before any deeper element.

use crate::error::RobotError;

/// The deepest nesting of elements a URDF file may have: the URDF grammar nests five deep
/// (`robot`, `link`, `visual`, `geometry`, `mesh`), extensions such as `<gazebo>` a few
/// more.
pub const MAX_URDF_DEPTH: usize = 64;
/// The most elements a URDF file may have: a robot of a thousand links with a visual and a
/// collision each has about 20 000.
pub const MAX_URDF_ELEMENTS: usize = 200_000;
/// The most `<link>` elements a URDF file may have.
pub const MAX_URDF_LINKS: usize = 10_000;
/// The most `<joint>` elements a URDF file may have.
pub const MAX_URDF_JOINTS: usize = 10_000;

/// Checks the nesting depth and the element counts of URDF text (module docs).
pub(crate) fn check_size(text: &str) -> Result<(), RobotError> {
    let bytes = text.as_bytes();
    let too_large = |what: String| RobotError::UrdfChain(what);
    let line_of = |at: usize| 1 + bytes[..at].iter().filter(|&&b| b == b'\n').count();
    let mut depth = 0usize;
    let mut elements = 0usize;
    let mut links = 0usize;
    let mut joints = 0usize;
    let mut i = 0;
    while let Some(offset) = memchr(b'<', &bytes[i..]) {
        let start = i + offset;
        let rest = &bytes[start..];
        let skip_past = |from: usize, end: &[u8]| {
            find(&bytes[from..], end).map_or(bytes.len(), |k| from + k + end.len())
        };
        if rest.starts_with(b"<!--") {
            i = skip_past(start + 4, b"-->");
        } else if rest.starts_with(b"<![CDATA[") {
            i = skip_past(start + 9, b"]]>");
        } else if rest.starts_with(b"<?") {
            i = skip_past(start + 2, b"?>");
        } else if rest.starts_with(b"<!") {
            i = skip_past(start + 2, b">");
        } else if rest.starts_with(b"</") {
            depth = depth.saturating_sub(1);
            i = skip_past(start + 2, b">");
        } else {
            // A start tag: its name, then attributes to '>' (quoted values may hold '>').
            let name_end = rest[1..]
                .iter()
                .position(|b| b.is_ascii_whitespace() || matches!(b, b'>' | b'/'))
                .map_or(rest.len(), |k| k + 1);
            let name = &rest[1..name_end];
            let mut k = start + name_end;
            let mut quote = None;
            let mut empty = false;
            while k < bytes.len() {
                let b = bytes[k];
                match quote {
                    Some(q) if b == q => quote = None,
                    Some(_) => {}
                    None if b == b'"' || b == b'\'' => quote = Some(b),
                    None if b == b'>' => {
                        empty = bytes[k - 1] == b'/';
                        break;
                    }
                    None => {}
                }
                k += 1;
            }
            i = (k + 1).min(bytes.len());
            elements += 1;
            if depth == 1 {
                match name {
                    b"link" => links += 1,
                    b"joint" => joints += 1,
                    _ => {}
                }
            }
            if !empty {
                depth += 1;
                if depth > MAX_URDF_DEPTH {
                    return Err(too_large(format!(
                        "elements nested more than {MAX_URDF_DEPTH} deep (line {}): a URDF \
                         file nests a few levels; this is not one",
                        line_of(start)
                    )));
                }
            }
            if elements > MAX_URDF_ELEMENTS {
                return Err(too_large(format!(
                    "more than {MAX_URDF_ELEMENTS} elements (line {}): more than any robot's \
                     description holds",
                    line_of(start)
                )));
            }
        }
    }
    for (count, max, what) in [
        (links, MAX_URDF_LINKS, "<link>"),
        (joints, MAX_URDF_JOINTS, "<joint>"),
    ] {
        if count > max {
            return Err(too_large(format!(
                "{count} {what} elements, more than the {max} a URDF file may have"
            )));
        }
    }
    Ok(())
}

/// The position of the first `needle` byte in `haystack`.
fn memchr(needle: u8, haystack: &[u8]) -> Option<usize> {
    haystack.iter().position(|&b| b == needle)
}

/// The position of the first occurrence of `needle` in `haystack`.
fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nested(depth: usize) -> String {
        format!(
            "<robot name=\"r\">{}{}</robot>",
            "<a>".repeat(depth),
            "</a>".repeat(depth)
        )
    }

    #[test]
    fn depth_and_counts_are_refused_beyond_the_limits() {
        assert!(check_size(&nested(MAX_URDF_DEPTH - 1)).is_ok());
        let error = check_size(&nested(MAX_URDF_DEPTH)).unwrap_err();
        assert!(error.to_string().contains("nested more than 64"), "{error}");
        // Unclosed, and far deeper: refused at the first level too deep.
        let error = check_size(&"<a>".repeat(1_000_000)).unwrap_err();
        assert!(error.to_string().contains("nested more than 64"), "{error}");
        // Empty elements, comments, CDATA, declarations and quoted '>' do not nest.
        let text = format!(
            "<?xml version=\"1.0\"?><!DOCTYPE robot><robot name=\"a>b\">{}<!-- <a><a> -->\
             <![CDATA[<a><a>]]><link name='x>'/></robot>",
            "<a/>".repeat(1000)
        );
        assert!(check_size(&text).is_ok());
        let links = format!(
            "<robot>{}</robot>",
            "<link name=\"l\"/>".repeat(MAX_URDF_LINKS + 1)
        );
        let error = check_size(&links).unwrap_err();
        assert!(
            error.to_string().contains("10001 <link> elements"),
            "{error}"
        );
        let many = format!("<robot><x>{}</x></robot>", "<y/>".repeat(MAX_URDF_ELEMENTS));
        assert!(check_size(&many).is_err());
    }
}
