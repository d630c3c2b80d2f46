//! Forward kinematics of a serial robot in the MD-H convention (Hayati-modified
//! Denavit-Hartenberg), on plain `f64` arrays.
//!
//! The link transform and [`forward`], the plain product of link transforms, are the one
//! geometry the compiler simulates and identifies with and the runtime's model is built
//! from. The served query walks its chain with its own fast form (`chain`, position and
//! rotation in one pass), which its tests hold equal to [`forward`], the slow, obvious
//! reference. Nothing here allocates or panics.
//!
//! The link transform of joint `i` is
//!
//! ```text
//! A_i = Rot(z, θ_i) · Trans(0, 0, d_i) · Trans(a_i, 0, 0) · Rot(x, α_i) · Rot(y, β_i)
//! ```
//!
//! with `θ_i = q_i + θ_offset_i`, `q_i` being the joint variable the controller commands.
//! The flange pose in the base frame is `A_1 · A_2 · … · A_n`, and the tool centre point
//! (TCP) pose is that times the tool transform. Standard Denavit-Hartenberg
//! (`Rz(θ) · Tz(d) · Tx(a) · Rx(α)`) is the special case `β = 0`.
//!
//! ```
//! use adwi_runtime::kinematics::{forward, MdhJoint, Transform};
//!
//! // A planar two-link arm: 1000 mm then 500 mm, both joints about the base z axis.
//! let link = |a_mm| MdhJoint { a_mm, ..MdhJoint::default() };
//! let joints = [link(1000.0), link(500.0)];
//! let tcp = forward(&joints, &Transform::IDENTITY, &[0.0, std::f64::consts::FRAC_PI_2]);
//! assert!((tcp.translation_mm[0] - 1000.0).abs() < 1e-9);
//! assert!((tcp.translation_mm[1] - 500.0).abs() < 1e-9);
//! ```

/// The geometry of one joint in the MD-H convention: lengths in mm, angles in radians.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MdhJoint {
    /// Link length `a`: translation along the rotated x axis, mm.
    pub a_mm: f64,
    /// Link offset `d`: translation along the joint's z axis, mm.
    pub d_mm: f64,
    /// Link twist `α` about the x axis, rad.
    pub alpha_rad: f64,
    /// Hayati twist `β` about the y axis, rad: keeps the model well conditioned where two
    /// consecutive axes are (nearly) parallel.
    pub beta_rad: f64,
    /// Constant added to the joint variable: `θ = q + theta_offset_rad`, rad.
    pub theta_offset_rad: f64,
}

impl MdhJoint {
    /// The link transform `A = Rz(θ) · Tz(d) · Tx(a) · Rx(α) · Ry(β)` for the joint
    /// variable `q_rad` (so `θ = q_rad + theta_offset_rad`).
    pub fn transform(&self, q_rad: f64) -> Transform {
        link_transform(
            self.a_mm,
            self.d_mm,
            self.alpha_rad.sin_cos(),
            self.beta_rad.sin_cos(),
            (q_rad + self.theta_offset_rad).sin_cos(),
        )
    }
}

/// `A = Rz(θ) · Tz(d) · Tx(a) · Rx(α) · Ry(β)` from the sines and cosines of α, β and θ:
/// the one closed form every link transform is computed with.
#[inline]
fn link_transform(
    a_mm: f64,
    d_mm: f64,
    (sa, ca): (f64, f64),
    (sb, cb): (f64, f64),
    (st, ct): (f64, f64),
) -> Transform {
    // The closed form of the product, as written out in docs/method.md §2.
    Transform {
        rotation: [
            [ct * cb - st * sa * sb, -st * ca, ct * sb + st * sa * cb],
            [st * cb + ct * sa * sb, ct * ca, st * sb - ct * sa * cb],
            [-ca * sb, sa, ca * cb],
        ],
        translation_mm: [a_mm * ct, a_mm * st, d_mm],
    }
}

/// A rigid transform (rotation and translation in mm): the pose of one frame in another.
///
/// It maps a point `p` given in the child frame to `rotation · p + translation_mm` in the
/// parent frame. Kept as plain arrays so that the runtime needs no linear-algebra crate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transform {
    /// Rotation matrix, row-major: `rotation[row][column]`. Its columns are the child
    /// frame's x, y, z axes expressed in the parent frame.
    pub rotation: [[f64; 3]; 3],
    /// Position of the child frame's origin in the parent frame, mm.
    pub translation_mm: [f64; 3],
}

