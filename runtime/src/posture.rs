//! The posture term of a hybrid table: what the residual owes to the arm's posture rather
//! than to the position alone.
//!
//! A redundant or compliant arm reaches one position in many postures (a 7-axis arm's
//! elbow turns about the shoulder-wrist line), and its error differs between them: joint
//! elasticity under gravity and the gear errors of the joints that move with the elbow
//! change with the posture while the target stays. A field over positions serves the
//! postures' average; the posture term serves what is left, learnt from the samples
//! nearest in *pose* space, position and joint values together:
//!
//! ```text
//! p(x, q) = s(x) · Σ_i w_i r_i / max(Σ_i w_i, W0)
//! w_i     = ψ(|x̄ − x_i| / R) · ψ(|q − q_i| / ℓ_q),    ψ(t) = (1 − t)⁴ (4t + 1) for t < 1, else 0
//! ```
//!
//! - `x` the target, `x̄` its nearest point of the table's grid box (itself inside), `s`
//!   the served field's fade outside the box ([`crate::served`]: `s = 1` inside, down to
//!   0 with zero slope a fade length away), `q` the query's joint values;
//! - `x_i`, `q_i`, `r_i` each sample's nominal position, joint values and residual: its
//!   measured error minus what the table *without the term* answers at its pose (the
//!   calibrated model and the served field), so the term learns only what those cannot;
//! - `ψ` Wendland's C2 function: 1 at the sample, zero with zero slope and curvature at
//!   the support's edge, so no weight jumps however the query moves;
//! - `R` (mm), `ℓ_q` (rad, Euclidean over the joints) the supports, `W0` the floor: where
//!   the evidence is thin (`Σ w_i < W0`) the term shrinks toward zero in proportion, and
//!   with no sample in reach it is zero.
//!
//! # Guarantees
//!
//! - **Continuity.** Every weight is a continuous function of `(x, q)` and the denominator
//!   is at least `W0 > 0`, so the term is continuous in both, along any joint path. A query
//!   reads only the list of the posture cell holding `x̄`; the compiler lists there every
//!   sample whose spatial support reaches the cell's box, so a sample missing from a list
//!   weighs zero anywhere in the cell and the lists change nothing but the work.
//! - **Bounded work, no allocation.** A list holds at most
//!   [`MAX_POSTURE_CANDIDATES`](crate::format::v3::MAX_POSTURE_CANDIDATES) samples (the
//!   compiler refuses more, with the figure); a query loops over one list in place.
//! - **The exact tier** is the paper's method to the digit and does not add the term;
//!   the served tier does ([`crate::Table::query_with_joints`]).
//! - **Position only**: the term corrects the position; the orientation is the served
//!   field's and the model's.
//!
//! [`reference`](fn@reference) is the same sum over every sample, without lists: the definition the fast
//! path ([`PreparedPosture::term`]) is tested against.

use crate::format::v3::ArchivedPostureRecord;
use crate::format::{Grid, Header};

/// Wendland's C2 function `(1 − t)⁴ (4t + 1)` on `[0, 1)`, 0 beyond: a smooth bump with
/// compact support, 1 at 0.
#[inline]
pub fn wendland(t: f64) -> f64 {
    if t < 1.0 {
        let u = 1.0 - t;
        let u2 = u * u;
        u2 * u2 * (4.0 * t + 1.0)
    } else {
        0.0
    }
}

/// The squared Euclidean distance of two joint vectors, rad² (over the shorter one).
#[inline]
pub fn joint_distance_squared_rad2(a_rad: &[f64], b_rad: impl IntoIterator<Item = f64>) -> f64 {
    let mut sum = 0.0;
    for (a, b) in a_rad.iter().zip(b_rad) {
        let d = a - b;
        sum += d * d;
    }
    sum
}

/// The posture term's parameters (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PostureParams {
    /// The spatial support `R`, mm.
    pub radius_mm: f64,
    /// The joint-space support `ℓ_q`, rad.
    pub length_rad: f64,
    /// The weight floor `W0`.
    pub floor: f64,
}

