//! A CSV of poses, for controllers whose language is not read here: the columns of
//! `tablec query --targets`, read by the same reader.
//!
//! One header row, then one pose per row; lines starting with `#` and blank lines are kept
//! as they are; a UTF-8 byte-order mark is not part of the first name. Fields are separated
//! by commas, semicolons or tabs, whichever the header uses most outside quotes
//! ([`adwi_samples::Delimiter::detect`]), and may be quoted (`"1500,5"`); the `csv` crate
//! splits the rows, as for every sample file. Numbers take a decimal point in
//! comma-separated files; elsewhere the first number with a mark decides between a point and
//! a comma, and every other must agree (a rewritten number keeps the file's mark). Columns,
//! found by name in any order (case-insensitive, spaces trimmed): `x,y,z` (mm, required),
//! `a,b,c` (KUKA angles, degrees: `R = Rz(a)·Ry(b)·Rx(c)`), `j1..jn` (the joint values the
//! controller will use, degrees, at most [`crate::bounds::MAX_JOINTS`]: they select the
//! posture, and are rewritten to the command's when its inverse kinematics is solved),
//! `config` (the inverse-kinematics configuration, an integer 0-254 as in sample files;
//! the robots solved in closed form have 0-7). Other columns are left alone.

use adwi_samples::Delimiter;

use crate::number::{parse_number, Number};
use crate::program::{
    CartesianTarget, ConfigHint, Format, LengthUnit, Orientation, Program, ProgramTarget,
    TargetKind,
};
use crate::source::Source;
use crate::Error;

/// A UTF-8 byte-order mark, which spreadsheets put first.
const BOM: &[u8] = b"\xef\xbb\xbf";

/// Reads the poses of a CSV file.
///
/// # Errors
///
/// [`Error::Syntax`] for a missing column, a row of the wrong length or a field that is not
/// a number, with its line, column and the column's name.
pub fn read(src: &Source) -> Result<Program, Error> {
    read_at_most(src, usize::MAX)
}

/// [`read`], stopping after `limit` rows ([`Program::truncated_at`]).
///
/// # Errors
///
/// As [`read`].
pub fn read_at_most(src: &Source, limit: usize) -> Result<Program, Error> {
    let skip = if src.bytes.starts_with(BOM) {
        BOM.len()
    } else {
        0
    };
    let data = &src.bytes[skip..];
    // The header line: the first that is neither blank nor a comment.
    let header_text = data
        .split(|&b| b == b'\n')
        .map(|l| l.strip_suffix(b"\r").unwrap_or(l))
        .find(|l| !l.trim_ascii().is_empty() && l.first() != Some(&b'#'))
        .unwrap_or(&[]);
    let delimiter = Delimiter::detect(header_text).byte();
    let mut reader = ::csv::ReaderBuilder::new()
        .delimiter(delimiter)
        .has_headers(false)
        .flexible(true)
        .comment(Some(b'#'))
        .from_reader(data);
    let mut rows = Rows {
        src,
        skip,
        delimiter,
        record: ::csv::ByteRecord::new(),
        spans: Vec::new(),
    };
    let Some(header) = rows.next(&mut reader)? else {
        return Err(src.error(src.bytes.len(), "no header row: expected columns x,y,z"));
    };
    let columns = Columns::of_header(src, &rows.spans, header, delimiter)?;
    // The decimal mark: a point in comma-separated files, else the first number's with one.
    let mut comma_decimal = (delimiter == b',').then_some((false, 0));
    let mut targets = Vec::new();
    let mut truncated_at = None;
    while let Some(row) = rows.next(&mut reader)? {
        if targets.len() > limit {
            truncated_at = Some(row);
            break;
        }
        targets.push(columns.target(src, row, &rows.spans, &mut comma_decimal)?);
    }
    // A file of decimal commas gets them in every number rewritten, those it wrote
    // without a mark included.
    if let Some((true, _)) = comma_decimal {
        mark_decimal_commas(&mut targets);
    }
    Ok(Program {
        format: Format::Csv,
        targets,
        truncated_at,
        first_motion: None,
        in_partner: Vec::new(),
    })
}

/// The columns a CSV program's header names: x, y, z, and a, b, c, j1.., config when
/// present.
struct Columns {
    names: Vec<String>,
    x: usize,
    y: usize,
    z: usize,
    abc: Option<[usize; 3]>,
    joints: Vec<usize>,
    config: Option<usize>,
}

