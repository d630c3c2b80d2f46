//! The offline side of approximation-degree weighted interpolation: reading sample
//! databases, the brute-force reference, and compiling cell tables for the runtime.
//!
//! The method itself lives in [`adwi_runtime::method`]; this crate calls it, never
//! re-implements it.

pub mod baselines;
pub mod build;
pub mod calibrate;
pub mod eval;
pub mod hybrid;
pub mod latency;
pub mod pose;
pub mod reference;
pub mod robot;
pub mod samples;
pub mod simulate;
