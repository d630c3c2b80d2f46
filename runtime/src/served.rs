//! The served tier: the continuous correction field of a version-2 table.
//!
//! The compiler evaluates the exact method at every node (corner) of the cell grid — a
//! node's value is `Σ q_i d_i` over its own neighbours and weights, the base weights of
//! the paper placed where they are used — and a query blends the 8 nodes of the target's
//! cell trilinearly:
//!
//! ```text
//! d(p) = Σ_{a,b,c ∈ {0,1}} w_a(u) w_b(v) w_c(w) · d[i+a, j+b, k+c],   w_0(t) = 1 − t, w_1(t) = t
//! ```
//!
//! with `(i, j, k)` the cell and `(u, v, w)` the target's position in it, each in `[0, 1]`.
//! On a face between two cells both blend the same 4 nodes with the same weights, so the
//! field is continuous (C0) everywhere it is defined, and linear along every cell edge:
//! a servo loop stepping through it never meets a jump. It is defined in every cell whose
//! 8 nodes have values; elsewhere a query of a position-only table says
//! [`Status::UncoveredCell`] and never extrapolates (a hybrid table fades its residual
//! instead: see below). With the method's values, coverage is the exact tier's shrunk by up to one
//! cell where the samples end (a target whose own neighbourhood is admissible can have a
//! corner that is not); a kriging field has values at every corner of a cell where the
//! exact tier can answer, so it covers at least what the exact tier does. A node without a
//! value holds [`crate::format::v2::NO_NODE_VALUE`] in every component;
//! the NaN spreads through the blend (even at weight 0), which is how the query notices.
//!
//! A tool-axis field ([`crate::format::ServedField::KrigingToolAxis`]) holds four vectors
//! a node, `f, h_x, h_y, h_z`, and answers `f + a_x h_x + a_y h_y + a_z h_z` blended, with
//! `a` the approach axis of the nominal TCP at the query's joint values. The combination
//! is linear, so each corner's combination is blended with the same weights: the field is
//! continuous in position for a fixed `a`, and a missing node is missed whatever `a` is.
//!
//! # A hybrid table's residual
//!
//! A hybrid table's field is the residual its calibrated model leaves, and the model is
//! valid everywhere: where the residual has no value the answer is the model alone, and
//! the residual fades to zero on the way there rather than stopping with a jump
//! ([`crate::Residual`] says which of the three a query got):
//!
//! - inside the grid a corner without a value contributes zero, so across the last cell
//!   the blend runs linearly from the last values to zero (no renormalisation over the
//!   corners that remain, which would jump where a corner's weight reaches zero);
//! - outside the grid the field is evaluated at the target's nearest point of the grid box
//!   and multiplied by `s(1 − d / L)`, `s(t) = 3t² − 2t³` (smoothstep), with `d` the
//!   target's distance to the box and `L` the fade length ([`fade_length_mm`]), so it
//!   meets the field on the box's faces and reaches zero, with zero slope, at `d = L`;
//! - beyond the fade, or for a configuration no node set has, the residual is zero.
//!
//! One node set serves targets of unknown configuration, one each configuration the
//! samples carry ([`crate::format::v2::NodeSet`]). A table with a joint-space screen has no served tier:
//! its admissible samples change with the target's joint values, which no node grid over
//! positions can hold (its queries are the exact tier's).

use crate::correction::{Correction, Residual, Status};
use crate::format::v2::ArchivedTableData;
use crate::format::{Header, CONTENT_MODEL};
use crate::lanes::{Lanes, Pair};

