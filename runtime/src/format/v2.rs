//! Version 2 of the payload: what a query reads and nothing else.
//!
//! Two tiers answer from it. The **served tier** is the continuous correction field a
//! servo loop takes: the exact method evaluated by the compiler at every node (corner) of
//! the cell grid, blended trilinearly over the 8 nodes of the target's cell; one node set
//! per configuration the samples carry. The **exact tier** is the paper's method to the
//! digit: each cell's candidate list inside its own 64-byte record (one cache line), the
//! samples in a 32-byte query block (actual position and its norm), their errors apart.
//!
//! The archive's fields, in order (the order is the layout: rkyv writes each field's data
//! in declaration order from the payload's first byte, so the cell records start at the
//! payload's offset 0, which is 64-byte aligned in a mapped file):
//!
//! | field | per | bytes | read by |
//! |---|---|---:|---|
//! | `cells` | cell, x fastest | 64 | exact tier: count and up to 31 candidates (`u16`), or where its long list is |
//! | `cells_wide` | cell, when more than 65,535 samples | 64 | as `cells`, 15 candidates (`u32`) |
//! | `overflow` | long-list entry | 4 | exact tier, for lists longer than a record holds |
//! | `samples` | sample | 32 | exact tier: actual position and its norm |
//! | `errors_mm` | sample | 24 | exact tier: position errors weighted |
//! | `orientation_errors_rad` | sample, with orientation | 24 | exact tier |
//! | `configs` | sample, with configurations | 1 | exact tier: configuration screen |
//! | `joints_rad` | sample × joint, with a joint screen | 8 | exact tier: joint screen |
//! | `node_sets` | configuration | 8 | served tier: which nodes serve a target configuration |
//! | `node_errors_mm` | node × set | 24 | served tier |
//! | `node_orientation_errors_rad` | node × set, with orientation | 24 | served tier |
//! | `model` | table, hybrid | — | both tiers: the model part at the target's joints |
//!
//! Nothing else is stored: base weights, nominal positions and the samples' joint angles
//! (without a joint screen) are read by no query, and `explain` recomputes what it shows.

use rkyv::{Archive, Deserialize, Serialize};

use super::{rows_of, transform_of};
use crate::chain::{Chain, ChainError, ChainJoint, Compliance, JointKind, MAX_JOINTS};

/// Candidates a narrow cell record holds inline; longer lists go to `overflow`.
pub const INLINE_CANDIDATES: usize = 31;
/// Candidates a wide cell record (tables of more than 65,535 samples) holds inline.
pub const INLINE_CANDIDATES_WIDE: usize = 15;
/// The most samples a table with narrow (`u16`) cell records may have.
pub const NARROW_SAMPLES: usize = u16::MAX as usize;

/// A narrow cell record: `[count, candidates…]`. With `count ≤ 31` the candidates (sample
/// indices, nearest the cell's centre first) are slots 1..=count; with more, slots 1 and 2
/// hold the list's start in `overflow` (low and high 16 bits). Unused slots are zero.
pub type CellRecord = [u16; 32];

/// A wide cell record: `[count, candidates…]` as [`CellRecord`], 15 candidates inline, or
/// the list's start in `overflow` in slot 1.
pub type WideCellRecord = [u32; 16];

/// Node errors the method could not give (no admissible sample at the node): every
/// component of every vector of the node is this NaN. A cell with such a node is not
/// served.
pub const NO_NODE_VALUE: f64 = f64::NAN;

/// What an exact query reads of a sample to select and weigh it.
#[derive(Archive, Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[rkyv(derive(Debug))]
pub struct QuerySample {
    /// Actual position = nominal + measured error (a hybrid table's: + residual), mm.
    pub actual_mm: [f64; 3],
    /// `|actual_mm|`, as [`crate::method::norm_mm`] computes it.
    pub norm_mm: f64,
}

/// The nodes serving targets of one configuration.
#[derive(Archive, Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[rkyv(derive(Debug))]
pub struct NodeSet {
    /// The target configuration served, or [`crate::method::CONFIG_UNKNOWN`] for targets
    /// of unknown configuration (every sample admissible). The first set is always that.
    pub config: u8,
    /// Its first node in `node_errors_mm`, counted in nodes (its first vector is
    /// `first_node · stride`): sets whose values are identical share nodes.
    pub first_node: u32,
}

