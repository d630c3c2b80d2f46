//! A robot described as data: robot files (TOML, URDF), their validation, and the nominal
//! model as a runtime [`Chain`].
//!
//! A robot is a serial chain of 1 to [`MAX_JOINTS`] revolute or prismatic joints: its
//! nominal kinematics (a runtime [`Chain`]: base, joint origins and axes, tool), the range
//! each joint variable may take, a home posture, and — when known — the mass and centre of
//! mass of the link each joint moves (for gravity compliance). Joint values are radians for
//! revolute joints and millimetres for prismatic ones, in chain order: the joint values of a
//! sample map to the chain's movable joints in order.
//!
//! [`Robot::load`] chooses the format by extension: `.urdf` is a URDF file ([`crate::urdf`]),
//! anything else a TOML robot file.
//!
//! # TOML robot files
//!
//! Units are in the key names: `_mm` for lengths, `_deg` for angles. The joints are given
//! either all in the MD-H convention (Hayati-modified Denavit-Hartenberg, `A_i = Rz(θ_i) ·
//! Tz(d_i) · Tx(a_i) · Rx(α_i) · Ry(β_i)`, `θ_i = q_i + theta_offset_i`):
//!
//! ```toml
//! name = "KUKA KR150-2"
//! home_deg = [0.0, -90.0, 90.0, 0.0, 0.0, 0.0]   # optional, zeros by default
//!
//! [tool]                          # TCP in the flange frame (optional: the flange)
//! translation_mm = [0.0, 0.0, 0.0]
//! abc_deg = [0.0, 0.0, 0.0]       # KUKA A, B, C: R = Rz(A)·Ry(B)·Rx(C)
//!
//! [base]                          # the robot base in the frame poses are given in (optional)
//! translation_mm = [0.0, 0.0, 0.0]
//! abc_deg = [0.0, 0.0, 0.0]
//!
//! [[joints]]                      # any number of these, 1 to 12, base to flange
//! a_mm = 350.0
//! d_mm = 750.0
//! alpha_deg = -90.0
//! beta_deg = 0.0                  # optional
//! theta_offset_deg = 0.0          # optional
//! limits_deg = [-185.0, 185.0]
//! mass_kg = 400.0                 # optional: the link this joint moves
//! com_mm = [-300.0, 150.0, 0.0]   # optional: its centre of mass in MD-H frame i
//! compliance_urad_per_nm = 2.5    # optional: gravity compliance, µrad/(N·m)
//!
//! [payload]                       # optional: what the flange carries (tool, workpiece)
//! mass_kg = 100.0
//! com_mm = [0.0, 0.0, 150.0]      # in the last joint's com_mm frame: MD-H frame n, the flange
//! ```
//!
//! or all as general chain joints, the form a URDF joint has (`T = base · O_1 · M_1(q_1 +
//! o_1) ⋯ O_n · M_n(q_n + o_n) · tool`, see [`adwi_runtime::chain`]):
//!
//! ```toml
//! [[joints]]
//! name = "joint_a2"               # optional
//! type = "revolute"               # or "prismatic" (default revolute)
//! xyz_mm = [0.0, 0.0, 202.5]      # the joint's origin in the previous joint's frame
//! rpy_deg = [90.0, 0.0, 180.0]    # after its motion: roll, pitch, yaw as in URDF
//! axis = [0.0, 0.0, 1.0]          # unit axis in the joint's frame (default z)
//! offset_deg = 0.0                # added to the joint variable (offset_mm when prismatic)
//! limits_deg = [-120.0, 120.0]    # limits_mm when prismatic; ±inf for a continuous joint
//! mass_kg = 6.35                  # optional
//! com_mm = [0.3, 59.0, 42.0]      # optional: in the joint's frame after its motion
//! compliance_urad_per_nm = 2.5    # optional, revolute joints only
//! ```
//!
//! where the tool is the TCP in the flange frame: the last joint's frame after its motion,
//! or a `[flange]` (`translation_mm`, `abc_deg`) in it where the mounting flange, the frame
//! a controller's tool data start in, lies beyond. A `[payload]`'s `com_mm` is in the last
//! joint's frame. A TOML file may instead name a URDF file (`urdf = "robot.urdf"`, relative
//! to the TOML file, with optional `base_link`, `tip_link` and `flange_link`:
//! [`crate::urdf`]) and add a `name`, `home_deg`, `[tool]` (TCP in the tip link's frame),
//! `[base]` and `[payload]` (in the last movable joint's frame) to it. The file it names
//! may itself be a TOML robot file naming another (a tool added to a robot), at most
//! [`crate::error::MAX_ROBOT_FILE_DEPTH`] files deep and never in a cycle;
//! [`Robot::load_with_files`] reports every file read. `home_deg` holds degrees for
//! revolute joints and millimetres for prismatic ones.
//!
//! Every number must lie in its plausible range ([`crate::plausible`]: lengths within
//! 1 km, masses to 10⁶ kg, ...); a value beyond is refused with its key.
//!
//! # Gravity compliance
//!
//! `compliance_urad_per_nm` is how far a revolute joint gives under the gravity torque
//! about its axis, µrad per N·m: the arm stands at `q_j + c_j · τ_j(q)` when commanded `q`
//! ([`adwi_runtime::chain`], "Gravity compliance"), with `τ_j` the torque of the masses
//! (`mass_kg`, `com_mm`) of the links joint `j` carries and of the payload, gravity along
//! the base frame's −z. A payload is what the flange carries beyond the arm's own links: a
//! spindle or gripper, the workpiece, a reflector and its holder. On a heavy robot it can
//! outweigh the wrist, so a compliance identified without it is wrong for every posture.
//! `tablec calibrate --compliance` writes the identified compliances under this key. When a
//! file gives one for any joint, the robot's chain carries them all (zero where not given)
//! and the robot's model of where the arm stands is the deflected one
//! ([`Chain::loaded_tcp_pose`]); the commanded pose ([`Robot::tcp_pose`]) is the chain
//! without deflection, as the controller computes it. A calibration starts from these
//! compliances, as it starts from the file's geometry. URDF has no place for them or for a
//! payload: a robot written as URDF ([`Robot::to_urdf_string`]) leaves them out.
//!
//! # Frames
//!
//! MD-H frame `i` is the frame after `A_i` (the flange is frame `n`); a chain joint's frame
//! after its motion is `base · O_1 · M_1 ⋯ O_i · M_i`, which for an MD-H robot is MD-H
//! frame `i − 1` turned by `θ_i`. [`Robot::gravity_model`] gives every centre of mass in the
//! latter, the runtime's convention.

use std::path::{Path, PathBuf};

pub use adwi_runtime::chain::{Chain, ChainJoint, Compliance, JointKind, MAX_JOINTS};
use adwi_samples::pose::kuka_abc_deg_from_rotation;

pub use crate::error::RobotError;
use crate::plausible::{check, check_all, Quantity};

/// One µrad/(N·m), the unit robot files and calibration reports give compliances in, in the
/// runtime's unit, rad per kg·mm²/s² (= rad per µN·m).
pub const URAD_PER_NM: f64 = 1e-12;
use adwi_runtime::kinematics::{MdhJoint, Transform};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// How a robot's joints are described: the parameterisation identification perturbs and
/// the closed-form inverse kinematics needs.
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// MD-H rows, one per joint (all revolute about z); the tool is the TCP in the flange
    /// (MD-H frame `n`).
    Mdh(Vec<MdhJoint>),
    /// General chain joints (URDF, or a TOML file of chain joints); the tool is the TCP in
    /// the last joint's frame after its motion.
    Chain(Vec<ChainJoint>),
}

