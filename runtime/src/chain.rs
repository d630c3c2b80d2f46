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
}
