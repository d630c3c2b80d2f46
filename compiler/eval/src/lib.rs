//! Held-out evaluation: every compensation method predicts the error at points it was not
//! built from, and the residuals say which method compensates best.
//!
//! A point's *residual* after compensation by a method is `measured error − predicted
//! error`: what would remain if the controller commanded `target − predicted error`, to
//! first order. Before compensation the residual is the measured error itself. Statistics
//! are over residual norms: position in mm, orientation in mrad (when the samples carry
//! orientation errors), both in the base frame.
//!
//! Two protocols ([`Protocol`]): a separate validation set, or k-fold cross-validation of
//! the samples alone (each sample predicted once, by methods built from the other folds).
//!
//! The methods ([`Method`]) compared:
//!
//! - `paper`: the approximation-degree method through the real pipeline: the training
//!   samples are compiled by [`adwi_compile::build::compile`] into table bytes, opened by
//!   [`adwi_runtime::Table::from_vec`] and queried with
//!   [`adwi_runtime::Table::query_target`], exactly as `tablec build` and `tablec query`
//!   would;
//! - `paper-joint`: the same weights ([`adwi_runtime::method`]), but the `k` neighbours are
//!   the admissible samples nearest in *joint space* (Euclidean distance of the six joint
//!   angles, degrees), by brute force; the paper's remark that "close" really means close
//!   joint angles, taken literally;
//! - `idw`, `grid`, `kriging`: the [`crate::baselines`];
//! - `kinematic`: model-based calibration ([`adwi_identify::calibrate`]) predicting the error at the
//!   point's joint angles;
//! - `hybrid`: the real hybrid table ([`adwi_compile::hybrid::compile`]): kinematic calibration,
//!   then the `paper` table built from what the calibrated model leaves unexplained, both
//!   in one file, opened with [`adwi_runtime::Table::from_vec`] and queried with
//!   [`adwi_runtime::Table::query_with_joints`] at the point's joint angles, exactly as
//!   `tablec build --hybrid` and a controller would; prediction = model + interpolated
//!   remainder.
//!
//! With a joint-space screen in the table options (`joint_radius_deg`), `paper` and
//! `hybrid` are queried with the point's joint angles, so the screen applies.
//!
//! A point a method cannot predict (outside the table's grid, no admissible neighbour,
//! outside the lattice) is counted per method with its reason, never dropped silently; the
//! method's statistics are over the points it predicted.

pub mod baselines;
mod calibration;
pub mod choice;
pub mod comparison;
pub mod continuity;
pub mod folds;
pub mod latency;
pub mod noise_floor;
mod options;
pub mod output;
pub mod report;

pub use calibration::{CalibrationSummary, ParameterRow};
pub use options::{EvalOptions, PostureDecision, SplitChoice, SplitChoiceRecord, SplitRule};

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use adwi_runtime::{Evidence, Residual, Status, Table, Target, Tier};

use crate::baselines::{BaselineError, Grid, Idw, Kriging, PredictError, ResidualStats};
use adwi_compile::build::{self, BuildError, BuildOptions, Queried};
use adwi_identify::calibrate::{self, CalibrateError, Calibration};
use adwi_samples::SampleSet;
use rayon::prelude::*;

/// A compensation method under evaluation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Method {
    /// Approximation-degree weighted interpolation through a compiled table: its exact
    /// tier, the paper's method to the digit.
    Paper,
    /// The same table's served tier: the method at the grid's nodes, blended trilinearly
    /// (the continuous field `tablec query` serves).
    PaperTrilinear,
    /// Inverse distance weighting.
    Idw,
    /// Trilinear interpolation on a sample lattice.
    Grid,
    /// Ordinary kriging.
    Kriging,
    /// Identified kinematic model.
    Kinematic,
    /// Identified kinematic model plus the table on its remainder, exact tier.
    Hybrid,
    /// The hybrid table's served tier: the model plus the continuous residual field (what
    /// the build's served field holds: the method's answer or a kriging of the residuals).
    HybridTrilinear,
    /// A table built before, scored as it is: its served field, queried with the points'
    /// joint angles when it is hybrid ([`evaluate_table`]).
    Table,
}

impl Method {
    /// Every method that is built from samples, in report order.
    pub const ALL: [Method; 8] = [
        Method::Paper,
        Method::PaperTrilinear,
        Method::Idw,
        Method::Grid,
        Method::Kriging,
        Method::Kinematic,
        Method::Hybrid,
        Method::HybridTrilinear,
    ];

    /// What an evaluation compares when not told: what a table serves (both tiers, with
    /// and without a kinematic model) and the cheap baselines, inverse distance weighting
    /// and the kinematic model alone. `grid` and `kriging` are asked for by name: the
    /// lattice answers nothing on scattered real data, and ordinary kriging interpolates
    /// the noise a kriging served field smooths.
    pub const DEFAULT: [Method; 6] = [
        Method::Paper,
        Method::PaperTrilinear,
        Method::Idw,
        Method::Kinematic,
        Method::Hybrid,
        Method::HybridTrilinear,
    ];

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Method::Paper => "paper",
            Method::PaperTrilinear => "paper-trilinear",
            Method::Idw => "idw",
            Method::Grid => "grid",
            Method::Kriging => "kriging",
            Method::Kinematic => "kinematic",
            Method::Hybrid => "hybrid",
            Method::HybridTrilinear => "hybrid-trilinear",
            Method::Table => "table",
        }
    }

    /// One line on what the method is, for reports.
    pub fn description(self) -> &'static str {
        match self {
            Method::Paper => {
                "approximation-degree weights, compiled table, exact tier (tablec query --exact)"
            }
            Method::PaperTrilinear => {
                "the same table's served field: the method at the nodes, trilinear (tablec query)"
            }
            Method::Idw => "inverse distance weighting, k nearest nominal positions",
            Method::Grid => "trilinear interpolation in the sample lattice",
            Method::Kriging => "ordinary kriging, fitted variogram",
            Method::Kinematic => "identified MD-H deviations, tool offset and base registration",
            Method::Hybrid => {
                "hybrid table: kinematic model + compiled table on the remaining errors, exact tier"
            }
            Method::HybridTrilinear => {
                "hybrid table's served field: kinematic model + continuous residual field"
            }
            Method::Table => "the table given, its served field (tablec query)",
        }
    }

    /// Whether the method needs joint angles in samples and validation points.
    pub fn needs_joints(self) -> bool {
        matches!(
            self,
            Method::Kinematic | Method::Hybrid | Method::HybridTrilinear
        )
    }

    /// Whether the method needs a robot model.
    pub fn needs_robot(self) -> bool {
        self.needs_joints()
    }

    /// Whether a table serves the method's answer to a controller (`tablec query`), as
    /// opposed to a baseline it is compared with.
    pub fn is_served(self) -> bool {
        matches!(
            self,
            Method::Paper
                | Method::PaperTrilinear
                | Method::Hybrid
                | Method::HybridTrilinear
                | Method::Table
        )
    }
}