impl Geometry {
    /// The number of joints.
    pub fn len(&self) -> usize {
        match self {
            Geometry::Mdh(rows) => rows.len(),
            Geometry::Chain(joints) => joints.len(),
        }
    }

    /// Whether there is no joint.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// A centre of mass as a robot file gives it for the link joint `i` (0-based) moves,
    /// MD-H frame `i + 1` for MD-H rows, in that joint's frame after its motion (the
    /// runtime's convention, which chain joints use in files too).
    pub(crate) fn com_from_file(&self, i: usize, com_mm: [f64; 3]) -> [f64; 3] {
        match self {
            Geometry::Mdh(rows) => mdh_constant_part(&rows[i]).transform_point(com_mm),
            Geometry::Chain(_) => com_mm,
        }
    }

    /// [`Geometry::com_from_file`] undone: the centre of mass as a robot file gives it.
    pub(crate) fn com_to_file(&self, i: usize, com_mm: [f64; 3]) -> [f64; 3] {
        match self {
            Geometry::Mdh(rows) => mdh_constant_part(&rows[i])
                .inverse()
                .transform_point(com_mm),
            Geometry::Chain(_) => com_mm,
        }
    }
}

/// The mass and centre of mass of the link a joint moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkInertial {
    /// Mass, kg.
    pub mass_kg: f64,
    /// Centre of mass in the joint's frame after its motion (the runtime's convention), mm.
    pub com_mm: [f64; 3],
}

/// One joint's non-kinematic data.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// Its name (`joint_1` … when the file gives none).
    pub name: String,
    /// `[lower, upper]` limits of the joint variable (not of the variable plus offset), rad
    /// or mm; `[−∞, ∞]` for a continuous joint.
    pub limits: [f64; 2],
    /// The link it moves, when the file gives its mass.
    pub inertial: Option<LinkInertial>,
    /// Its gravity compliance, µrad/(N·m) (module docs, "Gravity compliance"), when the
    /// file gives one; revolute joints only.
    pub compliance_urad_per_nm: Option<f64>,
}

/// Where a robot's chain came from in its URDF file, for writing it back.
#[derive(Debug, Clone)]
pub(crate) struct UrdfSource {
    /// The parsed file.
    pub(crate) robot: urdf_rs::Robot,
    /// The link the chain ends at.
    pub(crate) tip_link: String,
    /// The controller's base frame in the chain's base link (`urdf`, "Base"): the robot's
    /// nominal base is its inverse.
    pub(crate) base_frame: Transform,
    /// Per movable joint of the chain, its index in `robot.joints`.
    pub(crate) movable: Vec<usize>,
    /// Per movable joint, the fixed joints between the previous movable joint (or the base
    /// link) and it, in chain order.
    pub(crate) fixed_before: Vec<Vec<usize>>,
    /// The fixed joints from the last movable joint to the tip link.
    pub(crate) fixed_after: Vec<usize>,
}

/// A validated robot: 1 to 12 joints, a tool, a base, a home posture, and its nominal
/// chain.
#[derive(Debug, Clone)]
pub struct Robot {
    /// Human-readable name, e.g. "KUKA KR150-2".
    pub name: String,
    geometry: Geometry,
    joints: Vec<Joint>,
    base: Transform,
    /// The flange (the frame tool data are given in) in the last joint's frame after its
    /// motion: identity but for a chain whose flange lies beyond its last joint's frame
    /// (a URDF's `tool0`, a chain file's `[flange]`).
    flange: Transform,
    tool: Transform,
    home: Vec<f64>,
    chain: Chain,
    urdf: Option<UrdfSource>,
    /// What the flange carries beyond the links (a tool, a workpiece, a reflector and its
    /// holder), centre of mass in the last joint's frame after its motion like the links'
    /// (module docs, "Gravity compliance").
    payload: Option<LinkInertial>,
}

impl Robot {
    /// A robot of the given parts, validated: 1 to [`MAX_JOINTS`] joints, one [`Joint`]
    /// and one home value per joint, finite geometry, limits with lower < upper, home within
    /// them, non-negative finite masses.
    ///
    /// `tool` is the TCP in the flange frame for an MD-H geometry, in the last joint's frame
    /// after its motion for a chain geometry; `base` the robot's base in the frame poses are
    /// given in.
    ///
    /// # Errors
    ///
    /// The [`RobotError`] naming what is wrong.
    pub fn new(
        name: String,
        geometry: Geometry,
        joints: Vec<Joint>,
        base: Transform,
        tool: Transform,
        home: Vec<f64>,
    ) -> Result<Robot, RobotError> {
        Robot::with_flange_at(
            name,
            geometry,
            joints,
            base,
            Transform::IDENTITY,
            tool,
            home,
        )
    }

    /// [`Robot::new`] for a chain geometry whose flange, the frame `tool` is given in, is
    /// `flange` in the last joint's frame after its motion (a URDF's `tool0` beyond its
    /// last joint, a chain file's `[flange]`): the chain ends in `flange · tool`.
    ///
    /// # Errors
    ///
    /// As [`Robot::new`], and [`RobotError::Invalid`] for a flange other than the identity
    /// on an MD-H geometry (whose flange is frame `n`) or one not finite.
    pub fn with_flange_at(
        name: String,
        geometry: Geometry,
        joints: Vec<Joint>,
        base: Transform,
        flange: Transform,
        tool: Transform,
        home: Vec<f64>,
    ) -> Result<Robot, RobotError> {
        check_counts(&geometry, &joints, &home)?;
        for (t, what) in [(&base, "base"), (&flange, "flange"), (&tool, "tool")] {
            check_all(&t.translation_mm, Quantity::LengthMm, || {
                format!("{what} translation_mm")
            })?;
        }
        check_geometry(&geometry)?;
        let mut chain = match &geometry {
            Geometry::Mdh(_) if flange != Transform::IDENTITY => {
                return Err(RobotError::Invalid {
                    field: "flange".into(),
                    reason: "an MD-H robot's flange is its frame n: give the TCP as the tool"
                        .into(),
                })
            }
            Geometry::Mdh(rows) => Chain::from_mdh(base, rows, tool, None),
            Geometry::Chain(rows) => Chain::new(base, rows, flange.compose(&tool), None),
        }
        .map_err(RobotError::Chain)?;
        let kinds: Vec<JointKind> = chain.joints().iter().map(|j| j.kind).collect();
        for (i, (joint, &kind)) in joints.iter().zip(&kinds).enumerate() {
            check_joint(i + 1, joint, kind)?;
        }
        chain.compliance = compliance_of(&joints, None, &chain.tool);
        check_composed(&chain)?;
        check_home(&home, &joints, &kinds)?;
        Ok(Robot {
            name,
            geometry,
            joints,
            base,
            flange,
            tool,
            home,
            chain,
            urdf: None,
            payload: None,
        })
    }

    /// This robot carrying `payload` at the flange (`None` for nothing beyond the links):
    /// mass and centre of mass in the last joint's frame after its motion, as a link's
    /// ([`LinkInertial`]). Its weight adds to every joint's gravity torque.
    ///
    /// # Errors
    ///
    /// [`RobotError::Invalid`] for a mass that is not finite and ≥ 0 or a centre of mass
    /// that is not finite.
    pub fn with_payload(&self, payload: Option<LinkInertial>) -> Result<Robot, RobotError> {
        if let Some(p) = &payload {
            check_inertial(p, || "payload".to_string())?;
        }
        let mut robot = self.clone();
        robot.payload = payload;
        robot.chain.compliance = compliance_of(&robot.joints, payload, &robot.chain.tool);
        Ok(robot)
    }

    /// What the flange carries beyond the links, when the file says
    /// ([`Robot::with_payload`]).
    pub fn payload(&self) -> Option<LinkInertial> {
        self.payload
    }

