//! [`Table`]: a validated correction table and its queries.

use std::path::Path;

use crate::format::{
    ArchivedSampleRecord, ArchivedTableData, Grid, Header, KinematicModel, CONTENT_CONFIG,
    CONTENT_JOINTS, CONTENT_MODEL, CONTENT_ORIENTATION, HEADER_LEN, JOINT_COUNT, PAYLOAD_ALIGN,
};
use crate::method::{self, MethodParams, Prediction, SampleError, Selection};
use crate::model::native_model;
use crate::residency::{Lock, OpenOptions, Residency};
use crate::OpenError;

/// What a query's answer means.
#[repr(u8)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Status {
    /// The correction was predicted from at least one admissible neighbour.
    Ok = 0,
    /// The target lies outside the table's grid; the correction is zero.
    OutsideGrid = 1,
    /// No sample is admissible for the target; the correction is zero.
    NoAdmissibleNeighbour = 2,
    /// The target is not finite (NaN or infinite coordinates); the correction is zero.
    InvalidInput = 3,
    /// The table is a hybrid table (a calibrated kinematic model plus residuals), whose
    /// correction depends on the joint angles: query it with
    /// [`Table::query_with_joints`]. The correction is zero.
    MissingJoints = 4,
    /// The prediction came out non-finite (NaN or infinite). A validated table gives this
    /// only in degenerate geometry, such as a target and a sample both within about
    /// 1e-160 mm of the base origin, where the approximation degrees overflow; answered
    /// instead of a correction no robot can be commanded with. The correction is zero.
    NumericalFailure = 5,
}

impl Status {
    /// A short lowercase name, as the CLI prints it.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::OutsideGrid => "outside_grid",
            Status::NoAdmissibleNeighbour => "no_neighbour",
            Status::InvalidInput => "invalid_input",
            Status::MissingJoints => "missing_joints",
            Status::NumericalFailure => "numerical_failure",
        }
    }
}

/// A target: where the controller wants the tool to be.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Target {
    /// Nominal position, mm, base frame.
    pub position_mm: [f64; 3],
    /// The inverse-kinematics configuration the controller will use, if known: samples
    /// of another configuration are then not admissible.
    pub config: Option<u8>,
}

impl Target {
    /// A target given by position alone.
    pub fn at(position_mm: [f64; 3]) -> Target {
        Target {
            position_mm,
            config: None,
        }
    }
}

/// The predicted error at a target: where the robot will land relative to where it was
/// told to go. Command `target − position_error_mm` to land on the target (to first
/// order; [`Table::compensate`] solves it exactly).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correction {
    /// Predicted position error (actual − nominal), mm, base frame.
    pub position_error_mm: [f64; 3],
    /// Predicted orientation error, rotation vector of `R_actual · R_nominalᵀ`, rad, base
    /// frame; zero when the table has no orientation ([`Table::has_orientation`]).
    pub orientation_error_rad: [f64; 3],
    /// The number of neighbours whose errors were weighted.
    pub neighbours: u32,
    /// Whether the prediction holds; every other field is zero unless this is `Ok`.
    pub status: Status,
}

impl Correction {
    pub(crate) fn failed(status: Status) -> Correction {
        Correction {
            position_error_mm: [0.0; 3],
            orientation_error_rad: [0.0; 3],
            neighbours: 0,
            status,
        }
    }

    /// This correction, or [`Status::NumericalFailure`] if it claims [`Status::Ok`] with
    /// a non-finite value: the last line of defence of every query path, so that no caller
    /// is ever told to command a NaN.
    #[inline]
    pub(crate) fn finite_or_failure(self) -> Correction {
        let values = self
            .position_error_mm
            .iter()
            .chain(&self.orientation_error_rad);
        if self.status == Status::Ok && !values.into_iter().all(|v| v.is_finite()) {
            return Correction::failed(Status::NumericalFailure);
        }
        self
    }
}

