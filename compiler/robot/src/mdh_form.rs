//! A chain of revolute joints (a URDF robot: joint origins and axes) written as MD-H rows,
//! a base and a tool: the same kinematics for every joint vector, so that what is defined
//! on MD-H rows (the closed-form inverse kinematics, its configuration labels) serves a
//! robot whatever file it came from.
//!
//! The rows are plain Denavit-Hartenberg (β = 0) in the distal convention of
//! [`MdhJoint::transform`], `A_i = Rz(q_i + θ_i) · Tz(d_i) · Tx(a_i) · Rx(α_i)`: frame `i−1`'s
//! z axis is joint `i`'s axis as the chain turns it (its sign kept, so `q_i` is the chain's
//! own joint value), frame `i`'s x axis the common normal from joint `i`'s axis to joint
//! `i+1`'s, its origin where that normal meets joint `i+1`'s axis. The free choices:
//!
//! - parallel axes: the normal through frame `i−1`'s origin (`d_i = 0`);
//! - axes that meet: `a_i = 0`, x along `z_{i−1} × z_i`;
//! - frame 0: origin the foot of the chain's base origin on joint 1's axis, x the base
//!   frame's x (or y) made normal to that axis;
//! - the last frame: joint `n`'s axis, x kept from frame `n−1` (`θ_n = α_n = a_n = 0`), origin
//!   the foot of the zero posture's TCP on that axis; what remains of the TCP is the tool.
//!
//! Everything is read at the zero posture (joint offsets included), where a serial chain is
//! its axis lines and its TCP; [`mdh_form`] checks the result against the chain at other
//! postures before handing it out.

use adwi_runtime::chain::{Chain, JointKind};
use adwi_runtime::kinematics::{MdhJoint, Transform};
use nalgebra::{Matrix3, Rotation3, Vector3};

use crate::model::{chain_frames, transform_from_parts};

/// A chain's kinematics as MD-H rows: `base · A_1 ⋯ A_n · tool` is the chain's TCP pose.
#[derive(Debug, Clone, PartialEq)]
pub struct MdhForm {
    /// MD-H frame 0 in the frame poses are given in.
    pub base: Transform,
    /// One row per joint, β = 0.
    pub rows: Vec<MdhJoint>,
    /// The TCP in MD-H frame `n`.
    pub tool: Transform,
}

/// Two axes closer than this are taken to meet, mm; a direction shorter than this (after
/// a projection) as none.
const MEET_TOLERANCE_MM: f64 = 1e-9;
/// Two axes whose directions' cross product is shorter than this are parallel.
const PARALLEL_TOLERANCE: f64 = 1e-12;
/// How far the MD-H form's TCP may lie from the chain's at the check postures, mm and rad.
const AGREEMENT_TOLERANCE: f64 = 1e-7;

/// The MD-H form of `chain` (module docs); `Err` names why there is none: a prismatic
/// joint, two joints turning about one line.
pub fn mdh_form(chain: &Chain) -> Result<MdhForm, String> {
    let n = chain.joint_count();
    if let Some(i) = chain
        .joints()
        .iter()
        .position(|j| j.kind == JointKind::Prismatic)
    {
        return Err(format!("joint {} is prismatic", i + 1));
    }
    let v = Vector3::from;
    let (frames, tcp) = chain_frames(chain, &vec![0.0; n]);
    // Joint j's axis line at the zero posture: a point on it and its direction, as the
    // joint turns (a positive value turns the chain about it right-handedly).
    let axes: Vec<(Vector3<f64>, Vector3<f64>)> = frames
        .iter()
        .zip(chain.joints())
        .map(|((before, _), joint)| {
            (
                v(before.translation_mm),
                v(before.rotate_vector(joint.axis)).normalize(),
            )
        })
        .collect();

    // Frame 0.
    let (p0, z0) = axes[0];
    let base_origin = v(chain.base.translation_mm);
    let mut origin = p0 + z0 * (base_origin - p0).dot(&z0);
    let mut x = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
        .into_iter()
        .map(|e| {
            let e = v(chain.base.rotate_vector(e));
            e - z0 * e.dot(&z0)
        })
        .find_map(|e| e.try_normalize(1e-6))
        .expect("a unit axis is normal to the base's x or y");
    let base = frame(&x, &z0, &origin);

    let mut rows = Vec::with_capacity(n);
    for j in 0..n {
        let (_, z) = axes[j];
        let (foot, next_origin, next_x, next_z) = if let Some(&(p_next, z_next)) = axes.get(j + 1) {
            let (foot, next_origin) = common_normal(&origin, &z, &p_next, &z_next)
                .ok_or_else(|| format!("joints {} and {} turn about one line", j + 1, j + 2))?;
            let normal = next_origin - foot;
            let next_x = normal
                .try_normalize(MEET_TOLERANCE_MM)
                .unwrap_or_else(|| z.cross(&z_next).normalize());
            (foot, next_origin, next_x, z_next)
        } else {
            let foot = origin + z * (v(tcp.translation_mm) - origin).dot(&z);
            (foot, foot, x, z)
        };
        rows.push(MdhJoint {
            a_mm: (next_origin - foot).dot(&next_x),
            d_mm: (foot - origin).dot(&z),
            alpha_rad: signed_angle(&z, &next_z, &next_x),
            beta_rad: 0.0,
            theta_offset_rad: signed_angle(&x, &next_x, &z),
        });
        origin = next_origin;
        x = next_x;
    }
    // Frame n: joint n's axis, frame n−1's x, at the TCP's foot.
    let last = frame(&x, &axes[n - 1].1, &origin);
    let form = MdhForm {
        base,
        tool: last.inverse().compose(&tcp),
        rows,
    };
    check_agreement(chain, &form)?;
    Ok(form)
}

