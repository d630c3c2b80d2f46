//! The sample database: measured errors at commanded poses, read from CSV.
//!
//! # CSV format
//!
//! One header row, then one row per sample; lines starting with `#` are comments; fields
//! may be padded with spaces. The separator — comma, semicolon or tab — is the one the
//! header line uses most; numbers take a decimal point, or a decimal comma in files not
//! separated by commas (detected from the first number with a mark; every number must then
//! agree). Both can be given instead ([`ReadOptions`]). Columns are found by name, in any
//! order; unknown columns are ignored.
//!
//! | columns | meaning | |
//! |---|---|---|
//! | `x,y,z` | nominal (commanded) position, robot base frame | required |
//! | `dx,dy,dz` | measured position error = actual − nominal | one of these two |
//! | `mx,my,mz` | measured actual position | |
//! | a nominal orientation | see below | optional |
//! | `rx,ry,rz` | orientation error: rotation vector of `R_actual·R_nominalᵀ`, base frame, rad | optional, or: |
//! | a measured orientation | the nominal's names with an `m` before them (needs a nominal one) | |
//! | `j1..jn` | joint values, n from 1 to 12, no gaps | optional |
//! | `config` | inverse-kinematics configuration, integer 0-254 | optional |
//!
//! Orientations, one convention per side (nominal, measured):
//!
//! | nominal | measured | convention |
//! |---|---|---|
//! | `a,b,c` | `ma,mb,mc` | KUKA, `R = Rz(a)·Ry(b)·Rx(c)` |
//! | `q1,q2,q3,q4` | `mq1..mq4` | quaternion w, x, y, z (ABB), normalised |
//! | `qx,qy,qz,qw` | `mqx,mqy,mqz,mqw` | quaternion x, y, z, w, normalised |
//! | `w,p,r` | `mw,mp,mr` | Fanuc, `R = Rz(r)·Ry(p)·Rx(w)` |
//! | `roll,pitch,yaw` | `mroll,mpitch,myaw` | extrinsic x-y-z, `R = Rz(yaw)·Ry(pitch)·Rx(roll)` |
//! | `ex,ey,ez` | `mex,mey,mez` | intrinsic X-Y-Z Euler, `R = Rx(ex)·Ry(ey)·Rz(ez)` |
//!
//! Units: positions in millimetres and angles (orientation angles, joints) in degrees
//! unless [`ReadOptions`] says otherwise for the whole file or the column mapping for a
//! group of columns; the rotation vector `rx,ry,rz` is in radians unless mapped `:deg`.
//! Everything read is returned in millimetres and radians.
//!
//! Files whose columns are named otherwise are read through a [`ColumnMap`]:
//! `x=x_t,y=y_t,z=z_t,dx=x_dif,...`; a source name prefixed by `-` is negated
//! (`dx=-x_dif` for a file that records nominal − actual), one followed by `:unit` is in
//! that unit (`x=Goal x:m`, `ma=measurement_rx:deg`; `mm`, `m`, `deg`, `rad`), and `x:m`
//! alone gives a unit to a column named as expected. The columns of a group (`x,y,z`,
//! `ma,mb,mc`, ...) take one unit; joints may mix angles and lengths (prismatic joints).
//!
//! Several rows may share a nominal position when their orientations, joints or
//! configurations differ. Rows that command the same pose (see [`REPEAT_RESOLUTION`]) are
//! one sample, the mean of their measured errors, and their spread is reported in
//! [`SampleSet::repeats`].
//!
//! Every problem is an error naming the file, the line and, where there is one, the
//! column: a wrong field count, a field that is not a number, NaN or infinite, a number
//! with the other decimal mark, a zero quaternion, a missing or incomplete group of
//! columns, a mapped column the header lacks (with the header's closest names), two
//! conventions on one side, mixed units in a group, an empty file; and values no robot
//! has: a position, error or measured coordinate beyond 1 km, an orientation error beyond
//! [`MAX_PLAUSIBLE_ROTATION_ERROR_DEG`] (with its likely cause: degrees read as radians).
//! Several series trained together are checked by [`check_series`]: none given twice, none
//! in another length unit than the others.
//!
//! Samples that read but look wrong for a robot in millimetres — a file in metres spans a
//! millimetre — are flagged by [`SampleSet::plausibility_warnings`], typed, for the caller
//! to print.
//!
//! Measurements in another frame than the robot's base (a laser tracker's) are read by
//! [`read_measurements`] into [`Measurements`], which a registration turns into samples.

