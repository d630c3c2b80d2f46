//! Serial kinematic chains of any robot: revolute and prismatic joints about arbitrary axes,
//! from 1 to [`MAX_JOINTS`] of them, with gravity compliance. Allocation-free and
//! panic-free, so that a hybrid table evaluates its model inside the query path.
//!
//! A chain is the general form every robot description maps to exactly:
//!
//! ```text
//! T(q) = base · O_1 · M_1(q_1 + o_1) · O_2 · M_2(q_2 + o_2) ⋯ O_n · M_n(q_n + o_n) · tool
//! ```
//!
//! with `O_i` the constant pose of joint `i`'s frame in its parent link's frame (a URDF
//! joint's `origin`), `M_i` the joint's motion — a rotation by the angle about its unit axis
//! (revolute), or a translation by the distance along it (prismatic) — and `o_i` a constant
//! offset added to the joint variable. A Hayati-modified Denavit-Hartenberg (MD-H) robot is
//! the chain with every axis along z, `O_1` the identity and `O_i = Tz(d)·Tx(a)·Rx(α)·Ry(β)`
//! of link `i − 1` ([`Chain::from_mdh`]); a URDF file's joints are its rows directly.
//!
//! # Gravity compliance
//!
//! A joint's gear and bearings give under the gravity torque about its axis; one compliance
//! per joint models that: the arm stands at `q + Δq` with `Δq_j = c_j · τ_j(q)`. The torque
//! `τ_j = z_j · Σ_{k ≥ j} (p_k − a_j) × m_k g` sums over the links `k` that joint `j` carries
//! (and the payload), with `a_j` and `z_j` the joint's position and axis, `p_k` link `k`'s
//! centre of mass, `m_k` its mass and `g` gravity, all in the base frame (for a prismatic
//! joint the force along the axis, `z_j · Σ m_k g`). Units: mm, kg, mm/s², so torques come
//! in kg·mm²/s² = µN·m and compliances in rad/(kg·mm²/s²).

use crate::kinematics::{MdhJoint, Transform};
use crate::lanes::{Lanes, Pair};

#[cfg(target_arch = "x86_64")]
mod avx;

/// The model at one set of joint values ([`crate::model::PreparedModel::at`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelAt {
    /// The predicted position error, mm, base frame.
    pub position_mm: [f64; 3],
    /// The predicted orientation error (rotation vector), rad, base frame.
    pub rotation_rad: [f64; 3],
    /// The nominal TCP's approach axis, a unit vector, base frame.
    pub approach: [f64; 3],
    /// The nominal TCP's position, mm, base frame: where the controller puts the tool.
    pub nominal_tcp_mm: [f64; 3],
    /// The nominal TCP frame's rotation (row-major, its columns the frame's axes in the
    /// base frame), when evaluated with the orientation; `None` from the position-only
    /// walk.
    pub nominal_rotation: Option<[[f64; 3]; 3]>,
}

/// The most joints a chain may have: robots with more axes than this are not served (the
/// chain lives in fixed-size arrays, so that queries never allocate).
pub const MAX_JOINTS: usize = 12;

/// Standard gravity, mm/s².
pub const STANDARD_GRAVITY_MM_S2: f64 = 9806.65;

/// How a joint moves.
#[repr(u8)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum JointKind {
    /// A rotation about the axis by the joint variable, rad.
    #[default]
    Revolute = 0,
    /// A translation along the axis by the joint variable, mm.
    Prismatic = 1,
}

/// One joint of a chain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChainJoint {
    /// The joint's frame in its parent link's frame at zero motion (mm for the translation).
    pub origin: Transform,
    /// The axis of motion, a unit vector in the joint's frame.
    pub axis: [f64; 3],
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Added to the joint variable before it moves the joint (rad, or mm when prismatic):
    /// where the controller's zero is on the axis.
    pub offset: f64,
}

impl Default for ChainJoint {
    fn default() -> Self {
        ChainJoint {
            origin: Transform::IDENTITY,
            axis: [0.0, 0.0, 1.0],
            kind: JointKind::Revolute,
            offset: 0.0,
        }
    }
}

impl ChainJoint {
    /// The joint's motion `M(value)` for the joint variable `value` (offset not added).
    #[inline]
    pub fn motion(&self, value: f64) -> Transform {
        let [x, y, z] = self.axis;
        match self.kind {
            JointKind::Prismatic => Transform {
                rotation: Transform::IDENTITY.rotation,
                translation_mm: [x * value, y * value, z * value],
            },
            JointKind::Revolute => {
                let (s, c) = value.sin_cos();
                // Rodrigues: R = c·I + s·[k]× + (1 − c)·k·kᵀ.
                let v = 1.0 - c;
                Transform {
                    rotation: [
                        [c + v * x * x, v * x * y - s * z, v * x * z + s * y],
                        [v * y * x + s * z, c + v * y * y, v * y * z - s * x],
                        [v * z * x - s * y, v * z * y + s * x, c + v * z * z],
                    ],
                    translation_mm: [0.0; 3],
                }
            }
        }
    }
}

/// Masses for the gravity compliance of a chain: per joint, the link it moves, and the
/// payload at the tool.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Compliance {
    /// Gravity in the chain's base frame, mm/s² (`[0, 0, −9806.65]` for a floor-mounted
    /// robot).
    pub gravity_mm_s2: [f64; 3],
    /// Per joint, the mass of the link it moves, kg.
    pub link_mass_kg: [f64; MAX_JOINTS],
    /// Per joint, that link's centre of mass in the joint's frame after its motion, mm.
    pub link_com_mm: [[f64; 3]; MAX_JOINTS],
    /// The payload's mass, kg.
    pub payload_kg: f64,
    /// The payload's centre of mass in the tool frame, mm.
    pub payload_com_mm: [f64; 3],
    /// Per joint, the compliance `c_j`: deflection per unit of gravity torque,
    /// rad/(kg·mm²/s²) (mm/(kg·mm/s²) when prismatic).
    pub compliance: [f64; MAX_JOINTS],
}

impl Compliance {
    /// No masses, no compliance.
    pub const NONE: Compliance = Compliance {
        gravity_mm_s2: [0.0, 0.0, -STANDARD_GRAVITY_MM_S2],
        link_mass_kg: [0.0; MAX_JOINTS],
        link_com_mm: [[0.0; 3]; MAX_JOINTS],
        payload_kg: 0.0,
        payload_com_mm: [0.0; 3],
        compliance: [0.0; MAX_JOINTS],
    };
}

/// A serial chain of `len` joints (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chain {
    /// The robot's base in the frame poses are given in (the measurement frame for a
    /// calibrated model, the identity for a nominal one).
    pub base: Transform,
    joints: [ChainJoint; MAX_JOINTS],
    len: usize,
    /// The tool centre point in the last joint's frame.
    pub tool: Transform,
    /// Gravity compliance, when modelled.
    pub compliance: Option<Compliance>,
}

/// Why a chain could not be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChainError {
    /// No joint, or more than [`MAX_JOINTS`].
    JointCount(usize),
    /// A value is not finite, or an axis is not a unit vector.
    Invalid(&'static str),
}

impl std::fmt::Display for ChainError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ChainError::JointCount(n) => {
                write!(f, "a chain has 1 to {MAX_JOINTS} joints, not {n}")
            }
            ChainError::Invalid(what) => write!(f, "invalid chain: {what}"),
        }
    }
}

impl std::error::Error for ChainError {}

impl Chain {
    /// A chain of the given joints, checked: 1 to [`MAX_JOINTS`] joints, finite values,
    /// unit axes (to 1e-9), orthonormal rotations (to 1e-9).
    ///
    /// # Errors
    ///
    /// [`ChainError`] naming what is wrong.
    pub fn new(
        base: Transform,
        joints: &[ChainJoint],
        tool: Transform,
        compliance: Option<Compliance>,
    ) -> Result<Chain, ChainError> {
        if joints.is_empty() || joints.len() > MAX_JOINTS {
            return Err(ChainError::JointCount(joints.len()));
        }
        let mut chain = Chain {
            base,
            joints: [ChainJoint::default(); MAX_JOINTS],
            len: joints.len(),
            tool,
            compliance,
        };
        chain.joints[..joints.len()].copy_from_slice(joints);
        chain.check()?;
        Ok(chain)
    }

    /// The MD-H chain `A_1 ⋯ A_n · tool` with `A_i = Rz(q_i + θ_offset_i) · Tz(d_i) ·
    /// Tx(a_i) · Rx(α_i) · Ry(β_i)` (see [`crate::kinematics`]): every axis z, each link's
    /// constant part becoming the next joint's origin and the last one's the tool's.
    ///
    /// # Errors
    ///
    /// As [`Chain::new`].
    pub fn from_mdh(
        base: Transform,
        joints: &[MdhJoint],
        tool: Transform,
        compliance: Option<Compliance>,
    ) -> Result<Chain, ChainError> {
        if joints.is_empty() || joints.len() > MAX_JOINTS {
            return Err(ChainError::JointCount(joints.len()));
        }
        let mut rows = [ChainJoint::default(); MAX_JOINTS];
        let mut previous = Transform::IDENTITY;
        for (row, joint) in rows.iter_mut().zip(joints) {
            *row = ChainJoint {
                origin: previous,
                axis: [0.0, 0.0, 1.0],
                kind: JointKind::Revolute,
                offset: joint.theta_offset_rad,
            };
            // The link's constant part: the MD-H transform at θ = 0.
            previous = MdhJoint {
                theta_offset_rad: 0.0,
                ..*joint
            }
            .transform(0.0);
        }
        Chain::new(
            base,
            &rows[..joints.len()],
            previous.compose(&tool),
            compliance,
        )
    }