/// The frame of x axis `x` and z axis `z` (unit, normal) at `origin`.
fn frame(x: &Vector3<f64>, z: &Vector3<f64>, origin: &Vector3<f64>) -> Transform {
    let rotation = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[*x, z.cross(x), *z]));
    transform_from_parts([origin.x, origin.y, origin.z], &rotation)
}

/// The angle turning `from` into `to` about `axis` (all unit, `from` and `to` normal to
/// `axis`), rad.
fn signed_angle(from: &Vector3<f64>, to: &Vector3<f64>, axis: &Vector3<f64>) -> f64 {
    from.cross(to).dot(axis).atan2(from.dot(to))
}

/// The common normal from the line through `origin` along `z` to the line through `p` along
/// `w`: its feet on the first and on the second line. Through `origin` where the lines are
/// parallel; `None` where they are one line.
fn common_normal(
    origin: &Vector3<f64>,
    z: &Vector3<f64>,
    p: &Vector3<f64>,
    w: &Vector3<f64>,
) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let r = p - origin;
    let normal = z.cross(w);
    let sin2 = normal.norm_squared();
    if sin2 <= PARALLEL_TOLERANCE * PARALLEL_TOLERANCE {
        let foot = p + w * (origin - p).dot(w);
        return ((foot - origin).norm() > MEET_TOLERANCE_MM).then_some((*origin, foot));
    }
    // Feet origin + s·z and p + t·w with the normal between them orthogonal to both.
    let s = r.cross(w).dot(&normal) / sin2;
    let t = r.cross(z).dot(&normal) / sin2;
    Some((origin + z * s, p + w * t))
}