use std::path::Path;

use adwi_runtime::format::SampleRecord;
use adwi_runtime::method::CONFIG_UNKNOWN;
use nalgebra::Rotation3;

mod columns;
mod measurements;
mod plausible;
pub mod pose;
mod reader;
mod repeats;
mod series;

pub use columns::{
    orientation_columns, AngleUnit, ColumnMap, ColumnMapError, LengthUnit, Unit, UnitError,
    CANONICAL_COLUMNS, MAX_JOINTS,
};
pub use measurements::{Measurements, MeasurementsError};
pub use plausible::{
    SampleWarning, MAX_PLAUSIBLE_ERROR_RMS_MM, MAX_PLAUSIBLE_EXTENT_MM,
    MAX_PLAUSIBLE_ROTATION_ERROR_DEG, MIN_PLAUSIBLE_EXTENT_MM,
};
pub use reader::{
    Choice, Decimal, Delimiter, MappedColumnMissing, ReadError, ReadErrorKind, ReadOptions,
};
pub use repeats::{RepeatReport, REPEAT_RESOLUTION};
pub use series::{check_series, SeriesConflict, SeriesRows, MAX_SERIES_SCALE_RATIO};

use reader::{parse, read_file, Purpose, Rows};

/// Series that cannot make one sample set: one carries columns the first does not.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("series {series} differs from the first in {what}: series trained together need the same columns")]
pub struct SeriesMismatch {
    /// Which series (1-based) differs from the first.
    pub series: usize,
    /// What it differs in.
    pub what: &'static str,
}

/// A sample database in memory, in source order. Positions mm, base frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SampleSet {
    /// Nominal (commanded) positions, mm.
    pub nominal_mm: Vec<[f64; 3]>,
    /// Measured position errors, actual − nominal, mm.
    pub error_mm: Vec<[f64; 3]>,
    /// Nominal orientations (the commanded frame in the base frame), when given.
    pub nominal_rotation: Option<Vec<Rotation3<f64>>>,
    /// Measured orientation errors, rotation vectors (rad, base frame), when given.
    pub rotation_error_rad: Option<Vec<[f64; 3]>>,
    /// Joint values, when given: rad (mm for prismatic joints), one row per sample.
    pub joints: Option<Joints>,
    /// Inverse-kinematics configurations, when given.
    pub config: Option<Vec<u8>>,
    /// The source line of each sample (1-based), for messages; of a repeated pose, its
    /// first row's.
    pub lines: Vec<u64>,
    /// The spread of repeated poses' measured errors, when rows repeated a pose (each
    /// repeated pose is one sample, the mean of its rows).
    pub repeats: Option<RepeatReport>,
}

