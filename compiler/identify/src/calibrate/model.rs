//! The calibration model: a robot and its parameters, evaluated exactly at any parameter
//! vector, with its analytic Jacobian (module docs of [`crate::calibrate`], "The model",
//! "Identification").

use adwi_runtime::chain::JointKind;
use adwi_runtime::joint_terms::JointTerms;
use adwi_runtime::kinematics::Transform;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use adwi_robot::error_model::{
    apply_deviations, deviations_from_vector, mdh_screws_from, transform_pose_error, MdhParameter,
    Screw, PARAMETERS_PER_JOINT,
};
use adwi_robot::model::{
    chain_frames, mdh_constant_part, rotation_of, transform_from_parts, Geometry, Robot,
    URAD_PER_NM,
};
use adwi_samples::pose::{rotation_from_vector, rotation_vector};

use super::parameters::Parameter;
use super::CalibrateError;

/// The robot and its parameters: the model evaluated at any parameter vector.
#[derive(Debug, Clone)]
pub(super) struct Model {
    pub(super) robot: Robot,
    pub(super) parameters: Vec<Parameter>,
    /// Columns updated multiplicatively (`Exp(δ) · R`): the tool and base rotations.
    pub(super) multiplicative: [usize; 2],
    /// The first tool translation column; tool rotation, base translation and base
    /// rotation follow.
    pub(super) tool_translation: usize,
    /// Per compliance column (they follow the base's), its joint.
    pub(super) compliance_joints: Vec<usize>,
    /// Per joint-space term column (they follow the compliances): joint, harmonic, cosine.
    pub(super) term_columns: Vec<(usize, u8, bool)>,
}

/// A parameter state: the calibrated robot it describes.
#[derive(Debug, Clone)]
pub(super) struct State {
    pub(super) robot: Robot,
    /// The joint-space terms ([`JointTerms::NONE`] without).
    pub(super) terms: JointTerms,
    /// Each MD-H row's constant part ([`mdh_constant_part`]; empty for another geometry):
    /// the same at every sample the Jacobian is taken at.
    mdh_constants: Vec<Transform>,
}

impl Model {
    /// The model of `robot`'s geometry, of its joints' compliances when `compliance`, and
    /// of its joint-space terms up to harmonic `harmonics` (0: none).
    pub(super) fn new(robot: &Robot, compliance: bool, harmonics: u8) -> Model {
        let mut parameters = Parameter::all_of(robot);
        let tool_translation = parameters
            .iter()
            .position(|p| *p == Parameter::ToolTranslation(0))
            .expect("every robot has a tool");
        let compliances = if compliance {
            Parameter::compliances_of(robot)
        } else {
            Vec::new()
        };
        let compliance_joints = compliances
            .iter()
            .map(|p| match p {
                Parameter::Compliance { joint } => *joint,
                _ => unreachable!("compliances_of gives compliances"),
            })
            .collect();
        parameters.extend(compliances);
        let terms = Parameter::joint_terms_of(robot, harmonics);
        let term_columns = terms
            .iter()
            .map(|p| match *p {
                Parameter::JointTerm {
                    joint,
                    harmonic,
                    cosine,
                } => (joint, harmonic, cosine),
                _ => unreachable!("joint_terms_of gives joint terms"),
            })
            .collect();
        parameters.extend(terms);
        Model {
            term_columns,
            robot: robot.clone(),
            multiplicative: [tool_translation + 3, tool_translation + 9],
            tool_translation,
            compliance_joints,
            parameters,
        }
    }

    /// The first compliance column.
    pub(super) fn first_compliance(&self) -> usize {
        self.tool_translation + 12
    }

    /// The first joint-space term column.
    pub(super) fn first_term(&self) -> usize {
        self.first_compliance() + self.compliance_joints.len()
    }

    /// Per column, what the robot file gives for that parameter: the joint's compliance
    /// for a compliance column, zero for the rest (their values are deviations from the
    /// file's geometry).
    pub(super) fn file_values(&self) -> Vec<f64> {
        let compliances = self.robot.compliances_urad_per_nm();
        self.parameters
            .iter()
            .map(|p| match p {
                Parameter::Compliance { joint } => compliances[*joint],
                _ => 0.0,
            })
            .collect()
    }

    pub(super) fn len(&self) -> usize {
        self.parameters.len()
    }