/// What a served query needs of the grid, prepared once at open: the node strides and the
/// first node of the set serving targets of unknown configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ServedGrid {
    origin_mm: [f64; 3],
    cell_mm: f64,
    cells: [usize; 3],
    /// `cells` as doubles (exact: each is a `u32`, the header's `dims`), and the last cell
    /// of each axis (`cells − 1`, 0 for none): what every query's [`ServedGrid::locate`]
    /// compares and clamps with, converted once.
    cells_f64: [f64; 3],
    last_cell: [u32; 3],
    /// Node offsets of a cell's 8 corners from its minimum one, x fastest.
    corners: [usize; 8],
    /// The first node of the first set (targets of unknown configuration).
    first_any: usize,
    /// Whether the samples carry configurations (targets' configurations then choose the
    /// set).
    with_configs: bool,
    /// Vectors per node ([`crate::format::ServedField::node_stride`]).
    stride: usize,
    /// A hybrid table's fade length ([`fade_length_mm`]): its residual fades to zero
    /// where it has no value. `None`: a position-only table, which refuses there.
    fade_mm: Option<f64>,
    /// [`squared_within`] the fade length, which is also a hybrid table's bound on the
    /// distance from the nominal TCP at the query's joint values to the target
    /// ([`crate::Table::joints_tolerance_mm`]): that check on squares, without a root.
    joints_within_mm2: f64,
}

/// The distance from the grid box over which a hybrid table's residual fades to zero:
/// two cells, and at least 20 mm.
///
/// Smoothstep's steepest slope is `1.5 / L`, so a residual of amplitude `A` changes by at
/// most `1.5 A · δ / L` over a step `δ` outside the box: with `L ≥ 20 mm`, a 1 mm residual
/// changes by at most 0.75 µm per 0.01 mm step (a servo loop's increments see no jump),
/// to which the field's own slope along the box face adds what it has inside. Two cells
/// keep the fade no shorter than the field's own resolution on a coarse grid, where a
/// residual a cell away is still the field's best guess.
pub fn fade_length_mm(cell_mm: f64) -> f64 {
    (2.0 * cell_mm).max(20.0)
}

/// The largest double `T` whose square root is at most `length_mm` (positive and
/// finite): `d2 ≤ T` exactly when `√d2 ≤ length_mm`, for every `d2` (NaN and infinity
/// fail both), since the square root is correctly rounded and so never decreases. A query
/// then compares a squared distance with `T` and takes no root, with the decisions of the
/// root's comparison to the last bit. Found at open, from `length_mm²` a few steps of one
/// unit in the last place each way.
pub(crate) fn squared_within(length_mm: f64) -> f64 {
    // Positive finite doubles are ordered as their bits: one unit up or down is one bit
    // pattern up or down.
    let up = |t: f64| f64::from_bits(t.to_bits() + 1);
    let down = |t: f64| f64::from_bits(t.to_bits() - 1);
    let mut t = length_mm * length_mm;
    if !(t.is_finite() && t > 0.0) {
        return t;
    }
    while t > 0.0 && t.sqrt() > length_mm {
        t = down(t);
    }
    while up(t).is_finite() && up(t).sqrt() <= length_mm {
        t = up(t);
    }
    t
}

impl ServedGrid {
    /// The prepared grid of a validated table with a served tier.
    pub(crate) fn new(header: &Header, data: &ArchivedTableData) -> ServedGrid {
        let grid = &header.grid;
        let [nx, ny, _] = grid.dims.map(|d| d as usize + 1);
        let nxy = nx * ny;
        ServedGrid {
            origin_mm: grid.origin_mm,
            cell_mm: grid.cell_mm,
            cells: grid.dims.map(|d| d as usize),
            cells_f64: grid.dims.map(f64::from),
            last_cell: grid.dims.map(|d| d.saturating_sub(1)),
            corners: [0, 1, nx, nx + 1, nxy, nxy + 1, nxy + nx, nxy + nx + 1],
            first_any: data
                .node_sets
                .first()
                .map_or(0, |s| s.first_node.to_native() as usize),
            with_configs: !data.configs.is_empty(),
            stride: header.served_field.node_stride(),
            fade_mm: (header.content_flags & CONTENT_MODEL != 0)
                .then(|| fade_length_mm(grid.cell_mm)),
            joints_within_mm2: squared_within(fade_length_mm(grid.cell_mm)),
        }
    }

    /// Vectors per node: 1, or 4 for a field that turns with the tool.
    #[inline]
    pub(crate) fn stride(&self) -> usize {
        self.stride
    }

