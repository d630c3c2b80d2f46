//! The table's parameters chosen by evidence: k-fold cross-validation of candidate
//! parameters on the training samples alone (`tablec build --tune`). Validation points
//! never take part: a choice made on them would be fitted to them.
//!
//! The candidates are the neighbour count `k` and the neighbourhood radius ε as a multiple
//! of the sample spacing (the method's other parameters stay as given). Each is scored by
//! the mean position residual of the method the table serves — `paper`, or `hybrid` with a
//! robot — over the held-out folds. A candidate that leaves points unpredicted never beats
//! one that predicts more: the choice is the lowest mean among those that miss the fewest.
//!
//! Then, with the chosen `k` and ε, what the served field's nodes hold
//! ([`ServedField`]): the method's own answer, or kriging with a nugget of the samples'
//! errors (which turns with the tool's axis where its likelihood says so). Each is scored
//! the same way on the served tier (`paper-trilinear`, or `hybrid-trilinear`), and the
//! lowest mean wins; a table with a joint screen has no served tier and keeps the
//! method's. That choice is also what every build makes by default, without `--tune`
//! ([`auto_served_field`]: the build's own parameters, at most [`AUTO_MAX_SAMPLES`] of the
//! samples).
//!
//! The folds are the same for every candidate, and so is a hybrid table's model on each:
//! the robot is identified once per fold, by the first evaluation, and every later one
//! reuses it.

use std::cell::RefCell;

use adwi_compile::build::{BuildOptions, ServedField, Tuning};
use adwi_compile::nugget_kriging::GivenChoices;
use adwi_eval::{evaluate, EvalError, EvalOptions, Method, Protocol};
use adwi_robot::calibrate::Calibration;
use adwi_robot::Robot;
use adwi_samples::SampleSet;

/// The neighbour counts tried.
pub const K_CANDIDATES: [u32; 3] = [4, 8, 12];
/// The radii tried, in sample spacings (the default is 2).
pub const RADIUS_CANDIDATES_SPACINGS: [f64; 3] = [1.5, 2.0, 3.0];

/// One candidate's cross-validated figures.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    /// The neighbour count.
    pub k: u32,
    /// The radius, mm.
    pub radius_mm: f64,
    /// Mean position residual over the predicted held-out points, mm; `None` when none was
    /// predicted.
    pub cv_mean_mm: Option<f64>,
    /// Held-out points not predicted.
    pub missed: usize,
}

/// One served field's cross-validated figures, with the chosen `k` and ε.
#[derive(Clone, Debug, PartialEq)]
pub struct ServedCandidate {
    /// What the nodes hold.
    pub field: ServedField,
    /// Mean position residual of the served tier over the predicted held-out points, mm.
    pub cv_mean_mm: Option<f64>,
    /// Held-out points the served tier did not predict.
    pub missed: usize,
}

/// What tuning found: every candidate, and the options chosen.
#[derive(Clone, Debug)]
pub struct TuneReport {
    /// The method scored.
    pub method: Method,
    /// The folds.
    pub folds: usize,
    /// Every candidate, in the order tried.
    pub candidates: Vec<Candidate>,
    /// The index of the chosen one.
    pub chosen: usize,
    /// The served fields tried with the chosen `k` and ε (none with a joint screen).
    pub served: Vec<ServedCandidate>,
    /// The posture term's cross-validation, when asked for (a hybrid table).
    pub posture: Option<PostureChoice>,
    /// The build options with the chosen parameters and the tuning recorded.
    pub options: BuildOptions,
}