    fn check(&self) -> Result<(), ChainError> {
        let transform_ok = |t: &Transform| {
            let finite = t
                .rotation
                .iter()
                .flatten()
                .chain(&t.translation_mm)
                .all(|v| v.is_finite());
            finite && orthonormal(&t.rotation)
        };
        if !transform_ok(&self.base) || !transform_ok(&self.tool) {
            return Err(ChainError::Invalid(
                "base or tool is not a finite rigid transform",
            ));
        }
        for j in self.joints() {
            if !transform_ok(&j.origin) {
                return Err(ChainError::Invalid(
                    "a joint origin is not a finite rigid transform",
                ));
            }
            let norm =
                (j.axis[0] * j.axis[0] + j.axis[1] * j.axis[1] + j.axis[2] * j.axis[2]).sqrt();
            if !within(norm, 1.0, 1e-9) || !j.offset.is_finite() {
                return Err(ChainError::Invalid(
                    "a joint axis is not a unit vector, or an offset is not finite",
                ));
            }
        }
        if let Some(c) = &self.compliance {
            let values = c
                .gravity_mm_s2
                .iter()
                .chain(&c.link_mass_kg)
                .chain(c.link_com_mm.iter().flatten())
                .chain(&c.payload_com_mm)
                .chain(&c.compliance)
                .chain(std::iter::once(&c.payload_kg));
            if !values.clone().all(|v| v.is_finite()) {
                return Err(ChainError::Invalid("a compliance value is not finite"));
            }
            if c.link_mass_kg.iter().any(|m| *m < 0.0) || c.payload_kg < 0.0 {
                return Err(ChainError::Invalid("a mass is negative"));
            }
        }
        Ok(())
    }

    /// The joints, base to tool.
    #[inline]
    pub fn joints(&self) -> &[ChainJoint] {
        &self.joints[..self.len.min(MAX_JOINTS)]
    }

    /// The number of joints.
    #[inline]
    pub fn joint_count(&self) -> usize {
        self.len
    }

    /// The prismatic joints, bit `i` for joint `i` (0-based): which joint values are
    /// lengths (mm) rather than angles.
    pub fn prismatic_joints(&self) -> u64 {
        self.joints()
            .iter()
            .enumerate()
            .filter(|(_, j)| j.kind == JointKind::Prismatic)
            .fold(0, |mask, (i, _)| mask | 1 << i)
    }

    /// The tool centre point's pose at joint values `q` (rad, mm for prismatic joints),
    /// without compliance: `None` when `q` does not have one value per joint.
    #[inline]
    pub fn tcp_pose(&self, q: &[f64]) -> Option<Transform> {
        if q.len() != self.len {
            return None;
        }
        let mut pose = self.base;
        for (joint, &value) in self.joints().iter().zip(q) {
            pose = pose
                .compose(&joint.origin)
                .compose(&joint.motion(value + joint.offset));
        }
        Some(pose.compose(&self.tool))
    }

    /// The joint values the arm stands at under gravity when commanded `q`:
    /// `q + Δq(q)` (module docs), or `q` itself without compliance. `None` when `q` does not
    /// have one value per joint.
    #[inline]
    pub fn loaded_joints(&self, q: &[f64]) -> Option<[f64; MAX_JOINTS]> {
        if q.len() != self.len {
            return None;
        }
        let mut out = [0.0; MAX_JOINTS];
        out[..self.len].copy_from_slice(q);
        if let Some(c) = &self.compliance {
            let torque = self.gravity_torques(q, c)?;
            for j in 0..self.len {
                out[j] += c.compliance[j] * torque[j];
            }
        }
        Some(out)
    }

    /// The tool centre point's pose at joint values `q`, deflected by gravity when the
    /// chain models compliance: what a calibrated model predicts.
    #[inline]
    pub fn loaded_tcp_pose(&self, q: &[f64]) -> Option<Transform> {
        let loaded = self.loaded_joints(q)?;
        self.tcp_pose(&loaded[..self.len])
    }

    /// The gravity torque about each joint's axis at `q` (module docs), kg·mm²/s² (or
    /// kg·mm/s² for a prismatic joint).
    pub fn gravity_torques(&self, q: &[f64], c: &Compliance) -> Option<[f64; MAX_JOINTS]> {
        if q.len() != self.len {
            return None;
        }
        let n = self.len;
        // Each joint's position and axis, and each link's centre of mass, base frame.
        let mut joint_at = [[0.0; 3]; MAX_JOINTS];
        let mut axis = [[0.0; 3]; MAX_JOINTS];
        let mut com = [[0.0; 3]; MAX_JOINTS];
        let mut pose = self.base;
        for (j, (joint, &value)) in self.joints().iter().zip(q).enumerate() {
            pose = pose.compose(&joint.origin);
            joint_at[j] = pose.translation_mm;
            axis[j] = pose.rotate_vector(joint.axis);
            pose = pose.compose(&joint.motion(value + joint.offset));
            com[j] = pose.transform_point(c.link_com_mm[j]);
        }
        let payload_at = pose.compose(&self.tool).transform_point(c.payload_com_mm);
        let g = c.gravity_mm_s2;
        let mut torque = [0.0; MAX_JOINTS];
        for j in 0..n {
            // Σ over the links joint j carries, and the payload, of the force and its moment.
            let mut force = [0.0; 3];
            let mut moment = [0.0; 3];
            let loads = (j..n)
                .map(|k| (c.link_mass_kg[k], com[k]))
                .chain(std::iter::once((c.payload_kg, payload_at)));
            for (mass, at) in loads {
                let f = g.map(|v| v * mass);
                let arm = [0, 1, 2].map(|a| at[a] - joint_at[j][a]);
                let m = cross(arm, f);
                for a in 0..3 {
                    force[a] += f[a];
                    moment[a] += m[a];
                }
            }
            let about = match self.joints[j].kind {
                JointKind::Revolute => moment,
                JointKind::Prismatic => force,
            };
            torque[j] = dot(about, axis[j]);
        }
        Some(torque)
    }
}

/// A [`Chain`] folded for evaluation at many joint values: the query path of a hybrid
/// table, where two chains are evaluated at the same joint values for every query.
///
/// Rodrigues' rotation is linear in `(1, cos θ, sin θ)`, axis unit or not:
/// `R_k(θ) = k kᵀ + cos θ (I − k kᵀ) + sin θ [k]×`, and expanding `θ = q + o` keeps it linear
/// in `(1, cos q, sin q)`. So each joint's constant parts (its origin, axis and offset, and
/// for the first joint the base) are multiplied out once, into
/// `O · M(q + o) = [F + cos q · C + sin q · S | t + q · u]` ([`FoldedJoint`]), and a pose
/// costs per joint 9 multiply-adds of that sum and one 3 × 4 product, with the sine and
/// cosine of `q` given (computed once for both chains). The gravity torques come from
/// suffix sums over the links in one pass instead of a double loop. [`Chain::tcp_pose`] and
/// [`Chain::loaded_tcp_pose`] are the reference this is held to (tests: some units in the
/// last place of the reach).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FoldedChain {
    joints: [FoldedJoint; MAX_JOINTS],
    len: usize,
    tool: Transform,
    gravity: Option<FoldedGravity>,
    /// Whether every revolute joint's axis is a unit vector to 1e-13, so that its rotations
    /// compose exactly ([`FoldedChain::loaded_tcp`]).
    unit_axes: bool,
    /// The chain for its TCP's position and approach axis alone ([`ReachChain`]), when
    /// every axis is a unit vector to rounding.
    reach: Option<ReachChain>,
}

/// A chain re-expressed for [`FoldedChain::reach`]: each joint's frame turned so that its
/// axis is z, and its offset folded into the fixed part before it,
///
/// ```text
/// T(q) = Z_1 · J(q_1) · Z_2 · J(q_2) ⋯ Z_n · J(q_n) · tool_z,   J(q) = Rz(q) or Tz(q)
/// ```
///
/// (`Z_j = Q_{j−1}ᵀ · O_j · Q_j · J(o_j)`, with `Q_j` a rotation taking z onto joint `j`'s
/// axis, and `tool_z = Q_nᵀ · tool`). Taken from the tool back to the base, a point and a
/// direction cost a joint a turn about z (4 products, given `sin q` and `cos q`) and a
/// 3 × 4 product each, where composing frames costs a 3 × 3 and a 3 × 4 product.
///
/// The turn is applied to the frame, not to the point: `Z_j · Rz(q)` mixes the frame's
/// first two columns by `cos q` and `sin q` ([`turned_row`]), which waits only for the
/// joint's sine and cosine, so that the operations that carry the point from the tool to
/// the base, each waiting for the one before (the query's latency), are a 3 × 4 product a
/// joint and no more: three dependent steps ([`moved`]) where turning the point first took
/// six.
#[derive(Clone, Copy, Debug, PartialEq)]
struct ReachChain {
    /// Each joint's frame `Z_j`, row by row: the rotation's three entries, then the
    /// translation.
    frames: [[[f64; 4]; 3]; MAX_JOINTS],
    prismatic: [bool; MAX_JOINTS],
    /// The TCP's position, approach (z) axis and x axis in the last joint's turned frame.
    tool_mm: [f64; 3],
    tool_approach: [f64; 3],
    tool_across: [f64; 3],
}

/// [`FoldedChain::reach_pair`] prepared: the two chains' frames interleaved, so that each
/// joint turns and moves both points in one [`Pair`] per coordinate (`a` in the first lane,
/// `b` in the second; so do both chains' approach axes, and for [`ReachPair::walk_posed`]
/// their x axes). Every lane does the arithmetic [`ReachChain::step`] does, in its order:
/// the walk gives `reach_pair`'s values to the bit, with one instruction where
/// `reach_pair` has two.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ReachPair {
    /// Each joint's frame, row by row: the rotation's three entries, then the translation.
    frames: [[[Pair; 4]; 3]; MAX_JOINTS],
    prismatic: [bool; MAX_JOINTS],
    len: usize,
    tool_mm: [Pair; 3],
    tool_approach: [Pair; 3],
    /// The TCP frame's x axis in the last joint's turned frame, both chains.
    tool_across: [Pair; 3],
    /// Whether [`ReachPair::posed_model_at`] walks four lanes wide (x86-64 with AVX2, found
    /// when the pair is made).
    wide: bool,
}