    /// Whether a squared distance `d2` (mm²) from the nominal TCP at the query's joint
    /// values to the target is within a hybrid table's bound
    /// ([`crate::Table::joints_tolerance_mm`]): `√d2 ≤` the bound, decided on squares
    /// ([`squared_within`]). NaN is not.
    #[inline(always)]
    pub(crate) fn joints_within(&self, d2_mm2: f64) -> bool {
        d2_mm2 <= self.joints_within_mm2
    }

    /// Whether [`blend_strict`] serves this grid: one vector a node and no fade (a
    /// position-only table's field).
    #[inline]
    pub(crate) fn is_strict(&self) -> bool {
        self.stride == 1 && self.fade_mm.is_none()
    }

    /// The node index of the target's cell's minimum corner (x fastest over `dims + 1`
    /// nodes per axis) and the target's fractional position in the cell, each in
    /// `[0, 1]`; `None` outside the grid or for a non-finite position. Cells are half-open
    /// except at the grid's maximum faces, as [`crate::format::Grid::cell_of`] has them.
    #[inline(always)]
    fn locate(&self, position_mm: [f64; 3]) -> Option<(usize, [f64; 3])> {
        // A division, not a multiplication by the reciprocal, so that the cell is the one
        // `Grid::cell_of` finds, to the last bit at cell faces.
        // Each axis written out: an array's `map` was compiled as a call returning through
        // memory, whose reload stalled the processor's store forwarding.
        let along = |a: usize| (position_mm[a] - self.origin_mm[a]) / self.cell_mm;
        let u = [along(0), along(1), along(2)];
        // Written so that NaN fails the test; one branch for the three axes.
        let inside = |a: usize| u[a] >= 0.0 && u[a] <= self.cells_f64[a];
        if !(inside(0) & inside(1) & inside(2)) {
            return None;
        }
        // `u` is in `[0, cells]` and `cells` in `u32` (the header's `dims`): a cast to
        // `u32` truncates as one to `usize` would, in fewer instructions.
        let cell_of = |a: usize| (u[a] as u32).min(self.last_cell[a]);
        let cell = [cell_of(0), cell_of(1), cell_of(2)];
        let fraction_of = |a: usize| (u[a] - f64::from(cell[a])).clamp(0.0, 1.0);
        let fraction = [fraction_of(0), fraction_of(1), fraction_of(2)];
        let [nx, nxy] = [self.corners[2], self.corners[4]];
        let index = cell[0] as usize + nx * cell[1] as usize + nxy * cell[2] as usize;
        Some((index, fraction))
    }

    /// [`ServedGrid::locate`] of the grid box's point nearest to `position_mm`, and the
    /// distance to it (mm; zero inside the box); `None` for a non-finite position.
    #[inline]
    fn locate_nearest(&self, position_mm: [f64; 3]) -> Option<(usize, [f64; 3], f64)> {
        let mut cell = [0usize; 3];
        let mut fraction = [0.0; 3];
        let mut outside_mm2 = 0.0;
        for axis in 0..3 {
            let u = (position_mm[axis] - self.origin_mm[axis]) / self.cell_mm;
            if !u.is_finite() {
                return None;
            }
            let cells = self.cells[axis];
            let inside = u.clamp(0.0, cells as f64);
            let outside_mm = (u - inside) * self.cell_mm;
            outside_mm2 += outside_mm * outside_mm;
            cell[axis] = (inside as u32 as usize).min(cells.saturating_sub(1));
            fraction[axis] = (inside - cell[axis] as f64).clamp(0.0, 1.0);
        }
        let [nx, nxy] = [self.corners[2], self.corners[4]];
        Some((
            cell[0] + nx * cell[1] + nxy * cell[2],
            fraction,
            outside_mm2.sqrt(),
        ))
    }
}

/// The blended node vectors at a target: position, and orientation (zero without), one
/// vector per term (`f`, then `h_x, h_y, h_z` for a tool-axis field).
#[derive(Clone, Copy, Debug)]
pub(crate) struct ServedTerms<const S: usize> {
    pub(crate) position_mm: [[f64; 3]; S],
    pub(crate) orientation_rad: [[f64; 3]; S],
    /// The corners that held a value (8 where the field is defined).
    pub(crate) nodes: u32,
    /// How much of the field the terms hold.
    pub(crate) residual: Residual,
}