impl Columns {
    /// The header's columns, `spans` its fields, `header` where it starts.
    fn of_header(
        src: &Source,
        spans: &[(usize, usize)],
        header: usize,
        delimiter: u8,
    ) -> Result<Columns, Error> {
        let names: Vec<String> = spans
            .iter()
            .map(|&(s, e)| src.text(s, e).trim().to_ascii_lowercase())
            .collect();
        let column = |name: &str| names.iter().position(|n| n == name);
        let (Some(x), Some(y), Some(z)) = (column("x"), column("y"), column("z")) else {
            return Err(src.error(
                header,
                format!(
                    "missing column x, y or z (position, mm); the header, separated by '{}', is: {}",
                    (delimiter as char).escape_default(),
                    names.join(", ")
                ),
            ));
        };
        let abc = match (column("a"), column("b"), column("c")) {
            (Some(a), Some(b), Some(c)) => Some([a, b, c]),
            (None, None, None) => None,
            _ => return Err(src.error(header, "columns a, b, c (KUKA angles) come together")),
        };
        let joints: Vec<usize> = (1..=crate::bounds::MAX_JOINTS + 1)
            .map_while(|k| column(&format!("j{k}")))
            .collect();
        if joints.len() > crate::bounds::MAX_JOINTS {
            return Err(src.error(
                header,
                format!(
                    "more than {} joint columns (j1..j{} are read)",
                    crate::bounds::MAX_JOINTS,
                    crate::bounds::MAX_JOINTS
                ),
            ));
        }
        let config = column("config");
        Ok(Columns {
            names,
            x,
            y,
            z,
            abc,
            joints,
            config,
        })
    }

    /// A row's target: `spans` its fields, `comma_decimal` the file's decimal mark as far
    /// as it is known.
    fn target(
        &self,
        src: &Source,
        row: usize,
        spans: &[(usize, usize)],
        comma_decimal: &mut Option<(bool, usize)>,
    ) -> Result<ProgramTarget, Error> {
        let Columns {
            names,
            x,
            y,
            z,
            abc,
            joints,
            config,
        } = self;
        let (x, y, z, abc, config) = (*x, *y, *z, *abc, *config);
        if spans.len() != names.len() {
            return Err(src.error(
                row,
                format!(
                    "{} fields where the header has {}",
                    spans.len(),
                    names.len()
                ),
            ));
        }
        let mut number = |k: usize| -> Result<Number, Error> {
            let (s, e) = spans[k];
            field_number(src, (s, e), comma_decimal).ok_or_else(|| {
                src.error(
                    s,
                    format!(
                        "(column '{}'): not a number{}: '{}'",
                        names[k],
                        match *comma_decimal {
                            Some((true, at)) => format!(
                                " with a decimal comma, as the first number with a mark ({}:{})",
                                src.location(at).0,
                                src.location(at).1
                            ),
                            Some((false, at)) if at > 0 => format!(
                                " with a decimal point, as the first number with a mark ({}:{})",
                                src.location(at).0,
                                src.location(at).1
                            ),
                            _ => String::new(),
                        },
                        src.text(s, e).trim()
                    ),
                )
            })
        };
        let position = [number(x)?, number(y)?, number(z)?];
        let orientation = match abc {
            Some([a, b, c]) => Some(Orientation::KukaAbcDeg([
                number(a)?,
                number(b)?,
                number(c)?,
            ])),
            None => None,
        };
        let config = match config {
            Some(k) => {
                let n = number(k)?;
                // As sample files: 0-254, 255 being "unknown".
                if !(n.value.fract() == 0.0 && (0.0..255.0).contains(&n.value)) {
                    return Err(src.error(
                        n.span.0,
                        "(column 'config'): a configuration is an integer 0-254",
                    ));
                }
                ConfigHint::Configuration(n.value as u8)
            }
            None => ConfigHint::None,
        };
        let joints = joints
            .iter()
            .map(|&k| number(k))
            .collect::<Result<Vec<_>, _>>()?;
        let (line, _) = src.location(row);
        Ok(ProgramTarget {
            name: format!("row {line}"),
            offset: row,
            kind: TargetKind::Cartesian(Box::new(CartesianTarget {
                position,
                unit: LengthUnit::Millimetre,
                orientation,
                config,
                joints,
            })),
            uses: Vec::new(),
            refused: None,
        })
    }
}

/// Every number of every target marked to be written with a decimal comma.
fn mark_decimal_commas(targets: &mut [ProgramTarget]) {
    for t in targets {
        if let TargetKind::Cartesian(c) = &mut t.kind {
            let orientation = match &mut c.orientation {
                Some(Orientation::KukaAbcDeg(n)) => &mut n[..],
                _ => &mut [],
            };
            for n in c
                .position
                .iter_mut()
                .chain(orientation)
                .chain(&mut c.joints)
            {
                n.style.decimal_comma = true;
            }
        }
    }
}

/// The rows of a file as the `csv` crate reads them, each field located in the file.
struct Rows<'s, 'a> {
    src: &'s Source<'a>,
    /// The bytes before the reader's input (a byte-order mark).
    skip: usize,
    delimiter: u8,
    record: ::csv::ByteRecord,
    /// The current row's fields: their text in the file, quotes excluded.
    spans: Vec<(usize, usize)>,
}