/// Both chains' TCP frames from one walk ([`ReachPair::walk_posed`]), base frame: the
/// position, the x axis and the approach (z) axis of each; the y axis is `z × x`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PosedPair {
    pub(crate) a_mm: [f64; 3],
    pub(crate) a_x: [f64; 3],
    pub(crate) a_z: [f64; 3],
    pub(crate) b_mm: [f64; 3],
    pub(crate) b_x: [f64; 3],
    pub(crate) b_z: [f64; 3],
}

impl PosedPair {
    /// The model's values at these frames, `a` the nominal chain's and `b` the calibrated
    /// one's ([`crate::model::PreparedModel::at`]): the nominal rotation's columns `x`,
    /// `z × x`, `z`, and the orientation error from the columns without forming
    /// `R_b · R_aᵀ`: with `n_c` and `k_c` the nominal and calibrated columns, that product
    /// is `Σ_c k_c n_cᵀ`, so its skew part (`sin θ` times the axis) is `½ Σ_c n_c × k_c` and
    /// its trace `Σ_c n_c · k_c` ([`small_rotation_vector`]).
    #[inline(always)]
    pub(crate) fn model_at(&self) -> ModelAt {
        let nominal = [self.a_x, cross(self.a_z, self.a_x), self.a_z];
        let calibrated = [self.b_x, cross(self.b_z, self.b_x), self.b_z];
        let mut sin_axis = [0.0; 3];
        let mut trace = 0.0;
        for (n, k) in nominal.iter().zip(&calibrated) {
            let turn = cross(*n, *k);
            for (s, t) in sin_axis.iter_mut().zip(turn) {
                *s += t;
            }
            trace += dot(*n, *k);
        }
        let sin_axis = [0.5 * sin_axis[0], 0.5 * sin_axis[1], 0.5 * sin_axis[2]];
        let rotation_rad =
            small_rotation_vector(sin_axis, 0.5 * (trace - 1.0)).unwrap_or_else(|| {
                // R_b · R_aᵀ[i][l] = Σ_c k_c[i] n_c[l], for a turn beyond the series.
                let e = [0, 1, 2].map(|i| {
                    [0, 1, 2].map(|l| {
                        calibrated[0][i] * nominal[0][l]
                            + calibrated[1][i] * nominal[1][l]
                            + calibrated[2][i] * nominal[2][l]
                    })
                });
                crate::kinematics::rotation_vector(&e)
            });
        let [x, y, z] = nominal;
        ModelAt {
            position_mm: [
                self.b_mm[0] - self.a_mm[0],
                self.b_mm[1] - self.a_mm[1],
                self.b_mm[2] - self.a_mm[2],
            ],
            rotation_rad,
            approach: z,
            nominal_tcp_mm: self.a_mm,
            nominal_rotation: Some([[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]]),
        }
    }
}

/// Whether two model values are the same to the bit, field by field (the four-lane walk's
/// tests).
#[cfg(test)]
pub(crate) fn same_bits(x: &ModelAt, y: &ModelAt) -> bool {
    let bits = |v: &[f64]| v.iter().map(|e| e.to_bits()).collect::<Vec<_>>();
    let rotation = |m: &ModelAt| m.nominal_rotation.map(|r| bits(r.as_flattened()));
    bits(&x.position_mm) == bits(&y.position_mm)
        && bits(&x.rotation_rad) == bits(&y.rotation_rad)
        && bits(&x.approach) == bits(&y.approach)
        && bits(&x.nominal_tcp_mm) == bits(&y.nominal_tcp_mm)
        && rotation(x) == rotation(y)
}

/// Whether this processor walks a [`ReachPair`] four lanes wide.
fn wide_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    return avx::available();
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// The rotation vector of a rotation given `sin θ` times its axis and `cos θ`, for the
/// turns a calibration identifies (the UR5's reach 0.015 rad): `θ / sin θ = asin(s) / s`
/// by its series in `s²` to `s¹²` (the next term is under 1e-20 relative for `s ≤ 0.05`),
/// where [`crate::kinematics::rotation_vector`] takes an `atan2`. `None` from `s = 0.05`
/// (2.9°) or for `cos θ ≤ 0`: the general logarithm then.
#[inline]
fn small_rotation_vector(sin_axis: [f64; 3], cos_angle: f64) -> Option<[f64; 3]> {
    let s2 = dot(sin_axis, sin_axis);
    if !(s2 < 2.5e-3 && cos_angle > 0.0) {
        return None;
    }
    // (2n)! / (4ⁿ (n!)² (2n + 1)), n = 1..6; Estrin's form in s², s⁴ and s⁸.
    let [c1, c2, c3, c4, c5, c6] = [
        1.0 / 6.0,
        3.0 / 40.0,
        5.0 / 112.0,
        35.0 / 1152.0,
        63.0 / 2816.0,
        231.0 / 13312.0,
    ];
    let s4 = s2 * s2;
    let low = (1.0 + c1 * s2) + s4 * (c2 + c3 * s2);
    let high = (c4 + c5 * s2) + s4 * c6;
    let scale = low + (s4 * s4) * high;
    Some([
        sin_axis[0] * scale,
        sin_axis[1] * scale,
        sin_axis[2] * scale,
    ])
}

impl ReachPair {
    /// Whether this processor walks the pair four lanes wide.
    #[inline]
    pub(crate) fn wide(&self) -> bool {
        self.wide
    }

    /// The pair walked two lanes wide on any processor (the four-lane walk's tests).
    #[cfg(test)]
    pub(crate) fn narrowed(self) -> ReachPair {
        ReachPair {
            wide: false,
            ..self
        }
    }

    /// The pair of `a` and `b` when [`FoldedChain::reach_pair`] takes them, and their
    /// joints are of the same kinds.
    pub(crate) fn new(a: &FoldedChain, b: &FoldedChain) -> Option<ReachPair> {
        let (Some(za), Some(zb)) = (&a.reach, &b.reach) else {
            return None;
        };
        if b.gravity.is_some() || a.len != b.len || a.len > MAX_JOINTS {
            return None;
        }
        if za.prismatic[..a.len] != zb.prismatic[..a.len] {
            return None;
        }
        let both = |x: [f64; 3], y: [f64; 3]| [0, 1, 2].map(|i| Pair([x[i], y[i]]));
        let mut frames = [[[Pair([0.0; 2]); 4]; 3]; MAX_JOINTS];
        for (j, rows) in frames.iter_mut().enumerate().take(a.len) {
            let (fa, fb) = (&za.frames[j], &zb.frames[j]);
            *rows = [0, 1, 2].map(|i| [0, 1, 2, 3].map(|k| Pair([fa[i][k], fb[i][k]])));
        }
        Some(ReachPair {
            frames,
            prismatic: za.prismatic,
            len: a.len,
            tool_mm: both(za.tool_mm, zb.tool_mm),
            tool_approach: both(za.tool_approach, zb.tool_approach),
            tool_across: both(za.tool_across, zb.tool_across),
            wide: wide_available(),
        })
    }

    /// Both chains' TCP frames at joint values `q` given their sines and cosines, from one
    /// walk from the tool back: the point and the approach axis as [`ReachPair::walk`]
    /// walks them (the same values to the bit), and the x axis beside them, turned and
    /// rotated as the approach axis is. What a hybrid query's orientation error and TCP
    /// lever need, for a third more work a joint than the position alone, where composing
    /// each chain's frames down the chain took twice the walk. Both slices hold at least
    /// the chains' joint count (the caller's check).
    #[inline]
    pub(crate) fn walk_posed(&self, q: &[f64], sin_cos: &[(f64, f64)]) -> PosedPair {
        self.walk_posed_by(q, sin_cos.len(), |j| {
            let (s, c) = sin_cos[j];
            (Pair::splat(s), Pair::splat(c))
        })
    }

    /// The model's values at joint values `q` ([`PosedPair::model_at`] of
    /// [`ReachPair::walk_posed`]), their sines and cosines computed here; on a processor
    /// with AVX2 four lanes wide and compiled for it ([`ReachPair::wide`]), to the bit.
    /// `q` holds the chains' joint count (the caller's check). Always `Some`: in the form
    /// the caller returns, so that the answer is written in its place, not copied there.
    #[inline]
    pub(crate) fn posed_model_at(&self, q: &[f64]) -> Option<ModelAt> {
        #[cfg(target_arch = "x86_64")]
        if self.wide {
            // SAFETY: `wide` is set only where the processor has AVX2 (`ReachPair::new`).
            return unsafe { avx::posed_model_at(self, q) };
        }
        let mut sin_cos = [(0.0, 1.0); MAX_JOINTS];
        crate::trig::sin_cos_each(q, &mut sin_cos);
        Some(
            self.walk_posed(q, &sin_cos[..q.len().min(MAX_JOINTS)])
                .model_at(),
        )
    }

    /// [`ReachPair::posed_model_at`] with the calibrated chain `b` at its own revolute
    /// angles: `moved` fills their sines and cosines from `q` and its own (a calibrated
    /// chain with joint-space terms stands at `q'`, [`crate::joint_terms`]), and both
    /// chains walk together ([`ReachPair::walk_posed_apart`]); four lanes wide with AVX2,
    /// to the bit.
    #[inline]
    pub(crate) fn posed_model_at_moved(
        &self,
        q: &[f64],
        moved: impl FnOnce(&[f64], &[(f64, f64)], &mut [(f64, f64)]),
    ) -> Option<ModelAt> {
        #[cfg(target_arch = "x86_64")]
        if self.wide {
            // SAFETY: `wide` is set only where the processor has AVX2 (`ReachPair::new`).
            return unsafe { avx::posed_model_at_moved(self, q, moved) };
        }
        let n = q.len().min(MAX_JOINTS);
        let mut sin_cos = [(0.0, 1.0); MAX_JOINTS];
        crate::trig::sin_cos_each(&q[..n], &mut sin_cos);
        let mut moved_sin_cos = [(0.0, 1.0); MAX_JOINTS];
        moved(&q[..n], &sin_cos[..n], &mut moved_sin_cos[..n]);
        Some(
            self.walk_posed_apart(q, &sin_cos[..n], &moved_sin_cos[..n])
                .model_at(),
        )
    }

