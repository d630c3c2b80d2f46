//! Inverse kinematics: every configuration of a six-axis robot with a spherical wrist (KUKA
//! KR150-2 and the like) in closed form, each refined by Newton steps on the exact model; and
//! for any other robot of six or more joints (an offset wrist, seven axes) one solution by
//! damped least squares from a seed posture ([`solve_near`]).
//!
//! # Configurations
//!
//! A pose is reached by up to eight joint vectors. Each is labelled by a [`Configuration`],
//! an integer of three bits:
//!
//! - bit 0, **shoulder**: 0 *front*, 1 *back*. Front when joint 1's x axis (from the base
//!   axis toward joint 2) points toward the wrist centre's horizontal direction, back when
//!   the arm reaches over behind itself.
//! - bit 1, **elbow**: 0 *up*, 1 *down*: the side the arm bends to. Up when the elbow
//!   (joint 3's axis) lies above the line from the shoulder (joint 2's axis) to the wrist
//!   centre, seen in the arm's vertical plane (normal to joint 2's axis; through the base
//!   axis unless the arm is offset sideways) with the horizontal axis along joint 1's x axis,
//!   the arm's front, whichever side the wrist centre is on. So an arm reaching over behind
//!   itself keeps the label of its bend as a front posture shows it (the elbow may then be
//!   the lower), as ABB's cfx ("the wrist centre behind the lower arm"), KUKA's status bit
//!   1 and Fanuc's U/D (both from J3 alone) count it. Above is along joint 1's axis, or
//!   against it where that axis points down in the robot's base frame (a URDF that turns
//!   joint 1 about −z, as KUKA counts A1).
//! - bit 2, **wrist**: 0 *no flip*, 1 *flip*. Flip when joint 5's value is negative, as the
//!   robot file counts it and the controller writes it (KUKA's A5 < 0, Fanuc's `F`): the
//!   wrist's singularity is at J5 = 0°, where θ5 = q5 + its offset is 0° or 180°, so flip is
//!   `sin θ5 < 0` with an offset of 0° and `sin θ5 > 0` with one of 180° (a file that puts
//!   J5's zero elsewhere has no labels).
//!
//! The labels are geometric, so they change only where the robot passes a singularity
//! (wrist centre on axis 1, arm stretched or folded, axes 4 and 6 aligned).
//!
//! # Closed form
//!
//! A robot given by its joints' origins and axes (a URDF) is read in its MD-H form
//! ([`crate::mdh_form`]: the same kinematics, written as rows), so that it has the closed
//! form and the labels wherever its geometry has them. Where joints 1 and 2 meet (a1 = 0),
//! that form's frame 1 x axis (which then says the shoulder's front) points where the arm
//! reaches at the home posture, or, upright there, where a positive J2 leans it.
//!
//! The closed form assumes the *skeleton* of the nominal model: six MD-H joints with α1, α3,
//! α4, α5 = ±90°, α2 = 0, all β = 0, a4 = a5 = a6 = d5 = 0 (α2 = 180°, a J3 that turns
//! against J2 as Fanuc and Yaskawa count it, is the same skeleton with q3 counted the other
//! way, `Rx(π)·Rz(θ3)·Tz(d3) = Rz(−θ3)·Tz(−d3)·Rx(π)`). Joints 2 and 3 are then parallel,
//! and axes 4, 5, 6 meet at the wrist centre, which decouples position (joints 1-3 place the
//! wrist centre) from orientation (joints 4-6 are a Z-X-Z-like Euler triple). The model
//! actually used — a nominal β2, or a calibrated model with all 30 deviations — differs
//! slightly from the skeleton, so every closed-form solution is refined by Newton steps on
//! that exact model (the runtime's chain with the geometric Jacobian), keeping the
//! skeleton's configuration label. Solutions outside the joint limits are dropped; joints
//! with more than a full turn of travel are taken at the representative `q + 2πk` closest
//! to the robot's home posture.
//!
//! # Redundancy resolution (seven axes and more; any robot without the closed form)
//!
//! [`solve_near`] finds, of the postures that reach a pose, the one nearest a seed posture
//! (the robot's home, say) in joint space, in two stages:
//!
//! 1. onto the pose from the seed: damped least-squares steps `Δq = Jᵀ(JJᵀ + λ²I)⁻¹e`
//!    (orientation rows weighted by [`ORIENTATION_WEIGHT_MM_PER_RAD`], λ = 10⁻³ of J's
//!    largest singular value, each joint moving at most [`MAX_STEP`] per step), undamped
//!    minimum-norm Newton steps once within 1 µm, until the pose is reached to
//!    [`POSITION_TOLERANCE_MM`] and [`ORIENTATION_TOLERANCE_RAD`];
//! 2. along the self-motion toward the seed: the seed's pull projected into J's null space,
//!    `(I − J⁺J)(q_seed − q)` (the joint motion that does not move the TCP, to first
//!    order), then stage 1 again from there to come back onto the pose; a step is kept when
//!    it brings the posture closer to the seed, halved otherwise, until the pull vanishes.
//!
//! At the end the pose is exact and `q − q_seed` has no part in the null space: the posture
//! is a stationary point of the joint-space distance to the seed on the set of postures
//! that reach the pose — locally the nearest one. A six-joint robot has no null space: the
//! solution is the one stage 1 reaches from the seed. When stage 1 does not converge or the
//! posture breaks a joint limit (a seed at a singularity may lead onto a branch that does),
//! [`FURTHER_SEEDS`] starting postures drawn within the joint ranges (from a fixed seed: the
//! answer is deterministic) take the two stages, walking toward the original seed, and the
//! within-limits posture nearest the original seed is returned; none when no start gives one.
//! Distances are Euclidean in joint space (rad, and mm for prismatic joints).
//!
//! # Starting near the pose (many poses, any posture)
//!
//! [`solve_near`] from a far seed is slow: from the iiwa's stretched home a pose in front
//! of it took about 2,400 damped steps and 1,000 steps along the self-motion (40 ms), most
//! of them in the [`FURTHER_SEEDS`] restarts, since the posture nearest home bends joint 6
//! past its limit for more than half of those poses. Where any posture within the limits
//! will do (the candidates of a measurement plan), a [`PostureTable`] draws
//! [`TABLE_POSTURES`] postures within the limits once, and solves a pose by stage 1 alone
//! from the drawn postures whose TCP poses are nearest it, nearest first, taking the first
//! that ends within the limits: about ten steps (0.3–0.5 ms), deterministic since the
//! table is drawn from a fixed seed. The posture found is not the one nearest home.

use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::fmt;

use adwi_runtime::chain::Chain;
use adwi_runtime::kinematics::{link_frames, MdhJoint, Transform};
use nalgebra::{DMatrix, DVector, Isometry3, Rotation3, UnitQuaternion, Vector3, Vector6};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::error_model::{joint_jacobian, transform_pose_error};
use super::mdh_form::mdh_form;
use super::model::{isometry_from_transform, rotation_of, transform_from_isometry, Robot};

/// The joint count of the robots the closed form solves.
pub const JOINT_COUNT: usize = 6;

/// An inverse-kinematics branch: bit 0 shoulder (front 0 / back 1), bit 1 elbow (up 0 /
/// down 1), bit 2 wrist (no flip 0 / flip 1). See the module docs for the geometry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Configuration(u8);

impl Configuration {
    /// Shoulder back (bit 0).
    pub const SHOULDER_BACK: u8 = 1;
    /// Elbow down (bit 1).
    pub const ELBOW_DOWN: u8 = 2;
    /// Wrist flipped (bit 2).
    pub const WRIST_FLIP: u8 = 4;

    /// The configuration of an integer 0..=7, `None` for anything else.
    pub fn from_bits(bits: u8) -> Option<Configuration> {
        (bits < 8).then_some(Configuration(bits))
    }

    fn new(shoulder_back: bool, elbow_down: bool, wrist_flip: bool) -> Configuration {
        Configuration(
            u8::from(shoulder_back) * Self::SHOULDER_BACK
                + u8::from(elbow_down) * Self::ELBOW_DOWN
                + u8::from(wrist_flip) * Self::WRIST_FLIP,
        )
    }

    /// The integer 0..=7 written to sample files.
    pub fn bits(self) -> u8 {
        self.0
    }

    /// Whether the arm reaches over behind joint 1.
    pub fn shoulder_back(self) -> bool {
        self.0 & Self::SHOULDER_BACK != 0
    }

    /// Whether the elbow is below the shoulder–wrist line.
    pub fn elbow_down(self) -> bool {
        self.0 & Self::ELBOW_DOWN != 0
    }

    /// Whether joint 5 bends to its negative side.
    pub fn wrist_flip(self) -> bool {
        self.0 & Self::WRIST_FLIP != 0
    }
}

impl fmt::Display for Configuration {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} (shoulder {}, elbow {}, wrist {})",
            self.0,
            if self.shoulder_back() {
                "back"
            } else {
                "front"
            },
            if self.elbow_down() { "down" } else { "up" },
            if self.wrist_flip() { "flip" } else { "no flip" }
        )
    }
}

/// One joint vector reaching the requested pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkSolution {
    /// Joint variables, rad, within the robot's limits.
    pub q_rad: [f64; JOINT_COUNT],
    /// Its branch.
    pub config: Configuration,
}

/// Why a robot has no closed-form inverse here.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IkError {
    /// The nominal geometry is not the spherical-wrist structure the closed form needs.
    #[error(
        "{robot}: no closed-form inverse kinematics: {reason} \
         (needs six MD-H joints with α1, α3, α4, α5 = ±90°, α2 = 0° or 180°, β = 0, \
         a4 = a5 = a6 = d5 = 0, a2 > 0)"
    )]
    UnsupportedGeometry {
        /// Robot name.
        robot: String,
        /// Which parameter breaks the structure.
        reason: String,
    },
}