/// Why tuning could not choose.
#[derive(Debug, thiserror::Error)]
pub enum TuneError {
    /// The samples have no spacing to scale radii by (fewer than two positions).
    #[error("the samples have no spacing to scale the candidate radii by")]
    NoSpacing,
    /// Fewer than two folds.
    #[error("tuning needs at least 2 folds")]
    Folds,
    /// The samples' identification failed (the hyperparameters of a hybrid table's kriging
    /// are those of its residuals).
    #[error("cannot identify the robot from the samples")]
    Identify(#[source] adwi_robot::calibrate::CalibrateError),
    /// The kriging's hyperparameters could not be chosen.
    #[error("cannot fit the kriging of the served field")]
    Kriging(#[source] adwi_compile::build::BuildError),
    /// Too few samples to cross-validate a choice by default ([`AUTO_MIN_SAMPLES`]).
    #[error("{0} samples; at least {AUTO_MIN_SAMPLES} are cross-validated")]
    TooFewSamples(usize),
    /// No candidate predicted a single held-out point.
    #[error("no candidate predicted any held-out point")]
    NothingPredicted,
    /// An evaluation failed.
    #[error(transparent)]
    Eval(#[from] EvalError),
}

/// Chooses `k` and ε for a table of `samples` (a hybrid table when `robot` is given) by
/// `folds`-fold cross-validation with `seed`, the other options as in `base`; then, when
/// `choose_field`, the served field with them ([`served_field`]).
///
/// # Errors
///
/// [`TuneError`].
#[allow(clippy::too_many_arguments)]
pub fn tune(
    samples: &SampleSet,
    robot: Option<&Robot>,
    base: &BuildOptions,
    calibrate: &adwi_robot::calibrate::CalibrateOptions,
    folds: usize,
    seed: u64,
    choose_field: bool,
    choose_posture: bool,
) -> Result<TuneReport, TuneError> {
    if folds < 2 {
        return Err(TuneError::Folds);
    }
    let spacing = samples.spacing_mm().ok_or(TuneError::NoSpacing)?;
    let method = if robot.is_some() {
        Method::Hybrid
    } else {
        Method::Paper
    };
    // Each fold's identification, made by the first candidate's evaluation.
    let identified: RefCell<Vec<Calibration>> = RefCell::new(Vec::new());
    let score = |method: Method, build: BuildOptions| {
        cross_validate(
            samples,
            robot,
            calibrate,
            folds,
            seed,
            &identified,
            method,
            build,
        )
    };
    let mut candidates = Vec::new();
    for &k in &K_CANDIDATES {
        for &spacings in &RADIUS_CANDIDATES_SPACINGS {
            let mut build = base.clone();
            build.method.max_neighbours = k;
            build.method.radius_mm = Some(spacings * spacing);
            let (cv_mean_mm, missed) = score(method, build)?;
            candidates.push(Candidate {
                k,
                radius_mm: spacings * spacing,
                cv_mean_mm,
                missed,
            });
        }
    }
    let chosen = best(candidates.iter().map(|c| (c.cv_mean_mm, c.missed)))
        .ok_or(TuneError::NothingPredicted)?;
    let mut options = base.clone();
    options.method.max_neighbours = candidates[chosen].k;
    options.method.radius_mm = Some(candidates[chosen].radius_mm);
    options.tuning = Some(Tuning {
        folds: folds as u32,
        cv_mean_mm: candidates[chosen].cv_mean_mm.unwrap_or(0.0),
        served_cv_mean_mm: None,
        posture_cv_mean_mm: None,
    });
    let served = if choose_field {
        let choice = served_field(
            samples,
            robot,
            &options,
            calibrate,
            folds,
            seed,
            &identified,
        )?;
        options.served_field = choice.field();
        if let Some(tuning) = &mut options.tuning {
            tuning.served_cv_mean_mm = choice.chosen_cv_mean_mm();
        }
        choice.candidates
    } else {
        Vec::new()
    };
    let posture = match robot.filter(|_| choose_posture) {
        Some(robot) => {
            // The chosen field's figure on these folds, scored above when it was chosen.
            let without_mm = match options.tuning.and_then(|t| t.served_cv_mean_mm) {
                Some(mean) => Some(mean),
                None => served_field_among(
                    &[options.served_field],
                    samples,
                    Some(robot),
                    &options,
                    calibrate,
                    folds,
                    seed,
                    &identified,
                )?
                .chosen_cv_mean_mm(),
            };
            let posture = posture_choice(
                samples,
                robot,
                &options,
                calibrate,
                folds,
                seed,
                &identified,
                without_mm,
            )?;
            if posture.chosen {
                options.posture = adwi_compile::posture::Posture::Fit;
                if let Some(tuning) = &mut options.tuning {
                    tuning.served_cv_mean_mm = posture.without_mm;
                    tuning.posture_cv_mean_mm = posture.with_mm;
                }
            }
            Some(posture)
        }
        None => None,
    };
    Ok(TuneReport {
        method,
        folds,
        candidates,
        chosen,
        served,
        posture,
        options,
    })
}

/// What the served field's nodes should hold, chosen by cross-validation of the served tier
/// (`paper-trilinear`, or `hybrid-trilinear` with a robot) on the training samples alone:
/// the method's own answer against kriging with a nugget, with the other options as in
/// `options`. A table with a joint screen has no served tier: no candidate, the method's.
///
/// `identified` holds each fold's identification of a hybrid table's model once made, so
/// that every later evaluation on the same folds reuses it.
///
/// # Errors
///
/// An evaluation failing.
pub fn served_field(
    samples: &SampleSet,
    robot: Option<&Robot>,
    options: &BuildOptions,
    calibrate: &adwi_robot::calibrate::CalibrateOptions,
    folds: usize,
    seed: u64,
    identified: &RefCell<Vec<Calibration>>,
) -> Result<ServedChoice, TuneError> {
    if folds < 2 {
        return Err(TuneError::Folds);
    }
    if options.joint_radius_deg.is_some_and(|r| r > 0.0) {
        return Ok(ServedChoice::default());
    }
    // The kriging turns with the tool's axis where its likelihood says so: one kind.
    served_field_among(
        &[ServedField::Method, ServedField::Kriging],
        samples,
        robot,
        options,
        calibrate,
        folds,
        seed,
        identified,
    )
}

/// [`served_field`] among `fields`.
#[allow(clippy::too_many_arguments)]
fn served_field_among(
    fields: &[ServedField],
    samples: &SampleSet,
    robot: Option<&Robot>,
    options: &BuildOptions,
    calibrate: &adwi_robot::calibrate::CalibrateOptions,
    folds: usize,
    seed: u64,
    identified: &RefCell<Vec<Calibration>>,
) -> Result<ServedChoice, TuneError> {
    let method = if robot.is_some() {
        Method::HybridTrilinear
    } else {
        Method::PaperTrilinear
    };
    let mut candidates = Vec::new();
    for &field in fields {
        let build = BuildOptions {
            served_field: field,
            ..options.clone()
        };
        let (cv_mean_mm, missed) = cross_validate(
            samples, robot, calibrate, folds, seed, identified, method, build,
        )?;
        candidates.push(ServedCandidate {
            field,
            cv_mean_mm,
            missed,
        });
    }
    // The same cells are served either way; ties keep the method's own answer.
    let chosen = best(candidates.iter().map(|c| (c.cv_mean_mm, c.missed)));
    Ok(ServedChoice {
        folds,
        candidates,
        chosen,
    })
}

/// The served fields tried and the one chosen ([`served_field`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ServedChoice {
    /// The folds.
    pub folds: usize,
    /// Every field tried, in order (none for a table without a served tier).
    pub candidates: Vec<ServedCandidate>,
    /// The index of the chosen one, if any predicted a held-out point.
    pub chosen: Option<usize>,
}

impl ServedChoice {
    /// The field chosen: the method's own answer when none was.
    pub fn field(&self) -> ServedField {
        self.chosen
            .map_or(ServedField::Method, |i| self.candidates[i].field)
    }

    /// The chosen field's cross-validated mean, mm.
    pub fn chosen_cv_mean_mm(&self) -> Option<f64> {
        self.chosen.and_then(|i| self.candidates[i].cv_mean_mm)
    }
}

/// One candidate's cross-validated mean position residual of `method` (`None` when no
/// held-out point was predicted) and its missed points, on the same folds as every other;
/// the first evaluation fills `identified`.
#[allow(clippy::too_many_arguments)]
fn cross_validate(
    samples: &SampleSet,
    robot: Option<&Robot>,
    calibrate: &adwi_robot::calibrate::CalibrateOptions,
    folds: usize,
    seed: u64,
    identified: &RefCell<Vec<Calibration>>,
    method: Method,
    build: BuildOptions,
) -> Result<(Option<f64>, usize), TuneError> {
    let options = EvalOptions {
        methods: Some(vec![method]),
        build,
        robot: robot.cloned(),
        calibrate: *calibrate,
        identified: identified.borrow().clone(),
        ..EvalOptions::default()
    };
    let evaluation = evaluate(samples, &Protocol::KFold { folds, seed }, &options)?;
    if identified.borrow().is_empty() {
        *identified.borrow_mut() = evaluation.identified.clone();
    }
    let result = evaluation.method(method);
    Ok((
        result.and_then(|r| r.position_mm.as_ref().map(|p| p.mean_norm)),
        result.map_or(samples.len(), |r| samples.len() - r.predicted()),
    ))
}

/// The fewest samples the served field's choice by default cross-validates: with fewer,
/// the folds are too small to tell two fields apart, and the method's own answer is served.
pub const AUTO_MIN_SAMPLES: usize = 25;
/// The folds of the served field's choice by default ([`auto_served_field`]).
pub const AUTO_FOLDS: usize = 5;
/// The most samples the served field's choice by default cross-validates: above, an evenly
/// strided subset of this many, so that the choice costs a bounded time whatever the
/// sample count (the table itself is built from all of them).
pub const AUTO_MAX_SAMPLES: usize = 1000;

/// The served field chosen by default, and the evidence.
#[derive(Clone, Debug, PartialEq)]
pub struct AutoServedField {
    /// The served fields tried and the one chosen.
    pub choice: ServedChoice,
    /// The exact tier's cross-validated mean on the same folds, mm (the method the table
    /// computes, with the build's parameters).
    pub exact_cv_mean_mm: Option<f64>,
    /// How many of the samples were cross-validated ([`AUTO_MAX_SAMPLES`] at most).
    pub samples: usize,
    /// The kriging's hyperparameters every fold used: the table's, when kriging is chosen.
    pub kriging_choices: Option<GivenChoices>,
    /// The posture term's cross-validation, when it was asked for (a hybrid table).
    pub posture: Option<PostureChoice>,
}

/// The posture term's cross-validation ([`posture_choice`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PostureChoice {
    /// The served tier's mean without the term (the chosen field's), mm.
    pub without_mm: Option<f64>,
    /// The same with the term, mm.
    pub with_mm: Option<f64>,
    /// Whether the term is added: it improved the mean by the margin.
    pub chosen: bool,
}

/// The least relative improvement of the cross-validated mean for which a build adds the
/// posture term.
pub const POSTURE_MIN_GAIN_FRACTION: f64 = 0.02;
/// The least absolute improvement of the cross-validated mean for which a build adds the
/// posture term, mm: below, the term's evidence is within what a different fold split
/// moves.
pub const POSTURE_MIN_GAIN_MM: f64 = 0.005;

/// Whether a hybrid table's served tier (`hybrid-trilinear`, as `options` build it) gains
/// from the posture term, by cross-validation on the same folds as its served field's
/// choice: `without_mm` is that choice's figure, the term is fitted on each fold's
/// training samples alone, and added when it lowers the mean by at least
/// [`POSTURE_MIN_GAIN_FRACTION`] and [`POSTURE_MIN_GAIN_MM`].
///
/// # Errors
///
/// An evaluation failing.
#[allow(clippy::too_many_arguments)]
pub fn posture_choice(
    samples: &SampleSet,
    robot: &Robot,
    options: &BuildOptions,
    calibrate: &adwi_robot::calibrate::CalibrateOptions,
    folds: usize,
    seed: u64,
    identified: &RefCell<Vec<Calibration>>,
    without_mm: Option<f64>,
) -> Result<PostureChoice, TuneError> {
    let build = BuildOptions {
        posture: adwi_compile::posture::Posture::Fit,
        ..options.clone()
    };
    let (with_mm, _) = cross_validate(
        samples,
        Some(robot),
        calibrate,
        folds,
        seed,
        identified,
        Method::HybridTrilinear,
        build,
    )?;
    let chosen = match (without_mm, with_mm) {
        (Some(without), Some(with)) => {
            let gain = without - with;
            gain >= POSTURE_MIN_GAIN_MM && gain >= POSTURE_MIN_GAIN_FRACTION * without
        }
        _ => false,
    };
    Ok(PostureChoice {
        without_mm,
        with_mm,
        chosen,
    })
}

impl AutoServedField {
    /// `options` with the chosen field (and the kriging's hyperparameters, when chosen)
    /// and the evidence recorded.
    pub fn apply(&self, options: &mut BuildOptions) {
        options.served_field = self.choice.field();
        options.tuning = self.tuning();
        if options.served_field != ServedField::Method {
            options.kriging_choices = self.kriging_choices;
        }
        if self.posture.is_some_and(|p| p.chosen) {
            options.posture = adwi_compile::posture::Posture::Fit;
        }
    }