impl Compensation {
    /// This compensation, with its correction turned into [`Status::NumericalFailure`]
    /// (and `converged` false) if it claims [`Status::Ok`] with a non-finite command or
    /// residual.
    #[inline]
    pub(crate) fn finite_or_failure(mut self) -> Compensation {
        let values = (self.command_position_mm.iter())
            .chain(&self.command_rotation_rad)
            .chain([&self.residual_mm]);
        if self.correction.status == Status::Ok && !values.into_iter().all(|v| v.is_finite()) {
            self.correction = Correction::failed(Status::NumericalFailure);
            self.converged = false;
        }
        self
    }
}

/// The command that makes the robot land on a target, found by fixed-point iteration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Compensation {
    /// The position to command, mm, base frame: `command + error(command) = target`.
    pub command_position_mm: [f64; 3],
    /// The rotation to apply to the target orientation, rotation vector, rad, base frame:
    /// command `R_cmd = Exp(command_rotation_rad) · R_target`. Zero without orientation.
    pub command_rotation_rad: [f64; 3],
    /// The correction predicted at the command.
    pub correction: Correction,
    /// Iterations used (queries made).
    pub iterations: u32,
    /// Whether `|command + error(command) − target| ≤ tolerance` was reached.
    pub converged: bool,
    /// `|command + error(command) − target|` at the returned command, mm.
    pub residual_mm: f64,
}

/// A correction table, validated at open, answering queries without allocating, locking or
/// panicking.
///
/// Generic over its bytes: a [`memmap2::Mmap`] ([`Table::open`]), an owned aligned buffer
/// ([`Table::from_vec`]) or any 16-byte-aligned `AsRef<[u8]>` ([`Table::from_bytes`]).
pub struct Table<D> {
    data: D,
    header: Header,
    /// Address and length of the validated bytes: queries check that `data` still hands
    /// out the same slice, so an `AsRef` implementation that does not is refused rather
    /// than read unchecked.
    validated_at: (usize, usize),
    /// A hybrid table's kinematic model with its constant sines and cosines computed once
    /// at open, so that a query pays only for the joint angles' ([`crate::hybrid`]).
    pub(crate) prepared_model: Option<crate::model::PreparedModel>,
}

/// An owned, 16-byte-aligned copy of a table's bytes.
pub type AlignedBytes = rkyv::util::AlignedVec<PAYLOAD_ALIGN>;

impl Table<memmap2::Mmap> {
    /// Memory-maps and validates the table at `path`.
    ///
    /// # Errors
    ///
    /// Any [`OpenError`]: the file cannot be read, or fails a check of
    /// [`Table::from_bytes`].
    ///
    /// # Safety
    ///
    /// The file must not be modified or truncated while the table is alive: the mapping
    /// would change under validated data (queries could then read out of bounds). Build
    /// new tables under a new name and rename them into place, as `tablec build` does;
    /// a rename never changes a mapped file.
    pub unsafe fn open(path: impl AsRef<Path>) -> Result<Table<memmap2::Mmap>, OpenError> {
        // SAFETY: the caller upholds `open_with`'s contract, which is this one.
        unsafe { Table::open_with(path, crate::OpenOptions::default()) }.map(|(table, _)| table)
    }

    /// Memory-maps the table at `path` as [`Table::open`] does, first prefaulting and
    /// locking its pages as `options` asks.
    ///
    /// The lock is taken before validation so that the validated pages are the locked
    /// ones; it is released when the table (its mapping) is dropped.
    ///
    /// # Errors
    ///
    /// As [`Table::open`], and [`OpenError::Lock`] when `options.lock` is
    /// [`Lock::Required`] and `mlock` fails.
    ///
    /// # Safety
    ///
    /// As [`Table::open`]: the file must not be modified or truncated while the table is
    /// alive.
    pub unsafe fn open_with(
        path: impl AsRef<Path>,
        options: OpenOptions,
    ) -> Result<(Table<memmap2::Mmap>, Residency), OpenError> {
        let file = std::fs::File::open(path)?;
        let len = file.metadata()?.len();
        if len < HEADER_LEN as u64 {
            // Also refuses empty files, which cannot be mapped.
            return Err(OpenError::Truncated {
                len,
                needed: HEADER_LEN as u64,
            });
        }
        let mut mmap_options = memmap2::MmapOptions::new();
        if options.prefault {
            mmap_options.populate();
        }
        // SAFETY: the caller guarantees the file is not modified while mapped.
        let map = unsafe { mmap_options.map(&file)? };
        let mut residency = Residency {
            pages_touched: 0,
            locked: false,
            lock_error: None,
        };
        match options.lock {
            Lock::No => {}
            Lock::BestEffort => match map.lock() {
                Ok(()) => residency.locked = true,
                Err(e) => residency.lock_error = Some(e),
            },
            Lock::Required => {
                map.lock().map_err(OpenError::Lock)?;
                residency.locked = true;
            }
        }
        if options.prefault {
            residency.pages_touched = crate::residency::touch_pages(&map);
        }
        Ok((Table::from_bytes(map)?, residency))
    }
}

