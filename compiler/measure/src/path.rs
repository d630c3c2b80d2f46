//! ISO 9283:1998 path characteristics (clause 8) from a tracker stream.
//!
//! The robot runs a commanded path (a line, a circle, a rectangle in the cube's plane) cycle
//! after cycle while a laser tracker records where the TCP is, point after point with a
//! timestamp. This module reduces that stream to the standard's path figures
//! (docs/measure.md gives every formula with its clause):
//!
//! - path accuracy `AT_P` and repeatability `RT_P`: in each of `m` planes normal to the
//!   commanded path, the `n` cycles' crossings have a barycentre; `AT_P` is the largest
//!   distance of a barycentre to the commanded point, `RT_P` the largest `l̄ + 3 S_l` of
//!   the crossings about their barycentre;
//! - cornering round-off `CR` (the corner point's distance to the attained path) and
//!   cornering overshoot `CO` (how far the attained path runs past the outgoing side after
//!   the corner), per corner;
//! - path velocity accuracy `AV`, repeatability `RV` and fluctuation `FV`, against the
//!   commanded speed along the path's constant-speed part.
//!
//! Cycles are taken from a `cycle` column, or found in the stream: each motion between two
//! standstills that starts at the path's start, ends at its end and follows it is a cycle.
//!
//! A point's place along the path (its arc length `s`) is the nearest point of the path,
//! searched near the previous point's so that a closed path's end is not taken for its
//! start: on a line this is the normal plane the point lies in, on an arc the plane through
//! the arc's axis, as the standard's normal planes are.

use std::io::{BufRead, BufReader, Read, Seek};
use std::ops::Range;
use std::path::Path;

use nalgebra::Vector3;
use serde::Serialize;

type V3 = Vector3<f64>;

/// The most rows a stream may hold: a tracker at 1 kHz for 33 minutes. Larger streams are
/// refused with their count before any is read (split them per path).
pub const MAX_STREAM_ROWS: u64 = 2_000_000;

/// The most rows a command file may hold.
pub const MAX_COMMAND_ROWS: u64 = 10_000;

/// The most segments of one path: the standard's have one to four; a point is tracked
/// along the path by projecting it on the segments near its predecessor's, at most these.
pub const MAX_SEGMENTS: usize = 1_000;

/// The cycles the standard asks for per path characteristic.
pub const ISO_PATH_CYCLES: usize = 10;

/// The normal planes per path at which accuracy and repeatability are evaluated, evenly
/// spaced between 1 % and 99 % of its length.
pub const PLANES: usize = 1000;

/// A cycle starts and ends within this of the path's start and end (mm).
pub const END_TOLERANCE_MM: f64 = 10.0;

/// The robot stands still when it moves less than [`STILL_MM`] over this time (s).
pub const STILL_WINDOW_S: f64 = 0.1;

/// See [`STILL_WINDOW_S`] (mm): 5 mm/s.
pub const STILL_MM: f64 = 0.5;

/// The speed is the displacement over this time, centred on each point (s): tracker noise
/// of 0.01 mm makes 0.3 mm/s of speed noise over it, where 1 ms would make 14 mm/s.
pub const VELOCITY_WINDOW_S: f64 = 0.05;

/// A vertex where the path turns by more than this (degrees) is a corner.
const CORNER_DEG: f64 = 1.0;

/// The stretch about a corner where CR and CO are measured and which the accuracy and
/// velocity figures leave out: this fraction of the shorter side at the corner.
pub const CORNER_ZONE: f64 = 0.1;

/// Velocity is measured between these fractions of the path's length (acceleration and
/// deceleration left out).
const VELOCITY_SPAN: (f64, f64) = (0.1, 0.9);

/// The largest magnitude of a coordinate (mm), a speed (mm/s) or a time (s).
const MAX_FIELD: f64 = adwi_runtime::format::MAX_COORDINATE_MM;
const MAX_TIME_S: f64 = 1e9;

/// Why a command or a stream cannot be read or reduced.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PathError {
    /// The file cannot be read.
    #[error("cannot read {file}: {reason}")]
    Io {
        /// The file.
        file: String,
        /// Why.
        reason: String,
    },
    /// A field that is not what its column holds.
    #[error("{file}:{line}:{column} (column '{name}'): {why}")]
    Field {
        /// The file.
        file: String,
        /// The line (1-based).
        line: u64,
        /// The field's place in the row (1-based).
        column: usize,
        /// The column's name.
        name: String,
        /// What is wrong.
        why: String,
    },
    /// A row that is wrong as a whole.
    #[error("{file}:{line}: {why}")]
    Row {
        /// The file.
        file: String,
        /// The line.
        line: u64,
        /// What is wrong.
        why: String,
    },
    /// A column the format needs.
    #[error("{file}: the header has no column '{name}' (needs {needs})")]
    MissingColumn {
        /// The file.
        file: String,
        /// The column.
        name: &'static str,
        /// The format's columns.
        needs: &'static str,
    },
    /// More rows than the format allows, counted before any is read.
    #[error("{file}: {rows} rows, more than {max}: split the stream per path or per run")]
    TooManyRows {
        /// The file.
        file: String,
        /// Its rows.
        rows: u64,
        /// The limit.
        max: u64,
    },
    /// A stream that cannot be reduced, and why.
    #[error("{0}")]
    Refused(String),
}

/// One segment of a commanded path.
#[derive(Debug, Clone, PartialEq)]
enum Geometry {
    Line {
        start: V3,
        end: V3,
    },
    /// An arc about `centre` of `radius` from `centre + radius·u` turning towards `w` by
    /// `sweep_rad`.
    Arc {
        centre: V3,
        radius: f64,
        u: V3,
        w: V3,
        sweep_rad: f64,
    },
}

impl Geometry {
    fn length(&self) -> f64 {
        match self {
            Geometry::Line { start, end } => (end - start).norm(),
            Geometry::Arc {
                radius, sweep_rad, ..
            } => radius * sweep_rad,
        }
    }

    /// The point at arc length `s` from the segment's start (clamped).
    fn point(&self, s: f64) -> V3 {
        match self {
            Geometry::Line { start, end } => {
                let l = (end - start).norm();
                start + (end - start) * (s / l).clamp(0.0, 1.0)
            }
            Geometry::Arc {
                centre,
                radius,
                u,
                w,
                sweep_rad,
            } => {
                let t = (s / radius).clamp(0.0, *sweep_rad);
                centre + (u * t.cos() + w * t.sin()) * *radius
            }
        }
    }

    /// The unit direction of motion at arc length `s`.
    fn tangent(&self, s: f64) -> V3 {
        match self {
            Geometry::Line { start, end } => (end - start).normalize(),
            Geometry::Arc {
                radius,
                u,
                w,
                sweep_rad,
                ..
            } => {
                let t = (s / radius).clamp(0.0, *sweep_rad);
                w * t.cos() - u * t.sin()
            }
        }
    }