impl<const S: usize> ServedTerms<S> {
    /// No field at all: a hybrid table's model alone.
    const MODEL_ONLY: ServedTerms<S> = ServedTerms {
        position_mm: [[0.0; 3]; S],
        orientation_rad: [[0.0; 3]; S],
        nodes: 0,
        residual: Residual::ModelOnly,
    };
}

impl ServedTerms<1> {
    /// The field of one vector a node, as a correction.
    #[inline]
    pub(crate) fn correction(&self) -> Correction {
        Correction {
            position_error_mm: self.position_mm[0],
            orientation_error_rad: self.orientation_rad[0],
            neighbours: self.nodes,
            status: Status::Ok,
            residual: self.residual,
            evidence: crate::Evidence::WITHIN,
        }
    }
}

impl ServedTerms<4> {
    /// The tool-axis field turned by the nominal TCP's approach axis `a`:
    /// `f + a_x h_x + a_y h_y + a_z h_z`, position and orientation.
    #[inline(always)]
    pub(crate) fn turned(&self, a: [f64; 3]) -> Correction {
        // Written out: an array's `map`, and even a closure, is a call the compiler does
        // not always inline.
        #[inline(always)]
        fn turn(t: &[[f64; 3]; 4], a: [f64; 3]) -> [f64; 3] {
            [
                t[0][0] + a[0] * t[1][0] + a[1] * t[2][0] + a[2] * t[3][0],
                t[0][1] + a[0] * t[1][1] + a[1] * t[2][1] + a[2] * t[3][1],
                t[0][2] + a[0] * t[1][2] + a[1] * t[2][2] + a[2] * t[3][2],
            ]
        }
        Correction {
            position_error_mm: turn(&self.position_mm, a),
            orientation_error_rad: turn(&self.orientation_rad, a),
            neighbours: self.nodes,
            status: Status::Ok,
            residual: self.residual,
            evidence: crate::Evidence::WITHIN,
        }
    }
}

/// Where a target's served value comes from ([`site`]): found before the blend, so that a
/// hybrid query can ask for the nodes' memory ([`prefetch`]) while it computes its model
/// part.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Site {
    /// The node of the cell's minimum corner (counted in nodes from the first of the node
    /// values, its set's offset included), the target's fractional position in the cell,
    /// and outside the grid the fade factor of a hybrid table's residual.
    Cell {
        first: usize,
        fraction: [f64; 3],
        fade: Option<f64>,
    },
    /// No field here: a hybrid table's model alone.
    ModelOnly,
}

/// The cell a target of configuration `config` at `position_mm` is served from, or why
/// there is none (the module docs: a hybrid table's field fades and never misses).
#[inline(always)]
pub(crate) fn site(
    grid: &ServedGrid,
    data: &ArchivedTableData,
    position_mm: [f64; 3],
    config: Option<u8>,
) -> Result<Site, Status> {
    let (base, fraction, fade) = match (grid.locate(position_mm), grid.fade_mm) {
        (Some((base, fraction)), _) => (base, fraction, None),
        (None, None) => return Err(Status::OutsideGrid),
        (None, Some(length_mm)) => {
            let (base, fraction, distance_mm) = grid
                .locate_nearest(position_mm)
                .ok_or(Status::OutsideGrid)?;
            let fade = crate::fade::smoothstep(1.0 - distance_mm / length_mm);
            if fade <= 0.0 {
                return Ok(Site::ModelOnly);
            }
            (base, fraction, Some(fade))
        }
    };
    // Samples without configurations serve targets of any configuration; with them, a
    // configuration no sample has is served by none.
    let first_set = match config {
        Some(c) if grid.with_configs => match data.node_sets.iter().find(|s| s.config == c) {
            Some(set) => set.first_node.to_native() as usize,
            None if grid.fade_mm.is_some() => return Ok(Site::ModelOnly),
            None => return Err(Status::NoAdmissibleNeighbour),
        },
        _ => grid.first_any,
    };
    Ok(Site::Cell {
        first: first_set + base,
        fraction,
        fade,
    })
}

