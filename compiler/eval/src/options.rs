//! What an evaluation is asked for: the methods, their build options, the identification
//! and baseline parameters, and how a split's served-tier table is chosen from its
//! training samples.

use adwi_compile::build::{BuildOptions, ServedField};
use adwi_compile::nugget_kriging::GivenChoices;
use adwi_compile::posture::Posture;
use adwi_identify::calibrate::{CalibrateOptions, Calibration};
use adwi_robot::Robot;
use adwi_samples::SampleSet;

use crate::baselines::{GridParams, IdwParams, KrigingParams};
use crate::choice::{default_choices, Ask, FoldModels, ResidualWeight};
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
    /// protocol and identification options made it ([`crate::Evaluation::identified`]): several
    /// evaluations then identify once per split. Empty: identified here.
    pub identified: Vec<Calibration>,
    /// Each split's kriging hyperparameters, when searched before on its training samples
    /// alone ([`crate::choice::CrossValidation`]): a kriging served field of the split's
    /// tables takes them instead of searching its own. Empty: each table searches.
    pub split_kriging_choices: Vec<Option<GivenChoices>>,
    /// Each split's fold models from its harmonic choice when made before on its training
    /// samples ([`crate::choice::harmonics_choice_and_folds`]): the split's table choices
    /// take them where they are of the same samples and folds ([`crate::choice::Ask::folds`]).
    /// Empty: identified by the choices.
    pub split_fold_models: Vec<Option<crate::choice::FoldModels>>,
    /// The series of each sample (its index among the files read), when several: a
    /// split's residual weight is then learned by leaving one series out.
    pub series: Option<Vec<usize>>,
    /// Chooses what the served-tier methods' tables (`paper-trilinear`,
    /// `hybrid-trilinear`) are built with from each split's training samples alone, as a
    /// build decides what it is not given (the served field, a hybrid table's posture
    /// term); `None`: `build` as it is.
    pub split_rule: Option<SplitRule>,
    /// Chooses each split's harmonic count of the joint-space terms from its training
    /// samples alone, as a build does by default
    /// ([`crate::choice::CrossValidation::choose_harmonics`]); `calibrate.harmonics` is
    /// then where the choice starts, not the count. Only with a robot.
    pub choose_harmonics: bool,
}

/// What a split's served-tier table (`paper-trilinear`, `hybrid-trilinear`) is built with
/// when [`EvalOptions::build`] leaves it to be chosen: decided on the split's training
/// samples alone, as a build decides what it is not given ([`crate::choice::default_choices`],
/// the same code), so that no held-out point ever takes part. A split too small to
/// cross-validate gets what a build would then write: the method's field, no term.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SplitRule {
    /// The served field is chosen (else `build`'s).
    pub choose_field: bool,
    /// A hybrid table's posture term is decided (else as `build` says).
    pub choose_posture: bool,
    /// A hybrid table's residual weight is learned from the split's training samples, by
    /// their series or regions ([`crate::choice::CrossValidation::residual_weight`]).
    pub weigh_residual: bool,
}

/// What a [`SplitRule`] chose for one split's table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplitChoice {
    /// The served field.
    pub served_field: ServedField,
    /// The posture term's decision, when the rule made it (a hybrid table, the term
    /// neither asked for nor refused); `None`: as `build` says.
    pub posture: Option<PostureDecision>,
    /// The residual field's weight and its evidence, when the rule learned it (a hybrid
    /// table; none when the held-out points could not tell).
    pub residual_weight: Option<ResidualWeight>,
}

/// Whether a split's hybrid table gets the posture term, by the cross-validation a build
/// makes on its training samples ([`crate::choice::CrossValidation::posture`]).
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
    /// The residual field's weight and its evidence, when learned per split.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residual_weight: Option<ResidualWeight>,
}

/// The build options of `method` on split `split`'s training samples `train`, its model
/// identified with `calibrate`:
/// `options.build` (with the split's kriging hyperparameters, when given), with what a
/// served-tier method's table is built with chosen from `train` when a rule is given, and
/// that choice; `folds`, the folds' models the split's harmonic choice identified on
/// `train` ([`Ask::folds`]).
pub(crate) fn build_options_for(
    method: Method,
    split: usize,
    train: &SampleSet,
    train_series: Option<&[usize]>,
    calibrate: &CalibrateOptions,
    options: &EvalOptions,
    folds: Option<&FoldModels>,
) -> (BuildOptions, Option<SplitChoice>) {
    let mut given = options.build.clone();
    if given.kriging_choices.is_none() {
        given.kriging_choices = options.split_kriging_choices.get(split).copied().flatten();
    }
    let Some(rule) = options.split_rule else {
        return (given, None);
    };
    let hybrid = match method {
        Method::PaperTrilinear => false,
        Method::HybridTrilinear => true,
        _ => return (given, None),
    };
    let choice = split_choice(rule, train, train_series, hybrid, calibrate, options, folds);
    let mut build = BuildOptions {
        served_field: choice.served_field,
        ..given
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

/// What `rule` chooses for a split's table on `train`: a hybrid table's or a position-only
/// one's, as a build without a robot chooses it.
fn split_choice(
    rule: SplitRule,
    train: &SampleSet,
    train_series: Option<&[usize]>,
    hybrid: bool,
    calibrate: &CalibrateOptions,
    options: &EvalOptions,
    folds: Option<&FoldModels>,
) -> SplitChoice {
    let build = &options.build;
    let posture = rule.choose_posture && hybrid;
    let weight = rule.weigh_residual && hybrid;
    if !(rule.choose_field || posture || weight) {
        return SplitChoice {
            served_field: build.served_field,
            posture: None,
            residual_weight: None,
        };
    }
    let robot = options.robot.as_ref().filter(|_| hybrid);
    let ask = Ask {
        field: rule.choose_field,
        posture,
        weight,
        harmonics: false,
        series: train_series,
        folds,
    };
    let chosen = default_choices(train, robot, build, calibrate, ask);
    let mut chosen_options = build.clone();
    if let Ok(auto) = &chosen {
        auto.apply(&mut chosen_options);
    }
    let residual_weight = (chosen.as_ref().ok())
        .filter(|_| weight)
        .and_then(|auto| auto.residual_weight);
    SplitChoice {
        served_field: chosen_options.served_field,
        residual_weight,
        posture: posture.then(|| {
            let decided = chosen.ok().and_then(|auto| auto.posture);
            PostureDecision {
                without_mm: decided.and_then(|p| p.without_mm),
                with_mm: decided.and_then(|p| p.with_mm),
                on: decided.is_some_and(|p| p.chosen),
            }
        }),
    }
}
