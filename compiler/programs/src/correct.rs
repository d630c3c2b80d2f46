//! The command for one target: the table's fixed point, through forward and inverse
//! kinematics where the target is joints or the table is hybrid, with the checks that keep
//! a command from surprising the robot.

use std::f64::consts::TAU;

use adwi_robot::ik::{solve_near, solve_position_first, JOINT_COUNT};
use adwi_robot::{Configuration, InverseKinematics, Robot};
use adwi_runtime::{Evidence, Residual, Status, Table, Target};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// What became of a target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetStatus {
    /// Corrected.
    Ok,
    /// Not corrected: the table gives no correction there (outside its grid, no admissible
    /// sample, a cell its served field does not cover; the runtime's status says which).
    Outside(Status),
    /// Not corrected: the inverse kinematics found no posture for the target or for its
    /// command (out of reach, beyond a joint limit, not in the written configuration).
    IkFailed,
    /// Not corrected: the command's posture is in another configuration than the
    /// target's.
    ConfigurationChanged,
    /// Refused: the correction is larger than the job's bound.
    TooLarge,
    /// Refused: a joint would move more than the job's bound between target and command.
    JointJump,
    /// Not corrected: the fixed point was not reached within the iterations.
    NotConverged,
    /// Not corrected: the program writes the target in part.
    Incomplete,
    /// Not corrected: joint targets need a robot (or a hybrid table's chain).
    NeedsRobot,
    /// Not corrected: the target has no orientation, which its frames (or the inverse
    /// kinematics a hybrid table needs) require.
    NeedsOrientation,
    /// Not corrected: the target is used with different tools or work objects, so no one
    /// command lands it for every use.
    AmbiguousFrame,
    /// Not corrected: the target's numbers give no finite pose or command (a value far
    /// beyond any workspace).
    Invalid,
    /// Not corrected: a motion the reader found but whose target no command computed
    /// offline lands (an offset, a run-time value, a frame not given, an external axis,
    /// an unknown motion), named by its reason.
    Unaccounted(crate::program::Reason),
    /// Refused: a position-only table would answer beyond what its samples cover (an
    /// orientation they never had), where nothing carries its answer
    /// ([`adwi_runtime::Evidence`]); [`Limits::beyond_evidence`] corrects it anyway.
    BeyondEvidence(Evidence),
}

/// A status by its name ([`TargetStatus::as_str`]), as the report's CSV writes it.
impl serde::Serialize for TargetStatus {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

impl TargetStatus {
    /// Whether the target was corrected (its numbers replaced).
    pub fn corrected(self) -> bool {
        self == TargetStatus::Ok
    }

    /// Its name in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            TargetStatus::Ok => "ok",
            TargetStatus::Outside(_) => "outside",
            TargetStatus::IkFailed => "ik_failed",
            TargetStatus::ConfigurationChanged => "configuration_changed",
            TargetStatus::TooLarge => "too_large",
            TargetStatus::JointJump => "joint_jump",
            TargetStatus::NotConverged => "not_converged",
            TargetStatus::Incomplete => "incomplete",
            TargetStatus::NeedsRobot => "needs_robot",
            TargetStatus::NeedsOrientation => "needs_orientation",
            TargetStatus::AmbiguousFrame => "ambiguous_frame",
            TargetStatus::Invalid => "invalid",
            TargetStatus::Unaccounted(reason) => reason.as_str(),
            TargetStatus::BeyondEvidence(_) => "beyond_evidence",
        }
    }
}

/// The bounds of a job's corrections.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// The largest correction of a target's position, mm.
    pub max_correction_mm: f64,
    /// The largest change of one joint between a target and its command, degrees (mm
    /// for a prismatic joint).
    pub max_joint_change_deg: f64,
    /// The fixed point's tolerance: `|command + error(command) − target|`, mm.
    pub tolerance_mm: f64,
    /// The fixed point's iterations (queries).
    pub max_iterations: u32,
    /// Correct a position-only table's targets beyond its samples' evidence too (an
    /// orientation they never had), instead of refusing them. A hybrid table's model
    /// answers there either way, and the report says so.
    pub beyond_evidence: bool,
}