/// Asks the processor to bring a cell's node values (and their orientation terms when
/// `orientation`) into its cache without waiting for them: a hybrid query calls this before
/// its model part, whose arithmetic then hides the memory's latency. Reads nothing and
/// changes no answer; a hint only, and none on other architectures than x86-64.
#[inline(always)]
pub(crate) fn prefetch(
    grid: &ServedGrid,
    data: &ArchivedTableData,
    site: &Site,
    orientation: bool,
) {
    let Site::Cell { first, .. } = *site else {
        return;
    };
    // The stride a constant, so that each run's lines are a fixed count, unrolled.
    let arrays = [
        Some(data.node_errors_mm.as_slice()),
        orientation.then(|| data.node_orientation_errors_rad.as_slice()),
    ];
    for values in arrays.into_iter().flatten() {
        // Another stride is not read: `blend_site` refuses it.
        match grid.stride {
            1 => prefetch_cell::<1>(grid, values, first),
            4 => prefetch_cell::<4>(grid, values, first),
            _ => {}
        }
    }
}

/// [`prefetch`] of one array of node values of stride `S`: the cell's 8 corners are 4 runs
/// of 2 neighbouring nodes along x, in the block [`blend`] reads ([`cell_block`]).
#[inline(always)]
fn prefetch_cell<const S: usize>(
    grid: &ServedGrid,
    values: &[rkyv::Archived<[f64; 3]>],
    first: usize,
) {
    let Some(block) = cell_block::<S>(values, first, &grid.corners) else {
        return;
    };
    for corner in [0, 2, 4, 6] {
        // Within the block's length, which did not overflow.
        let at = grid.corners[corner] * S;
        if let Some(run) = block.get(at..at + 2 * S) {
            prefetch_bytes(run);
        }
    }
}

/// Prefetches every cache line `values` spans.
#[inline(always)]
fn prefetch_bytes<T>(values: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        const LINE: usize = 64;
        let len = std::mem::size_of_val(values);
        let Some(last) = len.checked_sub(1) else {
            return;
        };
        let start = values.as_ptr().cast::<i8>();
        let at = |offset: usize| {
            // SAFETY: a prefetch is a hint that reads nothing architecturally and never
            // faults, whatever the address; these bytes are `values`' anyway. SSE, which
            // the instruction needs, is part of x86-64.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(offset)) };
        };
        // A byte every line's length from the first, and the last byte: every line the
        // bytes span, one perhaps twice (a repeat costs nothing), in a count that depends on
        // the length alone. The lines spanned depend on the address too, and a loop over
        // them is mispredicted on a random target.
        for line in 0..last.div_ceil(LINE) {
            at(line * LINE);
        }
        at(last);
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = values;
}

/// The node vectors of a [`site`], blended trilinearly term by term (position, and
/// orientation when `orientation`). `S` is the table's stride (1, or 4 for a tool-axis
/// field, whose terms the caller turns with the axis once it knows the field answers:
/// the axis costs a forward kinematics a miss need not pay); another `S` is
/// [`Status::InvalidInput`]. A position-only table's cell with a corner without a value
/// is [`Status::UncoveredCell`]. Never allocates or panics.
#[inline(always)]
pub(crate) fn blend_site<const S: usize>(
    grid: &ServedGrid,
    data: &ArchivedTableData,
    site: &Site,
    orientation: bool,
) -> Result<ServedTerms<S>, Status> {
    if grid.stride != S {
        return Err(Status::InvalidInput);
    }
    let Site::Cell {
        first,
        fraction,
        fade,
    } = *site
    else {
        return Ok(ServedTerms::MODEL_ONLY);
    };
    let weights = trilinear_weights(fraction);
    let nodes = data.node_errors_mm.as_slice();
    let blended = blend::<S>(nodes, first, &grid.corners, &weights).ok_or(Status::InvalidInput)?;
    let strict = grid.fade_mm.is_none();
    if strict && blended.missing != 0 {
        return Err(Status::UncoveredCell);
    }
    let (orientation_rad, missing) = if orientation {
        let nodes = data.node_orientation_errors_rad.as_slice();
        let turned =
            blend::<S>(nodes, first, &grid.corners, &weights).ok_or(Status::InvalidInput)?;
        if strict && turned.missing != 0 {
            return Err(Status::UncoveredCell);
        }
        (turned.sum, blended.missing | turned.missing)
    } else {
        ([[0.0; 3]; S], blended.missing)
    };
    let mut terms = ServedTerms {
        position_mm: blended.sum,
        orientation_rad,
        nodes: 8 - missing.count_ones(),
        residual: match (missing, fade) {
            (0, None) => Residual::Full,
            _ if !blended.contributed => Residual::ModelOnly,
            _ => Residual::Faded,
        },
    };
    if let Some(fade) = fade {
        // Term by term, by value: a loop of references into `terms` kept it in memory,
        // stored in pieces of other widths than the caller then read (a stall of the
        // processor's store forwarding).
        let scale = |v: [f64; 3]| [v[0] * fade, v[1] * fade, v[2] * fade];
        for t in 0..S {
            terms.position_mm[t] = scale(terms.position_mm[t]);
            terms.orientation_rad[t] = scale(terms.orientation_rad[t]);
        }
    }
    Ok(terms)
}

