//! The C ABI: what `include/adwi.h` declares, for controllers written in C or C++.
//!
//! Conventions, as the header documents them for C callers:
//!
//! - Every function returns an [`AdwiResult`]; outputs are written only when it is
//!   [`AdwiResult::Ok`], so a failed call leaves the caller's variables as they were.
//! - Null pointers are refused with [`AdwiResult::NullPointer`], never dereferenced.
//! - Every export runs inside `catch_unwind`: a panic (none is expected; queries cannot
//!   panic by construction) becomes [`AdwiResult::Panic`] instead of unwinding into C,
//!   which would be undefined behaviour.
//! - Queries and compensations do not allocate, lock or touch thread-local state. Only the
//!   open functions record a detailed message, in a thread-local string that
//!   [`adwi_last_open_error`] copies into a caller buffer.
//! - A handle may be queried from several threads at once; it must not be closed while
//!   another thread uses it.
//! - Every function taking a handle first checks its marker ([`AdwiTable`]) and answers
//!   [`AdwiResult::InvalidHandle`] for a pointer that is not an open handle as far as it
//!   can tell: a handle used after close or closed twice, shortly after the close.

use std::cell::RefCell;
use std::ffi::{c_char, c_int, CStr};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

use crate::chain::MAX_JOINTS;
use crate::residency::{Lock, OpenOptions};
use crate::{AlignedBytes, Compensation, Correction, OpenError, Table, Target};

/// Result codes; the values are part of the ABI.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AdwiResult {
    /// Success; outputs were written.
    Ok = 0,
    /// A required pointer argument was null.
    NullPointer = 1,
    /// An argument is out of range (configuration, tolerance, path not UTF-8).
    InvalidArgument = 2,
    /// The file could not be read or mapped.
    Io = 3,
    /// The bytes are not a valid table: truncated, corrupt, wrong magic or checksum.
    InvalidTable = 4,
    /// The table's format version is not one this runtime reads.
    UnsupportedVersion = 5,
    /// Locking the table in memory was required and failed.
    Lock = 6,
    /// A panic was caught at the boundary (a bug: please report it).
    Panic = 7,
    /// The handle is not an open table: closed already, or never returned by an open
    /// function (as far as its marker tells).
    InvalidHandle = 8,
    /// The memory for a copy of the table could not be allocated
    /// ([`adwi_table_open_bytes`]); the process is not aborted.
    OutOfMemory = 9,
}

/// A table as C sees it: behind the opaque `adwi_table` handle, either mapped from a
/// file or copied into aligned memory.
///
/// `magic` comes first and is [`HANDLE_LIVE`] from open to close, where it is overwritten
/// with [`HANDLE_CLOSED`] before the memory is freed: every function reads it before
/// anything else, so that the usual mistakes (a query after close, a second close) are
/// refused instead of reading a freed table. This is a check of the common case, not a
/// guarantee: freed memory may have been unmapped or reused for another handle since, so
/// using a closed handle remains undefined behaviour.
#[repr(C)]
pub struct AdwiTable {
    magic: u64,
    table: Table<Backing>,
}

/// The marker of an open handle ("adwi:tbl" in memory).
pub const HANDLE_LIVE: u64 = u64::from_le_bytes(*b"adwi:tbl");
/// The marker a handle gets at close, before its memory is freed ("adwi:end").
pub const HANDLE_CLOSED: u64 = u64::from_le_bytes(*b"adwi:end");

/// The table behind `handle`, or the result code refusing it: null, misaligned, or
/// without the marker of an open handle.
///
/// # Safety
///
/// `handle` is null, or points to at least 8 readable bytes (any handle from an open
/// function, closed or not, still does in the common case; see [`AdwiTable`]).
#[inline]
unsafe fn open_table<'a>(handle: *const AdwiTable) -> Result<&'a Table<Backing>, AdwiResult> {
    if handle.is_null() {
        return Err(AdwiResult::NullPointer);
    }
    if handle as usize % std::mem::align_of::<AdwiTable>() != 0 {
        return Err(AdwiResult::InvalidHandle);
    }
    // SAFETY: non-null, aligned and readable by contract; volatile so that the read is
    // made even where the compiler could assume it sees a live handle.
    let magic = unsafe { std::ptr::addr_of!((*handle).magic).read_volatile() };
    if magic != HANDLE_LIVE {
        return Err(AdwiResult::InvalidHandle);
    }
    // SAFETY: the marker is that of an open handle, created by `finish_open` and not yet
    // closed (by the caller's contract); only shared access is taken.
    Ok(unsafe { &(*handle).table })
}

/// The bytes behind a C handle.
enum Backing {
    Mapped(memmap2::Mmap),
    Owned(AlignedBytes),
}

