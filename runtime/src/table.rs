//! [`Table`]: a validated correction table and its queries.
//!
//! A version-2 table answers from two tiers: the **served** field (continuous, one cell's
//! 8 nodes blended, [`crate::served`]) through [`Table::query`], [`Table::query_target`],
//! [`Table::query_with_joints`] and [`Table::compensate`]; and the **exact** method (the
//! paper's, to the digit, [`crate::exact`]) through the same calls on [`Table::exact`]. A
//! table without a served tier — version 1, or a table with a joint-space screen — answers
//! both from its exact tier ([`Table::has_served_field`] says which).
//!
//! A hybrid table of format version 3 also has a posture term ([`crate::posture`],
//! [`Table::posture`]), which its served answers given joint values add; the exact tier
//! does not.

use std::path::Path;

use crate::correction::{Compensation, Correction, Evidence, Residual, Status, Target};
use crate::exact::{self, V1, V2};
use crate::format::{
    v1, v2, v3, v5, Grid, Header, CONTENT_CONFIG, CONTENT_MODEL, CONTENT_ORIENTATION, HEADER_LEN,
    MAX_COORDINATE_MM, PAYLOAD_ALIGN,
};
use crate::kinematics::rotation_displacement;
use crate::method::{self, MethodParams, Prediction};
use crate::model::{ModelAt, PreparedModel};
use crate::posture::{PostureParams, PreparedPosture};
use crate::residency::{Lock, OpenOptions, Residency};
use crate::served::ServedGrid;
use crate::OpenError;

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
    /// A hybrid table's kinematic model, its chains prepared at open.
    model: Option<PreparedModel>,
    /// The served tier's grid, prepared at open; `None` without a served tier.
    served: Option<ServedGrid>,
    /// A version-3 table's posture term, prepared at open.
    posture: Option<PreparedPosture>,
}

/// How far a hybrid table lets the nominal TCP at the query's joint values lie from the
/// target ([`Table::joints_tolerance_mm`]): the residual's fade length
/// ([`crate::served::fade_length_mm`]), two cells and at least 20 mm.
///
/// Joint values the controller uses for a target put the nominal TCP on it (the shipped
/// UR5 samples: within 0.05 mm); joint values in the wrong unit put it hundreds of
/// millimetres away. A table does not hold its samples' joint values (only a table with a
/// joint screen does), so the bound cannot be learnt from them; it is the distance beyond
/// which the table itself treats a position as unrelated to its residual field: farther
/// than that, the model part (at the joints' pose) and the residual part (at the target)
/// would describe two places the table keeps apart.
fn joints_tolerance_mm(grid: &Grid) -> f64 {
    crate::served::fade_length_mm(grid.cell_mm)
}

/// A hybrid query's model part ([`Table::answer`]).
#[derive(Clone, Copy, Debug)]
struct ModelPart {
    /// The model's orientation error at the query's joint values (rotation vector, rad,
    /// base frame).
    rotation_rad: [f64; 3],
    /// The nominal TCP's approach axis at the query's joint values, base frame.
    approach: [f64; 3],
    /// The model's position error at the table's point, mm, base frame.
    error_mm: [f64; 3],
    /// A named TCP's lever from the table's point, base frame (mm): the answer's rotation
    /// error, the model's and the residual's, turns it (docs/runtime.md, "Another TCP").
    /// `None` when no TCP is named or the table does not record its point.
    lever_mm: Option<[f64; 3]>,
    /// Where the table's point is for the target, mm, base frame: what the residual
    /// field and the joints' check read.
    point_mm: [f64; 3],
    /// Whether a joint with joint-space terms is beyond the angles they were identified
    /// over ([`Evidence::JOINTS`]).
    beyond_terms: bool,
}

impl ModelPart {
    /// The answer's position error at the target's TCP from its error at the table's
    /// point (the residual's and the model's) and its whole rotation error: a named TCP's
    /// lever turned by that rotation, as the TCP rides on the point; the point's error
    /// when no TCP is named. Both served paths and the exact tier add it alike.
    #[inline(always)]
    fn at_tcp(&self, point_error_mm: [f64; 3], rotation_rad: [f64; 3]) -> [f64; 3] {
        match self.lever_mm {
            Some(lever_mm) => {
                let turn = rotation_displacement(rotation_rad, lever_mm);
                [0, 1, 2].map(|a| point_error_mm[a] + turn[a])
            }
            None => point_error_mm,
        }
    }
}

/// [`scaled_residual`] of a correction's residual, in place.
#[inline(always)]
fn scale_residual(c: &mut Correction, scale: f64) {
    let parts = (
        c.position_error_mm,
        c.orientation_error_rad,
        c.neighbours,
        c.residual,
    );
    (
        c.position_error_mm,
        c.orientation_error_rad,
        c.neighbours,
        c.residual,
    ) = scaled_residual(scale, parts);
}

/// A hybrid answer's residual (its position and orientation parts, the neighbours it
/// weighed, its flag) scaled by the model part's `scale`
/// ([`PreparedModel::residual_scale`]): unchanged at 1, none at 0 (the model alone,
/// [`Residual::ModelOnly`]), else scaled and at least [`Residual::Faded`].
#[inline(always)]
fn scaled_residual(
    scale: f64,
    parts: ([f64; 3], [f64; 3], u32, Residual),
) -> ([f64; 3], [f64; 3], u32, Residual) {
    if scale >= 1.0 {
        return parts;
    }
    if scale <= 0.0 {
        return ([0.0; 3], [0.0; 3], 0, Residual::ModelOnly);
    }
    let (position_mm, orientation_rad, neighbours, residual) = parts;
    let residual = match residual {
        Residual::Full => Residual::Faded,
        other => other,
    };
    (
        position_mm.map(|v| v * scale),
        orientation_rad.map(|v| v * scale),
        neighbours,
        residual,
    )
}

/// Whether a target's values are finite and within the plausible range: positions and
/// a TCP within [`MAX_COORDINATE_MM`], a rotation of at most a few turns.
#[inline]
fn target_is_plausible(target: &Target) -> bool {
    let within = |v: &[f64; 3], limit: f64| v.iter().all(|x| x.abs() <= limit);
    // Written so that NaN fails each test.
    within(&target.position_mm, MAX_COORDINATE_MM)
        && target.tcp_mm.is_none_or(|t| within(&t, MAX_COORDINATE_MM))
        && target
            .rotation_rad
            .is_none_or(|r| within(&r, MAX_ROTATION_RAD))
}

/// The largest plausible component of a target's rotation vector, rad: two turns.
const MAX_ROTATION_RAD: f64 = 4.0 * std::f64::consts::PI;

/// A table's archived payload, by format version.
#[derive(Clone, Copy, Debug)]
pub enum Payload<'a> {
    /// A version-1 table ([`v1::TableData`]).
    V1(&'a v1::ArchivedTableData),
    /// A version-2 table ([`v2::TableData`]), or the version-2 part of a version-3 one
    /// ([`v3::TableData::base`]; [`Table::posture`] says whether it has the term).
    V2(&'a v2::ArchivedTableData),
}

/// Which tier answers a query ([`Table::answer`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tier {
    /// The served field: the nodes of the target's cell, blended ([`Table::query`]).
    Served,
    /// The exact tier: the method itself, from the cell's candidates ([`Table::exact`]).
    Exact,
}