/// [`blend_site`] of a table whose field neither fades nor turns with the tool (a
/// position-only table's: one vector a node, a corner without a value refused), as a
/// correction: the same sums to the bit, the 8 corners blended without a test each. A
/// missing corner holds NaN in every component and spreads it through its sums (even at
/// weight 0), so a NaN sum is [`Status::UncoveredCell`], as `blend_site`'s test of each
/// corner says; validated values are finite and plausible, so nothing else makes one.
/// Another grid is [`Status::InvalidInput`]. Never allocates or panics.
#[inline(always)]
pub(crate) fn blend_strict(
    grid: &ServedGrid,
    data: &ArchivedTableData,
    site: &Site,
    orientation: bool,
) -> Result<Correction, Status> {
    let Site::Cell {
        first,
        fraction,
        fade: None,
    } = *site
    else {
        return Err(Status::InvalidInput);
    };
    if !grid.is_strict() {
        return Err(Status::InvalidInput);
    }
    let weights = trilinear_weights(fraction);
    // A function, not a closure: the closure was compiled as a call returning through
    // memory.
    #[inline(always)]
    fn sum_of(
        nodes: &[rkyv::Archived<[f64; 3]>],
        first: usize,
        corners: &[usize; 8],
        weights: &[f64; 8],
    ) -> Option<[f64; 3]> {
        let block = cell_block::<1>(nodes, first, corners)?;
        // `blend`'s pairs: x and y in one, z beside a zero; each lane `x += w · v` in the
        // corners' order.
        let (mut xy, mut z) = (Pair([0.0; 2]), Pair([0.0; 2]));
        for (&corner, &weight) in corners.iter().zip(weights) {
            let node = block.get(corner)?;
            let w = Pair::splat(weight);
            xy = xy + w * Pair([node[0].to_native(), node[1].to_native()]);
            z = z + w * Pair([node[2].to_native(), 0.0]);
        }
        Some([xy.0[0], xy.0[1], z.0[0]])
    }
    let sum = |nodes| sum_of(nodes, first, &grid.corners, &weights);
    let position_mm = sum(data.node_errors_mm.as_slice()).ok_or(Status::InvalidInput)?;
    let defined = |v: &[f64; 3]| !(v[0].is_nan() | v[1].is_nan() | v[2].is_nan());
    if !defined(&position_mm) {
        return Err(Status::UncoveredCell);
    }
    let orientation_error_rad = if orientation {
        let r = sum(data.node_orientation_errors_rad.as_slice()).ok_or(Status::InvalidInput)?;
        if !defined(&r) {
            return Err(Status::UncoveredCell);
        }
        r
    } else {
        [0.0; 3]
    };
    Ok(Correction {
        position_error_mm: position_mm,
        orientation_error_rad,
        neighbours: 8,
        status: Status::Ok,
        residual: Residual::Full,
        evidence: crate::Evidence::WITHIN,
    })
}

