//! Orientation conventions: KUKA A, B, C angles, Fanuc W, P, R, roll-pitch-yaw, intrinsic
//! X-Y-Z Euler angles, quaternions, rotation matrices and rotation vectors.
//!
//! Sample files write orientations in the convention of their robot's controller (see
//! [`Convention`]). Every one of them is singular somewhere (KUKA's at B = ±90°, exactly where
//! the reference targets sit), so every computation holds orientations as rotation
//! matrices, and orientation *errors* as small rotation vectors (rad, base frame):
//! `δ = log(R_actual · R_nominalᵀ)`. This module is the one place where a convention becomes
//! a rotation.

use nalgebra::{Quaternion, Rotation3, UnitQuaternion, Vector3};

/// The rotation `Rz(A) · Ry(B) · Rx(C)` of KUKA angles given in degrees.
pub fn rotation_from_kuka_abc_deg(abc_deg: [f64; 3]) -> Rotation3<f64> {
    let [a, b, c] = abc_deg.map(f64::to_radians);
    rotation_zyx_rad(a, b, c)
}

/// The KUKA angles `[A, B, C]` (degrees) of a rotation, the inverse of
/// [`rotation_from_kuka_abc_deg`].
///
/// B is returned in [-90°, 90°] and A, C in (-180°, 180°]. At B = ±90° (gimbal lock) only
/// `A − C` (B = +90°) or `A + C` (B = −90°) is defined; the convention chosen there is
/// C = 0, so the whole turn about the base z axis goes into A. Near that singularity A and C
/// separately lose digits, but the rotation they rebuild stays exact, which is all a pose
/// needs: that is why orientations are carried as rotations and never as angle triples.
pub fn kuka_abc_deg_from_rotation(rotation: &Rotation3<f64>) -> [f64; 3] {
    let m = rotation.matrix();
    // R = Rz(A)·Ry(B)·Rx(C): first column (cA·cB, sA·cB, −sB), last row (−sB, cB·sC, cB·cC).
    let cos_b = m[(0, 0)].hypot(m[(1, 0)]);
    let b = (-m[(2, 0)]).atan2(cos_b);
    // Below this, cos B is rounding noise and A, C would be atan2 of noise.
    const GIMBAL_LOCK_COS_B: f64 = 1e-12;
    let (a, c) = if cos_b > GIMBAL_LOCK_COS_B {
        (m[(1, 0)].atan2(m[(0, 0)]), m[(2, 1)].atan2(m[(2, 2)]))
    } else {
        // With C = 0 the second column is Rz(A)·Ry(±90°)·y = (−sA, cA, 0).
        ((-m[(0, 1)]).atan2(m[(1, 1)]), 0.0)
    };
    [a.to_degrees(), b.to_degrees(), c.to_degrees()]
}

/// The rotation vector (axis × angle, rad) of a rotation: the logarithm map, computed by
/// the runtime's one implementation ([`adwi_runtime::kinematics::rotation_vector`]), which
/// keeps every digit of the small rotations that orientation errors are and stays exact up
/// to θ = π.
pub fn rotation_vector(rotation: &Rotation3<f64>) -> [f64; 3] {
    let m = rotation.matrix();
    adwi_runtime::kinematics::rotation_vector(&[0, 1, 2].map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]))
}

/// The rotation of a rotation vector (axis × angle, rad): the exponential map.
pub fn rotation_from_vector(rotation_vector_rad: [f64; 3]) -> Rotation3<f64> {
    Rotation3::from_scaled_axis(Vector3::from(rotation_vector_rad))
}

/// The base-frame orientation error `log(R_actual · R_nominalᵀ)`, rad.
pub fn orientation_error(nominal: &Rotation3<f64>, actual: &Rotation3<f64>) -> [f64; 3] {
    rotation_vector(&(actual * nominal.inverse()))
}

/// The rotation `Rz(z) · Ry(y) · Rx(x)` of three angles in radians: KUKA's `A, B, C` are
/// `z, y, x`, Fanuc's `W, P, R` are `x, y, z`, and so are roll, pitch and yaw.
pub fn rotation_zyx_rad(z: f64, y: f64, x: f64) -> Rotation3<f64> {
    // nalgebra's Euler angles are (roll about x, pitch about y, yaw about z) applied as
    // Rz(yaw) · Ry(pitch) · Rx(roll).
    Rotation3::from_euler_angles(x, y, z)
}

