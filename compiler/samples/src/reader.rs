//! The CSV reader: separators and decimal marks, the header's columns, and every row's
//! numbers converted to millimetres and radians, each problem located by file, line and
//! column.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use adwi_runtime::format::MAX_COORDINATE_MM;
use adwi_runtime::method::CONFIG_UNKNOWN;
use nalgebra::Rotation3;
use rayon::iter::{IntoParallelIterator, IntoParallelRefIterator, ParallelIterator};

use super::columns::{
    orientation_columns, AngleUnit, ColumnMap, LengthUnit, Quantity, Source, Unit, JOINT_COLUMNS,
    MAX_JOINTS,
};
use super::Joints;
use crate::plausible::number;
use crate::pose::Convention;

/// The character between fields.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delimiter {
    /// `,`
    Comma,
    /// `;`, as spreadsheets write CSV where the decimal mark is a comma.
    Semicolon,
    /// A tab.
    Tab,
}

impl Delimiter {
    /// The byte.
    pub fn byte(self) -> u8 {
        match self {
            Delimiter::Comma => b',',
            Delimiter::Semicolon => b';',
            Delimiter::Tab => b'\t',
        }
    }

    /// The name, as `--delimiter` takes it.
    pub fn name(self) -> &'static str {
        match self {
            Delimiter::Comma => "comma",
            Delimiter::Semicolon => "semicolon",
            Delimiter::Tab => "tab",
        }
    }

    fn plural(self) -> &'static str {
        match self {
            Delimiter::Comma => "commas",
            Delimiter::Semicolon => "semicolons",
            Delimiter::Tab => "tabs",
        }
    }

    const ALL: [Delimiter; 3] = [Delimiter::Comma, Delimiter::Semicolon, Delimiter::Tab];

    /// The separator of a header line: of comma, semicolon and tab, the one that occurs
    /// most often outside quotes (a comma on a tie, or when there is none).
    pub fn detect(header_line: &[u8]) -> Delimiter {
        let mut counts = [0usize; 3];
        let mut quoted = false;
        for &b in header_line {
            if b == b'"' {
                quoted = !quoted;
            } else if !quoted {
                if let Some(i) = Delimiter::ALL.iter().position(|d| d.byte() == b) {
                    counts[i] += 1;
                }
            }
        }
        // `max_by_key` keeps the last maximum: search from the back so that the first wins.
        let best = (0..3).rev().max_by_key(|&i| counts[i]).unwrap_or(0);
        Delimiter::ALL[best]
    }
}

impl FromStr for Delimiter {
    type Err = String;

    fn from_str(s: &str) -> Result<Delimiter, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "comma" | "," => Ok(Delimiter::Comma),
            "semicolon" | ";" => Ok(Delimiter::Semicolon),
            "tab" | "\t" | "\\t" => Ok(Delimiter::Tab),
            other => Err(format!(
                "unknown delimiter '{other}': comma, semicolon or tab"
            )),
        }
    }
}

/// The decimal mark of the numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decimal {
    /// `1234.56`
    Point,
    /// `1234,56`, in files separated by semicolons or tabs (or quoted).
    Comma,
}

impl Decimal {
    /// The name, as `--decimal` takes it.
    pub fn name(self) -> &'static str {
        match self {
            Decimal::Point => "point",
            Decimal::Comma => "comma",
        }
    }

    fn mark(self) -> u8 {
        match self {
            Decimal::Point => b'.',
            Decimal::Comma => b',',
        }
    }
}

impl FromStr for Decimal {
    type Err = String;

    fn from_str(s: &str) -> Result<Decimal, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "point" | "." => Ok(Decimal::Point),
            "comma" | "," => Ok(Decimal::Comma),
            other => Err(format!("unknown decimal mark '{other}': point or comma")),
        }
    }
}

/// How a file is read, beyond its column names.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// The field separator; `None` detects it from the header line
    /// ([`Delimiter::detect`]).
    pub delimiter: Option<Delimiter>,
    /// The decimal mark; `None` detects it: a point in comma-separated files, otherwise the
    /// mark of the first number that has one, after which every number must agree.
    pub decimal: Option<Decimal>,
    /// The unit of position columns whose mapping gives none.
    pub length_unit: LengthUnit,
    /// The unit of joint and orientation-angle columns whose mapping gives none (not of the
    /// rotation vector `rx,ry,rz`, which is in radians unless mapped `:deg`).
    pub angle_unit: AngleUnit,
    /// The prismatic joints of the robot the file is read for (bit `i`: joint `i + 1`):
    /// their columns, where the mapping gives no unit, are lengths in `length_unit`, not
    /// angles (the robot file says which; the reader alone cannot know).
    pub prismatic_joints: u64,
}

/// How the reader came to use a separator or a decimal mark, for messages.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Choice {
    /// Given in the options.
    Given,
    /// Detected from the header line (separators).
    Detected,
    /// Implied: a comma-separated file has decimal points.
    CommaSeparated,
    /// Detected from the first number with a decimal mark, at this line and column.
    FirstNumber {
        /// The 1-based line.
        line: u64,
        /// The 1-based column and its header name.
        column: (usize, String),
    },
}

/// What is wrong with a sample file.
#[derive(Debug, Clone, PartialEq)]
pub enum ReadErrorKind {
    /// The file could not be read.
    Io(String),
    /// The file has no header row.
    Empty,
    /// The file has a header but no sample row.
    NoSamples,
    /// The column mapping names a column the header lacks (a typo, most often).
    MappedColumnMissing(Box<MappedColumnMissing>),
    /// A required column is absent from the header.
    MissingColumn {
        /// The columns wanted.
        wanted: String,
        /// What the header holds instead, as read: its separator and how it was chosen, its
        /// column count, and the separator it seems to use when that is another.
        found: String,
    },
    /// Columns that only make sense together are partly present.
    IncompleteColumns(String),
    /// Columns that say the same thing twice (two orientation conventions on one side,
    /// errors and measured positions).
    ConflictingColumns(String),
    /// The columns of one group are in different units.
    MixedUnits(String),
    /// More joints than [`super::MAX_JOINTS`].
    TooManyJoints,
    /// A column is given twice in the header.
    DuplicateColumn(String),
    /// A row has a different number of fields from the header.
    FieldCount {
        /// Fields in the header.
        expected: u64,
        /// Fields in this row.
        found: u64,
    },
    /// A field is not a number.
    NotANumber(String),
    /// A field is NaN or infinite.
    NotFinite(String),
    /// A number's decimal mark is not the file's.
    DecimalMark {
        /// The field.
        text: String,
        /// The file's decimal mark.
        expected: Decimal,
        /// How the file's mark was chosen.
        choice: Box<Choice>,
    },
    /// A quaternion is zero.
    ZeroQuaternion,
    /// A configuration is not an integer from 0 to 254.
    BadConfig(String),
    /// A field is not UTF-8.
    NotUtf8,
    /// A position, error or measured coordinate beyond
    /// [`adwi_runtime::format::MAX_COORDINATE_MM`] (1 km), or one that overflowed in its
    /// unit's conversion: no robot's, a unit or a damaged field.
    ImplausibleCoordinate {
        /// The value, mm (infinite when the conversion overflowed).
        value_mm: f64,
    },
    /// An orientation error beyond [`crate::MAX_PLAUSIBLE_ROTATION_ERROR_DEG`]: no robot
    /// turns that far from its command.
    ImplausibleRotationError {
        /// The error's angle as read, rad (infinite when its norm overflows).
        angle_rad: f64,
        /// The unit the rotation vector `rx,ry,rz` was read in; `None` for an error
        /// computed from a nominal and a measured orientation.
        vector_unit: Option<AngleUnit>,
    },
    /// The CSV syntax is broken (e.g. an unterminated quote).
    Syntax(String),
}

/// A column the mapping names that the header lacks ([`ReadErrorKind::MappedColumnMissing`]).
#[derive(Debug, Clone, PartialEq)]
pub struct MappedColumnMissing {
    /// The canonical column mapped.
    pub name: &'static str,
    /// The column the mapping names, as compared (lower case).
    pub column: String,
    /// The header's names closest to it, closest first (at most three).
    pub closest: Vec<String>,
}

/// An error in a sample file, located by file, line and column.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadError {
    /// The file.
    pub path: PathBuf,
    /// The 1-based line, when the error has one.
    pub line: Option<u64>,
    /// The 1-based column number and its header name, when the error has one.
    pub column: Option<(usize, String)>,
    /// What is wrong.
    pub kind: ReadErrorKind,
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some((number, name)) = &self.column {
            write!(f, ":{number} (column '{name}')")?;
        }
        write!(f, ": ")?;
        match &self.kind {
            ReadErrorKind::Io(e) => write!(f, "cannot read: {e}"),
            ReadErrorKind::Empty => write!(f, "empty file: expected a header row"),
            ReadErrorKind::NoSamples => write!(f, "no sample rows after the header"),
            ReadErrorKind::MappedColumnMissing(missing) => {
                let MappedColumnMissing {
                    name,
                    column,
                    closest,
                } = missing.as_ref();
                write!(
                    f,
                    "the column mapping takes '{name}' from a column '{column}', which the \
                     header does not have"
                )?;
                match closest.as_slice() {
                    [] => Ok(()),
                    [one] => write!(f, "; the closest is '{one}'"),
                    more => write!(f, "; the closest are '{}'", more.join("', '")),
                }
            }
            ReadErrorKind::MissingColumn { wanted, found } => write!(
                f,
                "missing column {wanted} (name it in the header, or map it with --columns); {found}"
            ),
            ReadErrorKind::IncompleteColumns(what) => write!(f, "incomplete columns: {what}"),
            ReadErrorKind::ConflictingColumns(what) => write!(f, "conflicting columns: {what}"),
            ReadErrorKind::MixedUnits(what) => write!(f, "mixed units: {what}"),
            ReadErrorKind::TooManyJoints => write!(
                f,
                "more than {MAX_JOINTS} joint columns (j1..j{MAX_JOINTS} are read)"
            ),
            ReadErrorKind::DuplicateColumn(c) => write!(f, "column '{c}' appears twice"),
            ReadErrorKind::FieldCount { expected, found } => {
                write!(f, "{found} fields where the header has {expected}")
            }
            ReadErrorKind::NotANumber(v) => write!(f, "not a number: '{v}'"),
            ReadErrorKind::NotFinite(v) => write!(f, "not a finite number: '{v}'"),
            ReadErrorKind::DecimalMark {
                text,
                expected,
                choice,
            } => {
                let other = match expected {
                    Decimal::Point => "a decimal comma",
                    Decimal::Comma => "a decimal point",
                };
                write!(f, "'{text}' has {other}, but ")?;
                match choice.as_ref() {
                    Choice::Given | Choice::Detected => {
                        write!(f, "the file is read with --decimal {}", expected.name())
                    }
                    Choice::CommaSeparated => write!(
                        f,
                        "a comma-separated file has decimal points (quoted decimal commas \
                         need --decimal comma)"
                    ),
                    Choice::FirstNumber { line, column } => write!(
                        f,
                        "the file's numbers have decimal {}s, as the first one with a mark \
                         (line {line}, column {} '{}'); --decimal point or comma chooses",
                        expected.name(),
                        column.0,
                        column.1
                    ),
                }
            }
            ReadErrorKind::ZeroQuaternion => {
                write!(f, "the quaternion is zero, which is no orientation")
            }
            ReadErrorKind::BadConfig(v) => {
                write!(
                    f,
                    "configuration must be an integer from 0 to 254, found '{v}'"
                )
            }
            ReadErrorKind::NotUtf8 => write!(f, "field is not valid UTF-8"),
            ReadErrorKind::ImplausibleCoordinate { value_mm } => write!(
                f,
                "{} mm is beyond the ±{} mm (1 km) within which every robot's positions and \
                 errors lie: a unit, a misplaced column or a damaged field",
                number(*value_mm),
                number(adwi_runtime::format::MAX_COORDINATE_MM)
            ),
            ReadErrorKind::ImplausibleRotationError {
                angle_rad,
                vector_unit,
            } => {
                let limit = crate::MAX_PLAUSIBLE_ROTATION_ERROR_DEG;
                if angle_rad.to_degrees().is_finite() {
                    write!(
                        f,
                        "an orientation error of {} (a rotation of {} rad)",
                        degrees(*angle_rad),
                        number(*angle_rad)
                    )?;
                } else {
                    write!(f, "an orientation error of {} rad", number(*angle_rad))?;
                }
                write!(
                    f,
                    ", more than the {limit}° by which any robot's orientation misses its command"
                )?;
                match vector_unit {
                    // Degrees read as radians: the error as degrees would be a robot's.
                    Some(AngleUnit::Radian) if *angle_rad <= limit => {
                        write!(
                            f,
                            ": rx,ry,rz look like degrees read as radians (read as degrees, \
                             {}); give their columns the unit deg (rx:deg,ry:deg,rz:deg, or \
                             rx=COLUMN:deg,... in --columns)",
                            degrees(angle_rad.to_radians())
                        )
                    }
                    Some(_) => write!(
                        f,
                        ": no unit makes it a robot's; is the column an orientation rather \
                         than its error, or another quantity?"
                    ),
                    None => write!(
                        f,
                        ": the measured orientation is that far from the nominal one; are both \
                         in one convention and one unit, and the measured one in the robot's \
                         base frame (a tracker's frame needs --measured-in tracker)?"
                    ),
                }
            }
            ReadErrorKind::Syntax(e) => write!(f, "malformed CSV: {e}"),
        }
    }
}