impl Default for Transform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Transform {
    /// The transform that changes nothing.
    pub const IDENTITY: Transform = Transform {
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation_mm: [0.0, 0.0, 0.0],
    };

    /// The composition `self · other`: `other` is expressed in `self`'s child frame.
    #[inline]
    pub fn compose(&self, other: &Transform) -> Transform {
        let r = &self.rotation;
        let mut rotation = [[0.0; 3]; 3];
        for (row_out, row) in rotation.iter_mut().zip(r) {
            for (j, out) in row_out.iter_mut().enumerate() {
                *out = row[0] * other.rotation[0][j]
                    + row[1] * other.rotation[1][j]
                    + row[2] * other.rotation[2][j];
            }
        }
        Transform {
            rotation,
            translation_mm: self.transform_point(other.translation_mm),
        }
    }

    /// The inverse transform (rotation transposed, translation `-Rᵀ · t`).
    #[inline]
    pub fn inverse(&self) -> Transform {
        let r = &self.rotation;
        let rotation = [
            [r[0][0], r[1][0], r[2][0]],
            [r[0][1], r[1][1], r[2][1]],
            [r[0][2], r[1][2], r[2][2]],
        ];
        let t = self.translation_mm;
        let mut translation_mm = [0.0; 3];
        for (out, row) in translation_mm.iter_mut().zip(&rotation) {
            *out = -(row[0] * t[0] + row[1] * t[1] + row[2] * t[2]);
        }
        Transform {
            rotation,
            translation_mm,
        }
    }

    /// Maps a point (mm) from the child frame into the parent frame.
    #[inline]
    pub fn transform_point(&self, point_mm: [f64; 3]) -> [f64; 3] {
        let mut out = self.translation_mm;
        for (o, row) in out.iter_mut().zip(&self.rotation) {
            *o += row[0] * point_mm[0] + row[1] * point_mm[1] + row[2] * point_mm[2];
        }
        out
    }

    /// Rotates a direction from the child frame into the parent frame (no translation).
    #[inline]
    pub fn rotate_vector(&self, vector: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        [
            r[0][0] * vector[0] + r[0][1] * vector[1] + r[0][2] * vector[2],
            r[1][0] * vector[0] + r[1][1] * vector[1] + r[1][2] * vector[2],
            r[2][0] * vector[0] + r[2][1] * vector[1] + r[2][2] * vector[2],
        ]
    }
}

/// The pose of the tool centre point in the base frame: `A_1(q_1) · … · A_N(q_N) · tool`.
///
/// `tool` is the TCP in the flange frame; pass [`Transform::IDENTITY`] for the flange itself.
/// The arrays' common length `N` ties joint count and joint vector together at compile time,
/// so there is no length to check and nothing to fail.
pub fn forward<const N: usize>(
    joints: &[MdhJoint; N],
    tool: &Transform,
    q_rad: &[f64; N],
) -> Transform {
    let mut pose = Transform::IDENTITY;
    for (joint, &q) in joints.iter().zip(q_rad) {
        pose = pose.compose(&joint.transform(q));
    }
    pose.compose(tool)
}

/// The frames of every link in the base frame: element `i` is `A_1 · … · A_{i+1}`, the frame
/// that joint `i + 1` carries (so the last element is the flange).
///
/// Error models and Jacobians need every intermediate frame; computing them in one pass
/// costs the same as [`forward`].
pub fn link_frames<const N: usize>(joints: &[MdhJoint; N], q_rad: &[f64; N]) -> [Transform; N] {
    let mut frames = [Transform::IDENTITY; N];
    let mut pose = Transform::IDENTITY;
    for ((frame, joint), &q) in frames.iter_mut().zip(joints).zip(q_rad) {
        pose = pose.compose(&joint.transform(q));
        *frame = pose;
    }
    frames
}