/// The exact tier of a table ([`Table::exact`]): the paper's method to the digit, with the
/// same calls as the table's served field.
#[derive(Clone, Copy)]
pub struct Exact<'a, D> {
    table: &'a Table<D>,
}

/// An owned copy of a table's bytes, aligned to a cache line (64 bytes): the payload then
/// starts on one, as in a memory map, and so does every version-2 cell record.
///
/// Made by [`AlignedBytes::copy_from`], whose allocation is fallible: a table too large
/// for the memory left is an error, never an abort of the process that asked (a
/// controller).
pub struct AlignedBytes {
    /// The allocation: `start` bytes of padding, then the table's bytes. Never grown after
    /// the copy, so the table's bytes never move.
    buffer: Vec<u8>,
    /// Where the table's bytes start: the first 64-byte boundary of `buffer`.
    start: usize,
}

/// The alignment of [`AlignedBytes`], bytes.
const CACHE_LINE: usize = 64;

impl AlignedBytes {
    /// Copies `bytes` into memory aligned to 64 bytes.
    ///
    /// # Errors
    ///
    /// [`OpenError::OutOfMemory`] when the copy cannot be allocated; nothing is aborted
    /// and nothing is printed.
    pub fn copy_from(bytes: &[u8]) -> Result<AlignedBytes, OpenError> {
        let len = bytes.len();
        let too_large = || OpenError::OutOfMemory { len: len as u64 };
        let capacity = len.checked_add(CACHE_LINE - 1).ok_or_else(too_large)?;
        let mut buffer = Vec::<u8>::new();
        buffer
            .try_reserve_exact(capacity)
            .map_err(|_| too_large())?;
        let start = buffer.as_ptr().align_offset(CACHE_LINE).min(CACHE_LINE - 1);
        // Within the capacity reserved: neither reallocates.
        buffer.resize(start, 0);
        buffer.extend_from_slice(bytes);
        Ok(AlignedBytes { buffer, start })
    }
}

impl AsRef<[u8]> for AlignedBytes {
    #[inline]
    fn as_ref(&self) -> &[u8] {
        self.buffer.get(self.start..).unwrap_or_default()
    }
}

impl std::ops::Deref for AlignedBytes {
    type Target = [u8];
    #[inline]
    fn deref(&self) -> &[u8] {
        self.as_ref()
    }
}

impl Table<memmap2::Mmap> {
    /// Memory-maps and validates the table at `path`.
    ///
    /// # Errors
    ///
    /// Any [`OpenError`]: the file cannot be read or is not a regular file (a FIFO, a
    /// device: [`crate::input::open_regular`]), or fails a check of
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
        // A FIFO or a device is refused at once: never waited on, never read without end.
        let file = crate::input::open_regular(path.as_ref())?;
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

/// rkyv's validation message with every address in it ("ptr 0x00007f3a…") given as the
/// byte of the file it points at: a heap address tells a reader nothing, changes from run
/// to run, and would tell a C host's log where this process keeps its memory.
fn without_addresses(error: &impl std::fmt::Display, payload: &[u8]) -> String {
    use std::fmt::Write;
    let message = error.to_string();
    let base = payload.as_ptr() as usize as i128 - HEADER_LEN as i128;
    let mut out = String::with_capacity(message.len());
    let mut rest = message.as_str();
    while let Some(at) = rest.find("0x") {
        out.push_str(&rest[..at]);
        let digits = rest[at + 2..]
            .bytes()
            .take_while(u8::is_ascii_hexdigit)
            .count();
        let token = &rest[at..at + 2 + digits];
        match u64::from_str_radix(&token[2..], 16) {
            Ok(address) if digits > 0 => {
                let _ = write!(out, "file byte {}", address as i128 - base);
            }
            _ => out.push_str(token),
        }
        rest = &rest[at + 2 + digits..];
    }
    out.push_str(rest);
    out
}

impl Table<AlignedBytes> {
    /// Copies `bytes` into an aligned buffer and validates it; for bytes of unknown
    /// alignment (a `Vec<u8>`, an `include_bytes!`).
    ///
    /// # Errors
    ///
    /// [`OpenError::OutOfMemory`] when the copy cannot be allocated, or as
    /// [`Table::from_bytes`].
    pub fn from_vec(bytes: impl AsRef<[u8]>) -> Result<Table<AlignedBytes>, OpenError> {
        Table::from_bytes(AlignedBytes::copy_from(bytes.as_ref())?)
    }
}

impl<D: AsRef<[u8]>> Table<D> {
    /// Validates a table held in `data`. Never panics, for any input.
    ///
    /// Checks, in order, stopping at the first failure:
    /// 1. the header ([`Header::from_bytes`]): length, magic, endianness mark, version,
    ///    header length, header checksum, rkyv format flags, reserved bytes;
    /// 2. the length: header plus payload length, exactly;
    /// 3. the payload checksum;
    /// 4. the buffer's alignment, then rkyv validation of the version's archive (bounds,
    ///    alignment);
    /// 5. the table's own invariants ([`crate::validate`]): parameters in range, known
    ///    content flags, grid size matching the cells, counts, finite values, parameters,
    ///    grid and samples of plausible magnitude ([`crate::format::check_plausible`]),
    ///    every index in range, candidate lists without repeats, node values finite or
    ///    marked missing, kinematic chains valid.
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
        let archive_error =
            |e: rkyv::rancor::BoxedError| OpenError::Archive(without_addresses(&e, payload));
        let v2_part = |archived: &v2::ArchivedTableData| {
            let model = crate::validate::validate_v2(&header, archived)?;
            let served = (header.node_set_count > 0).then(|| ServedGrid::new(&header, archived));
            Ok::<_, OpenError>((model, served))
        };
        let (model, served, posture) = match header.version {
            1 => {
                let archived =
                    rkyv::access::<v1::ArchivedTableData, rkyv::rancor::BoxedError>(payload)
                        .map_err(archive_error)?;
                crate::validate::validate_v1(&header, archived)?;
                (crate::model::prepared_model_v1(archived), None, None)
            }
            _ if header.has_joint_terms() => {
                let archived =
                    rkyv::access::<v5::ArchivedTableData, rkyv::rancor::BoxedError>(payload)
                        .map_err(archive_error)?;
                let (model, served) = v2_part(&archived.base)?;
                let corrupt = OpenError::Corrupt {
                    what: "joint-space terms that do not fit the calibrated chain (non-finite, beyond 0.1 rad, on a prismatic joint or beyond the chain)",
                };
                let model = match (model, archived.joint_terms.to_terms()) {
                    (Some(m), Some(terms)) => {
                        let m = m.with_joint_terms(terms).ok_or(corrupt)?;
                        Some(match header.bounds_residual_by_joints() {
                            true => m.bounding_residual(),
                            false => m,
                        })
                    }
                    _ => return Err(corrupt),
                };
                let posture = if header.has_posture() {
                    crate::validate::validate_posture(&header, &archived.posture)?;
                    Some(PreparedPosture::new(&header, &archived.posture))
                } else {
                    None
                };
                (model, served, posture)
            }
            _ if !header.has_posture() => {
                let archived =
                    rkyv::access::<v2::ArchivedTableData, rkyv::rancor::BoxedError>(payload)
                        .map_err(archive_error)?;
                let (model, served) = v2_part(archived)?;
                (model, served, None)
            }
            _ => {
                let archived =
                    rkyv::access::<v3::ArchivedTableData, rkyv::rancor::BoxedError>(payload)
                        .map_err(archive_error)?;
                let (model, served) = v2_part(&archived.base)?;
                crate::validate::validate_posture(&header, &archived.posture)?;
                let posture = PreparedPosture::new(&header, &archived.posture);
                (model, served, Some(posture))
            }
        };
        let validated_at = (bytes.as_ptr() as usize, bytes.len());
        Ok(Table {
            data,
            header,
            validated_at,
            model,
            served,
            posture,
        })
    }

