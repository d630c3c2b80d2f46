//! ISO 9283:1998 pose characteristics from measured cycles.
//!
//! A robot is commanded to the same poses cycle after cycle; a laser tracker records where
//! it stands each time. ISO 9283 reduces those cycles to figures a robot's data sheet
//! quotes, per commanded pose (docs/measure.md gives every formula with its clause):
//!
//! - pose accuracy `AP`: how far the barycentre of the attained positions lies from the
//!   commanded one, `AP_P = sqrt((x̄−x_c)² + (ȳ−y_c)² + (z̄−z_c)²)`, and per axis
//!   `AP_x = x̄ − x_c`, ...; per orientation angle `AP_a = ā − a_c`, ...;
//! - pose repeatability `RP`: the radius of the sphere about that barycentre,
//!   `RP_l = l̄ + 3 S_l`, `l_j` the distance of attained position `j` to the barycentre and
//!   `S_l` their standard deviation (with `n − 1`); per orientation angle `±3 S_a`;
//! - distance accuracy `AD` and repeatability `RD`, between the standard's two poses P2
//!   and P4 (or pairs named): the attained distance `D_j = |P_1j − P_2j|` against the
//!   commanded `D_c`, `AD_P = D̄ − D_c`, per axis `AD_x = D̄_x − D_cx` with
//!   `D_xj = |x_1j − x_2j|`, and `RD = ±3 S_D`.
//!
//! Orientation angles are the standard's `a`, `b`, `c`: rotations about the base x, y and
//! z axes ([`ORIENTATION_CONVENTION`]). The cycles file gives KUKA A, B, C (about z, y, x),
//! the project's convention for `a,b,c` columns; both compose as `Rz·Ry·Rx`, so the
//! standard's `a, b, c` are KUKA's `C, B, A` of the same rotation.
//!
//! The measured cycles are a small CSV ([`parse_cycles`]): the plan [`write_cube_plan`]
//! writes, with the attained pose's columns added.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use adwi_samples::pose::{
    kuka_abc_deg_from_rotation, rotation_from_kuka_abc_deg, rotation_from_vector,
};
use serde::Serialize;

/// The most rows a cycles file may hold: ISO 9283 asks for 30 cycles of five poses; a
/// million rows is any campaign's, and read in well under a second.
pub const MAX_ROWS: usize = 1_000_000;

/// The number of cycles ISO 9283 asks for, per pose.
pub const ISO_CYCLES: u32 = 30;

/// The orientation convention of every orientation figure, as each output states it.
pub const ORIENTATION_CONVENTION: &str = "ISO 9283 a, b, c: rotations about the base x, y, z, \
     R = Rz(c)·Ry(b)·Rx(a), degrees (the cycles file's KUKA a, b, c, R = Rz(a)·Ry(b)·Rx(c), \
     are its c, b, a)";

/// The positions of a cube's cycle in the order the standard runs them: P1, P5, P4, P3,
/// P2 (then P1 of the next cycle).
pub const CUBE_SEQUENCE: [usize; 5] = [0, 4, 3, 2, 1];

/// The pair of positions whose distance the standard measures: P2 and P4, the ends of a
/// diagonal of the measurement plane.
pub const DISTANCE_PAIR: (&str, &str) = ("P2", "P4");

/// An ISO 9283 `b` within this of ±90° (degrees) is near the convention's gimbal lock:
/// `a` and `c` are then not separately defined and their figures mean little.
const GIMBAL_MARGIN_DEG: f64 = 10.0;

/// Two commanded poses of one position farther apart than this (mm, degrees) are two
/// poses, not one: the file is refused.
const SAME_COMMAND_TOLERANCE: f64 = 1e-6;

/// One measured cycle at one position: the commanded pose and the attained one.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleRow {
    /// The position's name (`P1`..`P5`, or any).
    pub position: String,
    /// The cycle number.
    pub cycle: u32,
    /// Commanded position, mm, base frame.
    pub commanded_mm: [f64; 3],
    /// Attained (measured) position, mm, base frame.
    pub attained_mm: [f64; 3],
    /// Commanded and attained orientation, KUKA A, B, C degrees, when the file gives both.
    pub orientation_abc_deg: Option<[[f64; 3]; 2]>,
    /// The source line (1-based), for messages.
    pub line: u64,
}

