//! Comparison baselines and residual statistics for evaluating the compensation method.
//!
//! The approximation-degree weighted interpolation is only worth its complexity if it beats
//! the simpler interpolators a reader would reach for first. This module holds those
//! competitors, each built from the same inputs and answering the same question:
//!
//! - [`idw`]: inverse distance weighting over the k nearest samples (Zhou, Liao, Tian 2013),
//!   the method the paper compares itself against;
//! - [`grid`]: trilinear interpolation inside the cubes of an axis-aligned sample lattice, the
//!   grid approach of patent CN201110113246.6, which needs samples on a lattice;
//! - [`kriging`]: ordinary kriging with a variogram fitted to the samples, the geostatistical
//!   best linear unbiased predictor;
//! - [`stats`]: residual statistics and deterministic k-fold splits for the evaluation.
//!
//! Every baseline is built from sample *nominal* positions (mm, base frame) and one value
//! 3-vector per sample. The values are usually position errors in mm, but nothing here
//! depends on their unit: the same code interpolates orientation errors held as rotation
//! vectors (rad, base frame), which are small enough that averaging them componentwise is
//! the usual first-order treatment.
//!
//! All baselines implement [`Baseline`], so an evaluation loop can treat them alike. They
//! are immutable after construction and `Sync`, so queries can run in parallel.

pub mod grid;
pub mod idw;
pub mod kriging;
mod neighbours;
pub mod stats;

pub use grid::{Grid, GridParams};
pub use idw::{Idw, IdwParams};
pub use kriging::{Kriging, KrigingParams, VariogramFit, VariogramModel};
pub use stats::{k_fold_splits, mean_and_standard_error, p_value_text, Fold, ResidualStats};

/// A baseline interpolator: predicts a value 3-vector at a query position.
///
/// The trait exists so that `tablec eval` can run every method through one loop; each
/// implementation documents when a query is not covered.
pub trait Baseline {
    /// A short, stable name for reports (`"idw"`, `"grid"`, `"kriging"`).
    fn name(&self) -> &'static str;

    /// The predicted value (same unit as the sample values) at `query_position_mm`
    /// (mm, base frame).
    ///
    /// # Errors
    ///
    /// [`PredictError::NonFiniteQuery`] for a query with a NaN or infinite coordinate, and
    /// the method-specific errors documented on each implementation.
    fn predict(&self, query_position_mm: [f64; 3]) -> Result<[f64; 3], PredictError>;
}

/// Why a baseline could not be built from the given samples.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BaselineError {
    /// There were no samples; no interpolator can answer anything from nothing.
    #[error("no samples given: a baseline needs at least one sample")]
    NoSamples,
    /// The position and value slices disagree in length, so samples cannot be paired.
    #[error(
        "{positions} sample positions but {values} sample values: they must pair up one to one"
    )]
    MismatchedLengths {
        /// Number of positions given.
        positions: usize,
        /// Number of values given.
        values: usize,
    },
    /// A sample position or value holds a NaN or an infinity, which would poison every
    /// prediction that uses it.
    #[error("sample {index} has a non-finite position or value; remove or repair it")]
    NonFiniteSample {
        /// Index of the offending sample in the input slices.
        index: usize,
    },
    /// A construction parameter is out of its valid range.
    #[error("invalid parameter `{name}`: {reason}")]
    InvalidParameter {
        /// The parameter's field name.
        name: &'static str,
        /// What the valid range is.
        reason: String,
    },
    /// The method cannot work on these samples at all (for example, trilinear interpolation
    /// on samples that do not form a lattice).
    #[error("method not applicable to these samples: {reason}")]
    Unsupported {
        /// Why the samples do not suit the method, in words a user can act on.
        reason: String,
    },
}

/// Why a baseline could not predict at one query position.
///
/// These are per-query outcomes, not failures of the baseline: an evaluation counts them
/// (for example, the share of test points a grid method cannot cover) rather than aborting.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PredictError {
    /// The query has a NaN or infinite coordinate.
    #[error("query position is not finite")]
    NonFiniteQuery,
    /// No samples support a prediction at this query; the method refuses to extrapolate.
    #[error("query not covered: {0}")]
    NotCovered(NotCovered),
    /// The kriging system for this query's neighbourhood is numerically singular, typically
    /// because neighbours are collinear or nearly coincident with a degenerate variogram.
    #[error("the kriging system over {neighbours} neighbours is singular; try a larger neighbourhood or a nonzero nugget floor")]
    SingularSystem {
        /// How many neighbours the system had.
        neighbours: usize,
    },
}