/// Methods earlier versions evaluated that no table serves, and what measures their
/// question through a real table now.
const RETIRED: [(&str, &str); 5] = [
    ("paper-joint", "the joint-space screen (--joint-radius) is what a table serves"),
    (
        "kinematic-kriging",
        "hybrid-trilinear with a kriging served field (--served-field kriging) measures it through the table",
    ),
    (
        "kinematic-kriging-tool-axis",
        "hybrid-trilinear with a kriging served field measures it through the table",
    ),
    (
        "kinematic-kriging-joint",
        "hybrid-trilinear measures what a table serves",
    ),
    (
        "kinematic-kriging-pose",
        "hybrid-trilinear measures what a table serves",
    ),
];

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let name = s.trim();
        if let Some(m) = Method::ALL.into_iter().find(|m| m.name() == name) {
            return Ok(m);
        }
        let names: Vec<_> = Method::ALL.iter().map(|m| m.name()).collect();
        let retired = RETIRED.iter().find(|(old, _)| *old == name);
        Err(match retired {
            Some((_, instead)) => format!(
                "method '{name}' was retired: no table can serve it; {instead} (choose from {})",
                names.join(", ")
            ),
            None => format!("unknown method '{name}': choose from {}", names.join(", ")),
        })
    }
}

impl serde::Serialize for Method {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

/// How points are held out.
#[derive(Debug, Clone)]
// One per evaluation: the validation set held inline costs nothing.
#[allow(clippy::large_enum_variant)]
pub enum Protocol {
    /// Build from all samples, predict at every point of a separate validation set.
    Validation(SampleSet),
    /// k-fold cross-validation of the samples ([`baselines::k_fold_splits`]).
    KFold {
        /// k, at least 2.
        folds: usize,
        /// Seed of the split.
        seed: u64,
    },
    /// Cross-validation by region: `folds` spatial blocks of the samples' nominal
    /// positions, each one fold ([`folds::block_splits`]).
    Blocks {
        /// The blocks, at least 2.
        folds: usize,
        /// Seed of the blocks' k-means.
        seed: u64,
    },
    /// Leave one series out: sample `i` belongs to series `series[i]`, and each series is
    /// predicted from the others ([`folds::group_splits`]).
    Series(Vec<usize>),
}

impl Protocol {
    /// The training and held-out indices of each split of `samples`, and the protocol in
    /// words; `None` for a validation set (its only split is every sample).
    fn splits(
        &self,
        samples: &SampleSet,
    ) -> Option<Result<(Vec<baselines::Fold>, String), EvalError>> {
        let n = samples.len();
        let invalid = |folds| baselines::stats::StatsError::InvalidFolds {
            sample_count: n,
            folds,
        };
        Some(match self {
            Protocol::Validation(_) => return None,
            Protocol::KFold { folds, seed } => baselines::k_fold_splits(n, *folds, *seed)
                .map(|s| {
                    let text =
                        format!("{folds}-fold cross-validation of {n} samples (seed {seed})");
                    (s, text)
                })
                .map_err(EvalError::from),
            Protocol::Blocks { folds, seed } => folds::block_splits(&samples.nominal_mm, *folds, *seed)
                .map(|s| {
                    let text = format!(
                        "{folds}-fold cross-validation by region of {n} samples (spatial blocks, seed {seed})"
                    );
                    (s, text)
                })
                .map_err(EvalError::from),
            Protocol::Series(series) if series.len() == n => match folds::group_splits(series) {
                Some(s) => {
                    let text = format!(
                        "leave-one-series-out validation of {n} samples in {} series",
                        s.len()
                    );
                    Ok((s, text))
                }
                None => Err(EvalError::from(invalid(1))),
            },
            Protocol::Series(series) => Err(EvalError::from(invalid(series.len()))),
        })
    }
}

/// Why an evaluation could not run at all (a method that cannot handle the data is not an
/// error: it is reported as unsupported).
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A method was asked for that the inputs cannot serve.
    #[error("method {method} cannot run: {reason}")]
    MethodUnavailable {
        /// The method.
        method: Method,
        /// Why.
        reason: String,
    },
    /// The fold count does not suit the samples.
    #[error(transparent)]
    Folds(#[from] baselines::stats::StatsError),
    /// The table could not be built.
    #[error("cannot build the table for {method}")]
    Build {
        /// The method.
        method: Method,
        /// Why.
        #[source]
        source: BuildError,
    },
    /// The table built could not be opened (a bug: compile and open disagree).
    #[error("the table built for {method} does not open: {message}")]
    Open {
        /// The method.
        method: Method,
        /// The runtime's message.
        message: String,
    },
    /// A baseline rejected its inputs for a reason other than unsuitability.
    #[error("cannot build {method}")]
    Baseline {
        /// The method.
        method: Method,
        /// Why.
        #[source]
        source: BaselineError,
    },
    /// Kriging of the kinematic residuals could not be fitted.
    #[error("cannot fit kriging for {method}")]
    Kriging {
        /// The method.
        method: Method,
        /// Why.
        #[source]
        source: adwi_compile::nugget_kriging::GpError,
    },
    /// The method predicted none of the points.
    #[error("{method} predicted none of the {points} points: {reasons}")]
    NothingPredicted {
        /// The method.
        method: Method,
        /// The points asked.
        points: usize,
        /// How many were not predicted, by reason.
        reasons: String,
    },
    /// Identification failed.
    #[error("cannot identify the kinematic model for {method}")]
    Calibrate {
        /// The method.
        method: Method,
        /// Why.
        #[source]
        source: CalibrateError,
    },
}

/// One method's predicted error at one point: position (mm) and, when predicted,
/// orientation (rad), base frame.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PointPrediction {
    /// Predicted position error, mm.
    pub position_error_mm: [f64; 3],
    /// Predicted orientation error (rotation vector), rad.
    pub orientation_error_rad: Option<[f64; 3]>,
    /// How much of a hybrid table's residual field the prediction holds; `None` for every
    /// other method (counted in [`MethodResult::residual`]).
    #[serde(skip)]
    pub residual: Option<Residual>,
    /// Where a table's answer lies beyond its samples' evidence, when the table records
    /// it (format version 4); `None` for every other method.
    #[serde(skip)]
    pub evidence: Option<Evidence>,
}