/// Why cycles cannot be read or reduced.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Iso9283Error {
    /// The file cannot be read.
    #[error("cannot read {path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// A malformed CSV record.
    #[error("line {line}: {reason}")]
    Csv {
        /// The line.
        line: u64,
        /// Why.
        reason: String,
    },
    /// A column the format needs is missing from the header.
    #[error("the header has no column '{0}' (needs position, cycle, x, y, z, mx, my, mz; for orientation figures a, b, c and ma, mb, mc)")]
    MissingColumn(&'static str),
    /// A field that is not what its column holds.
    #[error("line {line}, column {column}: '{text}' {why}")]
    Field {
        /// The line.
        line: u64,
        /// The column.
        column: &'static str,
        /// The field.
        text: String,
        /// What it should be.
        why: &'static str,
    },
    /// One position measured twice in one cycle.
    #[error("line {line}: position {position} cycle {cycle} is measured twice")]
    Duplicate {
        /// The position.
        position: String,
        /// The cycle.
        cycle: u32,
        /// The second row's line.
        line: u64,
    },
    /// One position commanded to two poses.
    #[error("line {line}: position {position} is commanded elsewhere than on line {first}: one name, one commanded pose")]
    CommandChanged {
        /// The position.
        position: String,
        /// The first row's line.
        first: u64,
        /// This row's line.
        line: u64,
    },
    /// Too few cycles for a standard deviation.
    #[error("position {position} has {n} cycle(s): repeatability needs at least 2 (ISO 9283 asks for {ISO_CYCLES})")]
    TooFewCycles {
        /// The position.
        position: String,
        /// Its cycles.
        n: usize,
    },
    /// No rows.
    #[error("no measured cycles")]
    Empty,
    /// A path command or tracker stream that cannot be read or reduced.
    #[error(transparent)]
    Path(#[from] crate::path::PathError),
    /// A distance pair naming a position the cycles do not have.
    #[error("no position named '{0}' in the cycles: a distance pair names two measured positions")]
    UnknownPosition(String),
    /// More rows than [`MAX_ROWS`].
    #[error("more than {MAX_ROWS} rows: {rows} and counting")]
    TooManyRows {
        /// Rows read so far.
        rows: usize,
    },
    /// A cube that is not one.
    #[error("{0}")]
    Cube(String),
    /// A compensation that gave no correction for a row.
    #[error("line {line}: {reason}")]
    Compensation {
        /// The row's line.
        line: u64,
        /// Why.
        reason: String,
    },
}

/// The largest magnitude a cycles file's number may have: mm for positions, degrees for
/// angles ([`adwi_runtime::format::MAX_COORDINATE_MM`]).
const MAX_FIELD: f64 = adwi_runtime::format::MAX_COORDINATE_MM;

/// Whether `text` is a whole number as written: an optional sign, then digits.
fn is_digits(text: &str) -> bool {
    let digits = text.strip_prefix(['+', '-']).unwrap_or(text);
    !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
}

/// Reads a cycles file ([`parse_cycles`]).
///
/// # Errors
///
/// As [`parse_cycles`], and a file that cannot be read.
pub fn read_cycles(path: &Path) -> Result<Vec<CycleRow>, Iso9283Error> {
    let bytes = adwi_runtime::input::read_regular(path).map_err(|e| Iso9283Error::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    parse_cycles(&bytes)
}

/// Parses measured cycles: a comma-separated file, `#` comment lines, one header row of
/// `position, cycle, x, y, z, mx, my, mz` (commanded and attained position, mm, base frame)
/// and optionally `a, b, c, ma, mb, mc` (commanded and attained orientation, KUKA degrees;
/// `a, b, c` without a measured orientation are ignored), in any order; other columns are
/// ignored. `position` is any name, `cycle` a whole number.
///
/// # Errors
///
/// A missing column, a field that is not a finite number (or, for `cycle`, a whole number),
/// a position measured twice in a cycle or commanded to two poses, more than
/// [`MAX_ROWS`] rows, no row.
pub fn parse_cycles(bytes: &[u8]) -> Result<Vec<CycleRow>, Iso9283Error> {
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_reader(bytes);
    let csv_error = |e: csv::Error| Iso9283Error::Csv {
        line: e.position().map_or(0, |p| p.line()),
        reason: e.to_string(),
    };
    let header = reader.headers().map_err(csv_error)?.clone();
    let find = |name: &'static str| header.iter().position(|h| h == name);
    let need = |name: &'static str| find(name).ok_or(Iso9283Error::MissingColumn(name));
    let position = need("position")?;
    let cycle = need("cycle")?;
    let commanded = [need("x")?, need("y")?, need("z")?];
    let attained = [need("mx")?, need("my")?, need("mz")?];
    // Orientation figures when the attained orientation was measured: a plan's commanded
    // a, b, c alone, measured by a position-only tracker, are read as position only.
    const ANGLES: [&str; 6] = ["a", "b", "c", "ma", "mb", "mc"];
    let angles: Vec<Option<usize>> = ANGLES.iter().map(|n| find(n)).collect();
    let orientation = if angles.iter().all(Option::is_some) {
        Some(
            angles
                .iter()
                .map(|a| a.expect("all some"))
                .collect::<Vec<_>>(),
        )
    } else if angles[3..].iter().any(Option::is_some) {
        // A measured orientation needs all three angles, and the commanded ones.
        let missing = ANGLES
            .iter()
            .zip(&angles)
            .find(|(_, a)| a.is_none())
            .map(|(n, _)| *n)
            .expect("not all present");
        return Err(Iso9283Error::MissingColumn(missing));
    } else {
        None
    };

    let mut rows = Vec::new();
    let mut record = csv::StringRecord::new();
    while reader.read_record(&mut record).map_err(csv_error)? {
        if rows.len() == MAX_ROWS {
            return Err(Iso9283Error::TooManyRows {
                rows: rows.len() + 1,
            });
        }
        let line = record.position().map_or(0, |p| p.line());
        let field = |i: usize| record.get(i).unwrap_or("");
        let number = |i: usize, column: &'static str| -> Result<f64, Iso9283Error> {
            let text = field(i);
            match text.parse::<f64>() {
                // No robot's position reaches a kilometre nor its angle 1e6 degrees:
                // beyond, the deviations and their squares stop meaning anything.
                Ok(v) if v.abs() <= MAX_FIELD => Ok(v),
                Ok(v) if v.is_finite() => Err(Iso9283Error::Field {
                    line,
                    column,
                    text: text.to_string(),
                    why: "is beyond any robot's workspace (1e6 mm, 1e6 degrees)",
                }),
                _ => Err(Iso9283Error::Field {
                    line,
                    column,
                    text: text.to_string(),
                    why: "is not a finite number",
                }),
            }
        };
        let triple = |cols: &[usize], names: [&'static str; 3]| -> Result<[f64; 3], Iso9283Error> {
            Ok([
                number(cols[0], names[0])?,
                number(cols[1], names[1])?,
                number(cols[2], names[2])?,
            ])
        };
        let name = field(position);
        if name.is_empty() {
            return Err(Iso9283Error::Field {
                line,
                column: "position",
                text: String::new(),
                why: "is empty: every row names its position",
            });
        }
        let cycle_number = field(cycle)
            .parse::<u32>()
            .map_err(|_| Iso9283Error::Field {
                line,
                column: "cycle",
                text: field(cycle).to_string(),
                // Digits that do not fit are a whole number still, only too large.
                why: if is_digits(field(cycle)) {
                    "is out of range: a cycle is a whole number up to 4294967295"
                } else {
                    "is not a whole number"
                },
            })?;
        let orientation_abc_deg = match &orientation {
            Some(cols) => Some([
                triple(&cols[..3], ["a", "b", "c"])?,
                triple(&cols[3..], ["ma", "mb", "mc"])?,
            ]),
            None => None,
        };
        rows.push(CycleRow {
            position: name.to_string(),
            cycle: cycle_number,
            commanded_mm: triple(&commanded, ["x", "y", "z"])?,
            attained_mm: triple(&attained, ["mx", "my", "mz"])?,
            orientation_abc_deg,
            line,
        });
    }
    if rows.is_empty() {
        return Err(Iso9283Error::Empty);
    }
    Ok(rows)
}

/// The pose characteristics of one position (ISO 9283 7.2.1, 7.2.2). Lengths mm, angles
/// degrees; `rp_*_deg` are the half-widths `3 S` of the `±` intervals.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PoseCharacteristics {
    /// The position's name.
    pub name: String,
    /// The cycles measured.
    pub n: usize,
    /// The commanded position, mm.
    pub commanded_mm: [f64; 3],
    /// The barycentre of the attained positions, mm.
    pub barycentre_mm: [f64; 3],
    /// Position accuracy AP_P, mm.
    pub ap_p_mm: f64,
    /// AP_x = x̄ − x_c, mm.
    pub ap_x_mm: f64,
    /// AP_y, mm.
    pub ap_y_mm: f64,
    /// AP_z, mm.
    pub ap_z_mm: f64,
    /// Orientation accuracy AP_a = ā − a_c, degrees, `a` about the base x axis
    /// ([`ORIENTATION_CONVENTION`]), when orientations were measured.
    pub ap_a_deg: Option<f64>,
    /// AP_b, degrees.
    pub ap_b_deg: Option<f64>,
    /// AP_c, degrees.
    pub ap_c_deg: Option<f64>,
    /// Position repeatability RP_l = l̄ + 3 S_l, mm.
    pub rp_l_mm: f64,
    /// l̄, the mean distance to the barycentre, mm.
    pub l_mean_mm: f64,
    /// S_l, mm.
    pub s_l_mm: f64,
    /// Orientation repeatability RP_a = ±3 S_a, degrees.
    pub rp_a_deg: Option<f64>,
    /// RP_b, degrees.
    pub rp_b_deg: Option<f64>,
    /// RP_c, degrees.
    pub rp_c_deg: Option<f64>,
}

