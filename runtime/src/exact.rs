//! The exact tier: the paper's method to the digit, over the candidate list of the
//! target's cell ([`crate::method`] does the selection and the weighing; this module only
//! reads a table's data for it).
//!
//! Both payload versions answer it, through one accessor trait ([`ExactSource`]), so that
//! one selection and one weighing serve a version-1 table (candidate lists shared between
//! cells behind 8-byte records) and a version-2 table (each cell's candidates inside its
//! own 64-byte record). Nothing here allocates or panics: indices were validated at open,
//! and every access is checked anyway.

use rkyv::Archived;

use crate::chain::MAX_JOINTS;
use crate::correction::{Correction, Status};
use crate::format::{v1, v2, Header, CONTENT_ORIENTATION};
use crate::method::{self, Prediction, SampleError, Selection, CONFIG_UNKNOWN};
use crate::Target;

/// What the exact tier reads of a table, whichever version holds it.
pub(crate) trait ExactSource {
    /// The candidate list of `cell`, or `None` when out of range.
    fn candidates(&self, cell: usize) -> Option<Candidates<'_>>;
    /// Sample `i`'s actual position, mm.
    fn actual(&self, i: u32) -> Option<[f64; 3]>;
    /// Sample `i`'s configuration ([`CONFIG_UNKNOWN`] when out of range).
    fn config(&self, i: u32) -> u8;
    /// Sample `i`'s `|actual|`, mm.
    fn norm(&self, i: u32) -> f64;
    /// Sample `i`'s errors.
    fn error(&self, i: u32) -> SampleError;
    /// Whether sample `i`'s joint values are all within `radius_rad` of `target_rad`.
    fn joints_within(&self, i: u32, target_rad: &[f64], radius_rad: f64) -> bool;
}

/// A candidate list: sample indices as stored.
pub(crate) enum Candidates<'a> {
    /// Narrow indices, inline in a version-2 cell record.
    Narrow(std::slice::Iter<'a, Archived<u16>>),
    /// Wide indices: a version-1 list, a version-2 long list or wide record.
    Wide(std::slice::Iter<'a, Archived<u32>>),
}

impl Iterator for Candidates<'_> {
    type Item = u32;

    #[inline]
    fn next(&mut self) -> Option<u32> {
        match self {
            Candidates::Narrow(i) => i.next().map(|v| u32::from(v.to_native())),
            Candidates::Wide(i) => i.next().map(|v| v.to_native()),
        }
    }
}

/// The candidate list of the cell holding `position_mm`.
#[inline]
fn candidates_at<'a>(
    source: &'a impl ExactSource,
    header: &Header,
    position_mm: [f64; 3],
) -> Result<Candidates<'a>, Status> {
    let cell = header
        .grid
        .cell_of(position_mm)
        .ok_or(Status::OutsideGrid)?;
    source.candidates(cell).ok_or(Status::NoAdmissibleNeighbour)
}