    /// The nearest point of the segment to `p`: its arc length and distance.
    fn project(&self, p: &V3) -> (f64, f64) {
        match self {
            Geometry::Line { start, end } => {
                let d = end - start;
                let l = d.norm();
                let t = ((p - start).dot(&d) / (l * l)).clamp(0.0, 1.0);
                (t * l, (start + d * t - p).norm())
            }
            Geometry::Arc {
                centre,
                radius,
                u,
                w,
                sweep_rad,
            } => {
                let q = p - centre;
                let t = q.dot(w).atan2(q.dot(u)).rem_euclid(std::f64::consts::TAU);
                if t <= *sweep_rad {
                    let s = t * radius;
                    (s, (self.point(s) - p).norm())
                } else {
                    let l = self.length();
                    let (to_start, to_end) =
                        ((self.point(0.0) - p).norm(), (self.point(l) - p).norm());
                    if to_start <= to_end {
                        (0.0, to_start)
                    } else {
                        (l, to_end)
                    }
                }
            }
        }
    }
}

/// One segment of a commanded path, with its commanded speed.
#[derive(Debug, Clone, PartialEq)]
struct Segment {
    geometry: Geometry,
    speed_mm_s: Option<f64>,
}

/// A commanded path: segments end to end, read from a command file ([`parse_command`]).
#[derive(Debug, Clone, PartialEq)]
pub struct CommandPath {
    /// The path's name (`line`, `circle`, `rectangle`, or any).
    pub name: String,
    segments: Vec<Segment>,
    /// Each segment's start, arc length from the path's start (mm).
    starts_mm: Vec<f64>,
    /// The path's length (mm).
    pub length_mm: f64,
}

/// A corner of a path: where one segment ends and the next starts in another direction.
#[derive(Debug, Clone, Copy)]
struct Corner {
    s: f64,
    point: V3,
    incoming: V3,
    outgoing: V3,
    zone: f64,
}

impl CommandPath {
    fn segment_at(&self, s: f64) -> usize {
        self.starts_mm
            .partition_point(|&a| a <= s)
            .saturating_sub(1)
    }

    /// The commanded point at arc length `s` (mm).
    pub fn point_at(&self, s: f64) -> [f64; 3] {
        let i = self.segment_at(s);
        let p = self.segments[i].geometry.point(s - self.starts_mm[i]);
        [p.x, p.y, p.z]
    }

    fn point_v(&self, s: f64) -> V3 {
        let i = self.segment_at(s);
        self.segments[i].geometry.point(s - self.starts_mm[i])
    }

    fn start(&self) -> V3 {
        self.segments[0].geometry.point(0.0)
    }

    fn end(&self) -> V3 {
        let last = &self.segments[self.segments.len() - 1].geometry;
        last.point(last.length())
    }

    /// The interior vertices where the direction turns by more than [`CORNER_DEG`].
    fn corners(&self) -> Vec<Corner> {
        let mut out = Vec::new();
        for i in 1..self.segments.len() {
            let before = &self.segments[i - 1].geometry;
            let after = &self.segments[i].geometry;
            let incoming = before.tangent(before.length());
            let outgoing = after.tangent(0.0);
            if incoming.dot(&outgoing).clamp(-1.0, 1.0).acos() > CORNER_DEG.to_radians() {
                out.push(Corner {
                    s: self.starts_mm[i],
                    point: after.point(0.0),
                    incoming,
                    outgoing,
                    zone: CORNER_ZONE * before.length().min(after.length()),
                });
            }
        }
        out
    }

    /// Whether arc length `s` lies in a corner's zone.
    fn near_corner(corners: &[Corner], s: f64) -> bool {
        corners.iter().any(|c| (s - c.s).abs() <= c.zone)
    }

    /// The arc length of `p`'s nearest point on the segments within `window` mm of
    /// `s_prev` (preferring a point itself within the window), and its distance. Only those
    /// segments are looked at, so that a point costs a few projections, not one per segment.
    fn track(&self, p: &V3, s_prev: f64, window: f64) -> (f64, f64) {
        let lo = self
            .starts_mm
            .partition_point(|&a| a < s_prev - window)
            .saturating_sub(1);
        let hi = self
            .starts_mm
            .partition_point(|&a| a <= s_prev + window)
            .max(lo + 1);
        let mut best: Option<(f64, f64)> = None;
        let mut near: Option<(f64, f64)> = None;
        for (seg, start) in self.segments[lo..hi].iter().zip(&self.starts_mm[lo..hi]) {
            let (s, d) = seg.geometry.project(p);
            let s = s + start;
            if near.is_none_or(|(_, e)| d < e) {
                near = Some((s, d));
            }
            if (s - s_prev).abs() <= window && best.is_none_or(|(_, e)| d < e) {
                best = Some((s, d));
            }
        }
        best.or(near).expect("a path has a segment")
    }

    /// The arc length of each point, tracked from the path's start.
    fn progress(&self, points: &[Sample]) -> Vec<f64> {
        let window = (0.05 * self.length_mm).max(20.0);
        let mut s_prev = 0.0;
        points
            .iter()
            .map(|p| {
                let (s, _) = self.track(&V3::from(p.position_mm), s_prev, window);
                s_prev = s;
                s
            })
            .collect()
    }

    /// The length of the arc a chord of `chord` mm spans where the path is at `s`: the
    /// chord itself on a line, `2R·asin(chord/2R)` on an arc of radius `R` (the speed over
    /// a 50 ms window on a 24 mm circle at 200 mm/s would read 0.7 % slow from the chord).
    fn arc_of_chord(&self, s: f64, chord: f64) -> f64 {
        match self.segments[self.segment_at(s)].geometry {
            Geometry::Arc { radius, .. } if chord < 2.0 * radius => {
                2.0 * radius * (chord / (2.0 * radius)).asin()
            }
            _ => chord,
        }
    }

    /// The one commanded speed of the segments that end after `from` and start before
    /// `to`, when they all give the same.
    fn speed_between(&self, from: f64, to: f64) -> Option<f64> {
        let mut speed = None;
        for (seg, start) in self.segments.iter().zip(&self.starts_mm) {
            if start + seg.geometry.length() <= from || *start >= to {
                continue;
            }
            let v = seg.speed_mm_s?;
            match speed {
                None => speed = Some(v),
                Some(w) if (w - v).abs() <= 1e-9 * w => {}
                Some(_) => return None,
            }
        }
        speed
    }
}

/// A file's columns: each name's field index.
struct Header {
    names: Vec<String>,
}

impl Header {
    fn find(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|h| h == name)
    }
}

/// A field read as a finite number of at most `max` in magnitude.
fn number(
    file: &str,
    record: &csv::StringRecord,
    line: u64,
    header: &Header,
    i: usize,
    max: f64,
) -> Result<f64, PathError> {
    let text = record.get(i).unwrap_or("");
    let error = |why: String| PathError::Field {
        file: file.to_string(),
        line,
        column: i + 1,
        name: header.names[i].clone(),
        why,
    };
    match text.parse::<f64>() {
        Ok(v) if v.abs() <= max => Ok(v),
        Ok(v) if v.is_finite() => Err(error(format!(
            "'{text}' is beyond any robot's workspace ({max:e})"
        ))),
        _ => Err(error(format!("'{text}' is not a finite number"))),
    }
}