    /// What the table's header records of it.
    pub fn tuning(&self) -> Option<Tuning> {
        Some(Tuning {
            folds: self.choice.folds as u32,
            cv_mean_mm: self.exact_cv_mean_mm?,
            served_cv_mean_mm: self.choice.chosen_cv_mean_mm(),
            posture_cv_mean_mm: self.posture.filter(|p| p.chosen).and_then(|p| p.with_mm),
        })
    }
}

/// The served field a build chooses when none is asked for: [`served_field`] with
/// [`AUTO_FOLDS`] folds on at most [`AUTO_MAX_SAMPLES`] of the samples, and the exact
/// tier's figure on the same folds.
///
/// # Errors
///
/// An evaluation failing.
pub fn auto_served_field(
    samples: &SampleSet,
    robot: Option<&Robot>,
    options: &BuildOptions,
    calibrate: &adwi_robot::calibrate::CalibrateOptions,
) -> Result<AutoServedField, TuneError> {
    auto_choice(samples, robot, options, calibrate, true, false)
}

/// [`auto_served_field`] (only scoring `options.served_field` unless `choose_field`),
/// then, when `posture` and a robot is given, whether the table gets a posture term
/// ([`posture_choice`], on the same folds and samples).
///
/// # Errors
///
/// An evaluation failing.
pub fn auto_choice(
    samples: &SampleSet,
    robot: Option<&Robot>,
    options: &BuildOptions,
    calibrate: &adwi_robot::calibrate::CalibrateOptions,
    choose_field: bool,
    posture: bool,
) -> Result<AutoServedField, TuneError> {
    if samples.len() < AUTO_MIN_SAMPLES {
        return Err(TuneError::TooFewSamples(samples.len()));
    }
    let subset;
    let samples = if samples.len() > AUTO_MAX_SAMPLES {
        let stride = samples.len() as f64 / AUTO_MAX_SAMPLES as f64;
        let indices: Vec<usize> = (0..AUTO_MAX_SAMPLES)
            .map(|i| (i as f64 * stride) as usize)
            .collect();
        subset = samples.subset(&indices);
        &subset
    } else {
        samples
    };
    let given = [options.served_field];
    let fields: &[ServedField] = if choose_field {
        &[ServedField::Method, ServedField::Kriging]
    } else {
        &given
    };
    // The kriging's hyperparameters, chosen once by likelihood on all these samples (a
    // hybrid table's: of the residuals of the model identified from them), are reused by
    // every fold: each fold then solves its kriging instead of searching again. Without a
    // kriging among the fields tried nothing would use them, and their search is most of a
    // choice's cost.
    let kriging_choices = if fields.iter().any(|&f| f != ServedField::Method) {
        let model = robot
            .map(|r| adwi_robot::calibrate::identify(r, samples, calibrate))
            .transpose()
            .map_err(TuneError::Identify)?
            .map(|c| c.prepared_model());
        adwi_compile::build::kriging_choices(samples, model.as_ref()).map_err(TuneError::Kriging)?
    } else {
        options.kriging_choices
    };
    let options = &BuildOptions {
        kriging_choices,
        ..options.clone()
    };
    let identified = RefCell::new(Vec::new());
    let exact = if robot.is_some() {
        Method::Hybrid
    } else {
        Method::Paper
    };
    let method = BuildOptions {
        served_field: ServedField::Method,
        ..options.clone()
    };
    let (exact_cv_mean_mm, _) = cross_validate(
        samples,
        robot,
        calibrate,
        AUTO_FOLDS,
        0,
        &identified,
        exact,
        method,
    )?;
    let choice = served_field_among(
        fields,
        samples,
        robot,
        options,
        calibrate,
        AUTO_FOLDS,
        0,
        &identified,
    )?;
    let posture = match robot.filter(|_| posture) {
        Some(robot) => {
            let chosen = BuildOptions {
                served_field: choice.field(),
                ..options.clone()
            };
            let without_mm = choice.chosen_cv_mean_mm();
            Some(posture_choice(
                samples,
                robot,
                &chosen,
                calibrate,
                AUTO_FOLDS,
                0,
                &identified,
                without_mm,
            )?)
        }
        None => None,
    };
    Ok(AutoServedField {
        choice,
        exact_cv_mean_mm,
        samples: samples.len(),
        kriging_choices,
        posture,
    })
}

/// The index of the best of `(mean, missed)` scores: the lowest mean among those that miss
/// the fewest, the first on a tie; `None` when none has a mean.
fn best(scores: impl Iterator<Item = (Option<f64>, usize)>) -> Option<usize> {
    scores
        .enumerate()
        .filter_map(|(i, (mean, missed))| mean.map(|m| (i, missed, m)))
        .min_by(|a, b| a.1.cmp(&b.1).then(a.2.total_cmp(&b.2)))
        .map(|(i, _, _)| i)
}
