//! The runtime side of approximation-degree weighted interpolation of robot positioning
//! errors: open a compiled correction table (memory-mapped, validated once) and ask it for
//! the predicted error at any target, in well under a microsecond, without allocating,
//! locking or panicking.
//!
//! Tables are written by the `tablec` compiler (crate `tablec`, over `adwi-compile`); their byte layout
//! is documented in [`format`](mod@format). The method itself — approximation degree, admissibility,
//! weights — is in [`method`], the single implementation that the compiler's reference,
//! its table builder and this runtime's queries all call.
//!
//! A *hybrid* table (`tablec build --robot ROBOT.toml --hybrid`) also carries a calibrated
//! kinematic model; it answers [`Table::query_with_joints`], which adds the model's
//! predicted error at the controller's joint angles to the interpolated residuals
//! ([`model`]). The same query applies a table's joint-space admissibility screen.
//!
//! # Example
//!
//! ```no_run
//! use adwi_runtime::{Status, Table, Target};
//!
//! // SAFETY: the table file is not modified while mapped (tablec writes by rename).
//! let table = unsafe { Table::open("tables/kr150-2/kr150.tbl") }?;
//! let target = [2000.0, 700.0, 1000.0]; // mm, robot base frame
//! let c = table.query(target);
//! if c.status == Status::Ok {
//!     let command = [
//!         target[0] - c.position_error_mm[0],
//!         target[1] - c.position_error_mm[1],
//!         target[2] - c.position_error_mm[2],
//!     ];
//!     println!("command {command:?}");
//! }
//! // Or solve command + error(command) = target exactly:
//! let exact = table.compensate(&Target::at(target), 1e-6, 20);
//! assert!(exact.converged);
//! # Ok::<(), adwi_runtime::OpenError>(())
//! ```

#![deny(missing_docs)]

pub mod capi;
pub mod chain;
mod correction;
mod error;
mod exact;
mod fade;
pub mod format;
pub mod input;
pub mod joint_terms;
pub mod kinematics;
mod lanes;
pub mod method;
pub mod model;
pub mod posture;
pub mod residency;
pub mod served;
mod swap;
mod table;
#[doc(hidden)]
pub mod testing;
pub mod trig;
mod validate;

pub use correction::{
    Compensation, Correction, Evidence, Residual, Status, Target, COMPENSATE_ITERATIONS,
    COMPENSATE_TOLERANCE_MM,
};
pub use error::OpenError;
pub use residency::{Lock, OpenOptions, Residency};
pub use swap::{Current, Retired, TableSwap};
pub use table::{AlignedBytes, Exact, Payload, Table, Tier};

/// The README's Rust example, compiled as a doctest so that it cannot rot.
#[cfg(doctest)]
#[doc = include_str!("../../README.md")]
struct ReadmeExample;
