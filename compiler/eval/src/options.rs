//! What an evaluation is asked for: the methods, their build options, the identification
//! and baseline parameters, and how a split's served-tier table is chosen from its
//! training samples.

use adwi_compile::build::{BuildOptions, ServedField};
use adwi_compile::posture::Posture;
use adwi_robot::calibrate::{CalibrateOptions, Calibration};
use adwi_robot::Robot;
use adwi_samples::SampleSet;

use crate::baselines::{GridParams, IdwParams, KrigingParams};
use crate::Method;

/// What to evaluate and with which parameters; the default evaluates every applicable
/// method with each one's default parameters.
#[derive(Debug, Clone, Default)]
pub struct EvalOptions {
    /// The methods; `None` for every method the data and options allow.
    pub methods: Option<Vec<Method>>,
    /// Table options for `paper`, `paper-joint` and `hybrid`, as `tablec build` takes them.
    pub build: BuildOptions,
    /// The robot, for `kinematic` and `hybrid`.
    pub robot: Option<Robot>,
    /// Identification options.
    pub calibrate: CalibrateOptions,
    /// IDW parameters.
    pub idw: IdwParams,
    /// Lattice detection parameters.
    pub grid: GridParams,
    /// Kriging parameters.
    pub kriging: KrigingParams,
    /// The identification of each split, when an earlier evaluation of the same samples,
    /// protocol and identification options made it ([`Evaluation::identified`]): several
    /// evaluations then identify once per split. Empty: identified here.
    pub identified: Vec<Calibration>,
    /// Chooses what the served-tier methods' tables (`paper-trilinear`,
    /// `hybrid-trilinear`) are built with from each split's training samples alone, as a
    /// build decides what it is not given (the served field, a hybrid table's posture
    /// term); `None`: `build` as it is.
    pub split_rule: Option<SplitRule>,
}

/// What a split's table is built with, chosen from its training samples alone, for a
/// hybrid table (`true`: by its residuals) or a position-only one: what
/// [`EvalOptions::split_rule`] holds. A rule, not a fixed choice, so that no held-out
/// point ever takes part in it.
#[derive(Clone)]
pub struct SplitRule(
    #[allow(clippy::type_complexity)]
    pub  std::sync::Arc<dyn Fn(&SampleSet, bool) -> SplitChoice + Send + Sync>,
);

impl std::fmt::Debug for SplitRule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SplitRule(..)")
    }
}

/// What a [`SplitRule`] chose for one split's table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplitChoice {
    /// The served field.
    pub served_field: ServedField,
    /// The posture term's decision, when the rule made it (a hybrid table, the term
    /// neither asked for nor refused); `None`: as `build` says.
    pub posture: Option<PostureDecision>,
}

/// Whether a split's hybrid table gets the posture term, by the cross-validation a build
/// makes on its training samples (`adwi_jobs::tune::posture_choice`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PostureDecision {
    /// The served tier's cross-validated mean without the term, mm.
    pub without_mm: Option<f64>,
    /// The same with the term, mm.
    pub with_mm: Option<f64>,
    /// Whether the term is added.
    pub on: bool,
}

/// What one split's served-tier table was built with, as its rule chose
/// ([`Evaluation::split_choices`](crate::Evaluation::split_choices)).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SplitChoiceRecord {
    /// The split (fold), from 0.
    pub split: usize,
    /// The method whose table it is.
    pub method: Method,
    /// The served field's name.
    pub served_field: &'static str,
    /// The posture term's decision, when made per split.
    pub posture: Option<PostureDecision>,
}

/// The build options of `method` on the training samples `train`: `options.build`, with
/// what a served-tier method's table is built with chosen from `train` when a rule is
/// given, and that choice.
pub(crate) fn build_options_for(
    method: Method,
    train: &SampleSet,
    options: &EvalOptions,
) -> (BuildOptions, Option<SplitChoice>) {
    match (&options.split_rule, method) {
        (Some(rule), Method::PaperTrilinear | Method::HybridTrilinear) => {
            let choice = (rule.0)(train, method == Method::HybridTrilinear);
            let mut build = BuildOptions {
                served_field: choice.served_field,
                ..options.build.clone()
            };
            if let Some(decision) = choice.posture {
                build.posture = if decision.on {
                    Posture::Fit
                } else {
                    Posture::Off
                };
            }
            (build, Some(choice))
        }
        _ => (options.build.clone(), None),
    }
}