    /// This robot with another name, base, tool and home posture (geometry, joints and URDF
    /// source kept).
    ///
    /// # Errors
    ///
    /// As [`Robot::new`].
    pub fn with_parts(
        &self,
        name: String,
        base: Transform,
        tool: Transform,
        home: Vec<f64>,
    ) -> Result<Robot, RobotError> {
        let mut robot = Robot::with_flange_at(
            name,
            self.geometry.clone(),
            self.joints.clone(),
            base,
            self.flange,
            tool,
            home,
        )?;
        robot.urdf = self.urdf.clone();
        robot.with_payload(self.payload)
    }

    /// This robot with another geometry, base and tool (the calibrated model of it): the
    /// name, joints, home posture and URDF source kept.
    ///
    /// # Errors
    ///
    /// As [`Robot::new`].
    pub fn with_geometry(
        &self,
        name: String,
        geometry: Geometry,
        base: Transform,
        tool: Transform,
    ) -> Result<Robot, RobotError> {
        let mut robot = Robot::with_flange_at(
            name,
            geometry,
            self.joints.clone(),
            base,
            self.flange,
            tool,
            self.home.clone(),
        )?;
        robot.urdf = self.urdf.clone();
        robot.with_payload(self.payload)
    }

    pub(crate) fn set_urdf_source(&mut self, source: UrdfSource) {
        self.urdf = Some(source);
    }

    pub(crate) fn urdf_source(&self) -> Option<&UrdfSource> {
        self.urdf.as_ref()
    }

    /// The nominal kinematics as the runtime evaluates them.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// The number of joints.
    pub fn joint_count(&self) -> usize {
        self.joints.len()
    }

    /// The joints' names, limits and masses, base to tool.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Whether joint `i` (0-based) is revolute or prismatic.
    pub fn joint_kind(&self, i: usize) -> JointKind {
        self.chain.joints()[i].kind
    }

    /// The prismatic joints, bit `i` for joint `i` (0-based; the first 64 joints): what a
    /// sample file's joint columns are read as lengths for.
    pub fn prismatic_joints(&self) -> u64 {
        self.chain.prismatic_joints()
    }

    /// How the joints are described.
    pub fn geometry(&self) -> &Geometry {
        &self.geometry
    }

    /// The MD-H rows, when the robot is described in MD-H.
    pub fn mdh(&self) -> Option<&[MdhJoint]> {
        match &self.geometry {
            Geometry::Mdh(rows) => Some(rows),
            Geometry::Chain(_) => None,
        }
    }

    /// The TCP in the flange frame: MD-H frame `n`, or a chain's [`Robot::flange`].
    pub fn tool(&self) -> Transform {
        self.tool
    }

    /// The flange, the frame [`Robot::tool`] and a program's tool data are given in, in
    /// the last joint's frame after its motion: the identity for an MD-H robot (its frame
    /// `n`) and for a chain file without `[flange]`; a URDF's flange link's (`tool0`)
    /// where it lies beyond the last movable joint.
    pub fn flange(&self) -> Transform {
        self.flange
    }

    /// The robot's base in the frame poses are given in.
    pub fn base(&self) -> Transform {
        self.base
    }

    /// The reference posture (rad; mm for prismatic joints): among several
    /// inverse-kinematics solutions the one closest to it is the default, joints with more
    /// than a turn of travel are wrapped toward it, and numerical inverse kinematics starts
    /// from it.
    pub fn home(&self) -> &[f64] {
        &self.home
    }

    /// Whether `q` has one value per joint and every one lies within its limits
    /// (inclusive).
    pub fn within_limits(&self, q: &[f64]) -> bool {
        q.len() == self.joints.len()
            && self
                .joints
                .iter()
                .zip(q)
                .all(|(joint, &v)| (joint.limits[0]..=joint.limits[1]).contains(&v))
    }

    /// The range joint `i` is sampled over: its limits, or one turn centred on the home
    /// posture for a continuous joint (infinite limits: the turn is clipped by the finite
    /// one when only one limit is infinite).
    pub fn sampling_range(&self, i: usize) -> [f64; 2] {
        let [lower, upper] = self.joints[i].limits;
        let home = self.home[i];
        let half = match self.joint_kind(i) {
            JointKind::Revolute => std::f64::consts::PI,
            JointKind::Prismatic => 1000.0,
        };
        [
            if lower.is_finite() {
                lower
            } else {
                (home - half).min(upper - 2.0 * half)
            },
            if upper.is_finite() {
                upper
            } else {
                (home + half).max(lower + 2.0 * half)
            },
        ]
    }

    /// The nominal TCP pose (in the frame poses are given in) at joint values `q`.
    ///
    /// # Panics
    ///
    /// When `q` does not have one value per joint.
    pub fn tcp_pose(&self, q: &[f64]) -> Isometry3<f64> {
        isometry_from_transform(&self.tcp_transform(q))
    }

    /// As [`Robot::tcp_pose`], as a runtime transform.
    ///
    /// # Panics
    ///
    /// When `q` does not have one value per joint.
    pub fn tcp_transform(&self, q: &[f64]) -> Transform {
        self.chain.tcp_pose(q).unwrap_or_else(|| {
            panic!(
                "{} joint values for a robot of {} joints",
                q.len(),
                self.joint_count()
            )
        })
    }

    /// The robot's link masses as a runtime [`Compliance`], with the file's compliances
    /// (zero where it gives none: the starting point of a gravity-compliance model), when
    /// the file gives at least one link's mass; links without one weigh nothing.
    pub fn gravity_model(&self) -> Option<Compliance> {
        if self.joints.iter().all(|j| j.inertial.is_none()) && self.payload.is_none() {
            return None;
        }
        Some(gravity_of(&self.joints, self.payload, &self.chain.tool))
    }

    /// This robot with the given compliances, µrad/(N·m), one per joint (`None` for none):
    /// its chain then carries them (module docs, "Gravity compliance").
    ///
    /// # Errors
    ///
    /// As [`Robot::new`]: a compliance that is not finite, or one for a prismatic joint.
    pub fn with_compliances(&self, compliances: &[Option<f64>]) -> Result<Robot, RobotError> {
        if compliances.len() != self.joints.len() {
            return Err(RobotError::Invalid {
                field: "compliances".into(),
                reason: format!(
                    "{} compliances for {} joints",
                    compliances.len(),
                    self.joints.len()
                ),
            });
        }
        for (i, c) in compliances.iter().enumerate() {
            if let Some(c) = c {
                check(*c, Quantity::ComplianceUradPerNm, || {
                    format!("joint {} compliance_urad_per_nm", i + 1)
                })?;
                if self.joint_kind(i) != JointKind::Revolute {
                    return Err(RobotError::Invalid {
                        field: format!("joint {} compliance_urad_per_nm", i + 1),
                        reason: "a compliance is given for revolute joints only".into(),
                    });
                }
            }
        }
        let mut robot = self.clone();
        for (joint, c) in robot.joints.iter_mut().zip(compliances) {
            joint.compliance_urad_per_nm = *c;
        }
        robot.chain.compliance = compliance_of(&robot.joints, robot.payload, &robot.chain.tool);
        Ok(robot)
    }

    /// The compliances the file gives, µrad/(N·m), per joint (zero where it gives none).
    pub fn compliances_urad_per_nm(&self) -> Vec<f64> {
        self.joints
            .iter()
            .map(|j| j.compliance_urad_per_nm.unwrap_or(0.0))
            .collect()
    }

