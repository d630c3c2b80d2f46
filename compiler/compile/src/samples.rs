//! The sample database: measured errors at commanded poses, read from CSV.
//!
//! # CSV format
//!
//! One header row, then one row per sample; lines starting with `#` are comments; fields
//! may be padded with spaces. Columns are found by name, in any order; unknown columns are
//! ignored.
//!
//! | columns | meaning | |
//! |---|---|---|
//! | `x,y,z` | nominal (commanded) position, mm, robot base frame | required |
//! | `dx,dy,dz` | measured position error = actual − nominal, mm | one of these two |
//! | `mx,my,mz` | measured actual position, mm | |
//! | `a,b,c` | nominal orientation, KUKA degrees, `R = Rz(a)·Ry(b)·Rx(c)` | optional |
//! | `rx,ry,rz` | orientation error, rotation vector of `R_actual·R_nominalᵀ`, rad | optional, or: |
//! | `ma,mb,mc` | measured orientation, KUKA degrees (needs `a,b,c`) | |
//! | `j1..j6` | joint angles, degrees | optional |
//! | `config` | inverse-kinematics configuration, integer 0-254 | optional |
//!
//! Files whose columns are named otherwise are read through a [`ColumnMap`]:
//! `x=x_t,y=y_t,z=z_t,dx=x_dif,...`; a source name prefixed by `-` is negated
//! (`dx=-x_dif` for a file that records nominal − actual).
//!
//! Every problem is an error naming the file, the line and, where there is one, the
//! column: a wrong field count, a field that is not a number, NaN or infinite, a nominal
//! position given twice, a missing column, an empty file.

use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};

use adwi_runtime::format::SampleRecord;
use adwi_runtime::method::CONFIG_UNKNOWN;

use crate::pose;

/// The canonical column names, in the order of the table above.
pub const CANONICAL_COLUMNS: [&str; 25] = [
    "x", "y", "z", "dx", "dy", "dz", "mx", "my", "mz", "a", "b", "c", "rx", "ry", "rz", "ma", "mb",
    "mc", "j1", "j2", "j3", "j4", "j5", "j6", "config",
];

/// A sample database in memory, in source order. Positions mm, base frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SampleSet {
    /// Nominal (commanded) positions, mm.
    pub nominal_mm: Vec<[f64; 3]>,
    /// Measured position errors, actual − nominal, mm.
    pub error_mm: Vec<[f64; 3]>,
    /// Nominal orientations, KUKA A, B, C degrees, when given.
    pub nominal_abc_deg: Option<Vec<[f64; 3]>>,
    /// Measured orientation errors, rotation vectors (rad, base frame), when given.
    pub rotation_error_rad: Option<Vec<[f64; 3]>>,
    /// Joint values, when given: rad (mm for prismatic joints), one row per sample.
    pub joints: Option<Joints>,
    /// Inverse-kinematics configurations, when given.
    pub config: Option<Vec<u8>>,
    /// The source line of each sample (1-based), for messages.
    pub lines: Vec<u64>,
}

impl SampleSet {
    /// The number of samples.
    pub fn len(&self) -> usize {
        self.nominal_mm.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.nominal_mm.is_empty()
    }

    /// Sample `i`'s actual position, nominal + error, mm.
    pub fn actual_mm(&self, i: usize) -> [f64; 3] {
        let (n, e) = (self.nominal_mm[i], self.error_mm[i]);
        [n[0] + e[0], n[1] + e[1], n[2] + e[2]]
    }

    /// Sample `i`'s joint values (rad; mm for prismatic joints), when the samples carry
    /// them.
    pub fn joints_rad(&self, i: usize) -> Option<&[f64]> {
        self.joints.as_ref().map(|j| j.row(i))
    }

    /// The number of joint values per sample, when the samples carry them.
    pub fn joint_count(&self) -> Option<usize> {
        self.joints.as_ref().map(Joints::count)
    }

    /// The samples at `indices`, in that order.
    pub fn subset(&self, indices: &[usize]) -> SampleSet {
        let pick = |v: &Vec<[f64; 3]>| indices.iter().map(|&i| v[i]).collect::<Vec<_>>();
        SampleSet {
            nominal_mm: pick(&self.nominal_mm),
            error_mm: pick(&self.error_mm),
            nominal_abc_deg: self.nominal_abc_deg.as_ref().map(pick),
            rotation_error_rad: self.rotation_error_rad.as_ref().map(pick),
            joints: self.joints.as_ref().map(|j| j.subset(indices)),
            config: self
                .config
                .as_ref()
                .map(|c| indices.iter().map(|&i| c[i]).collect()),
            lines: indices.iter().map(|&i| self.lines[i]).collect(),
        }
    }