/// The angle tolerance within which a nominal twist is taken as its skeleton's ±90° or 0°.
const SKELETON_ANGLE_TOLERANCE_RAD: f64 = 0.5 * PI / 180.0;
/// The length within which a nominal offset is taken as the skeleton's zero, mm.
const SKELETON_LENGTH_TOLERANCE_MM: f64 = 1.0;
/// How far beyond the skeleton's reach a wrist centre may lie and still be tried, mm.
const SKELETON_REACH_SLACK_MM: f64 = 10.0;
/// The least elbow bend a candidate starts from, so that Newton starts on the right side
/// of a stretched arm, rad.
const MIN_ELBOW_BEND_RAD: f64 = 1e-3;
/// Newton stops when a step moves every joint by less than this, rad.
const NEWTON_STEP_TOLERANCE_RAD: f64 = 1e-13;
/// Newton steps allowed per solution; from the skeleton's solution it needs two or three.
const NEWTON_MAX_STEPS: usize = 20;
/// A refined solution is kept only if its TCP is this close to the target, mm.
pub const POSITION_TOLERANCE_MM: f64 = 1e-9;
/// A refined solution is kept only if its orientation is this close to the target, rad.
pub const ORIENTATION_TOLERANCE_RAD: f64 = 1e-12;

/// Closed-form inverse kinematics of one robot, with Newton refinement on an exact model.
#[derive(Debug, Clone)]
pub struct InverseKinematics {
    robot: Robot,
    /// The robot's nominal kinematics in MD-H: its file's rows, or the rows written from
    /// its chain's axes (a URDF robot, [`mdh_form`]).
    model: NominalModel,
    /// The nominal model idealised to the structure the closed form solves.
    skeleton: [MdhJoint; JOINT_COUNT],
    /// ±1: the sign of sin α of joints 1, 3, 4, 5 in the skeleton.
    sin_alpha: [f64; JOINT_COUNT],
    /// Whether the robot's J3 turns against its J2 (α2 = 180°, as Fanuc and Yaskawa count
    /// J3): the skeleton then counts q3 the other way (`Rx(π)·Rz(θ3)·Tz(d3) =
    /// Rz(−θ3)·Tz(−d3)·Rx(π)`, the half turn passed on to α3).
    j3_reversed: bool,
}

impl InverseKinematics {
    /// Prepares the closed form for `robot`.
    ///
    /// # Errors
    ///
    /// [`IkError::UnsupportedGeometry`] when the nominal model is not (within 0.5° and
    /// 1 mm) a spherical-wrist arm with parallel joints 2 and 3.
    pub fn new(robot: &Robot) -> Result<InverseKinematics, IkError> {
        let unsupported = |reason: String| IkError::UnsupportedGeometry {
            robot: robot.name.clone(),
            reason: match robot.mdh() {
                Some(_) => reason,
                None => format!("its joints in MD-H form: {reason}"),
            },
        };
        let model = nominal_model(robot).map_err(unsupported)?;
        let mut skeleton = model.rows;
        // A negative link length is the same link with its x axis the other way:
        // `Tx(−a) = Rz(π)·Tx(a)·Rz(π)` and `Rz(π)·Rx(α) = Rx(−α)·Rz(π)`, so θ of the joint and
        // of the next turn by a half turn and α changes sign (q is unchanged: the offsets
        // take the half turns).
        for i in 0..JOINT_COUNT - 1 {
            if skeleton[i].a_mm < 0.0 {
                skeleton[i].a_mm = -skeleton[i].a_mm;
                skeleton[i].alpha_rad = -skeleton[i].alpha_rad;
                skeleton[i].theta_offset_rad += PI;
                skeleton[i + 1].theta_offset_rad += PI;
            }
        }
        let mut sin_alpha = [0.0; JOINT_COUNT];
        let mut j3_reversed = false;
        for (i, joint) in skeleton.iter_mut().enumerate() {
            let number = i + 1;
            if joint.beta_rad.abs() > SKELETON_ANGLE_TOLERANCE_RAD {
                return Err(unsupported(format!("β{number} is not 0")));
            }
            joint.beta_rad = 0.0;
            match number {
                1 | 3 | 4 | 5 => {
                    let mut sign = joint.alpha_rad.signum();
                    if (joint.alpha_rad.abs() - FRAC_PI_2).abs() > SKELETON_ANGLE_TOLERANCE_RAD {
                        return Err(unsupported(format!("α{number} is not ±90°")));
                    }
                    if number == 3 && j3_reversed {
                        sign = -sign;
                        joint.d_mm = -joint.d_mm;
                        joint.theta_offset_rad = -joint.theta_offset_rad;
                    }
                    joint.alpha_rad = sign * FRAC_PI_2;
                    sin_alpha[i] = sign;
                }
                2 => {
                    j3_reversed =
                        (joint.alpha_rad.abs() - PI).abs() <= SKELETON_ANGLE_TOLERANCE_RAD;
                    if joint.alpha_rad.abs() > SKELETON_ANGLE_TOLERANCE_RAD && !j3_reversed {
                        return Err(unsupported("α2 is neither 0° nor 180°".into()));
                    }
                    joint.alpha_rad = 0.0;
                }
                _ => {}
            }
        }
        // The labels count J5's sign, which says the wrist's side only where J5's zero is
        // its singularity.
        if skeleton[4].theta_offset_rad.sin().abs() > SKELETON_ANGLE_TOLERANCE_RAD.sin() {
            return Err(unsupported(format!(
                "J5's zero is not the wrist's singularity (θ5 offset {:.1}°, not 0° or 180°)",
                skeleton[4].theta_offset_rad.to_degrees()
            )));
        }
        let [_, _, _, joint4, joint5, joint6] = &mut skeleton;
        for (name, value) in [
            ("a4", &mut joint4.a_mm),
            ("a5", &mut joint5.a_mm),
            ("a6", &mut joint6.a_mm),
            ("d5", &mut joint5.d_mm),
        ] {
            if value.abs() > SKELETON_LENGTH_TOLERANCE_MM {
                return Err(unsupported(format!("{name} = {value} mm is not 0")));
            }
            *value = 0.0;
        }
        if skeleton[1].a_mm <= 0.0 || skeleton[2].a_mm.hypot(skeleton[3].d_mm) <= 0.0 {
            return Err(unsupported("a zero-length upper arm or forearm".into()));
        }
        Ok(InverseKinematics {
            robot: robot.clone(),
            model,
            skeleton,
            sin_alpha,
            j3_reversed,
        })
    }

    /// The configuration of joint values `q_rad` of the nominal robot (module docs).
    pub fn configuration(&self, q_rad: &[f64; JOINT_COUNT]) -> Configuration {
        self.label(&self.model.rows, q_rad)
    }

    /// [`configuration_of`] on `joints`, the elbow read against the robot's up.
    fn label(&self, joints: &[MdhJoint; JOINT_COUNT], q_rad: &[f64; JOINT_COUNT]) -> Configuration {
        let c = configuration_of(joints, q_rad);
        if self.model.up_against_z0 {
            Configuration(c.0 ^ Configuration::ELBOW_DOWN)
        } else {
            c
        }
    }

    /// The robot this solver was prepared for.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// Every configuration reaching `tcp_pose` (TCP in the frame poses are given in) with
    /// the robot's nominal model, tool and base, within the joint limits, sorted by
    /// configuration.
    ///
    /// Empty when the pose is out of reach, every solution breaks a limit, or the wrist
    /// centre lies on axis 1 (infinitely many solutions: none is returned).
    pub fn solve(&self, tcp_pose: &Isometry3<f64>) -> Vec<IkSolution> {
        let m = &self.model;
        self.solve_with_model(tcp_pose, &m.rows, &m.tool, &m.base)
    }

    /// Like [`InverseKinematics::solve`], for an exact model `joints`, `tool` and `base`
    /// near the nominal one (e.g. nominal plus identified deviations): the closed form on
    /// the skeleton gives the branches, Newton steps on the model's chain make them exact.
    pub fn solve_with_model(
        &self,
        tcp_pose: &Isometry3<f64>,
        joints: &[MdhJoint; JOINT_COUNT],
        tool: &Transform,
        base: &Transform,
    ) -> Vec<IkSolution> {
        let Ok(chain) = Chain::from_mdh(*base, joints, *tool, None) else {
            return Vec::new();
        };
        let tool_isometry = isometry_from_transform(tool);
        let flange = isometry_from_transform(&base.inverse()) * tcp_pose * tool_isometry.inverse();
        let target = transform_from_isometry(tcp_pose);
        let mut solutions: Vec<IkSolution> = Vec::with_capacity(8);
        for theta in self.skeleton_solutions(&flange) {
            let mut q: [f64; JOINT_COUNT] =
                std::array::from_fn(|i| theta[i] - self.skeleton[i].theta_offset_rad);
            if self.j3_reversed {
                q[2] = -q[2];
            }
            let Some(q) = newton(&chain, &target, q) else {
                continue;
            };
            let Some(q_rad) = self.wrap_into_limits(q) else {
                continue;
            };
            // Labelled on the exact model, so that a label always describes the posture
            // returned. At a singularity two candidates may meet in one posture: keep one.
            let config = self.label(joints, &q_rad);
            if solutions.iter().any(|s| s.config == config) {
                continue;
            }
            solutions.push(IkSolution { q_rad, config });
        }
        solutions.sort_by_key(|s| s.config);
        solutions
    }

    /// The solution closest to the home posture (sum of squared joint differences), or the
    /// one of the given configuration; `None` if there is no such solution.
    pub fn solve_one(
        &self,
        tcp_pose: &Isometry3<f64>,
        config: Option<Configuration>,
    ) -> Option<IkSolution> {
        let home = self.robot.home();
        let distance = |s: &IkSolution| -> f64 {
            s.q_rad
                .iter()
                .zip(home)
                .map(|(q, h)| (q - h) * (q - h))
                .sum()
        };
        self.solve(tcp_pose)
            .into_iter()
            .filter(|s| config.is_none() || config == Some(s.config))
            .min_by(|a, b| distance(a).total_cmp(&distance(b)))
    }

