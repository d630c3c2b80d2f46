//! Reading sample databases and compiling them into correction tables.
//!
//! - [`samples`]: the CSV reader (separators and decimal marks, column mapping, units,
//!   orientation conventions, every error located by file, line and column),
//!   [`samples::SampleSet`], the samples in memory, and [`samples::Measurements`], raw
//!   measurements in an instrument's frame;
//! - [`build`]: the table compiler — options resolved into a plan, candidate lists per
//!   cell, the encoded table;
//! - [`hybrid`]: a hybrid table from samples and a given kinematic model (its residuals);
//! - [`reference`]: the brute-force reference every compiled table is tested against;
//! - [`write`]: writing the file without ever losing data;
//! - [`inspect`]: what a table holds, in figures;
//! - [`pose`]: orientation conventions of sample files.
//!
//! The method itself lives in [`adwi_runtime::method`]; this crate calls it, never
//! re-implements it. Kinematic identification, which finds the model of a hybrid table, is
//! `adwi-robot`'s.

pub mod build;
pub mod hybrid;
pub mod inspect;
pub mod nugget_kriging;
pub mod pose;
pub mod reference;
pub mod samples;
pub mod write;