    /// The samples as the runtime stores them.
    pub fn records(&self) -> Vec<SampleRecord> {
        (0..self.len())
            .map(|i| SampleRecord {
                actual_mm: self.actual_mm(i),
                nominal_mm: self.nominal_mm[i],
                error_mm: self.error_mm[i],
                rotation_error_rad: self.rotation_error_rad.as_ref().map_or([0.0; 3], |r| r[i]),
                config: self.config.as_ref().map_or(CONFIG_UNKNOWN, |c| c[i]),
            })
            .collect()
    }

    /// XXH3-64 of the sample values (not of the file's text: comments, column order and
    /// number formatting do not change it).
    pub fn source_hash(&self) -> u64 {
        // Streamed: the same digest as hashing the concatenated bytes, without holding
        // them (200 bytes a sample).
        let mut hasher = xxhash_rust::xxh3::Xxh3::new();
        let mut push = |v: f64| hasher.update(&v.to_le_bytes());
        for i in 0..self.len() {
            self.nominal_mm[i].into_iter().for_each(&mut push);
            self.error_mm[i].into_iter().for_each(&mut push);
            if let Some(r) = &self.rotation_error_rad {
                r[i].into_iter().for_each(&mut push);
            }
            if let Some(j) = &self.joints {
                j.row(i).iter().copied().for_each(&mut push);
            }
            if let Some(c) = &self.config {
                push(f64::from(c[i]));
            }
        }
        let flags = [
            self.rotation_error_rad.is_some(),
            self.joints.is_some(),
            self.config.is_some(),
        ];
        hasher.update(&flags.map(u8::from));
        hasher.digest()
    }

    /// The median distance from a sample's nominal position to its nearest neighbour's,
    /// mm: the sample spacing of a lattice, a robust one of a cloud. `None` for fewer than
    /// two samples. Above 4000 samples, the median is taken over an evenly strided subset
    /// of 4000 (each still against all samples, found through a bucket grid so that a
    /// million samples take a fraction of a second rather than minutes).
    pub fn spacing_mm(&self) -> Option<f64> {
        let n = self.len();
        if n < 2 {
            return None;
        }
        let stride = n.div_ceil(4000);
        let grid = PointGrid::new(&self.nominal_mm);
        let mut nearest: Vec<f64> = (0..n)
            .step_by(stride)
            .map(|i| grid.nearest_other_mm(&self.nominal_mm, i))
            .collect();
        nearest.sort_by(f64::total_cmp);
        Some(nearest[nearest.len() / 2])
    }

    /// The axis-aligned bounding box of the nominal positions, mm, or `None` when empty.
    pub fn nominal_bounds_mm(&self) -> Option<([f64; 3], [f64; 3])> {
        let first = *self.nominal_mm.first()?;
        Some(self.nominal_mm.iter().fold((first, first), |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1]), lo[2].min(p[2])],
                [hi[0].max(p[0]), hi[1].max(p[1]), hi[2].max(p[2])],
            )
        }))
    }
}

/// The joint values of a sample set: the same number per sample, rad for revolute joints
/// and mm for prismatic ones, in sample order (one flat array, a row per sample).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Joints {
    count: usize,
    values: Vec<f64>,
}

impl Joints {
    /// No rows yet, `count` values per row.
    pub fn new(count: usize) -> Joints {
        Joints {
            count,
            values: Vec::new(),
        }
    }

    /// The rows of `values`, `count` per row.
    ///
    /// # Panics
    ///
    /// When `values.len()` is not a multiple of `count`.
    pub fn from_flat(count: usize, values: Vec<f64>) -> Joints {
        assert!(
            count > 0 && values.len() % count == 0,
            "{} joint values are not rows of {count}",
            values.len()
        );
        Joints { count, values }
    }

    /// Appends a row.
    ///
    /// # Panics
    ///
    /// When the row does not have [`Joints::count`] values.
    pub fn push(&mut self, row: &[f64]) {
        assert_eq!(row.len(), self.count, "a joint row of the wrong length");
        self.values.extend_from_slice(row);
    }