/// A hybrid table's answered points by residual flag ([`Residual`]): where the residual
/// field answered in full, faded, or left the calibrated model alone.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct ResidualCounts {
    /// Points answered with the whole residual.
    pub residual_full: usize,
    /// Points answered with a faded residual.
    pub residual_faded: usize,
    /// Points answered by the calibrated model alone.
    pub residual_model_only: usize,
}

impl ResidualCounts {
    /// The counts of `predictions`; `None` when none carries a flag (not a hybrid table).
    fn of(predictions: &[Option<PointPrediction>]) -> Option<ResidualCounts> {
        let mut counts = ResidualCounts::default();
        let mut any = false;
        for residual in predictions.iter().flatten().filter_map(|p| p.residual) {
            any = true;
            *match residual {
                Residual::Full => &mut counts.residual_full,
                Residual::Faded => &mut counts.residual_faded,
                Residual::ModelOnly => &mut counts.residual_model_only,
            } += 1;
        }
        any.then_some(counts)
    }
}

/// The outcome of one method over all points.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MethodResult {
    /// The method.
    pub method: Method,
    /// Why the method could not run on these samples at all, when it could not.
    pub unsupported: Option<String>,
    /// The prediction at each point, in point order; `None` where not predicted.
    pub predictions: Vec<Option<PointPrediction>>,
    /// Points not predicted, by kind of reason.
    pub not_predicted: BTreeMap<String, usize>,
    /// For each kind of reason, the particulars of the first few points it applied to
    /// (at most [`MISS_EXAMPLES`], in the order met), where they say more than the kind.
    pub not_predicted_examples: BTreeMap<String, Vec<String>>,
    /// Residual statistics after compensation over the predicted points, position, mm.
    pub position_mm: Option<ResidualStats>,
    /// Residual statistics after compensation over the predicted points, orientation,
    /// mrad, when both the samples and the method give orientation.
    pub orientation_mrad: Option<ResidualStats>,
    /// The raw errors' statistics over the same predicted points, position, mm: the fair
    /// "before" for a method that skipped points.
    pub before_position_mm: Option<ResidualStats>,
    /// A hybrid table's answered points by residual flag; `None` for other methods.
    #[serde(flatten)]
    pub residual: Option<ResidualCounts>,
    /// Points a table answered beyond its samples' evidence (an orientation they never
    /// had, a TCP it cannot place), when the table records its evidence; `None` otherwise.
    pub beyond_evidence: Option<usize>,
}

impl MethodResult {
    /// Its position residuals (measured − predicted error, mm, base frame) at the points it
    /// predicted, with each point's index; `measured_error_mm` holds the points' measured
    /// errors ([`Evaluation::measured_error_mm`]).
    pub fn position_residuals(&self, measured_error_mm: &[[f64; 3]]) -> Vec<(usize, [f64; 3])> {
        self.predictions
            .iter()
            .zip(measured_error_mm)
            .enumerate()
            .filter_map(|(i, (p, measured))| {
                let p = p.as_ref()?;
                Some((i, [0, 1, 2].map(|a| measured[a] - p.position_error_mm[a])))
            })
            .collect()
    }

    /// How many points the method predicted.
    pub fn predicted(&self) -> usize {
        self.predictions.iter().flatten().count()
    }

    /// How many points it did not predict.
    pub fn not_predicted_count(&self) -> usize {
        self.not_predicted.values().sum()
    }

    /// What the figures leave out or hide, in words: why points are missing, and a hybrid
    /// table's answered points by residual flag (the `note` column of every output).
    pub fn note(&self) -> String {
        if let Some(reason) = &self.unsupported {
            return format!("unsupported: {reason}");
        }
        let mut lines = self.not_predicted_summary();
        lines.extend(self.residual_summary());
        lines.extend(self.evidence_summary());
        lines.join("; ")
    }

    /// A hybrid table's answered points by residual flag, in words (`None` for other
    /// methods).
    pub fn residual_summary(&self) -> Option<String> {
        self.residual.map(|c| {
            format!(
                "residual: {} {}, {} {}, {} {}",
                c.residual_full,
                Residual::Full.as_str(),
                c.residual_faded,
                Residual::Faded.as_str(),
                c.residual_model_only,
                Residual::ModelOnly.as_str()
            )
        })
    }

    /// The points a table answered beyond its samples' evidence, in words, when any was.
    pub fn evidence_summary(&self) -> Option<String> {
        self.beyond_evidence.filter(|&n| n > 0).map(|n| {
            format!(
                "{n} of {} answered beyond the samples' evidence (an orientation they never had, a TCP the table cannot place, or a joint beyond its model's terms)",
                self.predicted()
            )
        })
    }

    /// The points not predicted, in words: a count per kind of reason with a few
    /// examples, so that thousands of misses read as a line per kind.
    pub fn not_predicted_summary(&self) -> Vec<String> {
        self.not_predicted
            .iter()
            .map(|(reason, n)| {
                let examples = self.not_predicted_examples.get(reason);
                match examples.filter(|e| !e.is_empty()) {
                    Some(e) => {
                        let more = if *n > e.len() { "; …" } else { "" };
                        format!("{n} not predicted: {reason} (e.g. {}{more})", e.join("; "))
                    }
                    None => format!("{n} not predicted: {reason}"),
                }
            })
            .collect()
    }
}

/// How many of `predictions` lie beyond their table's evidence; `None` when none carries
/// the flag (not a table that records its evidence).
fn beyond_evidence(predictions: &[Option<PointPrediction>]) -> Option<usize> {
    let flags: Vec<Evidence> = predictions
        .iter()
        .flatten()
        .filter_map(|p| p.evidence)
        .collect();
    (!flags.is_empty()).then(|| flags.iter().filter(|e| !e.is_within()).count())
}

/// How many examples of each kind of miss an evaluation keeps.
pub const MISS_EXAMPLES: usize = 3;

/// Why a method did not predict one point: the kind of reason, which points are counted
/// by, and the particulars, when they add to it.
#[derive(Debug, Clone, PartialEq)]
struct Miss {
    reason: String,
    detail: Option<String>,
}

impl Miss {
    fn status(status: Status) -> Miss {
        Miss {
            reason: status.as_str().to_string(),
            detail: None,
        }
    }

