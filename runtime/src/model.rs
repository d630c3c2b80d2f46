//! The kinematic model of a hybrid table: a calibrated model plus the interpolated
//! residuals it leaves, served by the same allocation-free query path.
//!
//! A *hybrid* table ([`crate::format::CONTENT_MODEL`]) carries two kinematic models of the
//! robot: the nominal one the controller commands with, and the calibrated one that
//! predicts where the robot really goes. Its samples' errors are the *residuals* the
//! calibrated model leaves (measured error minus the model's predicted error at the
//! sample's joint angles). A correction is then
//!
//! ```text
//! position_error_mm     = p_cal(q) − p_nom(q)            + interpolated residual at the target
//! orientation_error_rad = log(R_cal(q) · R_nom(q)ᵀ)        + interpolated residual at the target
//! ```
//!
//! where `q` are the joint angles the controller will command for the target, and
//! `T_cal(q) = B_cal · A_1(q_1) ⋯ A_6(q_6) · T_tool,cal`, `T_nom(q)` likewise with the
//! nominal parameters (the pose errors are in the base frame, as the samples record them).
//! The model part is a function of the joint angles, which a position alone does not
//! determine (one position has up to eight inverse-kinematics solutions and any tool
//! orientation), so a hybrid table must be queried with the joint angles:
//! [`crate::Table::query_with_joints`]. Queried by position alone
//! ([`crate::Table::query_target`]) it answers [`crate::Status::MissingJoints`] rather than
//! a residual that is not the error.
//!
//! The same joint angles drive the optional joint-space admissibility screen
//! ([`crate::format::Header::joint_radius_rad`]): a sample is admissible only if each of its
//! joint angles is within the radius of the target's ([`crate::method::joints_within`]). Samples close in
//! Cartesian space but reached with a very different arm posture (another wrist angle, say)
//! then stop standing in for the target, which is the method's own remark that "close"
//! means close joint angles. Position-only tables may use the screen too, when built from
//! samples with joint angles.
//!
//! This module evaluates the model part: everything here is allocation-free and panic-free.
//! A query's costs, on top of the ordinary query ([`crate::Table::query_with_joints`]): one
//! sine and cosine per joint, shared by both chains, two joints at a time
//! ([`crate::trig::sin_cos_each`]); then, when the calibrated chain has no gravity
//! compliance, one walk of both chains together from the tool back to the base, the TCP's
//! point, approach axis and x axis a joint (`ReachPair::walk_posed` in [`crate::chain`]),
//! and the orientation error from the two frames' columns by asin's series (every hybrid
//! answer carries it; [`PreparedModel::at_position`] walks the point and the approach axis
//! alone). With joint-space terms the walk is the same, the calibrated lane turned at `q'`
//! (its sines and cosines from `q`'s by angle addition, [`crate::joint_terms`]). Otherwise
//! (gravity compliance) one pass down each chain, folded at open (constant parts multiplied
//! out: `FoldedChain` in [`crate::chain`]), the gravity deflection by turning the calibrated
//! TCP about each joint's axis, and a 3 × 3 logarithm.
//! [`PreparedModel::error`] and the others evaluate the chains joint by joint, as the
//! compiler fits the residuals with them; the query path is held to them to 4e-12 mm
//! (joints within half a turn of zero; beyond, the chains' own rounding of each angle
//! before its `sin_cos` adds a few 1e-13 mm per joint).

use crate::chain::{Chain, FoldedChain, ReachPair, MAX_JOINTS};
use crate::format::v1::{ArchivedKinematicModel, ArchivedModelParams, ArchivedTableData};
use crate::format::{joint_rows_to_mdh, transform_of, KinematicModel, ModelParams, JOINT_COUNT};
use crate::joint_terms::{JointTerms, PreparedTerms};
use crate::kinematics::{pose_error, Transform};