    /// Moves the validated bytes into another holder without validating them again, for a
    /// holder whose `as_ref` returns the same slice (wrapping a memory map in an enum,
    /// say). Should it not, every query answers [`Status::InvalidInput`]: the address check
    /// of [`Table::payload`] still guards every access.
    pub(crate) fn map_data<E: AsRef<[u8]>>(self, wrap: impl FnOnce(D) -> E) -> Table<E> {
        Table {
            data: wrap(self.data),
            header: self.header,
            validated_at: self.validated_at,
            model: self.model,
            served: self.served,
            posture: self.posture,
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

    /// Whether this is a hybrid table (a kinematic model plus residuals): it then needs the
    /// target's joint values ([`Table::query_with_joints`]).
    pub fn is_hybrid(&self) -> bool {
        self.header.content_flags & CONTENT_MODEL != 0
    }

    /// The joint-space admissibility radius, rad; 0 when the screen is off.
    pub fn joint_radius_rad(&self) -> f64 {
        self.header.joint_radius_rad
    }

    /// The number of joint values [`Table::query_with_joints`] takes: the robot's joint
    /// count when the table carries joint values or a model, `None` when joint values play
    /// no part in its answers (any count is then accepted and ignored).
    pub fn joint_count(&self) -> Option<usize> {
        (self.header.joint_count > 0).then_some(self.header.joint_count as usize)
    }

    /// Which joint values are lengths (mm) rather than angles: bit `i` for a prismatic
    /// joint `i`, as the table's model says ([`crate::chain::Chain::prismatic_joints`]);
    /// none without a model.
    pub fn prismatic_joints(&self) -> u64 {
        self.model
            .as_ref()
            .map_or(0, |m| m.nominal().prismatic_joints())
    }

    /// Whether the table has a served tier (a continuous field): version-2 tables without a
    /// joint-space screen. Without one, [`Table::query`] and the others answer from the
    /// exact tier.
    pub fn has_served_field(&self) -> bool {
        self.header.node_set_count > 0
    }

    /// A hybrid table's bound on the distance between the target and the nominal TCP at
    /// the query's joint values, mm; farther, a query answers [`Status::JointsMismatch`].
    /// `None` for a position-only table (joint values then never move the answer's pose).
    pub fn joints_tolerance_mm(&self) -> Option<f64> {
        self.model
            .is_some()
            .then(|| joints_tolerance_mm(&self.header.grid))
    }

    /// A hybrid table's model, its chains ready for evaluation.
    pub fn model(&self) -> Option<&PreparedModel> {
        self.model.as_ref()
    }

    /// A hybrid table's posture term's parameters, when it has one ([`crate::posture`]):
    /// its served answers then add the term at the query's joint values.
    pub fn posture(&self) -> Option<PostureParams> {
        self.posture.map(|p| p.params())
    }

    /// A version-3 table's posture record, or `None` for another table or if `data` no
    /// longer returns the validated slice.
    #[inline]
    pub fn posture_record(&self) -> Option<&v3::ArchivedPostureRecord> {
        let bytes = self.data.as_ref();
        if !self.header.has_posture() || (bytes.as_ptr() as usize, bytes.len()) != self.validated_at
        {
            return None;
        }
        let payload = &bytes[HEADER_LEN..];
        if self.header.has_joint_terms() {
            // SAFETY: as in `payload`: these bytes passed `rkyv::access` for version 5.
            let data = unsafe { rkyv::access_unchecked::<v5::ArchivedTableData>(payload) };
            return Some(&data.posture);
        }
        // SAFETY: as in `payload`: these bytes passed `rkyv::access` for version 3.
        let data = unsafe { rkyv::access_unchecked::<v3::ArchivedTableData>(payload) };
        Some(&data.posture)
    }

    /// The validated archive, or `None` if `data` no longer returns the validated slice.
    #[inline]
    pub fn payload(&self) -> Option<Payload<'_>> {
        let bytes = self.data.as_ref();
        if (bytes.as_ptr() as usize, bytes.len()) != self.validated_at {
            return None;
        }
        let payload = &bytes[HEADER_LEN..];
        // SAFETY: these exact bytes (same address and length) passed `rkyv::access` for
        // this version's archive in `from_bytes`, and `D` gives shared access only, so they
        // are unchanged (for a memory map, by the contract of `Table::open`).
        Some(unsafe {
            match self.header.version {
                1 => Payload::V1(rkyv::access_unchecked::<v1::ArchivedTableData>(payload)),
                _ if self.header.has_joint_terms() => {
                    Payload::V2(&rkyv::access_unchecked::<v5::ArchivedTableData>(payload).base)
                }
                _ if !self.header.has_posture() => {
                    Payload::V2(rkyv::access_unchecked::<v2::ArchivedTableData>(payload))
                }
                _ => Payload::V2(&rkyv::access_unchecked::<v3::ArchivedTableData>(payload).base),
            }
        })
    }

    /// The number of samples.
    pub fn sample_count(&self) -> usize {
        self.header.sample_count as usize
    }

    /// The served correction at a position. Never allocates, locks or panics.
    ///
    /// A hybrid table answers [`Status::MissingJoints`]: use [`Table::query_with_joints`].
    #[inline]
    pub fn query(&self, position_mm: [f64; 3]) -> Correction {
        let target = Target::at(position_mm);
        match self.strict_served(&target) {
            Some((grid, data)) => self.served_strict(&target, data, grid),
            None => self.answer(&target, None, Tier::Served),
        }
    }

    /// The served correction at a target. Never allocates, locks or panics.
    ///
    /// A hybrid table answers [`Status::MissingJoints`]: use [`Table::query_with_joints`].
    #[inline]
    pub fn query_target(&self, target: &Target) -> Correction {
        match self.strict_served(target) {
            Some((grid, data)) => self.served_strict(target, data, grid),
            None => self.answer(target, None, Tier::Served),
        }
    }

    /// The served correction at a target that the controller will reach with joint values
    /// `joints_rad` (rad, mm for prismatic joints, in the robot file's order; exactly
    /// [`Table::joint_count`] of them when that is known). Never allocates, locks or
    /// panics.
    ///
    /// - On a hybrid table: the calibrated model's predicted error at `joints_rad` plus
    ///   the residual field at the target (see [`crate::model`]); a field that turns with
    ///   the tool ([`crate::format::ServedField::KrigingToolAxis`]) is turned by the
    ///   nominal TCP's approach axis at `joints_rad`.
    /// - On any table with a joint radius ([`Table::joint_radius_rad`]): only samples
    ///   whose joint values are all within that radius of `joints_rad` are admissible
    ///   (such a table has no served tier: this is its exact tier).
    /// - Otherwise the answer equals [`Table::query_target`]'s.
    ///
    /// Non-finite joint values, or a count other than the table's, give
    /// [`Status::InvalidInput`]. The joint values are taken as given: they are not checked
    /// against the target position (the controller's inverse kinematics is the authority
    /// on them).
    #[inline]
    pub fn query_with_joints(&self, target: &Target, joints_rad: &[f64]) -> Correction {
        match self.hybrid_served(target, joints_rad) {
            Some((model, grid, data)) => self.served_hybrid(target, joints_rad, model, grid, data),
            None => self.answer(target, Some(joints_rad), Tier::Served),
        }
    }

    /// The command that lands the robot on `target` by the served field
    /// ([`Table::query_target`]): iterates `command ← target − error(command)` from
    /// `command = target` until `|command + error(command) − target| ≤ tolerance_mm` or
    /// `max_iterations` queries. The served field is continuous and varies slowly (its
    /// slope is a small fraction of one), so the iteration contracts. Never allocates,
    /// locks or panics.
    pub fn compensate(
        &self,
        target: &Target,
        tolerance_mm: f64,
        max_iterations: u32,
    ) -> Compensation {
        self.compensate_with(target, tolerance_mm, max_iterations, Tier::Served)
    }

    /// The exact tier, for the paper's method to the digit: [`Exact::query`] and the
    /// others answer as this table's calls do, from the cell's candidate list.
    pub fn exact(&self) -> Exact<'_, D> {
        Exact { table: self }
    }

