//! The robot side: robot descriptions as data, inverse kinematics, and the first-order
//! pose error model.
//!
//! Forward kinematics is not here: it is [`adwi_runtime::kinematics`], shared with the
//! runtime so that one implementation serves simulation, identification and queries.

pub mod error_model;
pub mod ik;
pub mod model;

pub use ik::{Configuration, IkError, IkSolution, InverseKinematics};
pub use model::{Joint, Robot, RobotError, JOINT_COUNT};