    /// Values per row: the robot's joint count.
    pub fn count(&self) -> usize {
        self.count
    }

    /// The number of rows.
    pub fn len(&self) -> usize {
        self.values.len().checked_div(self.count).unwrap_or(0)
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// Row `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.values[i * self.count..(i + 1) * self.count]
    }

    /// Every row, in order.
    pub fn rows(&self) -> std::slice::ChunksExact<'_, f64> {
        self.values.chunks_exact(self.count.max(1))
    }

    /// Every value, row after row.
    pub fn as_flat(&self) -> &[f64] {
        &self.values
    }

    /// The rows at `indices`, in that order.
    pub fn subset(&self, indices: &[usize]) -> Joints {
        let mut out = Joints::new(self.count);
        for &i in indices {
            out.push(self.row(i));
        }
        out
    }
}

/// Points bucketed in a regular grid of about one point per bucket, for exact
/// nearest-neighbour distances without comparing every pair.
struct PointGrid {
    origin_mm: [f64; 3],
    bucket_mm: f64,
    dims: [usize; 3],
    /// Bucket `b` holds `items[starts[b]..starts[b + 1]]`.
    starts: Vec<usize>,
    items: Vec<u32>,
}

impl PointGrid {
    fn new(points: &[[f64; 3]]) -> PointGrid {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in points {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let extent = [0, 1, 2].map(|a| hi[a] - lo[a]);
        // The bucket edge that makes about as many buckets as points over the axes that
        // have an extent (a plane or a line of samples gets 2-D or 1-D bucketing).
        let target = points.len().max(1) as f64;
        let buckets_for = |edge: f64| -> f64 {
            extent
                .iter()
                .map(|e| (e / edge).floor() + 1.0)
                .product::<f64>()
        };
        let mut edge = extent
            .iter()
            .copied()
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        // Halve until the bucket count reaches the point count (at most ~60 steps: the
        // count grows with every halving along each axis with an extent).
        while buckets_for(edge / 2.0) <= target && edge > f64::MIN_POSITIVE * 2.0 {
            edge /= 2.0;
        }
        let dims = [0, 1, 2].map(|a| (extent[a] / edge) as usize + 1);
        let mut grid = PointGrid {
            origin_mm: lo,
            bucket_mm: edge,
            dims,
            starts: vec![0; dims[0] * dims[1] * dims[2] + 1],
            items: vec![0; points.len()],
        };
        let buckets: Vec<usize> = points.iter().map(|p| grid.bucket_of(*p)).collect();
        for &b in &buckets {
            grid.starts[b + 1] += 1;
        }
        for b in 0..grid.starts.len() - 1 {
            grid.starts[b + 1] += grid.starts[b];
        }
        let mut next = grid.starts.clone();
        for (i, &b) in buckets.iter().enumerate() {
            grid.items[next[b]] = i as u32;
            next[b] += 1;
        }
        grid
    }

    fn coords(&self, p: [f64; 3]) -> [usize; 3] {
        [0, 1, 2].map(|a| {
            let u = ((p[a] - self.origin_mm[a]) / self.bucket_mm).floor();
            (u.max(0.0) as usize).min(self.dims[a] - 1)
        })
    }

    fn bucket_of(&self, p: [f64; 3]) -> usize {
        let [x, y, z] = self.coords(p);
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    /// The distance from point `i` to the nearest other point, mm, computed by
    /// [`adwi_runtime::method::distance_mm`] exactly as a comparison with every point
    /// would: buckets are searched in growing shells until no unsearched bucket can hold
    /// a nearer point.
    fn nearest_other_mm(&self, points: &[[f64; 3]], i: usize) -> f64 {
        let p = points[i];
        let c = self.coords(p);
        let mut best = f64::INFINITY;
        let max_shell = self.dims.iter().copied().max().unwrap_or(1);
        for shell in 0..=max_shell {
            // Every point in shell `shell + 1` or beyond is at least `shell` bucket edges
            // away along some axis.
            if best <= shell.saturating_sub(1) as f64 * self.bucket_mm {
                break;
            }
            let range =
                |a: usize| c[a].saturating_sub(shell)..=(c[a] + shell).min(self.dims[a] - 1);
            for z in range(2) {
                for y in range(1) {
                    for x in range(0) {
                        let on_shell = [x, y, z]
                            .iter()
                            .zip(c)
                            .any(|(&v, centre)| v.abs_diff(centre) == shell);
                        if !on_shell {
                            continue;
                        }
                        let b = x + self.dims[0] * (y + self.dims[1] * z);
                        for &j in &self.items[self.starts[b]..self.starts[b + 1]] {
                            if j as usize != i {
                                let d = adwi_runtime::method::distance_mm(p, points[j as usize]);
                                best = best.min(d);
                            }
                        }
                    }
                }
            }
        }
        best
    }
}

/// Which source column supplies each canonical column, and whether it is negated.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColumnMap {
    entries: HashMap<String, (String, bool)>,
}

impl ColumnMap {
    /// Parses `canonical=source,...`; a `-` before the source negates it.
    ///
    /// # Errors
    ///
    /// An unknown canonical name, a missing `=`, an empty source or a name mapped twice.
    pub fn parse(spec: &str) -> Result<ColumnMap, String> {
        let mut map = ColumnMap::default();
        for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (canonical, source) = item
                .split_once('=')
                .ok_or_else(|| format!("column mapping '{item}' is not of the form name=column"))?;
            let canonical = canonical.trim().to_ascii_lowercase();
            if !CANONICAL_COLUMNS.contains(&canonical.as_str()) {
                return Err(format!(
                    "column mapping '{item}': '{canonical}' is not one of {}",
                    CANONICAL_COLUMNS.join(", ")
                ));
            }
            let source = source.trim();
            let (negate, source) = match source.strip_prefix('-') {
                Some(s) => (true, s.trim()),
                None => (false, source),
            };
            if source.is_empty() {
                return Err(format!("column mapping '{item}' names no source column"));
            }
            if map
                .entries
                .insert(canonical.clone(), (source.to_ascii_lowercase(), negate))
                .is_some()
            {
                return Err(format!("column mapping maps '{canonical}' twice"));
            }
        }
        Ok(map)
    }