    /// [`ReachPair::walk_posed`] with each chain at its own revolute angles: `a` turned by
    /// `a_sin_cos`, `b` by `b_sin_cos` (a calibrated chain with joint-space terms stands at
    /// `q'`, [`crate::joint_terms`]); a prismatic joint moves both by `q`. Each lane is
    /// the one-chain walk at its angles, in its order.
    #[inline]
    pub(crate) fn walk_posed_apart(
        &self,
        q: &[f64],
        a_sin_cos: &[(f64, f64)],
        b_sin_cos: &[(f64, f64)],
    ) -> PosedPair {
        self.walk_posed_by(q, a_sin_cos.len().min(b_sin_cos.len()), |j| {
            let ((sa, ca), (sb, cb)) = (a_sin_cos[j], b_sin_cos[j]);
            (Pair([sa, sb]), Pair([ca, cb]))
        })
    }

    /// The walk of [`ReachPair::walk_posed`], joint `j`'s turn by `turn_of(j)`, its sines
    /// and cosines lane by lane, for `j` below `len`.
    #[inline(always)]
    fn walk_posed_by(
        &self,
        q: &[f64],
        len: usize,
        turn_of: impl Fn(usize) -> (Pair, Pair),
    ) -> PosedPair {
        let n = self.len.min(MAX_JOINTS).min(q.len()).min(len);
        let (mut point, mut approach, mut across) =
            (self.tool_mm, self.tool_approach, self.tool_across);
        for j in (0..n).rev() {
            let (s, c) = if self.prismatic[j] {
                point[2] = point[2] + Pair::splat(q[j]);
                (Pair::splat(0.0), Pair::splat(1.0))
            } else {
                turn_of(j)
            };
            let [p, a, x] = [point, approach, across];
            // Row by row, each turned as it is used: the three turned rows at once did not
            // fit SSE2's registers beside the vectors.
            for (i, row) in self.frames[j].iter().enumerate() {
                let r = turned_row(row, s, c);
                point[i] = moved(&r, p);
                approach[i] = rotated(&r, a);
                across[i] = rotated(&r, x);
            }
        }
        let lane = |v: [Pair; 3], l: usize| [v[0].0[l], v[1].0[l], v[2].0[l]];
        PosedPair {
            a_mm: lane(point, 0),
            a_x: lane(across, 0),
            a_z: lane(approach, 0),
            b_mm: lane(point, 1),
            b_x: lane(across, 1),
            b_z: lane(approach, 1),
        }
    }

    /// `a`'s TCP position and approach axis, and `b`'s TCP position, at joint values `q`
    /// given their sines and cosines: [`FoldedChain::reach_pair`]'s values. Both slices hold
    /// at least the chains' joint count (the caller's check).
    #[inline]
    pub(crate) fn walk(&self, q: &[f64], sin_cos: &[(f64, f64)]) -> ([f64; 3], [f64; 3], [f64; 3]) {
        self.walk_by(q, sin_cos.len(), |j| {
            let (s, c) = sin_cos[j];
            (Pair::splat(s), Pair::splat(c))
        })
    }

    /// [`ReachPair::walk`] with each chain at its own revolute angles, as
    /// [`ReachPair::walk_posed_apart`].
    #[inline]
    pub(crate) fn walk_apart(
        &self,
        q: &[f64],
        a_sin_cos: &[(f64, f64)],
        b_sin_cos: &[(f64, f64)],
    ) -> ([f64; 3], [f64; 3], [f64; 3]) {
        self.walk_by(q, a_sin_cos.len().min(b_sin_cos.len()), |j| {
            let ((sa, ca), (sb, cb)) = (a_sin_cos[j], b_sin_cos[j]);
            (Pair([sa, sb]), Pair([ca, cb]))
        })
    }

    /// The walk of [`ReachPair::walk`], joint `j`'s turn by `turn_of(j)`, for `j` below
    /// `len`.
    #[inline(always)]
    fn walk_by(
        &self,
        q: &[f64],
        len: usize,
        turn_of: impl Fn(usize) -> (Pair, Pair),
    ) -> ([f64; 3], [f64; 3], [f64; 3]) {
        let n = self.len.min(MAX_JOINTS).min(q.len()).min(len);
        let (mut point, mut approach) = (self.tool_mm, self.tool_approach);
        for j in (0..n).rev() {
            let (s, c) = if self.prismatic[j] {
                point[2] = point[2] + Pair::splat(q[j]);
                (Pair::splat(0.0), Pair::splat(1.0))
            } else {
                turn_of(j)
            };
            let [p, a] = [point, approach];
            for (i, row) in self.frames[j].iter().enumerate() {
                let r = turned_row(row, s, c);
                point[i] = moved(&r, p);
                approach[i] = rotated(&r, a);
            }
        }
        let [x, y, z] = point;
        let [ax, ay, az] = approach;
        (
            [x.0[0], y.0[0], z.0[0]],
            [ax.0[0], ay.0[0], az.0[0]],
            [x.0[1], y.0[1], z.0[1]],
        )
    }
}

impl ReachChain {
    /// The re-expressed form of a chain whose axes are unit vectors.
    fn new(chain: &Chain) -> ReachChain {
        let mut frames = [[[0.0; 4]; 3]; MAX_JOINTS];
        let mut prismatic = [false; MAX_JOINTS];
        // `Q_{j−1}ᵀ`, carried into the next joint's frame.
        let mut carry = Transform::IDENTITY;
        for (j, joint) in chain.joints().iter().enumerate() {
            let origin = if j == 0 {
                chain.base.compose(&joint.origin)
            } else {
                joint.origin
            };
            let turn = Transform {
                rotation: z_onto(joint.axis),
                translation_mm: [0.0; 3],
            };
            let offset = match joint.kind {
                JointKind::Revolute => ChainJoint::default().motion(joint.offset),
                JointKind::Prismatic => Transform {
                    translation_mm: [0.0, 0.0, joint.offset],
                    ..Transform::IDENTITY
                },
            };
            frames[j] = rows(&carry.compose(&origin).compose(&turn).compose(&offset));
            prismatic[j] = joint.kind == JointKind::Prismatic;
            carry = turn.inverse();
        }
        let tool = carry.compose(&chain.tool);
        let r = &tool.rotation;
        ReachChain {
            frames,
            prismatic,
            tool_mm: tool.translation_mm,
            tool_approach: [r[0][2], r[1][2], r[2][2]],
            tool_across: [r[0][0], r[1][0], r[2][0]],
        }
    }
}

impl ReachChain {
    /// Joint `j` of the walk from the tool back: `point` and, when `APPROACH`, the
    /// direction `approach`, from the joint's moving frame at joint value `value` (with
    /// `(sin, cos)` of it) into its parent's.
    #[inline(always)]
    fn step<const APPROACH: bool>(
        &self,
        j: usize,
        value: f64,
        (s, c): (f64, f64),
        point: &mut [f64; 3],
        approach: &mut [f64; 3],
    ) {
        let (s, c) = if self.prismatic[j] {
            point[2] += value;
            (0.0, 1.0)
        } else {
            (s, c)
        };
        let (p, a) = (*point, *approach);
        for (i, row) in self.frames[j].iter().enumerate() {
            let r = turned_row(row, s, c);
            point[i] = moved(&r, p);
            if APPROACH {
                approach[i] = rotated(&r, a);
            }
        }
    }
}

/// A frame's rows: the rotation's three entries, then the translation.
fn rows(frame: &Transform) -> [[f64; 4]; 3] {
    let (r, t) = (&frame.rotation, &frame.translation_mm);
    [0, 1, 2].map(|i| [r[i][0], r[i][1], r[i][2], t[i]])
}

/// A row of a joint's frame turned by its angle, of `Z · Rz(q)`, given `sin q` and `cos q`:
/// the first two columns mixed, the third and the translation as they are ([`ReachChain`];
/// a prismatic joint's frame is its row with `sin 0 = 0` and `cos 0 = 1`: itself, but for
/// the sign of a zero). Written once for one chain and for a [`Pair`] of them, so that
/// each lane is the one-chain walk's to the bit.
#[inline(always)]
fn turned_row<T: Lanes>(r: &[T; 4], s: T, c: T) -> [T; 4] {
    [r[0] * c + r[1] * s, r[1] * c - r[0] * s, r[2], r[3]]
}

/// Row `r` of a frame applied to a point: `r · p + t`, summed in pairs, so that the point
/// waits for a product and two sums.
#[inline(always)]
fn moved<T: Lanes>(r: &[T; 4], p: [T; 3]) -> T {
    (r[0] * p[0] + r[1] * p[1]) + (r[2] * p[2] + r[3])
}

/// Row `r` of a frame's rotation applied to a direction.
#[inline(always)]
fn rotated<T: Lanes>(r: &[T; 4], v: [T; 3]) -> T {
    (r[0] * v[0] + r[1] * v[1]) + r[2] * v[2]
}