/// What the program says of the posture: a configuration and, per joint, its turn.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Posture {
    /// The configuration, in this project's labels ([`Configuration`]).
    pub configuration: Option<Configuration>,
    /// Per joint, which representative (`q + 2πk`) is meant.
    pub turns: Vec<Turn>,
}

/// Which of a joint's representatives `q + 2πk` a program means.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Turn {
    /// Any: the one nearest the seed.
    Any,
    /// KUKA Turn: negative (true) or not.
    Negative(bool),
    /// ABB robconf: the quadrant `floor(q / 90°)`.
    Quadrant(i64),
    /// Fanuc's turn number k: −180° + 360°k < q ≤ 180° + 360°k.
    Revolution(i64),
}

impl Turn {
    fn holds(self, q_rad: f64) -> bool {
        match self {
            Turn::Any => true,
            Turn::Negative(n) => (q_rad < 0.0) == n,
            Turn::Quadrant(k) => (q_rad.to_degrees() / 90.0).floor() as i64 == k,
            Turn::Revolution(k) => ((q_rad.to_degrees() - 180.0) / 360.0).ceil() as i64 == k,
        }
    }
}

/// A joint value in degrees for a message: three decimals, or where those would show
/// `−0.000` (a hair across zero that decides a turn), the value in full.
fn joint_deg(q_rad: f64) -> String {
    let deg = q_rad.to_degrees();
    if deg != 0.0 && deg.abs() < 5e-4 {
        format!("{deg:.3e}")
    } else {
        format!("{deg:.3}")
    }
}

/// A robot whose TCP is the table's point: forward and inverse kinematics.
pub struct Kinematics {
    robot: Robot,
    /// The closed form and its MD-H rows, or why the robot has none (what a written
    /// configuration's refusal names).
    closed: Result<InverseKinematics, String>,
}

impl Kinematics {
    /// The kinematics of `robot` (its tool the table's point).
    pub fn new(robot: Robot) -> Kinematics {
        let closed = InverseKinematics::new(&robot).map_err(|e| e.to_string());
        Kinematics { robot, closed }
    }

    /// Why postures carry no configuration labels, when they do not: the geometry the
    /// closed form needs, and what of it the robot file breaks.
    pub fn without_configurations(&self) -> Option<&str> {
        self.closed.as_ref().err().map(String::as_str)
    }

    /// The robot.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// Whether postures carry configuration labels (a six-axis spherical wrist).
    pub fn has_configurations(&self) -> bool {
        self.closed.is_ok()
    }

    /// The table point's pose at joint values `q`; `None` for the wrong count.
    pub fn forward(&self, q: &[f64]) -> Option<Isometry3<f64>> {
        let t = self.robot.chain().tcp_pose(q)?;
        Some(adwi_robot::model::isometry_from_transform(&t))
    }

    /// The configuration of `q`, for robots with configuration labels.
    pub fn configuration(&self, q: &[f64]) -> Option<Configuration> {
        let ik = self.closed.as_ref().ok()?;
        let q: [f64; JOINT_COUNT] = q.try_into().ok()?;
        Some(ik.configuration(&q))
    }

    /// The command a posture reaches for the asked `pose`, as [`Kinematics::inverse`]
    /// solves it: `(q, the pose reached, the turn left, rad)`. A robot of six joints or
    /// more reaches the pose asked; one of fewer its position, and of its orientation what
    /// its joints allow (a SCARA keeps its tool upright): the pose reached is the one to
    /// command, and the turn between it and the asked one is said. `ik_failed` when no
    /// posture in the configuration reaches it.
    pub fn reach(
        &self,
        pose: &Isometry3<f64>,
        posture: &Posture,
        near: &[f64],
    ) -> Result<(Vec<f64>, Isometry3<f64>, f64), Failure> {
        let q = self.inverse(pose, posture, near).ok_or_else(|| {
            (
                TargetStatus::IkFailed,
                self.unreached(pose, posture, near, "the command"),
            )
        })?;
        if self.robot.joint_count() >= 6 {
            return Ok((q, *pose, 0.0));
        }
        let reached = self.robot.tcp_pose(&q);
        let left = reached.rotation.angle_to(&pose.rotation);
        Ok((
            q,
            Isometry3::from_parts(pose.translation, reached.rotation),
            left,
        ))
    }