/// Counts a file's lines in bounded memory, so that a stream too large is refused with its
/// size before a row is read.
fn count_lines(reader: &mut impl Read) -> std::io::Result<u64> {
    let mut reader = BufReader::with_capacity(1 << 16, reader);
    let mut lines = 0u64;
    loop {
        let buf = reader.fill_buf()?;
        if buf.is_empty() {
            return Ok(lines);
        }
        lines += buf.iter().filter(|&&b| b == b'\n').count() as u64;
        let n = buf.len();
        reader.consume(n);
    }
}

fn csv_error(file: &str, e: &csv::Error) -> PathError {
    PathError::Row {
        file: file.to_string(),
        line: e.position().map_or(0, |p| p.line()),
        why: e.to_string(),
    }
}

fn header_of<R: Read>(file: &str, reader: &mut csv::Reader<R>) -> Result<Header, PathError> {
    let names = reader
        .headers()
        .map_err(|e| csv_error(file, &e))?
        .iter()
        .map(str::to_string)
        .collect();
    Ok(Header { names })
}

/// Opens `path` as a regular file, refusing more than `max` rows before reading one.
fn open_bounded(path: &Path, max: u64) -> Result<std::fs::File, PathError> {
    let file = path.display().to_string();
    let io = |e: std::io::Error| PathError::Io {
        file: file.clone(),
        reason: e.to_string(),
    };
    let mut f = adwi_runtime::input::open_regular(path).map_err(io)?;
    let lines = count_lines(&mut f).map_err(io)?;
    // The header is a line, and the last row may have no line end.
    if lines > max + 1 {
        return Err(PathError::TooManyRows {
            file,
            rows: lines.saturating_sub(1),
            max,
        });
    }
    f.rewind().map_err(io)?;
    Ok(f)
}

const COMMAND_COLUMNS: &str = "path, kind, x, y, z; vx, vy, vz for arcs; speed optional";

/// Reads a command file ([`parse_command`]).
///
/// # Errors
///
/// As [`parse_command`], a file that cannot be read, more than [`MAX_COMMAND_ROWS`] rows.
pub fn read_command(path: &Path) -> Result<Vec<CommandPath>, PathError> {
    let f = open_bounded(path, MAX_COMMAND_ROWS)?;
    parse_command(BufReader::new(f), &path.display().to_string())
}

/// Parses commanded paths: CSV, `#` comment lines, a header with `path, kind, x, y, z`
/// and, for arcs, `vx, vy, vz`, and optionally `speed` (mm/s); other columns (a, b, c for
/// the controller) are ignored. Each path starts with a row of kind `start` (its first
/// point); each `line` row goes straight to its point; each `arc` row goes to its point
/// along the circle through the previous point, its via point `vx, vy, vz` and its point
/// (as KUKA's CIRC). `speed` is the commanded path speed of the segment a row ends.
/// Positions mm, base frame. `file` names the source in errors.
///
/// # Errors
///
/// A missing column, a field that is not a finite number, a kind not known, a path without
/// its `start` row or without a segment, a segment of no length, an arc whose three points
/// lie on one line, a path continued after another began.
pub fn parse_command(bytes: impl Read, file: &str) -> Result<Vec<CommandPath>, PathError> {
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(bytes);
    let header = header_of(file, &mut reader)?;
    let need = |name: &'static str| {
        header.find(name).ok_or(PathError::MissingColumn {
            file: file.to_string(),
            name,
            needs: COMMAND_COLUMNS,
        })
    };
    let (path_col, kind_col) = (need("path")?, need("kind")?);
    let xyz = [need("x")?, need("y")?, need("z")?];
    let via = [header.find("vx"), header.find("vy"), header.find("vz")];
    let speed_col = header.find("speed");
    let mut paths: Vec<CommandPath> = Vec::new();
    let mut last: Option<V3> = None;
    let mut record = csv::StringRecord::new();
    while reader
        .read_record(&mut record)
        .map_err(|e| csv_error(file, &e))?
    {
        let line = record.position().map_or(0, |p| p.line());
        let row_error = |why: String| PathError::Row {
            file: file.to_string(),
            line,
            why,
        };
        let point = |cols: [usize; 3]| -> Result<V3, PathError> {
            Ok(V3::new(
                number(file, &record, line, &header, cols[0], MAX_FIELD)?,
                number(file, &record, line, &header, cols[1], MAX_FIELD)?,
                number(file, &record, line, &header, cols[2], MAX_FIELD)?,
            ))
        };
        let name = record.get(path_col).unwrap_or("");
        if name.is_empty() {
            return Err(PathError::Field {
                file: file.to_string(),
                line,
                column: path_col + 1,
                name: "path".into(),
                why: "is empty: every row names its path".into(),
            });
        }
        let kind = record.get(kind_col).unwrap_or("");
        let p = point(xyz)?;
        if kind == "start" {
            if paths.iter().any(|q| q.name == name) {
                return Err(row_error(format!("path '{name}' starts a second time")));
            }
            paths.push(CommandPath {
                name: name.to_string(),
                segments: Vec::new(),
                starts_mm: Vec::new(),
                length_mm: 0.0,
            });
            last = Some(p);
            continue;
        }
        let (Some(current), Some(from)) = (paths.last_mut(), last) else {
            return Err(row_error(format!(
                "path '{name}' has no start row before its first segment"
            )));
        };
        if current.name != name {
            return Err(row_error(format!(
                "path '{name}' continues without a start row (the path being read is '{}')",
                current.name
            )));
        }
        let geometry = match kind {
            "line" => Geometry::Line {
                start: from,
                end: p,
            },
            "arc" => {
                let [Some(vx), Some(vy), Some(vz)] = via else {
                    return Err(PathError::MissingColumn {
                        file: file.to_string(),
                        name: "vx",
                        needs: COMMAND_COLUMNS,
                    });
                };
                arc(from, point([vx, vy, vz])?, p)
                    .ok_or_else(|| row_error("the arc's start, via point and end lie on one line (a full circle is two arcs)".into()))?
            }
            _ => {
                return Err(PathError::Field {
                    file: file.to_string(),
                    line,
                    column: kind_col + 1,
                    name: "kind".into(),
                    why: format!("'{kind}' is not a kind: start, line or arc"),
                })
            }
        };
        if geometry.length() < 1e-6 {
            return Err(row_error("the segment has no length".into()));
        }
        if current.segments.len() == MAX_SEGMENTS {
            return Err(row_error(format!(
                "path '{name}' has more than {MAX_SEGMENTS} segments"
            )));
        }
        let speed_mm_s = match speed_col {
            Some(i) if !record.get(i).unwrap_or("").is_empty() => {
                let v = number(file, &record, line, &header, i, MAX_FIELD)?;
                if v <= 0.0 {
                    return Err(PathError::Field {
                        file: file.to_string(),
                        line,
                        column: i + 1,
                        name: "speed".into(),
                        why: format!("'{v}' is not a speed: give mm/s above 0"),
                    });
                }
                Some(v)
            }
            _ => None,
        };
        current.starts_mm.push(current.length_mm);
        current.length_mm += geometry.length();
        current.segments.push(Segment {
            geometry,
            speed_mm_s,
        });
        last = Some(p);
    }
    if paths.is_empty() {
        return Err(PathError::Refused(format!("{file}: no commanded path")));
    }
    if let Some(p) = paths.iter().find(|p| p.segments.is_empty()) {
        return Err(PathError::Refused(format!(
            "{file}: path '{}' has a start and no segment",
            p.name
        )));
    }
    Ok(paths)
}