    /// The full exact prediction at a target: the neighbours used, nearest first, with
    /// their approximation degrees and weights. Never allocates, locks or panics.
    ///
    /// # Errors
    ///
    /// The [`Status`] explaining why no prediction exists ([`Status::MissingJoints`] on a
    /// hybrid table, whose residuals alone are not the error).
    pub fn explain(&self, target: &Target) -> Result<Prediction, Status> {
        if self.is_hybrid() {
            return Err(Status::MissingJoints);
        }
        if !target.position_mm.iter().all(|v| v.is_finite()) {
            return Err(Status::InvalidInput);
        }
        let prediction = match self.payload().ok_or(Status::InvalidInput)? {
            Payload::V1(d) => exact::explain(&V1(d), &self.header, target, None)?,
            Payload::V2(d) => {
                exact::explain(&V2::new(d, &self.header), &self.header, target, None)?
            }
        };
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

    /// Every query's path: checks, the tier's residual (or whole) correction, the model
    /// part of a hybrid table, and the last guard against a non-finite answer. The named
    /// calls are this with their tier and joint values fixed (`query_target(t)` is
    /// `answer(t, None, Tier::Served)`); a caller choosing the tier and whether joint values
    /// are known at run time calls it directly. Never allocates, locks or panics.
    #[inline]
    pub fn answer(&self, target: &Target, joints_rad: Option<&[f64]>, tier: Tier) -> Correction {
        if joints_rad.is_none() && self.model.is_some() {
            return Correction::failed(Status::MissingJoints);
        }
        if !target_is_plausible(target) {
            return Correction::failed(Status::InvalidInput);
        }
        if let Some(q) = joints_rad {
            let expected = self.joint_count();
            if !q.iter().all(|v| v.is_finite()) || expected.is_some_and(|n| n != q.len()) {
                return Correction::failed(Status::InvalidInput);
            }
        }
        let Some(payload) = self.payload() else {
            return Correction::failed(Status::InvalidInput);
        };
        let h = &self.header;
        // The factor on a hybrid table's residual at the joint values (1 without a model):
        // 0 beyond the angles the samples span, where no residual is read at all.
        let residual_scale = match (&self.model, joints_rad) {
            (Some(model), Some(q)) => model.residual_scale(q),
            _ => 1.0,
        };
        let residual_read = residual_scale > 0.0;
        // Without a named TCP the served cell is known now: a hybrid table asks for its
        // nodes' memory before the model's arithmetic, which then hides their latency.
        let early_site = match (payload, &self.served, tier, target.tcp_mm) {
            (Payload::V2(d), Some(grid), Tier::Served, None) if residual_read => {
                let site = crate::served::site(grid, d, target.position_mm, target.config);
                if let (Ok(site), Some(_)) = (&site, &self.model) {
                    crate::served::prefetch(grid, d, site, self.has_orientation());
                }
                Some(site)
            }
            _ => None,
        };
        // Likewise the exact tier's candidate record.
        if let (Payload::V2(d), Tier::Exact, None, Some(_), true) =
            (payload, tier, target.tcp_mm, &self.model, residual_read)
        {
            exact::prefetch(d, h, target.position_mm);
        }
        // A hybrid table's model at the joint values, once: its pose error, the approach
        // axis a field turning with the tool needs and the evidence check reads, where the
        // joints put the nominal TCP, and, for a named TCP, where the table's point is
        // (`point`: the target less the lever) and the error at the TCP.
        let model_part = match (&self.model, joints_rad) {
            (Some(model), Some(q)) => {
                match self.model_part(model, q, target, |off_mm2| {
                    // Written so that NaN (a chain that overflowed) is not within.
                    off_mm2.sqrt() <= joints_tolerance_mm(&self.header.grid)
                }) {
                    Ok(part) => Some(part),
                    Err(status) => return Correction::failed(status),
                }
            }
            _ => None,
        };
        let point = Target {
            position_mm: model_part.map_or(target.position_mm, |m| m.point_mm),
            ..*target
        };
        // Flagged, not switched: the answer stays continuous across the edge of the
        // samples' evidence (on the KR150-2 hybrid table the residual left in changes the
        // figures beyond it by under 0.002 mm).
        let evidence = self.evidence_of(target, model_part.as_ref());
        let site = match (payload, &self.served, tier) {
            _ if early_site.is_some() => early_site,
            (Payload::V2(d), Some(grid), Tier::Served) if residual_read => Some(
                crate::served::site(grid, d, point.position_mm, point.config),
            ),
            _ => None,
        };
        let mut correction = match payload {
            _ if !residual_read => Correction::model_only(),
            Payload::V1(d) => exact::interpolate(&V1(d), h, &point, joints_rad),
            Payload::V2(d) => match (&self.served, site) {
                (Some(_), Some(Err(status))) => Correction::failed(status),
                (Some(grid), Some(Ok(site))) => {
                    let orientation = self.has_orientation();
                    if h.served_field.node_stride() == 1 {
                        match crate::served::blend_site::<1>(grid, d, &site, orientation) {
                            Ok(terms) => terms.correction(),
                            Err(status) => Correction::failed(status),
                        }
                    } else {
                        match crate::served::blend_site::<4>(grid, d, &site, orientation) {
                            Err(status) => Correction::failed(status),
                            // Validation admits such a field in hybrid tables only, and
                            // those were given joint values above.
                            Ok(terms) => match &model_part {
                                Some(m) => terms.turned(m.approach),
                                None => Correction::failed(Status::InvalidInput),
                            },
                        }
                    }
                }
                _ => exact::interpolate(&V2::new(d, h), h, &point, joints_rad),
            },
        };
        // A hybrid table's model holds everywhere: where the method has no neighbour, or
        // the target is outside the grid, the answer is the model alone.
        let residual_missing = matches!(
            correction.status,
            Status::OutsideGrid | Status::NoAdmissibleNeighbour
        );
        if residual_missing && self.model.is_some() {
            correction = Correction::model_only();
        }
        if correction.status != Status::Ok {
            return correction;
        }
        if let (Some(posture), Some(q), Tier::Served, true) =
            (&self.posture, joints_rad, tier, residual_read)
        {
            let term = self
                .posture_record()
                .and_then(|r| posture.term(r, point.position_mm, q));
            let Some(term) = term else {
                return Correction::failed(Status::InvalidInput);
            };
            for (out, p) in correction.position_error_mm.iter_mut().zip(term) {
                *out += p;
            }
        }
        if let Some(m) = &model_part {
            scale_residual(&mut correction, residual_scale);
            for (out, model) in correction.position_error_mm.iter_mut().zip(m.error_mm) {
                *out += model;
            }
            // The model's orientation error where the samples measured one (zero
            // otherwise, `model_part`): a command's orientation is corrected by it.
            let orientation = correction.orientation_error_rad.iter_mut();
            for (out, model) in orientation.zip(m.rotation_rad) {
                *out += model;
            }
            correction.position_error_mm = m.at_tcp(
                correction.position_error_mm,
                correction.orientation_error_rad,
            );
        }
        correction.evidence = evidence;
        correction.finite_or_failure()
    }

    /// Whether [`Table::served_strict`] answers a served query of `target` as
    /// [`Table::answer`] does: a table without a model or a posture term whose field
    /// neither fades nor turns with the tool (a position-only table's), a plausible target
    /// and the validated bytes; with what it reads. `None` for another table, or a target
    /// or bytes `answer` refuses (it then says why). Kept out of `answer`, whose other
    /// tiers and tables it slowed there; the answer not wrapped in an `Option`, as
    /// [`Table::hybrid_served`] says why.
    #[inline(always)]
    fn strict_served(&self, target: &Target) -> Option<(&ServedGrid, &v2::ArchivedTableData)> {
        let (None, None, Some(grid)) = (&self.model, &self.posture, &self.served) else {
            return None;
        };
        if !grid.is_strict() || !target_is_plausible(target) {
            return None;
        }
        match self.payload() {
            Some(Payload::V2(data)) => Some((grid, data)),
            _ => None,
        }
    }

    /// [`Table::answer`]'s served query of a position-only table, for [`Table::query`] and
    /// [`Table::query_target`] once [`Table::strict_served`] has checked it: the same
    /// answer to the bit, by the steps that table takes and no test of the others (the
    /// target's cell, its 8 nodes blended by [`crate::served::blend_strict`], the evidence
    /// flag, the last guard).
    #[inline(always)]
    fn served_strict(
        &self,
        target: &Target,
        data: &v2::ArchivedTableData,
        grid: &ServedGrid,
    ) -> Correction {
        let site = match crate::served::site(grid, data, target.position_mm, target.config) {
            Ok(site) => site,
            Err(status) => return Correction::failed(status),
        };
        let orientation = self.has_orientation();
        let blended = match crate::served::blend_strict(grid, data, &site, orientation) {
            Ok(correction) => correction,
            Err(status) => return Correction::failed(status),
        };
        Correction::ok_if_finite(
            blended.position_error_mm,
            blended.orientation_error_rad,
            blended.neighbours,
            blended.residual,
            self.evidence_of(target, None),
        )
    }

    /// Whether [`Table::served_hybrid`] answers a served query of `target` at `joints_rad`
    /// as [`Table::answer`] does: a hybrid table without a posture term, a plausible
    /// target, finite joint values of the table's count and the validated bytes; with what
    /// it reads. `None` for another table or query (`answer` then says why).
    ///
    /// The answer is not wrapped in an `Option` here: an `Option<Correction>` returned
    /// through memory was copied in pieces of other widths than those stored, a stall of
    /// the processor's store forwarding each.
    #[inline(always)]
    fn hybrid_served(
        &self,
        target: &Target,
        joints_rad: &[f64],
    ) -> Option<(&PreparedModel, &ServedGrid, &v2::ArchivedTableData)> {
        let (Some(model), None, Some(grid)) = (&self.model, &self.posture, &self.served) else {
            return None;
        };
        let joints_fit = joints_rad.len() == self.header.joint_count as usize
            && joints_rad.iter().all(|v| v.is_finite());
        if !joints_fit || !target_is_plausible(target) {
            return None;
        }
        match self.payload() {
            Some(Payload::V2(data)) => Some((model, grid, data)),
            _ => None,
        }
    }

    /// [`Table::answer`]'s served query of a hybrid table without a posture term, for
    /// [`Table::query_with_joints`] once [`Table::hybrid_served`] has checked it: the
    /// same answer to the bit, by the steps that table takes in the same order (the
    /// target's cell and its prefetch, the model part, the evidence flag, the blend, the
    /// model added, the last guard), without the tests and the moves of the other tiers
    /// and tables.
    #[inline(always)]
    fn served_hybrid(
        &self,
        target: &Target,
        q: &[f64],
        model: &PreparedModel,
        grid: &ServedGrid,
        data: &v2::ArchivedTableData,
    ) -> Correction {
        let orientation = self.has_orientation();
        // As in `answer`: the residual's factor first (0: no residual read), and without a
        // named TCP the cell is known before the model part.
        let residual_scale = model.residual_scale(q);
        let early_site = match (target.tcp_mm, residual_scale > 0.0) {
            (None, true) => {
                let site = crate::served::site(grid, data, target.position_mm, target.config);
                if let Ok(site) = &site {
                    crate::served::prefetch(grid, data, site, orientation);
                }
                Some(site)
            }
            _ => None,
        };
        let m = match self.model_part(model, q, target, |off_mm2| grid.joints_within(off_mm2)) {
            Ok(part) => part,
            Err(status) => return Correction::failed(status),
        };
        let evidence = self.evidence_of(target, Some(&m));
        let site = match (early_site, residual_scale > 0.0) {
            (Some(site), _) => site,
            (None, true) => crate::served::site(grid, data, m.point_mm, target.config),
            (None, false) => Ok(crate::served::Site::ModelOnly),
        };
        let blended = match site {
            Ok(site) if grid.stride() == 1 => {
                match crate::served::blend_site::<1>(grid, data, &site, orientation) {
                    Ok(terms) => Ok(terms.correction()),
                    Err(status) => Err(status),
                }
            }
            Ok(site) => match crate::served::blend_site::<4>(grid, data, &site, orientation) {
                Ok(terms) => Ok(terms.turned(m.approach)),
                Err(status) => Err(status),
            },
            Err(status) => Err(status),
        };
        // The residual's fields apart, not a correction: one merged from two branches was
        // written field by field and then copied whole, reloaded in wider pieces than
        // stored (a stall of the processor's store forwarding).
        let parts = |c: Correction| {
            (
                c.position_error_mm,
                c.orientation_error_rad,
                c.neighbours,
                c.residual,
            )
        };
        let (position_mm, orientation_rad, neighbours, residual) = match blended {
            Ok(correction) => parts(correction),
            // The model holds everywhere: where the residual has nothing, the model alone.
            Err(Status::OutsideGrid | Status::NoAdmissibleNeighbour) => {
                parts(Correction::model_only())
            }
            Err(status) => return Correction::failed(status),
        };
        let (position_mm, orientation_rad, neighbours, residual) = scaled_residual(
            residual_scale,
            (position_mm, orientation_rad, neighbours, residual),
        );
        // The residual plus the model, as `answer` adds them (a named TCP's lever turned
        // by the sum); built once, in place.
        let plus = |a: [f64; 3], b: [f64; 3]| [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
        let rotation_rad = plus(orientation_rad, m.rotation_rad);
        let position_mm = m.at_tcp(plus(position_mm, m.error_mm), rotation_rad);
        Correction::ok_if_finite(position_mm, rotation_rad, neighbours, residual, evidence)
    }

    /// A hybrid query's model part (see [`Table::answer`]): the model at `q` with its
    /// orientation, the table's point for the target, the joints' check against that
    /// point, and a named TCP's lever, which the answer's rotation error turns.
    #[inline(always)]
    fn model_part(
        &self,
        model: &PreparedModel,
        q: &[f64],
        target: &Target,
        joints_within: impl FnOnce(f64) -> bool,
    ) -> Result<ModelPart, Status> {
        // The model's rotation error is served only where the samples measured
        // orientation: positions at one point do not determine it, and a model fitted to
        // them can be several times further from the true rotation than no correction
        // (docs/runtime.md, "Another TCP"). A named TCP still needs the nominal rotation
        // to place its lever, which then turns by nothing.
        let rotation = self.has_orientation();
        // Not `ok_or`: its `Result` was copied through memory in misaligned pieces. Read
        // in place, by reference: a binding by value was a `memcpy` of the answer.
        let mut evaluated = model.evaluate(q, rotation || target.tcp_mm.is_some());
        let Some(at) = evaluated.as_mut() else {
            return Err(Status::InvalidInput);
        };
        if !rotation {
            at.rotation_rad = [0.0; 3];
        }
        let (point_mm, lever_mm) = self.placed(model, at, target)?;
        // NaN (a chain that overflowed) is refused too.
        if !joints_within(method::distance_squared_mm2(at.nominal_tcp_mm, point_mm)) {
            return Err(Status::JointsMismatch);
        }
        Ok(ModelPart {
            rotation_rad: at.rotation_rad,
            approach: at.approach,
            error_mm: at.position_mm,
            lever_mm,
            point_mm,
            beyond_terms: model.beyond_terms(q),
        })
    }

    /// Where a hybrid query puts `target` for the model evaluated `at` its joint values:
    /// the table's point for the target (the target moved back by the TCP's lever when the
    /// table records its point in the flange, else the target itself), which the joints'
    /// nominal TCP must lie near, and that lever in the base frame.
    #[inline(always)]
    fn placed(
        &self,
        model: &PreparedModel,
        at: &ModelAt,
        target: &Target,
    ) -> Result<([f64; 3], Option<[f64; 3]>), Status> {
        match (target.tcp_mm, self.header.evidence.point_in_flange) {
            (Some(tcp), Some(point)) => {
                let lever_mm = model
                    .lever_in_base(at, point.lever_of(tcp))
                    .ok_or(Status::InvalidInput)?;
                let p = target.position_mm;
                Ok(([0, 1, 2].map(|i| p[i] - lever_mm[i]), Some(lever_mm)))
            }
            _ => Ok((target.position_mm, None)),
        }
    }

    /// How far a hybrid table's nominal TCP at `joints_rad` lies from the table's point
    /// for `target` (with a named TCP the table records its point for, the target moved
    /// back by the TCP's lever), mm: what a query compares with
    /// [`Table::joints_tolerance_mm`] before it answers [`Status::JointsMismatch`].
    /// `None` for a position-only table or joint values the model cannot evaluate (a
    /// count other than the table's, a non-finite value).
    pub fn joints_offset_mm(&self, target: &Target, joints_rad: &[f64]) -> Option<f64> {
        let model = self.model.as_ref()?;
        let at = model.evaluate(joints_rad, true)?;
        let (point_mm, _) = self.placed(model, &at, target).ok()?;
        Some(method::distance_mm(at.nominal_tcp_mm, point_mm))
    }

    /// Where a query lies beyond the table's recorded evidence ([`Evidence`]): the tool's
    /// approach axis (a hybrid table's from its joint values, else the target's given
    /// orientation) against the samples' cone, a named TCP the table cannot place, and a
    /// hybrid table's joints beyond the angles its model's terms were identified over.
    #[inline(always)]
    fn evidence_of(&self, target: &Target, model_part: Option<&ModelPart>) -> Evidence {
        let mut evidence = Evidence::WITHIN;
        if let Some(cone) = self.header.evidence.approach {
            let axis = match (model_part, target.rotation_rad) {
                (Some(m), _) => Some(m.approach),
                (None, Some(rotation)) => {
                    let r = crate::kinematics::rotation_from_vector(rotation);
                    Some([r[0][2], r[1][2], r[2][2]])
                }
                (None, None) => None,
            };
            if axis.is_some_and(|axis| !cone.holds(axis)) {
                evidence = evidence.with(Evidence::ORIENTATION);
            }
        }
        // A hybrid table turns a named TCP's lever by its model's rotation error, within
        // the samples' evidence when they measured orientation; a position-only table has
        // nothing to turn it with ([`Header::tcp_within_evidence`]).
        if !self.header.tcp_within_evidence(target.tcp_mm) {
            evidence = evidence.with(Evidence::TCP);
        }
        if model_part.is_some_and(|m| m.beyond_terms) {
            evidence = evidence.with(Evidence::JOINTS);
        }
        evidence
    }

    fn compensate_with(
        &self,
        target: &Target,
        tolerance_mm: f64,
        max_iterations: u32,
        tier: Tier,
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
            let correction = self.answer(&command, None, tier);
            out.iterations += 1;
            out.correction = correction;
            out.command_position_mm = command.position_mm;
            if correction.status != Status::Ok {
                return out;
            }
            let p = correction.position_error_mm;
            let landing = [0, 1, 2].map(|a| command.position_mm[a] + p[a]);
            out.residual_mm = method::distance_mm(landing, target.position_mm);
            out.command_rotation_rad = correction.orientation_error_rad.map(|v| -v);
            if out.residual_mm <= tolerance_mm {
                out.converged = true;
                return out.finite_or_failure();
            }
            command.position_mm = [0, 1, 2].map(|a| target.position_mm[a] - p[a]);
        }
        out.finite_or_failure()
    }
}

impl<D: AsRef<[u8]>> Exact<'_, D> {
    /// The exact correction at a position ([`Table::query`]'s, by the method itself).
    #[inline]
    pub fn query(&self, position_mm: [f64; 3]) -> Correction {
        self.table
            .answer(&Target::at(position_mm), None, Tier::Exact)
    }

