//! Version 3 of the payload: a version-2 payload and a hybrid table's posture term
//! ([`crate::posture`]).
//!
//! Written only for a table that carries the term (content flag
//! [`CONTENT_POSTURE`](super::CONTENT_POSTURE)); a table without one is written as version
//! 2, byte for byte as before. The version-2 part comes first and is archived unchanged,
//! so its cell records still open the payload on a cache line and every reader of a
//! version-2 payload reads it as one.
//!
//! | field | per | bytes | read by |
//! |---|---|---:|---|
//! | `base` | table | — | everything a version-2 table holds, read as one ([`super::v2`]) |
//! | `posture.cell_offsets` | posture cell + 1 | 4 | served tier: where the cell's list is |
//! | `posture.cell_samples` | list entry | 4 | served tier: the samples whose support reaches the cell, ascending |
//! | `posture.positions_mm` | sample | 24 | served tier: the sample's nominal position |
//! | `posture.joints_rad` | sample × joint | 8 | served tier: the sample's joint values |
//! | `posture.residuals_mm` | sample | 24 | served tier: what the table without the term leaves at the sample |

use rkyv::{Archive, Deserialize, Serialize};

use super::v2;

/// The most entries a posture cell's list may hold: the bound on a query's work (the
/// term's cost is linear in it). The compiler refuses, with the figure, a support radius
/// that would list more.
pub const MAX_POSTURE_CANDIDATES: usize = 512;

/// The archived payload of a version-3 table (module docs).
#[derive(Archive, Serialize, Deserialize, Clone, Debug, Default, PartialEq)]
#[rkyv(derive(Debug))]
pub struct TableData {
    /// The version-2 payload, unchanged.
    pub base: v2::TableData,
    /// The posture term.
    pub posture: PostureRecord,
}

/// A hybrid table's posture term ([`crate::posture`]): its parameters, the samples it
/// weighs and, per cell of its own grid, the samples whose support reaches the cell.
#[derive(Archive, Serialize, Deserialize, Clone, Debug, Default, PartialEq)]
#[rkyv(derive(Debug))]
pub struct PostureRecord {
    /// The spatial support radius `R`, mm: a sample weighs nothing at a target farther.
    pub radius_mm: f64,
    /// The joint-space support length `ℓ_q`, rad: a sample weighs nothing at joint values
    /// whose Euclidean distance from its own exceeds it.
    pub length_rad: f64,
    /// The weight floor `W0`: the term is `Σ w_i r_i / max(Σ w_i, W0)`, so that it fades
    /// to zero where the evidence thins out.
    pub floor: f64,
    /// The posture grid's cell edge, mm: the grid starts at the table grid's origin and
    /// covers its box.
    pub cell_mm: f64,
    /// The posture grid's size in cells along x, y, z.
    pub dims: [u32; 3],
    /// Cell `c`'s list is `cell_samples[cell_offsets[c]..cell_offsets[c + 1]]`; cells x
    /// fastest.
    pub cell_offsets: Vec<u32>,
    /// Concatenated lists of sample indices, each ascending.
    pub cell_samples: Vec<u32>,
    /// Each sample's nominal position, mm, base frame. The term numbers its samples on its
    /// own (the compiler orders them by posture cell, so that a list reads a few ascending
    /// runs of memory); any order is valid.
    pub positions_mm: Vec<[f64; 3]>,
    /// Each sample's joint values, row after row (the header's joint count per row).
    pub joints_rad: Vec<f64>,
    /// Each sample's residual `r_i`: its measured position error minus what the table
    /// without the term answers at its nominal position and joint values, mm.
    pub residuals_mm: Vec<[f64; 3]>,
}