    fn baseline(e: PredictError) -> Miss {
        let detail = match &e {
            PredictError::NotCovered(n) => n.to_string(),
            other => other.to_string(),
        };
        let reason = e.kind().to_string();
        Miss {
            detail: (detail != reason).then_some(detail),
            reason,
        }
    }
}

/// The evaluation's results.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Evaluation {
    /// A one-line description of the protocol.
    pub protocol: String,
    /// Number of training samples (all samples for k-fold).
    pub samples: usize,
    /// The training samples' nominal positions, mm, base frame (all samples for k-fold),
    /// for the report's map of where samples and evaluated points lie; not in the JSON.
    #[serde(skip)]
    pub training_nominal_mm: Vec<[f64; 3]>,
    /// The evaluated points' nominal positions, mm, base frame.
    pub nominal_mm: Vec<[f64; 3]>,
    /// Their measured position errors, mm.
    pub measured_error_mm: Vec<[f64; 3]>,
    /// Their measured orientation errors, rad, when both sets carry them.
    pub measured_rotation_error_rad: Option<Vec<[f64; 3]>>,
    /// The raw errors' statistics, position, mm.
    pub uncompensated_position_mm: ResidualStats,
    /// The raw errors' statistics, orientation, mrad.
    pub uncompensated_orientation_mrad: Option<ResidualStats>,
    /// Each method's outcome, in [`Method::ALL`] order.
    pub methods: Vec<MethodResult>,
    /// Methods left out of a default selection, with the reason.
    pub skipped: Vec<(Method, String)>,
    /// What kinematic identification found, per split.
    pub calibrations: Vec<CalibrationSummary>,
    /// What each split's served-tier tables were built with, when chosen from the split's
    /// training samples ([`EvalOptions::split_rule`]): the served field and whether a
    /// hybrid table got the posture term.
    pub split_choices: Vec<SplitChoiceRecord>,
    /// The harmonic count of each split's identification, when chosen from its training
    /// samples (`--harmonics auto`; with a validation set, chosen on every sample).
    pub harmonics_choices: Vec<SplitHarmonics>,
    /// The noise floor of the first split's training samples ([`crate::noise_floor`]): of the
    /// residuals its identified model leaves when a robot is given, else of the measured
    /// errors. With a validation set that is every sample; in k-fold cross-validation the
    /// training samples of the first fold.
    pub noise_floor: Option<noise_floor::NoiseFloor>,
    /// Every method against the best, point by point ([`comparison`]): which differences
    /// these points resolve.
    pub comparison: Option<comparison::Comparison>,
    /// The identification of each split (with a validation set, of every sample), for a
    /// later evaluation of the same splits to reuse ([`EvalOptions::identified`]); not in
    /// the JSON ([`Evaluation::calibrations`] is).
    #[serde(skip)]
    pub identified: Vec<Calibration>,
}

/// The harmonic count one split's model was identified with, as chosen on its training
/// samples ([`Evaluation::harmonics_choices`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SplitHarmonics {
    /// The split (fold), from 0.
    pub split: usize,
    /// The counts tried, their held-out means, and the one chosen.
    #[serde(flatten)]
    pub choice: choice::HarmonicsChoice,
}

impl Evaluation {
    /// The result of `method`, if evaluated.
    pub fn method(&self, method: Method) -> Option<&MethodResult> {
        self.methods.iter().find(|m| m.method == method)
    }
}

/// A subset of a sample set, in the order of `indices` ([`SampleSet::subset`]).
pub fn subset(samples: &SampleSet, indices: &[usize]) -> SampleSet {
    samples.subset(indices)
}

/// Methods left out of a default selection, with the reason.
type Skipped = Vec<(Method, String)>;

/// Chooses the methods: the requested ones (refusing those the inputs cannot serve), or
/// every method that applies, with the reasons for those left out.
fn choose_methods(
    samples: &SampleSet,
    points: &SampleSet,
    options: &EvalOptions,
) -> Result<(Vec<Method>, Skipped), EvalError> {
    let unavailable = |m: Method| -> Option<String> {
        if m.needs_robot() && options.robot.is_none() {
            return Some("needs a robot model (--robot ROBOT.toml)".into());
        }
        if m.needs_joints() && samples.joints.is_none() {
            return Some("needs joint angles (j1..jn) in the samples".into());
        }
        if m.needs_joints() && points.joints.is_none() {
            return Some("needs joint angles (j1..jn) at the validation points".into());
        }
        None
    };
    match &options.methods {
        Some(list) => {
            let mut chosen = list.clone();
            chosen.sort();
            chosen.dedup();
            for &m in &chosen {
                if let Some(reason) = unavailable(m) {
                    return Err(EvalError::MethodUnavailable { method: m, reason });
                }
            }
            Ok((chosen, Vec::new()))
        }
        None => {
            let mut chosen = Vec::new();
            let mut skipped = Vec::new();
            for m in Method::DEFAULT {
                match unavailable(m) {
                    Some(reason) => skipped.push((m, reason)),
                    None => chosen.push(m),
                }
            }
            Ok((chosen, skipped))
        }
    }
}

/// Samples beyond which an evaluation runs its splits one at a time (the threads working
/// within each): a million samples' splits two at a time took 1.4 GB.
pub const ONE_SPLIT_AT_A_TIME: usize = 100_000;