    /// The exact correction at a target ([`Table::query_target`]'s).
    #[inline]
    pub fn query_target(&self, target: &Target) -> Correction {
        self.table.answer(target, None, Tier::Exact)
    }

    /// The exact correction with the target's joint values
    /// ([`Table::query_with_joints`]'s).
    #[inline]
    pub fn query_with_joints(&self, target: &Target, joints_rad: &[f64]) -> Correction {
        self.table.answer(target, Some(joints_rad), Tier::Exact)
    }

    /// The command by the exact field ([`Table::compensate`]'s). The exact field jumps
    /// where its neighbour set changes; there the iteration can cycle and reports
    /// `converged: false` with its last command.
    pub fn compensate(
        &self,
        target: &Target,
        tolerance_mm: f64,
        max_iterations: u32,
    ) -> Compensation {
        self.table
            .compensate_with(target, tolerance_mm, max_iterations, Tier::Exact)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`Table::answer`]'s general served path for a table without a model: the cell's
    /// nodes by [`crate::served::blend_site`] (a test of each corner), then the evidence
    /// and the last guard, as every table's served query took them.
    fn served_by_blend_site<D: AsRef<[u8]>>(table: &Table<D>, target: &Target) -> Correction {
        if !target_is_plausible(target) {
            return Correction::failed(Status::InvalidInput);
        }
        let (Some(Payload::V2(d)), Some(grid)) = (table.payload(), &table.served) else {
            return Correction::failed(Status::InvalidInput);
        };
        let site = match crate::served::site(grid, d, target.position_mm, target.config) {
            Ok(site) => site,
            Err(status) => return Correction::failed(status),
        };
        let orientation = table.has_orientation();
        let mut correction = match crate::served::blend_site::<1>(grid, d, &site, orientation) {
            Ok(terms) => terms.correction(),
            Err(status) => return Correction::failed(status),
        };
        correction.evidence = table.evidence_of(target, None);
        correction.finite_or_failure()
    }