impl std::error::Error for ReadError {}

/// Reads a whole regular file; a FIFO or a device is refused at once
/// ([`adwi_runtime::input::read_regular`]).
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, ReadError> {
    adwi_runtime::input::read_regular(path).map_err(|e| ReadError {
        path: path.to_path_buf(),
        line: None,
        column: None,
        kind: ReadErrorKind::Io(e.to_string()),
    })
}

/// What a reading needs from a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Purpose {
    /// A sample database: nominal positions and errors (or measured positions).
    Samples,
    /// Targets: nominal positions; everything else optional.
    Targets,
    /// Raw measurements: joints and measured positions; nominal poses optional; error
    /// columns not read.
    Measurements,
    /// Poses to measure: joint values; everything else optional.
    Poses,
}

/// One numeric column as read: its index in the row, and the factor to millimetres or
/// radians (unit and sign).
#[derive(Clone, Copy, Debug)]
struct Field {
    index: usize,
    scale: f64,
}

/// An orientation's columns.
#[derive(Clone, Debug)]
struct OrientationFields {
    convention: Convention,
    fields: Vec<Field>,
}

/// A column's factor to millimetres or radians (sign included), and its unit (none for a
/// quaternion component).
type Scale = (f64, Option<Unit>);

/// The columns a file provides, by part.
#[derive(Default)]
struct Layout {
    position: Option<[Field; 3]>,
    delta: Option<[Field; 3]>,
    measured: Option<[Field; 3]>,
    nominal_orientation: Option<OrientationFields>,
    measured_orientation: Option<OrientationFields>,
    rotation_vector: Option<[Field; 3]>,
    joints: Option<Vec<Field>>,
    config: Option<usize>,
}

/// The rows of a file, by part, in millimetres and radians; a part is `None` (or empty for
/// positions) when the file does not have it.
#[derive(Debug, Default, PartialEq)]
pub(crate) struct Rows {
    pub nominal_mm: Option<Vec<[f64; 3]>>,
    pub delta_mm: Option<Vec<[f64; 3]>>,
    pub measured_mm: Option<Vec<[f64; 3]>>,
    pub nominal_rotation: Option<Vec<Rotation3<f64>>>,
    pub measured_rotation: Option<Vec<Rotation3<f64>>>,
    pub rotation_vector_rad: Option<Vec<[f64; 3]>>,
    pub joints: Option<Joints>,
    pub config: Option<Vec<u8>>,
    pub lines: Vec<u64>,
}

const BOM: &[u8] = b"\xef\xbb\xbf";

/// Reads the rows of sample CSV held in memory; `path` only names it in messages.
pub(crate) fn parse(
    path: &Path,
    bytes: &[u8],
    columns: &ColumnMap,
    options: &ReadOptions,
    purpose: Purpose,
) -> Result<Rows, ReadError> {
    parse_in(
        path,
        bytes,
        columns,
        options,
        purpose,
        Cut::Chunks(CHUNK_BYTES),
    )
}

/// How the rows after the header are read: the two ways read every text alike (the tests
/// hold them equal, chunks of a few bytes included).
#[derive(Clone, Copy, Debug)]
enum Cut {
    /// Text without quotes, valid UTF-8, in chunks of about this many bytes of whole lines
    /// on the thread pool; other text by the CSV reader.
    Chunks(usize),
    /// All by the CSV reader, in one pass.
    #[cfg_attr(not(test), allow(dead_code))]
    CsvReader,
}

fn parse_in(
    path: &Path,
    bytes: &[u8],
    columns: &ColumnMap,
    options: &ReadOptions,
    purpose: Purpose,
    cut: Cut,
) -> Result<Rows, ReadError> {
    let error = |line: Option<u64>, column: Option<(usize, String)>, kind| ReadError {
        path: path.to_path_buf(),
        line,
        column,
        kind,
    };
    // Spreadsheets start UTF-8 files with a byte-order mark.
    let bytes = bytes.strip_prefix(BOM).unwrap_or(bytes);
    // Comment lines only above the header (as `tablec simulate` writes them) are skipped in
    // place; elsewhere the text is copied without them.
    let (leading, rest) = leading_comments(bytes);
    let uncommented = if rest.len() < bytes.len() && !has_comment_lines(rest) {
        None
    } else {
        without_comments(bytes)
    };
    let (data, leading): (&[u8], u64) = match &uncommented {
        Some((data, _)) => (data, 0),
        None if rest.len() < bytes.len() => (rest, leading),
        None => (bytes, 0),
    };
    let mut lines = LineCounter {
        data,
        byte: 0,
        line: 1,
        leading,
        physical: uncommented
            .as_ref()
            .map(|(_, physical)| physical.as_slice()),
    };
    // The header line: the first that is not blank (the CSV reader skips blank lines).
    let header_text = data
        .split(|&b| b == b'\n')
        .map(|l| l.strip_suffix(b"\r").unwrap_or(l))
        .find(|l| !l.is_empty())
        .unwrap_or(&[]);
    let (delimiter, delimiter_choice) = match options.delimiter {
        Some(d) => (d, Choice::Given),
        None => (Delimiter::detect(header_text), Choice::Detected),
    };
    let mut reader = csv_reader(delimiter, data);
    let (names, header_line) = read_header(path, &mut reader, &mut lines)?;
    let header_info = HeaderInfo {
        names: &names,
        delimiter,
        choice: &delimiter_choice,
    };
    let layout = resolve(&header_info, columns, options, purpose)
        .map_err(|kind| error(Some(header_line), None, kind))?;
    let mut row_reader = RowReader {
        path,
        names: &names,
        layout: &layout,
        purpose,
        decimal: match options.decimal {
            Some(d) => Some((d, Choice::Given)),
            None if delimiter == Delimiter::Comma => Some((Decimal::Point, Choice::CommaSeparated)),
            None => None,
        },
        joint_row: [0.0; MAX_JOINTS],
        orientation: [0.0; 4],
    };
    let body = reader.position().byte() as usize;
    let chunked = match cut {
        Cut::Chunks(bytes) => chunks(data, body, bytes),
        Cut::CsvReader => None,
    };
    #[cfg(test)]
    tests::CHUNKED.with(|c| c.set(c.get() + usize::from(chunked.is_some())));
    let Some(chunks) = chunked else {
        // Rows are at most the lines of the file: reserve once rather than grow.
        let mut rows = Rows::for_layout(&layout, memchr::memchr_iter(b'\n', data).count() + 1);
        row_reader.read_all(&mut reader, &mut lines, &mut rows)?;
        return finished(rows).map_err(|kind| error(Some(header_line), None, kind));
    };
    // Each chunk's first line's number in `data`, and room for every row.
    let text_bytes: usize = chunks.iter().map(|(text, _)| text.len()).sum();
    let mut line = 1 + memchr::memchr_iter(b'\n', &data[..data.len() - text_bytes]).count() as u64;
    let mut first_lines = Vec::with_capacity(chunks.len());
    for (_, newlines) in &chunks {
        first_lines.push(line);
        line += *newlines as u64;
    }
    let mut rows = Rows::for_layout(&layout, chunks.iter().map(|(_, n)| n + 1).sum());
    let lines = &lines;
    let chunk_rows = |c: usize, row_reader: &mut RowReader<'_>| {
        let (text, newlines) = chunks[c];
        let mut rows = Rows::for_layout(&layout, newlines + 1);
        row_reader.read_lines(text, delimiter, first_lines[c], lines, &mut rows)?;
        Ok::<Rows, ReadError>(rows)
    };
    // Chunks are read in order until the decimal mark is known (the first row, in most
    // files), then on the thread pool, a few at a time so that their rows are not all held
    // twice, each wave's rows appended while the next is read. Each chunk stops at its
    // first error, and the first chunk's error is the file's.
    let mut next = 0;
    while next < chunks.len() && (next == 0 || row_reader.decimal.is_none()) {
        rows.append(chunk_rows(next, &mut row_reader)?);
        next += 1;
    }
    let append = |rows: &mut Rows, read: Vec<Result<Rows, ReadError>>| {
        read.into_iter().try_for_each(|chunk| {
            rows.append(chunk?);
            Ok(())
        })
    };
    let mut read = Vec::new();
    for wave in (next..chunks.len())
        .collect::<Vec<_>>()
        .chunks(CHUNKS_AT_ONCE)
    {
        let (appended, wave_read) = rayon::join(
            || append(&mut rows, std::mem::take(&mut read)),
            || {
                wave.par_iter()
                    .map(|&c| chunk_rows(c, &mut row_reader.clone()))
                    .collect()
            },
        );
        appended?;
        read = wave_read;
    }
    append(&mut rows, read)?;
    finished(rows).map_err(|kind| error(Some(header_line), None, kind))
}

/// Text read in chunks of about this many bytes, on the thread pool.
const CHUNK_BYTES: usize = 1 << 20;

/// Chunks read at once: enough to keep every thread busy, few enough that their rows are
/// not held twice for long.
const CHUNKS_AT_ONCE: usize = 16;