    /// The representative of each joint within its limits, closest to home; `None` if a
    /// joint has none.
    fn wrap_into_limits(&self, q_rad: [f64; JOINT_COUNT]) -> Option<[f64; JOINT_COUNT]> {
        let mut out = [0.0; JOINT_COUNT];
        for (i, (o, q)) in out.iter_mut().zip(q_rad).enumerate() {
            let [lower, upper] = self.robot.joints()[i].limits;
            let home = self.robot.home()[i];
            // The representative nearest home, then its neighbours a turn away.
            let nearest = q + TAU * ((home - q) / TAU).round();
            *o = [nearest, nearest - TAU, nearest + TAU]
                .into_iter()
                .filter(|v| (lower..=upper).contains(v))
                .min_by(|a, b| (a - home).abs().total_cmp(&(b - home).abs()))?;
        }
        Some(out)
    }

    /// The skeleton's closed-form solutions for a flange pose: joint angles θ (offsets
    /// included, not wrapped), up to eight.
    fn skeleton_solutions(&self, flange: &Isometry3<f64>) -> Vec<[f64; JOINT_COUNT]> {
        let s = &self.skeleton;
        let flange_rotation = flange.rotation.to_rotation_matrix();
        // The wrist centre is joint 5's origin; the flange sits d6 along joint 6's axis,
        // whose direction in the flange frame is Rx(α6)ᵀ·z.
        let (sin_a6, cos_a6) = s[5].alpha_rad.sin_cos();
        let wrist_centre = flange.translation.vector
            - flange_rotation * Vector3::new(0.0, sin_a6, cos_a6) * s[5].d_mm;

        let (wx, wy) = (wrist_centre.x, wrist_centre.y);
        let radius = wx.hypot(wy);
        let offset_z = s[1].d_mm + s[2].d_mm;
        if radius <= 1e-9 || radius < offset_z.abs() {
            return Vec::new();
        }
        let heading = wy.atan2(wx);
        // Joint 1: z1 = sin α1 · (sin θ1, −cos θ1, 0) is horizontal, and the wrist centre
        // must lie d2 + d3 along it: sin α1 · r · sin(θ1 − heading) = d2 + d3. The solution
        // with |θ1 − heading| ≤ 90° faces the wrist centre (shoulder front), the other
        // reaches over the back.
        let lean = (self.sin_alpha[0] * offset_z / radius).asin();
        let mut solutions = Vec::with_capacity(8);
        for theta1 in [heading + lean, heading + PI - lean] {
            let q1 = theta1 - s[0].theta_offset_rad;
            let frame1 = s[0].transform(q1);
            let local = frame1.inverse().transform_point(wrist_centre.into());
            for (theta2, theta3) in self.planar_arm(local[0], local[1]) {
                let arm = [theta1, theta2, theta3];
                for (theta4, theta5, theta6) in self.wrist(&arm, &flange_rotation) {
                    solutions.push([theta1, theta2, theta3, theta4, theta5, theta6]);
                }
            }
        }
        solutions
    }

    /// Joints 2 and 3 as a planar two-link arm in frame 1: the upper arm `a2` and the
    /// forearm from joint 3 to the wrist centre, `(a3, −sin α3 · d4)` in frame 3 before its
    /// twist. Returns θ2, θ3 for both elbows (one when stretched or folded).
    fn planar_arm(&self, u: f64, v: f64) -> Vec<(f64, f64)> {
        let s = &self.skeleton;
        let upper = s[1].a_mm;
        let forearm_angle = (-self.sin_alpha[2] * s[3].d_mm).atan2(s[2].a_mm);
        let forearm = s[2].a_mm.hypot(s[3].d_mm);
        let reach = u.hypot(v);
        // The exact model's arm may be a few mm longer or shorter than the skeleton's: a
        // wrist centre just out of the skeleton's reach is tried from a nearly stretched
        // (or folded) elbow on both sides, and Newton decides.
        if reach > upper + forearm + SKELETON_REACH_SLACK_MM
            || reach < (upper - forearm).abs() - SKELETON_REACH_SLACK_MM
        {
            return Vec::new();
        }
        let cos_elbow =
            (reach * reach - upper * upper - forearm * forearm) / (2.0 * upper * forearm);
        let elbow = cos_elbow
            .clamp(-1.0, 1.0)
            .acos()
            .clamp(MIN_ELBOW_BEND_RAD, PI - MIN_ELBOW_BEND_RAD);
        [1.0, -1.0]
            .into_iter()
            .map(|sign: f64| {
                let gamma = sign * elbow;
                let theta2 =
                    v.atan2(u) - (forearm * gamma.sin()).atan2(upper + forearm * gamma.cos());
                (theta2, gamma - forearm_angle)
            })
            .collect()
    }

    /// Joints 4-6 from the rotation the wrist must produce (module docs, bit 2): both wrist
    /// solutions, or one at the wrist singularity (θ5 = 0 or π, only θ4 ± θ6 defined, J4 is
    /// set to its home value).
    fn wrist(&self, theta: &[f64; 3], flange_rotation: &Rotation3<f64>) -> Vec<(f64, f64, f64)> {
        let s = &self.skeleton;
        let q = |i: usize| theta[i] - s[i].theta_offset_rad;
        let arm = s[0]
            .transform(q(0))
            .compose(&s[1].transform(q(1)))
            .compose(&s[2].transform(q(2)));
        // M = R3ᵀ·R_flange·Rx(α6)ᵀ = Rz(θ4)·Rx(α4)·Rz(θ5)·Rx(α5)·Rz(θ6). With σ4, σ5 the signs
        // of sin α4, sin α5 and p = −σ4·σ5: M·z = (σ5 s5 c4, σ5 s5 s4, p c5) and
        // zᵀ·M = (σ4 s5 c6, −σ4 s5 s6, p c5).
        let last_twist = Rotation3::from_axis_angle(&Vector3::x_axis(), s[5].alpha_rad);
        let m = rotation_of(&arm).inverse() * flange_rotation * last_twist.inverse();
        let m = m.matrix();
        let (sigma4, sigma5) = (self.sin_alpha[3], self.sin_alpha[4]);
        let p = -sigma4 * sigma5;
        let cos5 = (p * m[(2, 2)]).clamp(-1.0, 1.0);
        let sin5_magnitude = (1.0 - cos5 * cos5).max(0.0).sqrt();
        // Below this, θ4 and θ6 would be atan2 of rounding noise.
        if sin5_magnitude < 1e-10 {
            let theta5 = if cos5 > 0.0 { 0.0 } else { PI };
            // J4 at its home value (how the robot file frames joint 4 then plays no part):
            // M = Rz(θ4)·Rx(α4)·Rz(θ5)·Rx(α5)·Rz(θ6), so
            // Rz(θ6) = (Rz(θ4)·Rx(α4)·Rz(θ5)·Rx(α5))ᵀ·M.
            let theta4 = self.robot.home()[3] + s[3].theta_offset_rad;
            let fixed = Rotation3::from_axis_angle(&Vector3::z_axis(), theta4)
                * Rotation3::from_axis_angle(&Vector3::x_axis(), s[3].alpha_rad)
                * Rotation3::from_axis_angle(&Vector3::z_axis(), theta5)
                * Rotation3::from_axis_angle(&Vector3::x_axis(), s[4].alpha_rad);
            let rest = fixed.inverse().matrix() * m;
            return vec![(theta4, theta5, rest[(1, 0)].atan2(rest[(0, 0)]))];
        }
        [1.0, -1.0]
            .into_iter()
            .map(|sign: f64| {
                let sin5 = sign * sin5_magnitude;
                let theta5 = sin5.atan2(cos5);
                let k4 = sigma5 * sign;
                let theta4 = (k4 * m[(1, 2)]).atan2(k4 * m[(0, 2)]);
                let k6 = sigma4 * sign;
                let theta6 = (-k6 * m[(2, 1)]).atan2(k6 * m[(2, 0)]);
                (theta4, theta5, theta6)
            })
            .collect()
    }
}

/// A robot's nominal kinematics as six MD-H rows: `base · A_1 ⋯ A_6 · tool`.
#[derive(Debug, Clone)]
struct NominalModel {
    base: Transform,
    rows: [MdhJoint; JOINT_COUNT],
    tool: Transform,
    /// Whether frame 0's z (joint 1's axis as it turns) points down in the robot's base
    /// frame (a URDF joint 1 about −z, as KUKA counts A1): the elbow's up is then against
    /// it, the base frame's.
    up_against_z0: bool,
}

/// The nominal model of `robot`, or why there is none. An MD-H file's rows as written; a chain's (URDF) in its MD-H form,
/// where, with joints 1 and 2 meeting (a1 = 0), frame 1's x axis (which then says the
/// shoulder's front) is turned toward the wrist centre's reach at the home posture, or where
/// the arm stands upright there, toward where a positive J2 leans it.
fn nominal_model(robot: &Robot) -> Result<NominalModel, String> {
    let six = |rows: &[MdhJoint]| -> Result<[MdhJoint; JOINT_COUNT], String> {
        rows.try_into()
            .map_err(|_| format!("{} joints, not {JOINT_COUNT}", rows.len()))
    };
    let Some(rows) = robot.mdh() else {
        let form = mdh_form(robot.chain())?;
        let mut rows = six(&form.rows)?;
        if rows[0].a_mm.abs() <= 1e-9 {
            if let Ok(home) = <[f64; JOINT_COUNT]>::try_from(robot.home()) {
                // The wrist centre's reach along frame 1's x axis (a shoulder's sideways
                // offset, along joint 2's axis, plays no part).
                let reach = |q: &[f64; JOINT_COUNT]| {
                    let frames = link_frames(&rows, q);
                    let [x, y, _] = frames[3].translation_mm;
                    Vector3::new(x, y, 0.0)
                        .dot(&Vector3::from(frames[0].rotate_vector([1.0, 0.0, 0.0])))
                };
                let mut toward = reach(&home);
                if toward.abs() <= 1e-6 {
                    let mut leaned = home;
                    leaned[1] += 1e-3;
                    toward = reach(&leaned);
                }
                if toward < 0.0 {
                    // Rz(θ1)·Rx(α1)·Rz(π) = Rz(θ1 + π)·Rx(−α1): frame 1 turned a half turn
                    // about its z, which joint 2's offset takes back.
                    rows[0].alpha_rad = -rows[0].alpha_rad;
                    rows[0].theta_offset_rad = wrap(rows[0].theta_offset_rad + PI);
                    rows[1].theta_offset_rad = wrap(rows[1].theta_offset_rad - PI);
                }
            }
        }
        let axis1 = Vector3::from(form.base.rotate_vector([0.0, 0.0, 1.0]));
        let base_up = Vector3::from(robot.base().rotate_vector([0.0, 0.0, 1.0]));
        return Ok(NominalModel {
            base: form.base,
            rows,
            tool: form.tool,
            up_against_z0: axis1.dot(&base_up) < 0.0,
        });
    };
    Ok(NominalModel {
        base: robot.base(),
        rows: six(rows)?,
        tool: robot.tool(),
        up_against_z0: false,
    })
}

