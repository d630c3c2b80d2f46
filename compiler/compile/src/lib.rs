//! Compiling sample databases ([`adwi_samples::SampleSet`]) into correction tables.
//!
//! - [`build`]: the table compiler — options resolved into a plan, candidate lists per
//!   cell, the encoded table;
//! - [`hybrid`]: a hybrid table from samples and a given kinematic model (its residuals);
//! - [`reference`](mod@reference): the brute-force reference every compiled table is tested against;
//! - [`inspect`]: what a table holds, in figures;
//! - [`nugget_kriging`]: kriging with a nugget, what a kriging served field holds;
//! - [`local_kriging`]: the same at any number of samples, from neighbours.
//!
//! The method itself lives in [`adwi_runtime::method`]; this crate calls it, never
//! re-implements it. Kinematic identification, which finds the model of a hybrid table, is
//! `adwi-robot`'s; writing the file without ever losing data is `adwi-output`'s.

pub mod build;
mod cholesky;
mod householder;
pub mod hybrid;
pub mod inspect;
pub mod local_kriging;
mod matern;
pub mod nugget_kriging;
pub mod posture;
pub mod reference;
