//! What a table holds, for `tablec inspect`: counts, coverage and the size of every
//! section, of either format version, and one cell in detail.

use adwi_runtime::format::v2;
use adwi_runtime::{Payload, Table};

/// A table's contents in figures.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Cells in the grid.
    pub cells: usize,
    /// Cells with at least one candidate.
    pub covered: usize,
    /// Mean candidates per covered cell.
    pub mean_candidates: f64,
    /// The longest candidate list.
    pub max_candidates: usize,
    /// Cells whose list is stored apart (version 2: longer than a record holds; version 1:
    /// every list, shared by cells with identical lists — this counts distinct lists).
    pub lists_apart: usize,
    /// Cells the served field covers (all 8 nodes answered, first node set); `None`
    /// without a served tier.
    pub served_cells: Option<usize>,
    /// The node sets' configurations (`255`: targets of unknown configuration).
    pub node_sets: Vec<u8>,
    /// Each section of the payload and its bytes, in file order.
    pub sections: Vec<(&'static str, usize)>,
}

/// One cell in detail.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CellDetail {
    /// The cell's linear index and `(ix, iy, iz)`.
    pub index: usize,
    /// Its coordinates.
    pub coords: [usize; 3],
    /// Its candidates, as stored.
    pub candidates: Vec<u32>,
    /// The position errors at its 8 nodes (first node set), x fastest; `None` where the
    /// method has no value, or without a served tier.
    pub nodes_mm: Vec<Option<[f64; 3]>>,
}

/// The figures of `table`; `None` if its bytes changed after validation.
pub fn summary<D: AsRef<[u8]>>(table: &Table<D>) -> Option<Summary> {
    let size = std::mem::size_of::<f64>();
    Some(match table.payload()? {
        Payload::V1(d) => {
            let lengths: Vec<usize> = d
                .cells
                .iter()
                .map(|c| c.list_len.to_native() as usize)
                .collect();
            let distinct: std::collections::HashSet<(u32, u32)> = d
                .cells
                .iter()
                .map(|c| (c.list_start.to_native(), c.list_len.to_native()))
                .collect();
            let (covered, mean, max) = list_figures(&lengths);
            Summary {
                cells: d.cells.len(),
                covered,
                mean_candidates: mean,
                max_candidates: max,
                lists_apart: distinct.len(),
                served_cells: None,
                node_sets: Vec::new(),
                sections: vec![
                    (
                        "samples",
                        d.samples.len()
                            * std::mem::size_of::<adwi_runtime::format::ArchivedSampleRecord>(),
                    ),
                    ("sample norms", d.actual_norms_mm.len() * size),
                    ("cell records", d.cells.len() * 8),
                    ("candidate lists", d.list_samples.len() * 4),
                    (
                        "base weights",
                        d.centre_offsets.len() * 4 + d.centre_samples.len() * 12,
                    ),
                    ("joint values", d.joints_rad.len() * 6 * size),
                ],
            }
        }
        Payload::V2(d) => {
            let narrow = d.cells.iter().map(|r| r[0].to_native() as usize);
            let wide = d.cells_wide.iter().map(|r| r[0].to_native() as usize);
            let lengths: Vec<usize> = narrow.chain(wide).collect();
            let (covered, mean, max) = list_figures(&lengths);
            let inline = if d.cells.is_empty() {
                v2::INLINE_CANDIDATES_WIDE
            } else {
                v2::INLINE_CANDIDATES
            };
            let served_cells = (!d.node_sets.is_empty()).then(|| {
                (0..lengths.len())
                    .filter(|&cell| corner_values(table, d, cell).iter().all(Option::is_some))
                    .count()
            });
            Summary {
                cells: lengths.len(),
                covered,
                mean_candidates: mean,
                max_candidates: max,
                lists_apart: lengths.iter().filter(|&&n| n > inline).count(),
                served_cells,
                node_sets: d.node_sets.iter().map(|s| s.config).collect(),
                sections: vec![
                    ("cell records", (d.cells.len() + d.cells_wide.len()) * 64),
                    ("long lists", d.overflow.len() * 4),
                    ("sample query block", d.samples.len() * 32),
                    ("sample errors", d.errors_mm.len() * 3 * size),
                    (
                        "sample orientation errors",
                        d.orientation_errors_rad.len() * 3 * size,
                    ),
                    ("sample configurations", d.configs.len()),
                    ("sample joint values", d.joints_rad.len() * size),
                    ("node errors", d.node_errors_mm.len() * 3 * size),
                    (
                        "node orientation errors",
                        d.node_orientation_errors_rad.len() * 3 * size,
                    ),
                ],
            }
        }
    })
    .map(|mut s: Summary| {
        s.sections.retain(|&(_, bytes)| bytes > 0);
        s
    })
}