    /// The source column name and negation for a canonical column.
    fn source(&self, canonical: &str) -> (String, bool) {
        self.entries
            .get(canonical)
            .cloned()
            .unwrap_or_else(|| (canonical.to_string(), false))
    }
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
    /// A required column is absent from the header.
    MissingColumn {
        /// The columns wanted.
        wanted: String,
        /// What the header holds instead, as read: its column count, and the separator
        /// it seems to use when that is not the one read with.
        found: String,
    },
    /// Columns that only make sense together are partly present.
    IncompleteColumns(String),
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
    /// A configuration is not an integer from 0 to 254.
    BadConfig(String),
    /// A field is not UTF-8.
    NotUtf8,
    /// The CSV syntax is broken (e.g. an unterminated quote).
    Syntax(String),
    /// A nominal position appears twice.
    DuplicatePosition {
        /// The line where it first appeared.
        first_line: u64,
    },
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
            ReadErrorKind::MissingColumn { wanted, found } => write!(
                f,
                "missing column {wanted} (name it in the header, or map it with --columns); {found}"
            ),
            ReadErrorKind::IncompleteColumns(what) => write!(f, "incomplete columns: {what}"),
            ReadErrorKind::DuplicateColumn(c) => write!(f, "column '{c}' appears twice"),
            ReadErrorKind::FieldCount { expected, found } => {
                write!(f, "{found} fields where the header has {expected}")
            }
            ReadErrorKind::NotANumber(v) => write!(f, "not a number: '{v}'"),
            ReadErrorKind::NotFinite(v) => write!(f, "not a finite number: '{v}'"),
            ReadErrorKind::BadConfig(v) => {
                write!(
                    f,
                    "configuration must be an integer from 0 to 254, found '{v}'"
                )
            }
            ReadErrorKind::NotUtf8 => write!(f, "field is not valid UTF-8"),
            ReadErrorKind::Syntax(e) => write!(f, "malformed CSV: {e}"),
            ReadErrorKind::DuplicatePosition { first_line } => write!(
                f,
                "nominal position already given on line {first_line}: each sample needs its own"
            ),
        }
    }
}

impl std::error::Error for ReadError {}

/// Reads a sample file. See the module docs for the format.
///
/// # Errors
///
/// The first problem found, with file, line and column.
pub fn read_samples(path: &Path, columns: &ColumnMap) -> Result<SampleSet, ReadError> {
    parse_samples(path, &read_file(path)?, columns)
}