    fn bits(c: &Correction) -> ([u64; 6], u32, Status, crate::Residual, Evidence) {
        let mut v = [0; 6];
        for (o, x) in v
            .iter_mut()
            .zip(c.position_error_mm.iter().chain(&c.orientation_error_rad))
        {
            *o = x.to_bits();
        }
        (v, c.neighbours, c.status, c.residual, c.evidence)
    }

    /// A compatibility fixture's bytes, opened.
    fn fixture(path: &str) -> Table<AlignedBytes> {
        let path = format!("{}/../tables/compat/{path}", env!("CARGO_MANIFEST_DIR"));
        Table::from_vec(std::fs::read(path).unwrap()).unwrap()
    }

    /// A table's payload is serialised where its file holds it, to the bytes it has
    /// serialised alone: the version-4 UR5 hybrid fixture, decoded and encoded again, is
    /// its own file byte for byte.
    #[test]
    fn encoding_a_decoded_table_gives_its_file() {
        let path = format!(
            "{}/../tables/compat/v4/ur5_hybrid.tbl",
            env!("CARGO_MANIFEST_DIR")
        );
        let file = std::fs::read(path).unwrap();
        let table = Table::from_vec(&file).unwrap();
        let Some(Payload::V2(archived)) = table.payload() else {
            panic!("a version-2 payload");
        };
        let data: v2::TableData =
            rkyv::deserialize::<v2::TableData, rkyv::rancor::Error>(archived).unwrap();
        let alone = rkyv::to_bytes::<rkyv::rancor::Error>(&data).unwrap();
        let encoded = crate::format::encode(*table.header(), &data).unwrap();
        assert_eq!(&encoded[crate::format::HEADER_LEN..], alone.as_slice());
        assert!(encoded == file, "the file encoded again differs");
    }