/// One joint of a stored chain ([`crate::chain::ChainJoint`]).
#[derive(Archive, Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[rkyv(derive(Debug))]
pub struct JointRecord {
    /// The joint's origin in its parent's frame, rows then translation (mm).
    pub origin: [f64; 12],
    /// The axis, a unit vector in the joint frame.
    pub axis: [f64; 3],
    /// 0 revolute, 1 prismatic.
    pub kind: u8,
    /// Added to the joint variable, rad (mm when prismatic).
    pub offset: f64,
}

/// Gravity compliance of a stored chain ([`crate::chain::Compliance`]), per joint arrays
/// of the chain's joint count.
#[derive(Archive, Serialize, Deserialize, Clone, Debug, PartialEq)]
#[rkyv(derive(Debug))]
pub struct ComplianceRecord {
    /// Gravity in the base frame, mm/s².
    pub gravity_mm_s2: [f64; 3],
    /// Link masses, kg.
    pub link_mass_kg: Vec<f64>,
    /// Link centres of mass in their joint frames, mm.
    pub link_com_mm: Vec<[f64; 3]>,
    /// Payload mass, kg.
    pub payload_kg: f64,
    /// Payload centre of mass in the tool frame, mm.
    pub payload_com_mm: [f64; 3],
    /// Compliance per joint, rad/(kg·mm²/s²).
    pub compliance: Vec<f64>,
}

/// A stored serial chain ([`crate::chain::Chain`]).
#[derive(Archive, Serialize, Deserialize, Clone, Debug, PartialEq)]
#[rkyv(derive(Debug))]
pub struct ChainRecord {
    /// The base in the measurement frame, rows then translation (mm).
    pub base: [f64; 12],
    /// The joints, base to tool.
    pub joints: Vec<JointRecord>,
    /// The tool centre point in the last joint's frame.
    pub tool: [f64; 12],
    /// Gravity compliance, when modelled.
    pub compliance: Option<ComplianceRecord>,
}

/// A hybrid table's model: the chain the controller commands with, and the calibrated one.
#[derive(Archive, Serialize, Deserialize, Clone, Debug, PartialEq)]
#[rkyv(derive(Debug))]
pub struct ModelRecord {
    /// The nominal chain.
    pub nominal: ChainRecord,
    /// The identified chain (with compliance when identified).
    pub calibrated: ChainRecord,
}

/// The archived payload of a version-2 table (module docs).
#[derive(Archive, Serialize, Deserialize, Clone, Debug, Default, PartialEq)]
#[rkyv(derive(Debug))]
pub struct TableData {
    /// Narrow cell records, one per cell (empty for wide tables).
    pub cells: Vec<CellRecord>,
    /// Wide cell records, one per cell (empty for narrow tables).
    pub cells_wide: Vec<WideCellRecord>,
    /// The candidate lists too long for their records, concatenated.
    pub overflow: Vec<u32>,
    /// The samples' query block, in source order: a sample's index is its position here.
    pub samples: Vec<QuerySample>,
    /// Each sample's position error (a hybrid table's: residual), mm, base frame.
    pub errors_mm: Vec<[f64; 3]>,
    /// Each sample's orientation error, rotation vector, rad, base frame; empty without.
    pub orientation_errors_rad: Vec<[f64; 3]>,
    /// Each sample's configuration; empty without.
    pub configs: Vec<u8>,
    /// Each sample's joint values, row after row (the header's joint count per row); only
    /// with a joint screen, empty otherwise.
    pub joints_rad: Vec<f64>,
    /// The served tier's node sets; empty for a table without one (a joint screen).
    pub node_sets: Vec<NodeSet>,
    /// Node errors, mm: set after set, each `(nx + 1)(ny + 1)(nz + 1)` nodes, x fastest.
    ///
    /// Each node holds [`ServedField::node_stride`](super::ServedField::node_stride)
    /// consecutive vectors: one, the error, or for
    /// [`ServedField::KrigingToolAxis`](super::ServedField::KrigingToolAxis) four, `f,
    /// h_x, h_y, h_z`, the error being `f + a_x h_x + a_y h_y + a_z h_z` for the nominal
    /// TCP's approach axis `a`. Node `n` of a set (counted in nodes, as
    /// [`NodeSet::first_node`] is) is then vectors `(first_node + n) · stride + t`,
    /// `t < stride`: a node's terms are adjacent, so a cell's corners stay one block. A
    /// node without a value holds [`NO_NODE_VALUE`] in all of its vectors.
    pub node_errors_mm: Vec<[f64; 3]>,
    /// Node orientation errors, rad, laid out as `node_errors_mm` (the same stride and
    /// terms); empty without orientation.
    pub node_orientation_errors_rad: Vec<[f64; 3]>,
    /// A hybrid table's model.
    pub model: Option<ModelRecord>,
}