    /// Why no posture in `posture`'s configuration and turns reaches `pose` (`what`, in
    /// words): where one in that configuration does on other turns, the joints whose turn
    /// it is; where one in another configuration does, the singularity between them (a
    /// wrist at J5 = 0°, which the smallest turn flips, is the usual one).
    pub fn unreached(
        &self,
        pose: &Isometry3<f64>,
        posture: &Posture,
        near: &[f64],
        what: &str,
    ) -> String {
        let unreached = format!("no posture reaches {what}");
        let (Some(wanted), Ok(_)) = (posture.configuration, &self.closed) else {
            return unreached;
        };
        // In its configuration on other turns: the turns written are the reason.
        let any_turn = Posture {
            configuration: Some(wanted),
            turns: Vec::new(),
        };
        let off: Vec<String> = self
            .inverse(pose, &any_turn, near)
            .map(|q| {
                (posture.turns.iter().zip(&q).enumerate())
                    .filter(|(_, (turn, v))| !turn.holds(**v))
                    .map(|(i, (_, v))| format!("J{} {}°", i + 1, joint_deg(*v)))
                    .collect()
            })
            .unwrap_or_default();
        if !off.is_empty() {
            return format!(
                "{unreached}: in it, only with {} on another turn than the program writes (within the joints' limits)",
                off.join(", ")
            );
        }
        let free = Posture {
            configuration: None,
            turns: posture.turns.clone(),
        };
        let Some((other, q)) = self
            .inverse(pose, &free, near)
            .and_then(|q| Some((self.configuration(&q)?, q)))
        else {
            return format!(
                "{unreached} (nor in any other: beyond the robot's reach or its joint limits)"
            );
        };
        let crossed: Vec<&str> = [
            (
                wanted.wrist_flip() != other.wrist_flip(),
                "the wrist's (J5 through 0°, axes 4 and 6 aligned)",
            ),
            (
                wanted.elbow_down() != other.elbow_down(),
                "the elbow's (the arm stretched or folded)",
            ),
            (
                wanted.shoulder_back() != other.shoulder_back(),
                "the shoulder's (the wrist centre over axis 1)",
            ),
        ]
        .into_iter()
        .filter_map(|(crossed, what)| crossed.then_some(what))
        .collect();
        if crossed.is_empty() {
            return unreached;
        }
        format!(
            "{unreached}: one reaches it across {} singularity, in configuration {other} (J5 {:.4}°)",
            crossed.join(" and "),
            q[4].to_degrees()
        )
    }

    /// The posture reaching `pose` in `posture`'s configuration and turns nearest `near`:
    /// in closed form where the robot has it, else by damped least squares from `near`
    /// (which then decides the configuration); for a robot of fewer than six joints
    /// position first ([`solve_position_first`]).
    pub fn inverse(
        &self,
        pose: &Isometry3<f64>,
        posture: &Posture,
        near: &[f64],
    ) -> Option<Vec<f64>> {
        let Ok(ik) = &self.closed else {
            // Fewer than six joints cannot take every orientation: position first.
            let q = if self.robot.joint_count() < 6 {
                solve_position_first(&self.robot, pose, near)?
            } else {
                solve_near(&self.robot, pose, near)?
            };
            return posture
                .turns
                .iter()
                .zip(&q)
                .all(|(t, v)| t.holds(*v))
                .then_some(q);
        };
        let distance =
            |q: &[f64]| -> f64 { q.iter().zip(near).map(|(a, b)| (a - b) * (a - b)).sum() };
        ik.solve(pose)
            .into_iter()
            .filter(|s| posture.configuration.is_none_or(|c| c == s.config))
            .filter_map(|s| self.representatives(&s.q_rad, posture, near))
            .min_by(|a, b| distance(a).total_cmp(&distance(b)))
    }