/// The reason a query is not covered by a baseline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NotCovered {
    /// No sample lies within the search radius.
    NoSampleWithinRadius {
        /// The search radius that was used, mm.
        radius_mm: f64,
    },
    /// The query lies outside the bounding box of the sample lattice.
    OutsideLattice,
    /// The lattice cube enclosing the query lacks a sampled corner.
    MissingCorner {
        /// Lattice indices (along x, y, z) of the missing corner.
        corner_index: [i64; 3],
    },
}

impl NotCovered {
    /// The kind of reason, without the particulars of one query: what an evaluation
    /// counts points by.
    pub fn kind(&self) -> &'static str {
        match self {
            Self::NoSampleWithinRadius { .. } => "no sample within the search radius",
            Self::OutsideLattice => "outside the sample lattice",
            Self::MissingCorner { .. } => "a corner of the enclosing lattice cube has no sample",
        }
    }
}

impl PredictError {
    /// The kind of reason, without the particulars of one query (see [`NotCovered::kind`]).
    pub fn kind(&self) -> &'static str {
        match self {
            Self::NonFiniteQuery => "query position is not finite",
            Self::NotCovered(n) => n.kind(),
            Self::SingularSystem { .. } => "singular kriging system",
        }
    }
}

impl std::fmt::Display for NotCovered {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NoSampleWithinRadius { radius_mm } => {
                write!(f, "no sample within {radius_mm} mm")
            }
            Self::OutsideLattice => write!(f, "outside the sample lattice"),
            Self::MissingCorner { corner_index } => write!(
                f,
                "lattice corner ({}, {}, {}) of the enclosing cube has no sample",
                corner_index[0], corner_index[1], corner_index[2]
            ),
        }
    }
}

// An evaluation runs queries in parallel: every baseline must stay shareable across threads.
const _: fn() = || {
    fn shareable<T: Send + Sync>() {}
    shareable::<Idw>();
    shareable::<Grid>();
    shareable::<Kriging>();
};

/// Checks the inputs every baseline shares: non-empty, paired, finite.
fn validate_samples(positions_mm: &[[f64; 3]], values: &[[f64; 3]]) -> Result<(), BaselineError> {
    if positions_mm.len() != values.len() {
        return Err(BaselineError::MismatchedLengths {
            positions: positions_mm.len(),
            values: values.len(),
        });
    }
    if positions_mm.is_empty() {
        return Err(BaselineError::NoSamples);
    }
    let finite = |v: &[f64; 3]| v.iter().all(|c| c.is_finite());
    match positions_mm
        .iter()
        .zip(values)
        .position(|(p, v)| !finite(p) || !finite(v))
    {
        Some(index) => Err(BaselineError::NonFiniteSample { index }),
        None => Ok(()),
    }
}

/// Checks a query position, shared by every baseline's `predict`.
fn validate_query(query_position_mm: [f64; 3]) -> Result<(), PredictError> {
    if query_position_mm.iter().all(|c| c.is_finite()) {
        Ok(())
    } else {
        Err(PredictError::NonFiniteQuery)
    }
}

/// Squared Euclidean distance between two points, mm².
fn distance_squared(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_reports_each_input_problem() {
        assert_eq!(validate_samples(&[], &[]), Err(BaselineError::NoSamples));
        assert_eq!(
            validate_samples(&[[0.0; 3]], &[]),
            Err(BaselineError::MismatchedLengths {
                positions: 1,
                values: 0
            })
        );
        assert_eq!(
            validate_samples(&[[0.0; 3], [1.0, f64::NAN, 0.0]], &[[0.0; 3]; 2]),
            Err(BaselineError::NonFiniteSample { index: 1 })
        );
        assert_eq!(
            validate_samples(&[[0.0; 3]], &[[f64::INFINITY, 0.0, 0.0]]),
            Err(BaselineError::NonFiniteSample { index: 0 })
        );
        assert_eq!(validate_samples(&[[0.0; 3]], &[[1.0; 3]]), Ok(()));
        assert_eq!(
            validate_query([0.0, f64::NAN, 0.0]),
            Err(PredictError::NonFiniteQuery)
        );
    }
}