/// The arc from `start` through `via` to `end`, or `None` when they lie on one line.
fn arc(start: V3, via: V3, end: V3) -> Option<Geometry> {
    let (ab, ac) = (via - start, end - start);
    let n = ab.cross(&ac);
    let n2 = n.norm_squared();
    let scale = ab.norm_squared().max(ac.norm_squared());
    if n2 <= 1e-18 * scale * scale || scale == 0.0 {
        return None;
    }
    let centre =
        start + (n.cross(&ab) * ac.norm_squared() + ac.cross(&n) * ab.norm_squared()) / (2.0 * n2);
    let radius = (start - centre).norm();
    let u = (start - centre) / radius;
    let w = n.normalize().cross(&u);
    let q = end - centre;
    let mut sweep_rad = q.dot(&w).atan2(q.dot(&u)).rem_euclid(std::f64::consts::TAU);
    if sweep_rad == 0.0 {
        sweep_rad = std::f64::consts::TAU;
    }
    Some(Geometry::Arc {
        centre,
        radius,
        u,
        w,
        sweep_rad,
    })
}

/// One tracker point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Time, s.
    pub t_s: f64,
    /// Measured position, mm, base frame.
    pub position_mm: [f64; 3],
}

/// A tracker stream: its points in time order, with each one's path and cycle when the
/// file names them.
#[derive(Debug, Clone, PartialEq)]
pub struct Stream {
    /// The file, for messages.
    pub file: String,
    /// The points.
    pub samples: Vec<Sample>,
    /// Each point's path, an index into `path_names`, when the file has a `path` column.
    pub paths: Option<Vec<u32>>,
    /// The names of the `path` column.
    pub path_names: Vec<String>,
    /// Each point's cycle, when the file has a `cycle` column.
    pub cycles: Option<Vec<u32>>,
    /// Each point's line, for messages.
    pub lines: Vec<u64>,
}

const STREAM_COLUMNS: &str = "t, x, y, z; path and cycle optional";

/// Reads a tracker stream ([`parse_stream`]), refusing more than [`MAX_STREAM_ROWS`] rows
/// with their count before any row is read.
///
/// # Errors
///
/// As [`parse_stream`], a file that cannot be read.
pub fn read_stream(path: &Path) -> Result<Stream, PathError> {
    let f = open_bounded(path, MAX_STREAM_ROWS)?;
    parse_stream(BufReader::new(f), &path.display().to_string())
}

/// Parses a tracker stream: CSV, `#` comment lines, a header with `t` (s), `x, y, z` (the
/// measured TCP position, mm, base frame), optionally `path` (which commanded path the
/// point belongs to) and `cycle` (a whole number); other columns ignored. Times strictly
/// increase.
///
/// # Errors
///
/// A missing column, a field that is not a finite number (or a whole number for `cycle`),
/// a time not after the previous row's, more than [`MAX_STREAM_ROWS`] rows, no row.
pub fn parse_stream(bytes: impl Read, file: &str) -> Result<Stream, PathError> {
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_reader(bytes);
    let header = header_of(file, &mut reader)?;
    let need = |name: &'static str| {
        header.find(name).ok_or(PathError::MissingColumn {
            file: file.to_string(),
            name,
            needs: STREAM_COLUMNS,
        })
    };
    let t_col = need("t")?;
    let xyz = [need("x")?, need("y")?, need("z")?];
    let path_col = header.find("path");
    let cycle_col = header.find("cycle");
    let mut stream = Stream {
        file: file.to_string(),
        samples: Vec::new(),
        paths: path_col.map(|_| Vec::new()),
        path_names: Vec::new(),
        cycles: cycle_col.map(|_| Vec::new()),
        lines: Vec::new(),
    };
    let mut record = csv::StringRecord::new();
    while reader
        .read_record(&mut record)
        .map_err(|e| csv_error(file, &e))?
    {
        let line = record.position().map_or(0, |p| p.line());
        if stream.samples.len() as u64 == MAX_STREAM_ROWS {
            return Err(PathError::TooManyRows {
                file: file.to_string(),
                rows: MAX_STREAM_ROWS + 1,
                max: MAX_STREAM_ROWS,
            });
        }
        let field = |i: usize, why: String| PathError::Field {
            file: file.to_string(),
            line,
            column: i + 1,
            name: header.names[i].clone(),
            why,
        };
        let t_s = number(file, &record, line, &header, t_col, MAX_TIME_S)?;
        if let Some(previous) = stream.samples.last() {
            if t_s <= previous.t_s {
                return Err(field(
                    t_col,
                    format!(
                        "{t_s} s is not after the previous row's {} s: a stream's times increase",
                        previous.t_s
                    ),
                ));
            }
        }
        let mut position_mm = [0.0; 3];
        for (a, &col) in xyz.iter().enumerate() {
            position_mm[a] = number(file, &record, line, &header, col, MAX_FIELD)?;
        }
        if let (Some(col), Some(paths)) = (path_col, stream.paths.as_mut()) {
            let name = record.get(col).unwrap_or("");
            if name.is_empty() {
                return Err(field(col, "is empty: every row names its path".into()));
            }
            let k = match stream.path_names.iter().position(|n| n == name) {
                Some(k) => k,
                None => {
                    stream.path_names.push(name.to_string());
                    stream.path_names.len() - 1
                }
            };
            paths.push(k as u32);
        }
        if let (Some(col), Some(cycles)) = (cycle_col, stream.cycles.as_mut()) {
            let text = record.get(col).unwrap_or("");
            let cycle = text.parse::<u32>().map_err(|_| {
                field(
                    col,
                    format!("'{text}' is not a whole number up to 4294967295"),
                )
            })?;
            cycles.push(cycle);
        }
        stream.samples.push(Sample { t_s, position_mm });
        stream.lines.push(line);
    }
    if stream.samples.is_empty() {
        return Err(PathError::Refused(format!("{file}: no tracker point")));
    }
    Ok(stream)
}