impl PostureParams {
    /// The weight of a sample at squared distance `distance2_mm2` from the (clamped)
    /// target and joint values `sample_joints_rad` against the query's `joints_rad`.
    /// Zero outside either support.
    #[inline]
    pub fn weight(
        &self,
        distance2_mm2: f64,
        joints_rad: &[f64],
        sample_joints_rad: impl IntoIterator<Item = f64>,
    ) -> f64 {
        self.weight_squared(
            distance2_mm2,
            joint_distance_squared_rad2(joints_rad, sample_joints_rad),
        )
    }

    /// [`weight_at`](Self::weight_at) from the squared distances, zero outside either
    /// support (and for a NaN) without a square root or a division: most samples a
    /// served query lists are outside one support or the other.
    #[inline]
    pub fn weight_squared(&self, distance2_mm2: f64, joint_distance2_rad2: f64) -> f64 {
        // `&`, not `&&`: one branch, rarely taken, instead of a first one taken about as
        // often as not. Written so that NaN fails the test.
        let inside = (distance2_mm2 < self.radius_mm * self.radius_mm)
            & (joint_distance2_rad2 < self.length_rad * self.length_rad);
        if inside {
            self.weight_at(distance2_mm2.sqrt(), joint_distance2_rad2.sqrt())
        } else {
            0.0
        }
    }

    /// `w_i` of a sample `distance_mm` from the target and `joint_distance_rad` (Euclidean)
    /// from the query's joint values: the one definition of the weight.
    #[inline]
    pub fn weight_at(&self, distance_mm: f64, joint_distance_rad: f64) -> f64 {
        wendland(distance_mm / self.radius_mm) * wendland(joint_distance_rad / self.length_rad)
    }

    /// The term from its sums: `Σ w_i r_i / max(Σ w_i, W0)`, before the fade.
    #[inline]
    pub fn term(&self, weight_sum: f64, weighted_mm: [f64; 3]) -> [f64; 3] {
        let denominator = weight_sum.max(self.floor);
        weighted_mm.map(|v| v / denominator)
    }
}

/// Where a posture term is evaluated: the nearest point of the table's grid box to
/// `position_mm` and the fade `s` there (1 inside the box, 0 a fade length or more away);
/// `None` for a non-finite position.
#[inline]
pub fn clamped_and_fade(grid: &Grid, position_mm: [f64; 3]) -> Option<([f64; 3], f64)> {
    let hi = grid.max_mm();
    let mut clamped = position_mm;
    let mut outside_mm2 = 0.0;
    for axis in 0..3 {
        let v = position_mm[axis];
        if !v.is_finite() {
            return None;
        }
        clamped[axis] = v.clamp(grid.origin_mm[axis], hi[axis]);
        let d = v - clamped[axis];
        outside_mm2 += d * d;
    }
    let length_mm = crate::served::fade_length_mm(grid.cell_mm);
    let fade = crate::fade::smoothstep(1.0 - outside_mm2.sqrt() / length_mm);
    Some((clamped, fade))
}

/// The posture term by its definition, over every sample (no lists): the reference the
/// table's fast path is held equal to. `joints_rad` holds each sample's joint values row
/// after row, `joints_rad.len() / positions_mm.len()` a row; `grid` is the table's.
pub fn reference(
    params: &PostureParams,
    grid: &Grid,
    positions_mm: &[[f64; 3]],
    joints_rad: &[f64],
    residuals_mm: &[[f64; 3]],
    position_mm: [f64; 3],
    query_joints_rad: &[f64],
) -> [f64; 3] {
    let Some((x, fade)) = clamped_and_fade(grid, position_mm) else {
        return [0.0; 3];
    };
    let stride = joints_rad.len() / positions_mm.len().max(1);
    let mut weight_sum = 0.0;
    let mut weighted_mm = [0.0; 3];
    for (i, (xi, ri)) in positions_mm.iter().zip(residuals_mm).enumerate() {
        let qi = &joints_rad[i * stride..(i + 1) * stride];
        let w = params.weight(
            crate::method::distance_squared_mm2(x, *xi),
            query_joints_rad,
            qi.iter().copied(),
        );
        if w > 0.0 {
            weight_sum += w;
            for (s, r) in weighted_mm.iter_mut().zip(ri) {
                *s += w * r;
            }
        }
    }
    params.term(weight_sum, weighted_mm).map(|v| v * fade)
}

/// The list entries a served query tests in one block ([`PreparedPosture::term`]).
const POSTURE_BLOCK: usize = 64;