impl AsRef<[u8]> for Backing {
    #[inline]
    fn as_ref(&self) -> &[u8] {
        match self {
            Backing::Mapped(m) => m,
            Backing::Owned(v) => v,
        }
    }
}

/// `adwi_correction`: [`Correction`] with a fixed-width status.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AdwiCorrection {
    /// Predicted position error (actual − nominal), mm, base frame.
    pub position_error_mm: [f64; 3],
    /// Predicted orientation error (rotation vector), rad, base frame.
    pub orientation_error_rad: [f64; 3],
    /// The number of neighbours weighted (exact tier), or of nodes blended (served: 8).
    pub neighbours: u32,
    /// [`crate::Status`] as an integer: 0 ok, 1 outside grid, 2 no admissible neighbour,
    /// 3 invalid input, 4 missing joint angles (a hybrid table queried without them),
    /// 5 numerical failure (a non-finite prediction, withheld), 6 uncovered cell (the
    /// served field is not defined there), 7 joints mismatch (a hybrid table's joint
    /// values, in radians, do not put the tool near the target).
    pub status: i32,
    /// [`crate::Residual`] as an integer: 0 full, 1 faded, 2 model only (a hybrid
    /// table's residual field, wholly, in part or not at all; 0 for a position-only table).
    pub residual: i32,
    /// [`crate::Evidence`] as bits: 0 within the samples' evidence, bit 0 (1) an
    /// orientation the samples never had, bit 1 (2) a TCP the table cannot place, bit 2
    /// (4) a joint beyond the angles its model terms were identified over. Also
    /// the struct's tail, so that it has no padding (every byte written, outputs
    /// comparable with `memcmp`).
    pub evidence: u32,
}

/// `adwi_compensation`: [`Compensation`] with fixed-width fields.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AdwiCompensation {
    /// The position to command, mm, base frame.
    pub command_position_mm: [f64; 3],
    /// The rotation to apply to the target orientation (rotation vector), rad.
    pub command_rotation_rad: [f64; 3],
    /// The correction predicted at the command.
    pub correction: AdwiCorrection,
    /// Iterations used.
    pub iterations: u32,
    /// 1 if the tolerance was reached, else 0.
    pub converged: i32,
    /// `|command + error(command) − target|`, mm.
    pub residual_mm: f64,
}

/// `ADWI_RESIDUAL_FULL`: a hybrid table's whole residual (and every position-only answer).
pub const ADWI_RESIDUAL_FULL: i32 = 0;
/// `ADWI_RESIDUAL_FADED`: part of a hybrid table's residual, fading where it has no value.
pub const ADWI_RESIDUAL_FADED: i32 = 1;
/// `ADWI_RESIDUAL_MODEL_ONLY`: a hybrid table's calibrated model alone.
pub const ADWI_RESIDUAL_MODEL_ONLY: i32 = 2;

/// `ADWI_OPEN_PREFAULT`: fault every page in at open.
pub const ADWI_OPEN_PREFAULT: u32 = 1;
/// `ADWI_OPEN_LOCK`: lock the table in memory, best effort.
pub const ADWI_OPEN_LOCK: u32 = 2;
/// `ADWI_OPEN_LOCK_REQUIRED`: lock the table in memory or fail with `ADWI_LOCK`.
pub const ADWI_OPEN_LOCK_REQUIRED: u32 = 4;
/// Every flag this runtime knows: a bit outside it (a flag of a newer header, or a
/// mistake) is refused with `ADWI_INVALID_ARGUMENT`, not ignored.
const ADWI_OPEN_KNOWN: u32 = ADWI_OPEN_PREFAULT | ADWI_OPEN_LOCK | ADWI_OPEN_LOCK_REQUIRED;

impl From<Correction> for AdwiCorrection {
    #[inline]
    fn from(c: Correction) -> AdwiCorrection {
        // Every query path checks this already; checked again where C takes over.
        let c = c.finite_or_failure();
        AdwiCorrection {
            position_error_mm: c.position_error_mm,
            orientation_error_rad: c.orientation_error_rad,
            neighbours: c.neighbours,
            status: c.status as i32,
            residual: c.residual as i32,
            evidence: u32::from(c.evidence.0),
        }
    }
}

impl From<Compensation> for AdwiCompensation {
    #[inline]
    fn from(c: Compensation) -> AdwiCompensation {
        let c = c.finite_or_failure();
        AdwiCompensation {
            command_position_mm: c.command_position_mm,
            command_rotation_rad: c.command_rotation_rad,
            correction: c.correction.into(),
            iterations: c.iterations,
            converged: c.converged.into(),
            residual_mm: c.residual_mm,
        }
    }
}

thread_local! {
    /// The message of the last failed open on this thread; written only by the open
    /// functions, never by queries.
    static LAST_OPEN_ERROR: RefCell<String> = const { RefCell::new(String::new()) };
}