/// The tool centre point's pose in the measurement (world) frame at joint angles `q_rad`:
/// `base · A_1(q_1) ⋯ A_6(q_6) · tool`, for a version-1 model's parameters.
pub fn tcp_pose(params: &ModelParams, q_rad: &[f64; JOINT_COUNT]) -> Transform {
    mdh_chain(params)
        .tcp_pose(q_rad)
        .unwrap_or(Transform::IDENTITY)
}

/// The pose error a version-1 kinematic model predicts at joint angles `q_rad`: the
/// calibrated TCP against the nominal one (see [`PreparedModel::error`]).
pub fn model_error(model: &KinematicModel, q_rad: &[f64; JOINT_COUNT]) -> ([f64; 3], [f64; 3]) {
    PreparedModel::from_mdh(model)
        .error(q_rad)
        .unwrap_or(([0.0; 3], [0.0; 3]))
}

/// A version-1 model's MD-H parameters as a chain (six joints, finite by validation: an
/// invalid one becomes a chain of one still joint, which validation never lets through).
fn mdh_chain(params: &ModelParams) -> Chain {
    Chain::from_mdh(
        transform_of(&params.base),
        &joint_rows_to_mdh(&params.joints),
        transform_of(&params.tool),
        None,
    )
    .unwrap_or_else(|_| still_chain())
}

/// One joint at rest, the identity everywhere: a placeholder that cannot fail.
fn still_chain() -> Chain {
    Chain::new(
        Transform::IDENTITY,
        &[crate::chain::ChainJoint::default()],
        Transform::IDENTITY,
        None,
    )
    .expect("the identity chain is valid")
}

/// A hybrid table's model ready for queries: the chain the controller commands with and
/// the calibrated one that predicts where the robot really goes (with its gravity
/// compliance, when identified).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreparedModel {
    nominal: Chain,
    calibrated: Chain,
    /// Both chains folded for queries ([`PreparedModel::at`]).
    folded: [FoldedChain; 2],
    /// Both chains walked together, when they have that form
    /// ([`PreparedModel::at_position`]); with joint-space terms each at its own angles.
    pair: Option<ReachPair>,
    /// The calibrated chain's joint-space terms ([`crate::joint_terms`]): it stands at
    /// `q'` of the commanded `q`.
    terms: JointTerms,
    /// Whether any term is not zero.
    has_terms: bool,
    /// `terms` for the query path.
    prepared_terms: PreparedTerms,
    /// Whether the terms' ranges, the angles the samples span, bound the residual
    /// ([`PreparedModel::residual_scale`]).
    bounds_residual: bool,
}

impl PreparedModel {
    /// The model of two chains of equal joint counts; `None` otherwise.
    pub fn new(nominal: Chain, calibrated: Chain) -> Option<PreparedModel> {
        (nominal.joint_count() == calibrated.joint_count())
            .then(|| PreparedModel::prepared(nominal, calibrated))
    }

    /// A version-1 model (six MD-H joints, tool and base as 12-value rows).
    pub fn from_mdh(model: &KinematicModel) -> PreparedModel {
        let (nominal, calibrated) = (mdh_chain(&model.nominal), mdh_chain(&model.calibrated));
        PreparedModel::prepared(nominal, calibrated)
    }

    /// The chains with their query forms.
    fn prepared(nominal: Chain, calibrated: Chain) -> PreparedModel {
        let folded = [FoldedChain::new(&nominal), FoldedChain::new(&calibrated)];
        PreparedModel {
            nominal,
            calibrated,
            pair: ReachPair::new(&folded[0], &folded[1]),
            folded,
            terms: JointTerms::NONE,
            prepared_terms: PreparedTerms::new(&JointTerms::NONE),
            has_terms: false,
            bounds_residual: false,
        }
    }

    /// How many lanes wide this processor walks the model's chains for a query with the
    /// orientation (every hybrid query): 4 on x86-64 with AVX2, 2 where both chains walk
    /// together otherwise (SSE2, NEON), 1 where they walk apart (a calibrated chain with
    /// gravity compliance, or joints of other kinds). The answers are the same to the bit
    /// at 4 and 2; a benchmark says which it timed.
    pub fn walk_lanes(&self) -> u32 {
        match &self.pair {
            Some(pair) if pair.wide() => 4,
            Some(_) => 2,
            None => 1,
        }
    }

