//! The parameters of the calibration model: what each column of the Jacobian is, its unit,
//! and the bounds the trust rules judge it by (module docs of [`crate::calibrate`]).

use adwi_runtime::chain::JointKind;

use adwi_robot::error_model::MdhParameter;
use adwi_robot::model::{Geometry, Robot};

/// One identifiable quantity of the calibration model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Parameter {
    /// An MD-H parameter of joint `joint` (0-based).
    Mdh {
        /// Joint index, 0-based.
        joint: usize,
        /// Which parameter.
        parameter: MdhParameter,
    },
    /// The offset of a chain joint (0-based): rad, or mm when `prismatic`.
    Offset {
        /// Joint index, 0-based.
        joint: usize,
        /// Whether the joint slides (mm) rather than turns (rad).
        prismatic: bool,
    },
    /// Translation of a chain joint's origin along an axis of its frame (0 = x, 1 = y,
    /// 2 = z), mm.
    OriginTranslation {
        /// Joint index, 0-based.
        joint: usize,
        /// The axis.
        axis: usize,
    },
    /// Rotation of a chain joint's origin about an axis of its frame, rad.
    OriginRotation {
        /// Joint index, 0-based.
        joint: usize,
        /// The axis.
        axis: usize,
    },
    /// Tool translation along a flange axis (0 = x, 1 = y, 2 = z), mm.
    ToolTranslation(usize),
    /// Tool rotation about a flange axis, rad.
    ToolRotation(usize),
    /// Base registration translation along a base axis, mm.
    BaseTranslation(usize),
    /// Base registration rotation about a base axis, rad.
    BaseRotation(usize),
    /// The gravity compliance of a revolute joint (0-based), µrad/(N·m): its deviation
    /// from the robot file's (module docs, "Gravity compliance").
    Compliance {
        /// Joint index, 0-based.
        joint: usize,
    },
    /// A joint-space term of a revolute joint (0-based), rad: the coefficient of
    /// `sin(h·q)` (or `cos(h·q)` when `cosine`) in the joint's angle error
    /// ([`adwi_runtime::joint_terms`]; module docs, "Joint-space terms").
    JointTerm {
        /// Joint index, 0-based.
        joint: usize,
        /// The harmonic, 1 or 2.
        harmonic: u8,
        /// The cosine's coefficient rather than the sine's.
        cosine: bool,
    },
}

impl Parameter {
    /// Whether the parameter is a length (mm) rather than an angle (rad).
    pub fn is_length(self) -> bool {
        match self {
            Parameter::Mdh { parameter, .. } => {
                matches!(parameter, MdhParameter::A | MdhParameter::D)
            }
            Parameter::Offset { prismatic, .. } => prismatic,
            Parameter::OriginTranslation { .. }
            | Parameter::ToolTranslation(_)
            | Parameter::BaseTranslation(_) => true,
            Parameter::OriginRotation { .. }
            | Parameter::ToolRotation(_)
            | Parameter::BaseRotation(_)
            | Parameter::Compliance { .. }
            | Parameter::JointTerm { .. } => false,
        }
    }

    /// Whether the parameter is a joint's gravity compliance (µrad/(N·m)).
    pub fn is_compliance(self) -> bool {
        matches!(self, Parameter::Compliance { .. })
    }

    /// Whether the parameter is a joint-space term (rad).
    pub fn is_joint_term(self) -> bool {
        matches!(self, Parameter::JointTerm { .. })
    }

    /// The joint-space terms of `robot` up to harmonic `harmonics` (0, 1 or 2): per
    /// revolute joint `sin q, cos q` (then `sin 2q, cos 2q`), in column order (they follow
    /// the compliances).
    pub fn joint_terms_of(robot: &Robot, harmonics: u8) -> Vec<Parameter> {
        let mut out = Vec::new();
        for joint in 0..robot.joint_count() {
            if robot.joint_kind(joint) != JointKind::Revolute {
                continue;
            }
            for harmonic in 1..=harmonics.min(2) {
                for cosine in [false, true] {
                    out.push(Parameter::JointTerm {
                        joint,
                        harmonic,
                        cosine,
                    });
                }
            }
        }
        out
    }