/// The text of `data` after the header (which the CSV reader left at byte `body`) as
/// chunks of whole lines of about `chunk_bytes`, each with its count of line ends, when it
/// can be split without the CSV reader: no quotes (whose fields may hold separators and line
/// ends), valid UTF-8, every `\r` that of a `\r\n`. `None` for text that cannot, which the
/// CSV reader reads.
fn chunks(data: &[u8], body: usize, chunk_bytes: usize) -> Option<Vec<(&str, usize)>> {
    // The CSV reader stops after the header's `\r` of a `\r\n`, before its `\n`.
    let body = match (body.checked_sub(1).map(|b| data[b]), data.get(body)) {
        (Some(b'\n'), _) => body,
        (Some(b'\r'), Some(b'\n')) => body + 1,
        (_, None) => body,
        _ => return None,
    };
    let mut ranges = Vec::with_capacity((data.len() - body) / chunk_bytes.max(1) + 1);
    let mut start = body;
    while start < data.len() {
        let end = match data.get(start + chunk_bytes..) {
            Some(rest) => {
                memchr::memchr(b'\n', rest).map_or(data.len(), |n| start + chunk_bytes + n + 1)
            }
            None => data.len(),
        };
        ranges.push(start..end);
        start = end;
    }
    // Lines cut at a `\n` are cut at a character's boundary. Checked on the thread pool
    // when there are several chunks (one is checked here, without waking the pool).
    let check = |range: Range<usize>| {
        let bytes = &data[range];
        let cuttable = memchr::memchr(b'"', bytes).is_none()
            && memchr::memchr_iter(b'\r', bytes).all(|r| bytes.get(r + 1) == Some(&b'\n'));
        let text = std::str::from_utf8(bytes).ok().filter(|_| cuttable)?;
        Some((text, memchr::memchr_iter(b'\n', bytes).count()))
    };
    if ranges.len() > 1 {
        ranges.into_par_iter().map(check).collect()
    } else {
        ranges.into_iter().map(check).collect()
    }
}

/// A CSV reader of `bytes` that leaves the header, the field count and the trimming to this
/// module.
fn csv_reader(delimiter: Delimiter, bytes: &[u8]) -> csv::Reader<&[u8]> {
    // Fields are trimmed here, not by the CSV reader, which builds a new record per row to
    // trim: a million-row file must not cost a million allocations.
    csv::ReaderBuilder::new()
        .delimiter(delimiter.byte())
        .has_headers(false)
        .flexible(true)
        .from_reader(bytes)
}

/// `rows`, refused when the file has none.
fn finished(rows: Rows) -> Result<Rows, ReadErrorKind> {
    if rows.lines.is_empty() {
        return Err(ReadErrorKind::NoSamples);
    }
    Ok(rows)
}

/// The number of comment lines that start `bytes`, and the text after them.
fn leading_comments(bytes: &[u8]) -> (u64, &[u8]) {
    let mut rest = bytes;
    let mut count = 0;
    while rest.first() == Some(&b'#') {
        count += 1;
        rest = match rest.iter().position(|&b| b == b'\n') {
            Some(end) => &rest[end + 1..],
            None => &[],
        };
    }
    (count, rest)
}

/// Whether any line of `bytes` is a comment line.
fn has_comment_lines(bytes: &[u8]) -> bool {
    bytes.first() == Some(&b'#') || memchr::memmem::find(bytes, b"\n#").is_some()
}

/// `bytes` without its comment lines, and the file line of each line kept
/// (`physical[n - 1]` is the file line of kept line n); `None` when it has none, as most
/// files, which are then read in place. Comment lines are removed here rather than by the
/// CSV reader, whose line numbers do not count them consistently.
fn without_comments(bytes: &[u8]) -> Option<(Vec<u8>, Vec<u64>)> {
    if !has_comment_lines(bytes) {
        return None;
    }
    let mut filtered = Vec::with_capacity(bytes.len());
    let mut physical = Vec::new();
    for (i, line) in bytes.split_inclusive(|&b| b == b'\n').enumerate() {
        if line.first() != Some(&b'#') {
            filtered.extend_from_slice(line);
            physical.push(i as u64 + 1);
        }
    }
    Some((filtered, physical))
}

/// The header's column names, trimmed and in lower case, each once; and its line.
fn read_header(
    path: &Path,
    reader: &mut csv::Reader<&[u8]>,
    lines: &mut LineCounter<'_>,
) -> Result<(Vec<String>, u64), ReadError> {
    let error = |line: Option<u64>, column: Option<(usize, String)>, kind| ReadError {
        path: path.to_path_buf(),
        line,
        column,
        kind,
    };
    let mut header = csv::ByteRecord::new();
    match reader.read_byte_record(&mut header) {
        Ok(true) => {}
        Ok(false) => return Err(error(None, None, ReadErrorKind::Empty)),
        Err(e) => return Err(csv_error(path, e, lines)),
    }
    let header_line = lines.of(header.position());
    let mut names = Vec::with_capacity(header.len());
    // A set beside the list: a linear `contains` per column is quadratic in the column
    // count, minutes for a hostile header of a million columns.
    let mut distinct = std::collections::HashSet::with_capacity(header.len());
    for field in header.iter() {
        let name = std::str::from_utf8(field.trim_ascii())
            .map_err(|_| error(Some(header_line), None, ReadErrorKind::NotUtf8))?
            .to_ascii_lowercase();
        if !name.is_empty() && !distinct.insert(name.clone()) {
            return Err(error(
                Some(header_line),
                Some((names.len() + 1, name.clone())),
                ReadErrorKind::DuplicateColumn(name),
            ));
        }
        names.push(name);
    }
    Ok((names, header_line))
}

impl Rows {
    /// `other`'s rows after these (both of one layout).
    fn append(&mut self, other: Rows) {
        fn join<T>(into: &mut Option<Vec<T>>, from: Option<Vec<T>>) {
            if let (Some(into), Some(mut from)) = (into.as_mut(), from) {
                into.append(&mut from);
            }
        }
        join(&mut self.nominal_mm, other.nominal_mm);
        join(&mut self.delta_mm, other.delta_mm);
        join(&mut self.measured_mm, other.measured_mm);
        join(&mut self.nominal_rotation, other.nominal_rotation);
        join(&mut self.measured_rotation, other.measured_rotation);
        join(&mut self.rotation_vector_rad, other.rotation_vector_rad);
        join(&mut self.config, other.config);
        if let (Some(into), Some(from)) = (self.joints.as_mut(), other.joints) {
            into.append(from);
        }
        self.lines.extend_from_slice(&other.lines);
    }

    /// Empty rows of the parts `layout` found, room for `rows_hint` rows reserved.
    fn for_layout(layout: &Layout, rows_hint: usize) -> Rows {
        Rows {
            nominal_mm: layout.position.map(|_| Vec::with_capacity(rows_hint)),
            delta_mm: layout.delta.map(|_| Vec::with_capacity(rows_hint)),
            measured_mm: layout.measured.map(|_| Vec::with_capacity(rows_hint)),
            nominal_rotation: layout.nominal_orientation.as_ref().map(|_| Vec::new()),
            measured_rotation: layout.measured_orientation.as_ref().map(|_| Vec::new()),
            rotation_vector_rad: layout.rotation_vector.map(|_| Vec::new()),
            joints: layout.joints.as_ref().map(|j| Joints::new(j.len())),
            config: layout.config.map(|_| Vec::new()),
            lines: Vec::with_capacity(rows_hint),
        }
    }
}

/// Reads each row's fields into [`Rows`] by the columns found; its buffers serve every
/// row.
#[derive(Clone)]
struct RowReader<'a> {
    path: &'a Path,
    names: &'a [String],
    layout: &'a Layout,
    purpose: Purpose,
    /// The decimal separator, once given or seen.
    decimal: Option<(Decimal, Choice)>,
    joint_row: [f64; MAX_JOINTS],
    orientation: [f64; 4],
}