impl Table<AlignedBytes> {
    /// Copies `bytes` into an aligned buffer and validates it; for bytes of unknown
    /// alignment (a `Vec<u8>`, an `include_bytes!`).
    ///
    /// # Errors
    ///
    /// As [`Table::from_bytes`].
    pub fn from_vec(bytes: impl AsRef<[u8]>) -> Result<Table<AlignedBytes>, OpenError> {
        let mut aligned = AlignedBytes::with_capacity(bytes.as_ref().len());
        aligned.extend_from_slice(bytes.as_ref());
        Table::from_bytes(aligned)
    }
}

impl<D: AsRef<[u8]>> Table<D> {
    /// Validates a table held in `data`. Never panics, for any input.
    ///
    /// Checks, in order, stopping at the first failure:
    /// 1. the header ([`Header::from_bytes`]): length, magic, endianness mark, version,
    ///    header length, header checksum, rkyv format flags;
    /// 2. the length: header plus payload length, exactly;
    /// 3. the payload checksum;
    /// 4. the buffer's alignment, then rkyv validation of the archive (bounds, alignment);
    /// 5. the table's own invariants: parameters in range, known content flags, grid size
    ///    matching the cells, sample count, finite values, parameters, grid and samples of
    ///    plausible magnitude ([`format::check_plausible`]), every index in range, candidate
    ///    lists without repeats, base weights in `[0, 1]` summing to 1.
    ///
    /// # Errors
    ///
    /// The first check that fails, as an [`OpenError`].
    pub fn from_bytes(data: D) -> Result<Table<D>, OpenError> {
        let bytes = data.as_ref();
        let header = Header::from_bytes(bytes)?;
        let expected =
            (HEADER_LEN as u64)
                .checked_add(header.payload_len)
                .ok_or(OpenError::Corrupt {
                    what: "payload length overflows",
                })?;
        let len = bytes.len() as u64;
        if len < expected {
            return Err(OpenError::Truncated {
                len,
                needed: expected,
            });
        }
        if len > expected {
            return Err(OpenError::TrailingBytes { len, expected });
        }
        let payload = &bytes[HEADER_LEN..];
        let computed = xxhash_rust::xxh3::xxh3_64(payload);
        if computed != header.payload_checksum {
            return Err(OpenError::PayloadChecksum {
                stored: header.payload_checksum,
                computed,
            });
        }
        let offset = payload.as_ptr() as usize % PAYLOAD_ALIGN;
        if offset != 0 {
            return Err(OpenError::Misaligned { offset });
        }
        let archived = rkyv::access::<ArchivedTableData, rkyv::rancor::BoxedError>(payload)
            .map_err(|e| OpenError::Archive(e.to_string()))?;
        crate::validate::validate(&header, archived)?;
        let validated_at = (bytes.as_ptr() as usize, bytes.len());
        let prepared_model = crate::model::prepared_model(archived);
        Ok(Table {
            data,
            header,
            validated_at,
            prepared_model,
        })
    }