    /// The model with the calibrated chain's joint-space terms ([`crate::joint_terms`]);
    /// `None` when they do not fit its joints ([`JointTerms::check`]).
    pub fn with_joint_terms(mut self, terms: JointTerms) -> Option<PreparedModel> {
        let n = self.calibrated.joint_count();
        let mut kinds = [crate::chain::JointKind::Prismatic; MAX_JOINTS];
        for (k, j) in kinds.iter_mut().zip(self.calibrated.joints()) {
            *k = j.kind;
        }
        terms.check(&kinds[..n]).ok()?;
        self.terms = terms;
        self.prepared_terms = PreparedTerms::new(&terms);
        self.has_terms = !terms.is_none();
        Some(self)
    }

    /// The calibrated chain's joint-space terms ([`JointTerms::NONE`] without).
    pub fn joint_terms(&self) -> &JointTerms {
        &self.terms
    }

    /// The model with its terms' ranges bounding the residual too (a version-6 table: the
    /// ranges are the angles the samples span): [`PreparedModel::residual_scale`].
    pub fn bounding_residual(mut self) -> PreparedModel {
        self.bounds_residual = true;
        self
    }

    /// Whether the terms' ranges bound the residual ([`PreparedModel::residual_scale`]).
    pub fn bounds_residual(&self) -> bool {
        self.bounds_residual
    }

    /// The factor on a hybrid table's residual at commanded `q` (rad, finite, one per
    /// joint): 1 within the angles the samples span, fading to 0
    /// [`crate::joint_terms::RESIDUAL_FADE_RAD`] beyond them; always 1 for a table that
    /// does not record them (before version 6).
    #[inline]
    pub fn residual_scale(&self, q: &[f64]) -> f64 {
        if !self.bounds_residual {
            return 1.0;
        }
        self.prepared_terms.residual_scale(q)
    }

    /// Whether commanded `q` (rad) takes a joint with joint-space terms more than
    /// [`crate::joint_terms::TERMS_MARGIN_RAD`] beyond the angles the terms were
    /// identified over, around the circle ([`crate::joint_terms::beyond_range`]), where
    /// the model holds the term at its range's end rather than knowing it
    /// ([`crate::Evidence::JOINTS`]). `false` without terms.
    #[inline]
    pub fn beyond_terms(&self, q: &[f64]) -> bool {
        self.has_terms && self.prepared_terms.beyond(q)
    }

    /// Where the calibrated chain stands, before gravity, when commanded `q`: `q'` of its
    /// joint-space terms. `None` when `q` does not have one value per joint.
    #[inline]
    fn moved(&self, q: &[f64]) -> Option<[f64; MAX_JOINTS]> {
        if q.len() != self.joint_count() {
            return None;
        }
        self.terms.joints(q)
    }

    /// The chain the controller commands with.
    pub fn nominal(&self) -> &Chain {
        &self.nominal
    }

    /// The identified chain.
    pub fn calibrated(&self) -> &Chain {
        &self.calibrated
    }

    /// A TCP's lever from the measured point in the base frame, `x = R_nom · lever`, from
    /// the model evaluated with its orientation (`at`) and `lever` in the nominal point's
    /// frame (as [`crate::format::PointInFlange::lever_of`] gives it); `None` without the
    /// nominal rotation.
    ///
    /// The TCP is rigid with the measured point: both ride on the flange, so the error at
    /// the TCP is the point's turned by the rotation error `ω` (the answer's: the model's
    /// and the residual's), `e_tcp = e_point + (Exp(ω) − I) · x`
    /// ([`crate::kinematics::rotation_displacement`]). An identified change of the point's
    /// own offset on the flange (the calibrated chain's tool) is taken as the flange's:
    /// the chain's tool also holds the last joint's fixed geometry, so the two cannot be
    /// told apart from the chains.
    #[inline]
    pub fn lever_in_base(&self, at: &ModelAt, lever: [f64; 3]) -> Option<[f64; 3]> {
        let r = at.nominal_rotation?;
        Some([0, 1, 2].map(|i| r[i][0] * lever[0] + r[i][1] * lever[1] + r[i][2] * lever[2]))
    }