/// How a path's cycles were found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Split {
    /// By the stream's `cycle` column.
    CycleColumn,
    /// As the motions between standstills that follow the path from its start to its end.
    Standstills,
}

/// A path with its points and its cycles, ready to reduce.
#[derive(Debug, Clone)]
pub struct MeasuredPath {
    /// The commanded path.
    pub command: CommandPath,
    /// Its points, in time order.
    pub samples: Vec<Sample>,
    /// Each cycle's points, a range of `samples`.
    pub cycles: Vec<Range<usize>>,
    /// How the cycles were found.
    pub split: Split,
    /// Motions between standstills that were not cycles (with [`Split::Standstills`]).
    pub skipped_motions: usize,
}

/// Matches the stream's points to the commanded paths and splits each path's points into
/// cycles.
///
/// # Errors
///
/// [`PathError::Refused`] with the reason: several commanded paths and no `path` column, a
/// stream's path not commanded, cycles that cannot be found or fewer than two of them.
pub fn measured_paths(
    stream: &Stream,
    commands: &[CommandPath],
) -> Result<Vec<MeasuredPath>, PathError> {
    let mut out = Vec::new();
    let groups: Vec<(CommandPath, Vec<usize>)> = match &stream.paths {
        None => {
            if commands.len() > 1 {
                let names: Vec<&str> = commands.iter().map(|c| c.name.as_str()).collect();
                return Err(PathError::Refused(format!(
                    "the command holds {} paths ({}): {} needs a path column naming each \
                     point's, or give a command with one path",
                    commands.len(),
                    names.join(", "),
                    stream.file
                )));
            }
            vec![(commands[0].clone(), (0..stream.samples.len()).collect())]
        }
        Some(paths) => {
            let mut groups = Vec::new();
            for (k, name) in stream.path_names.iter().enumerate() {
                let Some(command) = commands.iter().find(|c| &c.name == name) else {
                    let first = paths.iter().position(|&p| p as usize == k).unwrap_or(0);
                    return Err(PathError::Refused(format!(
                        "{}:{}: path '{name}' is not in the command (it has {})",
                        stream.file,
                        stream.lines[first],
                        commands
                            .iter()
                            .map(|c| c.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )));
                };
                let rows = (0..paths.len())
                    .filter(|&i| paths[i] as usize == k)
                    .collect();
                groups.push((command.clone(), rows));
            }
            groups
        }
    };
    for (command, rows) in groups {
        let samples: Vec<Sample> = rows.iter().map(|&i| stream.samples[i]).collect();
        let (cycles, split, skipped_motions) = match &stream.cycles {
            Some(labels) => (
                cycles_by_column(stream, &rows, labels, &command.name)?,
                Split::CycleColumn,
                0,
            ),
            None => {
                let (cycles, skipped) = cycles_by_standstills(&samples, &command, &stream.file)?;
                (cycles, Split::Standstills, skipped)
            }
        };
        if cycles.len() < 2 {
            return Err(PathError::Refused(format!(
                "path '{}' has {} cycle(s) in {}: repeatability needs at least 2 (ISO 9283 asks \
                 for {ISO_PATH_CYCLES})",
                command.name,
                cycles.len(),
                stream.file
            )));
        }
        out.push(MeasuredPath {
            command,
            samples,
            cycles,
            split,
            skipped_motions,
        });
    }
    Ok(out)
}

/// The cycles of a `cycle` column: each number's rows, consecutive.
fn cycles_by_column(
    stream: &Stream,
    rows: &[usize],
    labels: &[u32],
    name: &str,
) -> Result<Vec<Range<usize>>, PathError> {
    let mut out: Vec<(u32, Range<usize>)> = Vec::new();
    for (k, &i) in rows.iter().enumerate() {
        match out.last_mut() {
            Some((label, range)) if *label == labels[i] => range.end = k + 1,
            _ => {
                if out.iter().any(|(l, _)| *l == labels[i]) {
                    return Err(PathError::Refused(format!(
                        "{}:{}: path '{name}' cycle {} resumes after another cycle: a cycle's \
                         points are consecutive",
                        stream.file, stream.lines[i], labels[i]
                    )));
                }
                out.push((labels[i], k..k + 1));
            }
        }
    }
    Ok(out.into_iter().map(|(_, r)| r).collect())
}

/// The position at time `t` (linear between points, clamped to the ends).
fn position_at(samples: &[Sample], t: f64) -> V3 {
    let k = samples.partition_point(|s| s.t_s <= t);
    if k == 0 {
        return V3::from(samples[0].position_mm);
    }
    if k == samples.len() {
        return V3::from(samples[k - 1].position_mm);
    }
    let (a, b) = (&samples[k - 1], &samples[k]);
    let f = (t - a.t_s) / (b.t_s - a.t_s);
    V3::from(a.position_mm) * (1.0 - f) + V3::from(b.position_mm) * f
}

/// The cycles found as motions between standstills that start at the path's start, end at
/// its end and follow it to its end; and how many motions were not cycles.
fn cycles_by_standstills(
    samples: &[Sample],
    path: &CommandPath,
    file: &str,
) -> Result<(Vec<Range<usize>>, usize), PathError> {
    let h = STILL_WINDOW_S / 2.0;
    let moving: Vec<bool> = samples
        .iter()
        .map(|s| {
            (position_at(samples, s.t_s + h) - position_at(samples, s.t_s - h)).norm() > STILL_MM
        })
        .collect();
    let mut motions = Vec::new();
    let mut k = 0;
    while k < samples.len() {
        if !moving[k] {
            k += 1;
            continue;
        }
        let a = k;
        while k < samples.len() && moving[k] {
            k += 1;
        }
        motions.push(a.saturating_sub(1)..(k + 1).min(samples.len()));
    }
    let (start, end) = (path.start(), path.end());
    let mut cycles = Vec::new();
    let mut first_miss: Option<String> = None;
    for m in &motions {
        let p0 = V3::from(samples[m.start].position_mm);
        let p1 = V3::from(samples[m.end - 1].position_mm);
        let reached = path
            .progress(&samples[m.clone()])
            .last()
            .copied()
            .unwrap_or(0.0);
        // Once along the path, not round a closed one several times without stopping.
        let travelled: f64 = samples[m.clone()]
            .windows(2)
            .map(|w| (V3::from(w[1].position_mm) - V3::from(w[0].position_mm)).norm())
            .sum();
        let follows = (p0 - start).norm() <= END_TOLERANCE_MM
            && (p1 - end).norm() <= END_TOLERANCE_MM
            && reached >= path.length_mm - END_TOLERANCE_MM
            && travelled <= 1.5 * path.length_mm;
        if follows {
            cycles.push(m.clone());
        } else if first_miss.is_none() {
            first_miss = Some(format!(
                "the first, from {:.3} s to {:.3} s, starts {:.1} mm from the path's start, ends \
                 {:.1} mm from its end, follows it to {:.1} of {:.1} mm and travels {:.1} mm",
                samples[m.start].t_s,
                samples[m.end - 1].t_s,
                (p0 - start).norm(),
                (p1 - end).norm(),
                reached,
                path.length_mm,
                travelled
            ));
        }
    }
    if cycles.is_empty() {
        return Err(PathError::Refused(format!(
            "{file}: no cycle of path '{}' found: {} motion(s) between standstills (less than \
             {STILL_MM} mm in {STILL_WINDOW_S} s), none starting within {END_TOLERANCE_MM} mm of \
             the path's start, ending within {END_TOLERANCE_MM} mm of its end and following it once{}; \
             the robot must stand still between cycles, or give a cycle column",
            path.name,
            motions.len(),
            first_miss.map_or(String::new(), |m| format!(" ({m})"))
        )));
    }
    let skipped = motions.len() - cycles.len();
    Ok((cycles, skipped))
}

/// The cornering figures of one corner (ISO 9283 8.4 as read here), mm.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CornerCharacteristics {
    /// The corner's number along the path, from 1.
    pub corner: usize,
    /// The commanded corner point, mm.
    pub point_mm: [f64; 3],
    /// Its arc length along the path, mm.
    pub at_mm: f64,
    /// Cornering round-off CR: the corner point's distance to the attained path, the mean
    /// over the cycles.
    pub cr_mm: f64,
    /// The largest CR of a cycle.
    pub cr_max_mm: f64,
    /// Cornering overshoot CO: how far the attained path runs beyond the outgoing side
    /// (away from the incoming one), the mean over the cycles.
    pub co_mm: f64,
    /// The largest CO of a cycle.
    pub co_max_mm: f64,
}