fn read_file(path: &Path) -> Result<Vec<u8>, ReadError> {
    std::fs::read(path).map_err(|e| ReadError {
        path: path.to_path_buf(),
        line: None,
        column: None,
        kind: ReadErrorKind::Io(e.to_string()),
    })
}

/// Column indices of the parts a file provides.
struct Layout {
    position: [usize; 3],
    error: ErrorColumns,
    rotation: Option<RotationColumns>,
    joints: Option<[usize; 6]>,
    config: Option<usize>,
    negate: Vec<bool>,
}

enum ErrorColumns {
    None,
    Delta([usize; 3]),
    Measured([usize; 3]),
}

enum RotationColumns {
    Vector([usize; 3]),
    Measured {
        nominal: [usize; 3],
        measured: [usize; 3],
    },
}

/// A target read from a CSV: where to go and, when the file gives them, the joint angles
/// the controller will use.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetRow {
    /// Position and configuration.
    pub target: adwi_runtime::Target,
    /// Joint values `j1..jn`, rad (mm for prismatic joints), when the file has them.
    pub joints_rad: Option<Vec<f64>>,
}

/// Reads a CSV of targets: `x,y,z` (mm, base frame), optionally `config` and `j1..j6`
/// (degrees), through the same reader and column mapping as samples; other columns
/// (errors, say) are ignored, and positions may repeat.
///
/// # Errors
///
/// As [`read_samples`], but error columns are not required.
pub fn read_targets(path: &Path, columns: &ColumnMap) -> Result<Vec<TargetRow>, ReadError> {
    let set = parse(path, &read_file(path)?, columns, Purpose::Targets)?;
    Ok((0..set.len())
        .map(|i| TargetRow {
            target: adwi_runtime::Target {
                position_mm: set.nominal_mm[i],
                config: set.config.as_ref().map(|c| c[i]),
            },
            joints_rad: set.joints_rad(i).map(<[f64]>::to_vec),
        })
        .collect())
}

/// Parses sample CSV held in memory; `path` only names it in messages.
///
/// # Errors
///
/// As [`read_samples`].
pub fn parse_samples(
    path: &Path,
    bytes: &[u8],
    columns: &ColumnMap,
) -> Result<SampleSet, ReadError> {
    parse(path, bytes, columns, Purpose::Samples)
}

#[derive(Clone, Copy, PartialEq)]
enum Purpose {
    Samples,
    Targets,
}

