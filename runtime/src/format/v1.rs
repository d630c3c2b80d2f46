//! Version 1 of the payload: deduplicated candidate lists behind 8-byte cell records, the
//! base weights at every cell's centre, and a six-joint MD-H model. Read forever (answered
//! by the exact tier), no longer written.

use rkyv::{Archive, Deserialize, Serialize};

use super::SampleRecord;
use crate::kinematics::{MdhJoint, Transform};

/// One cell: where its candidate list is. Eight bytes, so that the cell records a query
/// touches stay dense in cache.
#[derive(Archive, Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[rkyv(derive(Debug))]
pub struct CellRecord {
    /// The candidate list is `list_samples[list_start .. list_start + list_len]`; cells with
    /// identical lists share one range.
    pub list_start: u32,
    /// The candidate list's length.
    pub list_len: u32,
}

/// The archived payload.
#[derive(Archive, Serialize, Deserialize, Clone, Debug, PartialEq)]
#[rkyv(derive(Debug))]
pub struct TableData {
    /// The samples, in source order: a sample's index is its position here.
    pub samples: Vec<SampleRecord>,
    /// `|actual_mm|` of each sample, mm, computed as the method computes it, so that a
    /// query need not take the square root again.
    pub actual_norms_mm: Vec<f64>,
    /// The cells, linear index `ix + nx · (iy + ny · iz)`. One record per cell, so that a
    /// query reads its list's range in a single access.
    pub cells: Vec<CellRecord>,
    /// Cell `c`'s base weights are entries `centre_offsets[c] .. centre_offsets[c + 1]` of
    /// `centre_samples` and `centre_weights` (kept apart from `cells`: queries never read
    /// them).
    pub centre_offsets: Vec<u32>,
    /// Concatenated distinct candidate lists: sample indices, each list ordered by distance
    /// to its cell's centre (ties by index), so that a query meets the likely neighbours
    /// first and ranks the rest with few moves. No sample appears twice in a list.
    pub list_samples: Vec<u32>,
    /// The neighbours selected at each cell's centre, nearest first.
    pub centre_samples: Vec<u32>,
    /// Their weights `q_i` (summing to 1 per cell with neighbours).
    pub centre_weights: Vec<f64>,
    /// Joint angles of each sample, rad, in sample order; empty when the samples carry
    /// none ([`super::CONTENT_JOINTS`]).
    pub joints_rad: Vec<[f64; 6]>,
    /// The kinematic model of a hybrid table ([`super::CONTENT_MODEL`]): the sample errors are
    /// then the residuals that the calibrated model leaves, and a correction adds the
    /// model's prediction at the target's joint angles.
    pub model: Option<KinematicModel>,
}

/// A 6-axis robot's kinematic parameters, as plain arrays.
#[derive(Archive, Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[rkyv(derive(Debug))]
pub struct ModelParams {
    /// Per joint, the MD-H parameters `[a (mm), d (mm), α (rad), β (rad), θ offset (rad)]`.
    pub joints: [[f64; 5]; 6],
    /// Flange to tool centre point: rotation rows then translation, `[r00, r01, r02, t0,
    /// r10, r11, r12, t1, r20, r21, r22, t2]` (mm).
    pub tool: [f64; 12],
    /// Robot base in the measurement (world) frame, same layout as `tool`.
    pub base: [f64; 12],
}

/// The nominal model the controller commands with, and the calibrated model that
/// predicts where the robot really goes.
#[derive(Archive, Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[rkyv(derive(Debug))]
pub struct KinematicModel {
    /// The controller's nominal parameters.
    pub nominal: ModelParams,
    /// The identified parameters.
    pub calibrated: ModelParams,
}

/// The number of joints of a model in a table.
pub const JOINT_COUNT: usize = 6;

// Layout conversions: the one place where the file's plain arrays become the runtime's
// kinematic types and back.
/// The rigid transform of a table's 12-value layout: rotation rows then translation,
/// `[r00, r01, r02, t0, r10, r11, r12, t1, r20, r21, r22, t2]` (mm).
#[inline]
pub fn transform_of(rows: &[f64; 12]) -> Transform {
    Transform {
        rotation: [
            [rows[0], rows[1], rows[2]],
            [rows[4], rows[5], rows[6]],
            [rows[8], rows[9], rows[10]],
        ],
        translation_mm: [rows[3], rows[7], rows[11]],
    }
}

/// A transform in the table's 12-value layout (the inverse of [`transform_of`]).
pub fn rows_of(transform: &Transform) -> [f64; 12] {
    let r = &transform.rotation;
    let t = transform.translation_mm;
    [
        r[0][0], r[0][1], r[0][2], t[0], r[1][0], r[1][1], r[1][2], t[1], r[2][0], r[2][1],
        r[2][2], t[2],
    ]
}

/// The joints of a model in the table's layout `[a (mm), d (mm), α, β, θ offset (rad)]`.
#[inline]
pub fn joint_rows_to_mdh(rows: &[[f64; 5]; JOINT_COUNT]) -> [MdhJoint; JOINT_COUNT] {
    rows.map(
        |[a_mm, d_mm, alpha_rad, beta_rad, theta_offset_rad]| MdhJoint {
            a_mm,
            d_mm,
            alpha_rad,
            beta_rad,
            theta_offset_rad,
        },
    )
}

/// The table layout of MD-H joints (the inverse of [`joint_rows_to_mdh`]).
pub fn joint_rows(joints: &[MdhJoint; JOINT_COUNT]) -> [[f64; 5]; JOINT_COUNT] {
    joints.map(|j| [j.a_mm, j.d_mm, j.alpha_rad, j.beta_rad, j.theta_offset_rad])
}