fn record_open_error(message: String) {
    LAST_OPEN_ERROR.with(|m| *m.borrow_mut() = message);
}

fn code_of(error: &OpenError) -> AdwiResult {
    match error {
        OpenError::Io(_) => AdwiResult::Io,
        OpenError::UnsupportedVersion { .. } => AdwiResult::UnsupportedVersion,
        OpenError::Lock(_) => AdwiResult::Lock,
        OpenError::OutOfMemory { .. } => AdwiResult::OutOfMemory,
        _ => AdwiResult::InvalidTable,
    }
}

/// Runs `f`, turning a panic into [`AdwiResult::Panic`].
#[inline]
fn guarded(f: impl FnOnce() -> AdwiResult) -> AdwiResult {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or(AdwiResult::Panic)
}

/// Finishes an open: stores the handle on success, records the message on failure.
///
/// # Safety
///
/// `out` is non-null and valid for a pointer write.
unsafe fn finish_open(
    result: Result<Table<Backing>, OpenError>,
    out: *mut *mut AdwiTable,
) -> AdwiResult {
    match result {
        Ok(table) => {
            let handle = Box::into_raw(Box::new(AdwiTable {
                magic: HANDLE_LIVE,
                table,
            }));
            // SAFETY: the caller checked `out` is non-null; C guarantees it is writable.
            unsafe { out.write(handle) };
            record_open_error(String::new());
            AdwiResult::Ok
        }
        Err(e) => {
            let code = code_of(&e);
            record_open_error(e.to_string());
            code
        }
    }
}

/// Opens the table file at `path` (NUL-terminated UTF-8) by memory map, validating it,
/// with `flags` a combination of `ADWI_OPEN_*` (0 for none).
///
/// # Safety
///
/// `path` is null or a NUL-terminated string; `out` is null or valid for a pointer write.
/// The file must not be modified or truncated while the table is open (replace tables by
/// renaming a new file into place).
#[no_mangle]
pub unsafe extern "C" fn adwi_table_open_with(
    path: *const c_char,
    flags: u32,
    out: *mut *mut AdwiTable,
) -> AdwiResult {
    guarded(|| {
        if path.is_null() || out.is_null() {
            record_open_error("a null pointer was passed to adwi_table_open".into());
            return AdwiResult::NullPointer;
        }
        // SAFETY: non-null, and NUL-terminated by the caller's contract.
        let path = unsafe { CStr::from_ptr(path) };
        let Ok(path) = path.to_str() else {
            record_open_error("the table path is not valid UTF-8".into());
            return AdwiResult::InvalidArgument;
        };
        if flags & !ADWI_OPEN_KNOWN != 0 {
            record_open_error(format!(
                "unknown open flags {:#x}: this runtime knows ADWI_OPEN_PREFAULT, \
                 ADWI_OPEN_LOCK and ADWI_OPEN_LOCK_REQUIRED ({ADWI_OPEN_KNOWN:#x})",
                flags & !ADWI_OPEN_KNOWN
            ));
            return AdwiResult::InvalidArgument;
        }
        let options = OpenOptions {
            prefault: flags & ADWI_OPEN_PREFAULT != 0,
            lock: if flags & ADWI_OPEN_LOCK_REQUIRED != 0 {
                Lock::Required
            } else if flags & ADWI_OPEN_LOCK != 0 {
                Lock::BestEffort
            } else {
                Lock::No
            },
        };
        // SAFETY: the caller guarantees the file is not modified while open.
        let opened = unsafe { Table::open_with(Path::new(path), options) };
        let result = opened.and_then(|(table, _)| rewrap(table));
        // SAFETY: `out` is non-null; the caller guarantees it is writable.
        unsafe { finish_open(result, out) }
    })
}

/// Moves a validated mapped table behind the C handle's backing type without validating
/// it again: moving an `Mmap` does not move the mapping, and the table checks on every
/// query that its bytes are still the validated ones.
fn rewrap(table: Table<memmap2::Mmap>) -> Result<Table<Backing>, OpenError> {
    Ok(table.map_data(Backing::Mapped))
}

/// [`adwi_table_open_with`] with no flags.
///
/// # Safety
///
/// As [`adwi_table_open_with`].
#[no_mangle]
pub unsafe extern "C" fn adwi_table_open(
    path: *const c_char,
    out: *mut *mut AdwiTable,
) -> AdwiResult {
    // SAFETY: same contract.
    unsafe { adwi_table_open_with(path, 0, out) }
}