    /// Each joint's representative `q + 2πk` within its limits that holds its turn,
    /// nearest `near`; `None` when a joint has none.
    fn representatives(&self, q: &[f64], posture: &Posture, near: &[f64]) -> Option<Vec<f64>> {
        q.iter()
            .enumerate()
            .map(|(i, &v)| {
                let [lower, upper] = self.robot.joints()[i].limits;
                let turn = posture.turns.get(i).copied().unwrap_or(Turn::Any);
                let seed = near.get(i).copied().unwrap_or(v);
                let nearest = v + TAU * ((seed - v) / TAU).round();
                [
                    nearest - TAU,
                    nearest,
                    nearest + TAU,
                    nearest - 2.0 * TAU,
                    nearest + 2.0 * TAU,
                ]
                .into_iter()
                .filter(|c| (lower..=upper).contains(c) && turn.holds(*c))
                .min_by(|a, b| (a - seed).abs().total_cmp(&(b - seed).abs()))
            })
            .collect()
    }
}

/// A solved command for the table's point.
#[derive(Clone, Debug)]
pub struct Command {
    /// The pose to command the table's point to, base frame.
    pub point: Isometry3<f64>,
    /// The target's posture, when solved or given.
    pub target_joints: Option<Vec<f64>>,
    /// The command's posture, when solved.
    pub joints: Option<Vec<f64>>,
    /// Queries made.
    pub iterations: u32,
    /// Whether the fixed point was reached.
    pub converged: bool,
    /// `|command + error(command) − target|`, mm.
    pub residual_mm: f64,
    /// How much of a hybrid table's residual field the correction at the command held
    /// ([`Residual::Full`] for a position-only table).
    pub residual: Residual,
    /// Where the correction at the command lies beyond the table's evidence.
    pub evidence: Evidence,
    /// The correction's turn a robot of fewer than six joints cannot give its tool at the
    /// command (a SCARA's tilt), left uncorrected, rad ([`Kinematics::reach`]); zero else.
    pub unturned_rad: f64,
}

/// Why no command was found, and the details for the report.
pub type Failure = (TargetStatus, String);

/// What [`solve`] is asked for one target.
#[derive(Clone, Copy, Debug)]
pub struct Request<'a> {
    /// The table's point at the target, base frame.
    pub target: &'a Isometry3<f64>,
    /// Whether the target has an orientation: one without is corrected in position only,
    /// and needs none of the kinematics.
    pub orientation: bool,
    /// The posture the program writes.
    pub posture: &'a Posture,
    /// The target's posture when the program gives it (joint targets).
    pub target_joints: Option<&'a [f64]>,
    /// The posture the inverse kinematics starts nearest.
    pub seed: &'a [f64],
    /// How far the program's TCP lies from the table's point, mm ([`crate::frames::FrameChain::lever_mm`]):
    /// a table with neither a model nor orientation errors cannot correct the turn the
    /// robot's rotation error gives that lever.
    pub lever_mm: f64,
}

/// Solves the command of one table point.
///
/// # Errors
///
/// Why the target gets no command: the [`TargetStatus`] and a detail for the report.
pub fn solve<D: AsRef<[u8]>>(
    table: &Table<D>,
    kinematics: Option<&Kinematics>,
    limits: &Limits,
    request: Request,
) -> Result<Command, Failure> {
    let Request {
        target,
        orientation,
        posture,
        target_joints,
        seed,
        lever_mm,
    } = request;
    let target_joints = target_joints.map(<[f64]>::to_vec);
    let kinematics = kinematics.filter(|_| orientation);
    if table.is_hybrid() && kinematics.is_none() {
        return Err((
            TargetStatus::NeedsOrientation,
            "a hybrid table needs the target's posture, from its orientation".into(),
        ));
    }
    let target_joints = match (target_joints, kinematics) {
        (Some(q), _) => Some(q),
        (None, Some(k)) => Some(k.inverse(target, posture, seed).ok_or_else(|| {
            (
                TargetStatus::IkFailed,
                k.unreached(target, posture, seed, "the target in its configuration"),
            )
        })?),
        (None, None) => None,
    };
    // The configuration the command must keep: written, or the target posture's own.
    let posture = match (&target_joints, kinematics) {
        (Some(q), Some(k)) if posture.configuration.is_none() => Posture {
            configuration: k.configuration(q),
            turns: posture.turns.clone(),
        },
        _ => posture.clone(),
    };
    let config = posture
        .configuration
        .filter(|_| table.has_config())
        .map(|c| c.bits());
    let solving = Solving {
        table,
        limits,
        target,
        posture,
        config,
    };
    let mut command = match kinematics {
        Some(k) if table.is_hybrid() => {
            solving.hybrid(k, target_joints.clone().expect("solved above"))?
        }
        _ => solving.position_table(kinematics, orientation, target_joints.as_deref())?,
    };
    // The TCP rides on the table's point: the frames turn it with the point's correction,
    // whose rotation a table without orientation errors does not know from its samples (a
    // hybrid table's model gives one, but samples of position alone do not determine it:
    // docs/runtime.md, "Another TCP"). A lever its samples did not measure is then beyond
    // their evidence.
    let lever_unknown = !table.has_orientation();
    if lever_unknown && lever_mm > adwi_runtime::format::TCP_MARGIN_MM {
        command.evidence = command.evidence.with(Evidence::TCP);
    }
    check_evidence(table, limits, &command)?;
    if let (Some(k), Some(q), Some(qc)) = (kinematics, &target_joints, &command.joints) {
        check_posture(k, limits, q, qc)?;
    }
    command.target_joints = target_joints;
    Ok(command)
}