impl TableData {
    /// About the bytes its archive takes: its arrays' (the archive stores them as they
    /// are in memory) and room for the rest. A hint for the encoder's buffer, so that a
    /// table of tens of megabytes is written once rather than regrown as it is written.
    pub fn archived_len_hint(&self) -> usize {
        use std::mem::size_of_val;
        [
            size_of_val(self.cells.as_slice()),
            size_of_val(self.cells_wide.as_slice()),
            size_of_val(self.overflow.as_slice()),
            size_of_val(self.samples.as_slice()),
            size_of_val(self.errors_mm.as_slice()),
            size_of_val(self.orientation_errors_rad.as_slice()),
            size_of_val(self.configs.as_slice()),
            size_of_val(self.joints_rad.as_slice()),
            size_of_val(self.node_sets.as_slice()),
            size_of_val(self.node_errors_mm.as_slice()),
            size_of_val(self.node_orientation_errors_rad.as_slice()),
            64 * 1024,
        ]
        .iter()
        .fold(0usize, |sum, n| sum.saturating_add(*n))
    }
}

// Layout conversions: the one place where a stored chain becomes the runtime's `Chain`
// and back.

impl ChainRecord {
    /// The stored form of `chain`.
    pub fn from_chain(chain: &Chain) -> ChainRecord {
        let n = chain.joint_count();
        ChainRecord {
            base: rows_of(&chain.base),
            joints: chain
                .joints()
                .iter()
                .map(|j| JointRecord {
                    origin: rows_of(&j.origin),
                    axis: j.axis,
                    kind: j.kind as u8,
                    offset: j.offset,
                })
                .collect(),
            tool: rows_of(&chain.tool),
            compliance: chain.compliance.map(|c| ComplianceRecord {
                gravity_mm_s2: c.gravity_mm_s2,
                link_mass_kg: c.link_mass_kg[..n].to_vec(),
                link_com_mm: c.link_com_mm[..n].to_vec(),
                payload_kg: c.payload_kg,
                payload_com_mm: c.payload_com_mm,
                compliance: c.compliance[..n].to_vec(),
            }),
        }
    }
}

impl ArchivedChainRecord {
    /// The chain this record stores, checked ([`Chain::new`]).
    ///
    /// # Errors
    ///
    /// [`ChainError`] for a joint count out of range, a per-joint array of another
    /// length, an unknown joint kind, non-finite values or an invalid transform or axis.
    pub fn to_chain(&self) -> Result<Chain, ChainError> {
        let n = self.joints.len();
        if n == 0 || n > MAX_JOINTS {
            return Err(ChainError::JointCount(n));
        }
        let three = |a: &rkyv::Archived<[f64; 3]>| a.map(|v| v.to_native());
        let twelve = |a: &rkyv::Archived<[f64; 12]>| a.map(|v| v.to_native());
        let mut joints = [ChainJoint::default(); MAX_JOINTS];
        for (out, j) in joints.iter_mut().zip(self.joints.iter()) {
            *out = ChainJoint {
                origin: transform_of(&twelve(&j.origin)),
                axis: three(&j.axis),
                kind: match j.kind {
                    0 => JointKind::Revolute,
                    1 => JointKind::Prismatic,
                    _ => return Err(ChainError::Invalid("unknown joint kind")),
                },
                offset: j.offset.to_native(),
            };
        }
        let compliance = match self.compliance.as_ref() {
            None => None,
            Some(c) => {
                let lengths = [
                    c.link_mass_kg.len(),
                    c.link_com_mm.len(),
                    c.compliance.len(),
                ];
                if lengths.iter().any(|&len| len != n) {
                    return Err(ChainError::Invalid(
                        "compliance arrays do not have one entry per joint",
                    ));
                }
                let mut out = Compliance::NONE;
                out.gravity_mm_s2 = three(&c.gravity_mm_s2);
                out.payload_kg = c.payload_kg.to_native();
                out.payload_com_mm = three(&c.payload_com_mm);
                for j in 0..n {
                    out.link_mass_kg[j] = c.link_mass_kg[j].to_native();
                    out.link_com_mm[j] = three(&c.link_com_mm[j]);
                    out.compliance[j] = c.compliance[j].to_native();
                }
                Some(out)
            }
        };
        Chain::new(
            transform_of(&twelve(&self.base)),
            &joints[..n],
            transform_of(&twelve(&self.tool)),
            compliance,
        )
    }
}