/// A table's posture term, prepared at open.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PreparedPosture {
    params: PostureParams,
    /// The table's grid (its box clamps the target).
    table_grid: Grid,
    /// The posture grid: the table grid's origin, the term's own cells.
    grid: Grid,
    joint_count: usize,
}

impl PreparedPosture {
    /// The term of a validated version-3 table.
    pub(crate) fn new(header: &Header, record: &ArchivedPostureRecord) -> PreparedPosture {
        PreparedPosture {
            params: params_of(record),
            table_grid: header.grid,
            grid: posture_grid(header, record),
            joint_count: header.joint_count as usize,
        }
    }

    /// The term at a target and the query's joint values (the table's joint count of
    /// them, checked by the caller); `None` only for data out of range, which validation
    /// excludes. Never allocates or panics.
    #[inline]
    pub(crate) fn term(
        &self,
        record: &ArchivedPostureRecord,
        position_mm: [f64; 3],
        joints_rad: &[f64],
    ) -> Option<[f64; 3]> {
        let (x, fade) = clamped_and_fade(&self.table_grid, position_mm)?;
        if fade <= 0.0 {
            return Some([0.0; 3]);
        }
        // The clamped point is inside the table's box, which the posture grid covers.
        let cell = self.grid.cell_of(x)?;
        let offsets = record.cell_offsets.as_slice();
        let start = offsets.get(cell)?.to_native() as usize;
        let end = offsets.get(cell + 1)?.to_native() as usize;
        let list = record.cell_samples.get(start..end)?;
        let positions = record.positions_mm.as_slice();
        let residuals = record.residuals_mm.as_slice();
        let joints = record.joints_rad.as_slice();
        let r2 = self.params.radius_mm * self.params.radius_mm;
        let position = |i: usize| Some(positions.get(i)?.map(|v| v.to_native()));
        // Two passes over each block of the list, because about half a list is in reach
        // and almost none of that half near in joint space: a test on the position in the
        // loop that weighs would be mispredicted about as often as not, and weighing every
        // entry reads and sums the joints of all. The first pass keeps the samples in
        // reach without a branch, the second weighs those alone; both keep the list's
        // order, so the sums are the reference's. (Blocks keep the buffer a few cache
        // lines, cleared per block.)
        let mut weight_sum = 0.0;
        let mut weighted_mm = [0.0; 3];
        for block in list.chunks(POSTURE_BLOCK) {
            let mut near = [0u32; POSTURE_BLOCK];
            let mut count = 0;
            for i in block {
                let i = i.to_native();
                let d2 = crate::method::distance_squared_mm2(x, position(i as usize)?);
                // Written at the next free place either way (there is one: `count` is at
                // most the entries tested before), kept by counting it; NaN is not kept.
                if let Some(slot) = near.get_mut(count) {
                    *slot = i;
                }
                count += usize::from(d2 < r2);
            }
            for &i in near.get(..count)? {
                let i = i as usize;
                let d2 = crate::method::distance_squared_mm2(x, position(i)?);
                let from = i * self.joint_count;
                let qi = joints.get(from..from + self.joint_count)?;
                let dq2 = joint_distance_squared_rad2(joints_rad, qi.iter().map(|v| v.to_native()));
                let w = self.params.weight_squared(d2, dq2);
                if w > 0.0 {
                    weight_sum += w;
                    for (s, r) in weighted_mm.iter_mut().zip(residuals.get(i)?.iter()) {
                        *s += w * r.to_native();
                    }
                }
            }
        }
        Some(self.params.term(weight_sum, weighted_mm).map(|v| v * fade))
    }

    /// The parameters.
    pub(crate) fn params(&self) -> PostureParams {
        self.params
    }
}

/// The parameters a record stores.
pub fn params_of(record: &ArchivedPostureRecord) -> PostureParams {
    PostureParams {
        radius_mm: record.radius_mm.to_native(),
        length_rad: record.length_rad.to_native(),
        floor: record.floor.to_native(),
    }
}

/// The posture grid a record describes over a table's grid.
pub fn posture_grid(header: &Header, record: &ArchivedPostureRecord) -> Grid {
    Grid {
        origin_mm: header.grid.origin_mm,
        cell_mm: record.cell_mm.to_native(),
        dims: record.dims.map(|d| d.to_native()),
    }
}