    /// The calibrated robot of parameter vector `x` (module-doc order).
    pub(super) fn state(&self, x: &DVector<f64>) -> Result<State, CalibrateError> {
        let robot = &self.robot;
        let geometry = match robot.geometry() {
            Geometry::Mdh(rows) => {
                let deviations =
                    deviations_from_vector(&x.as_slice()[..rows.len() * PARAMETERS_PER_JOINT]);
                Geometry::Mdh(apply_deviations(rows, &deviations))
            }
            Geometry::Chain(joints) => {
                let mut column = 0;
                let mut out = Vec::with_capacity(joints.len());
                for (i, joint) in joints.iter().enumerate() {
                    let mut j = *joint;
                    j.offset += x[column];
                    column += 1;
                    if i > 0 {
                        let t = [x[column], x[column + 1], x[column + 2]];
                        let r = [x[column + 3], x[column + 4], x[column + 5]];
                        column += 6;
                        j.origin = joint.origin.compose(&origin_perturbation(t, r));
                    }
                    out.push(j);
                }
                Geometry::Chain(out)
            }
        };
        let c = self.tool_translation;
        let three = |start: usize| [x[start], x[start + 1], x[start + 2]];
        let tool = robot.tool();
        let t = tool.translation_mm;
        let tool = transform_from_parts(
            [0, 1, 2].map(|a| t[a] + x[c + a]),
            &(rotation_from_vector(three(c + 3)) * rotation_of(&tool)),
        );
        let base = robot.base();
        let b = base.translation_mm;
        let base = transform_from_parts(
            [0, 1, 2].map(|a| b[a] + x[c + 6 + a]),
            &(rotation_from_vector(three(c + 9)) * rotation_of(&base)),
        );
        let invalid = |e: adwi_robot::model::RobotError| CalibrateError::InvalidModel {
            robot: robot.name.clone(),
            reason: e.to_string(),
        };
        let mut calibrated = robot
            .with_geometry(format!("{} (calibrated)", robot.name), geometry, base, tool)
            .map_err(invalid)?;
        if !self.compliance_joints.is_empty() {
            // The file's compliances (zero where it gives none) plus the deviations.
            let mut compliances: Vec<Option<f64>> = robot
                .joints()
                .iter()
                .map(|j| j.compliance_urad_per_nm)
                .collect();
            for (k, &joint) in self.compliance_joints.iter().enumerate() {
                let nominal = compliances[joint].unwrap_or(0.0);
                compliances[joint] = Some(nominal + x[self.first_compliance() + k]);
            }
            calibrated = calibrated.with_compliances(&compliances).map_err(invalid)?;
        }
        let mut terms = JointTerms::NONE;
        for (k, &(joint, harmonic, cosine)) in self.term_columns.iter().enumerate() {
            let slot = 2 * (harmonic as usize - 1) + cosine as usize;
            terms.coefficients_rad[joint][slot] = x[self.first_term() + k];
        }
        let mdh_constants = match calibrated.geometry() {
            Geometry::Mdh(rows) => rows.iter().map(mdh_constant_part).collect(),
            Geometry::Chain(_) => Vec::new(),
        };
        Ok(State {
            robot: calibrated,
            terms,
            mdh_constants,
        })
    }

    /// The predicted pose error of a state at `q`: `[dp (mm); δ (rad)]`, base frame: the
    /// state's TCP, deflected by gravity ([`Chain::loaded_tcp_pose`](adwi_runtime::chain::Chain::loaded_tcp_pose)), against the nominal
    /// commanded one.
    #[cfg(test)]
    pub(super) fn error(&self, state: &State, q: &[f64]) -> nalgebra::Vector6<f64> {
        self.error_from(&self.robot.tcp_transform(q), state, q)
    }

    /// The predicted pose error of a state at `q` (`Model::error`, which the tests use),
    /// given the nominal TCP at `q` (`self.robot.tcp_transform(q)`), which no parameter
    /// moves: a fit computes it once per measurement, not at every step.
    pub(super) fn error_from(
        &self,
        nominal_tcp: &Transform,
        state: &State,
        q: &[f64],
    ) -> nalgebra::Vector6<f64> {
        transform_pose_error(
            nominal_tcp,
            &loaded_with_terms(&state.robot, &state.terms, q),
        )
    }