    /// The number of joint values a prediction needs.
    pub fn joint_count(&self) -> usize {
        self.nominal.joint_count()
    }

    /// The predicted pose error at joint values `q` (rad; mm for prismatic joints): the
    /// calibrated model's TCP, deflected by gravity when it has compliance, against the
    /// nominal one, as position (mm) and orientation (rotation vector of `R_cal · R_nomᵀ`,
    /// rad), base frame. `None` when `q` does not have one value per joint.
    #[inline]
    pub fn error(&self, q: &[f64]) -> Option<([f64; 3], [f64; 3])> {
        let nominal = self.nominal.tcp_pose(q)?;
        let moved = self.moved(q)?;
        let calibrated = self.calibrated.loaded_tcp_pose(&moved[..q.len()])?;
        Some(pose_error(&nominal, &calibrated))
    }

    /// [`PreparedModel::error`] and the nominal TCP's approach axis at `q`: the z column of
    /// its rotation, a unit vector in the base frame. One forward kinematics of the
    /// nominal chain gives both, for the served field that turns with the tool
    /// ([`crate::format::ServedField::KrigingToolAxis`]). Returns `(position_mm,
    /// rotation_rad, approach)`; `None` as `error`.
    #[inline]
    pub fn error_with_approach(&self, q: &[f64]) -> Option<([f64; 3], [f64; 3], [f64; 3])> {
        let nominal = self.nominal.tcp_pose(q)?;
        let moved = self.moved(q)?;
        let calibrated = self.calibrated.loaded_tcp_pose(&moved[..q.len()])?;
        let (position_mm, rotation_rad) = pose_error(&nominal, &calibrated);
        Some((position_mm, rotation_rad, approach(&nominal)))
    }

    /// Everything a hybrid query needs of the model at `q`, from one forward kinematics of
    /// each chain: [`PreparedModel::error_with_approach`]'s values and the nominal TCP's
    /// position, which says whether `q` reaches the target at all. `None` as `error`.
    ///
    /// The query path: the chains folded at preparation and one `sin_cos` per joint
    /// shared by both ([`crate::chain`]'s `FoldedChain`); equal to the chains' own forward
    /// kinematics ([`crate::testing::model_at_by_chains`]) to 4e-12 mm (module docs).
    #[inline]
    pub fn at(&self, q: &[f64]) -> Option<ModelAt> {
        self.evaluate(q, true)
    }

    /// [`PreparedModel::at`] without the orientation error (zero), as a query of a table
    /// whose samples have no orientation computes it: the nominal TCP's position and
    /// approach axis and the calibrated TCP's position alone, from the tool back to the
    /// base, both chains in one walk, side by side in vector registers (`ReachPair` in
    /// [`crate::chain`]; `FoldedChain::reach_pair` if their joints differ in kind), when
    /// their axes are unit vectors to rounding and the calibrated chain has no gravity
    /// compliance. `None` as `error`.
    #[inline]
    pub fn at_position(&self, q: &[f64]) -> Option<ModelAt> {
        self.evaluate(q, false)
    }