    /// Moves the validated bytes into another holder without validating them again, for a
    /// holder whose `as_ref` returns the same slice (wrapping a memory map in an enum,
    /// say). Should it not, every query answers [`Status::InvalidInput`]: the address check
    /// of [`Table::archive`] still guards every access.
    pub(crate) fn map_data<E: AsRef<[u8]>>(self, wrap: impl FnOnce(D) -> E) -> Table<E> {
        Table {
            data: wrap(self.data),
            header: self.header,
            validated_at: self.validated_at,
            prepared_model: self.prepared_model,
        }
    }

    /// The decoded header: format, checksums and build parameters.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The method's parameters the table was built with.
    pub fn method(&self) -> &MethodParams {
        &self.header.method
    }

    /// The cell grid; targets outside it get [`Status::OutsideGrid`].
    pub fn grid(&self) -> &Grid {
        &self.header.grid
    }

    /// Whether samples carry orientation errors, so corrections include one.
    pub fn has_orientation(&self) -> bool {
        self.header.content_flags & CONTENT_ORIENTATION != 0
    }

    /// Whether samples carry configurations, so [`Target::config`] screens them.
    pub fn has_config(&self) -> bool {
        self.header.content_flags & CONTENT_CONFIG != 0
    }

    /// The validated archive, or `None` if `data` no longer returns the validated slice.
    #[inline]
    fn archive(&self) -> Option<&ArchivedTableData> {
        let bytes = self.data.as_ref();
        if (bytes.as_ptr() as usize, bytes.len()) != self.validated_at {
            return None;
        }
        // SAFETY: these exact bytes (same address and length) passed `rkyv::access` in
        // `from_bytes`, and `D` gives shared access only, so they are unchanged (for a
        // memory map, by the contract of `Table::open`).
        Some(unsafe { rkyv::access_unchecked::<ArchivedTableData>(&bytes[HEADER_LEN..]) })
    }

    /// The number of samples.
    pub fn sample_count(&self) -> usize {
        self.archive().map_or(0, |a| a.samples.len())
    }

    /// The raw archived data, for inspection tools.
    pub fn data(&self) -> Option<&ArchivedTableData> {
        self.archive()
    }

    /// The predicted correction at a position. Never allocates, locks or panics.
    #[inline]
    pub fn query(&self, position_mm: [f64; 3]) -> Correction {
        self.query_target(&Target::at(position_mm))
    }

    /// The predicted correction at a target. Never allocates, locks or panics.
    ///
    /// A hybrid table answers [`Status::MissingJoints`]: use [`Table::query_with_joints`].
    #[inline]
    pub fn query_target(&self, target: &Target) -> Correction {
        if self.is_hybrid() {
            return Correction::failed(Status::MissingJoints);
        }
        self.interpolate(target, None)
    }

    /// The full prediction at a target: the neighbours used, nearest first, with their
    /// approximation degrees and weights. Never allocates, locks or panics.
    ///
    /// # Errors
    ///
    /// The [`Status`] explaining why no prediction exists ([`Status::MissingJoints`] on a
    /// hybrid table, whose residuals alone are not the error).
    pub fn explain(&self, target: &Target) -> Result<Prediction, Status> {
        if self.is_hybrid() {
            return Err(Status::MissingJoints);
        }
        let (selection, archive) = self.select(target, None)?;
        let samples = archive.samples.as_slice();
        let neighbours = method::neighbours(target.position_mm, &selection, |i| actual(samples, i));
        let prediction = method::predict(&self.header.method, neighbours.as_slice(), |i| {
            sample_error(samples, i)
        })
        .ok_or(Status::NoAdmissibleNeighbour)?;
        // As every query path: never a non-finite prediction (degrees may be infinite: a
        // coincident sample's ζ is, by definition).
        let values = (prediction.position_error_mm.iter())
            .chain(&prediction.orientation_error_rad)
            .chain(prediction.weights.as_slice());
        if !values.into_iter().all(|v| v.is_finite()) {
            return Err(Status::NumericalFailure);
        }
        Ok(prediction)
    }