/// An angle in (−π, π], rad.
fn wrap(angle_rad: f64) -> f64 {
    let r = angle_rad.rem_euclid(TAU);
    if r > PI {
        r - TAU
    } else {
        r
    }
}

/// The configuration of joint angles `q_rad` on the MD-H model `joints` (module docs), up
/// along frame 0's z: a robot file's rows as written. A robot's own labels, whatever its
/// file (a URDF, a joint 1 about −z), are [`InverseKinematics::configuration`]'s.
///
/// Works for any joint vector, e.g. the commanded angles of a measured data set.
pub fn configuration_of(
    joints: &[MdhJoint; JOINT_COUNT],
    q_rad: &[f64; JOINT_COUNT],
) -> Configuration {
    let frames = link_frames(joints, q_rad);
    let shoulder = Vector3::from(frames[0].translation_mm);
    let elbow = Vector3::from(frames[1].translation_mm);
    // Joint 5's axis passes through the wrist centre.
    let wrist_centre = Vector3::from(frames[3].translation_mm);
    let heading = Vector3::new(wrist_centre.x, wrist_centre.y, 0.0);
    // From the base axis toward joint 2: frame 1's origin lies a1 along joint 1's x axis,
    // so the sense an MD-H file gives that axis (a negative a1) plays no part; the axis
    // itself where axes 1 and 2 meet (a1 = 0).
    let toward_joint2 = Vector3::new(shoulder.x, shoulder.y, 0.0);
    let arm_x = toward_joint2
        .try_normalize(1e-9)
        .unwrap_or_else(|| Vector3::from(frames[0].rotate_vector([1.0, 0.0, 0.0])));
    let shoulder_back = arm_x.dot(&heading) < 0.0;
    // The arm's vertical plane: horizontal coordinate along joint 1's x axis (the arm's
    // front, whichever side the wrist centre is on), vertical along base z. Not along the
    // wrist centre's heading: that turns the plane over when the arm reaches behind (the
    // elbow's side would flip with the shoulder's), and mixes in a sideways offset (d2 + d3)
    // wherever the wrist centre reaches little beyond axis 1.
    let plane = |p: &Vector3<f64>| (p.dot(&arm_x), p.z);
    let (sr, sz) = plane(&shoulder);
    let (er, ez) = plane(&elbow);
    let (wr, wz) = plane(&wrist_centre);
    // Cross product of shoulder→wrist and shoulder→elbow: positive with the elbow on the
    // left of that line (above it where the wrist centre is in front).
    let elbow_down = (wr - sr) * (ez - sz) - (wz - sz) * (er - sr) < 0.0;
    // J5 negative: the sine of θ5 less the half turns of its offset (0° or 180°), taken
    // out before the sine so that J5 = 0 reads as no flip with either offset.
    let offset = joints[4].theta_offset_rad;
    let wrist_flip = (q_rad[4] + offset - PI * (offset / PI).round()).sin() < 0.0;
    Configuration::new(shoulder_back, elbow_down, wrist_flip)
}

/// Newton steps on the exact model from `q_rad`; `None` if it does not reach the pose to
/// [`POSITION_TOLERANCE_MM`] and [`ORIENTATION_TOLERANCE_RAD`].
fn newton(
    chain: &Chain,
    target: &Transform,
    mut q_rad: [f64; JOINT_COUNT],
) -> Option<[f64; JOINT_COUNT]> {
    let error_at = |q: &[f64; JOINT_COUNT]| -> Option<Vector6<f64>> {
        Some(transform_pose_error(&chain.tcp_pose(q)?, target))
    };
    let mut error = error_at(&q_rad)?;
    if !(q_rad.iter().all(|v| v.is_finite()) && error.iter().all(|v| v.is_finite())) {
        return None;
    }
    for _ in 0..NEWTON_MAX_STEPS {
        if converged(&error) {
            break;
        }
        let jacobian: nalgebra::Matrix6<f64> = joint_jacobian(chain, &q_rad)
            .fixed_view::<6, 6>(0, 0)
            .into_owned();
        let step = jacobian.lu().solve(&error).or_else(|| {
            jacobian
                .try_svd(true, true, f64::EPSILON, SVD_MAX_ITERATIONS)?
                .solve(&error, 1e-12)
                .ok()
        })?;
        for (q, dq) in q_rad.iter_mut().zip(step.iter()) {
            *q += dq;
        }
        error = error_at(&q_rad)?;
        if step.amax() < NEWTON_STEP_TOLERANCE_RAD {
            break;
        }
    }
    converged(&error).then_some(q_rad)
}

fn converged(error: &Vector6<f64>) -> bool {
    error.fixed_rows::<3>(0).norm() <= POSITION_TOLERANCE_MM
        && error.fixed_rows::<3>(3).norm() <= ORIENTATION_TOLERANCE_RAD
}

/// Orientation rows of [`solve_near`] are weighted by this (mm per rad): an error of 1 mrad
/// counts like one of 1 mm.
pub const ORIENTATION_WEIGHT_MM_PER_RAD: f64 = 1000.0;
/// The largest change of one joint in one step of [`solve_near`] (rad, or mm for a
/// prismatic joint), so that a far seed approaches the pose in small steps.
pub const MAX_STEP: f64 = 0.2;
/// Iterations of [`solve_near`] before it gives up.
const NUMERIC_MAX_STEPS: usize = 500;

/// The posture of `robot` nearest `seed` that reaches `tcp_pose` (TCP in the frame poses are
/// given in), by damped least squares and a walk along the self-motion toward the seed
/// (module docs, "Redundancy resolution"); when that posture breaks a joint limit, the
/// within-limits posture nearest the seed among those reached from [`FURTHER_SEEDS`]
/// further starting postures; `None` when there is none.
///
/// # Panics
///
/// When `seed` does not have one value per joint.
pub fn solve_near(robot: &Robot, tcp_pose: &Isometry3<f64>, seed: &[f64]) -> Option<Vec<f64>> {
    let target = transform_from_isometry(tcp_pose);
    let chain = robot.chain();
    if let Some(q) = solve_near_chain(chain, &target, seed) {
        if robot.within_limits(&q) {
            return Some(q);
        }
    }
    let seed = DVector::from_column_slice(seed);
    let mut rng = ChaCha8Rng::seed_from_u64(FURTHER_SEEDS_RNG);
    let mut best: Option<(f64, DVector<f64>)> = None;
    for _ in 0..FURTHER_SEEDS {
        let start = DVector::from_fn(robot.joint_count(), |i, _| {
            let [lower, upper] = robot.sampling_range(i);
            rng.gen_range(lower..=upper)
        });
        let Some(on_pose) = to_pose(chain, &target, start, NUMERIC_MAX_STEPS) else {
            continue;
        };
        let walked = walk_toward(chain, &target, on_pose.clone(), &seed);
        let Some(q) = [walked, on_pose]
            .into_iter()
            .find(|q| robot.within_limits(q.as_slice()))
        else {
            continue;
        };
        let distance = (&q - &seed).norm();
        if best.as_ref().is_none_or(|(d, _)| distance < *d) {
            best = Some((distance, q));
        }
    }
    best.map(|(_, q)| q.as_slice().to_vec())
}

/// A posture of `robot` within its limits reaching `tcp_pose` by damped least squares from
/// `start` alone (as [`solve_near`]'s first stage, at most [`TABLE_MAX_STEPS`] steps),
/// without the walk toward it or further starts: from a start drawn within the limits, the
/// posture of whichever branch (or elbow angle of a redundant arm) lies nearest it. `None`
/// when the pose is not reached, the posture breaks a limit, or `start` has another joint
/// count than `robot`.
pub fn solve_from(robot: &Robot, tcp_pose: &Isometry3<f64>, start: &[f64]) -> Option<Vec<f64>> {
    if start.len() != robot.joint_count() {
        return None;
    }
    let target = transform_from_isometry(tcp_pose);
    let q = to_pose(
        robot.chain(),
        &target,
        DVector::from_column_slice(start),
        TABLE_MAX_STEPS,
    )?;
    robot
        .within_limits(q.as_slice())
        .then(|| q.as_slice().to_vec())
}