    /// [`PreparedModel::at`], with the orientation error computed only when `rotation`
    /// (zero otherwise): a table whose samples have no orientation never reads it. A
    /// table's query calls it with [`crate::Table::has_orientation`], so a caller doing
    /// the work a table does (a benchmark's contender) calls it the same way.
    #[inline]
    pub fn evaluate(&self, q: &[f64], rotation: bool) -> Option<ModelAt> {
        let n = self.joint_count();
        if q.len() != n || n > MAX_JOINTS {
            return None;
        }
        match (rotation, &self.pair, self.has_terms) {
            (true, Some(pair), false) => return pair.posed_model_at(q),
            (true, Some(pair), true) => {
                return pair.posed_model_at_moved(q, |q, sin_cos, moved| {
                    self.moved_sin_cos(q, sin_cos, moved)
                })
            }
            _ => {}
        }
        let mut sin_cos = [(0.0, 1.0); MAX_JOINTS];
        crate::trig::sin_cos_each(q, &mut sin_cos);
        let [nominal, calibrated] = &self.folded;
        let sin_cos = &sin_cos[..n];
        if let (Some(pair), true) = (&self.pair, self.has_terms) {
            return Some(self.walk_apart(pair, q, sin_cos));
        }
        if !rotation && !self.has_terms {
            let walked = match &self.pair {
                Some(pair) => Some(pair.walk(q, sin_cos)),
                None => FoldedChain::reach_pair(nominal, calibrated, q, sin_cos),
            };
            if let Some((nominal_mm, approach, calibrated_mm)) = walked {
                return Some(ModelAt {
                    position_mm: difference(calibrated_mm, nominal_mm),
                    rotation_rad: [0.0; 3],
                    approach,
                    nominal_tcp_mm: nominal_mm,
                    nominal_rotation: None,
                });
            }
        }
        // With joint-space terms the calibrated chain stands at q' (module
        // `joint_terms`), its own sines and cosines; the nominal chain at q.
        // (Declared here, filled only with terms: a table without pays nothing.)
        let mut moved;
        let mut moved_sin_cos;
        let (calibrated_q, calibrated_sin_cos) = if self.has_terms {
            moved = [0.0; MAX_JOINTS];
            moved_sin_cos = [(0.0, 1.0); MAX_JOINTS];
            self.prepared_terms.apply(q, sin_cos, &mut moved[..n]);
            crate::trig::sin_cos_each(&moved[..n], &mut moved_sin_cos);
            (&moved[..n], &moved_sin_cos[..n])
        } else {
            (q, sin_cos)
        };
        let (calibrated_mm, calibrated_rotation) =
            calibrated.loaded_tcp(calibrated_q, calibrated_sin_cos, rotation);
        let (nominal_mm, approach, rotation_rad, nominal_rotation) = match calibrated_rotation {
            Some(rotation) => {
                let nominal = nominal.tcp_pose(q, sin_cos);
                let calibrated = Transform {
                    rotation,
                    translation_mm: calibrated_mm,
                };
                let rotation_rad = pose_error(&nominal, &calibrated).1;
                let approach = approach(&nominal);
                (
                    nominal.translation_mm,
                    approach,
                    rotation_rad,
                    Some(nominal.rotation),
                )
            }
            None => {
                let (nominal_mm, approach) = nominal.reach::<true>(q, sin_cos);
                (nominal_mm, approach, [0.0; 3], None)
            }
        };
        Some(ModelAt {
            position_mm: difference(calibrated_mm, nominal_mm),
            rotation_rad,
            approach,
            nominal_tcp_mm: nominal_mm,
            nominal_rotation,
        })
    }

    /// [`PreparedModel::evaluate`] without the orientation of a model with joint-space terms
    /// whose chains walk together: the calibrated lane turned by the sines and cosines of
    /// `q'` ([`PreparedModel::moved_sin_cos`]). `q` and `sin_cos` hold the chains' joint
    /// count. Not inlined: in [`PreparedModel::evaluate`] it slowed the walk without terms.
    #[inline(never)]
    fn walk_apart(&self, pair: &ReachPair, q: &[f64], sin_cos: &[(f64, f64)]) -> ModelAt {
        let n = q.len().min(sin_cos.len()).min(MAX_JOINTS);
        let mut moved_sin_cos = [(0.0, 1.0); MAX_JOINTS];
        let moved_sin_cos = &mut moved_sin_cos[..n];
        self.moved_sin_cos(&q[..n], &sin_cos[..n], moved_sin_cos);
        let (nominal_mm, approach, calibrated_mm) = pair.walk_apart(q, sin_cos, moved_sin_cos);
        ModelAt {
            position_mm: difference(calibrated_mm, nominal_mm),
            rotation_rad: [0.0; 3],
            approach,
            nominal_tcp_mm: nominal_mm,
            nominal_rotation: None,
        }
    }