/// Copies `len` bytes at `bytes` into aligned memory and validates them as a table.
/// Memory that cannot be allocated is `ADWI_OUT_OF_MEMORY`, a length no buffer can have
/// (more than `isize::MAX`) `ADWI_INVALID_ARGUMENT`: both checked before anything could
/// panic, so that nothing is printed to the host's stderr and nothing aborts it.
///
/// # Safety
///
/// `bytes` is null or valid for reads of `len` bytes; `out` is null or valid for a
/// pointer write.
#[no_mangle]
pub unsafe extern "C" fn adwi_table_open_bytes(
    bytes: *const u8,
    len: usize,
    out: *mut *mut AdwiTable,
) -> AdwiResult {
    guarded(|| {
        if bytes.is_null() || out.is_null() {
            record_open_error("a null pointer was passed to adwi_table_open_bytes".into());
            return AdwiResult::NullPointer;
        }
        if isize::try_from(len).is_err() {
            record_open_error(format!(
                "a buffer of {len} bytes cannot exist: more than isize::MAX bytes"
            ));
            return AdwiResult::InvalidArgument;
        }
        // SAFETY: non-null and valid for `len` bytes by the caller's contract, and `len`
        // is at most `isize::MAX`.
        let slice = unsafe { std::slice::from_raw_parts(bytes, len) };
        let result = AlignedBytes::copy_from(slice)
            .and_then(|aligned| Table::from_bytes(Backing::Owned(aligned)));
        // SAFETY: `out` is non-null; the caller guarantees it is writable.
        unsafe { finish_open(result, out) }
    })
}

/// Converts a C configuration (-1 unknown, 0..=254 known) to a [`Target`] configuration.
#[inline]
fn config_of(config: i32) -> Option<Option<u8>> {
    match config {
        -1 => Some(None),
        0..=254 => Some(Some(config as u8)),
        _ => None,
    }
}

/// Reads a C `double[3]`.
///
/// # Safety
///
/// `p` is non-null and valid for reads of three doubles.
#[inline]
unsafe fn read3(p: *const f64) -> [f64; 3] {
    // SAFETY: as the function's contract; `read_unaligned` tolerates any alignment.
    unsafe {
        [
            p.read_unaligned(),
            p.add(1).read_unaligned(),
            p.add(2).read_unaligned(),
        ]
    }
}

/// Which tier a C call asks.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Tier {
    Served,
    Exact,
}

/// The shared body of the query exports: checks the pointers and arguments, reads the
/// target (and `n_joints` joint values when given), answers from `tier`.
///
/// # Safety
///
/// As [`adwi_table_query_joints`].
unsafe fn query_c(
    table: *const AdwiTable,
    target_mm: *const f64,
    config: i32,
    joints: Option<(*const f64, usize)>,
    out: *mut AdwiCorrection,
    tier: Tier,
) -> AdwiResult {
    // SAFETY: the caller upholds this function's contract, which is `query_pose_c`'s with
    // no rotation and no TCP.
    unsafe {
        query_pose_c(
            table,
            target_mm,
            std::ptr::null(),
            std::ptr::null(),
            config,
            joints,
            out,
            tier,
        )
    }
}

/// The shared body of the query exports, with the target's optional orientation and TCP.
///
/// # Safety
///
/// As [`adwi_table_query_pose`]; `joints` is `None` or a pointer (null or valid for its
/// count of doubles) and a count.
#[allow(clippy::too_many_arguments)]
unsafe fn query_pose_c(
    table: *const AdwiTable,
    target_mm: *const f64,
    rotation_rad: *const f64,
    tcp_mm: *const f64,
    config: i32,
    joints: Option<(*const f64, usize)>,
    out: *mut AdwiCorrection,
    tier: Tier,
) -> AdwiResult {
    guarded(|| {
        let joints_null = joints.is_some_and(|(p, _)| p.is_null());
        if table.is_null() || target_mm.is_null() || joints_null || out.is_null() {
            return AdwiResult::NullPointer;
        }
        // SAFETY: a handle from an open function by contract.
        let table = match unsafe { open_table(table) } {
            Ok(table) => table,
            Err(code) => return code,
        };
        let Some(config) = config_of(config) else {
            return AdwiResult::InvalidArgument;
        };
        // SAFETY: non-null, valid for three doubles by contract.
        let position_mm = unsafe { read3(target_mm) };
        let mut target = Target::at(position_mm).with_config(config);
        if !rotation_rad.is_null() {
            // SAFETY: non-null, valid for three doubles by contract.
            target = target.with_rotation(unsafe { read3(rotation_rad) });
        }
        if !tcp_mm.is_null() {
            // SAFETY: non-null, valid for three doubles by contract.
            target = target.with_tcp(unsafe { read3(tcp_mm) });
        }
        let c = match joints {
            None => match tier {
                Tier::Served => table.query_target(&target),
                Tier::Exact => table.exact().query_target(&target),
            },
            Some((p, n)) => {
                if n > MAX_JOINTS || table.joint_count().is_some_and(|count| count != n) {
                    return AdwiResult::InvalidArgument;
                }
                let mut q = [0.0; MAX_JOINTS];
                for (i, value) in q.iter_mut().enumerate().take(n) {
                    // SAFETY: non-null, valid for `n` doubles by contract.
                    *value = unsafe { p.add(i).read_unaligned() };
                }
                match tier {
                    Tier::Served => table.query_with_joints(&target, &q[..n]),
                    Tier::Exact => table.exact().query_with_joints(&target, &q[..n]),
                }
            }
        };
        // SAFETY: non-null, writable by contract.
        unsafe { out.write(c.into()) };
        AdwiResult::Ok
    })
}

