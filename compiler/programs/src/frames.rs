//! The frame chain from a program's target to the point a table corrects, and back
//! (docs/programs.md, "Frames").
//!
//! A program commands the TCP of a tool in a work-object (base) frame; a table corrects the
//! point its samples measured, in the robot's base frame. With `W` the work object in the
//! robot's base frame, `T` the tool (TCP in the flange frame) and `M` the table's own tool
//! (its measured point in the flange frame):
//!
//! ```text
//! T_base_tcp  = W · T_wobj_target         the target in the base frame
//! flange      = T_base_tcp · T⁻¹
//! table point = flange · M                 what the table corrects
//! ```
//!
//! and the command for the table point is mapped back the same way:
//! `T_wobj_command = W⁻¹ · command · M⁻¹ · T`.

use nalgebra::{Isometry3, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::program::Orientation;

/// The frames of one use of a target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameChain {
    /// The work object (base) in the robot's base frame, `W`.
    pub base: Isometry3<f64>,
    /// The program's TCP in the flange frame, `T`.
    pub tool: Isometry3<f64>,
    /// The table's measured point in the flange frame, `M`.
    pub table_tool: Isometry3<f64>,
}

impl FrameChain {
    /// The table's point, base frame, for a target pose in the work object.
    pub fn table_point(&self, target: &Isometry3<f64>) -> Isometry3<f64> {
        self.base * target * self.tool.inverse() * self.table_tool
    }

    /// How far the program's TCP lies from the table's point, mm: the lever the robot's
    /// rotation error turns between them (`|(T⁻¹ · M).translation|`).
    pub fn lever_mm(&self) -> f64 {
        (self.tool.inverse() * self.table_tool)
            .translation
            .vector
            .norm()
    }

    /// The target pose in the work object that puts the table's point at `point`: the
    /// inverse of [`FrameChain::table_point`].
    pub fn program_pose(&self, point: &Isometry3<f64>) -> Isometry3<f64> {
        self.base.inverse() * point * self.table_tool.inverse() * self.tool
    }
}

