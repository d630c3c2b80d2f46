//! The robot of adwi: robot descriptions as data ([`model`]: TOML robot files, [`urdf`]
//! files, each number in its [`plausible`] range), inverse kinematics ([`ik`]) and the
//! first-order pose error model ([`error_model`]), for any serial robot of 1 to
//! [`adwi_runtime::chain::MAX_JOINTS`] revolute or prismatic joints. What is done with a
//! robot stands above it: identification from measured samples and tracker registration in
//! `adwi-identify`, the simulation of sample databases in `adwi-simulate`.
//!
//! Forward kinematics is not here: every robot is a runtime [`adwi_runtime::chain::Chain`],
//! so that one implementation serves simulation, identification and queries.

pub mod error;
pub mod error_model;
pub mod file;
pub mod ik;
pub mod mdh_form;
pub mod model;
pub mod plausible;
pub mod testing;
pub mod toml_error;
pub mod urdf;

pub use ik::{Configuration, IkError, IkSolution, InverseKinematics};
pub use model::{Geometry, Joint, LinkInertial, Robot, RobotError};
pub use urdf::LinkNames;