    /// The sines and cosines of the calibrated chain's angles `q'` (module
    /// [`crate::joint_terms`]) into `moved`, from `q` and its own by angle addition
    /// ([`PreparedTerms::moved_sin_cos`]) or, for a term that may be large, by `sin_cos` of
    /// `q'`. The slices hold the chains' joint count.
    #[inline]
    fn moved_sin_cos(&self, q: &[f64], sin_cos: &[(f64, f64)], moved: &mut [(f64, f64)]) {
        if !self.prepared_terms.moved_sin_cos(q, sin_cos, moved) {
            let mut angles = [0.0; MAX_JOINTS];
            let n = q.len().min(MAX_JOINTS);
            self.prepared_terms.apply(q, sin_cos, &mut angles[..n]);
            crate::trig::sin_cos_each(&angles[..n], moved);
        }
    }

    /// The nominal TCP's approach axis at `q` alone (as [`PreparedModel::error_with_approach`]
    /// gives it): what the compiler fits a tool-axis field to at each sample's joint values,
    /// so that build and query use one definition. `None` when `q` does not have one value
    /// per joint.
    pub fn approach_axis(&self, q: &[f64]) -> Option<[f64; 3]> {
        Some(approach(&self.nominal.tcp_pose(q)?))
    }
}

// The model's answer at joint values is defined beside the chain walk that makes it.
pub use crate::chain::ModelAt;