/// Runs the evaluation.
///
/// # Errors
///
/// [`EvalError`] when a requested method cannot run on these inputs, the folds do not
/// suit the samples, or a method's model cannot be built (a table with invalid options, a
/// calibration the data cannot support). A method unsuited to the samples (`grid` on
/// scattered samples) is not an error: its result says why.
pub fn evaluate(
    samples: &SampleSet,
    protocol: &Protocol,
    options: &EvalOptions,
) -> Result<Evaluation, EvalError> {
    // Each split: its training samples' indices, their series (when several), the held-out
    // points. The training samples are copied out as each split runs: every split's copy
    // at once would be the samples four times over (a million samples, 600 MB more).
    type Split = (Vec<usize>, Option<Vec<usize>>, Vec<usize>);
    let series_of = |train: &[usize]| {
        (options.series.as_ref())
            .filter(|s| s.len() == samples.len())
            .map(|s| train.iter().map(|&i| s[i]).collect::<Vec<_>>())
    };
    // The held-out points: the validation set's, or the samples themselves (not a copy).
    let (splits, points, description): (Vec<Split>, &SampleSet, String) = match protocol {
        Protocol::Validation(validation) => (
            vec![(
                (0..samples.len()).collect(),
                series_of(&(0..samples.len()).collect::<Vec<_>>()),
                (0..validation.len()).collect(),
            )],
            validation,
            format!(
                "built from {} samples, evaluated at {} validation points",
                samples.len(),
                validation.len()
            ),
        ),
        held_out => {
            let (splits, description) = held_out.splits(samples).expect("not a validation set")?;
            (
                splits
                    .into_iter()
                    .map(|f| {
                        let series = series_of(&f.train);
                        (f.train, series, f.test)
                    })
                    .collect(),
                samples,
                description,
            )
        }
    };
    let (methods, skipped) = choose_methods(samples, points, options)?;
    let orientation = samples.rotation_error_rad.is_some() && points.rotation_error_rad.is_some();

    let mut collected = Collected::new(&methods, points.len());
    let mut calibrations = Vec::new();
    let mut split_choices = Vec::new();
    let mut harmonics_choices = Vec::new();
    let mut identified = Vec::new();

    // One split's identification, choices and predictions: independent of every other
    // split's, so splits run side by side (identification runs on one thread). A batch of
    // as many splits as the pool has threads at a time bounds the memory in flight to that
    // many splits'; the results are taken in split order, as one after the other would
    // give them, to the bit.
    let run_split = |split: usize, (train, train_series, test): &Split, unsupported: &[Method]| {
        let train = &subset(samples, train);
        let test_points = subset(points, test);
        let needs_robot = methods.iter().any(|m| m.needs_robot());
        // The split's harmonic count, chosen on its training samples alone as a build
        // chooses it; too few of them to choose by, none.
        // Its folds' models with the count chosen serve the split's table choices, made on
        // the same samples and folds.
        let (harmonics, folds) =
            (options.choose_harmonics && needs_robot && options.identified.is_empty())
                .then(|| {
                    choice::harmonics_choice_and_folds(
                        train,
                        options.robot.as_ref(),
                        &options.build,
                        &options.calibrate,
                        train_series.as_deref(),
                    )
                })
                .flatten()
                .unzip();
        let folds = folds
            .flatten()
            .or_else(|| options.split_fold_models.get(split).cloned().flatten());
        let split_calibrate = calibrate::CalibrateOptions {
            harmonics: harmonics
                .as_ref()
                .map_or(options.calibrate.harmonics, |h| h.chosen),
            ..options.calibrate
        };
        let calibration = if needs_robot {
            let robot = options.robot.as_ref().expect("checked by choose_methods");
            let method = *methods
                .iter()
                .find(|m| m.needs_robot())
                .expect("a method that needs the robot");
            Some(match options.identified.get(split) {
                Some(c) => c.clone(),
                None => calibrate::identify(robot, train, &split_calibrate)
                    .map_err(|source| EvalError::Calibrate { method, source })?,
            })
        } else {
            None
        };
        let mut outcomes = Vec::with_capacity(methods.len());
        for &method in &methods {
            if unsupported.contains(&method) {
                continue;
            }
            let (build, choice) = options::build_options_for(
                method,
                split,
                train,
                train_series.as_deref(),
                &split_calibrate,
                options,
                folds.as_ref(),
            );
            // A learned residual weight scales what the table's residual field holds.
            let weighted = match (choice.and_then(|c| c.residual_weight), &calibration) {
                (Some(w), Some(c)) if w.weight != 1.0 => {
                    Some(choice::weighted_residuals(train, c, w.weight))
                }
                _ => None,
            };
            let choice = choice.map(|choice| SplitChoiceRecord {
                split,
                method,
                served_field: choice.served_field.name(),
                posture: choice.posture,
                residual_weight: choice.residual_weight,
            });
            let outcome = predict_split(
                method,
                weighted.as_ref().unwrap_or(train),
                &test_points,
                calibration.as_ref(),
                options,
                &build,
                orientation,
            );
            outcomes.push((method, choice, outcome));
        }
        let harmonics = harmonics.map(|choice| SplitHarmonics { split, choice });
        Ok::<_, EvalError>((calibration, harmonics, outcomes))
    };
    // Beyond [`ONE_SPLIT_AT_A_TIME`] samples a split's training copy, merge and tables take
    // hundreds of megabytes: one split at a time, each with every thread.
    let in_flight = if samples.len() > ONE_SPLIT_AT_A_TIME {
        1
    } else {
        rayon::current_num_threads().max(1)
    };
    for (batch, chunk) in splits.chunks(in_flight).enumerate() {
        let unsupported: Vec<Method> = collected.unsupported.keys().copied().collect();
        let runs: Vec<_> = chunk
            .par_iter()
            .enumerate()
            .map(|(i, split)| run_split(batch * in_flight + i, split, &unsupported))
            .collect();
        for (i, run) in runs.into_iter().enumerate() {
            let split = batch * in_flight + i;
            let (calibration, harmonics, outcomes) = run?;
            harmonics_choices.extend(harmonics);
            if let Some(c) = calibration {
                calibrations.push(CalibrationSummary::new(split, &c));
                identified.push(c);
            }
            for (method, choice, outcome) in outcomes {
                // A method an earlier split found unsupported is not evaluated again (nor
                // its failure in this split reported, as one split after the other would).
                if collected.unsupported.contains_key(&method) {
                    continue;
                }
                let outcome = outcome?;
                split_choices.extend(choice);
                collected.record(method, &splits[split].2, outcome);
            }
        }
    }
    // The noise floor of the first split's training samples, as its identification leaves
    // them.
    let floor = splits
        .first()
        .map(|(train, _, _)| training_noise_floor(&subset(samples, train), identified.first()));
    let mut evaluation = assemble(description, samples, points, orientation, collected);
    evaluation.skipped = skipped;
    evaluation.calibrations = calibrations;
    evaluation.split_choices = split_choices;
    evaluation.harmonics_choices = harmonics_choices;
    evaluation.noise_floor = floor;
    evaluation.identified = identified;
    Ok(evaluation)
}