/// A command beyond its table's samples: refused unless the limits allow it where nothing
/// carries its answer (a position-only table beyond its samples, any table at a TCP lever
/// its samples did not measure); a hybrid table's model carries an orientation its samples
/// never had, and its report line says so.
fn check_evidence<D: AsRef<[u8]>>(
    table: &Table<D>,
    limits: &Limits,
    command: &Command,
) -> Result<(), Failure> {
    let carried = table.is_hybrid() && !command.evidence.contains(Evidence::TCP);
    if command.evidence.is_within() || carried || limits.beyond_evidence {
        return Ok(());
    }
    // Every reason the answer carries that refuses it: on a hybrid table the TCP's alone
    // (its model carries an orientation or joint angles its samples never had).
    let reasons: Vec<&str> = [
        (
            Evidence::TCP,
            "TCP lever, nor any orientation to turn it by",
        ),
        (Evidence::ORIENTATION, "orientation"),
        (Evidence::JOINTS, "joint angle for its joint terms"),
    ]
    .into_iter()
    .filter(|(flag, _)| {
        command.evidence.contains(*flag) && (*flag == Evidence::TCP || !table.is_hybrid())
    })
    .map(|(_, why)| why)
    .collect();
    Err((
        TargetStatus::BeyondEvidence(command.evidence),
        format!(
            "the table's samples never had this {} (--beyond-evidence corrects it anyway)",
            reasons.join("; nor this ")
        ),
    ))
}

/// The command's posture `qc` against the target's `q`: the same configuration, and no
/// joint moving beyond the limit.
fn check_posture(k: &Kinematics, limits: &Limits, q: &[f64], qc: &[f64]) -> Result<(), Failure> {
    if k.configuration(q) != k.configuration(qc) {
        return Err((
            TargetStatus::ConfigurationChanged,
            format!(
                "configuration {} at the target, {} at the command",
                k.configuration(q).map_or(0, |c| c.bits()),
                k.configuration(qc).map_or(0, |c| c.bits())
            ),
        ));
    }
    let jump = joint_change(k.robot(), q, qc);
    if jump > limits.max_joint_change_deg {
        return Err((
            TargetStatus::JointJump,
            format!(
                "a joint moves {jump:.3}° (bound {}°)",
                limits.max_joint_change_deg
            ),
        ));
    }
    Ok(())
}

/// One target being solved: the table's point there, the posture the command must keep,
/// and the configuration the table is asked in.
struct Solving<'a, D> {
    table: &'a Table<D>,
    limits: &'a Limits,
    target: &'a Isometry3<f64>,
    posture: Posture,
    config: Option<u8>,
}