fn parse(
    path: &Path,
    bytes: &[u8],
    columns: &ColumnMap,
    purpose: Purpose,
) -> Result<SampleSet, ReadError> {
    let error = |line: Option<u64>, column: Option<(usize, String)>, kind| ReadError {
        path: path.to_path_buf(),
        line,
        column,
        kind,
    };
    // Comment lines are removed here rather than by the CSV reader, whose line numbers do
    // not count them consistently; `physical[n - 1]` is the file line of filtered line n.
    let mut filtered = Vec::with_capacity(bytes.len());
    let mut physical = Vec::new();
    for (i, line) in bytes.split_inclusive(|&b| b == b'\n').enumerate() {
        if line.first() != Some(&b'#') {
            filtered.extend_from_slice(line);
            physical.push(i as u64 + 1);
        }
    }
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .has_headers(false)
        .flexible(true)
        .from_reader(filtered.as_slice());
    let mut header = csv::ByteRecord::new();
    match reader.read_byte_record(&mut header) {
        Ok(true) => {}
        Ok(false) => return Err(error(None, None, ReadErrorKind::Empty)),
        Err(e) => return Err(csv_error(path, e, &|_| 1)),
    }
    let line_at = |p: Option<&csv::Position>| {
        p.map_or(0, |p| {
            let n = p.line() as usize;
            physical
                .get(n.saturating_sub(1))
                .copied()
                .unwrap_or(p.line())
        })
    };
    let header_line = line_at(header.position());
    let mut names = Vec::with_capacity(header.len());
    // A set beside the list: a linear `contains` per column is quadratic in the column
    // count, minutes for a hostile header of a million columns.
    let mut distinct = std::collections::HashSet::with_capacity(header.len());
    for field in header.iter() {
        let name = std::str::from_utf8(field)
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
    let layout =
        layout(&names, columns, purpose).map_err(|kind| error(Some(header_line), None, kind))?;

    let mut set = SampleSet {
        nominal_abc_deg: layout
            .rotation
            .as_ref()
            .filter(|r| matches!(r, RotationColumns::Measured { .. }))
            .map(|_| Vec::new()),
        rotation_error_rad: layout.rotation.as_ref().map(|_| Vec::new()),
        joints: layout.joints.map(|cols| Joints::new(cols.len())),
        config: layout.config.map(|_| Vec::new()),
        ..SampleSet::default()
    };
    // Rows are at most the lines counted above: reserve once rather than grow.
    let rows = physical.len();
    set.nominal_mm.reserve(rows);
    set.error_mm.reserve(rows);
    set.lines.reserve(rows);
    // Keys are the positions' bits, not attacker-chosen strings worth SipHash's cost.
    let mut seen: rustc_hash::FxHashMap<[u64; 3], u64> = rustc_hash::FxHashMap::default();
    seen.reserve(rows);
    // One record buffer for every row: a million-row file must not cost a million
    // allocations.
    let mut record = csv::ByteRecord::new();
    loop {
        match reader.read_byte_record(&mut record) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(csv_error(path, e, &line_at)),
        }
        let line = line_at(record.position());
        if record.len() != names.len() {
            // A blank line is skipped by the reader; a row with one empty field is not.
            return Err(error(
                Some(line),
                None,
                ReadErrorKind::FieldCount {
                    expected: names.len() as u64,
                    found: record.len() as u64,
                },
            ));
        }
        let number = |index: usize| -> Result<f64, ReadError> {
            let column = || Some((index + 1, names[index].clone()));
            let text = std::str::from_utf8(&record[index])
                .map_err(|_| error(Some(line), column(), ReadErrorKind::NotUtf8))?;
            let value: f64 = text.parse().map_err(|_| {
                error(
                    Some(line),
                    column(),
                    ReadErrorKind::NotANumber(truncated(text)),
                )
            })?;
            if !value.is_finite() {
                return Err(error(
                    Some(line),
                    column(),
                    ReadErrorKind::NotFinite(truncated(text)),
                ));
            }
            Ok(if layout.negate[index] { -value } else { value })
        };
        let triple = |cols: [usize; 3]| -> Result<[f64; 3], ReadError> {
            Ok([number(cols[0])?, number(cols[1])?, number(cols[2])?])
        };
        let nominal = triple(layout.position)?;
        let error_mm = match layout.error {
            ErrorColumns::Delta(cols) => triple(cols)?,
            ErrorColumns::None => [0.0; 3],
            ErrorColumns::Measured(cols) => {
                let m = triple(cols)?;
                [m[0] - nominal[0], m[1] - nominal[1], m[2] - nominal[2]]
            }
        };
        match &layout.rotation {
            Some(RotationColumns::Vector(cols)) => {
                let r = triple(*cols)?;
                push(&mut set.rotation_error_rad, r);
            }
            Some(RotationColumns::Measured { nominal, measured }) => {
                let abc = triple(*nominal)?;
                let measured = triple(*measured)?;
                let r = pose::orientation_error(
                    &pose::rotation_from_kuka_abc_deg(abc),
                    &pose::rotation_from_kuka_abc_deg(measured),
                );
                push(&mut set.nominal_abc_deg, abc);
                push(&mut set.rotation_error_rad, r);
            }
            None => {}
        }
        if let (Some(cols), Some(joints)) = (layout.joints, set.joints.as_mut()) {
            let mut q = [0.0; 6];
            for (v, c) in q.iter_mut().zip(cols) {
                *v = number(c)?.to_radians();
            }
            joints.push(&q);
        }
        if let Some(c) = layout.config {
            let text = String::from_utf8_lossy(&record[c]).into_owned();
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
            push(&mut set.config, config);
        }
        // +0.0 folds -0.0 into 0.0, so both spellings of zero are the same position.
        let key = nominal.map(|v| (v + 0.0).to_bits());
        if let (Purpose::Samples, Some(&first_line)) = (purpose, seen.get(&key)) {
            return Err(error(
                Some(line),
                None,
                ReadErrorKind::DuplicatePosition { first_line },
            ));
        }
        seen.insert(key, line);
        set.nominal_mm.push(nominal);
        set.error_mm.push(error_mm);
        set.lines.push(line);
    }
    if set.is_empty() {
        return Err(error(Some(header_line), None, ReadErrorKind::NoSamples));
    }
    Ok(set)
}