/// Whether `form` gives the chain's TCP pose at a few postures away from zero.
fn check_agreement(chain: &Chain, form: &MdhForm) -> Result<(), String> {
    let n = chain.joint_count();
    let mdh = Chain::from_mdh(form.base, &form.rows, form.tool, None).map_err(|e| e.to_string())?;
    for k in 1..=3 {
        let q: Vec<f64> = (0..n)
            .map(|i| 0.37 * k as f64 * (1.0 + i as f64).sqrt())
            .collect();
        let (Some(a), Some(b)) = (chain.tcp_pose(&q), mdh.tcp_pose(&q)) else {
            return Err("the chain's pose is undefined".into());
        };
        let apart = (Vector3::from(a.translation_mm) - Vector3::from(b.translation_mm)).norm();
        let turned = (0..3)
            .flat_map(|r| (0..3).map(move |c| (r, c)))
            .map(|(r, c)| (a.rotation[r][c] - b.rotation[r][c]).abs())
            .fold(0.0, f64::max);
        if !(apart <= AGREEMENT_TOLERANCE && turned <= AGREEMENT_TOLERANCE) {
            return Err(format!(
                "its MD-H form does not reproduce it ({apart:.3e} mm apart)"
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::f64::consts::{FRAC_PI_2, PI};

    use proptest::prelude::*;

    use super::*;
    use crate::ik::InverseKinematics;
    use crate::urdf::LinkNames;
    use crate::Robot;

    /// One URDF joint: its origin (m) and rpy in its parent, its axis, its limits (rad).
    type UrdfJoint = ([f64; 3], [f64; 3], [f64; 3], [f64; 2]);

    /// A URDF of revolute joints, `tool0` fixed to the last link at `tool_rpy`.
    fn urdf(name: &str, joints: &[UrdfJoint], tool_rpy: [f64; 3]) -> String {
        let mut text = format!("<robot name=\"{name}\"><link name=\"base_link\"/>");
        let mut parent = "base_link".to_string();
        for (i, (xyz, rpy, axis, [lo, hi])) in joints.iter().enumerate() {
            let child = format!("link_{}", i + 1);
            let v = |a: &[f64; 3]| format!("{} {} {}", a[0], a[1], a[2]);
            text += &format!(
                "<link name=\"{child}\"/><joint name=\"joint_{}\" type=\"revolute\">\
                 <origin xyz=\"{}\" rpy=\"{}\"/><parent link=\"{parent}\"/><child link=\"{child}\"/>\
                 <axis xyz=\"{}\"/><limit effort=\"0\" lower=\"{lo}\" upper=\"{hi}\" velocity=\"1\"/></joint>",
                i + 1,
                v(xyz),
                v(rpy),
                v(axis)
            );
            parent = child;
        }
        text += &format!(
            "<link name=\"tool0\"/><joint name=\"flange-tool0\" type=\"fixed\"><origin xyz=\"0 0 0\" \
             rpy=\"{} {} {}\"/><parent link=\"{parent}\"/><child link=\"tool0\"/></joint></robot>",
            tool_rpy[0], tool_rpy[1], tool_rpy[2]
        );
        text
    }

    fn robot(text: &str) -> Robot {
        crate::urdf::robot_from_urdf_str(text, &LinkNames::default()).unwrap()
    }

    const Z: [f64; 3] = [0.0; 3];

    /// KUKA KR150-2 as ROS-Industrial's `kuka_kr150_support` describes it: KUKA's axis
    /// senses (A1 about −z, A4 and A6 about −x).
    fn kr150_2() -> Robot {
        let d = |deg: f64| deg.to_radians();
        robot(&urdf(
            "kr150_2",
            &[
                ([0.0, 0.0, 0.75], Z, [0.0, 0.0, -1.0], [d(-185.0), d(185.0)]),
                ([0.35, 0.0, 0.0], Z, [0.0, 1.0, 0.0], [d(-146.0), 0.0]),
                ([1.25, 0.0, 0.0], Z, [0.0, 1.0, 0.0], [d(-119.0), d(155.0)]),
                (
                    [0.0, 0.0, -0.055],
                    Z,
                    [-1.0, 0.0, 0.0],
                    [d(-350.0), d(350.0)],
                ),
                ([1.1, 0.0, 0.0], Z, [0.0, 1.0, 0.0], [d(-125.0), d(125.0)]),
                ([0.23, 0.0, 0.0], Z, [-1.0, 0.0, 0.0], [d(-350.0), d(350.0)]),
            ],
            [0.0, FRAC_PI_2, 0.0],
        ))
    }

    /// Fanuc LR Mate 200iD as ROS-Industrial's `fanuc_lrmate200id_support` describes it:
    /// J3 and J5 about −y (J3 turning against J2), J4 and J6 about −x.
    fn lrmate200id() -> Robot {
        let d = |deg: f64| deg.to_radians();
        robot(&urdf(
            "lrmate200id",
            &[
                ([0.0, 0.0, 0.33], Z, [0.0, 0.0, 1.0], [d(-170.0), d(170.0)]),
                ([0.05, 0.0, 0.0], Z, [0.0, 1.0, 0.0], [d(-100.0), d(145.0)]),
                ([0.0, 0.0, 0.33], Z, [0.0, -1.0, 0.0], [d(-70.0), d(205.0)]),
                (
                    [0.0, 0.0, 0.035],
                    Z,
                    [-1.0, 0.0, 0.0],
                    [d(-190.0), d(190.0)],
                ),
                (
                    [0.335, 0.0, 0.0],
                    Z,
                    [0.0, -1.0, 0.0],
                    [d(-125.0), d(125.0)],
                ),
                ([0.08, 0.0, 0.0], Z, [-1.0, 0.0, 0.0], [d(-360.0), d(360.0)]),
            ],
            [PI, -FRAC_PI_2, 0.0],
        ))
    }

    /// Stäubli TX2-60 as ROS-Industrial's `staubli_tx2_60_support` describes it: joints 1
    /// and 2 meet (a1 = 0), the forearm 20 mm to the side, upright at zero.
    fn tx2_60() -> Robot {
        let d = |deg: f64| deg.to_radians();
        robot(&urdf(
            "tx2_60",
            &[
                ([0.0, 0.0, 0.375], Z, [0.0, 0.0, 1.0], [d(-180.0), d(180.0)]),
                (Z, Z, [0.0, 1.0, 0.0], [d(-127.5), d(127.5)]),
                ([0.0, 0.02, 0.29], Z, [0.0, 1.0, 0.0], [d(-152.5), d(152.5)]),
                (Z, Z, [0.0, 0.0, 1.0], [d(-270.0), d(270.0)]),
                ([0.0, 0.0, 0.31], Z, [0.0, 1.0, 0.0], [d(-121.0), d(132.5)]),
                ([0.0, 0.0, 0.07], Z, [0.0, 0.0, 1.0], [d(-270.0), d(270.0)]),
            ],
            Z,
        ))
    }

    /// Joint vectors spread over the robot's limits (a low-discrepancy walk), with J5 = 0
    /// and the zero posture among them.
    fn postures(robot: &Robot, count: usize) -> Vec<[f64; 6]> {
        let mut out: Vec<[f64; 6]> = (1..=count)
            .map(|k| {
                std::array::from_fn(|i| {
                    let [lo, hi] = robot.joints()[i].limits;
                    let step = 0.618_033_988_75 + 0.414_213_562 * i as f64;
                    lo + (hi - lo) * (k as f64 * step).fract()
                })
            })
            .collect();
        let mut flat = out[0];
        flat[4] = 0.0;
        out.push(flat);
        out.push([0.0; 6]);
        out
    }

    fn pose_distance(a: &Transform, b: &Transform) -> f64 {
        let apart = (Vector3::from(a.translation_mm) - Vector3::from(b.translation_mm)).norm();
        let turned = (0..3)
            .flat_map(|r| (0..3).map(move |c| (r, c)))
            .map(|(r, c)| (a.rotation[r][c] - b.rotation[r][c]).abs())
            .fold(0.0, f64::max);
        apart.max(turned)
    }

    #[test]
    fn each_urdf_arm_is_its_mdh_form() {
        for robot in [kr150_2(), lrmate200id(), tx2_60()] {
            let form = mdh_form(robot.chain()).unwrap();
            let mdh = Chain::from_mdh(form.base, &form.rows, form.tool, None).unwrap();
            for q in postures(&robot, 200) {
                let (a, b) = (
                    robot.chain().tcp_pose(&q).unwrap(),
                    mdh.tcp_pose(&q).unwrap(),
                );
                assert!(pose_distance(&a, &b) < 1e-9, "{} at {q:?}", robot.name);
            }
        }
    }

    #[test]
    fn the_urdf_kr150_2_is_labelled_as_the_shipped_mdh_file() {
        // The shipped MD-H file turns A1, A4 and A6 the other way than KUKA counts them.
        let signs = [-1.0, 1.0, 1.0, -1.0, 1.0, -1.0];
        let urdf = kr150_2();
        let file = Robot::load(crate::model::shipped_robot_path("kr150-2")).unwrap();
        let (by_urdf, by_file) = (
            InverseKinematics::new(&urdf).unwrap(),
            InverseKinematics::new(&file).unwrap(),
        );
        let mut labels = std::collections::BTreeSet::new();
        for q in postures(&urdf, 2000) {
            let q_file: [f64; 6] = std::array::from_fn(|i| signs[i] * q[i]);
            let at = |r: &Robot, q: &[f64]| r.tcp_pose(q).translation.vector;
            assert!((at(&urdf, &q) - at(&file, &q_file)).norm() < 1e-9);
            let label = by_urdf.configuration(&q);
            assert_eq!(label, by_file.configuration(&q_file), "at {q:?}");
            labels.insert(label);
        }
        assert_eq!(labels.len(), 8, "every configuration met");
    }

    #[test]
    fn urdf_arms_solve_every_posture_in_its_own_configuration() {
        for robot in [kr150_2(), lrmate200id(), tx2_60()] {
            let ik = InverseKinematics::new(&robot).unwrap();
            let mut labels = std::collections::BTreeSet::new();
            for q in postures(&robot, 300) {
                let label = ik.configuration(&q);
                labels.insert(label);
                let pose = robot.tcp_pose(&q);
                let solutions = ik.solve(&pose);
                let wrapped = |a: f64, b: f64| (a - b + PI).rem_euclid(2.0 * PI) - PI;
                // At a singularity (J5 = 0, the zero posture upright) the posture is one of a
                // continuum: its label is still among the solutions'.
                let found = solutions.iter().find(|s| s.config == label);
                let Some(found) = found else {
                    panic!("{}: no solution labelled {label} at {q:?}", robot.name)
                };
                if q[4].abs() > 1e-3 && ik.solve(&pose).len() > 1 {
                    let apart = (0..6)
                        .map(|i| wrapped(found.q_rad[i], q[i]).abs())
                        .fold(0.0, f64::max);
                    assert!(
                        apart < 1e-7,
                        "{}: {label} at {q:?} solved as {:?}",
                        robot.name,
                        found.q_rad
                    );
                }
                for s in &solutions {
                    assert_eq!(ik.configuration(&s.q_rad), s.config);
                    let reached = robot.chain().tcp_pose(&s.q_rad).unwrap();
                    let asked = crate::model::transform_from_isometry(&pose);
                    assert!(pose_distance(&reached, &asked) < 1e-8);
                }
            }
            assert!(
                labels.len() >= 6,
                "{}: {} labels met",
                robot.name,
                labels.len()
            );
        }
    }

    #[test]
    fn a_shoulder_on_joint_1_is_front_as_the_arm_leans_forward() {
        // TX2-60 upright at zero: a positive J2 leans it toward +x, the front.
        let robot = tx2_60();
        let ik = InverseKinematics::new(&robot).unwrap();
        let forward = ik.configuration(&[0.0, 0.4, 0.9, 0.5, 0.6, 0.7]);
        assert!(!forward.shoulder_back());
        let over = ik.configuration(&[PI, -0.4, -0.9, 0.5, 0.6, 0.7]);
        assert!(over.shoulder_back());
    }

    #[test]
    fn prismatic_joints_and_one_line_have_no_form() {
        let mut joints = [
            ([0.0, 0.0, 0.4], Z, [0.0, 0.0, 1.0], [-1.0, 1.0]),
            ([0.0, 0.0, 0.1], Z, [0.0, 0.0, 1.0], [-1.0, 1.0]),
        ];
        let r = robot(&urdf("two", &joints, Z));
        assert_eq!(
            mdh_form(r.chain()).unwrap_err(),
            "joints 1 and 2 turn about one line"
        );
        joints[1].2 = [1.0, 0.0, 0.0];
        assert!(mdh_form(robot(&urdf("two", &joints, Z)).chain()).is_ok());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// Any revolute chain (random origins, turns and axes) is reproduced by its form.
        #[test]
        fn any_revolute_chain_is_its_mdh_form(
            links in proptest::collection::vec(
                (proptest::array::uniform3(-0.5f64..0.5), proptest::array::uniform3(-PI..PI),
                 proptest::array::uniform3(-1.0f64..1.0)), 1..8),
            tool in proptest::array::uniform3(-PI..PI),
            q in proptest::collection::vec(-PI..PI, 8),
        ) {
            let joints: Vec<_> = links
                .iter()
                .map(|&(xyz, rpy, axis)| (xyz, rpy, axis, [-4.0, 4.0]))
                .collect();
            prop_assume!(joints.iter().all(|j| Vector3::from(j.2).norm() > 0.1));
            let joints: Vec<_> = joints
                .into_iter()
                .map(|(xyz, rpy, axis, limits)| {
                    let u = Vector3::from(axis).normalize();
                    (xyz, rpy, [u.x, u.y, u.z], limits)
                })
                .collect();
            let robot = robot(&urdf("random", &joints, tool));
            let form = mdh_form(robot.chain()).unwrap();
            let mdh = Chain::from_mdh(form.base, &form.rows, form.tool, None).unwrap();
            let q = &q[..joints.len()];
            let (a, b) = (robot.chain().tcp_pose(q).unwrap(), mdh.tcp_pose(q).unwrap());
            prop_assert!(pose_distance(&a, &b) < 1e-8);
        }
    }
}