/// The weights of the 8 corners, in the order `corners` lists them in [`serve`]:
/// x fastest, then y, then z.
#[inline]
fn trilinear_weights([u, v, w]: [f64; 3]) -> [f64; 8] {
    let (u0, v0, w0) = (1.0 - u, 1.0 - v, 1.0 - w);
    [
        u0 * v0 * w0,
        u * v0 * w0,
        u0 * v * w0,
        u * v * w0,
        u0 * v0 * w,
        u * v0 * w,
        u0 * v * w,
        u * v * w,
    ]
}

/// A cell's corners blended ([`blend`]).
struct Blend<const S: usize> {
    /// `Σ weight · term` over the corners that hold a value.
    sum: [[f64; 3]; S],
    /// Bit `c` set: corner `c` holds no value (and contributed nothing).
    missing: u8,
    /// Whether a corner with a value had a positive weight.
    contributed: bool,
}

/// `Σ weight · term_t` over the corners that hold a value, for each term `t`, each node
/// being `S` consecutive vectors from node `first` (counted in nodes); `None` when a
/// corner is out of range (excluded by validation; checked so that nothing can panic).
#[inline(always)]
fn blend<const S: usize>(
    nodes: &[rkyv::Archived<[f64; 3]>],
    first: usize,
    corners: &[usize; 8],
    weights: &[f64; 8],
) -> Option<Blend<S>> {
    // One range check for the whole block of the cell's nodes, then offsets within it.
    let block = cell_block::<S>(nodes, first, corners)?;
    let mut out = Blend {
        sum: [[0.0; 3]; S],
        missing: 0,
        contributed: false,
    };
    // A node's `3 S` values in pairs, side by side ([`crate::lanes`]): each lane sums as
    // `x += weight · v` does, in the same order, so the sums are the scalar ones to the
    // bit. An odd count's last pair carries a zero beside its value, never read.
    const MOST: usize = 6;
    let pairs = (3 * S).div_ceil(2).min(MOST);
    let mut sums = [Pair([0.0; 2]); MOST];
    for (c, (&corner, &weight)) in corners.iter().zip(weights).enumerate() {
        // Within the block's length, which did not overflow.
        let at = corner * S;
        let node = block.get(at..at + S)?;
        // Validation admits finite values or the marker, NaN in every component.
        if node[0][0].to_native().is_nan() {
            out.missing |= 1 << c;
            continue;
        }
        out.contributed |= weight > 0.0;
        let value = |k: usize| node.get(k / 3).map_or(0.0, |v| v[k % 3].to_native());
        let w = Pair::splat(weight);
        for (p, sum) in sums.iter_mut().enumerate().take(pairs) {
            *sum = *sum + w * Pair([value(2 * p), value(2 * p + 1)]);
        }
    }
    for (t, term) in out.sum.iter_mut().enumerate() {
        for (i, x) in term.iter_mut().enumerate() {
            let k = 3 * t + i;
            *x = sums[(k / 2).min(MOST - 1)].0[k % 2];
        }
    }
    Some(out)
}

/// The node values from a cell's minimum corner `first` (counted in nodes) to its maximum
/// one, `S` vectors a node: every corner's, checked once. `None` when they are out of
/// range or their offsets overflow.
#[inline(always)]
fn cell_block<'a, const S: usize>(
    values: &'a [rkyv::Archived<[f64; 3]>],
    first: usize,
    corners: &[usize; 8],
) -> Option<&'a [rkyv::Archived<[f64; 3]>]> {
    let start = first.checked_mul(S)?;
    let end = first
        .checked_add(corners[7])?
        .checked_add(1)?
        .checked_mul(S)?;
    values.get(start..end)
}

/// The node values of one set, for inspection: node `(i, j, k)` of set `set`, or `None`
/// out of range. For a tool-axis field, its `f` term ([`node_terms`] has them all).
pub fn node(
    header: &Header,
    data: &ArchivedTableData,
    set: usize,
    ijk: [usize; 3],
) -> Option<([f64; 3], Option<[f64; 3]>)> {
    node_terms(header, data, set, ijk).map(|(p, r)| (p[0], r.map(|r| r[0])))
}