    /// The 6 × p Jacobian of the base-frame pose error with respect to the parameters at
    /// `state` (module docs), at the joint values the arm stands at under gravity, the
    /// torques taken as independent of the parameters.
    pub(super) fn jacobian(
        &self,
        x: &DVector<f64>,
        state: &State,
        commanded: &[f64],
    ) -> DMatrix<f64> {
        self.jacobian_of(x, state, commanded, &Walk::of(state, commanded))
    }

    /// [`Model::jacobian`] at the walk of `commanded` ([`Walk::of`]), which the error at the
    /// same joint values reads too.
    pub(super) fn jacobian_of(
        &self,
        x: &DVector<f64>,
        state: &State,
        commanded: &[f64],
        walk: &Walk,
    ) -> DMatrix<f64> {
        let mut j = DMatrix::zeros(6, self.len());
        let chain = state.robot.chain();
        let n = chain.joint_count();
        let terms_of = commanded;
        let commanded = &walk.moved[..n];
        let frames = &walk.frames;
        let tcp = Vector3::from(walk.tcp.translation_mm);
        let mut put = |column: usize, screw: &Screw| {
            j.column_mut(column)
                .copy_from(&screw.pose_error_column(&tcp));
        };
        // The frame the tool is given in.
        let flange = match state.robot.geometry() {
            Geometry::Mdh(rows) => {
                let screws = mdh_screws_from(frames, &state.mdh_constants);
                for (joint, joint_screws) in screws.iter().enumerate() {
                    for (parameter, screw) in MdhParameter::ALL.into_iter().zip(joint_screws) {
                        put(parameter.column(joint), screw);
                    }
                }
                let last = rows.len() - 1;
                frames[last].1.compose(&state.mdh_constants[last])
            }
            Geometry::Chain(joints) => {
                let Geometry::Chain(nominal) = self.robot.geometry() else {
                    unreachable!("a state has its robot's geometry")
                };
                let mut column = 0;
                for (i, joint) in joints.iter().enumerate() {
                    let (before, _) = &frames[i];
                    put(column, &Screw::of_joint(before, joint.axis, joint.kind));
                    column += 1;
                    if i > 0 {
                        // G: the unperturbed origin's frame; the translation slides along
                        // its axes, the rotation turns about R_G·J_l(r)·e_k through G·T(t).
                        let g = frames[i - 1].1.compose(&nominal[i].origin);
                        let r = [x[column + 3], x[column + 4], x[column + 5]];
                        let jl = left_jacobian(Vector3::from(r));
                        let rg = rotation_of(&g);
                        for axis in 0..3 {
                            let e = Vector3::ith(axis, 1.0);
                            put(column + axis, &Screw::Prismatic { direction: rg * e });
                            put(
                                column + 3 + axis,
                                &Screw::Revolute {
                                    axis: rg * (jl * e),
                                    point_mm: Vector3::from(before.translation_mm),
                                },
                            );
                        }
                        column += 6;
                    }
                }
                frames[joints.len() - 1].1.compose(&state.robot.flange())
            }
        };
        let c = self.tool_translation;
        let rf = rotation_of(&flange);
        let base_origin = Vector3::from(chain.base.translation_mm);
        for axis in 0..3 {
            let e = Vector3::ith(axis, 1.0);
            let flange_axis = rf * e;
            // A tool translation moves the TCP along a flange axis.
            put(
                c + axis,
                &Screw::Prismatic {
                    direction: flange_axis,
                },
            );
            // A tool rotation turns the TCP frame about a flange axis, in place.
            put(
                c + 3 + axis,
                &Screw::Revolute {
                    axis: flange_axis,
                    point_mm: tcp,
                },
            );
            put(c + 6 + axis, &Screw::Prismatic { direction: e });
            // A base rotation turns everything about the base's origin.
            put(
                c + 9 + axis,
                &Screw::Revolute {
                    axis: e,
                    point_mm: base_origin,
                },
            );
        }
        // A compliance turns its joint by the gravity torque per unit of compliance.
        if let Some(gravity) = &chain.compliance {
            let torques = chain
                .gravity_torques(commanded, gravity)
                .expect("one joint value per joint");
            for (k, &joint) in self.compliance_joints.iter().enumerate() {
                let column = self.first_compliance() + k;
                let screw = Screw::of_joint(
                    &frames[joint].0,
                    chain.joints()[joint].axis,
                    JointKind::Revolute,
                );
                j.column_mut(column)
                    .copy_from(&(screw.pose_error_column(&tcp) * (torques[joint] * URAD_PER_NM)));
            }
        }
        // A joint-space term turns its joint by its harmonic of the commanded angle.
        for (k, &(joint, harmonic, cosine)) in self.term_columns.iter().enumerate() {
            let angle = f64::from(harmonic) * terms_of[joint];
            let factor = if cosine { angle.cos() } else { angle.sin() };
            let screw = Screw::of_joint(
                &frames[joint].0,
                chain.joints()[joint].axis,
                JointKind::Revolute,
            );
            j.column_mut(self.first_term() + k)
                .copy_from(&(screw.pose_error_column(&tcp) * factor));
        }
        j
    }