/// The distance characteristics between two positions the robot moves between in each
/// cycle (ISO 9283 7.4). Lengths mm; `rd_mm` is the half-width `3 S_D`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DistanceCharacteristics {
    /// The first position.
    pub from: String,
    /// The second position.
    pub to: String,
    /// Cycles measured at both.
    pub n: usize,
    /// The commanded distance D_c, mm.
    pub commanded_mm: f64,
    /// The mean attained distance D̄, mm.
    pub mean_mm: f64,
    /// Distance accuracy AD_P = D̄ − D_c, mm.
    pub ad_p_mm: f64,
    /// AD_x = D̄_x − D_cx, mm.
    pub ad_x_mm: f64,
    /// AD_y, mm.
    pub ad_y_mm: f64,
    /// AD_z, mm.
    pub ad_z_mm: f64,
    /// Distance repeatability RD = ±3 S_D, mm.
    pub rd_mm: f64,
}

/// Every characteristic of a set of measured cycles.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// Per position, in the order of their names (P1, P2, ..., P10).
    pub positions: Vec<PoseCharacteristics>,
    /// Between the pairs asked for (the standard's P2 and P4 by default), each when both
    /// were measured in at least two common cycles.
    pub distance: Vec<DistanceCharacteristics>,
    /// The convention of the orientation figures ([`ORIENTATION_CONVENTION`]), when
    /// orientation was measured.
    pub orientation_convention: Option<&'static str>,
    /// What the figures cannot say: a distance pair not measured, orientation near the
    /// convention's gimbal lock.
    pub notes: Vec<String>,
}

/// The mean and the sample standard deviation (with `n − 1`) of `values`, `n ≥ 2`.
fn mean_and_sd(values: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = values.clone().count() as f64;
    let mean = values.clone().sum::<f64>() / n;
    let ss: f64 = values.map(|v| (v - mean) * (v - mean)).sum();
    (mean, (ss / (n - 1.0)).sqrt())
}