    /// The version-4 UR5 hybrid fixture with a field that turns with the tool (each node's
    /// `f` its value, its `h` terms made up from it) and, when `orientation`, orientation
    /// errors made up likewise: the served paths of a tool-axis table, whose values need
    /// not be a fit of anything to be served alike by both.
    fn tool_axis_fixture(orientation: bool) -> Table<AlignedBytes> {
        let table = fixture("v4/ur5_hybrid.tbl");
        let Some(Payload::V2(archived)) = table.payload() else {
            panic!("a version-2 payload");
        };
        let mut data: v2::TableData =
            rkyv::deserialize::<v2::TableData, rkyv::rancor::Error>(archived).unwrap();
        let turn = |v: [f64; 3], t: usize| {
            if t == 0 || crate::served::is_missing(&v) {
                v
            } else {
                [v[1] * 0.3 / t as f64, -v[2] * 0.2, v[0] * 0.1 * t as f64]
            }
        };
        let four = |values: &[[f64; 3]]| -> Vec<[f64; 3]> {
            values
                .iter()
                .flat_map(|&v| (0..4).map(move |t| turn(v, t)))
                .collect()
        };
        let mut header = *table.header();
        header.served_field = crate::format::ServedField::KrigingToolAxis;
        if orientation {
            header.content_flags |= CONTENT_ORIENTATION;
            let small = |v: &[f64; 3]| v.map(|x| x * 1e-3);
            data.orientation_errors_rad = data.errors_mm.iter().map(small).collect();
            let nodes: Vec<[f64; 3]> = data.node_errors_mm.iter().map(small).collect();
            data.node_orientation_errors_rad = four(&nodes);
        }
        data.node_errors_mm = four(&data.node_errors_mm);
        Table::from_vec(crate::format::encode(header, &data).unwrap()).unwrap()
    }

    /// The version-5 fixture's payload with every joint's range `[-3, 3]` rad, as three
    /// tables: version 6 (the ranges bound the residual), the same bytes as version 5
    /// (they do not) and version 6 with no residual (every sample's and node's error
    /// zero: its answers are the model's alone).
    fn bounded_fixtures() -> [Table<AlignedBytes>; 3] {
        let path = format!(
            "{}/../tables/compat/v5/ur5_hybrid_terms.tbl",
            env!("CARGO_MANIFEST_DIR")
        );
        let file = std::fs::read(path).unwrap();
        let payload = AlignedBytes::copy_from(&file[crate::format::HEADER_LEN..]).unwrap();
        let mut data =
            rkyv::from_bytes::<crate::format::v5::TableData, rkyv::rancor::Error>(&payload)
                .unwrap();
        for range in &mut data.joint_terms.range_rad {
            *range = [-3.0, 3.0];
        }
        let header = *Table::from_vec(&file).unwrap().header();
        let v6 = crate::format::encode_v6(header, &data, false).unwrap();
        let mut v5 = v6.clone();
        v5[10..12].copy_from_slice(&5u16.to_le_bytes());
        crate::testing::seal_header(&mut v5);
        let zero = |v: &mut Vec<[f64; 3]>| v.iter_mut().for_each(|e| *e = [0.0; 3]);
        zero(&mut data.base.errors_mm);
        zero(&mut data.base.orientation_errors_rad);
        zero(&mut data.base.node_errors_mm);
        zero(&mut data.base.node_orientation_errors_rad);
        let model_only = crate::format::encode_v6(header, &data, false).unwrap();
        [v6, v5, model_only].map(|bytes| Table::from_vec(bytes).unwrap())
    }

