//! Orientation conventions: KUKA A, B, C angles, rotation matrices and rotation vectors.
//!
//! Users type orientations as KUKA A, B, C in degrees, `R = Rz(A) · Ry(B) · Rx(C)`. That
//! convention is singular at B = ±90°, exactly where the reference targets sit, so every
//! computation holds orientations as rotation matrices, and orientation *errors* as small
//! rotation vectors (rad, base frame): `δ = log(R_actual · R_nominalᵀ)`.

use nalgebra::{Rotation3, Vector3};

/// The rotation `Rz(A) · Ry(B) · Rx(C)` of KUKA angles given in degrees.
pub fn rotation_from_kuka_abc_deg(abc_deg: [f64; 3]) -> Rotation3<f64> {
    let [a, b, c] = abc_deg.map(f64::to_radians);
    // nalgebra's Euler angles are (roll about x, pitch about y, yaw about z) applied as
    // Rz(yaw) · Ry(pitch) · Rx(roll): the KUKA order.
    Rotation3::from_euler_angles(c, b, a)
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
}