/// The served correction (the continuous field) at `target_mm` (x, y, z, mm, base frame)
/// for configuration `config` (-1 unknown). Returns `ADWI_OK` whenever the table answered;
/// `out->status` then says whether the correction holds. Does not allocate.
///
/// # Safety
///
/// `table` is null or a live handle from an open function; `target_mm` is null or valid
/// for three doubles; `out` is null or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn adwi_table_query(
    table: *const AdwiTable,
    target_mm: *const f64,
    config: i32,
    out: *mut AdwiCorrection,
) -> AdwiResult {
    // SAFETY: the caller upholds this function's contract, which is `query_c`'s.
    unsafe { query_c(table, target_mm, config, None, out, Tier::Served) }
}

/// As [`adwi_table_query`], from the exact tier: the paper's method to the digit.
///
/// # Safety
///
/// As [`adwi_table_query`].
#[no_mangle]
pub unsafe extern "C" fn adwi_table_query_exact(
    table: *const AdwiTable,
    target_mm: *const f64,
    config: i32,
    out: *mut AdwiCorrection,
) -> AdwiResult {
    // SAFETY: the caller upholds this function's contract, which is `query_c`'s.
    unsafe { query_c(table, target_mm, config, None, out, Tier::Exact) }
}

/// The served correction at `target_mm` for configuration `config` (-1 unknown), reached
/// with the `n_joints` joint values at `joints_rad` (rad, mm for prismatic joints): the
/// only query a hybrid table answers, and the one that applies a table's joint-space
/// screen ([`Table::query_with_joints`]). `n_joints` must be the table's joint count
/// ([`adwi_table_joint_count`]) when it has one, else `ADWI_INVALID_ARGUMENT`. Returns
/// `ADWI_OK` whenever the table answered; `out->status` then says whether the correction
/// holds. Does not allocate.
///
/// # Safety
///
/// As [`adwi_table_query`]; `joints_rad` is null or valid for `n_joints` doubles.
#[no_mangle]
pub unsafe extern "C" fn adwi_table_query_joints(
    table: *const AdwiTable,
    target_mm: *const f64,
    config: i32,
    joints_rad: *const f64,
    n_joints: usize,
    out: *mut AdwiCorrection,
) -> AdwiResult {
    // SAFETY: the caller upholds this function's contract, which is `query_c`'s.
    unsafe {
        query_c(
            table,
            target_mm,
            config,
            Some((joints_rad, n_joints)),
            out,
            Tier::Served,
        )
    }
}

/// The served correction at a pose: `target_mm` (x, y, z, mm, base frame) is the position
/// of the TCP at `tcp_mm` (x, y, z, mm, flange frame; null: the table's own measured
/// point), with the tool's orientation `rotation_rad` (rotation vector, rad, base frame;
/// null: not known), for configuration `config` (-1 unknown), reached with the `n_joints`
/// joint values at `joints_rad` (null with `n_joints` 0 for a position-only table). A
/// hybrid table answers the error at the TCP, its answer's rotation (the model's and the
/// residual's) turning the lever from its point (where its samples measured orientation;
/// else unturned, and flagged); `out->evidence` says where the answer lies beyond what the samples cover
/// ([`crate::Table::answer`]). Returns `ADWI_OK` whenever the table answered; `out->status`
/// then says whether the correction holds. Does not allocate.
///
/// # Safety
///
/// As [`adwi_table_query`]; `rotation_rad` and `tcp_mm` are null or valid for three
/// doubles; `joints_rad` is null or valid for `n_joints` doubles.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn adwi_table_query_pose(
    table: *const AdwiTable,
    target_mm: *const f64,
    rotation_rad: *const f64,
    tcp_mm: *const f64,
    config: i32,
    joints_rad: *const f64,
    n_joints: usize,
    out: *mut AdwiCorrection,
) -> AdwiResult {
    let joints = (!joints_rad.is_null()).then_some((joints_rad, n_joints));
    if joints.is_none() && n_joints != 0 {
        return AdwiResult::NullPointer;
    }
    // SAFETY: the caller upholds this function's contract, which is `query_pose_c`'s.
    unsafe {
        query_pose_c(
            table,
            target_mm,
            rotation_rad,
            tcp_mm,
            config,
            joints,
            out,
            Tier::Served,
        )
    }
}