/// The rotation matrix of rotation vector `v` (rad): Rodrigues' formula, the inverse of
/// [`rotation_vector`]. Near zero angle the series of `sin θ / θ` and `(1 − cos θ) / θ²`
/// keep full precision.
pub fn rotation_from_vector(v: [f64; 3]) -> [[f64; 3]; 3] {
    let theta2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    let (a, b) = exp_coefficients(theta2);
    let [x, y, z] = v;
    [
        [
            1.0 - b * (y * y + z * z),
            b * x * y - a * z,
            b * x * z + a * y,
        ],
        [
            b * x * y + a * z,
            1.0 - b * (x * x + z * z),
            b * y * z - a * x,
        ],
        [
            b * x * z - a * y,
            b * y * z + a * x,
            1.0 - b * (x * x + y * y),
        ],
    ]
}

/// `(Exp(v) − I) · u`: how rotation vector `v` moves the end of lever `u`, without
/// forming the matrix: `a (v × u) + b v × (v × u)` with Rodrigues' coefficients.
#[inline]
pub fn rotation_displacement(v: [f64; 3], u: [f64; 3]) -> [f64; 3] {
    let theta2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    let (a, b) = exp_coefficients(theta2);
    let c = cross(v, u);
    let cc = cross(v, c);
    [
        a * c[0] + b * cc[0],
        a * c[1] + b * cc[1],
        a * c[2] + b * cc[2],
    ]
}

/// Rodrigues' coefficients `sin θ / θ` and `(1 − cos θ) / θ²` of `θ² = |v|²`: their
/// series below 0.1 rad (truncation under 3e-14 relative), `sin_cos` above.
#[inline]
fn exp_coefficients(theta2: f64) -> (f64, f64) {
    if theta2 < 0.01 {
        let t2 = theta2;
        let a = 1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0));
        let b = 0.5 - t2 / 24.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0));
        (a, b)
    } else {
        let theta = theta2.sqrt();
        let (sin, cos) = crate::trig::sin_cos(theta);
        (sin / theta, (1.0 - cos) / theta2)
    }
}

/// `a × b`: the one cross product of the runtime.
#[inline]
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The rotation vector (axis × angle, rad) of a rotation matrix: the logarithm map,
/// allocation-free.
///
/// The skew part of `R` is `sin θ · axis` to full precision, so for the small rotations
/// that pose errors are the angle comes from `atan2(sin θ, cos θ)` and the vector from the
/// skew part (an angle from `acos` would lose half its digits). Near θ = π the skew part
/// vanishes; the axis then comes from the largest column of `R + I = 2 · axis · axisᵀ`
/// (for θ = π exactly), its sign from the skew part. Finite for every finite input.
#[inline]
pub fn rotation_vector(r: &[[f64; 3]; 3]) -> [f64; 3] {
    let sin_axis = [
        0.5 * (r[2][1] - r[1][2]),
        0.5 * (r[0][2] - r[2][0]),
        0.5 * (r[1][0] - r[0][1]),
    ];
    let sin_angle = norm(sin_axis);
    let cos_angle = 0.5 * (r[0][0] + r[1][1] + r[2][2] - 1.0);
    let angle = sin_angle.atan2(cos_angle);
    if cos_angle > -0.9 {
        // θ / sin θ → 1 as θ → 0; the series keeps it exact when sin θ underflows to 0.
        let scale = if sin_angle > 1e-8 {
            angle / sin_angle
        } else {
            1.0 + angle * angle / 6.0
        };
        return sin_axis.map(|v| v * scale);
    }
    // Near π: R + Rᵀ = 2 cos θ I + 2 (1 − cos θ) a aᵀ, so the symmetric part gives a aᵀ.
    let one_minus_cos = 1.0 - cos_angle;
    let outer = |i: usize, j: usize| {
        let delta = if i == j { 1.0 } else { 0.0 };
        (0.5 * (r[i][j] + r[j][i]) - cos_angle * delta) / one_minus_cos
    };
    let diagonal = [outer(0, 0), outer(1, 1), outer(2, 2)];
    let mut k = 0;
    for i in 1..3 {
        if diagonal[i] > diagonal[k] {
            k = i;
        }
    }
    let mut axis = [outer(0, k), outer(1, k), outer(2, k)];
    let length = norm(axis);
    if length > 0.0 {
        axis = axis.map(|v| v / length);
    }
    // The symmetric part fixes the axis up to sign; the skew part (sin θ · axis) the sign.
    let dot = axis[0] * sin_axis[0] + axis[1] * sin_axis[1] + axis[2] * sin_axis[2];
    if dot < 0.0 {
        axis = axis.map(|v| -v);
    }
    axis.map(|v| v * angle)
}

