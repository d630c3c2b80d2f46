//! Identification of a robot from measured samples: kinematic identification with joint
//! compliance and joint-space terms ([`calibrate`]), the registration of laser-tracker
//! measurements to the robot ([`register`]; [`measured`] reads tracker-frame sample files
//! through it), and the check that samples agree with the robot file before any of it
//! ([`agreement`]).
//!
//! The robot itself (its files, forward and inverse kinematics, the first-order error model
//! the identification linearises) is `adwi-robot`'s: this crate only estimates deviations of
//! it, so that identification, simulation and queries evaluate one and the same model.

pub mod agreement;
pub mod calibrate;
pub mod measured;
pub mod register;