impl RowReader<'_> {
    /// Reads every record of `reader` into `rows`, each checked to have the header's
    /// fields.
    fn read_all(
        &mut self,
        reader: &mut csv::Reader<&[u8]>,
        lines: &mut LineCounter<'_>,
        rows: &mut Rows,
    ) -> Result<(), ReadError> {
        // One record buffer for every row.
        let mut record = csv::ByteRecord::new();
        loop {
            match reader.read_byte_record(&mut record) {
                Ok(true) => {}
                Ok(false) => return Ok(()),
                Err(e) => return Err(csv_error(self.path, e, lines)),
            }
            let line = lines.of(record.position());
            self.read_row(&record, line, rows)?;
        }
    }

    /// Reads every line of `text` (quote-free and valid UTF-8: [`chunks`]), whose first is
    /// line `first_line` of the text `lines` counts, into `rows`, as the CSV reader would:
    /// blank lines skipped, a `\r` before a `\n` not part of the row.
    fn read_lines(
        &mut self,
        text: &str,
        delimiter: Delimiter,
        first_line: u64,
        lines: &LineCounter<'_>,
        rows: &mut Rows,
    ) -> Result<(), ReadError> {
        let bytes = text.as_bytes();
        let mut fields: Vec<&str> = Vec::with_capacity(self.names.len());
        let mut line = first_line;
        let mut start = 0;
        // Every separator and line end, found a word at a time; the text after the last
        // line end is a row too.
        let ends = memchr::memchr2_iter(b'\n', delimiter.byte(), bytes);
        for end in ends.chain((bytes.last() != Some(&b'\n')).then_some(bytes.len())) {
            let field = &text[start..end];
            start = end + 1;
            if bytes.get(end) == Some(&delimiter.byte()) {
                fields.push(field);
                continue;
            }
            fields.push(field.strip_suffix('\r').unwrap_or(field));
            if !(fields.len() == 1 && fields[0].is_empty()) {
                self.read_row(fields.as_slice(), lines.file_line(line), rows)?;
            }
            fields.clear();
            line += 1;
        }
        Ok(())
    }

    /// Reads one row at file line `line` into `rows`, its line included, once it has the
    /// header's number of fields.
    fn read_row<R: Record + ?Sized>(
        &mut self,
        record: &R,
        line: u64,
        rows: &mut Rows,
    ) -> Result<(), ReadError> {
        if record.len() != self.names.len() {
            // A blank line is skipped by the reader; a row with one empty field is not.
            return Err(ReadError {
                path: self.path.to_path_buf(),
                line: Some(line),
                column: None,
                kind: ReadErrorKind::FieldCount {
                    expected: self.names.len() as u64,
                    found: record.len() as u64,
                },
            });
        }
        self.read(record, line, rows)?;
        rows.lines.push(line);
        Ok(())
    }

    /// Reads the row `record` at file line `line` into `rows` (its line aside): every
    /// number in its unit, lengths and orientation errors checked.
    fn read<R: Record + ?Sized>(
        &mut self,
        record: &R,
        line: u64,
        rows: &mut Rows,
    ) -> Result<(), ReadError> {
        let RowReader {
            path,
            names,
            layout,
            purpose,
            decimal,
            joint_row,
            orientation,
        } = self;
        let (path, names, layout, purpose) = (*path, *names, *layout, *purpose);
        let error = |line: Option<u64>, column: Option<(usize, String)>, kind| ReadError {
            path: path.to_path_buf(),
            line,
            column,
            kind,
        };
        let mut number = |f: Field| -> Result<f64, ReadError> {
            (record.text(f.index))
                .and_then(|text| number_at(text, decimal, line, f.index, names))
                .map(|v| v * f.scale)
                .map_err(|kind| {
                    error(
                        Some(line),
                        Some((f.index + 1, names[f.index].clone())),
                        kind,
                    )
                })
        };
        let mut triple = |cols: [Field; 3]| -> Result<[f64; 3], ReadError> {
            Ok([number(cols[0])?, number(cols[1])?, number(cols[2])?])
        };
        // Lengths of samples and measurements within 1 km, in millimetres (a unit's
        // conversion may overflow a finite field); targets and poses are checked where
        // they are used.
        let length = |cols: [Field; 3], v: [f64; 3]| -> Result<[f64; 3], ReadError> {
            match (0..3).find(|&a| v[a].abs() > MAX_COORDINATE_MM || v[a].is_nan()) {
                Some(a) if matches!(purpose, Purpose::Samples | Purpose::Measurements) => {
                    let index = cols[a].index;
                    Err(error(
                        Some(line),
                        Some((index + 1, names[index].clone())),
                        ReadErrorKind::ImplausibleCoordinate { value_mm: v[a] },
                    ))
                }
                _ => Ok(v),
            }
        };
        if let (Some(cols), Some(v)) = (layout.position, rows.nominal_mm.as_mut()) {
            v.push(length(cols, triple(cols)?)?);
        }
        if let (Some(cols), Some(v)) = (layout.delta, rows.delta_mm.as_mut()) {
            v.push(length(cols, triple(cols)?)?);
        }
        if let (Some(cols), Some(v)) = (layout.measured, rows.measured_mm.as_mut()) {
            v.push(length(cols, triple(cols)?)?);
        }
        if let (Some(cols), Some(v)) = (layout.rotation_vector, rows.rotation_vector_rad.as_mut()) {
            let r = triple(cols)?;
            if purpose == Purpose::Samples {
                let unit = if cols[0].scale.abs() == 1.0 {
                    AngleUnit::Radian
                } else {
                    AngleUnit::Degree
                };
                check_rotation_error(r, Some(unit)).map_err(|kind| {
                    // The column of the largest component: the one to look at.
                    let a = (0..3)
                        .max_by(|&i, &j| r[i].abs().total_cmp(&r[j].abs()))
                        .unwrap_or(0);
                    let index = cols[a].index;
                    error(Some(line), Some((index + 1, names[index].clone())), kind)
                })?;
            }
            v.push(r);
        }
        for (part, out) in [
            (&layout.nominal_orientation, &mut rows.nominal_rotation),
            (&layout.measured_orientation, &mut rows.measured_rotation),
        ] {
            if let (Some(o), Some(out)) = (part, out.as_mut()) {
                let values = &mut orientation[..o.fields.len()];
                for (v, &f) in values.iter_mut().zip(&o.fields) {
                    *v = number(f)?;
                }
                let rotation = o.convention.rotation(values).ok_or_else(|| {
                    let first = o.fields[0].index;
                    error(
                        Some(line),
                        Some((first + 1, names[first].clone())),
                        ReadErrorKind::ZeroQuaternion,
                    )
                })?;
                out.push(rotation);
            }
        }
        // An error computed from the orientations is checked as a given one is.
        if let (Purpose::Samples, None, Some(m), Some(nominal), Some(measured)) = (
            purpose,
            layout.rotation_vector,
            &layout.measured_orientation,
            rows.nominal_rotation.as_ref().and_then(|r| r.last()),
            rows.measured_rotation.as_ref().and_then(|r| r.last()),
        ) {
            let r = crate::pose::orientation_error(nominal, measured);
            check_rotation_error(r, None).map_err(|kind| {
                let first = m.fields[0].index;
                error(Some(line), Some((first + 1, names[first].clone())), kind)
            })?;
        }
        if let (Some(cols), Some(joints)) = (&layout.joints, rows.joints.as_mut()) {
            let q = &mut joint_row[..cols.len()];
            for (v, &f) in q.iter_mut().zip(cols) {
                *v = number(f)?;
            }
            joints.push(q);
        }
        if let (Some(c), Some(configs)) = (layout.config, rows.config.as_mut()) {
            let text = String::from_utf8_lossy(record.bytes(c).trim_ascii()).into_owned();
            let config: u8 = text
                .parse()
                .ok()
                .filter(|&v| v != CONFIG_UNKNOWN)
                .ok_or_else(|| {
                    error(
                        Some(line),
                        Some((c + 1, names[c].clone())),
                        ReadErrorKind::BadConfig(truncated(&text)),
                    )
                })?;
            configs.push(config);
        }
        Ok(())
    }
}

/// Refuses an orientation error (rotation vector, rad) beyond
/// [`crate::MAX_PLAUSIBLE_ROTATION_ERROR_DEG`], or whose norm is not finite.
fn check_rotation_error(r: [f64; 3], vector_unit: Option<AngleUnit>) -> Result<(), ReadErrorKind> {
    // Scaled by the largest component, so that a norm of finite components only
    // overflows when it exceeds f64's range.
    let largest = r.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let angle_rad = if largest > 0.0 {
        largest * r.iter().map(|v| (v / largest).powi(2)).sum::<f64>().sqrt()
    } else {
        0.0
    };
    if angle_rad.to_degrees() <= crate::MAX_PLAUSIBLE_ROTATION_ERROR_DEG {
        return Ok(());
    }
    Err(ReadErrorKind::ImplausibleRotationError {
        angle_rad,
        vector_unit,
    })
}

/// A row's fields, as the CSV reader gives them or as split from a line.
trait Record {
    /// The number of fields.
    fn len(&self) -> usize;
    /// Field `i`'s bytes.
    fn bytes(&self, i: usize) -> &[u8];
    /// Field `i` as text.
    fn text(&self, i: usize) -> Result<&str, ReadErrorKind>;
}

impl Record for csv::ByteRecord {
    fn len(&self) -> usize {
        csv::ByteRecord::len(self)
    }
    fn bytes(&self, i: usize) -> &[u8] {
        &self[i]
    }
    fn text(&self, i: usize) -> Result<&str, ReadErrorKind> {
        std::str::from_utf8(&self[i]).map_err(|_| ReadErrorKind::NotUtf8)
    }
}

impl Record for [&str] {
    fn len(&self) -> usize {
        <[&str]>::len(self)
    }
    fn bytes(&self, i: usize) -> &[u8] {
        self[i].as_bytes()
    }
    fn text(&self, i: usize) -> Result<&str, ReadErrorKind> {
        Ok(self[i])
    }
}

/// The number in a field, in the file's unit: trimmed, with the file's decimal mark,
/// finite. `decimal` is the file's mark once known; the first number with a mark decides it
/// when it is not.
fn number_at(
    field: &str,
    decimal: &mut Option<(Decimal, Choice)>,
    line: u64,
    index: usize,
    names: &[String],
) -> Result<f64, ReadErrorKind> {
    let text = field.trim_ascii();
    let raw = text.as_bytes();
    let (mut point, mut comma) = (false, false);
    for &b in raw {
        point |= b == b'.';
        comma |= b == b',';
    }
    if point || comma {
        let mark = match decimal {
            Some((mark, _)) => *mark,
            None if point && comma => return Err(ReadErrorKind::NotANumber(truncated(text))),
            None => {
                let mark = if comma {
                    Decimal::Comma
                } else {
                    Decimal::Point
                };
                *decimal = Some((
                    mark,
                    Choice::FirstNumber {
                        line,
                        column: (index + 1, names[index].clone()),
                    },
                ));
                mark
            }
        };
        let foreign = match mark {
            Decimal::Point => comma,
            Decimal::Comma => point,
        };
        if foreign {
            let choice = Box::new(decimal.as_ref().map_or(Choice::Given, |(_, c)| c.clone()));
            return Err(ReadErrorKind::DecimalMark {
                text: truncated(text),
                expected: mark,
                choice,
            });
        }
    }
    let value: Result<f64, _> = if comma {
        // A decimal comma: the number with a point, on the stack for any number of usual
        // length.
        let mut buffer = [0u8; 64];
        match buffer.get_mut(..raw.len()) {
            Some(b) => {
                for (out, &c) in b.iter_mut().zip(raw) {
                    *out = if c == Decimal::Comma.mark() {
                        Decimal::Point.mark()
                    } else {
                        c
                    };
                }
                std::str::from_utf8(b).map_or(Ok(f64::NAN), str::parse)
            }
            None => text.replace(',', ".").parse(),
        }
    } else {
        text.parse()
    };
    let value = value.map_err(|_| ReadErrorKind::NotANumber(truncated(text)))?;
    if !value.is_finite() {
        return Err(ReadErrorKind::NotFinite(truncated(text)));
    }
    Ok(value)
}

/// An angle in radians as people read it, in degrees: four significant digits.
fn degrees(angle_rad: f64) -> String {
    format!("{}°", number(angle_rad.to_degrees()))
}

fn truncated(text: &str) -> String {
    const MAX: usize = 40;
    match text.char_indices().nth(MAX) {
        Some((cut, _)) => format!("{}…", &text[..cut]),
        None => text.to_string(),
    }
}

fn csv_error(path: &Path, e: csv::Error, lines: &mut LineCounter<'_>) -> ReadError {
    let line = e.position().map(|p| lines.of(Some(p)));
    let kind = match e.kind() {
        csv::ErrorKind::Utf8 { .. } => ReadErrorKind::NotUtf8,
        csv::ErrorKind::Io(io) => ReadErrorKind::Io(io.to_string()),
        _ => ReadErrorKind::Syntax(e.to_string()),
    };
    ReadError {
        path: path.to_path_buf(),
        line,
        column: None,
        kind,
    }
}

/// The file line of a record. The CSV reader's own line numbers, and its byte positions,
/// count from the end of the previous record, before the blank lines it skips and the `\n`
/// of a `\r\n` it has not consumed yet: the record starts at the first byte after them.
struct LineCounter<'a> {
    /// The text read (without comment lines).
    data: &'a [u8],
    /// A byte offset and the 1-based line it is on, where the last count stopped.
    byte: usize,
    line: u64,
    /// Comment lines above `data` in the file, when only those were skipped.
    leading: u64,
    /// The file line of each line of `data`, when comment lines were removed from it.
    physical: Option<&'a [u64]>,
}

impl LineCounter<'_> {
    /// The file line of line `line` (1-based) of the text read.
    fn file_line(&self, line: u64) -> u64 {
        match self.physical {
            Some(physical) => physical.get(line as usize - 1).copied().unwrap_or(line),
            None => self.leading + line,
        }
    }

    /// The file line where the record at `position` starts (0 without a position). Counts
    /// forward from the last call, so reading every record counts the text once.
    fn of(&mut self, position: Option<&csv::Position>) -> u64 {
        let Some(position) = position else {
            return 0;
        };
        let mut start = (position.byte() as usize).min(self.data.len());
        while start < self.data.len() && matches!(self.data[start], b'\r' | b'\n') {
            start += 1;
        }
        if start < self.byte {
            (self.byte, self.line) = (0, 1);
        }
        let newlines = memchr::memchr_iter(b'\n', &self.data[self.byte..start]).count();
        self.line += newlines as u64;
        self.byte = start;
        self.file_line(self.line)
    }
}