/// A rotation taking z onto the unit vector `k` (its third column is `k`): the identity
/// for z itself, so that an MD-H chain's frames are not touched.
fn z_onto(k: [f64; 3]) -> [[f64; 3]; 3] {
    if k == [0.0, 0.0, 1.0] {
        return Transform::IDENTITY.rotation;
    }
    // Any unit vector across `k`: from the coordinate axis least along it.
    let helper = if k[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let along = dot(helper, k);
    let x = [0, 1, 2].map(|a| helper[a] - along * k[a]);
    let norm = dot(x, x).sqrt();
    let x = x.map(|v| v / norm);
    let y = cross(k, x);
    [0, 1, 2].map(|i| [x[i], y[i], k[i]])
}

/// One joint of a [`FoldedChain`]: `O · M(q + o) = [fixed + cos q · cos_part + sin q ·
/// sin_part | translation_mm + q · travel]`, in the parent link's frame (the base frame for
/// the first joint, the base folded in).
#[derive(Clone, Copy, Debug, PartialEq)]
struct FoldedJoint {
    fixed: [[f64; 3]; 3],
    cos_part: [[f64; 3]; 3],
    sin_part: [[f64; 3]; 3],
    translation_mm: [f64; 3],
    /// A prismatic joint's direction of travel (`O · k`); zero for a revolute joint.
    travel: [f64; 3],
    /// The joint's axis `O · k` and its position (the origin's translation, before the
    /// offset of a prismatic joint): what the gravity torque about it needs.
    axis: [f64; 3],
    origin_mm: [f64; 3],
    kind: JointKind,
}

/// The constant parts of a chain's gravity compliance ([`Compliance`]).
#[derive(Clone, Copy, Debug, PartialEq)]
struct FoldedGravity {
    gravity_mm_s2: [f64; 3],
    link_mass_kg: [f64; MAX_JOINTS],
    link_com_mm: [[f64; 3]; MAX_JOINTS],
    /// Per joint, the mass it carries (its link's, every later link's and the payload):
    /// `Σ_{k ≥ j} m_k`.
    carried_kg: [f64; MAX_JOINTS],
    payload_kg: f64,
    /// The payload's centre of mass in the last joint's frame after its motion (the tool
    /// folded in), mm.
    payload_com_mm: [f64; 3],
    compliance: [f64; MAX_JOINTS],
}

impl FoldedChain {
    /// The folded form of a valid chain.
    pub(crate) fn new(chain: &Chain) -> FoldedChain {
        let mut joints = [FoldedJoint::STILL; MAX_JOINTS];
        for (j, (out, joint)) in joints.iter_mut().zip(chain.joints()).enumerate() {
            let origin = if j == 0 {
                chain.base.compose(&joint.origin)
            } else {
                joint.origin
            };
            *out = FoldedJoint::new(&origin, joint);
        }
        let gravity = chain.compliance.map(|c| {
            let mut carried_kg = [0.0; MAX_JOINTS];
            let mut total_kg = c.payload_kg;
            for j in (0..chain.len).rev() {
                total_kg += c.link_mass_kg[j];
                carried_kg[j] = total_kg;
            }
            FoldedGravity {
                gravity_mm_s2: c.gravity_mm_s2,
                link_mass_kg: c.link_mass_kg,
                link_com_mm: c.link_com_mm,
                carried_kg,
                payload_kg: c.payload_kg,
                payload_com_mm: chain.tool.transform_point(c.payload_com_mm),
                compliance: c.compliance,
            }
        });
        let unit_axes = chain
            .joints()
            .iter()
            .all(|j| j.kind == JointKind::Prismatic || within(dot(j.axis, j.axis), 1.0, 1e-13));
        // Unit to a few units in the last place: a rotation built on such an axis is the
        // chains' own Rodrigues rotation to rounding.
        let exactly_unit = chain
            .joints()
            .iter()
            .all(|j| within(dot(j.axis, j.axis), 1.0, 4.0 * f64::EPSILON));
        FoldedChain {
            joints,
            len: chain.len,
            tool: chain.tool,
            gravity,
            unit_axes,
            reach: exactly_unit.then(|| ReachChain::new(chain)),
        }
    }

    /// The TCP's position, and its approach axis when `APPROACH` (zero otherwise), at
    /// joint values `q` given their sines and cosines, without compliance: what
    /// [`FoldedChain::tcp_pose`] gives of them, from the tool back to the base
    /// ([`ReachChain`]) when the chain has that form. Both slices hold at least the chain's
    /// joint count (the caller's check).
    #[inline]
    pub(crate) fn reach<const APPROACH: bool>(
        &self,
        q: &[f64],
        sin_cos: &[(f64, f64)],
    ) -> ([f64; 3], [f64; 3]) {
        let Some(z) = &self.reach else {
            let pose = self.tcp_pose(q, sin_cos);
            let r = &pose.rotation;
            let approach = if APPROACH {
                [r[0][2], r[1][2], r[2][2]]
            } else {
                [0.0; 3]
            };
            return (pose.translation_mm, approach);
        };
        let n = self.len.min(MAX_JOINTS).min(q.len()).min(sin_cos.len());
        let mut point = z.tool_mm;
        let mut approach = if APPROACH { z.tool_approach } else { [0.0; 3] };
        for j in (0..n).rev() {
            z.step::<APPROACH>(j, q[j], sin_cos[j], &mut point, &mut approach);
        }
        (point, approach)
    }

    /// [`FoldedChain::reach`] of two chains at the same joint values in one walk, which
    /// interleaves their independent arithmetic: `a`'s position and approach axis, and
    /// `b`'s position. `None` unless both have the [`ReachChain`] form, `b` has no gravity
    /// compliance, and they have the same joint count.
    #[inline]
    pub(crate) fn reach_pair(
        a: &FoldedChain,
        b: &FoldedChain,
        q: &[f64],
        sin_cos: &[(f64, f64)],
    ) -> Option<([f64; 3], [f64; 3], [f64; 3])> {
        let (Some(za), Some(zb)) = (&a.reach, &b.reach) else {
            return None;
        };
        if b.gravity.is_some() || a.len != b.len {
            return None;
        }
        let n = a.len.min(MAX_JOINTS).min(q.len()).min(sin_cos.len());
        let (mut point_a, mut approach) = (za.tool_mm, za.tool_approach);
        let (mut point_b, mut unused) = (zb.tool_mm, [0.0; 3]);
        for j in (0..n).rev() {
            za.step::<true>(j, q[j], sin_cos[j], &mut point_a, &mut approach);
            zb.step::<false>(j, q[j], sin_cos[j], &mut point_b, &mut unused);
        }
        Some((point_a, approach, point_b))
    }

    /// The TCP pose at joint values `q` given their sines and cosines
    /// (`sin_cos[j] = q[j].sin_cos()`), without compliance: [`Chain::tcp_pose`]. Both
    /// slices hold at least the chain's joint count (the caller's check).
    #[inline]
    pub(crate) fn tcp_pose(&self, q: &[f64], sin_cos: &[(f64, f64)]) -> Transform {
        let joints = &self.joints[..self.len.min(MAX_JOINTS)];
        let mut pose = Transform::IDENTITY;
        for (j, ((joint, &value), &sc)) in joints.iter().zip(q).zip(sin_cos).enumerate() {
            let link = joint.at(value, sc);
            pose = if j == 0 { link } else { pose.compose(&link) };
        }
        pose.compose(&self.tool)
    }

    /// The TCP pose deflected by gravity when the chain models compliance:
    /// [`Chain::loaded_tcp_pose`], from the sines and cosines of `q` as
    /// [`FoldedChain::tcp_pose`] takes them. (Queries take [`FoldedChain::loaded_tcp`].)
    #[cfg(test)]
    fn loaded_tcp_pose(&self, q: &[f64], sin_cos: &[(f64, f64)]) -> Transform {
        let (translation_mm, rotation) = self.loaded_tcp(q, sin_cos, true);
        Transform {
            rotation: rotation.unwrap_or(Transform::IDENTITY.rotation),
            translation_mm,
        }
    }

    /// [`FoldedChain::loaded_tcp_pose`]'s position, and its rotation when `rotation` (a
    /// table without orientations never reads it).
    ///
    /// The torques need the chain's poses at `q`; from them the deflection follows without
    /// a second pass down the chain. A joint turning by `Δ_j` more moves everything beyond
    /// it by the rotation `W_j` about the joint's axis in the base frame, through its
    /// position there, and `T(q + Δ) = W_1 · W_2 ⋯ W_n · T(q)`: this holds exactly for unit
    /// axes (rotations about one axis compose), so a chain with an axis farther than 1e-13
    /// from unit length takes the second pass instead.
    #[inline]
    pub(crate) fn loaded_tcp(
        &self,
        q: &[f64],
        sin_cos: &[(f64, f64)],
        rotation: bool,
    ) -> ([f64; 3], Option<[[f64; 3]; 3]>) {
        let Some(g) = &self.gravity else {
            if !rotation {
                return (self.reach::<false>(q, sin_cos).0, None);
            }
            let pose = self.tcp_pose(q, sin_cos);
            return (pose.translation_mm, rotation.then_some(pose.rotation));
        };
        let n = self.len.min(MAX_JOINTS).min(q.len()).min(sin_cos.len());
        let at_q = self.gravity_pass(q, sin_cos, g);
        let delta = |j: usize| g.compliance[j] * at_q.torques[j];
        if !self.unit_axes {
            let mut loaded = [0.0; MAX_JOINTS];
            let mut loaded_sin_cos = [(0.0, 1.0); MAX_JOINTS];
            for j in 0..n {
                loaded[j] = q[j] + delta(j);
                let (s, c) = sin_cos[j];
                let (sd, cd, _) = small_sin_cos(delta(j));
                loaded_sin_cos[j] = (s * cd + c * sd, c * cd - s * sd);
            }
            let pose = self.tcp_pose(&loaded[..n], &loaded_sin_cos[..n]);
            return (pose.translation_mm, rotation.then_some(pose.rotation));
        }
        let mut position_mm = at_q.tcp.translation_mm;
        // The rotation's columns, turned as directions.
        let r = &at_q.tcp.rotation;
        let mut columns = [0, 1, 2].map(|c| [r[0][c], r[1][c], r[2][c]]);
        for j in (0..n).rev() {
            let z = at_q.axes[j];
            match self.joints[j].kind {
                JointKind::Prismatic => {
                    for (p, zc) in position_mm.iter_mut().zip(z) {
                        *p += delta(j) * zc;
                    }
                }
                JointKind::Revolute => {
                    let (sd, _, versine) = small_sin_cos(delta(j));
                    let arm = [0, 1, 2].map(|a| position_mm[a] - at_q.joints_mm[j][a]);
                    position_mm = turned(position_mm, arm, z, sd, versine);
                    if rotation {
                        for column in &mut columns {
                            *column = turned(*column, *column, z, sd, versine);
                        }
                    }
                }
            }
        }
        let rotation = rotation.then(|| [0, 1, 2].map(|i| columns.map(|c| c[i])));
        (position_mm, rotation)
    }

    /// What the gravity torques need of the chain at `q`, and the torques
    /// ([`Chain::gravity_torques`]): one pass down the chain for the joints' positions and
    /// axes and the links' centres of mass, then the moments from suffix sums,
    /// `Σ_{k ≥ j} (p_k − a_j) × m_k g = (Σ_{k ≥ j} m_k p_k − M_j a_j) × g`.
    #[inline]
    fn gravity_pass(&self, q: &[f64], sin_cos: &[(f64, f64)], g: &FoldedGravity) -> GravityPass {
        let n = self.len.min(MAX_JOINTS).min(q.len()).min(sin_cos.len());
        let mut out = GravityPass {
            joints_mm: [[0.0; 3]; MAX_JOINTS],
            axes: [[0.0; 3]; MAX_JOINTS],
            torques: [0.0; MAX_JOINTS],
            tcp: Transform::IDENTITY,
        };
        let mut weighted_com = [[0.0; 3]; MAX_JOINTS];
        let mut pose = Transform::IDENTITY;
        for j in 0..n {
            let joint = &self.joints[j];
            out.joints_mm[j] = pose.transform_point(joint.origin_mm);
            out.axes[j] = pose.rotate_vector(joint.axis);
            let link = joint.at(q[j], sin_cos[j]);
            pose = if j == 0 { link } else { pose.compose(&link) };
            let com = pose.transform_point(g.link_com_mm[j]);
            weighted_com[j] = com.map(|v| v * g.link_mass_kg[j]);
        }
        let payload = pose.transform_point(g.payload_com_mm);
        out.tcp = pose.compose(&self.tool);
        let mut moment_sum = payload.map(|v| v * g.payload_kg);
        for j in (0..n).rev() {
            for (s, w) in moment_sum.iter_mut().zip(weighted_com[j]) {
                *s += w;
            }
            let about = match self.joints[j].kind {
                JointKind::Revolute => {
                    let arm =
                        [0, 1, 2].map(|a| moment_sum[a] - g.carried_kg[j] * out.joints_mm[j][a]);
                    cross(arm, g.gravity_mm_s2)
                }
                JointKind::Prismatic => g.gravity_mm_s2.map(|v| v * g.carried_kg[j]),
            };
            out.torques[j] = dot(about, out.axes[j]);
        }
        out
    }
}

/// A chain at joint values `q` as its gravity deflection needs it ([`FoldedChain::loaded_tcp`]),
/// base frame.
struct GravityPass {
    /// Each joint's position and axis.
    joints_mm: [[f64; 3]; MAX_JOINTS],
    axes: [[f64; 3]; MAX_JOINTS],
    /// The gravity torque about each joint.
    torques: [f64; MAX_JOINTS],
    /// The TCP's pose at `q`, undeflected.
    tcp: Transform,
}

/// `point` turned by a small angle about the unit axis `z` through `point − arm`, given the
/// angle's sine and versine (`1 − cos`): Rodrigues' formula written as the change it makes,
/// `point + sin · z × arm + versine · ((z · arm) z − arm)`, so that rounding scales with the
/// change rather than with the point.
#[inline]
fn turned(point: [f64; 3], arm: [f64; 3], z: [f64; 3], sin: f64, versine: f64) -> [f64; 3] {
    let across = cross(z, arm);
    let along = dot(z, arm);
    [0, 1, 2].map(|a| point[a] + (sin * across[a] + versine * (along * z[a] - arm[a])))
}

impl FoldedJoint {
    /// A joint that does not move: what unused slots hold.
    const STILL: FoldedJoint = FoldedJoint {
        fixed: Transform::IDENTITY.rotation,
        cos_part: [[0.0; 3]; 3],
        sin_part: [[0.0; 3]; 3],
        translation_mm: [0.0; 3],
        travel: [0.0; 3],
        axis: [0.0, 0.0, 1.0],
        origin_mm: [0.0; 3],
        kind: JointKind::Revolute,
    };

    /// `joint` behind `origin` (its own origin, or the base's composed with it).
    fn new(origin: &Transform, joint: &ChainJoint) -> FoldedJoint {
        let k = joint.axis;
        let axis = origin.rotate_vector(k);
        let r = &origin.rotation;
        // `r · m` for a 3 × 3 `m`.
        let times = |m: [[f64; 3]; 3]| -> [[f64; 3]; 3] {
            [0, 1, 2].map(|i| [0, 1, 2].map(|c| (0..3).map(|l| r[i][l] * m[l][c]).sum()))
        };
        match joint.kind {
            JointKind::Prismatic => FoldedJoint {
                fixed: *r,
                cos_part: [[0.0; 3]; 3],
                sin_part: [[0.0; 3]; 3],
                translation_mm: [0, 1, 2]
                    .map(|a| origin.translation_mm[a] + joint.offset * axis[a]),
                travel: axis,
                axis,
                origin_mm: origin.translation_mm,
                kind: JointKind::Prismatic,
            },
            JointKind::Revolute => {
                let outer = [0, 1, 2].map(|i| [0, 1, 2].map(|c| k[i] * k[c]));
                let rest = [0, 1, 2]
                    .map(|i| [0, 1, 2].map(|c| if i == c { 1.0 } else { 0.0 } - outer[i][c]));
                let skew = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
                // cos(q + o) = cos q cos o − sin q sin o, sin(q + o) = sin q cos o + cos q sin o.
                let (so, co) = joint.offset.sin_cos();
                let mix = |a: f64, b: f64| {
                    [0, 1, 2].map(|i| [0, 1, 2].map(|c| a * rest[i][c] + b * skew[i][c]))
                };
                FoldedJoint {
                    fixed: times(outer),
                    cos_part: times(mix(co, so)),
                    sin_part: times(mix(-so, co)),
                    translation_mm: origin.translation_mm,
                    travel: [0.0; 3],
                    axis,
                    origin_mm: origin.translation_mm,
                    kind: JointKind::Revolute,
                }
            }
        }
    }

    /// `O · M(q + o)` at joint value `q`, given `(sin q, cos q)`.
    #[inline]
    fn at(&self, q: f64, (s, c): (f64, f64)) -> Transform {
        let mut rotation = self.fixed;
        for ((out, cos_row), sin_row) in rotation.iter_mut().zip(&self.cos_part).zip(&self.sin_part)
        {
            for ((o, &a), &b) in out.iter_mut().zip(cos_row).zip(sin_row) {
                *o += c * a + s * b;
            }
        }
        Transform {
            rotation,
            translation_mm: [0, 1, 2].map(|a| self.translation_mm[a] + q * self.travel[a]),
        }
    }
}

/// `(sin x, cos x, 1 − cos x)` for the small angle a gravity deflection is: Taylor series
/// to `x⁷` and `x⁸`, exact to rounding for `|x| ≤ 2⁻⁶` (the next terms are below `2⁻⁶⁰`
/// relative), the versine without the cancellation of `1 − cos x`; `f64::sin_cos` beyond.
#[inline]
fn small_sin_cos(x: f64) -> (f64, f64, f64) {
    if x.abs() > 1.0 / 64.0 {
        let (sin, cos) = x.sin_cos();
        // 1 − cos = sin² / (1 + cos), without cancellation where cos is near 1.
        let versine = if cos > 0.0 {
            sin * sin / (1.0 + cos)
        } else {
            1.0 - cos
        };
        return (sin, cos, versine);
    }
    let x2 = x * x;
    let sin = x * (1.0 - x2 * (1.0 / 6.0) * (1.0 - x2 * (1.0 / 20.0) * (1.0 - x2 * (1.0 / 42.0))));
    let versine = x2
        * 0.5
        * (1.0 - x2 * (1.0 / 12.0) * (1.0 - x2 * (1.0 / 30.0) * (1.0 - x2 * (1.0 / 56.0))));
    (sin, 1.0 - versine, versine)
}

#[inline]
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline]
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Whether `r` is a rotation to 1e-9: `r·rᵀ = I` and `det r = 1`.
fn orthonormal(r: &[[f64; 3]; 3]) -> bool {
    for i in 0..3 {
        for j in 0..3 {
            let expected = if i == j { 1.0 } else { 0.0 };
            if !within(dot(r[i], r[j]), expected, 1e-9) {
                return false;
            }
        }
    }
    within(dot(r[0], cross(r[1], r[2])), 1.0, 1e-9)
}