    /// The robot file of this robot (TOML, the format [`Robot::load`] reads, in the joints'
    /// own style): `comment` lines first. Loaded again it gives the same forward kinematics
    /// to rounding (every number is written with all its digits).
    pub fn to_toml_string(&self, comment: &[String]) -> String {
        let mut out = String::new();
        for block in comment {
            for line in block.lines() {
                out.push_str(&format!("# {line}\n"));
            }
        }
        if !comment.is_empty() {
            out.push('\n');
        }
        let kinds: Vec<JointKind> = self.chain.joints().iter().map(|j| j.kind).collect();
        out.push_str(&format!("name = {}\n", toml_string(&self.name)));
        let home: Vec<f64> = self
            .home
            .iter()
            .zip(&kinds)
            .map(|(&v, &k)| to_unit(v, k))
            .collect();
        out.push_str(&format!("home_deg = {}\n", toml_list(&home)));
        let frame = |out: &mut String, title: &str, t: &Transform| {
            let abc = kuka_abc_deg_from_rotation(&rotation_of(t));
            out.push_str(&format!(
                "\n[{title}]\ntranslation_mm = {}\nabc_deg = {}\n",
                toml_list(&t.translation_mm),
                toml_list(&abc)
            ));
        };
        frame(&mut out, "base", &self.base);
        if self.flange != Transform::IDENTITY {
            frame(&mut out, "flange", &self.flange);
        }
        frame(&mut out, "tool", &self.tool);
        for (i, (joint, &kind)) in self.joints.iter().zip(&kinds).enumerate() {
            out.push_str("\n[[joints]]\n");
            out.push_str(&format!("name = {}\n", toml_string(&joint.name)));
            match &self.geometry {
                Geometry::Mdh(rows) => {
                    let r = &rows[i];
                    out.push_str(&format!(
                        "a_mm = {}\nd_mm = {}\nalpha_deg = {}\nbeta_deg = {}\ntheta_offset_deg = {}\n",
                        toml_float(r.a_mm),
                        toml_float(r.d_mm),
                        toml_float(r.alpha_rad.to_degrees()),
                        toml_float(r.beta_rad.to_degrees()),
                        toml_float(r.theta_offset_rad.to_degrees()),
                    ));
                }
                Geometry::Chain(rows) => {
                    let j = &rows[i];
                    let (roll, pitch, yaw) = rotation_of(&j.origin).euler_angles();
                    let (kind_name, offset_key) = match kind {
                        JointKind::Revolute => ("revolute", "offset_deg"),
                        JointKind::Prismatic => ("prismatic", "offset_mm"),
                    };
                    out.push_str(&format!(
                        "type = \"{kind_name}\"\nxyz_mm = {}\nrpy_deg = {}\naxis = {}\n{offset_key} = {}\n",
                        toml_list(&j.origin.translation_mm),
                        toml_list(&[roll, pitch, yaw].map(f64::to_degrees)),
                        toml_list(&j.axis),
                        toml_float(to_unit(j.offset, kind)),
                    ));
                }
            }
            let limits_key = match kind {
                JointKind::Revolute => "limits_deg",
                JointKind::Prismatic => "limits_mm",
            };
            out.push_str(&format!(
                "{limits_key} = {}\n",
                toml_list(&joint.limits.map(|v| to_unit(v, kind)))
            ));
            if let Some(inertial) = joint.inertial {
                out.push_str(&format!(
                    "mass_kg = {}\ncom_mm = {}\n",
                    toml_float(inertial.mass_kg),
                    toml_list(&self.geometry.com_to_file(i, inertial.com_mm))
                ));
            }
            if let Some(c) = joint.compliance_urad_per_nm {
                out.push_str(&format!("compliance_urad_per_nm = {}\n", toml_float(c)));
            }
        }
        if let Some(payload) = self.payload {
            // In the last link's frame: MD-H frame n, the flange, for MD-H joints.
            let com_mm = self
                .geometry
                .com_to_file(self.joints.len() - 1, payload.com_mm);
            out.push_str(&format!(
                "\n[payload]\nmass_kg = {}\ncom_mm = {}\n",
                toml_float(payload.mass_kg),
                toml_list(&com_mm)
            ));
        }
        out
    }
}

/// The joints' masses and compliances and the payload as a runtime [`Compliance`]
/// (massless links weigh nothing, joints without a compliance have none). The runtime
/// places the payload in the tool frame: its centre of mass moves there from the last
/// joint's frame through the chain's `tool`.
fn gravity_of(joints: &[Joint], payload: Option<LinkInertial>, tool: &Transform) -> Compliance {
    let mut c = Compliance::NONE;
    for (i, joint) in joints.iter().enumerate() {
        if let Some(inertial) = joint.inertial {
            c.link_mass_kg[i] = inertial.mass_kg;
            c.link_com_mm[i] = inertial.com_mm;
        }
        c.compliance[i] = joint.compliance_urad_per_nm.unwrap_or(0.0) * URAD_PER_NM;
    }
    if let Some(p) = payload {
        c.payload_kg = p.mass_kg;
        c.payload_com_mm = tool.inverse().transform_point(p.com_mm);
    }
    c
}

/// The chain's compliance: the joints' and the payload's when any joint gives a
/// compliance, else none.
fn compliance_of(
    joints: &[Joint],
    payload: Option<LinkInertial>,
    tool: &Transform,
) -> Option<Compliance> {
    joints
        .iter()
        .any(|j| j.compliance_urad_per_nm.is_some())
        .then(|| gravity_of(joints, payload, tool))
}

/// A mass within [`Quantity::MassKg`] at a centre of mass within [`Quantity::LengthMm`], or
/// the error naming `owner`'s `mass_kg` or `com_mm`.
fn check_inertial(inertial: &LinkInertial, owner: impl Fn() -> String) -> Result<(), RobotError> {
    check(inertial.mass_kg, Quantity::MassKg, || {
        format!("{} mass_kg", owner())
    })?;
    check_all(&inertial.com_mm, Quantity::LengthMm, || {
        format!("{} com_mm", owner())
    })
}

/// The constant part of an MD-H row, `Tz(d)·Tx(a)·Rx(α)·Ry(β)`: MD-H frame `i` in the
/// joint's frame after its motion.
pub fn mdh_constant_part(row: &MdhJoint) -> Transform {
    MdhJoint {
        theta_offset_rad: 0.0,
        ..*row
    }
    .transform(0.0)
}

/// Degrees for a revolute joint's value, mm for a prismatic one's.
pub(crate) fn to_unit(value: f64, kind: JointKind) -> f64 {
    match kind {
        JointKind::Revolute => value.to_degrees(),
        JointKind::Prismatic => value,
    }
}

/// The unit [`to_unit`] converts to.
pub(crate) fn unit_of(kind: JointKind) -> &'static str {
    match kind {
        JointKind::Revolute => "deg",
        JointKind::Prismatic => "mm",
    }
}

/// The unit vector along `v`, or `None` for a zero or non-finite vector. A direction has
/// no magnitude: a vector whose length would overflow (`1e200 0 0`) or underflow is scaled
/// by its largest component first.
pub(crate) fn unit_axis(v: [f64; 3]) -> Option<[f64; 3]> {
    if !v.iter().all(|x| x.is_finite()) {
        return None;
    }
    let norm = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if norm.is_finite() && norm >= f64::MIN_POSITIVE {
        return Some(v.map(|x| x / norm));
    }
    let largest = v.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
    if largest == 0.0 {
        return None;
    }
    let s = v.map(|x| x / largest);
    let norm = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
    Some(s.map(|x| x / norm))
}

pub(crate) fn finite(value: f64, field: impl FnOnce() -> String) -> Result<(), RobotError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(RobotError::NonFinite { field: field() })
    }
}

/// A float as TOML writes it, every digit kept (`inf` and `-inf` as TOML spells them).
pub(crate) fn toml_float(v: f64) -> String {
    // Debug keeps a decimal point or an exponent, so an integral value stays a float.
    format!("{v:?}")
}