/// Scores a table built before at `points` (with their measured errors): its served field,
/// queried with each point's joint angles when the table is hybrid, as a controller would
/// query it. The evaluation holds the one method [`Method::Table`]; its sample count is
/// the table's, and `description` says what was evaluated.
///
/// # Errors
///
/// [`EvalError::MethodUnavailable`] for a hybrid table and points without joint angles.
pub fn evaluate_table<D: AsRef<[u8]>>(
    table: &Table<D>,
    points: &SampleSet,
    description: String,
) -> Result<Evaluation, EvalError> {
    let method = Method::Table;
    if table.is_hybrid() && points.joints.is_none() {
        return Err(EvalError::MethodUnavailable {
            method,
            reason: "the table is hybrid: its answer needs each point's joint angles (j1..jn)"
                .into(),
        });
    }
    // A file with another robot's joint count fails every point the same way: said once,
    // before any query.
    if let (Some(expected), Some(given)) = (table.joint_count(), points.joint_count()) {
        if expected != given {
            return Err(EvalError::MethodUnavailable {
                method,
                reason: format!(
                    "the table's robot has {expected} joints; the validation points give \
                     {given} joint values (j1..j{given}) each"
                ),
            });
        }
    }
    let orientation = points.rotation_error_rad.is_some() && table.has_orientation();
    let mut collected = Collected::new(&[method], points.len());
    let outcome = (0..points.len())
        .map(|i| {
            // The point's orientation, when the file gives one: a position-only table
            // checks it against its samples'.
            let rotation_rad = (points.nominal_rotation.as_ref())
                .map(|r| adwi_samples::pose::rotation_vector(&r[i]));
            let target = Target {
                position_mm: points.nominal_mm[i],
                config: points.config.as_ref().map(|c| c[i]),
                rotation_rad,
                tcp_mm: None,
            };
            table_prediction(table, &target, points.joints_rad(i), false, orientation)
        })
        .collect();
    let all: Vec<usize> = (0..points.len()).collect();
    collected.record(method, &all, SplitOutcome::Predicted(outcome));
    let mut evaluation = assemble(
        description,
        &SampleSet::default(),
        points,
        orientation,
        collected,
    );
    evaluation.samples = table.sample_count();
    // No point predicted is no evaluation: an error with the reasons, never a report of
    // nothing called a success.
    if let Some(result) = evaluation.method(method) {
        if !points.is_empty() && result.predictions.iter().all(Option::is_none) {
            let reasons: Vec<String> = (result.not_predicted.iter())
                .map(|(reason, n)| format!("{n} {reason}"))
                .collect();
            return Err(EvalError::NothingPredicted {
                method,
                points: points.len(),
                reasons: reasons.join(", "),
            });
        }
    }
    Ok(evaluation)
}

/// Per method: misses counted by kind of reason, and a few particulars of each kind.
type Tally = (BTreeMap<String, usize>, BTreeMap<String, Vec<String>>);

/// Every method's predictions at every point, gathered split by split.
struct Collected {
    methods: Vec<Method>,
    predictions: BTreeMap<Method, Vec<Option<PointPrediction>>>,
    failures: BTreeMap<Method, Tally>,
    unsupported: BTreeMap<Method, String>,
}

impl Collected {
    fn new(methods: &[Method], points: usize) -> Collected {
        Collected {
            methods: methods.to_vec(),
            predictions: methods.iter().map(|&m| (m, vec![None; points])).collect(),
            failures: BTreeMap::new(),
            unsupported: BTreeMap::new(),
        }
    }