fn push<T>(column: &mut Option<Vec<T>>, value: T) {
    if let Some(v) = column {
        v.push(value);
    }
}

fn truncated(text: &str) -> String {
    const MAX: usize = 40;
    match text.char_indices().nth(MAX) {
        Some((cut, _)) => format!("{}…", &text[..cut]),
        None => text.to_string(),
    }
}

fn csv_error(
    path: &Path,
    e: csv::Error,
    line_at: &dyn Fn(Option<&csv::Position>) -> u64,
) -> ReadError {
    let line = e.position().map(|p| line_at(Some(p)));
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

/// What a header holds, for a missing-column message: how many columns were read with the
/// comma as separator, and which other separator the text suggests when it is one column.
fn describe_header(names: &[String]) -> String {
    const SHOWN: usize = 60;
    let mut text = names.join(",");
    if let Some((cut, _)) = text.char_indices().nth(SHOWN) {
        text.truncate(cut);
        text.push('…');
    }
    let columns = match names.len() {
        1 => "1 column".to_string(),
        n => format!("{n} columns"),
    };
    let seen = [(';', "semicolons"), ('\t', "tabs"), ('|', "vertical bars")]
        .into_iter()
        .filter(|(c, _)| names.len() == 1 && names[0].contains(*c))
        .max_by_key(|(c, _)| names[0].matches(*c).count());
    match seen {
        Some((_, name)) => format!(
            "the header, read with commas as separators, is {columns} ('{text}'): the file is \
             separated by {name}, and tablec reads comma-separated files"
        ),
        None => format!("the header, read with commas as separators, has {columns}: '{text}'"),
    }
}

/// Finds the columns of each part; all-or-none groups must be complete.
fn layout(names: &[String], map: &ColumnMap, purpose: Purpose) -> Result<Layout, ReadErrorKind> {
    let missing = |wanted: &str| ReadErrorKind::MissingColumn {
        wanted: wanted.to_string(),
        found: describe_header(names),
    };
    let mut negate = vec![false; names.len()];
    let mut find = |canonical: &str| -> Option<usize> {
        let (source, neg) = map.source(canonical);
        let index = names.iter().position(|n| *n == source)?;
        negate[index] = neg;
        Some(index)
    };
    let mut group = |cols: &[&str]| -> Result<Option<Vec<usize>>, ReadErrorKind> {
        let found: Vec<Option<usize>> = cols.iter().map(|c| find(c)).collect();
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
        Ok(Some(found.into_iter().flatten().collect()))
    };
    let three = |v: Vec<usize>| [v[0], v[1], v[2]];
    let position = group(&["x", "y", "z"])?
        .map(three)
        .ok_or_else(|| missing("x,y,z (nominal position, mm)"))?;
    let delta = group(&["dx", "dy", "dz"])?.map(three);
    let measured = group(&["mx", "my", "mz"])?.map(three);
    let error = match (delta, measured) {
        (Some(d), None) => ErrorColumns::Delta(d),
        (None, Some(m)) => ErrorColumns::Measured(m),
        (Some(_), Some(_)) => {
            return Err(ReadErrorKind::IncompleteColumns(
                "both dx,dy,dz and mx,my,mz given: keep one".into(),
            ))
        }
        (None, None) if purpose == Purpose::Targets => ErrorColumns::None,
        (None, None) => {
            return Err(missing(
                "dx,dy,dz (error, mm) or mx,my,mz (measured position, mm)",
            ))
        }
    };
    let nominal_abc = group(&["a", "b", "c"])?.map(three);
    let vector = group(&["rx", "ry", "rz"])?.map(three);
    let measured_abc = group(&["ma", "mb", "mc"])?.map(three);
    let rotation = match (nominal_abc, vector, measured_abc) {
        (_, Some(_), Some(_)) => {
            return Err(ReadErrorKind::IncompleteColumns(
                "both rx,ry,rz and ma,mb,mc given: keep one".into(),
            ))
        }
        (_, Some(v), None) => Some(RotationColumns::Vector(v)),
        (Some(nominal), None, Some(measured)) => {
            Some(RotationColumns::Measured { nominal, measured })
        }
        (None, None, Some(_)) => {
            return Err(missing(
                "a,b,c (nominal orientation) for the measured orientation ma,mb,mc",
            ))
        }
        (_, None, None) => None,
    };
    let joints =
        group(&["j1", "j2", "j3", "j4", "j5", "j6"])?.map(|v| [v[0], v[1], v[2], v[3], v[4], v[5]]);
    let config = find("config");
    Ok(Layout {
        position,
        error,
        rotation,
        joints,
        config,
        negate,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<SampleSet, ReadError> {
        parse_samples(Path::new("s.csv"), text.as_bytes(), &ColumnMap::default())
    }

    #[test]
    fn reads_errors_comments_and_padding() {
        let s = parse(
            "# header comment\nx, y, z, dx, dy, dz\n1,2,3,0.1,0.2,0.3\n# mid\n4,5,6,-1,-2,-3\n",
        )
        .unwrap();
        assert_eq!(s.nominal_mm, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(s.error_mm[1], [-1.0, -2.0, -3.0]);
        assert_eq!(s.lines, vec![3, 5]);
        assert!(s.rotation_error_rad.is_none() && s.config.is_none());
    }

    /// The bucketed nearest-neighbour search gives exactly what comparing every pair
    /// gives, on clouds, lattices, lines, planes and repeated points.
    #[test]
    fn bucketed_nearest_distances_equal_the_brute_force() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut shapes: Vec<Vec<[f64; 3]>> = Vec::new();
        shapes.push(
            (0..500)
                .map(|_| [0, 1, 2].map(|_| rng.gen_range(-800.0..1500.0)))
                .collect(),
        );
        shapes.push(
            (0..343)
                .map(|i| {
                    [
                        (i % 7) as f64 * 50.0,
                        (i / 7 % 7) as f64 * 50.0,
                        (i / 49) as f64 * 50.0,
                    ]
                })
                .collect(),
        );
        shapes.push(
            (0..300)
                .map(|i| [i as f64 * 3.0, i as f64 * 3.0, i as f64 * 3.0])
                .collect(),
        );
        shapes.push(
            (0..400)
                .map(|_| [rng.gen_range(0.0..100.0), 5.0, rng.gen_range(0.0..1e4)])
                .collect(),
        );
        shapes.push(vec![[1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [1.0, 2.0, 4.0]]);
        shapes.push(vec![[0.0; 3], [1e-300, 0.0, 0.0]]);
        for points in shapes {
            let grid = PointGrid::new(&points);
            for i in 0..points.len() {
                let brute = (0..points.len())
                    .filter(|&j| j != i)
                    .map(|j| adwi_runtime::method::distance_mm(points[i], points[j]))
                    .fold(f64::INFINITY, f64::min);
                assert_eq!(grid.nearest_other_mm(&points, i), brute, "point {i}");
            }
        }
    }

    #[test]
    fn measured_positions_become_errors() {
        let s = parse("x,y,z,mx,my,mz\n1,2,3,1.5,2,2\n").unwrap();
        assert_eq!(s.error_mm[0], [0.5, 0.0, -1.0]);
    }

    #[test]
    fn measured_orientation_becomes_a_rotation_vector() {
        let s = parse("x,y,z,dx,dy,dz,a,b,c,ma,mb,mc\n1,2,3,0,0,0,0,90,0,0.01,90,0\n").unwrap();
        let r = s.rotation_error_rad.unwrap()[0];
        // Rz(0.01°) applied before Ry(90°): a rotation of 0.01° about the base z axis.
        assert!((r[2] - 0.01f64.to_radians()).abs() < 1e-12, "{r:?}");
        assert!(r[0].abs() < 1e-12 && r[1].abs() < 1e-12);
    }

    #[test]
    fn column_map_renames_and_negates() {
        let map = ColumnMap::parse("x=x_t,y=y_t,z=z_t,dx=-x_dif,dy=y_dif,dz=z_dif").unwrap();
        let s = parse_samples(
            Path::new("u.csv"),
            b"step,x_t,y_t,z_t,x_dif,y_dif,z_dif\n0,1,2,3,0.5,0.25,0.125\n",
            &map,
        )
        .unwrap();
        assert_eq!(s.error_mm[0], [-0.5, 0.25, 0.125]);
        assert!(ColumnMap::parse("q=x_t").is_err());
        assert!(ColumnMap::parse("x=a,x=b").is_err());
    }
}