    /// Beyond the angles its samples span, a version-6 table's residual fades to zero: in
    /// both tiers' queries, at random joint values around each joint's range, its answer is the
    /// model's plus the factor of [`crate::testing::reference_residual_scale`] times the residual the same bytes
    /// give as version 5 (within 1e-12 mm and rad), flagged full within the ranges, faded
    /// in the fade and model-only beyond it; within them it is version 5's to the bit.
    #[test]
    fn beyond_the_joints_its_samples_span_the_residual_fades_to_the_model() {
        let [bounded, unbounded, model_only] = bounded_fixtures();
        let model = bounded.model().unwrap();
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = || crate::testing::uniform(&mut state);
        let mut seen = [0usize; 3];
        for i in 0..6_000 {
            // Mostly within ±3 rad; one joint a few degrees either side of an end.
            let mut q: Vec<f64> = (0..6).map(|_| -2.9 + 5.8 * next()).collect();
            let edge = if next() < 0.5 { -3.0 } else { 3.0 };
            q[i % 6] = edge + (next() - 0.5) * 0.15;
            let target = Target::at(model.nominal().tcp_pose(&q).unwrap().translation_mm);
            let s = crate::testing::reference_residual_scale(&q, &[[-3.0, 3.0]; 6]);
            for exact in [false, true] {
                // The queries a controller calls: the served one takes its own path.
                let query = |t: &Table<AlignedBytes>| match exact {
                    false => t.query_with_joints(&target, &q),
                    true => t.exact().query_with_joints(&target, &q),
                };
                let (b, u, m) = (query(&bounded), query(&unbounded), query(&model_only));
                assert_eq!(b.status, u.status, "{q:?}");
                if u.status != Status::Ok {
                    continue;
                }
                if s == 1.0 {
                    assert_eq!(bits(&b), bits(&u), "{q:?}");
                    seen[0] += 1;
                    continue;
                }
                let expected = |u: &[f64; 3], m: &[f64; 3], k: usize| m[k] + s * (u[k] - m[k]);
                for k in 0..3 {
                    let p = expected(&u.position_error_mm, &m.position_error_mm, k);
                    let r = expected(&u.orientation_error_rad, &m.orientation_error_rad, k);
                    assert!((b.position_error_mm[k] - p).abs() < 1e-12, "{q:?} {s}");
                    assert!((b.orientation_error_rad[k] - r).abs() < 1e-12, "{q:?} {s}");
                }
                let flag = match (s, u.residual) {
                    (0.0, _) => crate::Residual::ModelOnly,
                    (_, crate::Residual::Full) => crate::Residual::Faded,
                    (_, other) => other,
                };
                assert_eq!(b.residual, flag, "{q:?} {s}");
                seen[if s == 0.0 { 2 } else { 1 }] += 1;
            }
        }
        assert!(
            seen.iter().all(|&n| n > 100),
            "within, faded, beyond: {seen:?}"
        );
    }

    /// A hybrid table's served query by joint values (`query_with_joints`: its own steps,
    /// its answer built in place) answers as the general path (`answer`) to the bit,
    /// status and flags included: at random poses whose nominal TCP lies in the grid, near
    /// it (the residual fading) and far from it (the model alone), at targets moved from
    /// the TCP (beyond the joints' tolerance), with a named TCP, an orientation or a
    /// configuration, with joint values in degrees, non-finite or of another count; on
    /// tables of format versions 1 to 6 (with joint-space terms, with a posture term,
    /// which takes the general path) and with a field that turns with the tool, with and
    /// without orientations.
    #[test]
    fn a_hybrid_served_query_answers_as_the_general_path_to_the_bit() {
        let tables = [
            fixture("v1/ur5_hybrid.tbl"),
            fixture("v2/ur5_hybrid.tbl"),
            fixture("v3/ur5_hybrid_posture.tbl"),
            fixture("v4/ur5_hybrid.tbl"),
            fixture("v5/ur5_hybrid_terms.tbl"),
            bounded_fixtures().into_iter().next().unwrap(),
            tool_axis_fixture(false),
            tool_axis_fixture(true),
        ];
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || crate::testing::uniform(&mut state);
        let mut seen = std::collections::BTreeSet::new();
        for table in &tables {
            let model = table.model().unwrap();
            for i in 0..6_000 {
                let mut q: Vec<f64> = (0..6).map(|_| -3.2 + 6.4 * next()).collect();
                let mut target = Target::at(model.nominal().tcp_pose(&q).unwrap().translation_mm);
                match i % 12 {
                    1 => target.position_mm[0] += 60.0 * next() - 30.0,
                    2 => target.config = Some((i % 3) as u8),
                    3 => target.rotation_rad = Some([next(), -next(), 2.0 * next()]),
                    4 => target.tcp_mm = Some([40.0 * next(), -20.0, 150.0 * next()]),
                    5 => target.tcp_mm = Some([0.0, 0.09, 31.0]),
                    6 if i % 48 == 6 => q[3] = f64::NAN,
                    7 if i % 48 == 7 => q.truncate(5),
                    8 => q.iter_mut().for_each(|v| *v = v.to_degrees()),
                    9 if i % 48 == 9 => target.position_mm[2] = f64::INFINITY,
                    _ => {}
                }
                let fast = table.query_with_joints(&target, &q);
                let general = table.answer(&target, Some(&q), Tier::Served);
                assert_eq!(bits(&fast), bits(&general), "{target:?} {q:?}");
                seen.insert((fast.status as u8, fast.residual as u8, fast.evidence.0));
            }
        }
        for (status, residual) in [
            (Status::Ok, crate::Residual::Full),
            (Status::Ok, crate::Residual::Faded),
            (Status::Ok, crate::Residual::ModelOnly),
            (Status::JointsMismatch, crate::Residual::Full),
            (Status::InvalidInput, crate::Residual::Full),
        ] {
            assert!(
                seen.iter()
                    .any(|s| (s.0, s.1) == (status as u8, residual as u8)),
                "{status:?} {residual:?} not met"
            );
        }
        assert!(seen.iter().any(|s| s.2 != 0), "no answer flagged");
    }

    /// A position-only table's served query (`served_strict`, its corners blended
    /// without a test each) answers as the general path to the bit, status and flags
    /// included, at targets in covered and uncovered cells, on cell faces, on the grid's
    /// faces, outside it, and at non-finite positions.
    #[test]
    fn a_position_only_served_query_answers_as_the_general_path_to_the_bit() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../tables/compat/v2/worked_example.tbl"
        );
        let table = Table::from_vec(std::fs::read(path).unwrap()).unwrap();
        assert!(table.model().is_none() && table.has_served_field());
        let grid = *table.grid();
        let (lo, hi) = (grid.origin_mm, grid.max_mm());
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = || crate::testing::uniform(&mut state);
        let mut statuses = std::collections::BTreeSet::new();
        for i in 0..40_000 {
            let mut p = [0, 1, 2].map(|a| lo[a] - 10.0 + next() * (hi[a] - lo[a] + 20.0));
            match i % 8 {
                // On a cell face, and on the grid's faces.
                1 => p[0] = lo[0] + (p[0] - lo[0]).div_euclid(grid.cell_mm) * grid.cell_mm,
                2 => p[1] = hi[1],
                3 => p[2] = lo[2],
                4 if i % 64 == 4 => p[1] = f64::NAN,
                _ => {}
            }
            let target = Target::at(p).with_config((i % 3 == 0).then_some(1));
            let fast = table.query_target(&target);
            let general = served_by_blend_site(&table, &target);
            assert_eq!(bits(&fast), bits(&general), "{target:?}");
            statuses.insert(fast.status as u8);
        }
        for status in [
            Status::Ok,
            Status::OutsideGrid,
            Status::InvalidInput,
            Status::UncoveredCell,
        ] {
            assert!(statuses.contains(&(status as u8)), "{status:?} not met");
        }
    }
}