/// The posture of `robot` reached from `seed` that puts the TCP at `tcp_pose`'s position
/// and turns it as near that pose's orientation as the joints allow: position first, the
/// orientation in what the position leaves free (each step's orientation part in the null
/// space of the position's Jacobian, least squares). For a robot of fewer than six
/// joints, which cannot take every orientation (a SCARA does not tilt): `solve_near` asks
/// the whole pose and finds none. `None` unless the position is reached within
/// [`POSITION_TOLERANCE_MM`] and the posture lies within the limits, or when `seed` has
/// another joint count than `robot`.
pub fn solve_position_first(
    robot: &Robot,
    tcp_pose: &Isometry3<f64>,
    seed: &[f64],
) -> Option<Vec<f64>> {
    let n = robot.joint_count();
    if seed.len() != n {
        return None;
    }
    let target = transform_from_isometry(tcp_pose);
    let chain = robot.chain();
    let pinv = |m: DMatrix<f64>| {
        let eps = 1e-10 * m.norm() + f64::MIN_POSITIVE;
        m.pseudo_inverse(eps).ok()
    };
    let mut q = DVector::from_column_slice(seed);
    for _ in 0..NUMERIC_MAX_STEPS {
        let error = transform_pose_error(&chain.tcp_pose(q.as_slice())?, &target);
        let jacobian = joint_jacobian(chain, q.as_slice());
        if !(error.iter().all(|v| v.is_finite()) && jacobian.iter().all(|v| v.is_finite())) {
            return None;
        }
        let (jp, jo) = (
            jacobian.rows(0, 3).into_owned(),
            jacobian.rows(3, 3).into_owned(),
        );
        let ep = DVector::from_column_slice(error.fixed_rows::<3>(0).as_slice());
        let eo = DVector::from_column_slice(error.fixed_rows::<3>(3).as_slice());
        let jp_pinv = pinv(jp.clone())?;
        let step_p = &jp_pinv * &ep;
        let null = DMatrix::identity(n, n) - &jp_pinv * &jp;
        let jo_null = &jo * &null;
        let step_o = &null * (pinv(jo_null)? * (&eo - &jo * &step_p));
        if take_step(&mut q, step_p + step_o) {
            break;
        }
    }
    let error = transform_pose_error(&chain.tcp_pose(q.as_slice())?, &target);
    (error.fixed_rows::<3>(0).norm() <= POSITION_TOLERANCE_MM && robot.within_limits(q.as_slice()))
        .then(|| q.as_slice().to_vec())
}

/// Starting postures [`solve_near`] tries, uniformly within the joint ranges, when the
/// seed's solution breaks a limit.
pub const FURTHER_SEEDS: usize = 32;
/// The ChaCha8 seed of those postures: the same pose always gives the same answer.
const FURTHER_SEEDS_RNG: u64 = 0x5eed;

/// Postures drawn within a robot's joint limits, with their TCP poses: starts for the
/// numerical inverse kinematics of many poses (module docs, "Starting near the pose").
#[derive(Debug, Clone)]
pub struct PostureTable {
    /// The drawn postures, one after the other (rad; mm for prismatic joints).
    postures: Vec<f64>,
    joint_count: usize,
    /// Their TCP positions, mm, in the frame poses are given in.
    positions_mm: Vec<Vector3<f64>>,
    /// Their TCP orientations.
    rotations: Vec<UnitQuaternion<f64>>,
}

/// Postures a [`PostureTable`] draws: enough that the nearest lies a few damped steps from
/// any pose of the workspace, few enough that finding it costs less than those steps.
pub const TABLE_POSTURES: usize = 1024;
/// The nearest postures of the table [`PostureTable::solve`] starts from, in turn, before
/// it gives up.
pub const TABLE_STARTS: usize = 8;
/// Damped steps [`PostureTable::solve`] allows from one start: ten times what the iiwa's
/// plan poses take on average from the nearest posture (10 steps, 1.1 starts); a start
/// that needs more is far from its pose, or the pose is out of reach.
pub const TABLE_MAX_STEPS: usize = 100;
/// The ChaCha8 seed of a table's postures: the same robot always gets the same table.
const TABLE_RNG: u64 = 0x7ab1e;

impl PostureTable {
    /// [`TABLE_POSTURES`] postures of `robot` drawn uniformly within its sampling ranges
    /// (its limits, or a turn around home for a joint without), from a fixed seed.
    pub fn new(robot: &Robot) -> PostureTable {
        let n = robot.joint_count();
        let ranges: Vec<[f64; 2]> = (0..n).map(|i| robot.sampling_range(i)).collect();
        let mut rng = ChaCha8Rng::seed_from_u64(TABLE_RNG);
        let postures: Vec<f64> = (0..TABLE_POSTURES * n)
            .map(|k| {
                let [lower, upper] = ranges[k % n];
                rng.gen_range(lower..=upper)
            })
            .collect();
        let poses: Vec<Isometry3<f64>> = postures
            .chunks_exact(n)
            .map(|q| robot.tcp_pose(q))
            .collect();
        PostureTable {
            joint_count: n,
            positions_mm: poses.iter().map(|p| p.translation.vector).collect(),
            rotations: poses.iter().map(|p| p.rotation).collect(),
            postures,
        }
    }

    /// A posture of `robot` within its limits reaching `tcp_pose`: damped least squares
    /// (as [`solve_near`]'s first stage) from each of the [`TABLE_STARTS`] postures of the
    /// table nearest the pose, nearest first (position distance plus the rotation angle
    /// weighted by [`ORIENTATION_WEIGHT_MM_PER_RAD`]; ties to the earlier drawn), the
    /// first that ends within the limits; `None` when none does, or when `robot` has
    /// another joint count than the robot the table was drawn for.
    pub fn solve(&self, robot: &Robot, tcp_pose: &Isometry3<f64>) -> Option<Vec<f64>> {
        if robot.joint_count() != self.joint_count {
            return None;
        }
        let target = transform_from_isometry(tcp_pose);
        self.nearest(tcp_pose).into_iter().find_map(|k| {
            let start = &self.postures[k * self.joint_count..(k + 1) * self.joint_count];
            let q = to_pose(
                robot.chain(),
                &target,
                DVector::from_column_slice(start),
                TABLE_MAX_STEPS,
            )?;
            robot
                .within_limits(q.as_slice())
                .then(|| q.as_slice().to_vec())
        })
    }

    /// The indices of the [`TABLE_STARTS`] postures nearest `tcp_pose`, nearest first.
    fn nearest(&self, tcp_pose: &Isometry3<f64>) -> Vec<usize> {
        let p = tcp_pose.translation.vector;
        // The nearest TABLE_STARTS by (distance, index), kept sorted; the angle is computed
        // only for postures whose position alone is near enough.
        let mut nearest: Vec<(f64, usize)> = Vec::with_capacity(TABLE_STARTS + 1);
        for (k, (position, rotation)) in self.positions_mm.iter().zip(&self.rotations).enumerate() {
            let worst = if nearest.len() == TABLE_STARTS {
                nearest[TABLE_STARTS - 1].0
            } else {
                f64::INFINITY
            };
            let position_part = (position - p).norm_squared();
            if position_part >= worst {
                continue;
            }
            // The angle between two unit quaternions q, r is 2·acos|q·r|.
            let cos_half = rotation
                .coords
                .dot(&tcp_pose.rotation.coords)
                .abs()
                .min(1.0);
            let angle_rad = 2.0 * cos_half.acos();
            let distance = position_part + (ORIENTATION_WEIGHT_MM_PER_RAD * angle_rad).powi(2);
            if distance < worst {
                let at = nearest.partition_point(|&(d, _)| d <= distance);
                nearest.insert(at, (distance, k));
                nearest.truncate(TABLE_STARTS);
            }
        }
        nearest.into_iter().map(|(_, k)| k).collect()
    }
}

/// [`solve_near`] on a chain, without limits.
pub(crate) fn solve_near_chain(
    chain: &Chain,
    target: &Transform,
    seed: &[f64],
) -> Option<Vec<f64>> {
    assert_eq!(seed.len(), chain.joint_count(), "one seed value per joint");
    let seed = DVector::from_column_slice(seed);
    // 1. Onto the pose: from the seed, minimum-norm steps stay near it.
    let q = to_pose(chain, target, seed.clone(), NUMERIC_MAX_STEPS)?;
    // 2. Along the self-motion toward the seed.
    Some(walk_toward(chain, target, q, &seed).as_slice().to_vec())
}

/// From a posture `q` on the pose, along the self-motion toward `seed`: each step the
/// seed's pull projected into the null space, then back onto the pose; a step is kept when
/// it brings the posture closer to the seed (or, at the end, shrinks the pull), halved
/// otherwise.
fn walk_toward(
    chain: &Chain,
    target: &Transform,
    mut q: DVector<f64>,
    seed: &DVector<f64>,
) -> DVector<f64> {
    let mut gain: f64 = 1.0;
    for _ in 0..NUMERIC_MAX_STEPS {
        let Some(pull) = null_space_part(chain, &q, &(seed - &q)) else {
            break;
        };
        if pull.amax() < NULL_SPACE_TOLERANCE {
            break;
        }
        let mut step = &pull * gain;
        let largest = step.amax();
        if largest > MAX_STEP {
            step *= MAX_STEP / largest;
        }
        // Close to the end, where the change of distance falls below rounding, a step is
        // kept when the pull shrinks.
        let small = pull.amax() < 1e-6;
        let closer = to_pose(chain, target, &q + step, NUMERIC_MAX_STEPS).filter(|next| {
            if small {
                null_space_part(chain, next, &(seed - next)).is_some_and(|p| p.amax() < pull.amax())
            } else {
                (next - seed).norm() < (&q - seed).norm()
            }
        });
        match closer {
            Some(next) => {
                q = next;
                gain = (gain * 2.0).min(1.0);
            }
            None => {
                gain *= 0.5;
                if gain < 1e-6 {
                    break;
                }
            }
        }
    }
    q
}

/// The most sweeps an SVD of a Jacobian may take: a 6×n Jacobian converges in a few dozen;
/// one that does not (non-finite entries) is given up on rather than iterated on forever.
const SVD_MAX_ITERATIONS: usize = 1000;

/// A null-space pull below this (rad, mm) ends the walk toward the seed.
const NULL_SPACE_TOLERANCE: f64 = 1e-12;

