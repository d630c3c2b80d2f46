//! The robot side of adwi: robot descriptions as data ([`model`]: TOML robot files,
//! [`urdf`] files), inverse kinematics ([`ik`]), the first-order pose error model
//! ([`error_model`]), kinematic identification from measured samples ([`calibrate`]), the
//! registration of laser-tracker measurements to the robot ([`register`]; [`measured`] reads
//! tracker-frame sample files through it), for any serial robot of 1 to
//! [`adwi_runtime::chain::MAX_JOINTS`] revolute or prismatic joints. The simulation of
//! sample databases is `adwi-simulate`'s.
//!
//! Forward kinematics is not here: every robot is a runtime [`adwi_runtime::chain::Chain`],
//! so that one implementation serves simulation, identification and queries.

pub mod agreement;
pub mod calibrate;
pub mod error;
pub mod error_model;
pub mod file;
pub mod ik;
pub mod measured;
pub mod model;
pub mod plausible;
pub mod register;
pub mod testing;
pub mod toml_error;
pub mod urdf;

pub use ik::{Configuration, IkError, IkSolution, InverseKinematics};
pub use model::{Geometry, Joint, LinkInertial, Robot, RobotError};
pub use urdf::LinkNames;
