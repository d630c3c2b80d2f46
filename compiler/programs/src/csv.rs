//! A CSV of poses, for controllers whose language is not read here: the columns of
//! `tablec query --targets`.
//!
//! One header row, then one pose per row; lines starting with `#` and blank lines are kept
//! as they are. Fields are separated by commas, semicolons or tabs, whichever the header
//! uses most. Columns, found by name in any order (case-insensitive, spaces trimmed):
//! `x,y,z` (mm, required), `a,b,c` (KUKA angles, degrees: `R = Rz(a)·Ry(b)·Rx(c)`),
//! `j1..jn` (the joint values the controller will use, degrees: they select the
//! posture, and are rewritten to the command's when its inverse kinematics is solved),
//! `config` (this project's inverse-kinematics configuration, 0-7). Other columns are
//! left alone. Numbers take a decimal point.

use crate::number::{parse_number, Number};
use crate::program::{
    CartesianTarget, ConfigHint, Format, LengthUnit, Orientation, Program, ProgramTarget,
    TargetKind,
};
use crate::source::Source;
use crate::Error;

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
    let mut lines = Vec::new();
    let mut start = 0;
    for (i, b) in src.bytes.iter().enumerate() {
        if *b == b'\n' {
            lines.push((start, i));
            start = i + 1;
        }
    }
    if start < src.bytes.len() {
        lines.push((start, src.bytes.len()));
    }
    let content = |&(s, e): &(usize, usize)| {
        let e = if e > s && src.bytes[e - 1] == b'\r' {
            e - 1
        } else {
            e
        };
        (s, e)
    };
    let is_data = |(s, e): (usize, usize)| {
        let text = &src.bytes[s..e];
        let first = text.iter().position(|b| !b.is_ascii_whitespace());
        first.is_some_and(|f| text[f] != b'#')
    };
    let mut rows = lines.iter().map(content).filter(|l| is_data(*l));
    let Some(header) = rows.next() else {
        return Err(src.error(src.bytes.len(), "no header row: expected columns x,y,z"));
    };
    let header_text = &src.bytes[header.0..header.1];
    let delimiter = [b',', b';', b'\t']
        .into_iter()
        .max_by_key(|d| (header_text.iter().filter(|b| *b == d).count(), d == &b','))
        .unwrap_or(b',');
    let names: Vec<String> = fields(header, src.bytes, delimiter)
        .map(|(s, e)| src.text(s, e).trim().to_ascii_lowercase())
        .collect();
    let column = |name: &str| names.iter().position(|n| n == name);
    let (Some(x), Some(y), Some(z)) = (column("x"), column("y"), column("z")) else {
        return Err(src.error(
            header.0,
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
        _ => return Err(src.error(header.0, "columns a, b, c (KUKA angles) come together")),
    };
    let joints: Vec<usize> = (1..).map_while(|k| column(&format!("j{k}"))).collect();
    let config = column("config");
    let mut targets = Vec::new();
    let mut truncated_at = None;
    for row in rows {
        if targets.len() > limit {
            truncated_at = Some(row.0);
            break;
        }
        let spans: Vec<(usize, usize)> = fields(row, src.bytes, delimiter).collect();
        if spans.len() != names.len() {
            return Err(src.error(
                row.0,
                format!(
                    "{} fields where the header has {}",
                    spans.len(),
                    names.len()
                ),
            ));
        }
        let number = |k: usize| -> Result<Number, Error> {
            let (s, e) = spans[k];
            let text = &src.bytes[s..e];
            let lead = text.iter().take_while(|b| b.is_ascii_whitespace()).count();
            let trail = text
                .iter()
                .rev()
                .take_while(|b| b.is_ascii_whitespace())
                .count();
            match parse_number(src.bytes, s + lead) {
                Some(n) if n.span.1 == e - trail.min(e - s - lead) => Ok(n),
                _ => Err(src.error(
                    s,
                    format!(
                        "(column '{}'): not a number: '{}'",
                        names[k],
                        src.text(s, e).trim()
                    ),
                )),
            }
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
                if !(n.value.fract() == 0.0 && (0.0..8.0).contains(&n.value)) {
                    return Err(src.error(
                        n.span.0,
                        "(column 'config'): a configuration is an integer 0-7",
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
        let (line, _) = src.location(row.0);
        targets.push(ProgramTarget {
            name: format!("row {line}"),
            offset: row.0,
            kind: TargetKind::Cartesian(Box::new(CartesianTarget {
                position,
                unit: LengthUnit::Millimetre,
                orientation,
                config,
                joints,
            })),
            uses: Vec::new(),
        });
    }
    Ok(Program {
        format: Format::Csv,
        targets,
        truncated_at,
    })
}

/// The byte spans of a line's fields.
fn fields(
    (start, end): (usize, usize),
    bytes: &[u8],
    delimiter: u8,
) -> impl Iterator<Item = (usize, usize)> + '_ {
    let mut s = start;
    let mut done = false;
    std::iter::from_fn(move || {
        if done {
            return None;
        }
        let e = bytes[s..end]
            .iter()
            .position(|b| *b == delimiter)
            .map_or(end, |p| s + p);
        let out = (s, e);
        if e == end {
            done = true;
        } else {
            s = e + 1;
        }
        Some(out)
    })
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