/// As [`adwi_table_query_joints`], from the exact tier.
///
/// # Safety
///
/// As [`adwi_table_query_joints`].
#[no_mangle]
pub unsafe extern "C" fn adwi_table_query_joints_exact(
    table: *const AdwiTable,
    target_mm: *const f64,
    config: i32,
    joints_rad: *const f64,
    n_joints: usize,
    out: *mut AdwiCorrection,
) -> AdwiResult {
    // SAFETY: the caller upholds this function's contract, which is `query_c`'s.
    unsafe {
        query_c(
            table,
            target_mm,
            config,
            Some((joints_rad, n_joints)),
            out,
            Tier::Exact,
        )
    }
}

/// The shared body of the compensation exports.
///
/// # Safety
///
/// As [`adwi_table_compensate`].
unsafe fn compensate_c(
    table: *const AdwiTable,
    target_mm: *const f64,
    config: i32,
    tolerance_mm: f64,
    max_iterations: u32,
    out: *mut AdwiCompensation,
    tier: Tier,
) -> AdwiResult {
    guarded(|| {
        if table.is_null() || target_mm.is_null() || out.is_null() {
            return AdwiResult::NullPointer;
        }
        // SAFETY: a handle from an open function by contract.
        let table = match unsafe { open_table(table) } {
            Ok(table) => table,
            Err(code) => return code,
        };
        let Some(config) = config_of(config) else {
            return AdwiResult::InvalidArgument;
        };
        if !(tolerance_mm.is_finite() && tolerance_mm >= 0.0) || max_iterations == 0 {
            return AdwiResult::InvalidArgument;
        }
        // SAFETY: non-null, valid for three doubles by contract.
        let position_mm = unsafe { read3(target_mm) };
        // No command exists for a target that is not a point: refused, rather than
        // answered with the target itself (a NaN) as the command.
        if !position_mm.iter().all(|v| v.is_finite()) {
            return AdwiResult::InvalidArgument;
        }
        let target = Target::at(position_mm).with_config(config);
        let c = match tier {
            Tier::Served => table.compensate(&target, tolerance_mm, max_iterations),
            Tier::Exact => table
                .exact()
                .compensate(&target, tolerance_mm, max_iterations),
        };
        // SAFETY: non-null, writable by contract.
        unsafe { out.write(c.into()) };
        AdwiResult::Ok
    })
}

/// The command that lands the robot on `target_mm` by the served field: iterates until
/// `|command + error(command) − target| <= tolerance_mm` or `max_iterations` queries.
/// Returns `ADWI_OK` whenever the table answered; `out->converged` and
/// `out->correction.status` say how well; the command is always finite then. A target
/// that is not finite, a negative or non-finite tolerance and `max_iterations` 0 are
/// `ADWI_INVALID_ARGUMENT`. Does not allocate.
///
/// # Safety
///
/// As [`adwi_table_query`].
#[no_mangle]
pub unsafe extern "C" fn adwi_table_compensate(
    table: *const AdwiTable,
    target_mm: *const f64,
    config: i32,
    tolerance_mm: f64,
    max_iterations: u32,
    out: *mut AdwiCompensation,
) -> AdwiResult {
    // SAFETY: the caller upholds this function's contract, which is `compensate_c`'s.
    unsafe {
        compensate_c(
            table,
            target_mm,
            config,
            tolerance_mm,
            max_iterations,
            out,
            Tier::Served,
        )
    }
}

/// As [`adwi_table_compensate`], by the exact field.
///
/// # Safety
///
/// As [`adwi_table_query`].
#[no_mangle]
pub unsafe extern "C" fn adwi_table_compensate_exact(
    table: *const AdwiTable,
    target_mm: *const f64,
    config: i32,
    tolerance_mm: f64,
    max_iterations: u32,
    out: *mut AdwiCompensation,
) -> AdwiResult {
    // SAFETY: the caller upholds this function's contract, which is `compensate_c`'s.
    unsafe {
        compensate_c(
            table,
            target_mm,
            config,
            tolerance_mm,
            max_iterations,
            out,
            Tier::Exact,
        )
    }
}

/// The number of joint values [`adwi_table_query_joints`] takes, written to `out`: the
/// robot's joint count for a table with joint values or a model, 0 for one whose answers
/// do not depend on joints.
///
/// # Safety
///
/// `table` is null or a live handle; `out` is null or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn adwi_table_joint_count(
    table: *const AdwiTable,
    out: *mut u32,
) -> AdwiResult {
    guarded(|| {
        if table.is_null() || out.is_null() {
            return AdwiResult::NullPointer;
        }
        // SAFETY: a handle from an open function by contract.
        let n = match unsafe { open_table(table) } {
            Ok(table) => table.joint_count().unwrap_or(0),
            Err(code) => return code,
        };
        // SAFETY: non-null, writable by contract.
        unsafe { out.write(n as u32) };
        AdwiResult::Ok
    })
}