    /// The `k` nearest admissible samples of the target's cell, and the samples.
    #[inline]
    fn select(
        &self,
        target: &Target,
        joints_rad: Option<&[f64]>,
    ) -> Result<(Selection, &ArchivedTableData), Status> {
        let p = target.position_mm;
        if !p.iter().all(|v| v.is_finite()) {
            return Err(Status::InvalidInput);
        }
        let archive = self.archive().ok_or(Status::InvalidInput)?;
        let cell = self.header.grid.cell_of(p).ok_or(Status::OutsideGrid)?;
        let list = candidate_list(archive, cell).ok_or(Status::NoAdmissibleNeighbour)?;
        let samples = archive.samples.as_slice();
        // The joint-space screen, when the table has one and the target's joints are known
        // (validation guarantees one joint vector per sample whenever the radius is set).
        let radius_rad = self.header.joint_radius_rad;
        let screen = joints_rad.filter(|_| radius_rad > 0.0);
        let sample_joints = archive.joints_rad.as_slice();
        let selection = method::select(
            &self.header.method,
            p,
            target.config,
            list.iter().map(|i| i.to_native()),
            |i| {
                let s = samples.get(i as usize)?;
                if let Some(target_joints) = screen {
                    let q = sample_joints.get(i as usize)?.map(|v| v.to_native());
                    if !crate::method::joints_within(&q, target_joints, radius_rad) {
                        return None;
                    }
                }
                Some((s.actual_mm.map(|v| v.to_native()), s.config))
            },
        );
        Ok((selection, archive))
    }

    /// The interpolated sample errors at a target (with the joint-space screen when
    /// `joints_rad` is given): the ordinary query, and a hybrid table's residual part.
    #[inline]
    pub(crate) fn interpolate(&self, target: &Target, joints_rad: Option<&[f64]>) -> Correction {
        let estimate = self
            .select(target, joints_rad)
            .and_then(|(selection, archive)| {
                let samples = archive.samples.as_slice();
                let norms = archive.actual_norms_mm.as_slice();
                let sample = |i: u32| {
                    let norm = norms.get(i as usize).map_or(0.0, |n| n.to_native());
                    (actual(samples, i), norm, sample_error(samples, i))
                };
                method::estimate(&self.header.method, target.position_mm, &selection, sample)
                    .ok_or(Status::NoAdmissibleNeighbour)
            });
        match estimate {
            Ok(e) => Correction {
                position_error_mm: e.position_error_mm,
                orientation_error_rad: e.orientation_error_rad,
                neighbours: e.neighbours,
                status: Status::Ok,
            }
            .finite_or_failure(),
            Err(status) => Correction::failed(status),
        }
    }

    /// The command that lands the robot on `target`: iterates
    /// `command ← target − error(command)` from `command = target` until
    /// `|command + error(command) − target| ≤ tolerance_mm` or `max_iterations` queries.
    ///
    /// The predicted error field is continuous within a neighbourhood but may jump where
    /// the neighbour set changes; there the iteration can cycle and reports
    /// `converged: false` with its last command. Never allocates, locks or panics.
    pub fn compensate(
        &self,
        target: &Target,
        tolerance_mm: f64,
        max_iterations: u32,
    ) -> Compensation {
        let mut command = *target;
        let mut out = Compensation {
            command_position_mm: target.position_mm,
            command_rotation_rad: [0.0; 3],
            correction: Correction::failed(Status::InvalidInput),
            iterations: 0,
            converged: false,
            residual_mm: f64::INFINITY,
        };
        while out.iterations < max_iterations.max(1) {
            let correction = self.query_target(&command);
            out.iterations += 1;
            out.correction = correction;
            out.command_position_mm = command.position_mm;
            if correction.status != Status::Ok {
                return out;
            }
            let landing = add(command.position_mm, correction.position_error_mm);
            out.residual_mm = method::distance_mm(landing, target.position_mm);
            out.command_rotation_rad = correction.orientation_error_rad.map(|v| -v);
            if out.residual_mm <= tolerance_mm {
                out.converged = true;
                return out.finite_or_failure();
            }
            command.position_mm = sub(target.position_mm, correction.position_error_mm);
        }
        out.finite_or_failure()
    }