/// `|value − expected| ≤ tolerance`; false for NaN.
fn within(value: f64, expected: f64, tolerance: f64) -> bool {
    (value - expected).abs() <= tolerance
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::forward;
    use proptest::prelude::*;

    fn kr150() -> [MdhJoint; 6] {
        use std::f64::consts::FRAC_PI_2;
        let j = |a_mm, d_mm, alpha_rad, beta_rad, theta_offset_rad| MdhJoint {
            a_mm,
            d_mm,
            alpha_rad,
            beta_rad,
            theta_offset_rad,
        };
        [
            j(350.0, 750.0, -FRAC_PI_2, 0.0, 0.0),
            j(1250.0, 0.0, 0.0, 0.002, 0.01),
            j(55.0, 0.0, FRAC_PI_2, 0.0, FRAC_PI_2),
            j(0.0, 1100.0, -FRAC_PI_2, 0.0, 0.0),
            j(0.0, 0.0, FRAC_PI_2, 0.0, -0.02),
            j(0.0, 230.0, 0.0, 0.0, 0.0),
        ]
    }

    fn close(a: &Transform, b: &Transform, tolerance_mm: f64) -> bool {
        let t = (0..3).all(|i| (a.translation_mm[i] - b.translation_mm[i]).abs() <= tolerance_mm);
        let r =
            (0..3).all(|i| (0..3).all(|j| (a.rotation[i][j] - b.rotation[i][j]).abs() <= 1e-12));
        t && r
    }

    #[test]
    fn an_mdh_chain_equals_the_mdh_forward_kinematics() {
        let joints = kr150();
        let tool = MdhJoint {
            a_mm: 12.0,
            d_mm: 180.0,
            alpha_rad: 0.3,
            beta_rad: 0.0,
            theta_offset_rad: 0.0,
        }
        .transform(0.2);
        let chain = Chain::from_mdh(Transform::IDENTITY, &joints, tool, None).unwrap();
        for q in [
            [0.0; 6],
            [0.1, -0.7, 1.2, 0.3, -0.4, 1.1],
            [-2.0, 0.4, -0.3, 2.9, 1.4, -3.0],
        ] {
            let want = forward(&joints, &tool, &q);
            let got = chain.tcp_pose(&q).unwrap();
            assert!(close(&got, &want, 1e-9), "{got:?} vs {want:?}");
        }
        assert!(chain.tcp_pose(&[0.0; 5]).is_none());
    }

    #[test]
    fn a_prismatic_joint_translates_along_its_axis() {
        let slide = ChainJoint {
            axis: [0.0, 1.0, 0.0],
            kind: JointKind::Prismatic,
            offset: 5.0,
            ..ChainJoint::default()
        };
        let chain = Chain::new(Transform::IDENTITY, &[slide], Transform::IDENTITY, None).unwrap();
        let pose = chain.tcp_pose(&[20.0]).unwrap();
        assert_eq!(pose.translation_mm, [0.0, 25.0, 0.0]);
    }

    #[test]
    fn a_horizontal_arm_bends_down_under_gravity() {
        // One revolute joint about the base y axis and a 1 kg point mass 1000 mm out along
        // x: the torque about y is ((1000, 0, 0) × (0, 0, −g)) · y = +1000 g, and a positive
        // rotation about y turns +x toward −z: the tip sags.
        let joint = ChainJoint {
            axis: [0.0, 1.0, 0.0],
            ..ChainJoint::default()
        };
        let mut compliance = Compliance::NONE;
        compliance.link_mass_kg[0] = 1.0;
        compliance.link_com_mm[0] = [1000.0, 0.0, 0.0];
        compliance.compliance[0] = 1e-9;
        let tool = Transform {
            translation_mm: [1000.0, 0.0, 0.0],
            ..Transform::IDENTITY
        };
        let chain = Chain::new(Transform::IDENTITY, &[joint], tool, Some(compliance)).unwrap();
        let torque = chain.gravity_torques(&[0.0], &compliance).unwrap();
        assert!((torque[0] - 1000.0 * STANDARD_GRAVITY_MM_S2).abs() < 1e-6);
        let loaded = chain.loaded_tcp_pose(&[0.0]).unwrap();
        // Rotating about +y by a small positive angle moves the tip to −z.
        assert!(loaded.translation_mm[2] < 0.0, "{loaded:?}");
        let expected_rad = 1e-9 * 1000.0 * STANDARD_GRAVITY_MM_S2;
        assert!((loaded.translation_mm[2] + 1000.0 * expected_rad.sin()).abs() < 1e-12);
    }

    #[test]
    fn invalid_chains_are_refused() {
        let bad_axis = ChainJoint {
            axis: [1.0, 1.0, 0.0],
            ..ChainJoint::default()
        };
        assert!(Chain::new(Transform::IDENTITY, &[bad_axis], Transform::IDENTITY, None).is_err());
        assert!(Chain::new(Transform::IDENTITY, &[], Transform::IDENTITY, None).is_err());
        let many = [ChainJoint::default(); MAX_JOINTS + 1];
        assert_eq!(
            Chain::new(Transform::IDENTITY, &many, Transform::IDENTITY, None),
            Err(ChainError::JointCount(MAX_JOINTS + 1))
        );
    }

    /// A rigid transform from a rotation vector (Rodrigues) and a translation.
    fn rigid(rotation_rad: [f64; 3], translation_mm: [f64; 3]) -> Transform {
        let joint = ChainJoint::default();
        let angle = dot(rotation_rad, rotation_rad).sqrt();
        let axis = if angle > 0.0 {
            rotation_rad.map(|v| v / angle)
        } else {
            [0.0, 0.0, 1.0]
        };
        Transform {
            translation_mm,
            ..ChainJoint { axis, ..joint }.motion(angle)
        }
    }

    fn unit(v: [f64; 3]) -> [f64; 3] {
        let n = dot(v, v).sqrt();
        if n < 1e-3 {
            [0.0, 0.0, 1.0]
        } else {
            v.map(|x| x / n)
        }
    }

    fn vec3(range: f64) -> impl Strategy<Value = [f64; 3]> {
        [-range..range, -range..range, -range..range]
    }

    prop_compose! {
        fn any_joint()(
            rotation in vec3(3.0),
            translation in vec3(600.0),
            axis in vec3(1.0),
            // Axes as long as validation admits, which the deflection by rotations about
            // them must notice (it holds for unit axes).
            axis_length in prop_oneof![Just(1.0), 1.0 - 9e-10..1.0 + 9e-10],
            prismatic in proptest::bool::weighted(0.2),
            offset in -1.0..1.0f64,
        ) -> ChainJoint {
            ChainJoint {
                origin: rigid(rotation, translation),
                axis: unit(axis).map(|v| v * axis_length),
                kind: if prismatic { JointKind::Prismatic } else { JointKind::Revolute },
                offset: if prismatic { offset * 100.0 } else { offset },
            }
        }
    }

    prop_compose! {
        fn any_chain()(
            joints in proptest::collection::vec(any_joint(), 1..=MAX_JOINTS),
            base in (vec3(3.0), vec3(500.0)),
            tool in (vec3(3.0), vec3(200.0)),
            masses in proptest::collection::vec(0.0..20.0f64, MAX_JOINTS),
            coms in proptest::collection::vec(vec3(300.0), MAX_JOINTS),
            payload in (0.0..10.0f64, vec3(100.0)),
            compliance in proptest::collection::vec(0.0..2e-10f64, MAX_JOINTS),
            compliant in proptest::bool::ANY,
        ) -> Chain {
            let mut c = Compliance::NONE;
            c.link_mass_kg.copy_from_slice(&masses);
            c.link_com_mm.copy_from_slice(&coms);
            (c.payload_kg, c.payload_com_mm) = payload;
            c.compliance.copy_from_slice(&compliance);
            for (j, joint) in joints.iter().enumerate() {
                if joint.kind == JointKind::Prismatic {
                    c.compliance[j] *= 1e-3;
                }
            }
            let (base, tool) = (rigid(base.0, base.1), rigid(tool.0, tool.1));
            Chain::new(base, &joints, tool, compliant.then_some(c)).unwrap()
        }
    }

    /// A unit-axis copy of `chain` without compliance, and the same with every frame
    /// moved by `moves` (a rotation vector, a translation and an offset each: the joints'
    /// origins, then the base and the tool), as a calibration moves them.
    fn nominal_and_moved(chain: &Chain, moves: &[([f64; 3], [f64; 3], f64)]) -> (Chain, Chain) {
        let unit_joints: Vec<ChainJoint> = chain
            .joints()
            .iter()
            .map(|j| ChainJoint {
                axis: unit(j.axis),
                ..*j
            })
            .collect();
        let nominal = Chain::new(chain.base, &unit_joints, chain.tool, None).unwrap();
        let moved_joints: Vec<ChainJoint> = unit_joints
            .iter()
            .zip(moves)
            .map(|(j, &(r, p, o))| ChainJoint {
                origin: j.origin.compose(&rigid(r, p)),
                offset: j.offset + o,
                ..*j
            })
            .collect();
        let moved = |t: &Transform, (r, p, _): ([f64; 3], [f64; 3], f64)| t.compose(&rigid(r, p));
        let calibrated = Chain::new(
            moved(&chain.base, moves[MAX_JOINTS]),
            &moved_joints,
            moved(&chain.tool, moves[MAX_JOINTS + 1]),
            None,
        )
        .unwrap();
        (nominal, calibrated)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        /// Two chains walked side by side ([`ReachPair`]) give what the walk of each gives
        /// ([`FoldedChain::reach_pair`]) to the bit: a calibrated chain is the nominal one
        /// with every frame moved a little, and any joint kinds.
        #[test]
        fn a_pair_of_chains_walks_as_each_chain_to_the_bit(
            chain in any_chain(),
            moves in proptest::collection::vec((vec3(0.01), vec3(2.0), -0.01..0.01f64), MAX_JOINTS + 2),
            q in proptest::collection::vec(-7.0..7.0f64, MAX_JOINTS),
        ) {
            let q = &q[..chain.joint_count()];
            let sin_cos: Vec<(f64, f64)> = q.iter().map(|v| v.sin_cos()).collect();
            let moved = |t: &Transform, (r, p, _): ([f64; 3], [f64; 3], f64)| t.compose(&rigid(r, p));
            let unit_joints: Vec<ChainJoint> = chain
                .joints()
                .iter()
                .map(|j| ChainJoint { axis: unit(j.axis), ..*j })
                .collect();
            let nominal = Chain::new(chain.base, &unit_joints, chain.tool, None).unwrap();
            let calibrated_joints: Vec<ChainJoint> = unit_joints
                .iter()
                .zip(&moves)
                .map(|(j, &(r, p, o))| ChainJoint {
                    origin: j.origin.compose(&rigid(r, p)),
                    offset: j.offset + o,
                    ..*j
                })
                .collect();
            let [base_move, tool_move] = [moves[MAX_JOINTS], moves[MAX_JOINTS + 1]];
            let calibrated = Chain::new(
                moved(&chain.base, base_move),
                &calibrated_joints,
                moved(&chain.tool, tool_move),
                chain.compliance,
            )
            .unwrap();
            let [a, b] = [FoldedChain::new(&nominal), FoldedChain::new(&calibrated)];
            let each = FoldedChain::reach_pair(&a, &b, q, &sin_cos);
            let pair = ReachPair::new(&a, &b);
            prop_assert_eq!(pair.is_some(), each.is_some());
            if let (Some(pair), Some(each)) = (pair, each) {
                let walked = pair.walk(q, &sin_cos);
                let bits = |v: [f64; 3]| v.map(f64::to_bits);
                prop_assert_eq!(
                    [bits(walked.0), bits(walked.1), bits(walked.2)],
                    [bits(each.0), bits(each.1), bits(each.2)]
                );
            }
        }

        /// Both chains' TCP frames from one walk ([`ReachPair::walk_posed`]): the point and
        /// approach axis to the bit as [`ReachPair::walk`] has them, and the model's values
        /// ([`PosedPair::model_at`]: the orientation error by the series or, beyond it, by
        /// the general logarithm) as the two chains' own forward kinematics and
        /// [`crate::kinematics::pose_error`] give them, to their rounding. Frames moved by up
        /// to `turn` rad about each axis, from a calibration's milliradians to 0.1 rad.
        #[test]
        fn a_posed_pair_walk_gives_the_chains_frames_and_their_orientation_error(
            chain in any_chain(),
            moves in proptest::collection::vec((vec3(1.0), vec3(2.0), -1.0..1.0f64), MAX_JOINTS + 2),
            turn in prop_oneof![Just(1e-4), Just(1e-3), Just(1e-2), Just(0.1)],
            q in proptest::collection::vec(-7.0..7.0f64, MAX_JOINTS),
        ) {
            let q = &q[..chain.joint_count()];
            let sin_cos: Vec<(f64, f64)> = q.iter().map(|v| v.sin_cos()).collect();
            let moves: Vec<_> = moves.iter().map(|&(r, p, o)| (r.map(|v| v * turn), p, o * turn)).collect();
            let (nominal, calibrated) = nominal_and_moved(&chain, &moves);
            let [a, b] = [FoldedChain::new(&nominal), FoldedChain::new(&calibrated)];
            let Some(pair) = ReachPair::new(&a, &b) else {
                return Ok(());
            };
            let posed = pair.walk_posed(q, &sin_cos);
            let walked = pair.walk(q, &sin_cos);
            let bits = |v: [f64; 3]| v.map(f64::to_bits);
            prop_assert_eq!(
                [bits(posed.a_mm), bits(posed.a_z), bits(posed.b_mm)],
                [bits(walked.0), bits(walked.1), bits(walked.2)]
            );
            let at = posed.model_at();
            let (reference_a, reference_b) = (nominal.tcp_pose(q).unwrap(), calibrated.tcp_pose(q).unwrap());
            let (position_mm, rotation_rad) = crate::kinematics::pose_error(&reference_a, &reference_b);
            let off = |x: [f64; 3], y: [f64; 3]| (0..3).map(|i| (x[i] - y[i]).abs()).fold(0.0, f64::max);
            let reach_mm = dot(reference_a.translation_mm, reference_a.translation_mm).sqrt()
                + chain.joints().iter().map(|j| dot(j.origin.translation_mm, j.origin.translation_mm).sqrt()).sum::<f64>()
                + 1000.0;
            let tolerance_mm = 1e-14 * reach_mm;
            prop_assert!(off(at.position_mm, position_mm) <= tolerance_mm, "{at:?} vs {position_mm:?}");
            prop_assert!(off(at.nominal_tcp_mm, reference_a.translation_mm) <= tolerance_mm);
            let r = &reference_a.rotation;
            let columns = |m: &[[f64; 3]; 3], c: usize| [m[0][c], m[1][c], m[2][c]];
            let rotation = at.nominal_rotation.unwrap();
            for c in 0..3 {
                prop_assert!(off(columns(&rotation, c), columns(r, c)) <= 1e-14, "{rotation:?} vs {r:?}");
            }
            prop_assert_eq!(at.approach, posed.a_z);
            prop_assert!(off(at.rotation_rad, rotation_rad) <= 4e-15, "{:?} vs {rotation_rad:?}", at.rotation_rad);
            // The query's form: the sines and cosines its own, and on a processor with AVX2
            // the four-lane walk, the two-lane one's to the bit.
            let narrow = pair.narrowed();
            let ours: Vec<(f64, f64)> = q.iter().map(|&v| crate::trig::sin_cos(v)).collect();
            let expected = narrow.walk_posed(q, &ours).model_at();
            prop_assert!(same_bits(&narrow.posed_model_at(q).unwrap(), &expected));
            prop_assert!(same_bits(&pair.posed_model_at(q).unwrap(), &expected));
            #[cfg(target_arch = "x86_64")]
            if avx::available() {
                // SAFETY: the processor has AVX2.
                let wide = unsafe { avx::posed_model_at(&pair, q) }.unwrap();
                prop_assert!(same_bits(&wide, &expected), "{wide:?} vs {expected:?}");
            }
        }

        /// The folded chain of the query path against the chain's own forward kinematics,
        /// joint by joint: any axes, prismatic joints, offsets, base, tool and compliance.
        #[test]
        fn a_folded_chain_equals_the_chain(
            chain in any_chain(),
            q in proptest::collection::vec(-7.0..7.0f64, MAX_JOINTS),
        ) {
            let q = &q[..chain.joint_count()];
            let sin_cos: Vec<(f64, f64)> = q.iter().map(|v| v.sin_cos()).collect();
            let folded = FoldedChain::new(&chain);
            // Rounding grows with the chain's size: some units in the last place of the
            // longest reach (one unit is 1.1e-13 mm at a metre), 4e-12 mm for an arm of a
            // metre.
            let norm = |v: [f64; 3]| dot(v, v).sqrt();
            let travel_mm: f64 = chain.joints().iter().zip(q).map(|(j, v)| match j.kind {
                JointKind::Prismatic => (v + j.offset).abs(),
                JointKind::Revolute => 0.0,
            }).sum();
            let reach_mm = norm(chain.base.translation_mm)
                + chain.joints().iter().map(|j| norm(j.origin.translation_mm)).sum::<f64>()
                + norm(chain.tool.translation_mm)
                + travel_mm;
            let tolerance_mm = 4e-15 * reach_mm.max(1000.0);
            let pairs = [
                (folded.tcp_pose(q, &sin_cos), chain.tcp_pose(q).unwrap()),
                (folded.loaded_tcp_pose(q, &sin_cos), chain.loaded_tcp_pose(q).unwrap()),
            ];
            for (fast, reference) in pairs {
                for a in 0..3 {
                    let off_mm = (fast.translation_mm[a] - reference.translation_mm[a]).abs();
                    prop_assert!(off_mm <= tolerance_mm, "{fast:?} vs {reference:?}");
                    for c in 0..3 {
                        let off = (fast.rotation[a][c] - reference.rotation[a][c]).abs();
                        prop_assert!(off <= 1e-14, "{fast:?} vs {reference:?}");
                    }
                }
            }
            // The position and approach axis alone, from the tool back (unit axes) or from
            // the pose (axes validation admits but the re-expression does not take).
            let unit_axes = chain.joints().iter().all(|j| (dot(j.axis, j.axis) - 1.0).abs() <= 4.0 * f64::EPSILON);
            prop_assert_eq!(folded.reach.is_some(), unit_axes);
            let reference = chain.tcp_pose(q).unwrap();
            let (tcp_mm, approach) = folded.reach::<true>(q, &sin_cos);
            let (alone_mm, no_approach) = folded.reach::<false>(q, &sin_cos);
            prop_assert_eq!(alone_mm, tcp_mm);
            prop_assert_eq!(no_approach, [0.0; 3]);
            let pair = FoldedChain::reach_pair(&folded, &folded, q, &sin_cos);
            prop_assert_eq!(pair.is_some(), unit_axes && chain.compliance.is_none());
            if let Some(pair) = pair {
                prop_assert_eq!(pair, (tcp_mm, approach, tcp_mm));
            }
            let loaded_mm = folded.loaded_tcp(q, &sin_cos, false).0;
            let loaded = chain.loaded_tcp_pose(q).unwrap();
            for a in 0..3 {
                let off_mm = (tcp_mm[a] - reference.translation_mm[a]).abs();
                prop_assert!(off_mm <= tolerance_mm, "{tcp_mm:?} vs {reference:?}");
                let off = (approach[a] - reference.rotation[a][2]).abs();
                prop_assert!(off <= 1e-14, "{approach:?} vs {reference:?}");
                let off_mm = (loaded_mm[a] - loaded.translation_mm[a]).abs();
                prop_assert!(off_mm <= tolerance_mm, "{loaded_mm:?} vs {loaded:?}");
            }
        }
    }

    #[test]
    fn an_mdh_chain_and_coordinate_axes_are_not_turned() {
        assert_eq!(z_onto([0.0, 0.0, 1.0]), Transform::IDENTITY.rotation);
        for k in [
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, -1.0],
            [0.0, -1.0, 0.0],
        ] {
            let q = z_onto(k);
            assert_eq!([q[0][2], q[1][2], q[2][2]], k);
            assert!(orthonormal(&q));
            // Exact: entries of 0 and ±1 only.
            assert!(
                q.iter().flatten().all(|v| [0.0, 1.0, -1.0].contains(v)),
                "{q:?}"
            );
        }
        let chain =
            Chain::from_mdh(Transform::IDENTITY, &kr150(), Transform::IDENTITY, None).unwrap();
        let reach = FoldedChain::new(&chain).reach.unwrap();
        for (j, joint) in chain.joints().iter().enumerate().skip(1) {
            // A z axis and no offset: the joint's own origin.
            if joint.offset == 0.0 {
                assert_eq!(reach.frames[j], rows(&joint.origin));
            }
        }
    }

    #[test]
    fn small_angles_have_their_sine_and_cosine() {
        for x in [0.0, 1e-300, 1e-9, -3e-5, 1e-3, 0.01, -1.0 / 64.0, 0.02, 1.5] {
            let (s, c, v) = small_sin_cos(x);
            let (ws, wc) = x.sin_cos();
            assert!((s - ws).abs() <= 2.0 * f64::EPSILON * ws.abs(), "{x}");
            assert!((c - wc).abs() <= f64::EPSILON, "{x}");
            // 1 − cos x = 2 sin²(x / 2), without cancellation.
            let half = (x / 2.0).sin();
            assert!(
                (v - 2.0 * half * half).abs() <= 4.0 * f64::EPSILON * v,
                "{x}"
            );
        }
        assert_eq!(small_sin_cos(0.0), (0.0, 1.0, 0.0));
    }
}