    /// The unit of its value: `mm`, `rad`, or `µrad/(N·m)` for a compliance.
    pub fn unit(self) -> &'static str {
        if self.is_compliance() {
            "µrad/(N·m)"
        } else if self.is_length() {
            "mm"
        } else {
            "rad"
        }
    }

    /// The gravity compliances of `robot`, one per revolute joint, in column order (they
    /// follow [`Parameter::all_of`] when [`CalibrateOptions::compliance`](super::CalibrateOptions::compliance) asks for them).
    pub fn compliances_of(robot: &Robot) -> Vec<Parameter> {
        (0..robot.joint_count())
            .filter(|&joint| robot.joint_kind(joint) == JointKind::Revolute)
            .map(|joint| Parameter::Compliance { joint })
            .collect()
    }

    /// The parameters of `robot`, in column order (module docs).
    pub fn all_of(robot: &Robot) -> Vec<Parameter> {
        let mut out = Vec::new();
        match robot.geometry() {
            Geometry::Mdh(rows) => {
                for joint in 0..rows.len() {
                    for parameter in MdhParameter::ALL {
                        out.push(Parameter::Mdh { joint, parameter });
                    }
                }
            }
            Geometry::Chain(joints) => {
                for (joint, j) in joints.iter().enumerate() {
                    out.push(Parameter::Offset {
                        joint,
                        prismatic: j.kind == JointKind::Prismatic,
                    });
                    if joint > 0 {
                        for axis in 0..3 {
                            out.push(Parameter::OriginTranslation { joint, axis });
                        }
                        for axis in 0..3 {
                            out.push(Parameter::OriginRotation { joint, axis });
                        }
                    }
                }
            }
        }
        out.extend((0..3).map(Parameter::ToolTranslation));
        out.extend((0..3).map(Parameter::ToolRotation));
        out.extend((0..3).map(Parameter::BaseTranslation));
        out.extend((0..3).map(Parameter::BaseRotation));
        out
    }
}

impl std::fmt::Display for Parameter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        const AXES: [&str; 3] = ["x", "y", "z"];
        match *self {
            Parameter::Mdh { joint, parameter } => {
                write!(f, "Δ{}{}", parameter.name(), joint + 1)
            }
            Parameter::Offset { joint, .. } => write!(f, "Δoffset{}", joint + 1),
            Parameter::OriginTranslation { joint, axis } => {
                write!(f, "Δ{}{}", AXES[axis], joint + 1)
            }
            Parameter::OriginRotation { joint, axis } => {
                write!(f, "Δr{}{}", AXES[axis], joint + 1)
            }
            Parameter::ToolTranslation(a) => write!(f, "tool {}", AXES[a]),
            Parameter::ToolRotation(a) => write!(f, "tool r{}", AXES[a]),
            Parameter::BaseTranslation(a) => write!(f, "base {}", AXES[a]),
            Parameter::BaseRotation(a) => write!(f, "base r{}", AXES[a]),
            Parameter::Compliance { joint } => write!(f, "compliance{}", joint + 1),
            Parameter::JointTerm {
                joint,
                harmonic,
                cosine,
            } => {
                let function = if cosine { "cos" } else { "sin" };
                let times = if harmonic == 1 {
                    String::new()
                } else {
                    harmonic.to_string()
                };
                write!(f, "{function} {times}q{}", joint + 1)
            }
        }
    }
}

impl Parameter {
    /// The largest deviation of this kind that is physically plausible (mm, rad or
    /// µrad/(N·m); module docs, "Trust"): 5° and 5 mm for a joint's geometry, 25 mm and
    /// 10° for the tool, 50 mm and 10° for the base registration, 100 µrad/(N·m) for a
    /// joint's compliance (of its whole compliance, not of the deviation).
    pub fn plausible_bound(self) -> f64 {
        let degrees = |d: f64| d.to_radians();
        match self {
            Parameter::Compliance { .. } => MAX_PLAUSIBLE_COMPLIANCE_URAD_PER_NM,
            Parameter::ToolTranslation(_) => 25.0,
            Parameter::ToolRotation(_) => degrees(10.0),
            Parameter::BaseTranslation(_) => 50.0,
            Parameter::BaseRotation(_) => degrees(10.0),
            Parameter::JointTerm { .. } => MAX_PLAUSIBLE_JOINT_TERM_RAD,
            p if p.is_length() => 5.0,
            _ => degrees(5.0),
        }
    }

    /// A standard error below which the data determine the parameter whatever its value:
    /// 0.01 mm, 0.01 mrad, or 0.001 µrad/(N·m) (10 µrad under the 10 kN·m a 150 kg robot's
    /// shoulder carries).
    pub fn negligible_standard_error(self) -> f64 {
        if self.is_compliance() {
            1e-3
        } else if self.is_length() {
            0.01
        } else {
            1e-5
        }
    }
}

/// The largest plausible coefficient of a joint-space term, rad (0.5°): a gear's
/// transmission error is of arcminutes; a term this large explains something else.
pub const MAX_PLAUSIBLE_JOINT_TERM_RAD: f64 = 0.5 * std::f64::consts::PI / 180.0;

/// The largest plausible gravity compliance of a joint, µrad/(N·m) (module docs, "Trust").
pub const MAX_PLAUSIBLE_COMPLIANCE_URAD_PER_NM: f64 = 100.0;