/// The number of samples in the table, written to `out`.
///
/// # Safety
///
/// `table` is null or a live handle; `out` is null or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn adwi_table_sample_count(
    table: *const AdwiTable,
    out: *mut u32,
) -> AdwiResult {
    guarded(|| {
        if table.is_null() || out.is_null() {
            return AdwiResult::NullPointer;
        }
        // SAFETY: a handle from an open function by contract.
        let n = match unsafe { open_table(table) } {
            Ok(table) => table.sample_count(),
            Err(code) => return code,
        };
        // SAFETY: non-null, writable by contract.
        unsafe { out.write(n as u32) };
        AdwiResult::Ok
    })
}

/// Closes a handle, unmapping or freeing its table. Null is accepted and ignored
/// (`ADWI_OK`); a handle without the marker of an open one (closed already, say) is
/// refused with `ADWI_INVALID_HANDLE` and nothing is freed.
///
/// # Safety
///
/// `table` is null or a handle from an open function, not in use by another thread. A
/// handle closed already is caught in the common case only ([`AdwiTable`]).
#[no_mangle]
pub unsafe extern "C" fn adwi_table_close(table: *mut AdwiTable) -> AdwiResult {
    guarded(|| {
        if table.is_null() {
            return AdwiResult::Ok;
        }
        // SAFETY: a handle from an open function by contract.
        if let Err(code) = unsafe { open_table(table) } {
            return code;
        }
        // SAFETY: an open handle from `Box::into_raw`, so writable and freed only here.
        // The marker is overwritten first, volatile so that the store is not dropped as
        // dead before the free.
        unsafe {
            std::ptr::addr_of_mut!((*table).magic).write_volatile(HANDLE_CLOSED);
            drop(Box::from_raw(table));
        }
        AdwiResult::Ok
    })
}

/// A static, NUL-terminated name for a result code ("ok", "null pointer", ...); never
/// null, "unknown result" for values outside the enum.
#[no_mangle]
pub extern "C" fn adwi_result_name(code: c_int) -> *const c_char {
    let name: &'static CStr = match code {
        0 => c"ok",
        1 => c"null pointer",
        2 => c"invalid argument",
        3 => c"cannot read the table",
        4 => c"invalid table",
        5 => c"unsupported table format version",
        6 => c"cannot lock the table in memory",
        7 => c"internal panic",
        8 => c"invalid handle",
        9 => c"out of memory",
        _ => c"unknown result",
    };
    name.as_ptr()
}