    /// Whether this is a hybrid table (a kinematic model plus residuals): it then needs the
    /// target's joint angles ([`Table::query_with_joints`]).
    pub fn is_hybrid(&self) -> bool {
        self.header().content_flags & CONTENT_MODEL != 0
    }

    /// The number of joint values [`Table::query_with_joints`] takes: the robot's joint
    /// count when the table carries joint angles or a model, `None` when joint angles play
    /// no part in its answers (any count is then accepted and ignored).
    pub fn joint_count(&self) -> Option<usize> {
        let flags = self.header.content_flags;
        (flags & (CONTENT_JOINTS | CONTENT_MODEL) != 0).then_some(JOINT_COUNT)
    }

    /// The joint-space admissibility radius, rad; 0 when the screen is off.
    pub fn joint_radius_rad(&self) -> f64 {
        self.header().joint_radius_rad
    }

    /// The kinematic model of a hybrid table (nominal and calibrated parameters).
    pub fn kinematic_model(&self) -> Option<KinematicModel> {
        Some(native_model(self.data()?.model.as_ref()?))
    }

    /// The predicted correction at a target that the controller will reach with joint
    /// angles `joints_rad` (rad, the controller's joint variables, in the robot file's
    /// order). Never allocates, locks or panics.
    ///
    /// - On a hybrid table: the calibrated model's predicted error at `joints_rad` plus
    ///   the interpolated residual at the target (see the module docs).
    /// - On any table with a joint radius ([`Table::joint_radius_rad`]): only samples
    ///   whose joint angles are all within that radius of `joints_rad` are admissible.
    /// - Otherwise the answer equals [`Table::query_target`]'s.
    ///
    /// `neighbours` counts the interpolated residuals' neighbours. Non-finite joint angles
    /// give [`Status::InvalidInput`]. The joint angles are taken as given: they are not
    /// checked against the target position (the controller's inverse kinematics is the
    /// authority on them).
    pub fn query_with_joints(&self, target: &Target, joints_rad: &[f64]) -> Correction {
        let expected = self.joint_count();
        if !joints_rad.iter().all(|q| q.is_finite())
            || (expected.is_some() && expected != Some(joints_rad.len()))
        {
            return Correction::failed(Status::InvalidInput);
        }
        let mut correction = self.interpolate(target, Some(joints_rad));
        if correction.status != Status::Ok {
            return correction;
        }
        if let Some(model) = &self.prepared_model {
            let Some((position_mm, rotation_rad)) = model.error(joints_rad) else {
                return Correction::failed(Status::InvalidInput);
            };
            for (out, model) in correction.position_error_mm.iter_mut().zip(position_mm) {
                *out += model;
            }
            // Position-only samples: the table predicts no orientation, the model does.
            if self.has_orientation() {
                let orientation = correction.orientation_error_rad.iter_mut();
                for (out, model) in orientation.zip(rotation_rad) {
                    *out += model;
                }
            }
        }
        correction.finite_or_failure()
    }
}

#[inline]
fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline]
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
fn actual(samples: &[ArchivedSampleRecord], index: u32) -> [f64; 3] {
    samples
        .get(index as usize)
        .map_or([0.0; 3], |s| s.actual_mm.map(|v| v.to_native()))
}

#[inline]
fn sample_error(samples: &[ArchivedSampleRecord], index: u32) -> SampleError {
    match samples.get(index as usize) {
        Some(s) => SampleError {
            position_mm: s.error_mm.map(|v| v.to_native()),
            orientation_rad: s.rotation_error_rad.map(|v| v.to_native()),
        },
        None => SampleError::default(),
    }
}

/// The candidate list of a cell, or `None` if a range is out of bounds (excluded by
/// validation; checked anyway so that no query can panic).
#[inline]
fn candidate_list(archive: &ArchivedTableData, cell: usize) -> Option<&[rkyv::Archived<u32>]> {
    let c = archive.cells.get(cell)?;
    let start = c.list_start.to_native() as usize;
    let end = start.checked_add(c.list_len.to_native() as usize)?;
    archive.list_samples.get(start..end)
}