/// `a − b`, written out (an array's `map` is a call the compiler does not always inline,
/// and this is on every hybrid query's path).
#[inline(always)]
fn difference(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The approach (z) axis of a TCP pose: the third column of its rotation, base frame.
#[inline]
fn approach(tcp: &Transform) -> [f64; 3] {
    let r = &tcp.rotation;
    [r[0][2], r[1][2], r[2][2]]
}

/// The prepared model of a validated version-1 archive, if it carries one.
pub(crate) fn prepared_model_v1(archive: &ArchivedTableData) -> Option<PreparedModel> {
    Some(PreparedModel::from_mdh(&native_model(
        archive.model.as_ref()?,
    )))
}

/// A kinematic model out of the archive.
pub(crate) fn native_model(model: &ArchivedKinematicModel) -> KinematicModel {
    KinematicModel {
        nominal: native(&model.nominal),
        calibrated: native(&model.calibrated),
    }
}

/// A model's parameters out of the archive.
#[inline]
fn native(a: &ArchivedModelParams) -> ModelParams {
    ModelParams {
        joints: a.joints.map(|j| j.map(|v| v.to_native())),
        tool: a.tool.map(|v| v.to_native()),
        base: a.base.map(|v| v.to_native()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::rows_of;

    #[test]
    fn identical_models_predict_no_error_and_a_shifted_base_predicts_the_shift() {
        use std::f64::consts::FRAC_PI_2;
        let joint = |a_mm, d_mm, alpha_rad| [a_mm, d_mm, alpha_rad, 0.0, 0.0];
        let identity = rows_of(&Transform::IDENTITY);
        let nominal = ModelParams {
            joints: [
                joint(350.0, 750.0, -FRAC_PI_2),
                joint(1250.0, 0.0, 0.0),
                joint(55.0, 0.0, FRAC_PI_2),
                joint(0.0, 1100.0, -FRAC_PI_2),
                joint(0.0, 0.0, FRAC_PI_2),
                joint(0.0, 230.0, 0.0),
            ],
            tool: identity,
            base: identity,
        };
        let q = [0.1, -0.7, 1.2, 0.3, -0.4, 1.1];
        let same = KinematicModel {
            nominal,
            calibrated: nominal,
        };
        assert_eq!(model_error(&same, &q), ([0.0; 3], [0.0; 3]));
        let mut shifted = nominal;
        shifted.base[3] = 0.25;
        shifted.base[11] = -0.5;
        let (p, r) = model_error(
            &KinematicModel {
                nominal,
                calibrated: shifted,
            },
            &q,
        );
        for (got, want) in p.iter().zip([0.25, 0.0, -0.5]) {
            assert!((got - want).abs() < 1e-12, "{p:?}");
        }
        assert!(r.iter().all(|v| v.abs() < 1e-15), "{r:?}");
    }

    /// A UR5's MD-H rows (`tables/ur5/robot.toml`), the calibrated one moved by tenths of a
    /// millimetre and milliradian, with a tool offset; `terms` on the calibrated chain.
    fn ur5_with_terms(moves: &[[f64; 3]; 6], terms: JointTerms) -> PreparedModel {
        use std::f64::consts::FRAC_PI_2;
        let rows = [
            [0.0, 89.159, FRAC_PI_2],
            [-425.0, 0.0, 0.0],
            [-392.25, 0.0, 0.0],
            [0.0, 109.15, FRAC_PI_2],
            [0.0, 94.65, -FRAC_PI_2],
            [0.0, 82.3, 0.0],
        ];
        let mut tool = rows_of(&Transform::IDENTITY);
        tool[7] = 0.09;
        tool[11] = 31.0;
        let params = |m: &[[f64; 3]; 6]| ModelParams {
            joints: [0, 1, 2, 3, 4, 5].map(|j| {
                let [a, d, alpha] = rows[j];
                [
                    a + m[j][0],
                    d + m[j][1],
                    alpha + m[j][2] * 1e-3,
                    0.0,
                    -m[j][2] * 1e-3,
                ]
            }),
            tool,
            base: rows_of(&Transform::IDENTITY),
        };
        PreparedModel::from_mdh(&KinematicModel {
            nominal: params(&[[0.0; 3]; 6]),
            calibrated: params(moves),
        })
        .with_joint_terms(terms)
        .expect("terms within the bounds, on revolute joints")
    }

    use proptest::prelude::*;

    proptest! {
        /// The query path of a model with joint-space terms walks both chains together,
        /// the calibrated one at `q'` (its sines and cosines by angle addition for small
        /// terms, by `sin_cos` of `q'` for large ones), and is held to the chains' own
        /// forward kinematics joint by joint (`PreparedModel::error`, the library's
        /// `sin_cos`, `q'` rounded before it) within 1e-12 mm and 2e-15 rad: the two differ
        /// in the sines' and cosines' last bits (2⁻⁵¹ at most, a few 1e-13 mm at the
        /// UR5's reach) and in the order of the chains' products, as the walk without
        /// terms does (`chain::tests`).
        #[test]
        fn a_model_with_joint_terms_walks_as_the_chains_at_the_moved_angles(
            q in proptest::array::uniform6(-3.2..3.2f64),
            moves in proptest::array::uniform6(proptest::array::uniform3(-0.5..0.5f64)),
            coefficients in proptest::array::uniform6(proptest::array::uniform4(-4e-3..4e-3f64)),
            ranges in proptest::array::uniform6((-3.0..0.0f64, 0.0..3.0f64)),
            large in proptest::bool::weighted(0.3),
        ) {
            let mut terms = JointTerms::NONE;
            for j in 0..6 {
                terms.coefficients_rad[j] = coefficients[j].map(|c| if large { 20.0 * c } else { c });
                terms.range_rad[j] = [ranges[j].0, ranges[j].1];
            }
            let model = ur5_with_terms(&moves, terms);
            prop_assert!(model.pair.is_some(), "a rigid calibrated chain walks in pairs");
            let at = model.at(&q).unwrap();
            let position = model.at_position(&q).unwrap();
            let (position_mm, rotation_rad) = model.error(&q).unwrap();
            let nominal = model.nominal().tcp_pose(&q).unwrap();
            for a in 0..3 {
                prop_assert!((at.position_mm[a] - position_mm[a]).abs() <= 1e-12, "{at:?} vs {position_mm:?}");
                prop_assert!((at.rotation_rad[a] - rotation_rad[a]).abs() <= 2e-15, "{at:?} vs {rotation_rad:?}");
                prop_assert!((at.nominal_tcp_mm[a] - nominal.translation_mm[a]).abs() <= 1e-12);
                prop_assert!((at.approach[a] - nominal.rotation[a][2]).abs() <= 2e-15);
                // The position-only walk is the posed walk's point and approach, to the bit.
                prop_assert_eq!(position.position_mm[a].to_bits(), at.position_mm[a].to_bits());
                prop_assert_eq!(position.approach[a].to_bits(), at.approach[a].to_bits());
            }
            // Four lanes wide (on a processor with AVX2) or two, the same bits.
            let narrow = PreparedModel { pair: model.pair.map(ReachPair::narrowed), ..model };
            let two = narrow.at(&q).unwrap();
            prop_assert!(crate::chain::same_bits(&two, &at), "{two:?} vs {at:?}");
        }

        /// The prepared terms give `JointTerms::offset` to the bit inside and beyond the
        /// range (the held ends computed once, not per query), and the angle-addition
        /// sines and cosines of `q'` are within 2⁻⁵⁰ of the library's `sin_cos(q')`:
        /// `trig::sin_cos` of `q`, which they start from, is within 2⁻⁵¹ of it, and the
        /// correction by `δ` adds a few units of 2⁻⁵³.
        #[test]
        fn prepared_terms_are_the_terms_and_their_moved_sines_the_moved_angles(
            q in proptest::array::uniform6(-6.0..6.0f64),
            coefficients in proptest::array::uniform6(proptest::array::uniform4(-3.9e-3..3.9e-3f64)),
            ranges in proptest::array::uniform6((-3.0..0.0f64, 0.0..3.0f64)),
        ) {
            let mut terms = JointTerms::NONE;
            for j in 0..6 {
                terms.coefficients_rad[j] = coefficients[j];
                terms.range_rad[j] = [ranges[j].0, ranges[j].1];
            }
            let prepared = PreparedTerms::new(&terms);
            let mut sin_cos = [(0.0, 1.0); 6];
            crate::trig::sin_cos_each(&q, &mut sin_cos);
            let mut moved = [0.0; 6];
            terms.apply(&q, &sin_cos, &mut moved);
            let mut fast = [0.0; 6];
            prepared.apply(&q, &sin_cos, &mut fast);
            prop_assert_eq!(moved.map(f64::to_bits), fast.map(f64::to_bits));
            let mut moved_sin_cos = [(0.0, 1.0); 6];
            prop_assert!(prepared.moved_sin_cos(&q, &sin_cos, &mut moved_sin_cos));
            for j in 0..6 {
                let (s, c) = moved[j].sin_cos();
                let bound = 4.0 * f64::EPSILON;
                prop_assert!((moved_sin_cos[j].0 - s).abs() <= bound, "{j}: {:?} vs {:?}", moved_sin_cos[j], (s, c));
                prop_assert!((moved_sin_cos[j].1 - c).abs() <= bound, "{j}: {:?} vs {:?}", moved_sin_cos[j], (s, c));
            }
        }
    }

    /// Terms that may exceed 1/64 rad take `sin_cos` of `q'` instead of the series.
    #[test]
    fn large_terms_are_not_moved_by_the_series() {
        let mut terms = JointTerms::NONE;
        terms.coefficients_rad[1] = [0.01, 0.01, 0.0, 0.0];
        let prepared = PreparedTerms::new(&terms);
        let mut out = [(0.0, 1.0); 2];
        assert!(!prepared.moved_sin_cos(&[0.3, 0.4], &[(0.0, 1.0); 2], &mut out));
        assert_eq!(out, [(0.0, 1.0); 2]);
    }
}
