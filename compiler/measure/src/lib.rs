//! Measurement planning and ISO 9283 pose characteristics.
//!
//! - [`iso9283`]: the pose accuracy and repeatability, and the distance accuracy and
//!   repeatability, of ISO 9283:1998 from measured cycles, and the standard's five test
//!   positions in a cube;
//! - [`path`]: the path characteristics of ISO 9283:1998 (accuracy, repeatability,
//!   cornering, velocity) from a tracker stream, and the standard's test paths in a cube;
//! - [`plan`]: which poses to measure so that an identification of the robot's kinematic
//!   parameters is well determined and the workspace is covered (D-optimal and space-filling
//!   selection from a reachable candidate pool, ordered as a short joint-space path);
//! - [`observability`]: the classical observability indices O1-O5 of a set of poses;
//! - [`field`]: a table's residual field's kriging variance, for planning where to measure
//!   next;
//! - [`truth`]: how close an identification is to a simulated robot's true parameters and
//!   positions.

pub mod field;
pub mod iso9283;
pub mod observability;
pub mod path;
pub mod plan;
pub mod truth;

/// The largest angle a planned or commanded orientation takes, degrees: three turns each
/// way. A wrist turns a few times at most; 1e308° is a typing error, whose sine and
/// cosine mean nothing.
pub const MAX_ANGLE_DEG: f64 = 1080.0;