/// The rotation `Rx(x) · Ry(y) · Rz(z)` of intrinsic X-Y-Z Euler angles in radians: turn
/// about x, then about the turned y, then about the twice-turned z.
pub fn rotation_xyz_intrinsic_rad(x: f64, y: f64, z: f64) -> Rotation3<f64> {
    // Rx·Ry·Rz = (Rz(−z)·Ry(−y)·Rx(−x))ᵀ, nalgebra's order with the angles negated.
    Rotation3::from_euler_angles(-x, -y, -z).inverse()
}

/// The rotation of the quaternion `w + x i + y j + z k`, normalised first; `None` for the
/// zero quaternion (or one whose components are not finite), which is no rotation.
pub fn rotation_from_quaternion_wxyz(q: [f64; 4]) -> Option<Rotation3<f64>> {
    // Scaled by the largest component first, so that neither 1e-200 nor 1e200 components
    // underflow or overflow in the norm.
    let largest = q.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if !(q.iter().all(|v| v.is_finite()) && largest > 0.0) {
        return None;
    }
    let [w, x, y, z] = q.map(|v| v / largest);
    let unit = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z));
    Some(unit.to_rotation_matrix())
}

/// How an orientation is written: each robot maker's convention, with its angles in
/// radians (units are the reader's business) or its quaternion components.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Convention {
    /// KUKA `A, B, C`: `R = Rz(A) · Ry(B) · Rx(C)`.
    KukaAbc,
    /// A quaternion in ABB's order `q1, q2, q3, q4` = `w, x, y, z`; normalised.
    QuaternionWxyz,
    /// A quaternion in the order `x, y, z, w` (ROS, Eigen's storage); normalised.
    QuaternionXyzw,
    /// Fanuc `W, P, R`: `R = Rz(R) · Ry(P) · Rx(W)`.
    FanucWpr,
    /// Roll, pitch and yaw about the fixed x, y and z axes (extrinsic x-y-z):
    /// `R = Rz(yaw) · Ry(pitch) · Rx(roll)`.
    RollPitchYaw,
    /// Intrinsic X-Y-Z Euler angles `ex, ey, ez`: `R = Rx(ex) · Ry(ey) · Rz(ez)`.
    EulerXyz,
}

impl Convention {
    /// Every convention.
    pub const ALL: [Convention; 6] = [
        Convention::KukaAbc,
        Convention::QuaternionWxyz,
        Convention::QuaternionXyzw,
        Convention::FanucWpr,
        Convention::RollPitchYaw,
        Convention::EulerXyz,
    ];

    /// How many numbers write one orientation: 3 angles or 4 quaternion components.
    pub fn value_count(self) -> usize {
        if self.is_quaternion() {
            4
        } else {
            3
        }
    }

    /// Whether the numbers are quaternion components (no unit) rather than angles.
    pub fn is_quaternion(self) -> bool {
        matches!(
            self,
            Convention::QuaternionWxyz | Convention::QuaternionXyzw
        )
    }