/// The path velocity figures (ISO 9283 8.5 as read here).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VelocityCharacteristics {
    /// The commanded path speed v_c, mm/s.
    pub commanded_mm_s: f64,
    /// The mean attained speed v̄ over the cycles, mm/s.
    pub mean_mm_s: f64,
    /// Path velocity accuracy AV = (v̄ − v_c)/v_c, percent.
    pub av_percent: f64,
    /// Path velocity repeatability RV = ±3 S_v / v_c, percent (half-width).
    pub rv_percent: f64,
    /// S_v, the standard deviation of the cycles' mean speeds, mm/s.
    pub s_v_mm_s: f64,
    /// Path velocity fluctuation FV: the largest spread (max − min) of a cycle's speed,
    /// mm/s.
    pub fv_mm_s: f64,
    /// The points over which it was measured.
    pub points: usize,
}

/// The characteristics of one path.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PathCharacteristics {
    /// The path's name.
    pub name: String,
    /// Its commanded length, mm.
    pub length_mm: f64,
    /// The cycles measured.
    pub n: usize,
    /// How they were found.
    pub split: Split,
    /// Each cycle's first and last time, s.
    pub cycle_times_s: Vec<[f64; 2]>,
    /// The normal planes at which AT and RT were evaluated.
    pub planes: usize,
    /// Path accuracy AT_P: the largest distance of a plane's barycentre to its commanded
    /// point, mm.
    pub at_p_mm: f64,
    /// The arc length where it is, mm.
    pub at_p_at_mm: f64,
    /// The mean of that distance over the planes, mm.
    pub at_mean_mm: f64,
    /// Path repeatability RT_P: the largest l̄ + 3 S_l of a plane, mm.
    pub rt_p_mm: f64,
    /// The arc length where it is, mm.
    pub rt_p_at_mm: f64,
    /// Per corner, CR and CO.
    pub corners: Vec<CornerCharacteristics>,
    /// The velocity figures, when the segments give one commanded speed.
    pub velocity: Option<VelocityCharacteristics>,
}

/// Every path's characteristics.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PathReport {
    /// Per path, in the order of the stream.
    pub paths: Vec<PathCharacteristics>,
    /// What the figures leave out.
    pub notes: Vec<String>,
}

fn mean_sd(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let ss: f64 = values.iter().map(|v| (v - mean) * (v - mean)).sum();
    (mean, (ss / (n - 1.0).max(1.0)).sqrt())
}

/// The distance of `q` to the segment from `a` to `b`.
fn point_segment(q: &V3, a: &V3, b: &V3) -> f64 {
    let d = b - a;
    let l2 = d.norm_squared();
    let t = if l2 == 0.0 {
        0.0
    } else {
        ((q - a).dot(&d) / l2).clamp(0.0, 1.0)
    };
    (a + d * t - q).norm()
}

/// Reduces measured paths to their characteristics.
///
/// # Errors
///
/// [`PathError::Refused`] for a path whose cycles cross no common normal plane.
pub fn characteristics(paths: &[MeasuredPath]) -> Result<PathReport, PathError> {
    let mut notes = Vec::new();
    let mut out = Vec::new();
    for m in paths {
        let (c, mut n) = path_characteristics(m)?;
        notes.append(&mut n);
        out.push(c);
    }
    Ok(PathReport { paths: out, notes })
}