/// Asks the processor to bring the candidate record of the cell holding `position_mm`
/// (a version-2 table) into its cache without waiting for it: a hybrid query of the exact
/// tier calls this before its model part, whose arithmetic then hides the memory's
/// latency (the records of a fine grid are megabytes, read at random). Reads nothing and
/// changes no answer; a hint only, and none on other architectures than x86-64.
#[inline]
pub(crate) fn prefetch(data: &v2::ArchivedTableData, header: &Header, position_mm: [f64; 3]) {
    let Some(cell) = header.grid.cell_of(position_mm) else {
        return;
    };
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let at = |first: *const i8, len: usize| {
            // SAFETY: a prefetch is a hint that reads nothing architecturally and never
            // faults, whatever the address; these bytes are the record's anyway. SSE, which
            // the instruction needs, is part of x86-64.
            unsafe {
                _mm_prefetch::<_MM_HINT_T0>(first);
                _mm_prefetch::<_MM_HINT_T0>(first.wrapping_add(len.saturating_sub(1)));
            }
        };
        if let Some(record) = data.cells.get(cell) {
            at(record.as_ptr().cast(), std::mem::size_of_val(record));
        } else if let Some(record) = data.cells_wide.get(cell) {
            at(record.as_ptr().cast(), std::mem::size_of_val(record));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (data, cell);
}

/// The `k` nearest admissible samples for `target` among `candidates`, with the
/// joint-space screen when the table has one and `joints_rad` is given. Returned by value
/// and not inside a `Result`, so that it is built in place rather than copied.
#[inline]
fn select_among(
    source: &impl ExactSource,
    header: &Header,
    target: &Target,
    joints_rad: Option<&[f64]>,
    candidates: Candidates<'_>,
) -> Selection {
    let radius_rad = header.joint_radius_rad;
    let screen = joints_rad.filter(|_| radius_rad > 0.0);
    let target_config = target.config;
    // Asked only of a candidate within ε that would enter the selection: the
    // configuration, then the joint screen.
    let admissible = |i: u32| {
        target_config.is_none_or(|_| method::config_matches(source.config(i), target_config))
            && screen.is_none_or(|q| source.joints_within(i, q, radius_rad))
    };
    let (params, target_mm) = (&header.method, target.position_mm);
    let actual = |i: u32| source.actual(i);
    // One loop for each width of index, and one without screens beyond the distance (a
    // target without configuration on a table without joint screen: the usual query), so
    // that a candidate's step tests neither.
    macro_rules! each_width {
        ($admissible:expr) => {
            match candidates {
                Candidates::Narrow(list) => method::select_nearest(
                    params,
                    target_mm,
                    list.map(|v| u32::from(v.to_native())),
                    actual,
                    $admissible,
                ),
                Candidates::Wide(list) => method::select_nearest(
                    params,
                    target_mm,
                    list.map(|v| v.to_native()),
                    actual,
                    $admissible,
                ),
            }
        };
    }
    if target_config.is_none() && screen.is_none() {
        each_width!(|_| true)
    } else {
        each_width!(admissible)
    }
}

/// The `k` nearest admissible samples for `target` in its cell ([`select_among`]).
#[inline]
pub(crate) fn select(
    source: &impl ExactSource,
    header: &Header,
    target: &Target,
    joints_rad: Option<&[f64]>,
) -> Result<Selection, Status> {
    let candidates = candidates_at(source, header, target.position_mm)?;
    Ok(select_among(source, header, target, joints_rad, candidates))
}

/// The exact prediction at `target`: the method over its cell's candidates.
#[inline]
pub(crate) fn interpolate(
    source: &impl ExactSource,
    header: &Header,
    target: &Target,
    joints_rad: Option<&[f64]>,
) -> Correction {
    let candidates = match candidates_at(source, header, target.position_mm) {
        Ok(c) => c,
        Err(status) => return Correction::failed(status),
    };
    let selection = select_among(source, header, target, joints_rad, candidates);
    let sample = |i: u32| {
        let actual = source.actual(i).unwrap_or([0.0; 3]);
        (actual, source.norm(i), source.error(i))
    };
    let orientation = header.content_flags & CONTENT_ORIENTATION != 0;
    match method::estimate(
        &header.method,
        target.position_mm,
        &selection,
        orientation,
        sample,
    ) {
        Some(e) => Correction {
            position_error_mm: e.position_error_mm,
            orientation_error_rad: e.orientation_error_rad,
            neighbours: e.neighbours,
            status: Status::Ok,
            residual: crate::Residual::Full,
            evidence: crate::Evidence::WITHIN,
        },
        None => Correction::failed(Status::NoAdmissibleNeighbour),
    }
}

/// The exact prediction with its neighbours, degrees and weights.
pub(crate) fn explain(
    source: &impl ExactSource,
    header: &Header,
    target: &Target,
    joints_rad: Option<&[f64]>,
) -> Result<Prediction, Status> {
    let selection = select(source, header, target, joints_rad)?;
    let actual = |i: u32| source.actual(i).unwrap_or([0.0; 3]);
    let neighbours = method::neighbours(target.position_mm, &selection, actual);
    method::predict(&header.method, neighbours.as_slice(), |i| source.error(i))
        .ok_or(Status::NoAdmissibleNeighbour)
}

/// A version-1 table's data.
pub(crate) struct V1<'a>(pub &'a v1::ArchivedTableData);