    /// The rotation written by `values` ([`Convention::value_count`] of them, in the
    /// convention's order; angles in radians). `None` for a zero quaternion.
    ///
    /// # Panics
    ///
    /// When `values` does not hold [`Convention::value_count`] numbers.
    pub fn rotation(self, values: &[f64]) -> Option<Rotation3<f64>> {
        let n = self.value_count();
        assert_eq!(values.len(), n, "{self:?} takes {n} numbers");
        let v = values;
        match self {
            Convention::KukaAbc => Some(rotation_zyx_rad(v[0], v[1], v[2])),
            Convention::FanucWpr | Convention::RollPitchYaw => {
                Some(rotation_zyx_rad(v[2], v[1], v[0]))
            }
            Convention::EulerXyz => Some(rotation_xyz_intrinsic_rad(v[0], v[1], v[2])),
            Convention::QuaternionWxyz => rotation_from_quaternion_wxyz([v[0], v[1], v[2], v[3]]),
            Convention::QuaternionXyzw => rotation_from_quaternion_wxyz([v[3], v[0], v[1], v[2]]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn kuka_order_is_z_then_y_then_x() {
        let r = rotation_from_kuka_abc_deg([30.0, 20.0, 10.0]);
        let expected = Rotation3::from_axis_angle(&Vector3::z_axis(), 30f64.to_radians())
            * Rotation3::from_axis_angle(&Vector3::y_axis(), 20f64.to_radians())
            * Rotation3::from_axis_angle(&Vector3::x_axis(), 10f64.to_radians());
        assert_abs_diff_eq!(r.matrix(), expected.matrix(), epsilon = 1e-15);
    }

    #[test]
    fn b_90_points_the_tool_z_along_minus_base_x() {
        // Ry(90°) maps z to x... and x to -z: the paper's targets at A 0, B 90, C 0.
        let r = rotation_from_kuka_abc_deg([0.0, 90.0, 0.0]);
        assert_abs_diff_eq!(r * Vector3::z(), Vector3::x(), epsilon = 1e-15);
        assert_abs_diff_eq!(r * Vector3::x(), -Vector3::z(), epsilon = 1e-15);
    }

    #[test]
    fn orientation_error_round_trips_through_exp() {
        let nominal = rotation_from_kuka_abc_deg([10.0, 90.0, -35.0]);
        let delta = [1e-4, -2e-4, 3e-5];
        let actual = rotation_from_vector(delta) * nominal;
        let back = orientation_error(&nominal, &actual);
        for i in 0..3 {
            assert_abs_diff_eq!(back[i], delta[i], epsilon = 1e-15);
        }
    }

    /// Rebuilds the rotation from its KUKA angles and checks the matrices agree.
    fn assert_abc_round_trip(abc_deg: [f64; 3]) {
        let r = rotation_from_kuka_abc_deg(abc_deg);
        let back = kuka_abc_deg_from_rotation(&r);
        assert!(back[1].abs() <= 90.0, "B out of range: {back:?}");
        let rebuilt = rotation_from_kuka_abc_deg(back);
        assert_abs_diff_eq!(r.matrix(), rebuilt.matrix(), epsilon = 1e-14);
    }

    #[test]
    fn abc_round_trip_away_from_gimbal_lock_returns_the_same_angles() {
        for abc in [
            [30.0, 20.0, 10.0],
            [-170.0, -45.0, 120.0],
            [0.0, 89.0, -179.0],
        ] {
            let back = kuka_abc_deg_from_rotation(&rotation_from_kuka_abc_deg(abc));
            for i in 0..3 {
                assert_abs_diff_eq!(back[i], abc[i], epsilon = 1e-9);
            }
            assert_abc_round_trip(abc);
        }
    }

    #[test]
    fn abc_round_trip_at_b_plus_and_minus_90() {
        for b in [90.0, -90.0] {
            for (a, c) in [(0.0, 0.0), (35.0, -20.0), (-170.0, 150.0), (90.0, 90.0)] {
                assert_abc_round_trip([a, b, c]);
            }
        }
        // The paper's orientation A 0, B 90, C 0 comes back exactly as written.
        let back = kuka_abc_deg_from_rotation(&rotation_from_kuka_abc_deg([0.0, 90.0, 0.0]));
        assert_abs_diff_eq!(back[0], 0.0, epsilon = 1e-12);
        assert_abs_diff_eq!(back[1], 90.0, epsilon = 1e-12);
        assert_abs_diff_eq!(back[2], 0.0, epsilon = 1e-12);
        // At B = +90° only A − C matters: (35, 90, −20) is the same rotation as (55, 90, 0).
        let back = kuka_abc_deg_from_rotation(&rotation_from_kuka_abc_deg([35.0, 90.0, -20.0]));
        assert_abs_diff_eq!(back[0], 55.0, epsilon = 1e-9);
        assert_abs_diff_eq!(back[2], 0.0, epsilon = 1e-12);
    }

    #[test]
    fn abc_round_trip_just_off_gimbal_lock() {
        for b in [90.0 - 1e-7, -90.0 + 1e-9, 90.0 - 1e-13] {
            assert_abc_round_trip([12.0, b, -40.0]);
        }
    }

    #[test]
    fn rotation_vector_inverts_exp_from_tiny_angles_to_near_pi() {
        let axis = Vector3::new(0.3, -0.5, 0.8).normalize();
        for angle in [
            1e-12,
            1e-6,
            1e-4,
            0.5,
            2.0,
            2.9,
            std::f64::consts::PI - 1e-6,
        ] {
            let v = axis * angle;
            let back = rotation_vector(&rotation_from_vector([v.x, v.y, v.z]));
            // A tiny rotation keeps all its digits; within 1e-6 of a half turn the axis is
            // recovered from the symmetric part, which is good to about 1e-10.
            let tolerance = if angle < 3.0 {
                1e-14 * angle.max(1e-2)
            } else {
                1e-9
            };
            for i in 0..3 {
                assert_abs_diff_eq!(back[i], v[i], epsilon = tolerance);
            }
        }
    }

    fn about(axis: Vector3<f64>, angle_rad: f64) -> Rotation3<f64> {
        Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle_rad)
    }

    /// Angle triples in radians, gimbal lock included (±90° on the middle axis).
    const ANGLES: [[f64; 3]; 8] = [
        [0.3, -0.2, 1.1],
        [-2.9, 0.7, -0.4],
        [1.0, std::f64::consts::FRAC_PI_2, 0.5],
        [-0.7, -std::f64::consts::FRAC_PI_2, 2.0],
        [0.0, std::f64::consts::FRAC_PI_2 - 1e-9, 0.0],
        [3.1, 0.0, -3.1],
        [0.0, 0.0, 0.0],
        [std::f64::consts::PI, 0.1, -std::f64::consts::PI],
    ];

    #[test]
    fn fanuc_wpr_is_z_then_y_then_x_with_w_about_x() {
        for [w, p, r] in ANGLES {
            let expected = about(Vector3::z(), r) * about(Vector3::y(), p) * about(Vector3::x(), w);
            let got = Convention::FanucWpr.rotation(&[w, p, r]).unwrap();
            assert_abs_diff_eq!(got.matrix(), expected.matrix(), epsilon = 1e-15);
        }
    }

    #[test]
    fn roll_pitch_yaw_is_extrinsic_x_y_z() {
        for [roll, pitch, yaw] in ANGLES {
            let got = Convention::RollPitchYaw
                .rotation(&[roll, pitch, yaw])
                .unwrap();
            // nalgebra's own roll-pitch-yaw, and the product of the three turns about the
            // fixed axes, x first.
            let nalgebra = Rotation3::from_euler_angles(roll, pitch, yaw);
            let fixed_axes =
                about(Vector3::z(), yaw) * about(Vector3::y(), pitch) * about(Vector3::x(), roll);
            assert_abs_diff_eq!(got.matrix(), nalgebra.matrix(), epsilon = 1e-15);
            assert_abs_diff_eq!(got.matrix(), fixed_axes.matrix(), epsilon = 1e-15);
        }
    }

    #[test]
    fn euler_xyz_turns_about_the_moving_axes() {
        for [ex, ey, ez] in ANGLES {
            let got = Convention::EulerXyz.rotation(&[ex, ey, ez]).unwrap();
            let product =
                about(Vector3::x(), ex) * about(Vector3::y(), ey) * about(Vector3::z(), ez);
            // Turn about x, then about the turned frame's y, then about its z: each turn
            // about a base-frame axis, the current frame's axis.
            let r1 = about(Vector3::x(), ex);
            let r2 = about(r1 * Vector3::y(), ey) * r1;
            let r3 = about(r2 * Vector3::z(), ez) * r2;
            assert_abs_diff_eq!(got.matrix(), product.matrix(), epsilon = 1e-15);
            assert_abs_diff_eq!(got.matrix(), r3.matrix(), epsilon = 1e-14);
        }
    }

    /// The rotation matrix of a unit quaternion, written out.
    fn by_hand(w: f64, x: f64, y: f64, z: f64) -> nalgebra::Matrix3<f64> {
        nalgebra::Matrix3::new(
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        )
    }

    #[test]
    fn quaternions_in_both_orders_match_the_written_out_matrix() {
        for q in [
            [1.0, 0.0, 0.0, 0.0],
            [0.5, 0.5, 0.5, 0.5],
            [0.0, 1.0, 0.0, 0.0],
            [0.9, -0.1, 0.3, -0.2],
            [-0.2, 0.6, 0.1, 0.7],
        ] {
            let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            let [w, x, y, z] = q.map(|v| v / n);
            let expected = by_hand(w, x, y, z);
            let wxyz = Convention::QuaternionWxyz.rotation(&q).unwrap();
            let xyzw = Convention::QuaternionXyzw
                .rotation(&[q[1], q[2], q[3], q[0]])
                .unwrap();
            assert_abs_diff_eq!(*wxyz.matrix(), expected, epsilon = 1e-15);
            assert_abs_diff_eq!(*xyzw.matrix(), expected, epsilon = 1e-15);
            // Normalised: any positive or negative multiple is the same rotation, however
            // small or large its components.
            for scale in [-1.0, 3.0, 1e-200, 1e200, -1e-300] {
                let scaled = Convention::QuaternionWxyz
                    .rotation(&q.map(|v| v * scale))
                    .unwrap();
                assert_abs_diff_eq!(*scaled.matrix(), expected, epsilon = 1e-15);
            }
        }
        // A quarter turn about z: x goes to y.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let r = Convention::QuaternionWxyz
            .rotation(&[h, 0.0, 0.0, h])
            .unwrap();
        assert_abs_diff_eq!(r * Vector3::x(), Vector3::y(), epsilon = 1e-15);
    }

    #[test]
    fn a_zero_quaternion_is_no_rotation() {
        assert!(Convention::QuaternionWxyz.rotation(&[0.0; 4]).is_none());
        assert!(Convention::QuaternionXyzw
            .rotation(&[-0.0, 0.0, 0.0, 0.0])
            .is_none());
        assert!(rotation_from_quaternion_wxyz([f64::NAN, 1.0, 0.0, 0.0]).is_none());
        assert!(rotation_from_quaternion_wxyz([5e-324, 0.0, 0.0, 0.0]).is_some());
    }

    /// Each convention's numbers for a rotation, found independently of `Convention` (the
    /// angles by the KUKA extraction, exact up to gimbal lock, or by nalgebra's; the
    /// quaternion by nalgebra), rebuild the same rotation — also at gimbal lock, where the
    /// angles found differ from those written.
    #[test]
    fn every_convention_round_trips_through_independently_found_numbers() {
        let mut rotations: Vec<Rotation3<f64>> = ANGLES
            .iter()
            .map(|&[a, b, c]| {
                about(Vector3::z(), a) * about(Vector3::y(), b) * about(Vector3::x(), c)
            })
            .collect();
        rotations.extend(ANGLES.iter().map(|&[a, b, c]| {
            about(Vector3::x(), a) * about(Vector3::y(), b) * about(Vector3::z(), c)
        }));
        for r in rotations {
            // R = Rz(yaw)·Ry(pitch)·Rx(roll).
            let [yaw, pitch, roll] = kuka_abc_deg_from_rotation(&r).map(f64::to_radians);
            // Rᵀ = Rz(−ez)·Ry(−ey)·Rx(−ex) for R = Rx(ex)·Ry(ey)·Rz(ez).
            let [mz, my, mx] = kuka_abc_deg_from_rotation(&r.inverse()).map(f64::to_radians);
            // nalgebra's extraction loses digits within 1e-9 rad of gimbal lock.
            let (nroll, npitch, nyaw) = r.euler_angles();
            let nalgebra = Convention::RollPitchYaw
                .rotation(&[nroll, npitch, nyaw])
                .unwrap();
            assert_abs_diff_eq!(nalgebra.matrix(), r.matrix(), epsilon = 1e-8);
            let q = UnitQuaternion::from_rotation_matrix(&r);
            let (w, x, y, z) = (q.w, q.i, q.j, q.k);
            for (convention, values) in [
                (Convention::KukaAbc, vec![yaw, pitch, roll]),
                (Convention::FanucWpr, vec![roll, pitch, yaw]),
                (Convention::RollPitchYaw, vec![roll, pitch, yaw]),
                (Convention::EulerXyz, vec![-mx, -my, -mz]),
                (Convention::QuaternionWxyz, vec![w, x, y, z]),
                (Convention::QuaternionXyzw, vec![x, y, z, w]),
            ] {
                let back = convention.rotation(&values).unwrap();
                assert_abs_diff_eq!(back.matrix(), r.matrix(), epsilon = 1e-14);
            }
        }
    }
}
