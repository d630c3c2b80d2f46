//! The robot side of adwi: robot descriptions as data ([`model`]), inverse kinematics
//! ([`ik`]), the first-order pose error model ([`error_model`]), kinematic identification
//! from measured samples ([`calibrate`]) and the simulation of sample databases
//! ([`simulate`]).
//!
//! Forward kinematics is not here: it is [`adwi_runtime::kinematics`], shared with the
//! runtime so that one implementation serves simulation, identification and queries.

pub mod calibrate;
pub mod error_model;
pub mod ik;
pub mod model;
pub mod simulate;

pub use ik::{Configuration, IkError, IkSolution, InverseKinematics};
pub use model::{Joint, Robot, RobotError, JOINT_COUNT};
