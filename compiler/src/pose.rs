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

/// The rotation vector (axis × angle, rad) of a rotation: the logarithm map.
pub fn rotation_vector(rotation: &Rotation3<f64>) -> [f64; 3] {
    let v = rotation.scaled_axis();
    [v.x, v.y, v.z]
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
}