/// A node's terms `f, h_x, h_y, h_z` ([`node_terms`]).
pub type NodeTerms = [[f64; 3]; 4];

/// Every term of node `(i, j, k)` of set `set`, `f, h_x, h_y, h_z` (position, and
/// orientation when the table has it), or `None` out of range. A field of one vector a
/// node does not turn with the tool: its `h` terms are zero.
pub fn node_terms(
    header: &Header,
    data: &ArchivedTableData,
    set: usize,
    [i, j, k]: [usize; 3],
) -> Option<(NodeTerms, Option<NodeTerms>)> {
    let [nx, ny, nz] = header.grid.dims.map(|d| d as usize + 1);
    if i >= nx || j >= ny || k >= nz {
        return None;
    }
    let stride = header.served_field.node_stride();
    let index = data.node_sets.get(set)?.first_node.to_native() as usize + i + nx * (j + ny * k);
    let start = index.checked_mul(stride)?;
    let terms = |values: &[rkyv::Archived<[f64; 3]>]| {
        let stored = values.get(start..start.checked_add(stride)?)?;
        let mut out: NodeTerms = [[0.0; 3]; 4];
        for (o, v) in out.iter_mut().zip(stored) {
            *o = v.map(|x| x.to_native());
        }
        Some(out)
    };
    let p = terms(data.node_errors_mm.as_slice())?;
    let r = terms(data.node_orientation_errors_rad.as_slice());
    Some((p, r))
}

/// Whether a stored node value is the "no value" marker ([`crate::format::v2::NO_NODE_VALUE`]).
pub fn is_missing(value: &[f64; 3]) -> bool {
    value.iter().all(|v| v.is_nan())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_sum_to_one_and_pick_the_corner_at_a_corner() {
        for f in [
            [0.0, 0.0, 0.0],
            [1.0, 1.0, 1.0],
            [0.3, 0.7, 0.2],
            [1.0, 0.0, 0.5],
        ] {
            let w = trilinear_weights(f);
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        }
        assert_eq!(trilinear_weights([1.0, 0.0, 1.0])[5], 1.0);
    }

    /// On squares the joints' check decides as on roots, to the last bit: at the bound's
    /// square and every double within 64 units in the last place of it, for fade lengths
    /// of every grid (two cells, at least 20 mm) and others.
    #[test]
    fn the_squared_bound_decides_as_the_root_does() {
        let mut lengths = vec![20.0, 33.393734788777906, 1e-3, 7.0, 1234.5678, 3e5];
        lengths.extend((1..2_000).map(|i| fade_length_mm(0.37 * f64::from(i))));
        for length in lengths {
            let bound = squared_within(length);
            assert!(bound.sqrt() <= length);
            let square = length * length;
            for d2 in (-64..=64_i64)
                .flat_map(|k| {
                    [square, bound].map(|t| f64::from_bits((t.to_bits() as i64 + k) as u64))
                })
                .chain([0.0, f64::NAN, f64::INFINITY, f64::MAX])
            {
                assert_eq!(d2 <= bound, d2.sqrt() <= length, "{length} {d2}");
            }
        }
    }

    #[test]
    fn locate_puts_the_maximum_face_in_the_last_cell() {
        let grid = ServedGrid {
            origin_mm: [0.0; 3],
            cell_mm: 10.0,
            cells: [2, 3, 4],
            cells_f64: [2.0, 3.0, 4.0],
            last_cell: [1, 2, 3],
            corners: [0, 1, 3, 4, 12, 13, 15, 16],
            first_any: 0,
            with_configs: false,
            stride: 1,
            fade_mm: None,
            joints_within_mm2: squared_within(20.0),
        };
        let (base, f) = grid.locate([20.0, 30.0, 40.0]).unwrap();
        assert_eq!(f, [1.0; 3]);
        assert_eq!(base, 1 + 3 * (2 + 4 * 3));
        assert!(grid.locate([20.0001, 0.0, 0.0]).is_none());
        assert!(grid.locate([f64::NAN, 0.0, 0.0]).is_none());
    }
}