    /// One split's outcome for `method`, at the points `test` (indices into all points).
    fn record(&mut self, method: Method, test: &[usize], outcome: SplitOutcome) {
        match outcome {
            SplitOutcome::Unsupported(reason) => {
                self.unsupported.insert(method, reason);
            }
            SplitOutcome::Predicted(list) => {
                for (local, result) in list.into_iter().enumerate() {
                    match result {
                        Ok(p) => {
                            self.predictions.get_mut(&method).expect("initialised")[test[local]] =
                                Some(p)
                        }
                        Err(miss) => {
                            let tally: &mut Tally = self.failures.entry(method).or_default();
                            *tally.0.entry(miss.reason.clone()).or_default() += 1;
                            let examples = tally.1.entry(miss.reason).or_default();
                            if let Some(detail) = miss.detail {
                                if examples.len() < MISS_EXAMPLES {
                                    examples.push(detail);
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}

/// The evaluation of what was collected at `points`: each method's residual statistics
/// and the comparison with the best (the caller adds what identification found).
fn assemble(
    description: String,
    samples: &SampleSet,
    points: &SampleSet,
    orientation: bool,
    collected: Collected,
) -> Evaluation {
    let Collected {
        methods,
        mut predictions,
        mut failures,
        mut unsupported,
    } = collected;
    let measured_rotation = if orientation {
        points.rotation_error_rad.clone()
    } else {
        None
    };
    let uncompensated_position_mm = stats(&points.error_mm);
    let uncompensated_orientation_mrad = measured_rotation
        .as_ref()
        .map(|r| stats(&r.iter().map(|v| v.map(|x| x * 1e3)).collect::<Vec<_>>()));

    let methods: Vec<MethodResult> = methods
        .into_iter()
        .map(|method| {
            let predicted = predictions.remove(&method).unwrap_or_default();
            let tally = failures.remove(&method).unwrap_or_default();
            if let Some(reason) = unsupported.remove(&method) {
                return MethodResult {
                    method,
                    unsupported: Some(reason),
                    predictions: vec![None; points.len()],
                    not_predicted: BTreeMap::from([("unsupported".to_string(), points.len())]),
                    not_predicted_examples: BTreeMap::new(),
                    position_mm: None,
                    orientation_mrad: None,
                    before_position_mm: None,
                    residual: None,
                    beyond_evidence: None,
                };
            }
            let mut position = Vec::new();
            let mut before = Vec::new();
            let mut rotation = Vec::new();
            for (i, p) in predicted.iter().enumerate() {
                let Some(p) = p else { continue };
                let e = points.error_mm[i];
                position.push([0, 1, 2].map(|a| e[a] - p.position_error_mm[a]));
                before.push(e);
                if let (Some(measured), Some(r)) = (&measured_rotation, p.orientation_error_rad) {
                    rotation.push([0, 1, 2].map(|a| (measured[i][a] - r[a]) * 1e3));
                }
            }
            let nonempty = |v: &Vec<[f64; 3]>| (!v.is_empty()).then(|| stats(v));
            MethodResult {
                method,
                unsupported: None,
                not_predicted: tally.0,
                not_predicted_examples: tally.1,
                position_mm: nonempty(&position),
                orientation_mrad: if rotation.len() == position.len() {
                    nonempty(&rotation)
                } else {
                    None
                },
                before_position_mm: nonempty(&before),
                residual: ResidualCounts::of(&predicted),
                beyond_evidence: beyond_evidence(&predicted),
                predictions: predicted,
            }
        })
        .collect();

    let comparison = comparison::compare(&methods, &points.error_mm);
    Evaluation {
        protocol: description,
        samples: samples.len(),
        training_nominal_mm: samples.nominal_mm.clone(),
        nominal_mm: points.nominal_mm.clone(),
        measured_error_mm: points.error_mm.clone(),
        measured_rotation_error_rad: measured_rotation,
        uncompensated_position_mm,
        uncompensated_orientation_mrad,
        methods,
        skipped: Vec::new(),
        calibrations: Vec::new(),
        split_choices: Vec::new(),
        harmonics_choices: Vec::new(),
        noise_floor: None,
        comparison,
        identified: Vec::new(),
    }
}

/// The noise floor of training samples: of the residuals `calibration` leaves on them, or
/// of their measured errors without one.
fn training_noise_floor(
    train: &SampleSet,
    calibration: Option<&Calibration>,
) -> noise_floor::NoiseFloor {
    match calibration {
        Some(c) if train.joints.is_some() => {
            let (residuals, _) = kinematic_residuals(c, train);
            noise_floor::noise_floor(train, &residuals, "kinematic residuals")
        }
        _ => noise_floor::noise_floor(train, &train.error_mm, "measured errors"),
    }
}

/// What the identified model leaves of samples' measured errors: position (mm) and, when
/// the samples carry them, orientation (rad).
///
/// # Panics
///
/// When the samples carry no joint angles (the callers check).
fn kinematic_residuals(
    calibration: &Calibration,
    samples: &SampleSet,
) -> (Vec<[f64; 3]>, Option<Vec<[f64; 3]>>) {
    let mut position = Vec::with_capacity(samples.len());
    let mut rotation = samples
        .rotation_error_rad
        .as_ref()
        .map(|_| Vec::with_capacity(samples.len()));
    for i in 0..samples.len() {
        let (p, r) = calibration.predict_error(samples.joints_rad(i).expect("joint angles"));
        let e = samples.error_mm[i];
        position.push([0, 1, 2].map(|a| e[a] - p[a]));
        if let (Some(out), Some(measured)) = (&mut rotation, &samples.rotation_error_rad) {
            let m = measured[i];
            out.push([0, 1, 2].map(|a| m[a] - r[a]));
        }
    }
    (position, rotation)
}

/// Statistics of residuals known to be finite and non-empty.
fn stats(residuals: &[[f64; 3]]) -> ResidualStats {
    ResidualStats::from_residuals(residuals)
        .expect("residuals come from finite, validated samples and are not empty")
}

enum SplitOutcome {
    /// The method cannot work on these samples.
    Unsupported(String),
    /// One result per test point: the prediction, or why there is none.
    Predicted(Vec<Result<PointPrediction, Miss>>),
}

fn predict_split(
    method: Method,
    train: &SampleSet,
    test: &SampleSet,
    calibration: Option<&Calibration>,
    options: &EvalOptions,
    build: &BuildOptions,
    orientation: bool,
) -> Result<SplitOutcome, EvalError> {
    let targets: Vec<Target> = (0..test.len())
        .map(|i| Target {
            position_mm: test.nominal_mm[i],
            config: test.config.as_ref().map(|c| c[i]),
            rotation_rad: None,
            tcp_mm: None,
        })
        .collect();
    fn joints_rad(set: &SampleSet, i: usize) -> &[f64] {
        set.joints_rad(i).expect("checked by choose_methods")
    }
    // A table is queried at the targets alone, by one tier: it needs only the nodes that
    // serve them (an exact tier's none) and the candidate lists they are computed from or
    // the exact tier reads.
    let positions: Vec<[f64; 3]> = targets.iter().map(|t| t.position_mm).collect();
    let nodes = match method {
        Method::PaperTrilinear | Method::HybridTrilinear => Queried::At {
            served: &positions,
            exact: &[],
        },
        _ => Queried::At {
            served: &[],
            exact: &positions,
        },
    };
    let outcome = match method {
        Method::Table => {
            return Ok(SplitOutcome::Unsupported(
                "a table built before is scored by itself (tablec eval --table)".into(),
            ))
        }
        Method::Paper | Method::PaperTrilinear => {
            let table = compile_table(method, train, build, nodes)?;
            let exact = method == Method::Paper;
            targets
                .iter()
                .enumerate()
                .map(|(i, t)| {
                    // The joint angles only matter to a table with a joint screen.
                    table_prediction(&table, t, test.joints_rad(i), exact, orientation)
                })
                .collect()
        }
        Method::Idw | Method::Grid | Method::Kriging => {
            let positions = &train.nominal_mm;
            let result = match method {
                Method::Idw => baseline_predictions(method, train, &targets, orientation, |v| {
                    Idw::new(positions, v, options.idw)
                }),
                Method::Grid => baseline_predictions(method, train, &targets, orientation, |v| {
                    Grid::new(positions, v, options.grid)
                }),
                _ => baseline_predictions(method, train, &targets, orientation, |v| {
                    Kriging::new(positions, v, options.kriging)
                }),
            };
            // A baseline that cannot work on these samples (a lattice method on a cloud)
            // is reported as unsupported, not as a failure of the evaluation.
            match result {
                Ok(list) => list,
                Err(EvalError::Baseline {
                    source: BaselineError::Unsupported { reason },
                    ..
                }) => return Ok(SplitOutcome::Unsupported(reason)),
                Err(e) => return Err(e),
            }
        }
        Method::Kinematic => {
            let c = calibration.expect("identified for kinematic methods");
            (0..test.len())
                .map(|i| {
                    let (p, r) = c.predict_error(joints_rad(test, i));
                    Ok(PointPrediction {
                        position_error_mm: p,
                        orientation_error_rad: orientation.then_some(r),
                        residual: None,
                        evidence: None,
                    })
                })
                .collect()
        }
        Method::Hybrid | Method::HybridTrilinear => {
            let c = calibration.expect("identified for kinematic methods");
            let exact = method == Method::Hybrid;
            // The real hybrid table: model and residuals compiled together, opened and
            // queried with the point's joint angles, as a controller would.
            let model = c.prepared_model();
            let bytes = build::plan(train, build)
                .and_then(|plan| {
                    adwi_compile::hybrid::compile_serving(train, &model, &plan, nodes, &|_| {})
                })
                .map_err(|source| EvalError::Build { method, source })?
                .bytes;
            let table = open_compiled(method, bytes)?;
            targets
                .iter()
                .enumerate()
                .map(|(i, t)| {
                    table_prediction(&table, t, Some(joints_rad(test, i)), exact, orientation)
                })
                .collect()
        }
    };
    Ok(SplitOutcome::Predicted(outcome))
}

/// Compiles samples into a table (its served tier's `nodes`) and opens it from its bytes,
/// as `tablec build` then `tablec query` would.
fn compile_table(
    method: Method,
    samples: &SampleSet,
    options: &BuildOptions,
    nodes: Queried<'_>,
) -> Result<Table<CompiledBytes>, EvalError> {
    let (bytes, _) = build::compile_serving(samples, options, nodes, &|_| {})
        .map_err(|source| EvalError::Build { method, source })?;
    open_compiled(method, bytes)
}

/// A table's bytes as compiled in memory, opened with [`open_compiled`].
enum CompiledBytes {
    /// The build's own allocation, which starts where the archive must.
    Built(Vec<u8>),
    /// A copy, where it does not.
    Copied(adwi_runtime::AlignedBytes),
}

impl AsRef<[u8]> for CompiledBytes {
    fn as_ref(&self) -> &[u8] {
        match self {
            CompiledBytes::Built(bytes) => bytes,
            CompiledBytes::Copied(bytes) => bytes,
        }
    }
}

/// Opens and validates a compiled table's bytes where they are when they start at a
/// multiple of the payload's alignment (the system allocator's blocks do), else copied
/// to an aligned buffer: an evaluation opens a table per method and split, each tens of
/// megabytes, and its queries do not depend on the cache-line alignment a copy gives.
fn open_compiled(method: Method, bytes: Vec<u8>) -> Result<Table<CompiledBytes>, EvalError> {
    let in_place = bytes
        .as_ptr()
        .align_offset(adwi_runtime::format::PAYLOAD_ALIGN)
        == 0;
    open_compiled_as(method, bytes, in_place)
}

/// [`open_compiled`], in place or copied as `in_place` says.
fn open_compiled_as(
    method: Method,
    bytes: Vec<u8>,
    in_place: bool,
) -> Result<Table<CompiledBytes>, EvalError> {
    let data = if in_place {
        CompiledBytes::Built(bytes)
    } else {
        CompiledBytes::Copied(adwi_runtime::AlignedBytes::copy_from(&bytes).map_err(|e| {
            EvalError::Open {
                method,
                message: e.to_string(),
            }
        })?)
    };
    Table::from_bytes(data).map_err(|e| EvalError::Open {
        method,
        message: e.to_string(),
    })
}

/// A table's answer at a target from its exact tier or its served field, queried with the
/// target's joint angles when known ([`Table::query_with_joints`]: the model part of a
/// hybrid table, the joint screen).
fn table_prediction<D: AsRef<[u8]>>(
    table: &Table<D>,
    target: &Target,
    joints_rad: Option<&[f64]>,
    exact: bool,
    orientation: bool,
) -> Result<PointPrediction, Miss> {
    let tier = if exact { Tier::Exact } else { Tier::Served };
    let c = table.answer(target, joints_rad, tier);
    if c.status != Status::Ok {
        return Err(Miss::status(c.status));
    }
    Ok(PointPrediction {
        position_error_mm: c.position_error_mm,
        orientation_error_rad: (orientation && table.has_orientation())
            .then_some(c.orientation_error_rad),
        residual: table.is_hybrid().then_some(c.residual),
        evidence: (table.header().version >= 4).then_some(c.evidence),
    })
}

/// Builds a baseline for position errors (and one for orientation errors when evaluated)
/// and predicts at every target.
fn baseline_predictions<B: baselines::Baseline + Sync>(
    method: Method,
    train: &SampleSet,
    targets: &[Target],
    orientation: bool,
    make: impl Fn(&[[f64; 3]]) -> Result<B, BaselineError>,
) -> Result<Vec<Result<PointPrediction, Miss>>, EvalError> {
    let wrap = |source| EvalError::Baseline { method, source };
    let position = make(&train.error_mm).map_err(wrap)?;
    let rotation = match (&train.rotation_error_rad, orientation) {
        (Some(r), true) => Some(make(r).map_err(wrap)?),
        _ => None,
    };
    // Held-out points side by side, collected in their order: the same list at any thread
    // count.
    Ok(targets
        .par_iter()
        .map(|t| {
            let p = position.predict(t.position_mm).map_err(Miss::baseline)?;
            let r = match &rotation {
                Some(b) => Some(b.predict(t.position_mm).map_err(Miss::baseline)?),
                None => None,
            };
            Ok(PointPrediction {
                position_error_mm: p,
                orientation_error_rad: r,
                residual: None,
                evidence: None,
            })
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A table opened where it was compiled answers as its aligned copy does, to the bit.
    #[test]
    fn a_compiled_table_opened_in_place_answers_as_its_copy() {
        let mut csv = String::from("x,y,z,dx,dy,dz\n");
        for i in 0..64 {
            let p = [i % 4, (i / 4) % 4, i / 16].map(|v| 1000.0 + 100.0 * f64::from(v));
            let e = [0.1 + 0.01 * f64::from(i), -0.2, 0.05 * f64::from(i % 5)];
            csv += &format!("{},{},{},{},{},{}\n", p[0], p[1], p[2], e[0], e[1], e[2]);
        }
        let columns = adwi_samples::ColumnMap::default();
        let samples =
            adwi_samples::parse_samples("s.csv".as_ref(), csv.as_bytes(), &columns).unwrap();
        let options = BuildOptions {
            served_field: adwi_compile::build::ServedField::Method,
            ..BuildOptions::default()
        };
        let (bytes, _) = build::compile(&samples, &options, &|_| {}).unwrap();
        assert_eq!(
            bytes.as_ptr() as usize % adwi_runtime::format::PAYLOAD_ALIGN,
            0
        );
        let in_place = open_compiled_as(Method::Paper, bytes.clone(), true).unwrap();
        let copied = open_compiled_as(Method::Paper, bytes, false).unwrap();
        let mut answered = 0;
        for i in 0..200 {
            let t = f64::from(i);
            let target = Target::at([1050.0 + 1.3 * t, 1020.0 + 0.9 * t, 1010.0 + 1.1 * t]);
            for tier in [Tier::Exact, Tier::Served] {
                let (a, b) = (
                    in_place.answer(&target, None, tier),
                    copied.answer(&target, None, tier),
                );
                assert_eq!(format!("{a:?}"), format!("{b:?}"));
                answered += usize::from(a.status == Status::Ok);
            }
        }
        assert!(answered > 100, "{answered}");
    }
}