/// The weighted Jacobian (orientation rows × [`ORIENTATION_WEIGHT_MM_PER_RAD`]) and the
/// weighted pose error at `q`.
fn weighted(
    chain: &Chain,
    target: &Transform,
    q: &DVector<f64>,
) -> Option<(DMatrix<f64>, DVector<f64>, Vector6<f64>)> {
    let error = transform_pose_error(&chain.tcp_pose(q.as_slice())?, target);
    let w = ORIENTATION_WEIGHT_MM_PER_RAD;
    let weight = [1.0, 1.0, 1.0, w, w, w];
    let mut jacobian = joint_jacobian(chain, q.as_slice());
    for (r, w) in weight.iter().enumerate() {
        jacobian.row_mut(r).scale_mut(*w);
    }
    let e = DVector::from_fn(6, |r, _| error[r] * weight[r]);
    Some((jacobian, e, error))
}

/// Steps from `q` onto the pose: damped least squares while far (λ = 10⁻³ of J's largest
/// singular value, each joint moving at most [`MAX_STEP`]), minimum-norm Newton within
/// 1 µm, until the steps vanish (or a thousandth of the tolerances is reached), at most
/// `max_steps` steps; `None` unless it reaches [`POSITION_TOLERANCE_MM`] and
/// [`ORIENTATION_TOLERANCE_RAD`].
fn to_pose(
    chain: &Chain,
    target: &Transform,
    mut q: DVector<f64>,
    max_steps: usize,
) -> Option<DVector<f64>> {
    for _ in 0..max_steps {
        let (jacobian, e, error) = weighted(chain, target, &q)?;
        // A non-finite pose or posture has no step: refused, never iterated on.
        if !(e.iter().all(|v| v.is_finite()) && jacobian.iter().all(|v| v.is_finite())) {
            return None;
        }
        // A thousand times tighter than asked: one more Newton step costs little.
        if error.fixed_rows::<3>(0).norm() <= 1e-3 * POSITION_TOLERANCE_MM
            && error.fixed_rows::<3>(3).norm() <= 1e-3 * ORIENTATION_TOLERANCE_RAD
        {
            return Some(q);
        }
        let svd = jacobian.try_svd(true, true, f64::EPSILON, SVD_MAX_ITERATIONS)?;
        let (u, v_t) = (svd.u.as_ref()?, svd.v_t.as_ref()?);
        let sigma = &svd.singular_values;
        let largest = sigma.max();
        if !(largest.is_finite() && largest > 0.0) {
            return None;
        }
        let rank_tolerance = 1e-10 * largest;
        let lambda2 = if e.norm() > 1e-3 {
            (1e-3 * largest).powi(2)
        } else {
            0.0
        };
        let step = pseudo_inverse_times(u, sigma, v_t, &e, |s| {
            if s > rank_tolerance {
                s / (s * s + lambda2)
            } else {
                0.0
            }
        });
        if take_step(&mut q, step) {
            break;
        }
    }
    let (_, _, error) = weighted(chain, target, &q)?;
    converged(&error).then_some(q)
}

/// Moves `q` by `step`, each joint at most [`MAX_STEP`] (the step scaled down as a whole);
/// whether the step was below [`NEWTON_STEP_TOLERANCE_RAD`], the iteration's end.
fn take_step(q: &mut DVector<f64>, mut step: DVector<f64>) -> bool {
    let step_size = step.amax();
    if step_size > MAX_STEP {
        step *= MAX_STEP / step_size;
    }
    *q += &step;
    step_size < NEWTON_STEP_TOLERANCE_RAD
}

/// The part of `v` in the null space of the chain's Jacobian at `q`: `(I − J⁺J) v`.
fn null_space_part(chain: &Chain, q: &DVector<f64>, v: &DVector<f64>) -> Option<DVector<f64>> {
    let svd = joint_jacobian(chain, q.as_slice()).try_svd(
        false,
        true,
        f64::EPSILON,
        SVD_MAX_ITERATIONS,
    )?;
    let v_t = svd.v_t.as_ref()?;
    let largest = svd.singular_values.max();
    let mut out = v.clone();
    for (k, &s) in svd.singular_values.iter().enumerate() {
        if s > 1e-10 * largest {
            let row = v_t.row(k).transpose();
            out -= &row * row.dot(v);
        }
    }
    Some(out)
}