/// An angle difference wrapped into (−180°, 180°]: an attained 179.9° against a commanded
/// −179.9° is 0.2° off, not 359.8°.
fn wrap_deg(d: f64) -> f64 {
    let w = d.rem_euclid(360.0);
    if w > 180.0 {
        w - 360.0
    } else {
        w
    }
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The rows of each position, in order of first appearance, checked: one commanded pose
/// per position, each cycle once.
fn by_position(rows: &[CycleRow]) -> Result<Vec<Vec<&CycleRow>>, Iso9283Error> {
    let mut index: HashMap<&str, usize> = HashMap::new();
    let mut groups: Vec<Vec<&CycleRow>> = Vec::new();
    for row in rows {
        let k = *index.entry(&row.position).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        if let Some(first) = groups[k].first() {
            let moved = (0..3).any(|a| {
                (first.commanded_mm[a] - row.commanded_mm[a]).abs() > SAME_COMMAND_TOLERANCE
            }) || match (first.orientation_abc_deg, row.orientation_abc_deg) {
                (Some(f), Some(r)) => {
                    (0..3).any(|a| wrap_deg(f[0][a] - r[0][a]).abs() > SAME_COMMAND_TOLERANCE)
                }
                _ => false,
            };
            if moved {
                return Err(Iso9283Error::CommandChanged {
                    position: row.position.clone(),
                    first: first.line,
                    line: row.line,
                });
            }
            if groups[k].iter().any(|r| r.cycle == row.cycle) {
                return Err(Iso9283Error::Duplicate {
                    position: row.position.clone(),
                    cycle: row.cycle,
                    line: row.line,
                });
            }
        }
        groups[k].push(row);
    }
    Ok(groups)
}

/// The pose characteristics of one position's cycles (at least two).
fn pose_characteristics(rows: &[&CycleRow]) -> PoseCharacteristics {
    let n = rows.len();
    let c = rows[0].commanded_mm;
    let bary: [f64; 3] =
        [0, 1, 2].map(|a| rows.iter().map(|r| r.attained_mm[a]).sum::<f64>() / n as f64);
    let ap = [0, 1, 2].map(|a| bary[a] - c[a]);
    let l = rows.iter().map(|r| distance(r.attained_mm, bary));
    let (l_mean_mm, s_l_mm) = mean_and_sd(l);
    let angles = rows[0].orientation_abc_deg.map(|_| {
        // The standard's a, b, c (about x, y, z) are KUKA's C, B, A.
        [2, 1, 0].map(|k| {
            // Attained minus commanded, wrapped: ā − a_c is the mean of the differences.
            let d = rows.iter().map(move |r| {
                let [commanded, attained] = r.orientation_abc_deg.expect("all rows or none");
                wrap_deg(attained[k] - commanded[k])
            });
            mean_and_sd(d)
        })
    });
    let angle = |k: usize, f: fn((f64, f64)) -> f64| angles.map(|a| f(a[k]));
    PoseCharacteristics {
        name: rows[0].position.clone(),
        n,
        commanded_mm: c,
        barycentre_mm: bary,
        ap_p_mm: (ap[0] * ap[0] + ap[1] * ap[1] + ap[2] * ap[2]).sqrt(),
        ap_x_mm: ap[0],
        ap_y_mm: ap[1],
        ap_z_mm: ap[2],
        ap_a_deg: angle(0, |(m, _)| m),
        ap_b_deg: angle(1, |(m, _)| m),
        ap_c_deg: angle(2, |(m, _)| m),
        rp_l_mm: l_mean_mm + 3.0 * s_l_mm,
        l_mean_mm,
        s_l_mm,
        rp_a_deg: angle(0, |(_, s)| 3.0 * s),
        rp_b_deg: angle(1, |(_, s)| 3.0 * s),
        rp_c_deg: angle(2, |(_, s)| 3.0 * s),
    }
}

/// The distance characteristics between two positions over their common cycles, or
/// `None` when fewer than two cycles are common.
fn distance_characteristics(
    first: &[&CycleRow],
    second: &[&CycleRow],
) -> Option<DistanceCharacteristics> {
    let pairs: Vec<(&CycleRow, &CycleRow)> = first
        .iter()
        .filter_map(|a| second.iter().find(|b| b.cycle == a.cycle).map(|b| (*a, *b)))
        .collect();
    if pairs.len() < 2 {
        return None;
    }
    let n = pairs.len() as f64;
    let (ca, cb) = (pairs[0].0.commanded_mm, pairs[0].1.commanded_mm);
    let commanded_mm = distance(ca, cb);
    let (mean_mm, s_d) = mean_and_sd(
        pairs
            .iter()
            .map(|(a, b)| distance(a.attained_mm, b.attained_mm)),
    );
    let ad_axis = |k: usize| {
        let mean = pairs
            .iter()
            .map(|(a, b)| (a.attained_mm[k] - b.attained_mm[k]).abs())
            .sum::<f64>()
            / n;
        mean - (ca[k] - cb[k]).abs()
    };
    Some(DistanceCharacteristics {
        from: pairs[0].0.position.clone(),
        to: pairs[0].1.position.clone(),
        n: pairs.len(),
        commanded_mm,
        mean_mm,
        ad_p_mm: mean_mm - commanded_mm,
        ad_x_mm: ad_axis(0),
        ad_y_mm: ad_axis(1),
        ad_z_mm: ad_axis(2),
        rd_mm: 3.0 * s_d,
    })
}

/// The characteristics of measured cycles: per position, and between the standard's
/// distance pair P2 and P4 when the cycles name both ([`characteristics_between`]).
///
/// # Errors
///
/// As [`characteristics_between`].
pub fn characteristics(rows: &[CycleRow]) -> Result<Report, Iso9283Error> {
    characteristics_between(rows, &[])
}

/// A natural order of names: `P2` before `P10`, the digits at the end compared as a
/// number.
fn name_key(name: &str) -> (&str, u64, &str) {
    let digits = name.len() - name.trim_end_matches(|c: char| c.is_ascii_digit()).len();
    let (stem, tail) = name.split_at(name.len() - digits);
    (stem, tail.parse().unwrap_or(u64::MAX), name)
}

/// The characteristics of measured cycles: per position (in the order of their names),
/// and the distance characteristics between each pair of `pairs`, or without pairs the
/// standard's P2 and P4 when both are measured. A pair not measured in two common cycles
/// is left out with a note.
///
/// # Errors
///
/// No rows, a position commanded to two poses or measured twice in a cycle, a position
/// with fewer than two cycles, a pair naming a position the cycles do not have.
pub fn characteristics_between(
    rows: &[CycleRow],
    pairs: &[(String, String)],
) -> Result<Report, Iso9283Error> {
    if rows.is_empty() {
        return Err(Iso9283Error::Empty);
    }
    let mut groups = by_position(rows)?;
    if let Some(g) = groups.iter().find(|g| g.len() < 2) {
        return Err(Iso9283Error::TooFewCycles {
            position: g[0].position.clone(),
            n: g.len(),
        });
    }
    groups.sort_by(|a, b| name_key(&a[0].position).cmp(&name_key(&b[0].position)));
    let find = |name: &str| groups.iter().find(|g| g[0].position == name);
    let mut notes = Vec::new();
    let mut distance = Vec::new();
    if pairs.is_empty() {
        let (from, to) = DISTANCE_PAIR;
        match (find(from), find(to)) {
            (Some(a), Some(b)) => match distance_characteristics(a, b) {
                Some(d) => distance.push(d),
                None => notes.push(format!(
                    "{from} and {to} are measured in fewer than two common cycles: no distance \
                     characteristics"
                )),
            },
            _ => notes.push(format!(
                "no positions named {from} and {to}, the standard's distance pair: no distance \
                 characteristics (name a pair to compute them)"
            )),
        }
    }
    for (from, to) in pairs {
        let (Some(a), Some(b)) = (find(from), find(to)) else {
            let missing = if find(from).is_none() { from } else { to };
            return Err(Iso9283Error::UnknownPosition(missing.clone()));
        };
        match distance_characteristics(a, b) {
            Some(d) => distance.push(d),
            None => notes.push(format!(
                "{from} and {to} are measured in fewer than two common cycles: no distance \
                 characteristics"
            )),
        }
    }
    let positions: Vec<PoseCharacteristics> =
        groups.iter().map(|g| pose_characteristics(g)).collect();
    let oriented = rows[0].orientation_abc_deg.is_some();
    if oriented {
        let near: Vec<&str> = groups
            .iter()
            .filter(|g| {
                let b = g[0].orientation_abc_deg.expect("oriented")[0][1];
                (wrap_deg(b).abs() - 90.0).abs() < GIMBAL_MARGIN_DEG
            })
            .map(|g| g[0].position.as_str())
            .collect();
        if !near.is_empty() {
            notes.push(format!(
                "{} commanded with b within {GIMBAL_MARGIN_DEG}° of ±90°, the gimbal lock of \
                 the a, b, c convention: their a and c figures mean little; measure orientation \
                 away from it (b = 45°, say)",
                near.join(", ")
            ));
        }
    }
    Ok(Report {
        positions,
        distance,
        orientation_convention: oriented.then_some(ORIENTATION_CONVENTION),
        notes,
    })
}

/// The cycles as a compensation would have attained them, to first order: each attained
/// pose less the error `predicted` at its commanded pose (position mm, and orientation a
/// rotation vector, rad, base frame, when the rows carry orientations). On simulated data,
/// where the error field is known smooth, this is the attained pose of the compensated
/// command up to the change of the error over the correction's length; on real data it is
/// a prediction, not a measurement (docs/measure.md).
///
/// # Errors
///
/// [`Iso9283Error::Compensation`] for a row `predicted` gives no correction for, named
/// by its line.
pub fn compensated(
    rows: &[CycleRow],
    predicted: impl Fn(&CycleRow) -> Result<([f64; 3], [f64; 3]), String>,
) -> Result<Vec<CycleRow>, Iso9283Error> {
    rows.iter()
        .map(|row| {
            let (dp, dr) = predicted(row).map_err(|reason| Iso9283Error::Compensation {
                line: row.line,
                reason,
            })?;
            let mut out = row.clone();
            out.attained_mm = [0, 1, 2].map(|a| row.attained_mm[a] - dp[a]);
            if let Some([commanded, attained]) = row.orientation_abc_deg {
                let r = rotation_from_vector([-dr[0], -dr[1], -dr[2]])
                    * rotation_from_kuka_abc_deg(attained);
                out.orientation_abc_deg = Some([commanded, kuka_abc_deg_from_rotation(&r)]);
            }
            Ok(out)
        })
        .collect()
}

/// The five ISO 9283 test positions P1–P5 of a cube (centre, edge length; mm, base frame):
/// P1 the cube's centre; P2–P5 on the diagonals of the measurement plane, a tenth of the
/// diagonal's length from its corners. The plane is the diagonal plane through the cube's
/// vertical edges at (x_min, y_min) and (x_max, y_max); P2 is near its corner
/// (x_min, y_min, z_max), P3 near (x_max, y_max, z_max), P4 near (x_max, y_max, z_min),
/// P5 near (x_min, y_min, z_min).
///
/// # Errors
///
/// [`Iso9283Error::Cube`] for a side that is not positive and finite, or a centre not
/// finite.
pub fn cube_positions(centre_mm: [f64; 3], side_mm: f64) -> Result<[[f64; 3]; 5], Iso9283Error> {
    use adwi_runtime::format::MAX_COORDINATE_MM;
    if !(side_mm.is_finite() && side_mm > 0.0 && centre_mm.iter().all(|v| v.is_finite())) {
        return Err(Iso9283Error::Cube(format!(
            "a cube needs a finite centre and a positive side; {side_mm} mm given"
        )));
    }
    // Within a kilometre of the base, as a table's coordinates: the corners then stay
    // finite (a centre of 1.7e308 mm put infinities into the plan).
    let reach = centre_mm.iter().map(|v| v.abs()).fold(side_mm, f64::max) + side_mm;
    if reach > MAX_COORDINATE_MM {
        return Err(Iso9283Error::Cube(format!(
            "a cube centred at {centre_mm:?} mm with a side of {side_mm} mm reaches beyond \
             {MAX_COORDINATE_MM:e} mm from the base; give the workspace in mm"
        )));
    }
    let h = side_mm / 2.0;
    let corner = |sx: f64, sz: f64| {
        [
            centre_mm[0] + sx * h,
            centre_mm[1] + sx * h,
            centre_mm[2] + sz * h,
        ]
    };
    // The plane's corners, each with its diagonal's opposite corner.
    let corners = [
        (corner(-1.0, 1.0), corner(1.0, -1.0)),
        (corner(1.0, 1.0), corner(-1.0, -1.0)),
        (corner(1.0, -1.0), corner(-1.0, 1.0)),
        (corner(-1.0, -1.0), corner(1.0, 1.0)),
    ];
    let mut out = [centre_mm; 5];
    for (k, (c, opposite)) in corners.into_iter().enumerate() {
        out[k + 1] = [0, 1, 2].map(|a| c[a] + 0.1 * (opposite[a] - c[a]));
    }
    Ok(out)
}

/// The most cycles a cube plan writes.
pub const MAX_CYCLES: u32 = 10_000;

/// A cube plan as CSV: a `#` line stating the conventions, then
/// `position,cycle,x,y,z,a,b,c`, the five positions in each of `cycles` cycles in the
/// standard's sequence P1, P5, P4, P3, P2 ([`CUBE_SEQUENCE`]), every pose at the tool
/// orientation `abc_deg` (KUKA A, B, C degrees, what the controller takes). The robot runs
/// it; the measurement adds `mx,my,mz` (and `ma,mb,mc`) and the file is read by
/// [`parse_cycles`].
///
/// # Errors
///
/// As [`cube_positions`]; [`Iso9283Error::Cube`] for no cycle or more than
/// [`MAX_CYCLES`], or a non-finite orientation.
pub fn write_cube_plan(
    centre_mm: [f64; 3],
    side_mm: f64,
    abc_deg: [f64; 3],
    cycles: u32,
) -> Result<String, Iso9283Error> {
    let positions = cube_positions(centre_mm, side_mm)?;
    if !(1..=MAX_CYCLES).contains(&cycles) {
        return Err(Iso9283Error::Cube(format!(
            "{cycles} cycles: give 1 to {MAX_CYCLES} (ISO 9283 asks for {ISO_CYCLES})"
        )));
    }
    if !abc_deg.iter().all(|v| v.is_finite()) {
        return Err(Iso9283Error::Cube("the orientation must be finite".into()));
    }
    if !abc_deg.iter().all(|v| v.abs() <= crate::MAX_ANGLE_DEG) {
        return Err(Iso9283Error::Cube(format!(
            "the orientation {abc_deg:?}° turns more than three turns ({}°); give degrees",
            crate::MAX_ANGLE_DEG
        )));
    }
    let mut out = format!(
        "# ISO 9283 cube: centre {centre_mm:?} mm, side {side_mm} mm; each cycle P1, P5, P4, \
         P3, P2; x, y, z mm, base frame; a, b, c KUKA A, B, C degrees, R = Rz(a)·Ry(b)·Rx(c) \
         (the standard's a, b, c about x, y, z are c, b, a)\nposition,cycle,x,y,z,a,b,c\n"
    );
    for cycle in 1..=cycles {
        for k in CUBE_SEQUENCE {
            let p = positions[k];
            let _ = writeln!(
                out,
                "P{},{cycle},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}",
                k + 1,
                p[0],
                p[1],
                p[2],
                abc_deg[0],
                abc_deg[1],
                abc_deg[2]
            );
        }
    }
    Ok(out)
}

/// The commanded paths of a cube for the path tests, as a command file: the line from P2
/// to P4 (a diagonal of the measurement plane), a circle about P1 in that plane of
/// diameter 80 % of the side, a small circle of a tenth of its diameter, and the rectangle
/// P2, P3, P4, P5 (docs/measure.md says which of these the standard's text was confirmed
/// for). Every segment at `speed_mm_s`; `abc_deg` the tool orientation (KUKA A, B, C) for
/// the controller.
///
/// # Errors
///
/// As [`cube_positions`]; a speed not above 0 or beyond 1e6 mm/s.
pub fn write_path_plan(
    centre_mm: [f64; 3],
    side_mm: f64,
    abc_deg: [f64; 3],
    speed_mm_s: f64,
) -> Result<String, Iso9283Error> {
    let p = cube_positions(centre_mm, side_mm)?;
    if !(speed_mm_s > 0.0 && speed_mm_s <= adwi_runtime::format::MAX_COORDINATE_MM) {
        return Err(Iso9283Error::Cube(format!(
            "a path speed of {speed_mm_s} mm/s: give mm/s above 0"
        )));
    }
    let v = |a: [f64; 3]| nalgebra::Vector3::from(a);
    let centre = v(p[0]);
    // The measurement plane: vertical, along the horizontal diagonal (1, 1, 0)/√2.
    let across = nalgebra::Vector3::new(1.0, 1.0, 0.0).normalize();
    let up = nalgebra::Vector3::z();
    let mut out = format!(
        "# ISO 9283 path test: cube centre {centre_mm:?} mm, side {side_mm} mm; x, y, z and vx, \
         vy, vz mm, base frame; speed mm/s; a, b, c KUKA A, B, C degrees, \
         R = Rz(a)·Ry(b)·Rx(c)\npath,kind,x,y,z,vx,vy,vz,speed,a,b,c\n"
    );
    let abc = format!("{:.4},{:.4},{:.4}", abc_deg[0], abc_deg[1], abc_deg[2]);
    let mut row =
        |path: &str, kind: &str, q: nalgebra::Vector3<f64>, via: Option<nalgebra::Vector3<f64>>| {
            let via = via.map_or(",,".to_string(), |w| {
                format!("{:.4},{:.4},{:.4}", w.x, w.y, w.z)
            });
            let speed = if kind == "start" {
                String::new()
            } else {
                format!("{speed_mm_s}")
            };
            out.push_str(&format!(
                "{path},{kind},{:.4},{:.4},{:.4},{via},{speed},{abc}\n",
                q.x, q.y, q.z
            ));
        };
    row("line", "start", v(p[1]), None);
    row("line", "line", v(p[3]), None);
    for (name, radius) in [("circle", 0.4 * side_mm), ("small_circle", 0.04 * side_mm)] {
        let top = centre + up * radius;
        row(name, "start", top, None);
        row(
            name,
            "arc",
            centre - up * radius,
            Some(centre + across * radius),
        );
        row(name, "arc", top, Some(centre - across * radius));
    }
    row("rectangle", "start", v(p[1]), None);
    for k in [2, 3, 4, 1] {
        row("rectangle", "line", v(p[k]), None);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(position: &str, cycle: u32, commanded: [f64; 3], attained: [f64; 3]) -> CycleRow {
        CycleRow {
            position: position.into(),
            cycle,
            commanded_mm: commanded,
            attained_mm: attained,
            orientation_abc_deg: None,
            line: 0,
        }
    }

    /// Three cycles worked by hand.
    ///
    /// P1 commanded at (0, 0, 0), attained at (1, 0, 0), (0, 1, 0), (2, 2, 3):
    /// barycentre (1, 1, 1), so AP_x = AP_y = AP_z = 1 and AP_P = √3 = 1.732051.
    /// Distances to the barycentre: l_1 = |(0, −1, −1)| = √2, l_2 = |(−1, 0, −1)| = √2,
    /// l_3 = |(1, 1, 2)| = √6. l̄ = (2√2 + √6)/3 = (2.828427 + 2.449490)/3 = 1.759306.
    /// S_l² = ((√2 − l̄)² · 2 + (√6 − l̄)²)/2 = (0.119089 · 2 + 0.476354)/2 = 0.357266,
    /// S_l = 0.597717; RP_l = l̄ + 3 S_l = 1.759306 + 1.793151 = 3.552457.
    ///
    /// P2 commanded at (100, 0, 0), attained at (101, 0, 0), (100, 1, 0), (102, 2, 3):
    /// every attained P2 − P1 is (100, 0, 0), so D_j = 100 = D_c: AD_P = 0, RD = 0; per
    /// axis D_x = 100 = D_cx, D_y = D_z = 0: AD_x = AD_y = AD_z = 0.
    #[test]
    fn the_characteristics_are_those_worked_by_hand() {
        let c1 = [0.0, 0.0, 0.0];
        let c2 = [100.0, 0.0, 0.0];
        let rows = vec![
            row("P1", 1, c1, [1.0, 0.0, 0.0]),
            row("P2", 1, c2, [101.0, 0.0, 0.0]),
            row("P1", 2, c1, [0.0, 1.0, 0.0]),
            row("P2", 2, c2, [100.0, 1.0, 0.0]),
            row("P1", 3, c1, [2.0, 2.0, 3.0]),
            row("P2", 3, c2, [102.0, 2.0, 3.0]),
        ];
        let report = characteristics_between(&rows, &[("P1".into(), "P2".into())]).unwrap();
        let p1 = &report.positions[0];
        assert_eq!(p1.n, 3);
        assert_eq!([p1.ap_x_mm, p1.ap_y_mm, p1.ap_z_mm], [1.0, 1.0, 1.0]);
        assert!((p1.ap_p_mm - 3f64.sqrt()).abs() < 1e-12);
        assert!((p1.l_mean_mm - 1.759306).abs() < 1e-6, "{}", p1.l_mean_mm);
        assert!((p1.s_l_mm - 0.597717).abs() < 1e-6, "{}", p1.s_l_mm);
        assert!((p1.rp_l_mm - 3.552457).abs() < 1e-6, "{}", p1.rp_l_mm);
        assert_eq!(p1.ap_a_deg, None);
        let d = &report.distance[0];
        assert_eq!((d.from.as_str(), d.to.as_str(), d.n), ("P1", "P2", 3));
        assert!((d.commanded_mm - 100.0).abs() < 1e-12);
        for v in [d.ad_p_mm, d.ad_x_mm, d.ad_y_mm, d.ad_z_mm, d.rd_mm] {
            assert!(v.abs() < 1e-12, "{d:?}");
        }
    }

    /// Distances worked by hand: P1 commanded at 0, P2 at (10, 0, 0); attained
    /// P2 − P1 = (10.2, 0, 0), (9.9, 0, 0), (10.2, 0.3, 0.4) in cycles 1, 2, 3.
    /// D_j = 10.2, 9.9, √(10.2² + 0.3² + 0.4²) = √104.29 = 10.212247.
    /// D̄ = 30.312247/3 = 10.104082: AD_P = 0.104082.
    /// D_x = 10.2, 9.9, 10.2: D̄_x = 10.1, AD_x = 0.1; D̄_y = 0.1, AD_y = 0.1;
    /// D̄_z = 0.4/3 = 0.133333, AD_z = 0.133333.
    /// S_D² = ((10.2 − D̄)² + (9.9 − D̄)² + (10.212247 − D̄)²)/2
    ///      = (0.009200 + 0.041650 + 0.011700)/2 = 0.031275: RD = 3 · 0.176847 = 0.530540.
    /// Orientation of P1: commanded KUKA A = 179.9° (about z: the standard's c), attained
    /// −179.9°, 179.8°, −179.7°: differences (wrapped) 0.2, −0.1, 0.4: AP_c = 0.5/3 =
    /// 0.166667°; S_c² = (0.033333² + 0.266667² + 0.233333²)/2 = 0.063333,
    /// RP_c = 3 · 0.251661 = 0.754983°.
    #[test]
    fn distances_and_wrapped_angles_are_those_worked_by_hand() {
        let c1 = [0.0, 0.0, 0.0];
        let c2 = [10.0, 0.0, 0.0];
        let oriented = |mut r: CycleRow, a: f64| {
            r.orientation_abc_deg = Some([[179.9, 0.0, 0.0], [a, 0.0, 0.0]]);
            r
        };
        let rows = vec![
            oriented(row("P1", 1, c1, [0.0; 3]), -179.9),
            oriented(row("P2", 1, c2, [10.2, 0.0, 0.0]), 179.9),
            oriented(row("P1", 2, c1, [0.0; 3]), 179.8),
            oriented(row("P2", 2, c2, [9.9, 0.0, 0.0]), 179.9),
            oriented(row("P1", 3, c1, [0.0; 3]), -179.7),
            oriented(row("P2", 3, c2, [10.2, 0.3, 0.4]), 179.9),
        ];
        let report = characteristics_between(&rows, &[("P1".into(), "P2".into())]).unwrap();
        let d = &report.distance[0];
        assert!((d.mean_mm - 10.104082).abs() < 1e-6, "{d:?}");
        assert!((d.ad_p_mm - 0.104082).abs() < 1e-6, "{d:?}");
        assert!((d.ad_x_mm - 0.1).abs() < 1e-9, "{d:?}");
        assert!((d.ad_y_mm - 0.1).abs() < 1e-9, "{d:?}");
        assert!((d.ad_z_mm - 0.4 / 3.0).abs() < 1e-9, "{d:?}");
        assert!((d.rd_mm - 0.530540).abs() < 1e-5, "{d:?}");
        let p1 = &report.positions[0];
        assert!((p1.ap_c_deg.unwrap() - 0.166667).abs() < 1e-5, "{p1:?}");
        assert!((p1.rp_c_deg.unwrap() - 0.754983).abs() < 1e-5, "{p1:?}");
        for v in [p1.ap_a_deg, p1.rp_a_deg, p1.ap_b_deg, p1.rp_b_deg] {
            assert!(v.unwrap().abs() < 1e-12, "{p1:?}");
        }
        assert_eq!(report.orientation_convention, Some(ORIENTATION_CONVENTION));
    }

    /// The standard's a, b, c turn about x, y, z: a tool turned 0.3° about the base x
    /// axis (KUKA C, the last of A, B, C) is off in a alone, one about z (KUKA A) in c.
    #[test]
    fn orientation_figures_are_the_standards_angles_about_x_y_z() {
        let oriented = |cycle: u32, attained: [f64; 3]| CycleRow {
            orientation_abc_deg: Some([[0.0, 45.0, 0.0], attained]),
            ..row("P1", cycle, [0.0; 3], [0.0; 3])
        };
        let rows = [
            oriented(1, [0.0, 45.0, 0.3]),
            oriented(2, [0.0, 45.0, 0.3]),
            oriented(3, [0.2, 45.0, 0.3]),
            oriented(4, [0.2, 45.0, 0.3]),
        ];
        let p = characteristics(&rows).unwrap().positions[0].clone();
        assert!((p.ap_a_deg.unwrap() - 0.3).abs() < 1e-12, "{p:?}");
        assert!((p.ap_c_deg.unwrap() - 0.1).abs() < 1e-12, "{p:?}");
        assert!(p.ap_b_deg.unwrap().abs() < 1e-12, "{p:?}");
        // A rotation about x is exactly the standard's a: R = Rz(c)·Ry(b)·Rx(a).
        let r = rotation_from_kuka_abc_deg([0.0, 45.0, 0.3]);
        let iso = nalgebra::Rotation3::from_axis_angle(&nalgebra::Vector3::z_axis(), 0.0)
            * nalgebra::Rotation3::from_axis_angle(
                &nalgebra::Vector3::y_axis(),
                45f64.to_radians(),
            )
            * nalgebra::Rotation3::from_axis_angle(
                &nalgebra::Vector3::x_axis(),
                0.3f64.to_radians(),
            );
        assert!((r.matrix() - iso.matrix()).abs().max() < 1e-12);
    }

    /// The distance characteristics are those of the standard's pair P2 and P4, not of
    /// positions consecutive in the file; a cube's cycle runs P1, P5, P4, P3, P2.
    #[test]
    fn distances_are_the_standards_pair_and_the_cycle_its_sequence() {
        let text = write_cube_plan([1000.0, 0.0, 1000.0], 400.0, [0.0, 45.0, 0.0], 3).unwrap();
        let rows: Vec<String> = text
            .lines()
            .filter(|l| !l.starts_with('#'))
            .skip(1)
            .take(5)
            .map(|l| l.split(',').next().unwrap().to_string())
            .collect();
        assert_eq!(rows, ["P1", "P5", "P4", "P3", "P2"]);
        let measured = measured_as_commanded(&text);
        let report = characteristics(&parse_cycles(measured.as_bytes()).unwrap()).unwrap();
        assert_eq!(report.distance.len(), 1, "{:?}", report.distance);
        let d = &report.distance[0];
        assert_eq!((d.from.as_str(), d.to.as_str(), d.n), ("P2", "P4", 3));
        // P2 and P4 are the ends of a diagonal of the measurement plane: 80 % of the
        // cube's space diagonal apart.
        assert!(
            (d.commanded_mm - 0.8 * 400.0 * 3f64.sqrt()).abs() < 1e-3,
            "{d:?}"
        );
        let names: Vec<&str> = report.positions.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["P1", "P2", "P3", "P4", "P5"]);
        // Other cycles name their own pair; a position not measured is refused.
        let report = characteristics_between(
            &parse_cycles(measured.as_bytes()).unwrap(),
            &[("P1".into(), "P3".into())],
        )
        .unwrap();
        assert_eq!(report.distance[0].to, "P3");
        let e = characteristics_between(
            &parse_cycles(measured.as_bytes()).unwrap(),
            &[("P1".into(), "P9".into())],
        )
        .unwrap_err();
        assert_eq!(e, Iso9283Error::UnknownPosition("P9".into()));
        // At the old default 0,90,0 the a and c figures are flagged.
        let text = write_cube_plan([1000.0, 0.0, 1000.0], 400.0, [0.0, 90.0, 0.0], 2).unwrap();
        let report =
            characteristics(&parse_cycles(measured_as_commanded(&text).as_bytes()).unwrap())
                .unwrap();
        assert!(
            report.notes.iter().any(|n| n.contains("gimbal lock")),
            "{:?}",
            report.notes
        );
    }

    /// A plan with the attained columns added, attained exactly as commanded.
    fn measured_as_commanded(plan: &str) -> String {
        let mut measured = String::new();
        for line in plan.lines().filter(|l| !l.starts_with('#')) {
            let f: Vec<&str> = line.split(',').collect();
            let extra = if f[0] == "position" {
                "mx,my,mz,ma,mb,mc".to_string()
            } else {
                f[2..8].join(",")
            };
            measured.push_str(&format!("{line},{extra}\n"));
        }
        measured
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(2000))]

        /// Cycles files mutated byte by byte: read and characterised, or refused with a
        /// reason; never a panic, never a non-finite figure (the fuzz target
        /// `iso9283_cycles` runs the same check unbounded).
        #[test]
        fn hostile_cycles_are_refused_or_give_finite_figures(
            mutations in proptest::collection::vec((0.0..1.0f64, 0..3u8, 0..ALPHABET.len()), 1..8),
        ) {
            let mut bytes = CYCLES.as_bytes().to_vec();
            for (at, op, b) in mutations {
                let i = ((at * bytes.len() as f64) as usize).min(bytes.len());
                match op {
                    0 if i < bytes.len() => bytes[i] = ALPHABET[b],
                    1 => bytes.insert(i, ALPHABET[b]),
                    _ if i < bytes.len() => {
                        bytes.remove(i);
                    }
                    _ => {}
                }
            }
            if let Ok(rows) = parse_cycles(&bytes) {
                if let Ok(report) = characteristics(&rows) {
                    let json = serde_json::to_string(&report).unwrap_or_default();
                    proptest::prop_assert!(!json.contains("NaN") && !json.contains("inf"), "{}", json);
                }
            }
        }
    }

    /// Bytes that matter to the cycles reader, and some that do not.
    const ALPHABET: &[u8] = b"0123456789.-+eE,#\" \t\r\nxyzmabcPcycle\xff\x00";

    /// Two positions, three cycles each.
    const CYCLES: &str = "position,cycle,x,y,z,mx,my,mz\n\
        P1,1,1000,0,1000,1000.1,0.02,999.95\n\
        P1,2,1000,0,1000,1000.12,0.01,999.96\n\
        P1,3,1000,0,1000,1000.09,0.03,999.94\n\
        P2,1,1200,100,900,1200.2,100.01,900.05\n\
        P2,2,1200,100,900,1200.18,100.03,900.04\n\
        P2,3,1200,100,900,1200.21,100.02,900.06\n";

    #[test]
    fn a_position_beyond_any_workspace_is_refused_where_read() {
        let text = CYCLES.replace("1000.12", "1e300");
        let error = parse_cycles(text.as_bytes()).unwrap_err().to_string();
        assert!(
            error.contains("line 3") && error.contains("1e300"),
            "{error}"
        );
        assert!(error.contains("beyond any robot's workspace"), "{error}");
    }

    #[test]
    fn a_cube_plan_reads_back_as_cycles_at_the_standard_positions() {
        let text = write_cube_plan([1000.0, 0.0, 1000.0], 400.0, [0.0, 90.0, 0.0], 2).unwrap();
        assert_eq!(text.lines().count(), 2 + 10);
        // Measured exactly where commanded: the plan plus the attained columns.
        let measured = measured_as_commanded(&text);
        let rows = parse_cycles(measured.as_bytes()).unwrap();
        let report = characteristics(&rows).unwrap();
        let names: Vec<&str> = report.positions.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["P1", "P2", "P3", "P4", "P5"]);
        // P2 a tenth of the space diagonal (400 √3 mm) from its corner (800, −200, 1200).
        let p2 = report.positions[1].commanded_mm;
        assert!((distance(p2, [800.0, -200.0, 1200.0]) - 40.0 * 3f64.sqrt()).abs() < 1e-3);
        assert_eq!(report.positions[0].commanded_mm, [1000.0, 0.0, 1000.0]);
        for p in &report.positions {
            assert!(p.ap_p_mm < 1e-9 && p.rp_l_mm < 1e-9, "{p:?}");
        }
    }

    #[test]
    fn malformed_files_are_refused_with_their_line() {
        let e = parse_cycles(b"position,cycle,x,y,z,mx,my\nP1,1,0,0,0,0,0\n").unwrap_err();
        assert_eq!(e, Iso9283Error::MissingColumn("mz"));
        let rows = parse_cycles(b"position,cycle,x,y,z,a,b,c,mx,my,mz\nP1,1,0,0,0,0,90,0,0,0,0\n")
            .unwrap();
        assert_eq!(rows[0].orientation_abc_deg, None);
        let e = parse_cycles(b"position,cycle,x,y,z,mx,my,mz,ma,mb,mc\nP1,1,0,0,0,0,0,0,0,0,0\n")
            .unwrap_err();
        assert_eq!(e, Iso9283Error::MissingColumn("a"));
        let e = parse_cycles(b"position,cycle,x,y,z,mx,my,mz\nP1,1,0,0,0,0,0,nan\n").unwrap_err();
        assert!(
            matches!(
                e,
                Iso9283Error::Field {
                    line: 2,
                    column: "mz",
                    ..
                }
            ),
            "{e}"
        );
        let e = parse_cycles(b"position,cycle,x,y,z,mx,my,mz\nP1,1.5,0,0,0,0,0,0\n").unwrap_err();
        assert!(
            matches!(
                e,
                Iso9283Error::Field {
                    column: "cycle",
                    ..
                }
            ),
            "{e}"
        );
        let text = b"position,cycle,x,y,z,mx,my,mz\nP1,1,0,0,0,0,0,0\nP1,1,0,0,0,0,0,0\n";
        let e = characteristics(&parse_cycles(text).unwrap()).unwrap_err();
        assert!(matches!(e, Iso9283Error::Duplicate { line: 3, .. }), "{e}");
        let text = b"position,cycle,x,y,z,mx,my,mz\nP1,1,0,0,0,0,0,0\nP1,2,1,0,0,0,0,0\n";
        let e = characteristics(&parse_cycles(text).unwrap()).unwrap_err();
        assert!(
            matches!(
                e,
                Iso9283Error::CommandChanged {
                    first: 2,
                    line: 3,
                    ..
                }
            ),
            "{e}"
        );
        let text = b"position,cycle,x,y,z,mx,my,mz\nP1,1,0,0,0,0,0,0\n";
        let e = characteristics(&parse_cycles(text).unwrap()).unwrap_err();
        assert!(matches!(e, Iso9283Error::TooFewCycles { n: 1, .. }), "{e}");
        assert!(cube_positions([0.0; 3], -1.0).is_err());
        assert!(write_cube_plan([0.0; 3], 1.0, [0.0; 3], 0).is_err());
    }

    /// A compensation that predicts each row's error exactly leaves only the spread.
    #[test]
    fn compensating_the_mean_error_leaves_the_repeatability() {
        let c = [0.0; 3];
        let rows = vec![
            row("P1", 1, c, [1.0, 0.0, 0.0]),
            row("P1", 2, c, [1.2, 0.0, 0.0]),
            row("P1", 3, c, [0.8, 0.0, 0.0]),
        ];
        let before = characteristics(&rows).unwrap().positions[0].clone();
        let after = compensated(&rows, |_| Ok(([1.0, 0.0, 0.0], [0.0; 3]))).unwrap();
        let after = characteristics(&after).unwrap().positions[0].clone();
        assert!((before.ap_p_mm - 1.0).abs() < 1e-12);
        assert!(after.ap_p_mm < 1e-12);
        assert!((before.rp_l_mm - after.rp_l_mm).abs() < 1e-12);
        let e = compensated(&rows, |_| Err("outside the table".into())).unwrap_err();
        assert!(matches!(e, Iso9283Error::Compensation { .. }));
    }

    /// A centre or side beyond a kilometre would put infinities in the plan (a centre of
    /// 1.7e308 mm did); an orientation beyond three turns is a typing error.
    #[test]
    fn cubes_and_orientations_beyond_any_workspace_are_refused() {
        for (centre, side) in [
            ([1.7e308, 0.0, 0.0], 100.0),
            ([0.0, 0.0, 0.0], 1e300),
            ([999_990.0, 0.0, 0.0], 100.0),
        ] {
            let e = write_cube_plan(centre, side, [0.0, 90.0, 0.0], 1).unwrap_err();
            assert!(e.to_string().contains("1e6 mm"), "{e}");
        }
        let e = write_cube_plan([1000.0, 0.0, 1000.0], 400.0, [0.0, 1e300, 0.0], 1).unwrap_err();
        assert!(e.to_string().contains("three turns"), "{e}");
        let text = write_cube_plan([1000.0, 0.0, 1000.0], 400.0, [0.0, 720.0, 0.0], 1).unwrap();
        assert!(!text.contains("inf") && !text.contains("NaN"), "{text}");
    }

    /// Digits too many for a cycle number are out of range, not "not a whole number".
    #[test]
    fn a_cycle_number_too_large_is_out_of_range() {
        let header = "position,cycle,x,y,z,mx,my,mz\n";
        for (cycle, why) in [
            ("5000000000", "is out of range"),
            ("-1", "is out of range"),
            ("1.5", "is not a whole number"),
            ("one", "is not a whole number"),
        ] {
            let text = format!("{header}P1,{cycle},0,0,0,0,0,0\n");
            let e = parse_cycles(text.as_bytes()).unwrap_err();
            assert!(e.to_string().contains(why), "{cycle}: {e}");
        }
    }
}