impl<D: AsRef<[u8]>> Solving<'_, D> {
    /// A hybrid table's command: the fixed point of `command + error(command) = target`,
    /// each query at the command's posture, solved from the target's `q0`.
    fn hybrid(&self, kinematics: &Kinematics, q0: Vec<f64>) -> Result<Command, Failure> {
        let (table, limits, target) = (self.table, self.limits, self.target);
        let p = target.translation.vector;
        let mut point = *target;
        let mut q = q0;
        let mut unturned_rad = 0.0;
        for iteration in 1..=limits.max_iterations.max(1) {
            let c = table.query_with_joints(
                &Target {
                    position_mm: point.translation.vector.into(),
                    config: self.config,
                    rotation_rad: None,
                    tcp_mm: None,
                },
                &q,
            );
            if c.status != Status::Ok {
                return Err((TargetStatus::Outside(c.status), c.status.as_str().into()));
            }
            let e = Vector3::from(c.position_error_mm);
            let residual_mm = (point.translation.vector + e - p).norm();
            if residual_mm <= limits.tolerance_mm {
                return Ok(Command {
                    point,
                    target_joints: None,
                    joints: Some(q),
                    iterations: iteration,
                    converged: true,
                    residual_mm,
                    residual: c.residual,
                    evidence: c.evidence,
                    unturned_rad,
                });
            }
            let asked = Isometry3::from_parts(
                Translation3::from(p - e),
                UnitQuaternion::from_scaled_axis(-Vector3::from(c.orientation_error_rad))
                    * target.rotation,
            );
            (q, point, unturned_rad) = kinematics.reach(&asked, &self.posture, &q)?;
        }
        Err((
            TargetStatus::NotConverged,
            format!("{} iterations", limits.max_iterations),
        ))
    }

    /// A position-only table's command: the table's own fixed point, with the command's
    /// posture solved near the target's when there are kinematics and a target posture.
    fn position_table(
        &self,
        kinematics: Option<&Kinematics>,
        orientation: bool,
        target_joints: Option<&[f64]>,
    ) -> Result<Command, Failure> {
        let (table, limits, target) = (self.table, self.limits, self.target);
        let comp = table.compensate(
            &Target {
                position_mm: target.translation.vector.into(),
                config: self.config,
                // The point's orientation, which a position-only table checks against
                // its samples', when the program writes one.
                rotation_rad: orientation.then(|| target.rotation.scaled_axis().into()),
                tcp_mm: None,
            },
            limits.tolerance_mm,
            limits.max_iterations,
        );
        let status = comp.correction.status;
        if status != Status::Ok {
            return Err((TargetStatus::Outside(status), status.as_str().into()));
        }
        if !comp.converged {
            return Err((
                TargetStatus::NotConverged,
                format!(
                    "residual {:.2e} mm after {} iterations",
                    comp.residual_mm, comp.iterations
                ),
            ));
        }
        let rotation = UnitQuaternion::from_scaled_axis(Vector3::from(comp.command_rotation_rad))
            * target.rotation;
        let asked = Isometry3::from_parts(
            Translation3::from(Vector3::from(comp.command_position_mm)),
            rotation,
        );
        let (joints, point, unturned_rad) = match (kinematics, target_joints) {
            (Some(k), Some(q)) => {
                let (qc, point, unturned) = k.reach(&asked, &self.posture, q)?;
                (Some(qc), point, unturned)
            }
            _ => (None, asked, 0.0),
        };
        Ok(Command {
            point,
            target_joints: None,
            joints,
            iterations: comp.iterations,
            converged: true,
            residual_mm: comp.residual_mm,
            residual: comp.correction.residual,
            evidence: comp.correction.evidence,
            unturned_rad,
        })
    }
}

/// The largest change of one joint between two postures: degrees for a revolute joint, mm
/// for a prismatic one.
pub fn joint_change(robot: &Robot, a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .enumerate()
        .map(|(i, (a, b))| match robot.joint_kind(i) {
            adwi_runtime::chain::JointKind::Revolute => (a - b).abs().to_degrees(),
            adwi_runtime::chain::JointKind::Prismatic => (a - b).abs(),
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::joint_deg;

    #[test]
    fn a_hair_across_zero_is_shown_not_rounded_to_minus_zero() {
        assert_eq!(joint_deg((-2.1e-5f64).to_radians()), "-2.100e-5");
        assert_eq!(joint_deg(0.0), "0.000");
        assert_eq!(joint_deg(19.659f64.to_radians()), "19.659");
        assert_eq!(joint_deg((-0.042f64).to_radians()), "-0.042");
    }
}
