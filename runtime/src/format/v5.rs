//! The joint record's payload, of versions 5 and 6: a hybrid table's calibrated model's
//! joint-space terms ([`crate::joint_terms`]) and the angles its samples span.
//!
//! Version 5 was written for a hybrid table whose model has terms (a table without was
//! version 2 to 4), and its ranges hold the terms alone. Version 6 is written for every
//! hybrid table (its terms zero when it has none), and its ranges also bound the residual:
//! beyond them it fades to zero ([`crate::joint_terms::RESIDUAL_FADE_RAD`]). Content flag
//! [`CONTENT_JOINT_TERMS`](super::CONTENT_JOINT_TERMS) in both. The version-2 part comes
//! first, archived unchanged, then the posture term (empty, and never read, without the
//! content flag [`CONTENT_POSTURE`](super::CONTENT_POSTURE)), then the record.
//!
//! | field | per | bytes | read by |
//! |---|---|---:|---|
//! | `base` | table | — | everything a version-2 table holds, read as one ([`super::v2`]) |
//! | `posture` | table | — | a posture term, as version 3 holds it ([`super::v3`]) |
//! | `joint_terms.coefficients_rad` | joint | 32 | both tiers: the calibrated chain's joint-space terms `[a1, b1, a2, b2]`, rad |
//! | `joint_terms.range_rad` | joint | 16 | both tiers: the commanded angles the samples span, `[lowest, highest]`, rad (a revolute joint's; unbounded, `[−∞, +∞]`, for a prismatic one in version 6): the terms are held beyond them; in version 6 the residual fades |

use rkyv::{Archive, Deserialize, Serialize};

use super::{v2, v3};
use crate::joint_terms::{JointTerms, COEFFICIENTS_PER_JOINT};

/// The archived payload of a version-5 table (module docs).
#[derive(Archive, Serialize, Deserialize, Clone, Debug, Default, PartialEq)]
#[rkyv(derive(Debug))]
pub struct TableData {
    /// The version-2 payload, unchanged.
    pub base: v2::TableData,
    /// The posture term, when the content flags say so; empty otherwise.
    pub posture: v3::PostureRecord,
    /// The calibrated chain's joint-space terms.
    pub joint_terms: JointTermsRecord,
}

/// A calibrated chain's joint-space terms ([`JointTerms`]): one row per joint of the
/// model.
#[derive(Archive, Serialize, Deserialize, Clone, Debug, Default, PartialEq)]
#[rkyv(derive(Debug))]
pub struct JointTermsRecord {
    /// Per joint `[a1, b1, a2, b2]`, rad ([`crate::joint_terms`]).
    pub coefficients_rad: Vec<[f64; COEFFICIENTS_PER_JOINT]>,
    /// Per joint the commanded angles the samples span (the terms were identified over
    /// them), `[lowest, highest]`, rad: beyond them a term is held at the end nearer around
    /// the circle ([`crate::joint_terms::beyond_range`]), and in version 6 the residual
    /// fades.
    pub range_rad: Vec<[f64; 2]>,
}

impl JointTermsRecord {
    /// The stored form of the first `joints` joints' terms.
    pub fn from_terms(terms: &JointTerms, joints: usize) -> JointTermsRecord {
        let n = joints.min(terms.coefficients_rad.len());
        JointTermsRecord {
            coefficients_rad: terms.coefficients_rad[..n].to_vec(),
            range_rad: terms.range_rad[..n].to_vec(),
        }
    }
}

impl ArchivedJointTermsRecord {
    /// The terms this record stores; `None` for more rows than
    /// [`crate::chain::MAX_JOINTS`] or a range per joint missing. Their values are checked against the chain by
    /// [`crate::model::PreparedModel::with_joint_terms`].
    pub fn to_terms(&self) -> Option<JointTerms> {
        let mut rows = [[0.0; COEFFICIENTS_PER_JOINT]; crate::chain::MAX_JOINTS];
        let stored = rows.get_mut(..self.coefficients_rad.len())?;
        for (out, row) in stored.iter_mut().zip(self.coefficients_rad.iter()) {
            *out = row.map(|v| v.to_native());
        }
        if self.range_rad.len() != self.coefficients_rad.len() {
            return None;
        }
        let mut terms = JointTerms::new(&rows)?;
        for (out, range) in terms.range_rad.iter_mut().zip(self.range_rad.iter()) {
            *out = range.map(|v| v.to_native());
        }
        Some(terms)
    }
}