fn path_characteristics(m: &MeasuredPath) -> Result<(PathCharacteristics, Vec<String>), PathError> {
    let path = &m.command;
    let l = path.length_mm;
    let corners = path.corners();
    let mut notes = Vec::new();
    if m.skipped_motions > 0 {
        notes.push(format!(
            "path '{}': {} motion(s) between standstills did not follow the path from its start \
             to its end and were left out",
            path.name, m.skipped_motions
        ));
    }
    if m.cycles.len() < ISO_PATH_CYCLES {
        notes.push(format!(
            "path '{}': {} cycles; ISO 9283 asks for {ISO_PATH_CYCLES}",
            path.name,
            m.cycles.len()
        ));
    }
    let progress: Vec<Vec<f64>> = m
        .cycles
        .iter()
        .map(|r| path.progress(&m.samples[r.clone()]))
        .collect();
    // The normal planes, away from the corners.
    let sigma: Vec<f64> = (0..PLANES)
        .map(|i| l * (0.01 + 0.98 * i as f64 / (PLANES - 1) as f64))
        .filter(|&s| !CommandPath::near_corner(&corners, s))
        .collect();
    // Each cycle's crossing of each plane: the first pair of points that straddles it.
    let mut crossings: Vec<Vec<Option<V3>>> = Vec::with_capacity(m.cycles.len());
    for (r, s) in m.cycles.iter().zip(&progress) {
        let pts = &m.samples[r.clone()];
        let mut at: Vec<Option<V3>> = vec![None; sigma.len()];
        for k in 0..pts.len().saturating_sub(1) {
            let (s0, s1) = (s[k], s[k + 1]);
            if s1 <= s0 {
                continue;
            }
            let first = sigma.partition_point(|&x| x < s0);
            let last = sigma.partition_point(|&x| x < s1);
            for i in first..last {
                if at[i].is_none() {
                    let f = (sigma[i] - s0) / (s1 - s0);
                    at[i] = Some(
                        V3::from(pts[k].position_mm) * (1.0 - f)
                            + V3::from(pts[k + 1].position_mm) * f,
                    );
                }
            }
        }
        crossings.push(at);
    }
    let mut planes = 0;
    let (mut at_p, mut at_p_at, mut at_sum) = (0.0f64, 0.0, 0.0);
    let (mut rt_p, mut rt_p_at) = (0.0f64, 0.0);
    for (i, &s) in sigma.iter().enumerate() {
        let Some(points): Option<Vec<V3>> = crossings.iter().map(|c| c[i]).collect() else {
            continue;
        };
        planes += 1;
        let bary = points.iter().sum::<V3>() / points.len() as f64;
        let at = (bary - path.point_v(s)).norm();
        at_sum += at;
        if at > at_p {
            (at_p, at_p_at) = (at, s);
        }
        let ls: Vec<f64> = points.iter().map(|p| (p - bary).norm()).collect();
        let (l_mean, s_l) = mean_sd(&ls);
        let rt = l_mean + 3.0 * s_l;
        if rt > rt_p {
            (rt_p, rt_p_at) = (rt, s);
        }
    }
    if planes == 0 {
        return Err(PathError::Refused(format!(
            "path '{}': no normal plane is crossed by every cycle: the attained paths do not \
             follow the commanded one",
            path.name
        )));
    }
    if planes < sigma.len() {
        notes.push(format!(
            "path '{}': {} of {} normal planes are not crossed by every cycle and were left out",
            path.name,
            sigma.len() - planes,
            sigma.len()
        ));
    }
    let corners_out = corners
        .iter()
        .enumerate()
        .map(|(k, c)| corner_characteristics(k + 1, c, m, &progress))
        .collect();
    let velocity = velocity_characteristics(m, &progress, &corners, &mut notes);
    Ok((
        PathCharacteristics {
            name: path.name.clone(),
            length_mm: l,
            n: m.cycles.len(),
            split: m.split,
            cycle_times_s: m
                .cycles
                .iter()
                .map(|r| [m.samples[r.start].t_s, m.samples[r.end - 1].t_s])
                .collect(),
            planes,
            at_p_mm: at_p,
            at_p_at_mm: at_p_at,
            at_mean_mm: at_sum / planes as f64,
            rt_p_mm: rt_p,
            rt_p_at_mm: rt_p_at,
            corners: corners_out,
            velocity,
        },
        notes,
    ))
}