/// The cell holding `position_mm`, in detail; `None` outside the grid or if the bytes
/// changed.
pub fn cell<D: AsRef<[u8]>>(table: &Table<D>, position_mm: [f64; 3]) -> Option<CellDetail> {
    let grid = table.grid();
    let index = grid.cell_of(position_mm)?;
    let (candidates, nodes_mm) = match table.payload()? {
        Payload::V1(d) => {
            let c = d.cells.get(index)?;
            let start = c.list_start.to_native() as usize;
            let list = d
                .list_samples
                .get(start..start + c.list_len.to_native() as usize)?;
            (list.iter().map(|i| i.to_native()).collect(), Vec::new())
        }
        Payload::V2(d) => {
            let candidates = if let Some(r) = d.cells.get(index) {
                let n = r[0].to_native() as usize;
                if n <= v2::INLINE_CANDIDATES {
                    r[1..=n].iter().map(|i| u32::from(i.to_native())).collect()
                } else {
                    let start = r[1].to_native() as usize | (r[2].to_native() as usize) << 16;
                    d.overflow
                        .get(start..start + n)?
                        .iter()
                        .map(|i| i.to_native())
                        .collect()
                }
            } else {
                let r = d.cells_wide.get(index)?;
                let n = r[0].to_native() as usize;
                if n <= v2::INLINE_CANDIDATES_WIDE {
                    r[1..=n].iter().map(|i| i.to_native()).collect()
                } else {
                    let start = r[1].to_native() as usize;
                    d.overflow
                        .get(start..start + n)?
                        .iter()
                        .map(|i| i.to_native())
                        .collect()
                }
            };
            (candidates, corner_values(table, d, index))
        }
    };
    Some(CellDetail {
        index,
        coords: grid.cell_coords(index),
        candidates,
        nodes_mm,
    })
}

/// The position errors at a cell's 8 nodes in the first node set (empty without one).
fn corner_values<D: AsRef<[u8]>>(
    table: &Table<D>,
    data: &v2::ArchivedTableData,
    cell: usize,
) -> Vec<Option<[f64; 3]>> {
    if data.node_sets.is_empty() {
        return Vec::new();
    }
    let grid = table.grid();
    let [i, j, k] = grid.cell_coords(cell);
    let mut out = Vec::with_capacity(8);
    for (dk, dj, di) in [
        (0, 0, 0),
        (0, 0, 1),
        (0, 1, 0),
        (0, 1, 1),
        (1, 0, 0),
        (1, 0, 1),
        (1, 1, 0),
        (1, 1, 1),
    ] {
        let value = adwi_runtime::served::node(table.header(), data, 0, [i + di, j + dj, k + dk])
            .map(|(p, _)| p)
            .filter(|p| !adwi_runtime::served::is_missing(p));
        out.push(value);
    }
    out
}

/// Covered cells, their mean and the longest list.
fn list_figures(lengths: &[usize]) -> (usize, f64, usize) {
    let covered: Vec<usize> = lengths.iter().copied().filter(|&n| n > 0).collect();
    let mean = covered.iter().sum::<usize>() as f64 / covered.len().max(1) as f64;
    (
        covered.len(),
        mean,
        covered.iter().max().copied().unwrap_or(0),
    )
}