fn toml_list(values: &[f64]) -> String {
    let items: Vec<String> = values.iter().map(|v| toml_float(*v)).collect();
    format!("[{}]", items.join(", "))
}

fn toml_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// The transform of a URDF-style origin: translation (mm), then roll, pitch, yaw (rad) about
/// the fixed x, y, z axes (`R = Rz(yaw)·Ry(pitch)·Rx(roll)`).
pub fn transform_from_xyz_rpy(xyz_mm: [f64; 3], rpy_rad: [f64; 3]) -> Transform {
    let [roll, pitch, yaw] = rpy_rad;
    transform_from_parts(xyz_mm, &Rotation3::from_euler_angles(roll, pitch, yaw))
}

/// The roll, pitch, yaw (rad) of a transform's rotation, the inverse of
/// [`transform_from_xyz_rpy`].
pub fn rpy_of(transform: &Transform) -> [f64; 3] {
    let (roll, pitch, yaw) = rotation_of(transform).euler_angles();
    [roll, pitch, yaw]
}

/// The pose with the given translation (mm) and rotation.
pub fn isometry_from_parts(translation_mm: [f64; 3], rotation: &Rotation3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(Vector3::from(translation_mm)),
        UnitQuaternion::from_rotation_matrix(rotation),
    )
}

/// A runtime transform as a nalgebra isometry.
///
/// The rotation is re-orthonormalised through a quaternion; for a transform that came out of
/// a forward kinematics that changes it by rounding noise only.
pub fn isometry_from_transform(transform: &Transform) -> Isometry3<f64> {
    isometry_from_parts(transform.translation_mm, &rotation_of(transform))
}

/// A nalgebra isometry as a runtime transform.
pub fn transform_from_isometry(isometry: &Isometry3<f64>) -> Transform {
    let t = &isometry.translation.vector;
    transform_from_parts([t.x, t.y, t.z], &isometry.rotation.to_rotation_matrix())
}

/// The runtime transform with the given translation (mm) and rotation matrix, exactly.
pub fn transform_from_parts(translation_mm: [f64; 3], rotation: &Rotation3<f64>) -> Transform {
    let m = rotation.matrix();
    Transform {
        rotation: [0, 1, 2].map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]),
        translation_mm,
    }
}

/// The rotation part of a runtime transform, as a nalgebra rotation.
pub fn rotation_of(transform: &Transform) -> Rotation3<f64> {
    let r = &transform.rotation;
    Rotation3::from_matrix_unchecked(Matrix3::new(
        r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
    ))
}

/// The frames of a chain at joint values `q`: per joint, its frame before its motion
/// (`base · O_1 · M_1 ⋯ O_i`) and after it (`… · M_i(q_i + o_i)`), in the frame poses are
/// given in; the TCP pose last. The same products as [`Chain::tcp_pose`].
///
/// # Panics
///
/// When `q` does not have one value per joint.
pub fn chain_frames(chain: &Chain, q: &[f64]) -> (Vec<(Transform, Transform)>, Transform) {
    assert_eq!(q.len(), chain.joint_count(), "one joint value per joint");
    let mut frames = Vec::with_capacity(q.len());
    let mut pose = chain.base;
    for (joint, &value) in chain.joints().iter().zip(q) {
        let before = pose.compose(&joint.origin);
        pose = before.compose(&joint.motion(value + joint.offset));
        frames.push((before, pose));
    }
    (frames, pose.compose(&chain.tool))
}

/// The path of a robot shipped in this repository's `tables/` folder, e.g.
/// `shipped_robot_path("kr150-2")` (its `robot.toml`).
pub fn shipped_robot_path(name: &str) -> PathBuf {
    shipped_file(name, "robot.toml")
}

/// A file of a robot shipped in this repository's `tables/` folder, e.g.
/// `shipped_file("iiwa14", "robot.urdf")`.
pub fn shipped_file(robot: &str, file: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tables")
        .join(robot)
        .join(file)
}

/// The joint count within the runtime's bound, and one joint description and one home
/// value per joint.
fn check_counts(geometry: &Geometry, joints: &[Joint], home: &[f64]) -> Result<(), RobotError> {
    let n = geometry.len();
    if n == 0 || n > MAX_JOINTS {
        return Err(RobotError::JointCount { found: n });
    }
    if joints.len() != n {
        return Err(RobotError::Invalid {
            field: "joints".into(),
            reason: format!("{} joint descriptions for {n} joints", joints.len()),
        });
    }
    if home.len() != n {
        return Err(RobotError::HomeLength {
            expected: n,
            found: home.len(),
        });
    }
    Ok(())
}

/// Every length and angle of the geometry as given, plausible.
fn check_geometry(geometry: &Geometry) -> Result<(), RobotError> {
    match geometry {
        Geometry::Mdh(rows) => {
            for (i, row) in rows.iter().enumerate() {
                let values = [
                    ("a_mm", row.a_mm, Quantity::LengthMm),
                    ("d_mm", row.d_mm, Quantity::LengthMm),
                    ("alpha_deg", row.alpha_rad.to_degrees(), Quantity::AngleDeg),
                    ("beta_deg", row.beta_rad.to_degrees(), Quantity::AngleDeg),
                    (
                        "theta_offset_deg",
                        row.theta_offset_rad.to_degrees(),
                        Quantity::AngleDeg,
                    ),
                ];
                for (key, value, quantity) in values {
                    check(value, quantity, || format!("joint {} {key}", i + 1))?;
                }
            }
        }
        Geometry::Chain(rows) => {
            for (i, row) in rows.iter().enumerate() {
                let number = i + 1;
                check_all(&row.origin.translation_mm, Quantity::LengthMm, || {
                    format!("joint {number} xyz_mm")
                })?;
                match row.kind {
                    JointKind::Revolute => {
                        check(row.offset.to_degrees(), Quantity::AngleDeg, || {
                            format!("joint {number} offset_deg")
                        })?
                    }
                    JointKind::Prismatic => check(row.offset, Quantity::LengthMm, || {
                        format!("joint {number} offset_mm")
                    })?,
                }
            }
        }
    }
    Ok(())
}

/// Joint `number`'s limits (a non-empty range of plausible values), its inertial and its
/// compliance (revolute joints only).
fn check_joint(number: usize, joint: &Joint, kind: JointKind) -> Result<(), RobotError> {
    let unit = unit_of(kind);
    let [lower, upper] = joint.limits;
    if lower.is_nan() || upper.is_nan() {
        return Err(RobotError::NonFinite {
            field: format!("joint {number} limits"),
        });
    }
    // NaN was refused above; [inf, inf] and [-inf, -inf] are empty too.
    if lower >= upper || lower == f64::INFINITY || upper == f64::NEG_INFINITY {
        return Err(RobotError::EmptyLimits {
            joint: number,
            lower: to_unit(lower, kind),
            upper: to_unit(upper, kind),
            unit,
        });
    }
    let quantity = match kind {
        JointKind::Revolute => Quantity::JointLimitDeg,
        JointKind::Prismatic => Quantity::LengthMm,
    };
    for (i, value) in joint.limits.into_iter().enumerate() {
        if value.is_finite() {
            check(to_unit(value, kind), quantity, || {
                format!("joint {number} limits_{unit}[{i}]")
            })?;
        }
    }
    if let Some(inertial) = &joint.inertial {
        check_inertial(inertial, || format!("joint {number}"))?;
    }
    if let Some(c) = joint.compliance_urad_per_nm {
        check(c, Quantity::ComplianceUradPerNm, || {
            format!("joint {number} compliance_urad_per_nm")
        })?;
        if kind != JointKind::Revolute {
            return Err(RobotError::Invalid {
                field: format!("joint {number} compliance_urad_per_nm"),
                reason: "a compliance is given for revolute joints only".into(),
            });
        }
    }
    Ok(())
}