impl SampleSet {
    /// A 64-bit digest (XXH3) of every value a model or a table is made from: nominal
    /// positions and orientations, errors, joint values and configurations, bit for bit,
    /// each part marked present or absent. Source lines and the repeats' report are
    /// left out: they only word messages. Two sets with the same fingerprint are taken
    /// to be the same samples (a collision by chance is about 1 in 2⁶⁴).
    pub fn fingerprint(&self) -> u64 {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        let mut values = |present: bool, values: &mut dyn Iterator<Item = f64>| {
            h.update(&[u8::from(present)]);
            for v in values {
                h.update(&v.to_bits().to_le_bytes());
            }
        };
        values(true, &mut self.nominal_mm.iter().flatten().copied());
        values(true, &mut self.error_mm.iter().flatten().copied());
        let rotations = self.nominal_rotation.as_deref();
        values(
            rotations.is_some(),
            &mut rotations
                .into_iter()
                .flatten()
                .flat_map(|r| r.matrix().iter().copied()),
        );
        let rotation_errors = self.rotation_error_rad.as_deref();
        values(
            rotation_errors.is_some(),
            &mut rotation_errors.into_iter().flatten().flatten().copied(),
        );
        let joints = self.joints.as_ref();
        values(
            joints.is_some(),
            &mut joints
                .map(|j| j.count as f64)
                .into_iter()
                .chain(joints.into_iter().flat_map(|j| j.values.iter().copied())),
        );
        h.update(&[u8::from(self.config.is_some())]);
        h.update(self.config.as_deref().unwrap_or(&[]));
        h.digest()
    }

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
            nominal_rotation: self
                .nominal_rotation
                .as_ref()
                .map(|r| indices.iter().map(|&i| r[i]).collect()),
            rotation_error_rad: self.rotation_error_rad.as_ref().map(pick),
            joints: self.joints.as_ref().map(|j| j.subset(indices)),
            config: self
                .config
                .as_ref()
                .map(|c| indices.iter().map(|&i| c[i]).collect()),
            lines: indices.iter().map(|&i| self.lines[i]).collect(),
            // The spread of the file's repeats is not the subset's.
            repeats: None,
        }
    }

    /// Several series as one sample set, in order: the samples of each, and a pose that
    /// two series command alike (after each series folded its own repeats) folded into
    /// one sample, the mean of their errors, as rows repeating a pose in one file are.
    /// The series must carry the same columns: joint values (and as many), nominal
    /// orientations, orientation errors and configurations all or none.
    ///
    /// # Errors
    ///
    /// [`SeriesMismatch`], naming the first series that differs from the first one.
    pub fn concat(series: &[SampleSet]) -> Result<SampleSet, SeriesMismatch> {
        let Some(first) = series.first() else {
            return Ok(SampleSet::default());
        };
        let shape = |s: &SampleSet| {
            (
                s.joint_count(),
                s.nominal_rotation.is_some(),
                s.rotation_error_rad.is_some(),
                s.config.is_some(),
            )
        };
        for (i, s) in series.iter().enumerate().skip(1) {
            let (a, b) = (shape(first), shape(s));
            let what = if a.0 != b.0 {
                "joint values (j1..jn, and as many)"
            } else if a.1 != b.1 {
                "a nominal orientation"
            } else if a.2 != b.2 {
                "orientation errors"
            } else if a.3 != b.3 {
                "configurations"
            } else {
                continue;
            };
            return Err(SeriesMismatch {
                series: i + 1,
                what,
            });
        }
        let gather3 = |f: fn(&SampleSet) -> &Vec<[f64; 3]>| -> Vec<[f64; 3]> {
            series.iter().flat_map(|s| f(s).iter().copied()).collect()
        };
        let joints = first.joints.as_ref().map(|j| {
            let mut all = Joints::new(j.count());
            for s in series {
                let js = s.joints.as_ref().expect("checked");
                for r in js.rows() {
                    all.push(r);
                }
            }
            all
        });
        Ok(repeats::fold(repeats::Parts {
            nominal_mm: gather3(|s| &s.nominal_mm),
            error_mm: gather3(|s| &s.error_mm),
            nominal_rotation: first.nominal_rotation.as_ref().map(|_| {
                series
                    .iter()
                    .flat_map(|s| {
                        s.nominal_rotation
                            .as_ref()
                            .expect("checked")
                            .iter()
                            .copied()
                    })
                    .collect()
            }),
            rotation_error_rad: first.rotation_error_rad.as_ref().map(|_| {
                series
                    .iter()
                    .flat_map(|s| {
                        s.rotation_error_rad
                            .as_ref()
                            .expect("checked")
                            .iter()
                            .copied()
                    })
                    .collect()
            }),
            joints,
            config: first.config.as_ref().map(|_| {
                series
                    .iter()
                    .flat_map(|s| s.config.as_ref().expect("checked").iter().copied())
                    .collect()
            }),
            lines: series
                .iter()
                .flat_map(|s| s.lines.iter().copied())
                .collect(),
        }))
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

    /// The median distance from a sample's nominal position to the nearest other nominal
    /// position, mm: the sample spacing of a lattice, a robust one of a cloud. Samples at
    /// one position (several orientations there) count as one position. `None` for fewer
    /// than two positions. Above 4000 samples, the median is taken over an evenly strided
    /// subset of 4000 (each still against all samples, found through a bucket grid so that
    /// a million samples take a fraction of a second rather than minutes).
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
            .filter(|d| d.is_finite())
            .collect();
        nearest.sort_by(f64::total_cmp);
        nearest.get(nearest.len() / 2).copied()
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

    /// `other`'s rows after these (of the same count).
    pub(crate) fn append(&mut self, mut other: Joints) {
        debug_assert_eq!(self.count, other.count);
        self.values.append(&mut other.values);
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
        grid.drop_coincident(points);
        grid
    }

    /// Keeps one point of each position in each bucket: the nearest *other* position is
    /// then found without looking at every sample of a position again (a million samples
    /// at one position would otherwise make each search look at a million).
    fn drop_coincident(&mut self, points: &[[f64; 3]]) {
        // +0.0 folds −0.0 into 0.0: both are the same position.
        let key = |j: u32| points[j as usize].map(|v| (v + 0.0).to_bits());
        let mut write = 0;
        for b in 0..self.starts.len() - 1 {
            let (lo, hi) = (self.starts[b], self.starts[b + 1]);
            if hi - lo > 1 {
                self.items[lo..hi].sort_unstable_by_key(|&j| key(j));
            }
            self.starts[b] = write;
            let mut previous = None;
            for k in lo..hi {
                let j = self.items[k];
                if previous != Some(key(j)) {
                    previous = Some(key(j));
                    self.items[write] = j;
                    write += 1;
                }
            }
        }
        *self.starts.last_mut().expect("one more start than buckets") = write;
        self.items.truncate(write);
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

    /// The distance from point `i` to the nearest point at another position, mm (infinite
    /// when there is none), computed by [`adwi_runtime::method::distance_mm`] exactly as a
    /// comparison with every point would: buckets are searched in growing shells until no
    /// unsearched bucket can hold a nearer point.
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
                            if points[j as usize] != p {
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

/// Reads a sample file with the default options (separator and decimal mark detected,
/// millimetres and degrees). See the module docs for the format.
///
/// # Errors
///
/// The first problem found, with file, line and column.
pub fn read_samples(path: &Path, columns: &ColumnMap) -> Result<SampleSet, ReadError> {
    read_samples_with(path, columns, &ReadOptions::default())
}

/// Reads a sample file. See the module docs for the format.
///
/// # Errors
///
/// The first problem found, with file, line and column.
pub fn read_samples_with(
    path: &Path,
    columns: &ColumnMap,
    options: &ReadOptions,
) -> Result<SampleSet, ReadError> {
    parse_samples_with(path, &read_file(path)?, columns, options)
}

/// Parses sample CSV held in memory with the default options; `path` only names it in
/// messages.
///
/// # Errors
///
/// As [`read_samples`].
pub fn parse_samples(
    path: &Path,
    bytes: &[u8],
    columns: &ColumnMap,
) -> Result<SampleSet, ReadError> {
    parse_samples_with(path, bytes, columns, &ReadOptions::default())
}

/// Parses sample CSV held in memory; `path` only names it in messages.
///
/// # Errors
///
/// As [`read_samples`].
pub fn parse_samples_with(
    path: &Path,
    bytes: &[u8],
    columns: &ColumnMap,
    options: &ReadOptions,
) -> Result<SampleSet, ReadError> {
    let rows = parse(path, bytes, columns, options, Purpose::Samples)?;
    Ok(samples_from_rows(rows))
}

/// The samples of a file's rows: errors as given, or from the measured poses (as
/// [`Measurements::to_samples`] computes them), repeated poses folded.
fn samples_from_rows(rows: Rows) -> SampleSet {
    let nominal_mm = rows.nominal_mm.unwrap_or_default();
    let error_mm = match (rows.delta_mm, rows.measured_mm) {
        (Some(delta), _) => delta,
        (None, Some(measured)) => measurements::position_errors(&nominal_mm, measured),
        (None, None) => vec![[0.0; 3]; nominal_mm.len()],
    };
    let rotation_error_rad = match (
        rows.rotation_vector_rad,
        &rows.nominal_rotation,
        &rows.measured_rotation,
    ) {
        (Some(v), _, _) => Some(v),
        (None, Some(nominal), Some(measured)) => {
            Some(measurements::orientation_errors(nominal, measured))
        }
        _ => None,
    };
    repeats::fold(repeats::Parts {
        nominal_mm,
        error_mm,
        nominal_rotation: rows.nominal_rotation,
        rotation_error_rad,
        joints: rows.joints,
        config: rows.config,
        lines: rows.lines,
    })
}

/// Reads a CSV of poses to measure: joint values `j1..jn` (rad; mm for prismatic joints),
/// one vector a row, in file order, through the same reader, column mapping and options as
/// samples; other columns (a plan's x,y,z, say) may be there or not and are not needed.
///
/// # Errors
///
/// As [`read_samples`], but only joint values are required.
pub fn read_poses(
    path: &Path,
    columns: &ColumnMap,
    options: &ReadOptions,
) -> Result<Vec<Vec<f64>>, ReadError> {
    let rows = parse(path, &read_file(path)?, columns, options, Purpose::Poses)?;
    Ok(match &rows.joints {
        Some(joints) => (0..rows.lines.len())
            .map(|i| joints.row(i).to_vec())
            .collect(),
        None => Vec::new(),
    })
}

/// A target read from a CSV: where to go and, when the file gives them, the joint values
/// the controller will use.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetRow {
    /// Position and configuration.
    pub target: adwi_runtime::Target,
    /// Joint values `j1..jn`, rad (mm for prismatic joints), when the file has them.
    pub joints_rad: Option<Vec<f64>>,
}

/// Reads a CSV of targets: `x,y,z` (base frame), optionally `config` and `j1..jn`, through
/// the same reader, column mapping and options as samples; other columns (errors, say)
/// are ignored, and positions may repeat.
///
/// # Errors
///
/// As [`read_samples`], but error columns are not required.
pub fn read_targets(
    path: &Path,
    columns: &ColumnMap,
    options: &ReadOptions,
) -> Result<Vec<TargetRow>, ReadError> {
    let rows = parse(path, &read_file(path)?, columns, options, Purpose::Targets)?;
    let nominal = rows.nominal_mm.unwrap_or_default();
    Ok((0..rows.lines.len())
        .map(|i| TargetRow {
            target: adwi_runtime::Target {
                position_mm: nominal[i],
                config: rows.config.as_ref().map(|c| c[i]),
                rotation_rad: None,
                tcp_mm: None,
            },
            joints_rad: rows.joints.as_ref().map(|j| j.row(i).to_vec()),
        })
        .collect())
}

/// Reads raw measurements ([`Measurements`]): joints `j1..jn` and measured position
/// `mx,my,mz` required, nominal position and orientations and the measured orientation
/// optional, through the same reader, column mapping and options as samples. Error columns
/// are not read, and rows are kept as they are (repeats are folded by
/// [`Measurements::to_samples`]).
///
/// # Errors
///
/// As [`read_samples`], but nominal positions are not required and joints are.
pub fn read_measurements(
    path: &Path,
    columns: &ColumnMap,
    options: &ReadOptions,
) -> Result<Measurements, ReadError> {
    parse_measurements(path, &read_file(path)?, columns, options)
}

/// Parses measurements held in memory ([`read_measurements`]); `path` only names the file
/// in messages.
///
/// # Errors
///
/// As [`read_measurements`].
pub fn parse_measurements(
    path: &Path,
    bytes: &[u8],
    columns: &ColumnMap,
    options: &ReadOptions,
) -> Result<Measurements, ReadError> {
    let rows = parse(path, bytes, columns, options, Purpose::Measurements)?;
    Ok(Measurements {
        joints: rows.joints.unwrap_or_default(),
        nominal_mm: rows.nominal_mm,
        nominal_rotation: rows.nominal_rotation,
        measured_mm: rows.measured_mm.unwrap_or_default(),
        measured_rotation: rows.measured_rotation,
        config: rows.config,
        lines: rows.lines,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_concatenate_and_a_pose_both_command_is_one_sample() {
        let parse = |text: &str| {
            parse_samples(Path::new("s.csv"), text.as_bytes(), &ColumnMap::default()).unwrap()
        };
        let a = parse("x,y,z,dx,dy,dz,j1\n0,0,0,0.1,0,0,1\n10,0,0,0.2,0,0,2\n");
        let c = parse("x,y,z,dx,dy,dz,j1\n10,0,0,0.4,0,0,2\n20,0,0,0.5,0,0,3\n");
        let both = SampleSet::concat(&[a.clone(), c]).unwrap();
        assert_eq!(
            both.nominal_mm,
            vec![[0.0; 3], [10.0, 0.0, 0.0], [20.0, 0.0, 0.0]]
        );
        assert_eq!(both.error_mm[1][0], (0.2 + 0.4) / 2.0);
        assert_eq!(both.joints.as_ref().unwrap().count(), 1);
        assert_eq!(both.repeats.as_ref().map(|r| r.poses), Some(1));
        let without_joints = parse("x,y,z,dx,dy,dz\n30,0,0,0.1,0,0\n");
        let e = SampleSet::concat(&[a, without_joints]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "series 2 differs from the first in joint values (j1..jn, and as many): series \
             trained together need the same columns"
        );
    }

    #[test]
    fn the_fingerprint_is_every_value_and_only_the_values() {
        let base = "x,y,z,a,b,c,dx,dy,dz,rx,ry,rz,j1,j2,config\n\
                    0,0,0,0,90,0,0.1,0,0,0.001,0,0,1,2,3\n\
                    10,0,0,0,90,0,0.2,0,0,0,0.001,0,2,3,3\n";
        let samples = parse(base).unwrap();
        let print = samples.fingerprint();
        assert_eq!(print, samples.clone().fingerprint());
        // The same values on other source lines (a comment above them): the same samples.
        let commented = parse(&format!("# a comment\n{base}")).unwrap();
        assert_ne!(commented.lines, samples.lines);
        assert_eq!(commented.fingerprint(), print);
        // Any value moved, or a part left out: other samples.
        let others = [
            base.replace("\n0,0,0,", "\n0,0,1e-9,"),
            base.replace("0.1,0,0,0.001", "0.1,0,0,0.002"),
            base.replace(",90,0,0.2", ",89,0,0.2"),
            base.replace(",1,2,3\n", ",1,2.5,3\n"),
            base.replace("2,3,3\n", "2,3,4\n"),
            base.replace("0.2,0,0,", "0.2,0,-0,"),
        ];
        for other in others {
            assert_ne!(parse(&other).unwrap().fingerprint(), print, "{other}");
        }
        let without_joints = parse(
            "x,y,z,a,b,c,dx,dy,dz,rx,ry,rz\n0,0,0,0,90,0,0.1,0,0,0.001,0,0\n10,0,0,0,90,0,0.2,0,0,0,0.001,0\n",
        )
        .unwrap();
        let mut no_joints = samples.clone();
        no_joints.joints = None;
        no_joints.config = None;
        assert_eq!(without_joints.fingerprint(), no_joints.fingerprint());
        assert_ne!(no_joints.fingerprint(), print);
    }

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
                    .filter(|&j| points[j] != points[i])
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

    /// Poses to measure are joint vectors: a file of `j1..jn` alone is read, in order; a
    /// file without them is refused naming them.
    #[test]
    fn poses_are_joint_values_alone() {
        let dir = std::env::temp_dir().join(format!("adwi-poses-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("poses.csv");
        std::fs::write(&path, "j1,j2,j3\n0,90,-90\n180,0,0\n").unwrap();
        let (columns, options) = (ColumnMap::default(), ReadOptions::default());
        let poses = read_poses(&path, &columns, &options).unwrap();
        let expected = [[0.0, 90.0, -90.0], [180.0, 0.0, 0.0]]
            .map(|row| row.map(|v: f64| v.to_radians()).to_vec());
        assert_eq!(poses, expected);
        std::fs::write(&path, "x,y,z\n1,2,3\n").unwrap();
        let e = read_poses(&path, &columns, &options).unwrap_err();
        assert!(e.to_string().contains("j1..jn"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
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