/// The header as read, for finding columns and for a missing column's message.
struct HeaderInfo<'a> {
    names: &'a [String],
    delimiter: Delimiter,
    choice: &'a Choice,
}

impl HeaderInfo<'_> {
    /// What the header holds: the separator it was read with and how that was chosen, its
    /// column count, and the separator the text suggests when it is one column.
    fn describe(&self) -> String {
        const SHOWN: usize = 60;
        let names = self.names;
        let mut text = names.join(",");
        if let Some((cut, _)) = text.char_indices().nth(SHOWN) {
            text.truncate(cut);
            text.push('…');
        }
        let columns = match names.len() {
            1 => "1 column".to_string(),
            n => format!("{n} columns"),
        };
        let how = match self.choice {
            Choice::Given => "as given by --delimiter",
            _ => "detected from it",
        };
        let read = format!(
            "the header, read with {} as separators ({how}),",
            self.delimiter.plural()
        );
        let seen = [
            (b';', Delimiter::Semicolon),
            (b'\t', Delimiter::Tab),
            (b',', Delimiter::Comma),
        ]
        .into_iter()
        .filter(|(c, d)| {
            *d != self.delimiter && names.len() == 1 && names[0].as_bytes().contains(c)
        })
        .max_by_key(|(c, _)| names[0].bytes().filter(|b| b == c).count());
        match seen {
            Some((_, other)) => format!(
                "{read} is {columns} ('{text}'): the file seems separated by {}; give \
                 --delimiter {}",
                other.plural(),
                other.name()
            ),
            None => format!("{read} has {columns}: '{text}'"),
        }
    }
}

/// Finds the columns of each part: all-or-none groups complete, one unit per group, one
/// orientation convention per side, joints `j1..jn` without gaps; then what `purpose`
/// requires.
fn resolve(
    header: &HeaderInfo<'_>,
    map: &ColumnMap,
    options: &ReadOptions,
    purpose: Purpose,
) -> Result<Layout, ReadErrorKind> {
    let names = header.names;
    let missing = |wanted: &str| ReadErrorKind::MissingColumn {
        wanted: wanted.to_string(),
        found: header.describe(),
    };
    check_mapped_columns(map, names)?;
    let find = |canonical: &str| -> Option<(usize, Source)> {
        let source = map.find(canonical)?;
        let index = names.iter().position(|n| *n == source.name)?;
        Some((index, source))
    };
    // The factor to millimetres or radians of a column (sign included), and its unit.
    let scale = |canonical: &str, source: &Source| -> Scale {
        let quantity = Quantity::of(canonical).expect("a canonical column");
        let prismatic = canonical
            .strip_prefix('j')
            .and_then(|n| n.parse::<u32>().ok())
            .is_some_and(|n| (1..=64).contains(&n) && options.prismatic_joints >> (n - 1) & 1 == 1);
        let unit = source.unit.or(match quantity {
            Quantity::Length => Some(Unit::Length(options.length_unit)),
            Quantity::Joint if prismatic => Some(Unit::Length(options.length_unit)),
            Quantity::Angle | Quantity::Joint => Some(Unit::Angle(options.angle_unit)),
            Quantity::RotationVector => Some(Unit::Angle(AngleUnit::Radian)),
            Quantity::Unitless => None,
        });
        let factor = match unit {
            Some(Unit::Length(u)) => u.mm(),
            Some(Unit::Angle(u)) => u.rad(),
            None => 1.0,
        };
        (if source.negate { -factor } else { factor }, unit)
    };
    // The columns of a group, all or none, in one unit.
    let group = |cols: &[&str]| -> Result<Option<Vec<Field>>, ReadErrorKind> {
        let found: Vec<Option<(usize, Source)>> = cols.iter().map(|c| find(c)).collect();
        if found.iter().all(Option::is_none) {
            return Ok(None);
        }
        if let Some(i) = found.iter().position(Option::is_none) {
            let present: Vec<&str> = cols
                .iter()
                .zip(&found)
                .filter(|(_, f)| f.is_some())
                .map(|(c, _)| *c)
                .collect();
            return Err(ReadErrorKind::IncompleteColumns(format!(
                "'{}' given without '{}'",
                present.join(","),
                cols[i]
            )));
        }
        let mut fields = Vec::with_capacity(cols.len());
        let mut first_unit: Option<(&str, Unit)> = None;
        for (c, (index, source)) in cols.iter().zip(found.into_iter().flatten()) {
            let (factor, unit) = scale(c, &source);
            match (first_unit, unit) {
                (Some((first, u)), Some(unit)) if u != unit => {
                    return Err(ReadErrorKind::MixedUnits(format!(
                        "'{first}' is in {u} but '{c}' in {unit}: the columns {} take one unit",
                        cols.join(",")
                    )))
                }
                (None, Some(unit)) => first_unit = Some((c, unit)),
                _ => {}
            }
            fields.push(Field {
                index,
                scale: factor,
            });
        }
        Ok(Some(fields))
    };
    let three = |v: Vec<Field>| [v[0], v[1], v[2]];
    let mut layout = Layout {
        position: group(&["x", "y", "z"])?.map(three),
        delta: group(&["dx", "dy", "dz"])?.map(three),
        measured: group(&["mx", "my", "mz"])?.map(three),
        rotation_vector: group(&["rx", "ry", "rz"])?.map(three),
        config: find("config").map(|(i, _)| i),
        ..Layout::default()
    };
    layout.nominal_orientation = orientation(false, &group)?;
    layout.measured_orientation = orientation(true, &group)?;
    layout.joints = joints(names, &find, &scale)?;
    check_quaternion_is_not_joints(&layout, map, names)?;
    check_purpose(&mut layout, purpose, &missing)?;
    Ok(layout)
}

/// A column the mapping names must be there: absent, it is a typo, not an absent group
/// (`dx=xdif` would read as "dy,dz without dx", `j1=joint1` drop the joints silently).
fn check_mapped_columns(map: &ColumnMap, names: &[String]) -> Result<(), ReadErrorKind> {
    for (name, source) in map.mapped() {
        if !names.contains(&source.name) {
            return Err(ReadErrorKind::MappedColumnMissing(Box::new(
                MappedColumnMissing {
                    name,
                    column: source.name.clone(),
                    closest: closest_names(&source.name, names),
                },
            )));
        }
    }
    Ok(())
}

/// The columns of a group, all or none, in one unit ([`resolve`]).
type GroupOf<'a> = dyn Fn(&[&str]) -> Result<Option<Vec<Field>>, ReadErrorKind> + 'a;

/// The columns of the nominal (or `measured`) orientation: one convention at most, its
/// columns found by `group` ([`resolve`]).
fn orientation(
    measured: bool,
    group: &GroupOf,
) -> Result<Option<OrientationFields>, ReadErrorKind> {
    let mut found: Option<OrientationFields> = None;
    for convention in Convention::ALL {
        let cols = orientation_columns(convention, measured);
        if let Some(fields) = group(cols)? {
            if let Some(first) = &found {
                return Err(ReadErrorKind::ConflictingColumns(format!(
                    "two conventions for the {} orientation, '{}' and '{}': keep one",
                    if measured { "measured" } else { "nominal" },
                    orientation_columns(first.convention, measured).join(","),
                    cols.join(",")
                )));
            }
            found = Some(OrientationFields { convention, fields });
        }
    }
    Ok(found)
}

/// Refuses a quaternion q1..q4 in a file that has q5: joint angles named q1..q6 are no
/// quaternion.
fn check_quaternion_is_not_joints(
    layout: &Layout,
    map: &ColumnMap,
    names: &[String],
) -> Result<(), ReadErrorKind> {
    if matches!(&layout.nominal_orientation, Some(o) if o.convention == Convention::QuaternionWxyz)
        && !map.maps("q1")
        && names.iter().any(|n| n == "q5")
    {
        return Err(ReadErrorKind::ConflictingColumns(
            "q1,q2,q3,q4 are read as a quaternion (w, x, y, z), but the file has q5 too: if \
             q1, q2, ... are joint angles, map them (j1=q1,j2=q2,...)"
                .into(),
        ));
    }
    Ok(())
}

/// What `purpose` requires of the columns found (and, for measurements, drops).
fn check_purpose(
    layout: &mut Layout,
    purpose: Purpose,
    missing: &dyn Fn(&str) -> ReadErrorKind,
) -> Result<(), ReadErrorKind> {
    if layout.position.is_none() && !matches!(purpose, Purpose::Measurements | Purpose::Poses) {
        return Err(missing("x,y,z (nominal position, mm)"));
    }
    match purpose {
        Purpose::Samples | Purpose::Targets => {
            if layout.delta.is_some() && layout.measured.is_some() {
                return Err(ReadErrorKind::ConflictingColumns(
                    "both dx,dy,dz and mx,my,mz given: keep one".into(),
                ));
            }
            if purpose == Purpose::Samples && layout.delta.is_none() && layout.measured.is_none() {
                return Err(missing(
                    "dx,dy,dz (error, mm) or mx,my,mz (measured position, mm)",
                ));
            }
            if let Some(m) = &layout.measured_orientation {
                let cols = orientation_columns(m.convention, true).join(",");
                if layout.rotation_vector.is_some() {
                    return Err(ReadErrorKind::ConflictingColumns(format!(
                        "both rx,ry,rz and {cols} given: keep one"
                    )));
                }
                if layout.nominal_orientation.is_none() {
                    return Err(missing(&format!(
                        "a,b,c (or another nominal orientation) for the measured orientation \
                         {cols}"
                    )));
                }
            }
        }
        Purpose::Poses => {
            if layout.joints.is_none() {
                return Err(missing("j1..jn (joint values)"));
            }
        }
        Purpose::Measurements => {
            if layout.joints.is_none() {
                return Err(missing("j1..jn (joint angles)"));
            }
            if layout.measured.is_none() {
                return Err(missing("mx,my,mz (measured position)"));
            }
            // Errors are what measurements lead to, not part of them.
            layout.delta = None;
            layout.rotation_vector = None;
        }
    }
    Ok(())
}

/// The header names closest to `wanted` by edit distance (at most three, closest first,
/// header order among equals), of those that share more than they differ; of a hostile
/// header only the first names are compared, so that a message costs milliseconds.
fn closest_names(wanted: &str, names: &[String]) -> Vec<String> {
    const SHOWN: usize = 3;
    const COMPARED: usize = 10_000;
    let wanted: Vec<char> = wanted.chars().collect();
    let mut scored: Vec<(usize, usize)> = names
        .iter()
        .take(COMPARED)
        .enumerate()
        .filter_map(|(i, name)| {
            let name: Vec<char> = name.chars().collect();
            let d = edit_distance(&wanted, &name);
            (2 * d < wanted.len().max(name.len())).then_some((d, i))
        })
        .collect();
    scored.sort_unstable();
    scored
        .into_iter()
        .take(SHOWN)
        .map(|(_, i)| names[i].clone())
        .collect()
}