/// `V · diag(f(σ)) · Uᵀ · e` of a thin SVD `J = U Σ Vᵀ`.
fn pseudo_inverse_times(
    u: &DMatrix<f64>,
    sigma: &DVector<f64>,
    v_t: &DMatrix<f64>,
    e: &DVector<f64>,
    f: impl Fn(f64) -> f64,
) -> DVector<f64> {
    let mut out = DVector::zeros(v_t.ncols());
    for (k, &s) in sigma.iter().enumerate() {
        let coefficient = f(s) * u.column(k).dot(e);
        if coefficient != 0.0 {
            out += v_t.row(k).transpose() * coefficient;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_model::{apply_deviations, pose_error, JointDeviation};
    use crate::model::{isometry_from_parts, shipped_robot_path};
    use adwi_samples::pose::{orientation_error, rotation_from_kuka_abc_deg};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn kr150() -> Robot {
        Robot::load(shipped_robot_path("kr150-2")).unwrap()
    }

    fn deg(q: [f64; 6]) -> [f64; 6] {
        q.map(f64::to_radians)
    }

    fn rows(robot: &Robot) -> [MdhJoint; 6] {
        robot.mdh().unwrap().try_into().unwrap()
    }

    fn fk(joints: &[MdhJoint; 6], tool: &Transform, q: &[f64]) -> Transform {
        Chain::from_mdh(Transform::IDENTITY, joints, *tool, None)
            .unwrap()
            .tcp_pose(q)
            .unwrap()
    }

    fn random_q(robot: &Robot, rng: &mut ChaCha8Rng) -> Vec<f64> {
        (0..robot.joint_count())
            .map(|i| {
                let [lo, hi] = robot.sampling_range(i);
                rng.gen_range(lo..hi)
            })
            .collect()
    }

    /// Asserts that `solution` reaches `target` with the model, to the round-trip tolerance.
    fn assert_reaches(
        joints: &[MdhJoint; 6],
        tool: &Transform,
        solution: &IkSolution,
        target: &Isometry3<f64>,
    ) {
        let pose = isometry_from_transform(&fk(joints, tool, &solution.q_rad));
        let error = pose_error(target, &pose);
        assert!(
            error.fixed_rows::<3>(0).norm() <= 1e-9,
            "config {}: {error:?}",
            solution.config
        );
        assert!(error.fixed_rows::<3>(3).norm() <= 1e-12);
    }

    /// A posture drawn uniformly within a six-joint robot's limits.
    fn posture_within(robot: &Robot, rng: &mut ChaCha8Rng) -> [f64; 6] {
        std::array::from_fn(|i| {
            let [lo, hi] = robot.joints()[i].limits;
            rng.gen_range(lo..hi)
        })
    }

    /// `other` describes the KR150-2 at the same joint values: at 2,000 postures drawn
    /// within its limits the same pose and the same label, and `other`'s closed form finds
    /// the posture with that label (away from the wrist's singularity).
    fn assert_the_kr150_at_the_same_joints(other: &Robot, seed: u64) {
        let robot = kr150();
        let ik = InverseKinematics::new(other).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for _ in 0..2_000 {
            let q = posture_within(&robot, &mut rng);
            let target = robot.tcp_pose(&q);
            let there = other.tcp_pose(&q);
            assert!((there.translation.vector - target.translation.vector).norm() < 1e-9);
            assert!(there.rotation.angle_to(&target.rotation) < 1e-12);
            let label = configuration_of(&rows(&robot), &q);
            assert_eq!(configuration_of(&rows(other), &q), label);
            assert_eq!(label.wrist_flip(), q[4].sin() < 0.0);
            if q[4].sin().abs() > 1e-3 {
                let found = ik.solve(&target);
                assert!(
                    found
                        .iter()
                        .any(|s| same_posture(&s.q_rad, &q) && s.config == label),
                    "{q:?} not recovered from {found:?}"
                );
            }
        }
    }

    /// Whether two joint vectors are the same posture (joints compared modulo a turn).
    fn same_posture(a: &[f64; 6], b: &[f64; 6]) -> bool {
        a.iter().zip(b).all(|(x, y)| {
            let d = (x - y).rem_euclid(TAU);
            d.min(TAU - d) < 1e-7
        })
    }

    #[test]
    fn round_trip_over_ten_thousand_random_reachable_poses() {
        let robot = kr150();
        let ik = InverseKinematics::new(&robot).unwrap();
        let (joints, tool) = (rows(&robot), robot.tool());
        let mut rng = ChaCha8Rng::seed_from_u64(2020);
        let mut solutions_checked = 0;
        let mut configs_seen = [false; 8];
        for _ in 0..10_000 {
            let q = posture_within(&robot, &mut rng);
            let target = robot.tcp_pose(&q);
            let solutions = ik.solve(&target);
            for solution in &solutions {
                assert!(robot.within_limits(&solution.q_rad));
                assert_reaches(&joints, &tool, solution, &target);
                configs_seen[usize::from(solution.config.bits())] = true;
            }
            solutions_checked += solutions.len();
            // The posture we started from is among them, unless it sits at a wrist
            // singularity, where only θ4 ± θ6 is defined.
            if q[4].sin().abs() > 1e-3 {
                assert!(
                    solutions.iter().any(|s| same_posture(&s.q_rad, &q)),
                    "{q:?} not recovered from {solutions:?}"
                );
            }
        }
        assert!(solutions_checked > 20_000, "{solutions_checked}");
        assert!(configs_seen.iter().all(|&seen| seen), "{configs_seen:?}");
    }

    /// A J3 that turns against J2 (α2 = 180°, as Fanuc and Yaskawa count it): the KR150-2
    /// written so (α2 180°, α3 and d3 and J3's offset and limits turned with it) is the same
    /// arm with q3 negated; the closed form solves it, every posture drawn is among the
    /// solutions of its pose with q3 negated, and each carries the label the KR150-2's
    /// own posture has.
    #[test]
    fn a_j3_turning_against_j2_is_solved_as_the_same_arm() {
        let robot = kr150();
        let text = std::fs::read_to_string(shipped_robot_path("kr150-2")).unwrap();
        let a2 = "a_mm = 1250.0\nd_mm = 0.0\nalpha_deg = 0.0";
        let a3 = "a_mm = 55.0\nd_mm = 0.0\nalpha_deg = 90.0\nbeta_deg = 0.0\ntheta_offset_deg = 90.0\nlimits_deg = [-119.0, 155.0]";
        assert!(text.contains(a2) && text.contains(a3));
        let reversed = Robot::from_toml_str(
            &text.replace(a2, "a_mm = 1250.0\nd_mm = 0.0\nalpha_deg = 180.0").replace(
                a3,
                "a_mm = 55.0\nd_mm = 0.0\nalpha_deg = -90.0\nbeta_deg = 0.0\ntheta_offset_deg = -90.0\nlimits_deg = [-155.0, 119.0]",
            ),
        )
        .unwrap();
        let ik = InverseKinematics::new(&reversed).unwrap();
        let (joints, tool) = (rows(&reversed), reversed.tool());
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..2_000 {
            let q = posture_within(&robot, &mut rng);
            let mut negated = q;
            negated[2] = -q[2];
            let target = robot.tcp_pose(&q);
            assert!(
                (reversed.tcp_pose(&negated).translation.vector - target.translation.vector).norm()
                    < 1e-9
            );
            let solutions = ik.solve(&target);
            for solution in &solutions {
                assert_reaches(&joints, &tool, solution, &target);
            }
            if q[4].sin().abs() > 1e-3 {
                let found = solutions
                    .iter()
                    .find(|s| same_posture(&s.q_rad, &negated))
                    .unwrap_or_else(|| panic!("{q:?} not recovered from {solutions:?}"));
                assert_eq!(found.config, configuration_of(&rows(&robot), &q));
            }
        }
    }

    /// The wrist label is J5's sign as the robot file counts it, whatever the half turn
    /// its θ5 offset holds: the KR150-2 written with θ5's offset 180° (α5 and θ6's offset
    /// turned with it: `Rz(π)·Rx(α5) = Rx(−α5)·Rz(π)`) is the same arm at the same joint
    /// values, so every posture has the same label in both, and each file's closed form
    /// finds it. (Labelled by `sin θ5` alone, the second file called every posture of the
    /// first flipped where it was not, and a program's `F` was solved in the other wrist.)
    #[test]
    fn the_wrist_label_is_j5s_sign_whatever_its_offset() {
        let text = std::fs::read_to_string(shipped_robot_path("kr150-2")).unwrap();
        let a5 = "alpha_deg = 90.0\nbeta_deg = 0.0\ntheta_offset_deg = 0.0\nlimits_deg = [-125.0, 125.0]";
        let a6 = "d_mm = 230.0\nalpha_deg = 0.0\nbeta_deg = 0.0\ntheta_offset_deg = 0.0";
        assert!(text.contains(a5) && text.contains(a6));
        let turned = Robot::from_toml_str(
            &text
                .replace(a5, "alpha_deg = -90.0\nbeta_deg = 0.0\ntheta_offset_deg = 180.0\nlimits_deg = [-125.0, 125.0]")
                .replace(a6, "d_mm = 230.0\nalpha_deg = 0.0\nbeta_deg = 0.0\ntheta_offset_deg = 180.0"),
        )
        .unwrap();
        assert_the_kr150_at_the_same_joints(&turned, 11);
    }

    /// Negative link lengths (an MD-H file that points x the other way, as one fitted to a
    /// URDF may): the KR150-2 with a1 and a2 negated, their offsets and α1 turned with them,
    /// is the same arm at the same joints; its closed form finds every posture drawn, with
    /// the KR150-2's labels (the shoulder's is read from where joint 2 is, not from the
    /// file's x axis).
    #[test]
    fn negative_link_lengths_are_solved_as_the_same_arm() {
        let text = std::fs::read_to_string(shipped_robot_path("kr150-2")).unwrap();
        let a1 =
            "a_mm = 350.0\nd_mm = 750.0\nalpha_deg = -90.0\nbeta_deg = 0.0\ntheta_offset_deg = 0.0";
        let a2 =
            "a_mm = 1250.0\nd_mm = 0.0\nalpha_deg = 0.0\nbeta_deg = 0.0\ntheta_offset_deg = 0.0";
        let a3 = "alpha_deg = 90.0\nbeta_deg = 0.0\ntheta_offset_deg = 90.0";
        assert!(text.contains(a1) && text.contains(a2) && text.contains(a3));
        let negated = Robot::from_toml_str(
            &text
                .replace(a1, "a_mm = -350.0\nd_mm = 750.0\nalpha_deg = 90.0\nbeta_deg = 0.0\ntheta_offset_deg = 180.0")
                .replace(a2, "a_mm = -1250.0\nd_mm = 0.0\nalpha_deg = 0.0\nbeta_deg = 0.0\ntheta_offset_deg = 0.0")
                .replace(a3, "alpha_deg = 90.0\nbeta_deg = 0.0\ntheta_offset_deg = -90.0"),
        )
        .unwrap();
        assert_the_kr150_at_the_same_joints(&negated, 13);
    }

    #[test]
    fn newton_makes_a_perturbed_model_exact() {
        let robot = kr150();
        let ik = InverseKinematics::new(&robot).unwrap();
        let mut deviations = [JointDeviation::default(); 6];
        for (i, d) in deviations.iter_mut().enumerate() {
            let k = i as f64 + 1.0;
            *d = JointDeviation {
                a_mm: 0.3 * k,
                d_mm: -0.2 * k,
                alpha_rad: 1e-3 / k,
                theta_rad: -5e-4 * k,
                beta_rad: 2e-4,
            };
        }
        let joints: [MdhJoint; 6] = apply_deviations(&rows(&robot), &deviations)
            .try_into()
            .unwrap();
        let tool = robot.tool();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..200 {
            let q = posture_within(&robot, &mut rng);
            let target = isometry_from_transform(&fk(&joints, &tool, &q));
            let solutions = ik.solve_with_model(&target, &joints, &tool, &Transform::IDENTITY);
            for solution in &solutions {
                assert_reaches(&joints, &tool, solution, &target);
            }
            // The deviations make the wrist slightly non-spherical: within a few degrees of
            // θ5 = 0 a pose has further exact solutions along θ4 − θ6, and Newton may land on
            // one of them (still exact, as checked above).
            if q[4].sin().abs() > 0.05 {
                assert!(
                    solutions.iter().any(|s| same_posture(&s.q_rad, &q)),
                    "{:?} not among {solutions:?}",
                    q.map(f64::to_degrees)
                );
            }
        }
    }

    #[test]
    fn labels_of_hand_built_postures() {
        let robot = kr150();
        let ik = InverseKinematics::new(&robot).unwrap();
        let label_of = |q_deg: [f64; 6]| {
            let q = deg(q_deg);
            let solutions = ik.solve(&robot.tcp_pose(&q));
            solutions
                .iter()
                .find(|s| same_posture(&s.q_rad, &q))
                .unwrap_or_else(|| panic!("{q_deg:?} not among {solutions:?}"))
                .config
                .bits()
        };
        // Home with the wrist bent +30°: upper arm up, forearm forward, elbow above the
        // shoulder–wrist line.
        assert_eq!(label_of([0.0, -90.0, 90.0, 0.0, 30.0, 0.0]), 0);
        assert_eq!(label_of([0.0, -90.0, 90.0, 0.0, -30.0, 0.0]), 4);
        // Upper arm 10° above horizontal, forearm folded back up: the elbow (1581, 0, 967)
        // is below the line from the shoulder (350, 0, 750) to the wrist (≈1205, 0, 2000).
        assert_eq!(label_of([0.0, -10.0, -100.0, 0.0, 30.0, 0.0]), 2);
        // Upper arm leaning 30° back, forearm horizontal backward: the wrist centre
        // (≈ −1375, 0, 1888) is behind the base axis, and the arm bends as in the elbow-down
        // posture above (A3 on the same side of stretched), though the elbow (−275, 0, 1833)
        // lies above the shoulder–wrist line: elbow down, as KUKA's status bit 1 (from A3)
        // and ABB's cfx (the wrist centre behind the lower arm) count it.
        assert_eq!(label_of([0.0, -120.0, -60.0, 0.0, 30.0, 0.0]), 3);
        // The same bend as home, reaching over behind: elbow up.
        assert_eq!(label_of([0.0, -140.0, 15.0, 0.0, 30.0, 0.0]), 1);
    }

    #[test]
    fn the_papers_target_is_reachable() {
        let robot = kr150();
        let ik = InverseKinematics::new(&robot).unwrap();
        let target = isometry_from_parts(
            [2000.0, 700.0, 1000.0],
            &rotation_from_kuka_abc_deg([0.0, 90.0, 0.0]),
        );
        // Closest to home: the arm in front, elbow up (its wrist bends to negative θ5).
        let best = ik.solve_one(&target, None).unwrap();
        assert!(
            !best.config.shoulder_back() && !best.config.elbow_down(),
            "{}",
            best.config
        );
        let pose = robot.tcp_pose(&best.q_rad);
        assert!((pose.translation.vector - target.translation.vector).norm() < 1e-9);
        let rotation_error = orientation_error(
            &target.rotation.to_rotation_matrix(),
            &pose.rotation.to_rotation_matrix(),
        );
        assert!(rotation_error.iter().all(|x| x.abs() < 1e-12));
        // A named configuration that exists is returned, one that breaks limits is not.
        for solution in ik.solve(&target) {
            let named = ik.solve_one(&target, Some(solution.config)).unwrap();
            assert_eq!(named, solution);
        }
        assert!(Configuration::from_bits(8).is_none());
    }

    #[test]
    fn an_offset_wrist_is_refused_with_the_reason() {
        let ur5 = Robot::load(shipped_robot_path("ur5")).unwrap();
        let error = InverseKinematics::new(&ur5).unwrap_err();
        assert!(error.to_string().contains("α3 is not ±90°"), "{error}");
    }

    #[test]
    fn a_robot_without_the_closed_form_is_refused_with_the_reason() {
        let iiwa = Robot::load(crate::model::shipped_file("iiwa14", "robot.toml")).unwrap();
        let error = InverseKinematics::new(&iiwa).unwrap_err();
        assert!(error.to_string().contains("7 joints"), "{error}");
        // A URDF is read in its MD-H form: the UR10's wrist is offset as in its MD-H file.
        let urdf = Robot::load(crate::model::shipped_file("ur10", "robot.urdf")).unwrap();
        let error = InverseKinematics::new(&urdf).unwrap_err();
        assert!(
            error
                .to_string()
                .contains("its joints in MD-H form: α3 is not ±90°"),
            "{error}"
        );
        let urdf = Robot::load(crate::model::shipped_file("iiwa14", "robot.urdf")).unwrap();
        let error = InverseKinematics::new(&urdf).unwrap_err();
        assert!(error.to_string().contains("7 joints, not 6"), "{error}");
    }

    /// The seven-axis iiwa: from a seed near a posture, the numerical inverse reaches the
    /// posture's pose exactly, and the solution is the posture nearest the seed (its
    /// distance to the seed has no component along the self-motion). Within the limits
    /// only where that nearest posture is.
    #[test]
    fn seven_axes_reach_the_pose_nearest_the_seed() {
        for file in ["robot.urdf", "robot.toml"] {
            let robot = Robot::load(crate::model::shipped_file("iiwa14", file)).unwrap();
            let mut rng = ChaCha8Rng::seed_from_u64(77);
            let (mut largest_mm, mut largest_rad, mut solved, mut within) = (0.0f64, 0.0f64, 0, 0);
            let tries = 200;
            for _ in 0..tries {
                let q = random_q(&robot, &mut rng);
                let target = robot.tcp_pose(&q);
                // A seed up to 0.3 rad from the posture on every joint.
                let seed: Vec<f64> = q.iter().map(|v| v + rng.gen_range(-0.3..0.3)).collect();
                let target_t = transform_from_isometry(&target);
                let Some(solution) = solve_near_chain(robot.chain(), &target_t, &seed) else {
                    continue;
                };
                solved += 1;
                if let Some(limited) = solve_near(&robot, &target, &seed) {
                    assert!(robot.within_limits(&limited));
                    let error = pose_error(&target, &robot.tcp_pose(&limited));
                    assert!(error.fixed_rows::<3>(0).norm() <= 1e-9);
                    within += 1;
                }
                let error = pose_error(&target, &robot.tcp_pose(&solution));
                largest_mm = largest_mm.max(error.fixed_rows::<3>(0).norm());
                largest_rad = largest_rad.max(error.fixed_rows::<3>(3).norm());
                // Nearest: (solution − seed) lies in the row space of J (no null-space part).
                let d = DVector::from_fn(7, |i, _| solution[i] - seed[i]);
                let null =
                    null_space_part(robot.chain(), &DVector::from_column_slice(&solution), &d)
                        .unwrap();
                assert!(
                    null.norm() < 1e-9,
                    "null-space part {} of {}",
                    null.norm(),
                    d.norm()
                );
            }
            println!(
                "iiwa ({file}): {solved} of {tries} poses solved from a seed within 0.3 rad \
                 ({within} within the limits); FK(IK(pose)) − pose at most {largest_mm:.2e} mm, \
                 {largest_rad:.2e} rad"
            );
            assert!(solved >= tries * 99 / 100, "{solved} of {tries}");
            assert!(within >= tries * 98 / 100, "{within} of {tries}");
            assert!(largest_mm <= 1e-9 && largest_rad <= 1e-12);
        }
    }

    /// The pruned search for the nearest postures is the full sort of every drawn posture
    /// by its weighted distance to the pose (ties to the earlier drawn).
    #[test]
    fn the_nearest_postures_are_those_of_a_full_sort() {
        let robot = Robot::load(crate::model::shipped_file("iiwa14", "robot.toml")).unwrap();
        let table = PostureTable::new(&robot);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..200 {
            let target = robot.tcp_pose(&random_q(&robot, &mut rng));
            let mut all: Vec<(f64, usize)> = (0..TABLE_POSTURES)
                .map(|k| {
                    let angle = table.rotations[k].angle_to(&target.rotation);
                    let d = (table.positions_mm[k] - target.translation.vector).norm_squared()
                        + (ORIENTATION_WEIGHT_MM_PER_RAD * angle).powi(2);
                    (d, k)
                })
                .collect();
            all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let expected: Vec<usize> = all[..TABLE_STARTS].iter().map(|&(_, k)| k).collect();
            assert_eq!(table.nearest(&target), expected);
        }
    }

    /// Started from the table, the iiwa's poses in front of it, tool down (a measurement
    /// plan's), are solved exactly within the limits, in a few steps, the same each time.
    #[test]
    fn the_table_solves_poses_within_the_limits_in_a_few_steps() {
        let robot = Robot::load(crate::model::shipped_file("iiwa14", "robot.toml")).unwrap();
        let table = PostureTable::new(&robot);
        let down = rotation_from_kuka_abc_deg([0.0, 180.0, 0.0]);
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let (tries, mut solved) = (200, 0);
        for _ in 0..tries {
            let position = [
                rng.gen_range(400.0..600.0),
                rng.gen_range(-200.0..200.0),
                rng.gen_range(300.0..600.0),
            ];
            let tilt = Rotation3::from_scaled_axis(Vector3::new(
                rng.gen_range(-0.05..0.05),
                rng.gen_range(-0.05..0.05),
                rng.gen_range(-0.05..0.05),
            ));
            let target = isometry_from_parts(position, &(tilt * down));
            let Some(q) = table.solve(&robot, &target) else {
                continue;
            };
            solved += 1;
            assert!(robot.within_limits(&q));
            let error = pose_error(&target, &robot.tcp_pose(&q));
            assert!(error.fixed_rows::<3>(0).norm() <= POSITION_TOLERANCE_MM);
            assert!(error.fixed_rows::<3>(3).norm() <= ORIENTATION_TOLERANCE_RAD);
            assert_eq!(table.solve(&robot, &target), Some(q));
        }
        assert_eq!(solved, tries);
    }

    /// Position first, for a SCARA (no tilt): every pose of a random posture is reached
    /// exactly from a seed a few degrees away; the same pose tilted by 1 mrad is reached
    /// in position to 1e-9 mm, upright, its orientation 1 mrad from the one asked (the
    /// tilt, nothing more); a six-joint robot's reachable pose is reached as `to_pose` does.
    #[test]
    fn position_first_reaches_the_position_and_the_orientation_the_joints_allow() {
        let scara = Robot::from_toml_str(
            "name = \"SCARA\"\n[tool]\ntranslation_mm = [0.0, 0.0, -50.0]\n\
             [[joints]]\nxyz_mm = [0.0, 0.0, 400.0]\nlimits_deg = [-130.0, 130.0]\n\
             [[joints]]\nxyz_mm = [325.0, 0.0, 0.0]\nlimits_deg = [-145.0, 145.0]\n\
             [[joints]]\ntype = \"prismatic\"\nxyz_mm = [275.0, 0.0, 0.0]\naxis = [0.0, 0.0, -1.0]\n\
             limits_mm = [0.0, 200.0]\n[[joints]]\naxis = [0.0, 0.0, 1.0]\nlimits_deg = [-360.0, 360.0]\n",
        )
        .unwrap();
        let ur5 = Robot::load(shipped_robot_path("ur5")).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for robot in [&scara, &ur5] {
            let mut solved = 0;
            for _ in 0..200 {
                let q: Vec<f64> = (0..robot.joint_count())
                    .map(|i| {
                        let [lo, hi] = robot.sampling_range(i);
                        rng.gen_range(0.8 * lo..0.8 * hi)
                    })
                    .collect();
                let seed: Vec<f64> = q.iter().map(|v| v + rng.gen_range(-0.05..0.05)).collect();
                let pose = robot.tcp_pose(&q);
                let Some(found) = solve_position_first(robot, &pose, &seed) else {
                    continue;
                };
                solved += 1;
                let reached = robot.tcp_pose(&found);
                assert!((reached.translation.vector - pose.translation.vector).norm() < 1e-9);
                assert!(
                    reached.rotation.angle_to(&pose.rotation) < 1e-9,
                    "{}",
                    robot.name
                );
                if robot.joint_count() < 6 {
                    let tilt = UnitQuaternion::from_scaled_axis(Vector3::new(1e-3, 0.0, 0.0));
                    let tilted = Isometry3::from_parts(pose.translation, tilt * pose.rotation);
                    let found = solve_position_first(robot, &tilted, &seed).unwrap();
                    let reached = robot.tcp_pose(&found);
                    assert!((reached.translation.vector - pose.translation.vector).norm() < 1e-9);
                    let left = reached.rotation.angle_to(&tilted.rotation);
                    assert!((left - 1e-3).abs() < 1e-9, "{left}");
                }
            }
            // A few seeds step past a limit; the rest are solved.
            assert!(solved >= 190, "{}: {solved} of 200", robot.name);
        }
    }

    /// From the home posture too: every pose of a random posture within limits that the
    /// damped steps reach is exact.
    #[test]
    fn numerical_inverse_from_home_is_exact_where_it_converges() {
        let robot = Robot::load(crate::model::shipped_file("ur10", "robot.urdf")).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let mut solved = 0;
        for _ in 0..100 {
            let q: Vec<f64> = random_q(&robot, &mut rng)
                .iter()
                .map(|v| v * 0.25)
                .collect();
            let target = robot.tcp_pose(&q);
            if let Some(solution) = solve_near(&robot, &target, robot.home()) {
                solved += 1;
                let error = pose_error(&target, &robot.tcp_pose(&solution));
                assert!(error.fixed_rows::<3>(0).norm() <= 1e-9, "{error:?}");
            }
        }
        assert!(solved >= 80, "{solved}");
    }
}
