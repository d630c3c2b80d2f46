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
//! 8 nodes the method answers; elsewhere a query says [`Status::UncoveredCell`] and never
//! extrapolates. Coverage is therefore the exact tier's shrunk by up to one cell where the
//! samples end (a target whose own neighbourhood is admissible can have a corner that is
//! not). A node the method cannot answer holds [`crate::format::v2::NO_NODE_VALUE`] in every component;
//! the NaN spreads through the blend (even at weight 0), which is how the query notices.
//!
//! One node set serves targets of unknown configuration, one each configuration the
//! samples carry ([`crate::format::v2::NodeSet`]). A table with a joint-space screen has no served tier:
//! its admissible samples change with the target's joint values, which no node grid over
//! positions can hold (its queries are the exact tier's).

use crate::correction::{Correction, Status};
use crate::format::v2::ArchivedTableData;
use crate::format::Grid;

/// What a served query needs of the grid, prepared once at open: the node strides and the
/// first node of the set serving targets of unknown configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ServedGrid {
    origin_mm: [f64; 3],
    cell_mm: f64,
    cells: [usize; 3],
    /// Node offsets of a cell's 8 corners from its minimum one, x fastest.
    corners: [usize; 8],
    /// The first node of the first set (targets of unknown configuration).
    first_any: usize,
    /// Whether the samples carry configurations (targets' configurations then choose the
    /// set).
    with_configs: bool,
}

impl ServedGrid {
    /// The prepared grid of a validated table with a served tier.
    pub(crate) fn new(grid: &Grid, data: &ArchivedTableData) -> ServedGrid {
        let [nx, ny, _] = grid.dims.map(|d| d as usize + 1);
        let nxy = nx * ny;
        ServedGrid {
            origin_mm: grid.origin_mm,
            cell_mm: grid.cell_mm,
            cells: grid.dims.map(|d| d as usize),
            corners: [0, 1, nx, nx + 1, nxy, nxy + 1, nxy + nx, nxy + nx + 1],
            first_any: data
                .node_sets
                .first()
                .map_or(0, |s| s.first_node.to_native() as usize),
            with_configs: !data.configs.is_empty(),
        }
    }

    /// The node index of the target's cell's minimum corner (x fastest over `dims + 1`
    /// nodes per axis) and the target's fractional position in the cell, each in
    /// `[0, 1]`; `None` outside the grid or for a non-finite position. Cells are half-open
    /// except at the grid's maximum faces, as [`Grid::cell_of`] has them.
    #[inline]
    fn locate(&self, position_mm: [f64; 3]) -> Option<(usize, [f64; 3])> {
        let mut cell = [0usize; 3];
        let mut fraction = [0.0; 3];
        for axis in 0..3 {
            // A division, not a multiplication by the reciprocal, so that the cell is the one
            // `Grid::cell_of` finds, to the last bit at cell faces.
            let u = (position_mm[axis] - self.origin_mm[axis]) / self.cell_mm;
            let cells = self.cells[axis];
            // Written so that NaN fails the test.
            if !(u >= 0.0 && u <= cells as f64) {
                return None;
            }
            cell[axis] = (u as usize).min(cells.saturating_sub(1));
            fraction[axis] = (u - cell[axis] as f64).clamp(0.0, 1.0);
        }
        let [nx, nxy] = [self.corners[2], self.corners[4]];
        Some((cell[0] + nx * cell[1] + nxy * cell[2], fraction))
    }
}

/// The served correction at `position_mm` for a target of configuration `config`: the
/// interpolated errors (position, and orientation when `orientation`), or why there are
/// none. Never allocates or panics.
#[inline]
pub(crate) fn serve(
    grid: &ServedGrid,
    data: &ArchivedTableData,
    position_mm: [f64; 3],
    config: Option<u8>,
    orientation: bool,
) -> Correction {
    let Some((base, fraction)) = grid.locate(position_mm) else {
        return Correction::failed(Status::OutsideGrid);
    };
    // Samples without configurations serve targets of any configuration; with them, a
    // configuration no sample has is served by none.
    let first_set = match config {
        Some(c) if grid.with_configs => match data.node_sets.iter().find(|s| s.config == c) {
            Some(set) => set.first_node.to_native() as usize,
            None => return Correction::failed(Status::NoAdmissibleNeighbour),
        },
        _ => grid.first_any,
    };
    let first = first_set + base;
    let weights = trilinear_weights(fraction);
    let nodes = data.node_errors_mm.as_slice();
    let Some(position_error_mm) = blend(nodes, first, &grid.corners, &weights) else {
        return Correction::failed(Status::UncoveredCell);
    };
    let orientation_error_rad = if orientation {
        let nodes = data.node_orientation_errors_rad.as_slice();
        match blend(nodes, first, &grid.corners, &weights) {
            Some(r) => r,
            None => return Correction::failed(Status::UncoveredCell),
        }
    } else {
        [0.0; 3]
    };
    Correction {
        position_error_mm,
        orientation_error_rad,
        neighbours: 8,
        status: Status::Ok,
    }
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

/// `Σ weight · node` over the corners, or `None` when a corner is out of range (excluded
/// by validation; checked so that nothing can panic) or holds no value.
#[inline]
fn blend(
    nodes: &[rkyv::Archived<[f64; 3]>],
    first: usize,
    corners: &[usize; 8],
    weights: &[f64; 8],
) -> Option<[f64; 3]> {
    // One range check for the whole block of the cell's nodes, then offsets within it.
    let block = nodes.get(first..first.checked_add(corners[7])? + 1)?;
    let mut sum = [0.0; 3];
    for (&corner, &weight) in corners.iter().zip(weights) {
        let node = block.get(corner)?;
        for (s, v) in sum.iter_mut().zip(node.iter()) {
            *s += weight * v.to_native();
        }
    }
    // A missing node is NaN in every component, and NaN survives a zero weight.
    sum.iter().all(|v| !v.is_nan()).then_some(sum)
}

/// The node values of one set, for inspection: node `(i, j, k)` of set `set`, or `None`
/// out of range.
pub fn node(
    grid: &Grid,
    data: &ArchivedTableData,
    set: usize,
    [i, j, k]: [usize; 3],
) -> Option<([f64; 3], Option<[f64; 3]>)> {
    let [nx, ny, nz] = grid.dims.map(|d| d as usize + 1);
    if i >= nx || j >= ny || k >= nz {
        return None;
    }
    let index = data.node_sets.get(set)?.first_node.to_native() as usize + i + nx * (j + ny * k);
    let p = data.node_errors_mm.get(index)?.map(|v| v.to_native());
    let r = data
        .node_orientation_errors_rad
        .get(index)
        .map(|r| r.map(|v| v.to_native()));
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

    #[test]
    fn locate_puts_the_maximum_face_in_the_last_cell() {
        let grid = ServedGrid {
            origin_mm: [0.0; 3],
            cell_mm: 10.0,
            cells: [2, 3, 4],
            corners: [0, 1, 3, 4, 12, 13, 15, 16],
            first_any: 0,
            with_configs: false,
        };
        let (base, f) = grid.locate([20.0, 30.0, 40.0]).unwrap();
        assert_eq!(f, [1.0; 3]);
        assert_eq!(base, 1 + 3 * (2 + 4 * 3));
        assert!(grid.locate([20.0001, 0.0, 0.0]).is_none());
        assert!(grid.locate([f64::NAN, 0.0, 0.0]).is_none());
    }
}