/// Copies the message of this thread's last failed open into `buf` (at most `len` bytes
/// including the terminating NUL, truncated if needed) and returns the message's full
/// length without the NUL, so a caller can size a buffer by passing `len = 0`. The message
/// is empty after a successful open.
///
/// # Safety
///
/// `buf` is null (only with `len == 0`) or valid for writes of `len` bytes.
#[no_mangle]
pub unsafe extern "C" fn adwi_last_open_error(buf: *mut c_char, len: usize) -> usize {
    catch_unwind(|| {
        LAST_OPEN_ERROR.with(|m| {
            let m = m.borrow();
            let bytes = m.as_bytes();
            if !buf.is_null() && len > 0 {
                let n = bytes.len().min(len - 1);
                // SAFETY: `buf` is valid for `len` bytes and `n + 1 <= len`; the regions
                // cannot overlap (the message is owned by this library).
                unsafe {
                    std::ptr::copy_nonoverlapping(bytes.as_ptr(), buf.cast::<u8>(), n);
                    buf.add(n).write(0);
                }
            }
            bytes.len()
        })
    })
    .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use std::mem::{align_of, offset_of, size_of};

    use super::*;

    /// The layout `include/adwi.h` declares, as `tests/c/smoke.c` asserts it on the C side
    /// (`_Static_assert`): the same numbers, so that either side drifting fails a test.
    #[test]
    fn layout_and_values_match_the_c_header() {
        assert_eq!(size_of::<AdwiResult>(), 4);
        assert_eq!(size_of::<AdwiCorrection>(), 64);
        assert_eq!(align_of::<AdwiCorrection>(), 8);
        assert_eq!(offset_of!(AdwiCorrection, position_error_mm), 0);
        assert_eq!(offset_of!(AdwiCorrection, orientation_error_rad), 24);
        assert_eq!(offset_of!(AdwiCorrection, neighbours), 48);
        assert_eq!(offset_of!(AdwiCorrection, status), 52);
        assert_eq!(offset_of!(AdwiCorrection, residual), 56);
        assert_eq!(offset_of!(AdwiCorrection, evidence), 60);
        assert_eq!(size_of::<AdwiCompensation>(), 128);
        assert_eq!(align_of::<AdwiCompensation>(), 8);
        assert_eq!(offset_of!(AdwiCompensation, command_position_mm), 0);
        assert_eq!(offset_of!(AdwiCompensation, command_rotation_rad), 24);
        assert_eq!(offset_of!(AdwiCompensation, correction), 48);
        assert_eq!(offset_of!(AdwiCompensation, iterations), 112);
        assert_eq!(offset_of!(AdwiCompensation, converged), 116);
        assert_eq!(offset_of!(AdwiCompensation, residual_mm), 120);
        assert_eq!(offset_of!(AdwiTable, magic), 0);
        let results = [
            (AdwiResult::Ok, 0),
            (AdwiResult::NullPointer, 1),
            (AdwiResult::InvalidArgument, 2),
            (AdwiResult::Io, 3),
            (AdwiResult::InvalidTable, 4),
            (AdwiResult::UnsupportedVersion, 5),
            (AdwiResult::Lock, 6),
            (AdwiResult::Panic, 7),
            (AdwiResult::InvalidHandle, 8),
            (AdwiResult::OutOfMemory, 9),
        ];
        for (result, value) in results {
            assert_eq!(result as i32, value);
        }
        let statuses = [
            (crate::Status::Ok, 0),
            (crate::Status::OutsideGrid, 1),
            (crate::Status::NoAdmissibleNeighbour, 2),
            (crate::Status::InvalidInput, 3),
            (crate::Status::MissingJoints, 4),
            (crate::Status::NumericalFailure, 5),
            (crate::Status::UncoveredCell, 6),
            (crate::Status::JointsMismatch, 7),
        ];
        for (status, value) in statuses {
            assert_eq!(status as i32, value);
        }
        let residuals = [
            (crate::Residual::Full, ADWI_RESIDUAL_FULL),
            (crate::Residual::Faded, ADWI_RESIDUAL_FADED),
            (crate::Residual::ModelOnly, ADWI_RESIDUAL_MODEL_ONLY),
        ];
        for (residual, value) in residuals {
            assert_eq!(residual as i32, value);
        }
        assert_eq!(
            (ADWI_OPEN_PREFAULT, ADWI_OPEN_LOCK, ADWI_OPEN_LOCK_REQUIRED),
            (1, 2, 4)
        );
    }

    #[test]
    fn handles_without_the_open_marker_are_refused_untouched() {
        let bytes = include_bytes!("../../tables/compat/v1/worked_example.tbl");
        let mut handle = std::ptr::null_mut();
        // SAFETY: valid bytes and output.
        let code = unsafe { adwi_table_open_bytes(bytes.as_ptr(), bytes.len(), &mut handle) };
        assert_eq!(code, AdwiResult::Ok);
        let target = [2000.0, 700.0, 1000.0];
        let joints = [0.0; 6];
        let mut count = 0u32;
        // SAFETY: an open handle and valid pointers.
        assert_eq!(
            unsafe { adwi_table_sample_count(handle, &mut count) },
            AdwiResult::Ok
        );
        assert_eq!(count, 8);
        // Readable, aligned memory that never was a handle: zeros, the closed marker, and
        // a misaligned pointer into it.
        let mut zeroed = [0u64; 64];
        let mut closed = [0u64; 64];
        closed[0] = HANDLE_CLOSED;
        let misaligned = zeroed
            .as_mut_ptr()
            .cast::<u8>()
            .wrapping_add(1)
            .cast::<AdwiTable>();
        for bogus in [
            zeroed.as_mut_ptr().cast::<AdwiTable>(),
            closed.as_mut_ptr().cast::<AdwiTable>(),
            misaligned,
        ] {
            let mut c = AdwiCorrection {
                neighbours: 77,
                ..AdwiCorrection::default()
            };
            let mut k = AdwiCompensation::default();
            let mut n = 5u32;
            // SAFETY: readable memory; the functions refuse it before reading more than
            // the marker.
            let codes = unsafe {
                [
                    adwi_table_query(bogus, target.as_ptr(), -1, &mut c),
                    adwi_table_query_joints(bogus, target.as_ptr(), -1, joints.as_ptr(), 6, &mut c),
                    adwi_table_compensate(bogus, target.as_ptr(), -1, 1e-6, 10, &mut k),
                    adwi_table_sample_count(bogus, &mut n),
                    adwi_table_close(bogus),
                ]
            };
            assert_eq!(codes, [AdwiResult::InvalidHandle; 5]);
            assert_eq!((c.neighbours, n, k), (77, 5, AdwiCompensation::default()));
        }
        assert_eq!(zeroed, [0; 64]);
        // SAFETY: an open handle, closed once; null is accepted.
        unsafe {
            assert_eq!(adwi_table_close(handle), AdwiResult::Ok);
            assert_eq!(adwi_table_close(std::ptr::null_mut()), AdwiResult::Ok);
        }
    }
}
