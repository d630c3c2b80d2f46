//! What an evaluation is asked for: the methods, their build options, the identification
//! and baseline parameters, and how a served field is chosen per split.

use adwi_compile::build::BuildOptions;
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
    /// Chooses the served field of the served-tier methods (`paper-trilinear`,
    /// `hybrid-trilinear`) from each split's training samples alone, as a build without a
    /// given field does; `None`: `build`'s served field.
    pub served_field: Option<ServedFieldRule>,
}

/// A served field chosen from a split's training samples, for a hybrid table (`true`: by
/// its residuals) or a position-only one: what [`EvalOptions::served_field`] holds. A rule, not a fixed field, so that no
/// held-out point ever takes part in the choice.
#[derive(Clone)]
pub struct ServedFieldRule(
    #[allow(clippy::type_complexity)]
    pub  std::sync::Arc<dyn Fn(&SampleSet, bool) -> adwi_compile::build::ServedField + Send + Sync>,
);

impl std::fmt::Debug for ServedFieldRule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ServedFieldRule(..)")
    }
}

/// The build options of `method` on the training samples `train`: `options.build`, with the
/// served field of a served-tier method chosen from `train` when a rule is given.
pub(crate) fn build_options_for(
    method: Method,
    train: &SampleSet,
    options: &EvalOptions,
) -> BuildOptions {
    match (&options.served_field, method) {
        (Some(rule), Method::PaperTrilinear | Method::HybridTrilinear) => BuildOptions {
            served_field: (rule.0)(train, method == Method::HybridTrilinear),
            ..options.build.clone()
        },
        _ => options.build.clone(),
    }
}