/// A pose from KUKA `X, Y, Z` (mm) and `A, B, C` (degrees): `R = Rz(A)·Ry(B)·Rx(C)`.
pub fn kuka_pose(xyz_mm: [f64; 3], abc_deg: [f64; 3]) -> Isometry3<f64> {
    let r = adwi_samples::pose::rotation_from_kuka_abc_deg(abc_deg);
    Isometry3::from_parts(
        Translation3::from(Vector3::from(xyz_mm)),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// The rotation an orientation writes; `None` for a zero quaternion.
pub fn rotation_of(orientation: &Orientation) -> Option<Rotation3<f64>> {
    match orientation {
        Orientation::KukaAbcDeg(abc) => Some(adwi_samples::pose::rotation_from_kuka_abc_deg(
            abc.map(|n| n.value),
        )),
        Orientation::QuaternionWxyz(q) => {
            adwi_samples::pose::rotation_from_quaternion_wxyz(q.map(|n| n.value))
        }
        Orientation::RotationVectorRad(v) => {
            Some(adwi_samples::pose::rotation_from_vector(v.map(|n| n.value)))
        }
        Orientation::XyzIntrinsicDeg(v) => {
            Some(rotation_from_xyz_intrinsic_deg(v.map(|n| n.value)))
        }
    }
}

/// Stäubli's `R = Rx(rx)·Ry(ry)·Rz(rz)` (degrees): the transpose of KUKA's
/// `Rz(−rz)·Ry(−ry)·Rx(−rx)`.
pub fn rotation_from_xyz_intrinsic_deg(rxyz: [f64; 3]) -> Rotation3<f64> {
    adwi_samples::pose::rotation_from_kuka_abc_deg([-rxyz[2], -rxyz[1], -rxyz[0]]).inverse()
}

/// Stäubli angles of `rotation` nearest `original` (degrees), through
/// [`kuka_abc_near`] of the transpose: at ry = ±90°, where only rx ± rz is defined, the
/// written rx is kept.
pub fn xyz_intrinsic_near(rotation: &Rotation3<f64>, original: [f64; 3]) -> [f64; 3] {
    let [a, b, c] = kuka_abc_near(
        &rotation.inverse(),
        [-original[2], -original[1], -original[0]],
    );
    [-c, -b, -a].map(|v| if v == 0.0 { 0.0 } else { v })
}

/// The numbers that write `rotation` in `orientation`'s convention, chosen nearest the
/// numbers written now: at KUKA's gimbal lock (B = ±90°) C is kept and A takes the turn;
/// a quaternion keeps the sign of its written one; a rotation vector of a half turn or
/// more keeps the written axis's direction.
pub fn orientation_values(orientation: &Orientation, rotation: &Rotation3<f64>) -> Vec<f64> {
    match orientation {
        Orientation::KukaAbcDeg(abc) => kuka_abc_near(rotation, abc.map(|n| n.value)).to_vec(),
        Orientation::XyzIntrinsicDeg(v) => {
            xyz_intrinsic_near(rotation, v.map(|n| n.value)).to_vec()
        }
        Orientation::QuaternionWxyz(q) => {
            let unit = UnitQuaternion::from_rotation_matrix(rotation);
            let new = [unit.w, unit.i, unit.j, unit.k];
            let dot: f64 = new.iter().zip(q).map(|(a, b)| a * b.value).sum();
            let sign = if dot < 0.0 { -1.0 } else { 1.0 };
            new.map(|v| sign * v).to_vec()
        }
        Orientation::RotationVectorRad(v) => {
            let old = Vector3::from(v.map(|n| n.value));
            let new = Vector3::from(adwi_samples::pose::rotation_vector(rotation));
            let angle = new.norm();
            // The same rotation about the opposite axis, by 2π − θ.
            let other = if angle > 0.0 {
                -new * ((std::f64::consts::TAU - angle) / angle)
            } else {
                new
            };
            let best = if (other - old).norm() < (new - old).norm() {
                other
            } else {
                new
            };
            vec![best.x, best.y, best.z]
        }
    }
}

/// KUKA angles of `rotation` nearest `original` (degrees), so that a corrected target
/// is written in the range its program wrote it in: an angle written within ±180° stays
/// within (−180°, 180°], as a pendant writes it; one written beyond keeps the whole turns
/// that bring it nearest (a generator's `C -206.374` stays below −180°); and a B written
/// beyond ±90° takes the other triple of the same rotation, `A + 180°, 180° − B,
/// C + 180°`, the canonical one ([`adwi_samples::pose::kuka_abc_deg_from_rotation`])
/// otherwise. At gimbal lock, where only `A − C` (B = 90°) or `A + C` (B = −90°) is
/// defined, the written C is kept.
pub fn kuka_abc_near(rotation: &Rotation3<f64>, original: [f64; 3]) -> [f64; 3] {
    let [a, b, c] = adwi_samples::pose::kuka_abc_deg_from_rotation(rotation);
    let m = rotation.matrix();
    let cos_b = m[(0, 0)].hypot(m[(1, 0)]);
    let turned = |v: f64, written: f64| {
        if written.abs() <= 180.0 {
            v - 360.0 * ((v - 180.0) / 360.0).ceil()
        } else {
            v + 360.0 * ((written - v) / 360.0).round()
        }
    };
    if cos_b > 1e-12 || c != 0.0 {
        let [a, b, c] = if original[1].abs() > 90.0 {
            [a + 180.0, 180.0 - b, c + 180.0]
        } else {
            [a, b, c]
        };
        return [0, 1, 2].map(|k| turned([a, b, c][k], original[k]));
    }
    let keep = original[2];
    let a = if b > 0.0 { a + keep } else { a - keep };
    [turned(a, original[0]), b, keep]
}

/// The angle of the rotation between two rotations, rad.
pub fn angle_between(a: &Rotation3<f64>, b: &Rotation3<f64>) -> f64 {
    Vector3::from(adwi_samples::pose::rotation_vector(&(a * b.inverse()))).norm()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn pose(v: [f64; 6]) -> Isometry3<f64> {
        kuka_pose([v[0], v[1], v[2]], [v[3], v[4], v[5]])
    }

    /// The chain written out with 4×4 homogeneous matrices and a general matrix inverse:
    /// the slow reference of [`FrameChain`].
    fn homogeneous(p: &Isometry3<f64>) -> nalgebra::Matrix4<f64> {
        p.to_homogeneous()
    }

    fn pose_strategy() -> impl Strategy<Value = [f64; 6]> {
        (
            -3000.0..3000.0f64,
            -3000.0..3000.0f64,
            -3000.0..3000.0f64,
            -180.0..180.0f64,
            -90.0..90.0f64,
            -180.0..180.0f64,
        )
            .prop_map(|(a, b, c, d, e, f)| [a, b, c, d, e, f])
    }

    proptest! {
        #[test]
        fn the_chain_matches_homogeneous_matrices_and_round_trips(
            base in pose_strategy(), tool in pose_strategy(), table in pose_strategy(), target in pose_strategy()
        ) {
            let chain = FrameChain { base: pose(base), tool: pose(tool), table_tool: pose(table) };
            let target = pose(target);
            let point = chain.table_point(&target);
            let reference = homogeneous(&chain.base) * homogeneous(&target)
                * homogeneous(&chain.tool).try_inverse().unwrap() * homogeneous(&chain.table_tool);
            prop_assert!((point.to_homogeneous() - reference).abs().max() < 1e-8);
            let back = chain.program_pose(&point);
            prop_assert!((back.translation.vector - target.translation.vector).norm() < 1e-8);
            prop_assert!(angle_between(&back.rotation.to_rotation_matrix(), &target.rotation.to_rotation_matrix()) < 1e-12);
        }

        #[test]
        fn kuka_angles_near_the_written_ones_rebuild_the_rotation(abc in pose_strategy(), lock in 0..3u8) {
            let mut abc = [abc[3], abc[4], abc[5]];
            if lock == 1 { abc[1] = 90.0 } else if lock == 2 { abc[1] = -90.0 }
            let r = adwi_samples::pose::rotation_from_kuka_abc_deg(abc);
            let near = kuka_abc_near(&r, abc);
            let rebuilt = adwi_samples::pose::rotation_from_kuka_abc_deg(near);
            prop_assert!(angle_between(&r, &rebuilt) < 1e-9);
            if lock != 0 {
                prop_assert_eq!(near[2], abc[2]);
                let d = (near[0] - abc[0]).rem_euclid(360.0);
                prop_assert!(!(1e-6..=360.0 - 1e-6).contains(&d), "{near:?} {abc:?}");
            } else {
                // Away from gimbal lock, the written angles themselves.
                prop_assert!(near.iter().zip(&abc).all(|(n, w)| (n - w).abs() < 1e-6), "{near:?} {abc:?}");
            }
        }

        /// Angles written beyond ±180° (a generator's `C -206.374`), or in the branch of B
        /// beyond ±90°, come back as written, and a small turn of them stays in that
        /// branch; angles written within ±180° stay within (a pendant's −179.97° turned
        /// past −180° is written 179.97°, never −180.03°).
        #[test]
        fn kuka_angles_keep_the_range_they_are_written_in(
            abc in pose_strategy(), turns in -1..=1i32, other in proptest::bool::ANY, small in -0.05..0.05f64
        ) {
            // B kept 0.9° from ±90°, where the small turn below would change its branch.
            let canonical = [abc[3], abc[4] / 2.0 * 0.99, abc[5]];
            let written = if other {
                [canonical[0] + 180.0, 180.0 - canonical[1], canonical[2] + 180.0]
            } else {
                canonical
            };
            let written = [written[0] + 360.0 * f64::from(turns), written[1], written[2] - 360.0 * f64::from(turns)];
            let r = adwi_samples::pose::rotation_from_kuka_abc_deg(written);
            let within = |v: f64, w: f64| if w.abs() <= 180.0 { v - 360.0 * ((v - 180.0) / 360.0).ceil() } else { v };
            let expected = [0, 1, 2].map(|k| within(written[k], written[k]));
            let near = kuka_abc_near(&r, written);
            prop_assert!(near.iter().zip(&expected).all(|(n, w)| (n - w).abs() < 1e-6), "{near:?} {written:?}");
            let moved = [written[0] + small, written[1] - small, written[2] + small];
            let near = kuka_abc_near(&adwi_samples::pose::rotation_from_kuka_abc_deg(moved), written);
            let rebuilt = adwi_samples::pose::rotation_from_kuka_abc_deg(near);
            prop_assert!(angle_between(&rebuilt, &adwi_samples::pose::rotation_from_kuka_abc_deg(moved)) < 1e-9);
            for k in 0..3 {
                if written[k].abs() <= 180.0 {
                    prop_assert!(near[k] > -180.0 && near[k] <= 180.0, "{near:?} {written:?}");
                }
                let d = (near[k] - moved[k]).rem_euclid(360.0);
                prop_assert!(!(1e-6..=360.0 - 1e-6).contains(&d), "{near:?} {moved:?}");
            }
        }
    }
}