    /// Applies a step `dx` to the state `x`: additive, except that tool and base rotations
    /// compose as `Exp(δ) · R`.
    pub(super) fn step(&self, x: &DVector<f64>, dx: &DVector<f64>) -> DVector<f64> {
        let mut next = x + dx;
        for start in self.multiplicative {
            let three = |v: &DVector<f64>| [v[start], v[start + 1], v[start + 2]];
            let composed = rotation_from_vector(three(dx)) * rotation_from_vector(three(x));
            let v = rotation_vector(&composed);
            next.rows_mut(start, 3).copy_from(&Vector3::from(v));
        }
        next
    }
}

/// A state's arm at commanded joint values: the joints the joint-space terms move them to,
/// each joint's frames at the values gravity then deflects them to ([`chain_frames`]) and
/// the TCP. Its TCP is [`loaded_with_terms`]'s to the bit (the same products, in the same
/// order), so that a linearisation computes the error and the Jacobian from one walk.
pub(super) struct Walk {
    moved: [f64; adwi_runtime::chain::MAX_JOINTS],
    frames: Vec<(Transform, Transform)>,
    pub(super) tcp: Transform,
}

impl Walk {
    pub(super) fn of(state: &State, commanded: &[f64]) -> Walk {
        let chain = state.robot.chain();
        let n = chain.joint_count();
        // The joint-space terms move the joints before gravity deflects them.
        let moved = state
            .terms
            .joints(commanded)
            .expect("one joint value per joint");
        let loaded = chain
            .loaded_joints(&moved[..n])
            .expect("one joint value per joint");
        let (frames, tcp) = chain_frames(chain, &loaded[..n]);
        Walk { moved, frames, tcp }
    }
}

/// The TCP pose of `robot` at commanded `q`, deflected by gravity when its chain models
/// compliance: exactly the runtime's [`Chain::loaded_tcp_pose`](adwi_runtime::chain::Chain::loaded_tcp_pose).
pub(super) fn loaded(robot: &Robot, q: &[f64]) -> Transform {
    robot.chain().loaded_tcp_pose(q).unwrap_or_else(|| {
        panic!(
            "{} joint values for a robot of {} joints",
            q.len(),
            robot.joint_count()
        )
    })
}

/// As [`loaded`], the joints first moved by the joint-space terms `terms`
/// ([`JointTerms::joints`]).
pub(super) fn loaded_with_terms(robot: &Robot, terms: &JointTerms, q: &[f64]) -> Transform {
    let moved = terms
        .joints(q)
        .unwrap_or_else(|| panic!("{} joint values for a robot", q.len()));
    loaded(robot, &moved[..q.len()])
}

/// `Trans(t) · Exp(r)`: a small perturbation of a joint origin (mm, rad).
pub(super) fn origin_perturbation(t: [f64; 3], r: [f64; 3]) -> Transform {
    transform_from_parts(t, &rotation_from_vector(r))
}

/// The left Jacobian of SO(3): `Exp(r + dr) = Exp(J_l(r)·dr) · Exp(r)` to first order.
pub(super) fn left_jacobian(r: Vector3<f64>) -> Matrix3<f64> {
    let theta2 = r.norm_squared();
    let k = r.cross_matrix();
    let (a, b) = if theta2 < 1e-8 {
        (0.5 - theta2 / 24.0, 1.0 / 6.0 - theta2 / 120.0)
    } else {
        let theta = theta2.sqrt();
        (
            (1.0 - theta.cos()) / theta2,
            (theta - theta.sin()) / (theta2 * theta),
        )
    };
    Matrix3::identity() + k * a + k * k * b
}