impl ExactSource for V1<'_> {
    #[inline]
    fn candidates(&self, cell: usize) -> Option<Candidates<'_>> {
        let c = self.0.cells.get(cell)?;
        let start = c.list_start.to_native() as usize;
        let end = start.checked_add(c.list_len.to_native() as usize)?;
        Some(Candidates::Wide(
            self.0.list_samples.get(start..end)?.iter(),
        ))
    }

    #[inline]
    fn actual(&self, i: u32) -> Option<[f64; 3]> {
        let s = self.0.samples.get(i as usize)?;
        let a = &s.actual_mm;
        Some([a[0].to_native(), a[1].to_native(), a[2].to_native()])
    }

    #[inline]
    fn config(&self, i: u32) -> u8 {
        self.0
            .samples
            .get(i as usize)
            .map_or(CONFIG_UNKNOWN, |s| s.config)
    }

    #[inline]
    fn norm(&self, i: u32) -> f64 {
        self.0
            .actual_norms_mm
            .get(i as usize)
            .map_or(0.0, |n| n.to_native())
    }

    #[inline]
    fn error(&self, i: u32) -> SampleError {
        match self.0.samples.get(i as usize) {
            Some(s) => SampleError {
                position_mm: s.error_mm.map(|v| v.to_native()),
                orientation_rad: s.rotation_error_rad.map(|v| v.to_native()),
            },
            None => SampleError::default(),
        }
    }

    #[inline]
    fn joints_within(&self, i: u32, target_rad: &[f64], radius_rad: f64) -> bool {
        self.0.joints_rad.get(i as usize).is_some_and(|q| {
            let q = q.map(|v| v.to_native());
            method::joints_within(&q, target_rad, radius_rad)
        })
    }
}

/// A version-2 table's data, with the header's joint count and whether it holds
/// orientation errors.
pub(crate) struct V2<'a> {
    pub data: &'a v2::ArchivedTableData,
    pub joint_count: usize,
    pub orientation: bool,
}

impl<'a> V2<'a> {
    /// The version-2 data of a table with `header`.
    pub fn new(data: &'a v2::ArchivedTableData, header: &Header) -> V2<'a> {
        V2 {
            data,
            joint_count: header.joint_count as usize,
            orientation: header.content_flags & CONTENT_ORIENTATION != 0,
        }
    }
}

impl ExactSource for V2<'_> {
    #[inline]
    fn candidates(&self, cell: usize) -> Option<Candidates<'_>> {
        let d = self.data;
        if let Some(record) = d.cells.get(cell) {
            let count = record[0].to_native() as usize;
            if count <= v2::INLINE_CANDIDATES {
                return Some(Candidates::Narrow(record.get(1..=count)?.iter()));
            }
            let start = record[1].to_native() as usize | (record[2].to_native() as usize) << 16;
            return Some(Candidates::Wide(
                d.overflow.get(start..start.checked_add(count)?)?.iter(),
            ));
        }
        let record = d.cells_wide.get(cell)?;
        let count = record[0].to_native() as usize;
        if count <= v2::INLINE_CANDIDATES_WIDE {
            return Some(Candidates::Wide(record.get(1..=count)?.iter()));
        }
        let start = record[1].to_native() as usize;
        Some(Candidates::Wide(
            d.overflow.get(start..start.checked_add(count)?)?.iter(),
        ))
    }

    #[inline]
    fn actual(&self, i: u32) -> Option<[f64; 3]> {
        let s = self.data.samples.get(i as usize)?;
        let a = &s.actual_mm;
        Some([a[0].to_native(), a[1].to_native(), a[2].to_native()])
    }

    #[inline]
    fn config(&self, i: u32) -> u8 {
        self.data
            .configs
            .get(i as usize)
            .copied()
            .unwrap_or(CONFIG_UNKNOWN)
    }

    #[inline]
    fn norm(&self, i: u32) -> f64 {
        self.data
            .samples
            .get(i as usize)
            .map_or(0.0, |s| s.norm_mm.to_native())
    }

    #[inline]
    fn error(&self, i: u32) -> SampleError {
        let i = i as usize;
        // Element by element: an array `map` here compiled to copies through the stack
        // whose reloads waited on the stores before them, a stall every neighbour.
        let three = |v: Option<&Archived<[f64; 3]>>| match v {
            Some(v) => [v[0].to_native(), v[1].to_native(), v[2].to_native()],
            None => [0.0; 3],
        };
        SampleError {
            position_mm: three(self.data.errors_mm.get(i)),
            orientation_rad: if self.orientation {
                three(self.data.orientation_errors_rad.get(i))
            } else {
                [0.0; 3]
            },
        }
    }

    #[inline]
    fn joints_within(&self, i: u32, target_rad: &[f64], radius_rad: f64) -> bool {
        let n = self.joint_count.min(MAX_JOINTS);
        let start = i as usize * n;
        let Some(stored) = self.data.joints_rad.get(start..start + n) else {
            return false;
        };
        let mut q = [0.0; MAX_JOINTS];
        for (out, v) in q.iter_mut().zip(stored) {
            *out = v.to_native();
        }
        method::joints_within(&q[..n], target_rad, radius_rad)
    }
}