/// The composed chain's translations (fixed joints folded in, a tool after a URDF's tip)
/// still within the bound.
fn check_composed(chain: &Chain) -> Result<(), RobotError> {
    // Composed (fixed joints folded in, a tool after a URDF's tip), the chain's
    // translations must still be within the bound (the table format's, which
    // `adwi_runtime::format::check_chain_plausible` holds exactly; here to rounding, so
    // that a robot file the tool writes reads again).
    for (t, what) in [(&chain.base, "base"), (&chain.tool, "tool")] {
        check_all(&t.translation_mm, Quantity::LengthMm, || {
            format!("the robot's {what} translation (mm, composed)")
        })?;
    }
    for (i, joint) in chain.joints().iter().enumerate() {
        check_all(&joint.origin.translation_mm, Quantity::LengthMm, || {
            format!("joint {} origin (mm, composed)", i + 1)
        })?;
    }
    Ok(())
}

/// Each home value finite and within its joint's limits.
fn check_home(home: &[f64], joints: &[Joint], kinds: &[JointKind]) -> Result<(), RobotError> {
    for (i, ((&value, joint), &kind)) in home.iter().zip(joints).zip(kinds).enumerate() {
        finite(value, || format!("home_deg[{i}]"))?;
        let [lower, upper] = joint.limits;
        if !(lower..=upper).contains(&value) {
            return Err(RobotError::HomeOutsideLimits {
                joint: i + 1,
                home: to_unit(value, kind),
                lower: to_unit(lower, kind),
                upper: to_unit(upper, kind),
                unit: unit_of(kind),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kr150() -> Robot {
        Robot::load(shipped_robot_path("kr150-2")).unwrap()
    }

    #[test]
    fn shipped_kr150_matches_the_method_table() {
        let robot = kr150();
        let rows = robot.mdh().unwrap();
        let a: Vec<f64> = rows.iter().map(|j| j.a_mm).collect();
        let d: Vec<f64> = rows.iter().map(|j| j.d_mm).collect();
        let alpha: Vec<f64> = rows.iter().map(|j| j.alpha_rad.to_degrees()).collect();
        assert_eq!(a, [350.0, 1250.0, 55.0, 0.0, 0.0, 0.0]);
        assert_eq!(d, [750.0, 0.0, 0.0, 1100.0, 0.0, 230.0]);
        for (got, want) in alpha.iter().zip([-90.0, 0.0, 90.0, -90.0, 90.0, 0.0]) {
            assert!((got - want).abs() < 1e-12);
        }
        assert!(robot.within_limits(robot.home()));
        assert_eq!(robot.tool(), Transform::IDENTITY);
        assert_eq!(robot.base(), Transform::IDENTITY);
        assert_eq!(robot.joint_count(), 6);
        assert!(robot.gravity_model().is_none());
    }

    #[test]
    fn shipped_ur5_loads() {
        let robot = Robot::load(shipped_robot_path("ur5")).unwrap();
        assert_eq!(robot.mdh().unwrap()[1].a_mm, -425.0);
        assert!(robot.tool().translation_mm[2] > 25.0);
    }

    /// The MD-H chain is the MD-H forward kinematics: the runtime's two evaluations agree.
    #[test]
    fn the_chain_of_an_mdh_robot_is_its_mdh_forward_kinematics() {
        let robot = kr150();
        let rows: [MdhJoint; 6] = robot.mdh().unwrap().try_into().unwrap();
        let q = [0.2, -1.1, 1.9, 0.4, 0.7, -2.0];
        let want = adwi_runtime::kinematics::forward(&rows, &robot.tool(), &q);
        let got = robot.tcp_transform(&q);
        for a in 0..3 {
            assert!((got.translation_mm[a] - want.translation_mm[a]).abs() < 1e-9);
        }
    }

    fn kr150_text() -> String {
        std::fs::read_to_string(shipped_robot_path("kr150-2")).unwrap()
    }

    #[test]
    fn any_joint_count_from_one_to_twelve_loads_and_others_are_refused() {
        let text = kr150_text();
        let first = text.find("[[joints]]").unwrap();
        let (head, joints) = text.split_at(first);
        let one_joint = &joints[..joints[1..].find("[[joints]]").unwrap() + 1];
        let head = head.replace("home_deg = [0.0, -90.0, 90.0, 0.0, 0.0, 0.0]", "");
        for n in [1, 5, 7, 12] {
            let robot = Robot::from_toml_str(&format!("{head}{}", one_joint.repeat(n))).unwrap();
            assert_eq!(robot.joint_count(), n);
            assert_eq!(robot.chain().joint_count(), n);
            assert_eq!(robot.home(), vec![0.0; n]);
        }
        for n in [0, 13] {
            let error =
                Robot::from_toml_str(&format!("{head}{}", one_joint.repeat(n))).unwrap_err();
            assert!(
                matches!(error, RobotError::JointCount { found } if found == n),
                "{error}"
            );
        }
        // A home posture of the wrong length is refused.
        let error =
            Robot::from_toml_str(&text.replacen("0.0, 0.0, 0.0]", "0.0, 0.0]", 1)).unwrap_err();
        assert!(
            matches!(
                error,
                RobotError::HomeLength {
                    expected: 6,
                    found: 5
                }
            ),
            "{error}"
        );
    }

    #[test]
    fn reversed_limits_unknown_keys_and_mixed_styles_are_refused() {
        let text = kr150_text().replacen(
            "limits_deg = [-185.0, 185.0]",
            "limits_deg = [10.0, -10.0]",
            1,
        );
        let error = Robot::from_toml_str(&text).unwrap_err();
        assert!(
            matches!(error, RobotError::EmptyLimits { joint: 1, .. }),
            "{error}"
        );

        let text = kr150_text().replacen("a_mm = 350.0", "a_mm = 350.0\nlength = 3", 1);
        let error = Robot::from_toml_str(&text).unwrap_err();
        assert!(matches!(error, RobotError::Parse { .. }), "{error}");

        let text = kr150_text().replacen("a_mm = 1250.0", "axis = [0.0, 0.0, 1.0]", 1);
        let error = Robot::from_toml_str(&text).unwrap_err();
        assert!(
            matches!(error, RobotError::JointStyle { joint: 2, .. }),
            "{error}"
        );
    }

    /// A robot written as a file and read again is the same robot, in either style.
    #[test]
    fn written_robot_files_load_as_the_same_robot() {
        let robot = kr150();
        let text = robot.to_toml_string(&["a test".into()]);
        let back = Robot::from_toml_str(&text).unwrap();
        let q = [0.2, -1.1, 1.9, 0.4, 0.7, -2.0];
        let (a, b) = (robot.tcp_transform(&q), back.tcp_transform(&q));
        for i in 0..3 {
            assert!(
                (a.translation_mm[i] - b.translation_mm[i]).abs() < 1e-9,
                "{text}"
            );
        }
        assert_eq!(back.joints()[0].limits, robot.joints()[0].limits);

        let chain_text = r#"
name = "two slides and a turn"
home_deg = [0.0, 10.0, 0.0]
[tool]
translation_mm = [0.0, 0.0, 100.0]
[[joints]]
type = "prismatic"
axis = [1.0, 0.0, 0.0]
limits_mm = [-500.0, 500.0]
mass_kg = 20.0
com_mm = [0.0, 0.0, 50.0]
[[joints]]
type = "prismatic"
xyz_mm = [0.0, 0.0, 300.0]
rpy_deg = [0.0, 0.0, 90.0]
axis = [1.0, 0.0, 0.0]
offset_mm = 5.0
limits_mm = [0.0, 800.0]
[[joints]]
xyz_mm = [0.0, 50.0, 0.0]
rpy_deg = [-90.0, 30.0, 0.0]
axis = [0.0, 0.0, -1.0]
limits_deg = [-inf, inf]
"#;
        let robot = Robot::from_toml_str(chain_text).unwrap();
        assert_eq!(robot.joint_kind(0), JointKind::Prismatic);
        assert_eq!(robot.joints()[2].limits, [f64::NEG_INFINITY, f64::INFINITY]);
        let range = robot.sampling_range(2);
        assert!((range[1] - range[0] - 2.0 * std::f64::consts::PI).abs() < 1e-12);
        // At zero: slide 1 at 0, slide 2 at its 5 mm offset along its x = base y, then
        // 50 mm along that frame's y = base −x, then 100 mm along the tool z.
        let pose = robot.tcp_transform(&[0.0, 0.0, 0.0]);
        let (roll, pitch) = (-90f64.to_radians(), 30f64.to_radians());
        let turn = Rotation3::from_euler_angles(roll, pitch, 0.0);
        let z = Rotation3::from_euler_angles(0.0, 0.0, 90f64.to_radians()) * turn * Vector3::z();
        let want = Vector3::new(-50.0, 5.0, 300.0) + z * 100.0;
        assert!(
            (Vector3::from(pose.translation_mm) - want).norm() < 1e-9,
            "{pose:?}"
        );
        let back = Robot::from_toml_str(&robot.to_toml_string(&[])).unwrap();
        let q = [120.0, 300.0, 2.0];
        let (a, b) = (robot.tcp_transform(&q), back.tcp_transform(&q));
        for i in 0..3 {
            assert!((a.translation_mm[i] - b.translation_mm[i]).abs() < 1e-9);
        }
        assert_eq!(back.gravity_model(), robot.gravity_model());
        assert_eq!(back.home(), robot.home());
    }

    /// A chain file's `[flange]` places the flange beyond the last joint's frame, the tool
    /// on it; a URDF robot read to `tool0` is written with its flange and reads back as
    /// the same robot, flange and tool apart; an MD-H file or one naming a URDF file
    /// refuses one.
    #[test]
    fn a_chain_file_places_its_flange_and_keeps_it_when_written() {
        use crate::urdf::LinkNames;
        let text = r#"
name = "one turn"
[flange]
translation_mm = [158.0, 0.0, 0.0]
abc_deg = [0.0, 90.0, 0.0]
[tool]
translation_mm = [0.0, 0.0, 100.0]
[[joints]]
axis = [-1.0, 0.0, 0.0]
limits_deg = [-350.0, 350.0]
"#;
        let robot = Robot::from_toml_str(text).unwrap();
        // The flange 158 mm along x, its z turned onto x: the TCP 258 mm along x at zero.
        let pose = robot.tcp_transform(&[0.0]);
        assert!((Vector3::from(pose.translation_mm) - Vector3::new(258.0, 0.0, 0.0)).norm() < 1e-9);
        assert_eq!(robot.tool().translation_mm, [0.0, 0.0, 100.0]);
        let urdf =
            Robot::load_with(shipped_file("iiwa14", "robot.urdf"), &LinkNames::default()).unwrap();
        // The iiwa's URDF names its media flange `flange`, 45 mm beyond link 7.
        assert!((urdf.flange().translation_mm[2] - 45.0).abs() < 1e-12);
        assert_eq!(urdf.tool(), Transform::IDENTITY);
        for robot in [robot, urdf] {
            let written = robot.to_toml_string(&[]);
            assert!(written.contains("[flange]"), "{written}");
            let back = Robot::from_toml_str(&written).unwrap();
            assert_eq!(back.flange(), robot.flange());
            assert_eq!(back.tool(), robot.tool());
            let q: Vec<f64> = (0..robot.joint_count())
                .map(|i| 0.1 * i as f64 - 0.2)
                .collect();
            let (a, b) = (robot.tcp_transform(&q), back.tcp_transform(&q));
            assert!(
                (Vector3::from(a.translation_mm) - Vector3::from(b.translation_mm)).norm() < 1e-9
            );
        }
        let mdh = kr150().to_toml_string(&[]).replacen(
            "\n[tool]",
            "\n[flange]\ntranslation_mm = [0.0, 0.0, 10.0]\n\n[tool]",
            1,
        );
        let error = Robot::from_toml_str(&mdh).unwrap_err().to_string();
        assert!(
            error.contains("an MD-H robot's flange is its frame n"),
            "{error}"
        );
        let dir = tempfile::tempdir().unwrap();
        let naming = dir.path().join("naming.toml");
        std::fs::write(
            &naming,
            format!(
                "name = \"n\"\nurdf = {:?}\n[flange]\ntranslation_mm = [0.0, 0.0, 1.0]\n",
                shipped_file("ur5", "robot.urdf").display().to_string()
            ),
        )
        .unwrap();
        let error = Robot::load(&naming).unwrap_err().to_string();
        assert!(error.contains("name the link as flange_link"), "{error}");
    }

    /// A file's compliances: the chain carries them with the masses (zero where none is
    /// given), the commanded pose stays undeflected, and a prismatic joint refuses one.
    #[test]
    fn compliances_in_robot_files() {
        let robot = Robot::load(shipped_robot_path("ur5")).unwrap();
        assert!(robot.chain().compliance.is_none());
        let text = robot.to_toml_string(&[]).replacen(
            "mass_kg = 8.393",
            "mass_kg = 8.393\ncompliance_urad_per_nm = 25.0",
            1,
        );
        let compliant = Robot::from_toml_str(&text).unwrap();
        let c = compliant.chain().compliance.unwrap();
        assert_eq!(c.compliance[1], 25.0 * URAD_PER_NM);
        assert_eq!(c.compliance[2], 0.0);
        assert_eq!(c.link_mass_kg[1], 8.393);
        assert_eq!(compliant.compliances_urad_per_nm()[1], 25.0);
        assert_eq!(compliant.gravity_model(), Some(c));
        let q = [0.3, -1.2, 1.0, 0.4, 0.7, 0.1];
        assert_eq!(compliant.tcp_transform(&q), robot.tcp_transform(&q));
        let deflected = compliant.chain().loaded_tcp_pose(&q).unwrap();
        let gap = Vector3::from(deflected.translation_mm)
            - Vector3::from(robot.tcp_transform(&q).translation_mm);
        assert!(gap.norm() > 0.1, "{gap}");
        let back = Robot::from_toml_str(&compliant.to_toml_string(&[])).unwrap();
        assert_eq!(back.chain().compliance.unwrap().compliance, c.compliance);

        let slide = r#"
name = "a slide"
[[joints]]
type = "prismatic"
limits_mm = [0.0, 100.0]
compliance_urad_per_nm = 1.0
"#;
        let error = Robot::from_toml_str(slide).unwrap_err();
        assert!(error.to_string().contains("compliance"), "{error}");
    }

    /// A payload weighs on every joint as a mass at the flange: the same torques and the
    /// same deflected pose as the last link made heavier by it (its centre of mass in the
    /// same frame as that link's, so the two reach the runtime by different paths: the
    /// link's frame, and the tool frame through the chain's tool). Files and robots of
    /// either style carry it, and write it back.
    #[test]
    fn a_payload_weighs_as_a_mass_at_the_flange() {
        let ur5 = Robot::load(shipped_robot_path("ur5")).unwrap();
        let iiwa = Robot::load(shipped_file("iiwa14", "robot.urdf")).unwrap();
        let payload_com_mm = [12.0, -30.0, 80.0];
        for robot in [ur5, iiwa] {
            let n = robot.joint_count();
            let compliances: Vec<Option<f64>> = (0..n).map(|j| Some(10.0 + j as f64)).collect();
            let robot = robot.with_compliances(&compliances).unwrap();
            let payload = LinkInertial {
                mass_kg: 5.0,
                com_mm: payload_com_mm,
            };
            let carrying = robot.with_payload(Some(payload)).unwrap();
            assert_eq!(carrying.payload(), Some(payload));
            let mut joints = robot.joints().to_vec();
            let last = joints[n - 1].inertial.unwrap();
            let mass_kg = last.mass_kg + payload.mass_kg;
            let com_mm = [0, 1, 2].map(|a| {
                (last.mass_kg * last.com_mm[a] + payload.mass_kg * payload.com_mm[a]) / mass_kg
            });
            joints[n - 1].inertial = Some(LinkInertial { mass_kg, com_mm });
            let heavier = Robot::with_flange_at(
                robot.name.clone(),
                robot.geometry().clone(),
                joints,
                robot.base(),
                robot.flange(),
                robot.tool(),
                robot.home().to_vec(),
            )
            .unwrap();
            let q: Vec<f64> = (0..n).map(|j| 0.3 - 0.25 * j as f64).collect();
            let torques = |r: &Robot| {
                r.chain()
                    .gravity_torques(&q, &r.chain().compliance.unwrap())
                    .unwrap()
            };
            let (with_payload, with_mass, without) =
                (torques(&carrying), torques(&heavier), torques(&robot));
            for j in 0..n {
                assert!(
                    (with_payload[j] - with_mass[j]).abs() <= 1e-9 * with_mass[j].abs().max(1.0),
                    "{}: joint {j}: {} against {}",
                    robot.name,
                    with_payload[j],
                    with_mass[j]
                );
            }
            // 5 kg out at the flange loads the shoulder.
            assert!((with_payload[1] - without[1]).abs() > 1e3, "{}", robot.name);
            let (a, b) = (
                carrying.chain().loaded_tcp_pose(&q).unwrap(),
                heavier.chain().loaded_tcp_pose(&q).unwrap(),
            );
            for i in 0..3 {
                assert!((a.translation_mm[i] - b.translation_mm[i]).abs() < 1e-9);
            }
            // Written and read again; a calibrated model keeps it.
            let text = carrying.to_toml_string(&[]);
            assert!(text.contains("\n[payload]\nmass_kg = 5"), "{text}");
            let back = Robot::from_toml_str(&text).unwrap();
            let p = back.payload().unwrap();
            assert_eq!(p.mass_kg, 5.0);
            for a in 0..3 {
                assert!((p.com_mm[a] - payload.com_mm[a]).abs() < 1e-9, "{p:?}");
            }
            let moved = carrying
                .with_parts(
                    "moved".into(),
                    carrying.base(),
                    carrying.tool(),
                    carrying.home().to_vec(),
                )
                .unwrap();
            assert_eq!(moved.payload(), Some(payload));
            assert_eq!(moved.chain().compliance, carrying.chain().compliance);
        }
        // In an MD-H file the payload's centre of mass is in the flange frame, as the last
        // link's `com_mm`: the UR5's flange is 82.3 mm along its last joint's axis.
        let text = format!(
            "{}\n[payload]\nmass_kg = 2.0\ncom_mm = [0.0, 0.0, 10.0]\n",
            std::fs::read_to_string(shipped_robot_path("ur5")).unwrap()
        );
        let robot = Robot::from_toml_str(&text).unwrap();
        let com = robot.payload().unwrap().com_mm;
        assert!((com[2] - (82.3 + 10.0)).abs() < 1e-9, "{com:?}");
        assert!(robot.gravity_model().is_some());
        for bad in [
            "mass_kg = -1.0",
            "mass_kg = nan",
            "mass_kg = 1.0\ncom_mm = [0.0, inf, 0.0]",
        ] {
            let text = format!(
                "{}\n[payload]\n{bad}\n",
                std::fs::read_to_string(shipped_robot_path("ur5")).unwrap()
            );
            let error = Robot::from_toml_str(&text).unwrap_err();
            assert!(error.to_string().contains("payload"), "{bad}: {error}");
        }
    }

    #[test]
    fn transform_conversions_round_trip() {
        let robot = kr150();
        let q = [0.2, -1.1, 1.9, 0.4, 0.7, -2.0];
        let pose = robot.tcp_pose(&q);
        let back = isometry_from_transform(&transform_from_isometry(&pose));
        assert!((back.translation.vector - pose.translation.vector).norm() < 1e-12);
        assert!(back.rotation.angle_to(&pose.rotation) < 1e-14);
    }

    /// The UR5 data set's targets are the nominal forward kinematics of its commanded joint
    /// angles with a tool offset along the flange. With `R`, `p` the flange pose, the target
    /// is `p + R·τ`, linear in the tool translation `τ`; since `RᵀR = I`, its least-squares
    /// estimate is the mean of `Rᵀ·(target − p)`.
    #[test]
    fn ur5_tool_offset_fits_the_data_set_targets() {
        let robot = Robot::load(shipped_robot_path("ur5")).unwrap();
        let flange_robot = robot
            .with_parts(
                robot.name.clone(),
                Transform::IDENTITY,
                Transform::IDENTITY,
                robot.home().to_vec(),
            )
            .unwrap();
        let data = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../tables/ur5/measurements/3D_UR5_uncalibrated_grid_cleaned.csv");
        let mut reader = csv::Reader::from_path(&data).unwrap();
        let mut flanges = Vec::new();
        let mut targets = Vec::new();
        for record in reader.records() {
            let record = record.unwrap();
            let value = |i: usize| record[i].parse::<f64>().unwrap();
            let q_rad: [f64; 6] = std::array::from_fn(|j| value(7 + j).to_radians());
            flanges.push(flange_robot.tcp_pose(&q_rad));
            targets.push(Vector3::new(value(1), value(2), value(3)));
        }
        assert_eq!(flanges.len(), 1000);

        let fitted: Vector3<f64> = flanges
            .iter()
            .zip(&targets)
            .map(|(f, t)| f.rotation.inverse() * (t - f.translation.vector))
            .sum::<Vector3<f64>>()
            / flanges.len() as f64;
        let rms = |tool: &Vector3<f64>| {
            let sum: f64 = flanges
                .iter()
                .zip(&targets)
                .map(|(f, t)| {
                    (f * nalgebra::Point3::from(*tool) - nalgebra::Point3::from(*t)).norm_squared()
                })
                .sum();
            (sum / flanges.len() as f64).sqrt()
        };
        let shipped = Vector3::from(robot.tool().translation_mm);
        println!(
            "UR5 tool fit: fitted {:.4?} mm, residual RMS {:.4} mm; shipped {:.4?} mm, residual RMS {:.4} mm",
            fitted.as_slice(),
            rms(&fitted),
            shipped.as_slice(),
            rms(&shipped)
        );
        // The tool is about 31 mm out along the flange z axis (and 0.09 mm along y).
        assert!(fitted.x.abs() < 0.2 && fitted.y.abs() < 0.2, "{fitted:?}");
        assert!((fitted.z - 31.0).abs() < 1.0, "{fitted:?}");
        // The targets are the model's FK to within rounding of the published joint angles.
        assert!(rms(&fitted) < 0.02, "residual RMS {} mm", rms(&fitted));
        // The shipped robot file carries the fitted tool to its printed precision.
        assert!(
            (shipped - fitted).norm() < 0.01,
            "shipped {shipped:?} vs fitted {fitted:?}"
        );
        assert!(rms(&shipped) < 0.02);
    }
}