impl Rows<'_, '_> {
    /// The next row's offset in the file, its fields in `spans`; `None` at the end.
    fn next(&mut self, reader: &mut ::csv::Reader<&[u8]>) -> Result<Option<usize>, Error> {
        let src = self.src;
        let at = |e: &::csv::Error| {
            e.position()
                .map_or(src.bytes.len(), |p| self.skip + p.byte() as usize)
        };
        loop {
            match reader.read_byte_record(&mut self.record) {
                // A line of blanks is kept as it is, as a blank line.
                Ok(true) if self.record.len() == 1 && self.record[0].trim_ascii().is_empty() => {}
                Ok(true) => break,
                Ok(false) => return Ok(None),
                Err(e) => return Err(src.error(at(&e), e.to_string())),
            }
        }
        let bytes = src.bytes;
        // The reader's position may be at the end of the previous row: the row starts after
        // the line ends and comment lines the reader skipped.
        let mut i = self.skip
            + self
                .record
                .position()
                .map_or(0, |p| p.byte() as usize)
                .min(bytes.len() - self.skip);
        loop {
            match bytes.get(i) {
                Some(b'\r' | b'\n') => i += 1,
                Some(b'#') if i == 0 || matches!(bytes[i - 1], b'\n' | b'\r') => {
                    while bytes.get(i).is_some_and(|b| *b != b'\n') {
                        i += 1;
                    }
                }
                _ => break,
            }
        }
        let row = i;
        self.spans.clear();
        for field in self.record.iter() {
            let quoted = bytes.get(i) == Some(&b'"');
            let span = if quoted {
                // A quoted field: its text between the quotes, `""` for a quote.
                let quotes = field.iter().filter(|b| **b == b'"').count();
                (i + 1, i + 1 + field.len() + quotes)
            } else {
                (i, i + field.len())
            };
            let located = bytes.get(span.0..span.1).is_some_and(|text| {
                if quoted {
                    bytes.get(span.1) == Some(&b'"') && unquoted(text).eq(field.iter().copied())
                } else {
                    text == field
                }
            });
            if !located {
                return Err(src.error(
                    i,
                    "a field that is not one quoted or unquoted text (text after a closing quote?)",
                ));
            }
            self.spans.push(span);
            i = if quoted { span.1 + 1 } else { span.1 };
            if bytes.get(i) == Some(&self.delimiter) {
                i += 1;
            }
        }
        Ok(Some(row))
    }
}

/// A quoted field's text with each `""` read as one `"`.
fn unquoted(text: &[u8]) -> impl Iterator<Item = u8> + '_ {
    let mut previous_quote = false;
    text.iter().copied().filter(move |&b| {
        let keep = !(b == b'"' && previous_quote);
        previous_quote = b == b'"' && !previous_quote;
        keep
    })
}

/// The number a field holds (blanks around it allowed): with a decimal point, or a comma
/// when `comma_decimal` says so or, not yet known, this number is the first with a mark
/// (`comma_decimal` is then set to it, with the number's offset).
fn field_number(
    src: &Source,
    (s, e): (usize, usize),
    comma_decimal: &mut Option<(bool, usize)>,
) -> Option<Number> {
    let text = &src.bytes[s..e];
    let lead = text.iter().take_while(|b| b.is_ascii_whitespace()).count();
    let trail = text[lead..]
        .iter()
        .rev()
        .take_while(|b| b.is_ascii_whitespace())
        .count();
    let (s, e) = (s + lead, e - trail);
    let text = &src.bytes[s..e];
    let (point, comma) = (text.contains(&b'.'), text.contains(&b','));
    if point || comma {
        match *comma_decimal {
            None if point && comma => return None,
            None => *comma_decimal = Some((comma, s)),
            Some((true, _)) if point => return None,
            Some((false, _)) if comma => return None,
            Some(_) => {}
        }
    }
    if !comma {
        return parse_number(src.bytes, s).filter(|n| n.span.1 == e);
    }
    // A decimal comma: read as a point, located and styled in the file.
    let swapped: Vec<u8> = text
        .iter()
        .map(|&b| if b == b',' { b'.' } else { b })
        .collect();
    let mut n = parse_number(&swapped, 0).filter(|n| n.span.1 == swapped.len())?;
    n.span = (s, e);
    n.style.decimal_comma = true;
    Some(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_become_targets_and_bad_fields_are_located() {
        let text = "# poses\nname;x;y;z\r\nP1;1500.5;0;1200\r\n\r\nP2; 1600 ;-5;1200\r\n";
        let p = read(&Source::new("t.csv", text.as_bytes())).unwrap();
        assert_eq!(p.targets.len(), 2);
        let TargetKind::Cartesian(c) = &p.targets[1].kind else {
            panic!()
        };
        assert_eq!(c.position.map(|n| n.value), [1600.0, -5.0, 1200.0]);
        let err = read(&Source::new("t.csv", b"x,y,z\n1,2,abc\n")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "t.csv:2:5: (column 'z'): not a number: 'abc'"
        );
        let err = read(&Source::new("t.csv", b"x,y,z\n1,2\n")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "t.csv:2:1: 2 fields where the header has 3"
        );
        let err = read(&Source::new("t.csv", b"x;y\n")).unwrap_err();
        assert!(err.to_string().contains("missing column"), "{err}");
    }
}