/// The Levenshtein distance of two names: insertions, deletions and substitutions.
fn edit_distance(a: &[char], b: &[char]) -> usize {
    let mut previous: Vec<usize> = (0..=b.len()).collect();
    let mut current = vec![0; b.len() + 1];
    for (i, ca) in a.iter().enumerate() {
        current[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let substitution = previous[j] + usize::from(ca != cb);
            current[j + 1] = substitution.min(previous[j + 1] + 1).min(current[j] + 1);
        }
        std::mem::swap(&mut previous, &mut current);
    }
    previous[b.len()]
}

/// The joint columns `j1..jn`: none, or a run from `j1` without gaps; revolute joints in
/// one angle unit.
fn joints(
    names: &[String],
    find: &dyn Fn(&str) -> Option<(usize, Source)>,
    scale: &dyn Fn(&str, &Source) -> Scale,
) -> Result<Option<Vec<Field>>, ReadErrorKind> {
    let found: Vec<Option<(usize, Source)>> = JOINT_COLUMNS.iter().map(|c| find(c)).collect();
    let Some(last) = found.iter().rposition(Option::is_some) else {
        return Ok(None);
    };
    if let Some(gap) = found[..last].iter().position(Option::is_none) {
        let present: Vec<&str> = JOINT_COLUMNS
            .iter()
            .zip(&found)
            .filter(|(_, f)| f.is_some())
            .map(|(c, _)| *c)
            .collect();
        return Err(ReadErrorKind::IncompleteColumns(format!(
            "'{}' given without '{}': joints are j1..jn without gaps",
            present.join(","),
            JOINT_COLUMNS[gap]
        )));
    }
    if last + 1 == MAX_JOINTS && names.iter().any(|n| n == "j13") {
        return Err(ReadErrorKind::TooManyJoints);
    }
    let mut fields = Vec::with_capacity(last + 1);
    let mut angle: Option<(&str, AngleUnit)> = None;
    for (c, (index, source)) in JOINT_COLUMNS.iter().zip(found.into_iter().flatten()) {
        let (factor, unit) = scale(c, &source);
        if let Some(Unit::Angle(u)) = unit {
            match angle {
                Some((first, a)) if a != u => {
                    return Err(ReadErrorKind::MixedUnits(format!(
                        "'{first}' is in {} but '{c}' in {}: revolute joints take one unit",
                        a.symbol(),
                        u.symbol()
                    )))
                }
                Some(_) => {}
                None => angle = Some((c, u)),
            }
        }
        fields.push(Field {
            index,
            scale: factor,
        });
    }
    Ok(Some(fields))
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use approx::assert_abs_diff_eq;
    use nalgebra::{UnitQuaternion, Vector3};

    use super::super::{parse_samples_with, ColumnMap, SampleSet};
    use super::*;
    use crate::pose;

    fn read(text: &str, map: &str, options: ReadOptions) -> Result<SampleSet, String> {
        parse_samples_with(
            Path::new("s.csv"),
            text.as_bytes(),
            &ColumnMap::parse(map).unwrap(),
            &options,
        )
        .map_err(|e| e.to_string())
    }

    fn samples(text: &str) -> SampleSet {
        read(text, "", ReadOptions::default()).unwrap()
    }

    fn refused(text: &str, map: &str, options: ReadOptions, needles: &[&str]) {
        let message = read(text, map, options).unwrap_err();
        for needle in needles {
            assert!(message.contains(needle), "{needle:?} not in: {message}");
        }
    }

    /// Orientation errors in degrees where radians are expected (a KR150-2 sample's
    /// 0.096° read as 0.096 rad, 5.5°), and values no unit makes a robot's, are refused
    /// where they are read, with line and column; those of a robot are read.
    #[test]
    fn orientation_errors_beyond_any_robots_are_refused_with_line_and_column() {
        let header = "x,y,z,dx,dy,dz,rx,ry,rz\n";
        let good = "1000,0,500,0.1,0.2,0.3,0.000029,0.0011,0.00063\n";
        let s = samples(&format!("{header}{good}{good}"));
        assert_eq!(
            s.rotation_error_rad.unwrap()[0],
            [0.000029, 0.0011, 0.00063]
        );
        refused(
            &format!("{header}{good}1000,100,500,0.1,0.2,0.3,0.0017,0.096,0.035\n"),
            "",
            ReadOptions::default(),
            &[
                "s.csv:3:8 (column 'ry'): an orientation error of 5.855° (a rotation of 0.1022 rad)",
                "more than the 5° by which any robot's orientation misses its command",
                "look like degrees read as radians (read as degrees, 0.1022°)",
                "rx:deg,ry:deg,rz:deg",
            ],
        );
        // Mapped in degrees, the same numbers are a robot's.
        assert!(read(
            &format!("{header}1000,100,500,0.1,0.2,0.3,0.0017,0.096,0.035\n"),
            "rx:deg,ry:deg,rz:deg",
            ReadOptions::default()
        )
        .is_ok());
        for absurd in ["1e20", "1e308", "-1.7976931348623157e308"] {
            refused(
                &format!("{header}{good}1000,100,500,0.1,0.2,0.3,{absurd},0,0\n"),
                "",
                ReadOptions::default(),
                &["s.csv:3:7 (column 'rx')", "no unit makes it a robot's"],
            );
        }
        // Three components of 1e308: the norm overflows, and is refused all the same.
        refused(
            &format!("{header}1e3,1,5e2,0,0,0,1e308,1e308,1e308\n"),
            "",
            ReadOptions::default(),
            &["s.csv:2:9 (column 'rz'): an orientation error of 1.732e308 rad, more than"],
        );
        // Computed from orientations: a measured orientation 10° from the nominal one.
        refused(
            "x,y,z,dx,dy,dz,a,b,c,ma,mb,mc\n1000,0,500,0,0,0,0,90,0,0.01,90,0\n\
             1000,0,600,0,0,0,0,90,0,10,90,0\n",
            "",
            ReadOptions::default(),
            &[
                "s.csv:3:10 (column 'ma')",
                "an orientation error of 10°",
                "are both in one convention and one unit",
            ],
        );
    }

    /// Positions and errors beyond a kilometre, or overflowing in their unit's conversion,
    /// are refused with line and column (a build once failed on them with "radius must be
    /// finite and positive").
    #[test]
    fn coordinates_beyond_a_kilometre_are_refused_with_line_and_column() {
        let header = "x,y,z,dx,dy,dz\n";
        refused(
            &format!("{header}1000,0,500,0.1,0,0\n1e308,0,500,0.1,0,0\n"),
            "",
            ReadOptions::default(),
            &["s.csv:3:1 (column 'x'): 1e308 mm is beyond the ±1000000 mm (1 km)"],
        );
        refused(
            &format!("{header}1000,0,500,0.1,0,2e6\n"),
            "",
            ReadOptions::default(),
            &["s.csv:2:6 (column 'dz'): 2000000 mm"],
        );
        // Finite in metres, infinite in millimetres.
        refused(
            &format!("{header}1.7e308,0,0.5,0,0,0\n"),
            "x:m,y:m,z:m",
            ReadOptions::default(),
            &["s.csv:2:1 (column 'x'): inf mm"],
        );
        assert!(read(
            &format!("{header}999999,0,0,0,0,0\n"),
            "",
            ReadOptions::default()
        )
        .is_ok());
    }

    #[test]
    fn the_separator_is_the_one_the_header_uses_most() {
        assert_eq!(Delimiter::detect(b"x,y,z"), Delimiter::Comma);
        assert_eq!(Delimiter::detect(b"x;y;z"), Delimiter::Semicolon);
        assert_eq!(Delimiter::detect(b"x\ty\tz"), Delimiter::Tab);
        assert_eq!(Delimiter::detect(b"x"), Delimiter::Comma);
        // Quoted names may hold other separators.
        assert_eq!(
            Delimiter::detect(b"\"x, mm\";\"y, mm\";\"z, mm\";\"a,b,c\""),
            Delimiter::Semicolon
        );
        // A tie goes to the comma, then the semicolon.
        assert_eq!(Delimiter::detect(b"a,b;c"), Delimiter::Comma);
        assert_eq!(Delimiter::detect(b"a\tb;c"), Delimiter::Semicolon);
        for (text, separator) in [
            ("x,y,z,dx,dy,dz\n1,2,3,0.5,0,0\n", ","),
            ("x;y;z;dx;dy;dz\n1;2;3;0.5;0;0\n", ";"),
            ("x\ty\tz\tdx\tdy\tdz\n1\t2\t3\t0.5\t0\t0\n", "\t"),
        ] {
            let s = samples(text);
            assert_eq!(s.nominal_mm, vec![[1.0, 2.0, 3.0]], "{separator:?}");
            assert_eq!(s.error_mm, vec![[0.5, 0.0, 0.0]], "{separator:?}");
        }
        // Padded tab-separated fields, a comment, CRLF line ends.
        let s = samples("# tracker export\r\n x \t y \t z \t dx \t dy \t dz \r\n 1 \t 2 \t 3 \t 0.5 \t 0 \t 0 \r\n");
        assert_eq!(s.nominal_mm, vec![[1.0, 2.0, 3.0]]);
        assert_eq!(s.lines, vec![3]);
    }

    #[test]
    fn decimal_commas_are_read_where_commas_do_not_separate() {
        let s = samples("x;y;z;dx;dy;dz\n1234,56;-2,5;3;0,125;-1,5E-3;2,02011E+2\n5;6;7;0;0;0\n");
        assert_eq!(s.nominal_mm[0], [1234.56, -2.5, 3.0]);
        assert_eq!(s.error_mm[0], [0.125, -1.5e-3, 2.02011e2]);
        let s = samples("x\ty\tz\tdx\tdy\tdz\n1,5\t2\t3\t0\t0\t0\n");
        assert_eq!(s.nominal_mm[0], [1.5, 2.0, 3.0]);
        // A decimal point in a semicolon file is read as such.
        let s = samples("x;y;z;dx;dy;dz\n1.5;2;3;0;0;0\n");
        assert_eq!(s.nominal_mm[0], [1.5, 2.0, 3.0]);
        // A number longer than the stack buffer.
        let long = format!("1,{}", "5".repeat(80));
        let s = samples(&format!("x;y;z;dx;dy;dz\n{long};2;3;0;0;0\n"));
        assert_abs_diff_eq!(s.nominal_mm[0][0], 1.5555555555555556, epsilon = 1e-15);
    }

    #[test]
    fn the_first_decimal_mark_decides_and_every_number_must_agree() {
        // Integers first: the mark is decided by the first number that has one.
        refused(
            "x;y;z;dx;dy;dz\n1;2;3;0;0;0\n4;5;6;0,5;0;0\n7;8;9;0.5;0;0\n",
            "",
            ReadOptions::default(),
            &[
                "s.csv:4:4 (column 'dx')",
                "'0.5' has a decimal point",
                "decimal commas",
                "line 3, column 4 'dx'",
            ],
        );
        refused(
            "x;y;z;dx;dy;dz\n1.5;2;3;0,5;0;0\n",
            "",
            ReadOptions::default(),
            &["s.csv:2:4 (column 'dx')", "'0,5' has a decimal comma"],
        );
        // Thousands separators are not read as decimal marks.
        refused(
            "x;y;z;dx;dy;dz\n1.234,5;2;3;0;0;0\n",
            "",
            ReadOptions::default(),
            &["s.csv:2:1 (column 'x')", "not a number: '1.234,5'"],
        );
        refused(
            "x;y;z;dx;dy;dz\n1,234,5;2;3;0;0;0\n",
            "",
            ReadOptions::default(),
            &["s.csv:2:1 (column 'x')", "not a number: '1,234,5'"],
        );
        // A quoted decimal comma in a comma-separated file.
        refused(
            "x,y,z,dx,dy,dz\n\"1,5\",2,3,0,0,0\n",
            "",
            ReadOptions::default(),
            &["s.csv:2:1", "comma-separated file has decimal points"],
        );
    }

    #[test]
    fn the_separator_and_the_decimal_mark_can_be_given() {
        let comma = ReadOptions {
            decimal: Some(Decimal::Comma),
            ..ReadOptions::default()
        };
        let s = read("x,y,z,dx,dy,dz\n\"1,5\",2,3,0,0,0\n", "", comma).unwrap();
        assert_eq!(s.nominal_mm[0], [1.5, 2.0, 3.0]);
        refused(
            "x;y;z;dx;dy;dz\n1.5;2;3;0;0;0\n",
            "",
            comma,
            &["s.csv:2:1", "read with --decimal comma"],
        );
        let point = ReadOptions {
            decimal: Some(Decimal::Point),
            ..ReadOptions::default()
        };
        refused(
            "x;y;z;dx;dy;dz\n1,5;2;3;0;0;0\n",
            "",
            point,
            &["s.csv:2:1", "'1,5' has a decimal comma"],
        );
        let tab = ReadOptions {
            delimiter: Some(Delimiter::Tab),
            ..ReadOptions::default()
        };
        // A header that uses more semicolons than tabs, read with tabs as told.
        let text = "x\ty\tz\tdx\tdy\tdz\tnote; with; seven; semicolons; in; it; really\n\
                    1\t2\t3\t0\t0\t0\tfree; text\n";
        let header = text.lines().next().unwrap();
        assert_eq!(Delimiter::detect(header.as_bytes()), Delimiter::Semicolon);
        let s = read(text, "", tab).unwrap();
        assert_eq!(s.nominal_mm[0], [1.0, 2.0, 3.0]);
    }

    #[test]
    fn a_missing_column_names_the_separator_read_with() {
        refused(
            "u;v;dx;dy;dz\n1;2;0;0;0\n",
            "",
            ReadOptions::default(),
            &[
                "s.csv:1:",
                "missing column x,y,z",
                "read with semicolons as separators (detected from it)",
            ],
        );
        refused(
            "x;y;z;dx;dy;dz\n1;2;3;0;0;0\n",
            "",
            ReadOptions {
                delimiter: Some(Delimiter::Comma),
                ..ReadOptions::default()
            },
            &[
                "s.csv:1:",
                "missing column x,y,z",
                "read with commas as separators (as given by --delimiter)",
                "seems separated by semicolons; give --delimiter semicolon",
            ],
        );
    }

    /// A mapping that names a column the header lacks is an error naming it and the
    /// closest names, not a group read as incomplete or absent.
    #[test]
    fn a_mapped_column_the_header_lacks_is_named_with_the_closest() {
        let text = "x_t,y_t,z_t,x_dif,y_dif,z_dif,joint_1,joint_2\n1,2,3,0.1,0.2,0.3,10,20\n";
        let map = "x=x_t,y=y_t,z=z_t,dx=xdif,dy=y_dif,dz=z_dif";
        assert_eq!(
            read(text, map, ReadOptions::default()).unwrap_err(),
            "s.csv:1: the column mapping takes 'dx' from a column 'xdif', which the header \
             does not have; the closest are 'x_dif', 'y_dif', 'z_dif'"
        );
        let map = "x=x_t,y=y_t,z=z_t,dx=x_dif,dy=y_dif,dz=z_dif,j1=joint1,j2=joint_2";
        assert_eq!(
            read(text, map, ReadOptions::default()).unwrap_err(),
            "s.csv:1: the column mapping takes 'j1' from a column 'joint1', which the header \
             does not have; the closest are 'joint_1', 'joint_2'"
        );
        // Nothing alike: no suggestion; the short form too.
        refused(
            text,
            "x=x_t,y=y_t,z=z_t,dx=x_dif,dy=y_dif,dz=z_dif,config=branch",
            ReadOptions::default(),
            &["takes 'config' from a column 'branch', which the header does not have"],
        );
        refused(
            text,
            "x=x_t,y=y_t,z=z_t,dx=x_dif,dy=y_dif,dz=z_dif,rx:deg",
            ReadOptions::default(),
            &["takes 'rx' from a column 'rx', which the header does not have"],
        );
        let map = "x=x_t,y=y_t,z=z_t,dx=x_dif,dy=y_dif,dz=z_dif,j1=joint_1,j2=joint_2";
        let s = read(text, map, ReadOptions::default()).unwrap();
        assert_eq!(s.joints.unwrap().count(), 2);
    }

    #[test]
    fn a_byte_order_mark_is_not_part_of_the_first_name() {
        let s = samples("\u{feff}x;y;z;dx;dy;dz\n1;2;3;0;0;0\n");
        assert_eq!(s.nominal_mm[0], [1.0, 2.0, 3.0]);
    }

    #[test]
    fn units_apply_per_group_with_file_wide_defaults() {
        // Nominal in metres, measured in millimetres; nominal angles in radians, measured
        // in degrees; joints in radians, one prismatic joint in metres.
        let text = "gx;gy;gz;mx;my;mz;ga;gb;gc;ma;mb;mc;s1;s2;rail\n\
                    0,4;-0,4;0,8;400,5;-400;800;0;1,5707963267948966;0;0,01;90;0;0,5;-1;1,25\n";
        let map = "x=gx:m,y=gy:m,z=gz:m,a=ga:rad,b=gb:rad,c=gc:rad,j1=s1:rad,j2=s2:rad,j3=rail:m";
        let s = read(text, map, ReadOptions::default()).unwrap();
        assert_eq!(s.nominal_mm[0], [400.0, -400.0, 800.0]);
        assert_abs_diff_eq!(s.error_mm[0][0], 0.5, epsilon = 1e-12);
        assert_abs_diff_eq!(s.error_mm[0][1], 0.0, epsilon = 1e-12);
        assert_eq!(s.joints_rad(0), Some(&[0.5, -1.0, 1250.0][..]));
        // Rz(0.01°) before Ry(90°): 0.01° about the base z axis.
        let r = s.rotation_error_rad.as_ref().unwrap()[0];
        assert_abs_diff_eq!(r[2], 0.01f64.to_radians(), epsilon = 1e-12);
        // The same through file-wide defaults and the short form.
        let text = "x;y;z;mx;my;mz;a;b;c;ma;mb;mc;j1;j2;j3\n\
                    0,4;-0,4;0,8;400,5;-400;800;0;1,5707963267948966;0;0,01;90;0;0,5;-1;1,25\n";
        let options = ReadOptions {
            length_unit: LengthUnit::Metre,
            angle_unit: AngleUnit::Radian,
            ..ReadOptions::default()
        };
        let t = read(text, "mx:mm,my:mm,mz:mm,ma:deg,mb:deg,mc:deg,j3:m", options).unwrap();
        assert_eq!(t, s);
    }

    /// A prismatic joint's column (a track, as `tablec simulate` writes it) is a length
    /// where the mapping gives no unit: in the file's length unit, not degrees; a unit
    /// mapped on it still holds.
    #[test]
    fn a_prismatic_joints_column_is_a_length() {
        let text = "x,y,z,dx,dy,dz,j1,j2\n1,2,3,0,0,0,1500,90\n";
        let track = ReadOptions {
            prismatic_joints: 1,
            ..ReadOptions::default()
        };
        let row = |map: &str, options| {
            read(text, map, options)
                .unwrap()
                .joints_rad(0)
                .unwrap()
                .to_vec()
        };
        assert_eq!(row("", track), [1500.0, 90f64.to_radians()]);
        assert_eq!(
            row("", ReadOptions::default()),
            [1500f64.to_radians(), 90f64.to_radians()]
        );
        let metres = ReadOptions {
            length_unit: LengthUnit::Metre,
            ..track
        };
        assert_eq!(row("", metres), [1_500_000.0, 90f64.to_radians()]);
        assert_eq!(row("j1:mm", metres), [1500.0, 90f64.to_radians()]);
    }

    #[test]
    fn the_rotation_vector_is_in_radians_unless_mapped_in_degrees() {
        let text = "x,y,z,dx,dy,dz,rx,ry,rz,j1\n1,2,3,0,0,0,0.001,0,0,90\n";
        let radians = ReadOptions {
            angle_unit: AngleUnit::Radian,
            ..ReadOptions::default()
        };
        for options in [ReadOptions::default(), radians] {
            let s = read(text, "", options).unwrap();
            assert_eq!(s.rotation_error_rad.unwrap()[0], [0.001, 0.0, 0.0]);
        }
        let s = read(text, "rx:deg,ry:deg,rz:deg", ReadOptions::default()).unwrap();
        assert_eq!(
            s.rotation_error_rad.as_ref().unwrap()[0],
            [0.001f64.to_radians(), 0.0, 0.0]
        );
        assert_eq!(s.joints_rad(0), Some(&[90f64.to_radians()][..]));
    }

    #[test]
    fn a_group_in_two_units_is_refused() {
        refused(
            "x,y,z,dx,dy,dz\n1,2,3,0,0,0\n",
            "x:m,z:m",
            ReadOptions::default(),
            &[
                "s.csv:1:",
                "mixed units",
                "'x' is in m but 'y' in mm",
                "x,y,z take one unit",
            ],
        );
        refused(
            "x,y,z,dx,dy,dz,a,b,c\n1,2,3,0,0,0,0,0,0\n",
            "c:rad",
            ReadOptions::default(),
            &["'a' is in deg but 'c' in rad"],
        );
        refused(
            "x,y,z,dx,dy,dz,j1,j2\n1,2,3,0,0,0,0,0\n",
            "j2:rad",
            ReadOptions::default(),
            &["'j1' is in deg but 'j2' in rad: revolute joints take one unit"],
        );
    }

    thread_local! {
        /// Readings of this thread that took the chunked way.
        pub(super) static CHUNKED: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
    }

    /// Reading in chunks on the thread pool gives the CSV reader's rows, or its error, to
    /// the bit: random files of every layout, both separators and decimal marks, `\n` and
    /// `\r\n`, blank and comment lines, a last line with or without its end, and faults (a
    /// field too many or too few, a word, a foreign decimal mark, an empty field, a
    /// padded field, a quoted one), in chunks of one byte to a megabyte.
    #[test]
    fn reading_in_chunks_is_the_csv_readers_reading() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        // Texts read in chunks, by line end.
        let mut chunked_texts = [0; 2];
        for case in 0..600 {
            let sep = if rng.gen_bool(0.3) { ";" } else { "," };
            let decimal_comma = sep == ";" && rng.gen_bool(0.5);
            let mut names = vec!["x", "y", "z", "dx", "dy", "dz"];
            if rng.gen_bool(0.4) {
                names.extend(["a", "b", "c"]);
            }
            if rng.gen_bool(0.4) {
                names.extend(["j1", "j2", "j3"]);
            }
            if rng.gen_bool(0.3) {
                names.push("config");
            }
            let eol = if rng.gen_bool(0.3) { "\r\n" } else { "\n" };
            let mut text = String::new();
            if rng.gen_bool(0.3) {
                text += &format!("# a comment{eol}");
            }
            if rng.gen_bool(0.2) {
                text += eol;
            }
            text += &(names.join(sep) + eol);
            let rows = rng.gen_range(0..40);
            for r in 0..rows {
                match rng.gen_range(0..25) {
                    0 => text += eol,
                    1 => text += &format!("# between{eol}"),
                    _ => {}
                }
                let mut fields: Vec<String> = (names.iter())
                    .map(|&name| match name {
                        "config" => rng.gen_range(0..8).to_string(),
                        _ => {
                            let v =
                                format!("{:.*}", rng.gen_range(0..6), rng.gen_range(-900.0..900.0));
                            if decimal_comma {
                                v.replace('.', ",")
                            } else {
                                v
                            }
                        }
                    })
                    .collect();
                let f = rng.gen_range(0..fields.len());
                match rng.gen_range(0..80) {
                    0 => fields.push("1".into()),
                    1 => drop(fields.pop()),
                    2 => fields[f] = "word".into(),
                    3 => fields[f] = "1,5".into(),
                    4 => fields[f] = "2.5".into(),
                    5 => fields[f].clear(),
                    6 => fields[f] = format!(" {} ", fields[f]),
                    7 => fields[f] = format!("\"{}\"", fields[f]),
                    _ => {}
                }
                text += &fields.join(sep);
                if r + 1 < rows || rng.gen_bool(0.7) {
                    text += eol;
                }
            }
            let read = |cut| {
                parse_in(
                    Path::new("r.csv"),
                    text.as_bytes(),
                    &ColumnMap::default(),
                    &ReadOptions::default(),
                    Purpose::Samples,
                    cut,
                )
            };
            let want = read(Cut::CsvReader);
            for chunk_bytes in [1, 5, 64, CHUNK_BYTES] {
                let before = CHUNKED.with(|c| c.get());
                assert_eq!(
                    read(Cut::Chunks(chunk_bytes)),
                    want,
                    "case {case}, chunks of {chunk_bytes}:\n{text}"
                );
                chunked_texts[usize::from(eol == "\r\n")] += CHUNKED.with(|c| c.get()) - before;
            }
        }
        // Most texts are read in chunks, with either line end (the others have quotes).
        assert!(
            chunked_texts[0] > 1000 && chunked_texts[1] > 400,
            "{chunked_texts:?}"
        );
    }

    #[test]
    fn any_joint_count_from_one_to_twelve() {
        for n in [1usize, 6, 7, 12] {
            let names: Vec<String> = (1..=n).map(|i| format!("j{i}")).collect();
            let values: Vec<String> = (1..=n).map(|i| format!("{}", 10 * i)).collect();
            let text = format!(
                "x,y,z,dx,dy,dz,{}\n1,2,3,0,0,0,{}\n",
                names.join(","),
                values.join(",")
            );
            let s = samples(&text);
            assert_eq!(s.joint_count(), Some(n));
            let expected: Vec<f64> = (1..=n).map(|i| (10.0 * i as f64).to_radians()).collect();
            assert_eq!(s.joints_rad(0), Some(expected.as_slice()));
        }
        // Mapped, in any column order.
        let s = read(
            "q8,q7,q6,q5,q4,q3,q2,q1,x,y,z,dx,dy,dz\n8,7,6,5,4,3,2,1,1,2,3,0,0,0\n",
            "j1=q1,j2=q2,j3=q3,j4=q4,j5=q5,j6=q6,j7=q7,j8=q8",
            ReadOptions::default(),
        )
        .unwrap();
        let expected: Vec<f64> = (1..=8).map(|i| (i as f64).to_radians()).collect();
        assert_eq!(s.joints_rad(0), Some(expected.as_slice()));
    }

    #[test]
    fn joints_with_gaps_or_beyond_twelve_are_refused() {
        let o = ReadOptions::default();
        refused(
            "x,y,z,dx,dy,dz,j1,j2,j4\n1,2,3,0,0,0,1,2,4\n",
            "",
            o,
            &["s.csv:1:", "'j1,j2,j4' given without 'j3'", "without gaps"],
        );
        refused(
            "x,y,z,dx,dy,dz,j2,j3\n1,2,3,0,0,0,1,2\n",
            "",
            o,
            &["'j2,j3' given without 'j1'"],
        );
        let names: Vec<String> = (1..=13).map(|i| format!("j{i}")).collect();
        let text = format!(
            "x,y,z,dx,dy,dz,{}\n1,2,3,0,0,0{}\n",
            names.join(","),
            ",0".repeat(13)
        );
        refused(&text, "", o, &["s.csv:1:", "more than 12 joint columns"]);
    }

    #[test]
    fn joint_columns_named_like_a_quaternion_are_joints_when_mapped() {
        let text = "x,y,z,dx,dy,dz,q1,q2,q3,q4,q5,q6\n1,2,3,0,0,0,0,0,0,0,0,90\n";
        refused(
            text,
            "",
            ReadOptions::default(),
            &["s.csv:1:", "the file has q5 too", "j1=q1,j2=q2"],
        );
        let s = read(
            text,
            "j1=q1,j2=q2,j3=q3,j4=q4,j5=q5,j6=q6",
            ReadOptions::default(),
        )
        .unwrap();
        assert!(s.nominal_rotation.is_none());
        assert_eq!(s.joints_rad(0).unwrap()[5], 90f64.to_radians());
    }

    #[test]
    fn line_numbers_count_blank_lines_comments_and_crlf_line_ends() {
        for (text, line) in [
            ("x,y,z,dx,dy,dz\n\n\n1,2,3,0,0,0\n\n1,2,4,0,0,x\n", 6),
            ("x,y,z,dx,dy,dz\r\n1,2,3,0,0,0\r\n1,2,4,0,0,x\r\n", 3),
            (
                "# c\r\n\r\nx,y,z,dx,dy,dz\r\n\r\n1,2,3,0,0,0\r\n# c\r\n1,2,4,0,0,x\r\n",
                7,
            ),
            ("x;y;z;dx;dy;dz\r\n1;2;3;0;0;0\r\n\"a\nb\";2;4;0;0;0\r\n", 3),
        ] {
            let message = read(text, "", ReadOptions::default()).unwrap_err();
            let expected = format!("s.csv:{line}:");
            assert!(
                message.starts_with(&expected),
                "{expected} for {text:?}: {message}"
            );
        }
    }

    /// A nominal orientation and a measured one `exp(δ)·R` written in every convention,
    /// by numbers found independently (nalgebra's quaternion and Euler angles): the reader
    /// gives back δ, whatever the conventions of the two sides.
    #[test]
    fn every_orientation_convention_gives_the_same_error() {
        let nominal = pose::rotation_zyx_rad(0.4, std::f64::consts::FRAC_PI_2, -1.2);
        let delta = [2e-4, -1e-4, 3e-4];
        let measured = pose::rotation_from_vector(delta) * nominal;
        // Each convention's column names and numbers for a rotation (angles in degrees).
        let write = |convention: Convention, r: &Rotation3<f64>| -> Vec<f64> {
            let (roll, pitch, yaw) = r.euler_angles();
            let (xr, xp, xy) = r.inverse().euler_angles();
            let q = UnitQuaternion::from_rotation_matrix(r);
            match convention {
                Convention::KukaAbc => vec![yaw, pitch, roll],
                Convention::FanucWpr | Convention::RollPitchYaw => vec![roll, pitch, yaw],
                // R = Rx(a)·Ry(b)·Rz(c) = (Rz(−c)·Ry(−b)·Rx(−a))ᵀ.
                Convention::EulerXyz => vec![-xr, -xp, -xy],
                Convention::QuaternionWxyz => return vec![q.w, q.i, q.j, q.k],
                Convention::QuaternionXyzw => return vec![q.i, q.j, q.k, q.w],
            }
            .into_iter()
            .map(f64::to_degrees)
            .collect()
        };
        for n in Convention::ALL {
            for m in Convention::ALL {
                let names = [orientation_columns(n, false), orientation_columns(m, true)].concat();
                let values: Vec<String> = [write(n, &nominal), write(m, &measured)]
                    .concat()
                    .iter()
                    .map(|v| format!("{v:e}"))
                    .collect();
                let text = format!(
                    "x,y,z,dx,dy,dz,{}\n1,2,3,0,0,0,{}\n",
                    names.join(","),
                    values.join(",")
                );
                let s = samples(&text);
                let r = s.rotation_error_rad.as_ref().unwrap()[0];
                for a in 0..3 {
                    assert_abs_diff_eq!(r[a], delta[a], epsilon = 1e-12);
                }
                let back = &s.nominal_rotation.as_ref().unwrap()[0];
                assert_abs_diff_eq!(back.matrix(), nominal.matrix(), epsilon = 1e-12);
            }
        }
    }

    #[test]
    fn a_nominal_orientation_alone_is_kept_without_errors() {
        let s = samples("x,y,z,dx,dy,dz,roll,pitch,yaw\n1,2,3,0,0,0,90,0,0\n");
        assert!(s.rotation_error_rad.is_none());
        let r = &s.nominal_rotation.unwrap()[0];
        assert_abs_diff_eq!(r * Vector3::y(), Vector3::z(), epsilon = 1e-15);
    }

    #[test]
    fn orientation_columns_are_refused_when_they_conflict_or_are_zero() {
        let o = ReadOptions::default();
        refused(
            "x,y,z,dx,dy,dz,a,b,c,roll,pitch,yaw\n1,2,3,0,0,0,0,0,0,0,0,0\n",
            "",
            o,
            &[
                "s.csv:1:",
                "two conventions for the nominal orientation, 'a,b,c' and 'roll,pitch,yaw'",
            ],
        );
        refused(
            "x,y,z,dx,dy,dz,a,b,c,mq1,mq2,mq3,mq4,mqx,mqy,mqz,mqw\n1,2,3,0,0,0,0,0,0,1,0,0,0,0,0,0,1\n",
            "",
            o,
            &["two conventions for the measured orientation, 'mq1,mq2,mq3,mq4' and 'mqx,mqy,mqz,mqw'"],
        );
        refused(
            "x,y,z,dx,dy,dz,w,p,r,mw,mp,mr,rx,ry,rz\n1,2,3,0,0,0,0,0,0,0,0,0,0,0,0\n",
            "",
            o,
            &["both rx,ry,rz and mw,mp,mr given: keep one"],
        );
        refused(
            "x,y,z,dx,dy,dz,mex,mey,mez\n1,2,3,0,0,0,0,0,0\n",
            "",
            o,
            &["missing column a,b,c (or another nominal orientation) for the measured orientation mex,mey,mez"],
        );
        refused(
            "x,y,z,dx,dy,dz,qx,qy,qz\n1,2,3,0,0,0,0,0,0\n",
            "",
            o,
            &["'qx,qy,qz' given without 'qw'"],
        );
        refused(
            "x,y,z,dx,dy,dz,q1,q2,q3,q4\n1,2,3,0,0,0,1,0,0,0\n# a comment\n4,5,6,0,0,0,0,0,0,0.0\n",
            "",
            o,
            &["s.csv:4:7 (column 'q1')", "the quaternion is zero"],
        );
    }
}