#[inline]
fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// The pose error of `actual` against `nominal`, both in one frame: position
/// `p_actual − p_nominal` (mm) and orientation `log(R_actual · R_nominalᵀ)` (rotation
/// vector, rad), in that frame. The one definition of a pose error: the runtime's model
/// part, the compiler's identification and its simulation all compute it here.
#[inline]
pub fn pose_error(nominal: &Transform, actual: &Transform) -> ([f64; 3], [f64; 3]) {
    let position_mm = [0, 1, 2].map(|a| actual.translation_mm[a] - nominal.translation_mm[a]);
    // R_act · R_nomᵀ: the rotation part of actual · nominal⁻¹.
    let relative = actual.compose(&nominal.inverse());
    (position_mm, rotation_vector(&relative.rotation))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    fn assert_close(actual: [f64; 3], expected: [f64; 3], tolerance: f64) {
        for i in 0..3 {
            assert!(
                (actual[i] - expected[i]).abs() <= tolerance,
                "component {i}: {actual:?} != {expected:?}"
            );
        }
    }

    /// KUKA KR150-2 nominal MD-H parameters of docs/method.md §2 (θ offsets zero).
    fn kr150() -> [MdhJoint; 6] {
        let j = |a_mm, d_mm, alpha_deg: f64| MdhJoint {
            a_mm,
            d_mm,
            alpha_rad: alpha_deg.to_radians(),
            ..MdhJoint::default()
        };
        [
            j(350.0, 750.0, -90.0),
            j(1250.0, 0.0, 0.0),
            j(55.0, 0.0, 90.0),
            j(0.0, 1100.0, -90.0),
            j(0.0, 0.0, 90.0),
            j(0.0, 230.0, 0.0),
        ]
    }

    #[test]
    fn link_transform_matches_the_product_of_elementary_transforms() {
        // With θ = 90°, α = 0, β = 90°: Rz(90) maps x→y, y→-x; Ry(90) maps z→x, x→-z.
        // R = Rz(90)·Ry(90): z → Rz(90)·x = y, x → Rz(90)·(-z) = -z, y → Rz(90)·y = -x.
        // Translation = Rz(90)·(a, 0, d) = (0, a, d).
        let joint = MdhJoint {
            a_mm: 10.0,
            d_mm: 20.0,
            alpha_rad: 0.0,
            beta_rad: FRAC_PI_2,
            theta_offset_rad: FRAC_PI_2,
        };
        let t = joint.transform(0.0);
        assert_close(t.rotate_vector([0.0, 0.0, 1.0]), [0.0, 1.0, 0.0], 1e-15);
        assert_close(t.rotate_vector([1.0, 0.0, 0.0]), [0.0, 0.0, -1.0], 1e-15);
        assert_close(t.rotate_vector([0.0, 1.0, 0.0]), [-1.0, 0.0, 0.0], 1e-15);
        assert_close(t.translation_mm, [0.0, 10.0, 20.0], 1e-12);
    }

    #[test]
    fn kr150_at_zero_by_hand() {
        // q = 0. Joint 1: origin (350, 0, 750); Rx(-90°) turns z1 into +y, y1 into -z.
        // Joint 2 (α 0): 1250 along x1 = +x → (1600, 0, 750).
        // Joint 3: 55 along x → (1655, 0, 750); Rx(+90°) about x turns z3 back to +z.
        // Joint 4: 1100 along z3 → wrist centre (1655, 0, 1850); Rx(-90°) then joint 5's
        // Rx(+90°) cancel, so z6 = z3 = +z; joint 6: 230 along z → flange (1655, 0, 2080).
        let flange = forward(&kr150(), &Transform::IDENTITY, &[0.0; 6]);
        assert_close(flange.translation_mm, [1655.0, 0.0, 2080.0], 1e-9);
        assert_close(
            flange.rotate_vector([0.0, 0.0, 1.0]),
            [0.0, 0.0, 1.0],
            1e-15,
        );
        assert_close(
            flange.rotate_vector([1.0, 0.0, 0.0]),
            [1.0, 0.0, 0.0],
            1e-15,
        );
    }

    #[test]
    fn kr150_first_axis_and_bent_elbow_by_hand() {
        // q1 = 90° swings the zero pose about the base z axis: (1655, 0, 2080) → (0, 1655, 2080).
        let mut q = [0.0; 6];
        q[0] = FRAC_PI_2;
        let flange = forward(&kr150(), &Transform::IDENTITY, &q);
        assert_close(flange.translation_mm, [0.0, 1655.0, 2080.0], 1e-9);

        // q3 = 90°: joints 2 and 3 turn about z1 = +y, and positive angles turn x toward
        // y1 = -z, i.e. downward. The forearm (along z3, vertical at q3 = 0) turns to +x:
        // elbow (1600, 0, 750); a3 = 55 now points down → (1600, 0, 695); then
        // d4 + d6 = 1330 along +x → flange (2930, 0, 695), tool z along +x.
        let mut q = [0.0; 6];
        q[2] = FRAC_PI_2;
        let flange = forward(&kr150(), &Transform::IDENTITY, &q);
        assert_close(flange.translation_mm, [2930.0, 0.0, 695.0], 1e-9);
        assert_close(
            flange.rotate_vector([0.0, 0.0, 1.0]),
            [1.0, 0.0, 0.0],
            1e-15,
        );
    }

    #[test]
    fn tool_and_link_frames_agree_with_forward() {
        let q = [0.1, -0.7, 2.2, 0.3, -0.4, 1.1];
        let tool = Transform {
            rotation: Transform::IDENTITY.rotation,
            translation_mm: [0.0, 0.0, 100.0],
        };
        let frames = link_frames(&kr150(), &q);
        let flange = forward(&kr150(), &Transform::IDENTITY, &q);
        assert_eq!(frames[5], flange);
        // The TCP lies 100 mm along the flange z axis.
        let tcp = forward(&kr150(), &tool, &q);
        let z = flange.rotate_vector([0.0, 0.0, 1.0]);
        let expected = [0, 1, 2].map(|i| flange.translation_mm[i] + 100.0 * z[i]);
        assert_close(tcp.translation_mm, expected, 1e-9);
    }

    #[test]
    fn inverse_undoes_compose() {
        let joint = MdhJoint {
            a_mm: 120.0,
            d_mm: -40.0,
            alpha_rad: 0.3,
            beta_rad: -0.2,
            theta_offset_rad: 0.1,
        };
        let t = joint.transform(0.9);
        let identity = t.compose(&t.inverse());
        for i in 0..3 {
            assert_close(identity.rotation[i], Transform::IDENTITY.rotation[i], 1e-15);
        }
        assert_close(identity.translation_mm, [0.0; 3], 1e-12);
    }

    /// `Exp(v)` by Rodrigues' formula, for checking the logarithm.
    fn exp(v: [f64; 3]) -> [[f64; 3]; 3] {
        let theta = norm(v);
        let k = if theta > 0.0 {
            v.map(|x| x / theta)
        } else {
            [0.0; 3]
        };
        let (s, c) = theta.sin_cos();
        let mut r = [[0.0; 3]; 3];
        let skew = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
        for i in 0..3 {
            for j in 0..3 {
                let delta = if i == j { 1.0 } else { 0.0 };
                r[i][j] = c * delta + s * skew[i][j] + (1.0 - c) * k[i] * k[j];
            }
        }
        r
    }

    #[test]
    fn logarithm_inverts_the_exponential_from_tiny_angles_to_pi() {
        let axes = [[1.0, 0.0, 0.0], [0.3, -0.5, 0.8], [-0.2, 0.9, 0.1]];
        for axis in axes {
            let unit = axis.map(|v| v / norm(axis));
            for angle in [
                0.0,
                1e-12,
                1e-6,
                1e-3,
                0.5,
                2.0,
                2.9,
                3.1,
                std::f64::consts::PI - 1e-7,
            ] {
                let v = unit.map(|x| x * angle);
                let back = rotation_vector(&exp(v));
                for a in 0..3 {
                    assert!(
                        (back[a] - v[a]).abs() < 1e-9 * angle.max(1e-3) + 1e-15,
                        "angle {angle}, axis {unit:?}: {back:?} vs {v:?}"
                    );
                }
            }
        }
    }
}