fn corner_characteristics(
    number: usize,
    c: &Corner,
    m: &MeasuredPath,
    progress: &[Vec<f64>],
) -> CornerCharacteristics {
    // Outward: the incoming direction's part across the outgoing side.
    let across = c.incoming - c.outgoing * c.incoming.dot(&c.outgoing);
    let outward = across.try_normalize(1e-12).unwrap_or(c.incoming);
    let mut cr = Vec::new();
    let mut co = Vec::new();
    for (r, s) in m.cycles.iter().zip(progress) {
        let pts = &m.samples[r.clone()];
        let near: Vec<V3> = pts
            .iter()
            .zip(s)
            .filter(|(_, &s)| (s - c.s).abs() <= c.zone)
            .map(|(p, _)| V3::from(p.position_mm))
            .collect();
        if near.is_empty() {
            continue;
        }
        let round_off = if near.len() == 1 {
            (near[0] - c.point).norm()
        } else {
            near.windows(2)
                .map(|w| point_segment(&c.point, &w[0], &w[1]))
                .fold(f64::INFINITY, f64::min)
        };
        let overshoot = near
            .iter()
            .map(|p| (p - c.point).dot(&outward))
            .fold(0.0f64, f64::max);
        cr.push(round_off);
        co.push(overshoot);
    }
    let mean = |v: &[f64]| {
        if v.is_empty() {
            0.0
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    CornerCharacteristics {
        corner: number,
        point_mm: [c.point.x, c.point.y, c.point.z],
        at_mm: c.s,
        cr_mm: mean(&cr),
        cr_max_mm: cr.iter().copied().fold(0.0, f64::max),
        co_mm: mean(&co),
        co_max_mm: co.iter().copied().fold(0.0, f64::max),
    }
}

fn velocity_characteristics(
    m: &MeasuredPath,
    progress: &[Vec<f64>],
    corners: &[Corner],
    notes: &mut Vec<String>,
) -> Option<VelocityCharacteristics> {
    let path = &m.command;
    let (from, to) = (
        VELOCITY_SPAN.0 * path.length_mm,
        VELOCITY_SPAN.1 * path.length_mm,
    );
    let Some(v_c) = path.speed_between(from, to) else {
        notes.push(format!(
            "path '{}': no velocity figures: its segments give no one commanded speed",
            path.name
        ));
        return None;
    };
    let h = VELOCITY_WINDOW_S / 2.0;
    let mut means = Vec::new();
    let mut fv = 0.0f64;
    let mut points = 0;
    for (r, s) in m.cycles.iter().zip(progress) {
        let pts = &m.samples[r.clone()];
        let (t0, t1) = (pts[0].t_s, pts[pts.len() - 1].t_s);
        let speeds: Vec<f64> = pts
            .iter()
            .zip(s)
            .filter(|(p, &s)| {
                s >= from
                    && s <= to
                    && !CommandPath::near_corner(corners, s)
                    && p.t_s - h >= t0
                    && p.t_s + h <= t1
            })
            .map(|(p, &s)| {
                let chord = (position_at(pts, p.t_s + h) - position_at(pts, p.t_s - h)).norm();
                path.arc_of_chord(s, chord) / VELOCITY_WINDOW_S
            })
            .collect();
        if speeds.len() < 2 {
            continue;
        }
        points += speeds.len();
        let (mean, _) = mean_sd(&speeds);
        let (lo, hi) = speeds
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        fv = fv.max(hi - lo);
        means.push(mean);
    }
    if means.len() < 2 {
        notes.push(format!(
            "path '{}': no velocity figures: fewer than two cycles have points in the \
             constant-speed part",
            path.name
        ));
        return None;
    }
    let (v_mean, s_v) = mean_sd(&means);
    Some(VelocityCharacteristics {
        commanded_mm_s: v_c,
        mean_mm_s: v_mean,
        av_percent: 100.0 * (v_mean - v_c) / v_c,
        rv_percent: 100.0 * 3.0 * s_v / v_c,
        s_v_mm_s: s_v,
        fv_mm_s: fv,
        points,
    })
}

/// The measured paths as a compensation would have attained them, to first order: each
/// point of a cycle less the error `predicted` at its commanded point (the point of the
/// path it is tracked to). As for poses ([`crate::iso9283::compensated`]), on real data
/// this is a prediction, not a measurement.
///
/// # Errors
///
/// [`PathError::Refused`] for a commanded point `predicted` gives no correction for.
pub fn compensated(
    paths: &[MeasuredPath],
    predicted: impl Fn([f64; 3]) -> Result<[f64; 3], String>,
) -> Result<Vec<MeasuredPath>, PathError> {
    paths
        .iter()
        .map(|m| {
            let mut out = m.clone();
            for r in &m.cycles {
                let s = m.command.progress(&m.samples[r.clone()]);
                for (k, s) in r.clone().zip(s) {
                    let c = m.command.point_at(s);
                    let e = predicted(c).map_err(|why| {
                        PathError::Refused(format!(
                            "path '{}' at {:.3} s: {why}",
                            m.command.name, m.samples[k].t_s
                        ))
                    })?;
                    let p = &mut out.samples[k].position_mm;
                    for a in 0..3 {
                        p[a] -= e[a];
                    }
                }
            }
            Ok(out)
        })
        .collect()
}

/// A simulated run of a commanded path with known errors, to check the reduction against
/// (tests, and `cargo run -p adwi-measure --example path_stream`).
#[derive(Debug, Clone, PartialEq)]
pub struct Simulation {
    /// Each cycle's speed as a fraction of the commanded one (their number is the
    /// cycles'): AV and RV follow from their mean and spread.
    pub speed_factors: Vec<f64>,
    /// A speed fluctuation `amplitude·sin(2π f t)` (mm/s, Hz) on top.
    pub fluctuation: (f64, f64),
    /// Every point off by this (mm): AT_P is its part across the path.
    pub offset_mm: [f64; 3],
    /// Each cycle off across the path by `±` this in turn (mm): RT_P is this.
    pub cycle_spread_mm: f64,
    /// Arcs attained at their radius times this.
    pub radius_scale: f64,
    /// Corners cut by a tangent arc of this radius (mm): CR = r (1/cos(θ/2) − 1).
    pub fillet_mm: f64,
    /// After a corner's fillet, the path bulges outward by this over 20 mm: CO.
    pub overshoot_mm: f64,
    /// Gaussian noise per coordinate, mm.
    pub noise_mm: f64,
    /// Points per second.
    pub rate_hz: f64,
    /// Standstill before and after each cycle, s.
    pub dwell_s: f64,
    /// The noise's seed.
    pub seed: u64,
}

/// The length over which the simulated overshoot bulges, mm.
const OVERSHOOT_LENGTH_MM: f64 = 20.0;

/// A tracker stream (`t,x,y,z` CSV) of `path` run as `sim` says, at the speed of its first
/// segment (100 mm/s without one).
pub fn simulated_stream(path: &CommandPath, sim: &Simulation) -> String {
    use rand::SeedableRng;
    use rand_distr_free::normal;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(sim.seed);
    let corners = path.corners();
    let v_c = path.segments[0].speed_mm_s.unwrap_or(100.0);
    let dt = 1.0 / sim.rate_hz;
    let mut out = String::from("t,x,y,z\n");
    let mut t = 0.0;
    let across_at = |s: f64| -> V3 {
        // A unit direction across the path at s: the tangent's cross with z (or x).
        let i = path.segment_at(s);
        let d = path.segments[i].geometry.tangent(s - path.starts_mm[i]);
        d.cross(&V3::z())
            .try_normalize(1e-9)
            .unwrap_or_else(|| d.cross(&V3::x()).normalize())
    };
    let attained = |s: f64, cycle: usize| -> V3 {
        let i = path.segment_at(s);
        let seg = &path.segments[i].geometry;
        let mut p = seg.point(s - path.starts_mm[i]);
        if let Geometry::Arc { centre, .. } = seg {
            p = centre + (p - centre) * sim.radius_scale;
        }
        for c in &corners {
            let turn = c.incoming.dot(&c.outgoing).clamp(-1.0, 1.0).acos();
            let tangent = sim.fillet_mm * (turn / 2.0).tan();
            if sim.fillet_mm > 0.0 && (s - c.s).abs() <= tangent {
                let a = c.point - c.incoming * tangent;
                let inward = (c.outgoing - c.incoming).normalize();
                let centre = c.point + inward * (sim.fillet_mm / (turn / 2.0).cos());
                let (ua, ub) = (
                    (a - centre).normalize(),
                    (c.point + c.outgoing * tangent - centre).normalize(),
                );
                let f = (s - (c.s - tangent)) / (2.0 * tangent);
                let angle = ua.dot(&ub).clamp(-1.0, 1.0).acos();
                let axis = ua.cross(&ub).normalize();
                let r = nalgebra::Rotation3::from_axis_angle(
                    &nalgebra::Unit::new_normalize(axis),
                    angle * f,
                );
                p = centre + r * ua * sim.fillet_mm;
            }
            let u = (s - c.s - tangent) / OVERSHOOT_LENGTH_MM;
            if sim.overshoot_mm > 0.0 && (0.0..=1.0).contains(&u) {
                let across = c.incoming - c.outgoing * c.incoming.dot(&c.outgoing);
                p += across.normalize() * sim.overshoot_mm * (std::f64::consts::PI * u).sin();
            }
        }
        let sign = if cycle % 2 == 0 { 1.0 } else { -1.0 };
        p + V3::from(sim.offset_mm) + across_at(s) * (sign * sim.cycle_spread_mm)
    };
    let mut emit = |t: f64, p: V3, rng: &mut rand_chacha::ChaCha8Rng| {
        let n = [normal(rng), normal(rng), normal(rng)];
        out.push_str(&format!(
            "{t:.6},{:.6},{:.6},{:.6}\n",
            p.x + sim.noise_mm * n[0],
            p.y + sim.noise_mm * n[1],
            p.z + sim.noise_mm * n[2]
        ));
    };
    let (amplitude, frequency) = sim.fluctuation;
    for (cycle, factor) in sim.speed_factors.iter().enumerate() {
        let still =
            |t: &mut f64,
             s: f64,
             rng: &mut rand_chacha::ChaCha8Rng,
             emit: &mut dyn FnMut(f64, V3, &mut rand_chacha::ChaCha8Rng)| {
                let end = *t + sim.dwell_s;
                while *t < end {
                    emit(*t, attained(s, cycle), rng);
                    *t += dt;
                }
            };
        still(&mut t, 0.0, &mut rng, &mut emit);
        let t0 = t;
        loop {
            let tau = t - t0;
            let w = std::f64::consts::TAU * frequency;
            let s = v_c * factor * tau
                + if frequency > 0.0 {
                    amplitude / w * (1.0 - (w * tau).cos())
                } else {
                    0.0
                };
            if s >= path.length_mm {
                break;
            }
            emit(t, attained(s, cycle), &mut rng);
            t += dt;
        }
        still(&mut t, path.length_mm, &mut rng, &mut emit);
    }
    out
}

/// Gaussian draws without another dependency: Box–Muller.
mod rand_distr_free {
    use rand::Rng;

    /// One standard normal draw.
    pub fn normal(rng: &mut impl Rng) -> f64 {
        let u1: f64 = rng.gen_range(f64::MIN_POSITIVE..1.0);
        let u2: f64 = rng.gen();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

#[cfg(test)]
mod tests;
