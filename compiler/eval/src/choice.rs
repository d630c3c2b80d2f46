//! The table's choices by evidence: cross-validation of candidate options on the training
//! samples alone, beside the evaluation it runs. Validation points never take part: a
//! choice made on them would be fitted to them.
//!
//! [`CrossValidation`] holds what every candidate is scored on — the samples, the robot of
//! a hybrid table, the identification options and the folds — and each fold's
//! identification once made, so that every candidate on the same folds reuses it.
//!
//! - [`CrossValidation::tune`] (`tablec build --tune`): the neighbour count `k` and the
//!   radius ε as a multiple of the sample spacing, scored by the mean position residual of
//!   the method the table serves (`paper`, or `hybrid` with a robot). A candidate that
//!   leaves points unpredicted never beats one that predicts more: the choice is the lowest
//!   mean among those that miss the fewest.
//! - [`CrossValidation::served_field`]: what the served field's nodes hold
//!   ([`ServedField`]), the method's own answer or kriging with a nugget of the samples'
//!   errors, scored on the served tier (`paper-trilinear`, or `hybrid-trilinear`); a table
//!   with a joint screen has no served tier and keeps the method's.
//! - [`CrossValidation::posture`]: whether a hybrid table gains from the posture term.
//! - [`CrossValidation::choose_harmonics`]: the identification's harmonic count of the
//!   joint-space terms (`--harmonics auto`), scored by the model alone, made first: every
//!   later choice's folds are identified with the count chosen.
//!
//! [`default_choices`] is what every build makes by default, without `--tune`, and what an
//! evaluation makes on each split's training samples ([`crate::SplitRule`]): the build's
//! own parameters, at most [`AUTO_MAX_SAMPLES`] samples, held out as use holds them out
//! ([`CrossValidation::matching_use`]): random folds leave every held-out sample among
//! training samples a few millimetres away, where a field that interpolates its
//! neighbours' noise looks better than on poses measured elsewhere or on another day.

use std::cell::RefCell;

use adwi_compile::build::{BuildOptions, ServedField, Tuning};
use adwi_compile::nugget_kriging::GivenChoices;
use adwi_compile::posture::Posture;
use adwi_identify::calibrate::{identify, CalibrateError, CalibrateOptions, Calibration};
use adwi_robot::Robot;
use adwi_runtime::chain::JointKind;
use adwi_runtime::joint_terms::{beyond_range, TERMS_MARGIN_RAD};
use adwi_samples::SampleSet;
use rayon::prelude::*;

use crate::baselines::Fold;
use crate::{evaluate, EvalError, EvalOptions, Method, MethodResult, Protocol};

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

/// Why a choice could not be made.
#[derive(Debug, thiserror::Error)]
pub enum TuneError {
    /// The samples have no spacing to scale radii by (fewer than two positions).
    #[error("the samples have no spacing to scale the candidate radii by")]
    NoSpacing,
    /// Fewer than two folds.
    #[error("tuning needs at least 2 folds")]
    Folds,
    /// A fold's identification failed (a hybrid table's kriging is fitted to the residuals
    /// of its model).
    #[error("cannot identify the robot from a fold's training samples")]
    Identify(#[source] CalibrateError),
    /// A fold's kriging hyperparameters could not be chosen.
    #[error("cannot fit the kriging of a fold's served field")]
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

/// The folds every candidate of a choice is scored on, and what they share: one value
/// instead of the same parameters handed to every scoring function.
#[derive(Debug)]
pub struct CrossValidation<'a> {
    samples: &'a SampleSet,
    robot: Option<&'a Robot>,
    /// The identification every candidate's folds are identified with (the harmonic count
    /// [`CrossValidation::choose_harmonics`] chose, once it has).
    calibrate: CalibrateOptions,
    /// How samples are held out: random folds, spatial blocks or whole series.
    protocol: Protocol,
    /// How many splits the protocol makes.
    folds: usize,
    /// Each split's training and held-out samples.
    splits: Vec<Fold>,
    /// Each fold's identification of a hybrid table's model with each identification's
    /// options, made once, before the first evaluation with them, and reused by every one.
    identified: RefCell<Vec<(CalibrateOptions, Vec<Calibration>)>>,
    /// Each fold's kriging hyperparameters, searched once by likelihood on its training
    /// samples alone ([`FOLD_SEARCH_SAMPLES`] at most) and given to every kriging field of
    /// its tables: no held-out point takes part in the field it is scored by.
    kriging: RefCell<Vec<(CalibrateOptions, Vec<Option<GivenChoices>>)>>,
    /// Each method's results on these folds with the options its tables were built with:
    /// a later choice that scores the same (the residual weight of the field and posture
    /// chosen before it) takes them instead of building the folds' tables again.
    scored: RefCell<Vec<(CalibrateOptions, Method, BuildOptions, MethodResult)>>,
}

impl<'a> CrossValidation<'a> {
    /// `folds`-fold cross-validation of `samples` split with `seed`; a hybrid table's when
    /// `robot` is given, identified with `calibrate`.
    ///
    /// # Errors
    ///
    /// [`TuneError::Folds`] for fewer than two folds.
    pub fn new(
        samples: &'a SampleSet,
        robot: Option<&'a Robot>,
        calibrate: CalibrateOptions,
        folds: usize,
        seed: u64,
    ) -> Result<CrossValidation<'a>, TuneError> {
        if folds < 2 {
            return Err(TuneError::Folds);
        }
        CrossValidation::held_out(samples, robot, calibrate, Protocol::KFold { folds, seed })
    }

    /// Cross-validation of `samples` by `protocol` (random folds, spatial blocks or whole
    /// series held out; not a validation set).
    ///
    /// # Errors
    ///
    /// [`TuneError::Folds`] for a protocol of fewer than two splits or a validation set.
    pub fn held_out(
        samples: &'a SampleSet,
        robot: Option<&'a Robot>,
        calibrate: CalibrateOptions,
        protocol: Protocol,
    ) -> Result<CrossValidation<'a>, TuneError> {
        let folds = match &protocol {
            Protocol::Validation(_) => return Err(TuneError::Folds),
            Protocol::KFold { folds, .. } | Protocol::Blocks { folds, .. } => *folds,
            Protocol::Series(series) => {
                let mut labels = series.clone();
                labels.sort_unstable();
                labels.dedup();
                labels.len()
            }
        };
        if folds < 2 {
            return Err(TuneError::Folds);
        }
        let (splits, _) = protocol.splits(samples).ok_or(TuneError::Folds)??;
        Ok(CrossValidation {
            samples,
            robot,
            calibrate,
            protocol,
            folds,
            splits,
            identified: RefCell::new(Vec::new()),
            kriging: RefCell::new(Vec::new()),
            scored: RefCell::new(Vec::new()),
        })
    }

    /// The cross-validation whose held-out points are what a table's use holds out: with
    /// `series` labelling two or more series, each series predicted from the others (as
    /// the next series will be); else, for a hybrid table (`robot` given), each of
    /// [`AUTO_FOLDS`] spatial blocks from the others (as poses elsewhere in the workspace
    /// will be); else [`AUTO_FOLDS`] random folds (seed 0): a position-only table answers
    /// only within ε of its samples, so a held-out region would score nothing.
    ///
    /// # Errors
    ///
    /// None in practice ([`CrossValidation::held_out`] with at least two splits).
    pub fn matching_use(
        samples: &'a SampleSet,
        robot: Option<&'a Robot>,
        calibrate: CalibrateOptions,
        series: Option<Vec<usize>>,
    ) -> Result<CrossValidation<'a>, TuneError> {
        let protocol = match series.filter(|s| crate::folds::group_splits(s).is_some()) {
            Some(series) => Protocol::Series(series),
            None if robot.is_some() => Protocol::Blocks {
                folds: AUTO_FOLDS,
                seed: 0,
            },
            None => Protocol::KFold {
                folds: AUTO_FOLDS,
                seed: 0,
            },
        };
        CrossValidation::held_out(samples, robot, calibrate, protocol)
    }

    /// How these folds hold points out.
    pub fn held_out_by(&self) -> HeldOut {
        match self.protocol {
            Protocol::Series(_) => HeldOut::Series,
            Protocol::Blocks { .. } => HeldOut::Blocks,
            Protocol::KFold { .. } | Protocol::Validation(_) => HeldOut::RandomFolds,
        }
    }

    /// The fold count.
    pub fn folds(&self) -> usize {
        self.folds
    }

    /// The method a table serves exactly: the hybrid with a robot, else the paper's.
    fn exact_method(&self) -> Method {
        if self.robot.is_some() {
            Method::Hybrid
        } else {
            Method::Paper
        }
    }

    /// The served tier of [`CrossValidation::exact_method`]'s table.
    fn served_method(&self) -> Method {
        if self.robot.is_some() {
            Method::HybridTrilinear
        } else {
            Method::PaperTrilinear
        }
    }

    /// One candidate's cross-validated mean position residual of `method` (`None` when no
    /// held-out point was predicted) and its missed points, on the same folds as every
    /// other; the first evaluation identifies each fold's model, every later one reuses it.
    ///
    /// # Errors
    ///
    /// The evaluation failing.
    pub fn score(
        &self,
        method: Method,
        build: BuildOptions,
    ) -> Result<(Option<f64>, usize), TuneError> {
        let n = self.samples.len();
        let result = self.results(&[method], &build)?.pop().flatten();
        Ok((
            (result.as_ref()).and_then(|r| r.position_mm.as_ref().map(|p| p.mean_norm)),
            result.map_or(n, |r| n - r.predicted()),
        ))
    }

    /// Each of `methods`' results on these folds with tables built as `build` says: those
    /// scored before with the same options as they were, the others evaluated together
    /// (each fold's identification made once). `None` for a method the evaluation did not
    /// run.
    fn results(
        &self,
        methods: &[Method],
        build: &BuildOptions,
    ) -> Result<Vec<Option<MethodResult>>, TuneError> {
        self.results_with(&self.calibrate, methods, build)
    }

    /// [`CrossValidation::results`] with the folds' models identified with `calibrate`.
    fn results_with(
        &self,
        calibrate: &CalibrateOptions,
        methods: &[Method],
        build: &BuildOptions,
    ) -> Result<Vec<Option<MethodResult>>, TuneError> {
        let known = |method: Method| {
            (self.scored.borrow().iter())
                .find(|(c, m, b, _)| c == calibrate && *m == method && b == build)
                .map(|(_, _, _, r)| r.clone())
        };
        let missing: Vec<Method> = methods
            .iter()
            .copied()
            .filter(|&m| known(m).is_none())
            .collect();
        if !missing.is_empty() {
            let identified = self.identified(calibrate)?;
            let kriging =
                if build.served_field != ServedField::Method && build.kriging_choices.is_none() {
                    self.fold_kriging(calibrate, &identified)?
                } else {
                    Vec::new()
                };
            let options = EvalOptions {
                methods: Some(missing.clone()),
                build: build.clone(),
                robot: self.robot.cloned(),
                calibrate: *calibrate,
                identified,
                split_kriging_choices: kriging,
                ..EvalOptions::default()
            };
            let evaluation = evaluate(self.samples, &self.protocol, &options)?;
            let mut scored = self.scored.borrow_mut();
            for method in missing {
                if let Some(result) = evaluation.method(method) {
                    scored.push((*calibrate, method, build.clone(), result.clone()));
                }
            }
        }
        Ok(methods.iter().map(|&m| known(m)).collect())
    }

    /// Each fold's identification of a hybrid table's model from its training samples
    /// with `calibrate` (none without a robot), made once, the folds side by side.
    fn identified(&self, calibrate: &CalibrateOptions) -> Result<Vec<Calibration>, TuneError> {
        let Some(robot) = self.robot else {
            return Ok(Vec::new());
        };
        let known = |identified: &[(CalibrateOptions, Vec<Calibration>)]| {
            (identified.iter())
                .find(|(c, _)| c == calibrate)
                .map(|(_, folds)| folds.clone())
        };
        if let Some(folds) = known(&self.identified.borrow()) {
            return Ok(folds);
        }
        let samples = self.samples;
        let identified = (self.splits.par_iter())
            .map(|fold| identify(robot, &samples.subset(&fold.train), calibrate))
            .collect::<Result<Vec<_>, _>>()
            .map_err(TuneError::Identify)?;
        (self.identified.borrow_mut()).push((*calibrate, identified.clone()));
        Ok(identified)
    }

    /// The folds' models identified with the options every later candidate is identified
    /// with (the harmonic count chosen, once it has been), if they have been.
    fn fold_models(&self) -> Option<FoldModels> {
        let identified = (self.identified.borrow().iter())
            .find(|(c, _)| *c == self.calibrate)
            .map(|(_, folds)| folds.clone())?;
        Some(FoldModels {
            calibrate: self.calibrate,
            train: self.splits.iter().map(|f| f.train.clone()).collect(),
            inputs: self.inputs_fingerprint()?,
            identified,
        })
    }

    /// The digest of what the folds' models are identified from: the samples, every value,
    /// and the robot (its whole description, as `Debug` spells it, each number to the bit);
    /// `None` without a robot.
    fn inputs_fingerprint(&self) -> Option<[u64; 2]> {
        let robot = self.robot?;
        let robot = xxhash_rust::xxh3::xxh3_64(format!("{robot:?}").as_bytes());
        Some([self.samples.fingerprint(), robot])
    }

    /// Takes `models` as the folds' identification with their options, when they were
    /// identified on these samples and folds (else nothing): the same identifications, not
    /// made again.
    fn adopt(&self, models: &FoldModels) {
        let same = self.inputs_fingerprint() == Some(models.inputs)
            && models.train.len() == self.splits.len()
            && (models.train.iter().zip(&self.splits)).all(|(t, f)| *t == f.train);
        let mut identified = self.identified.borrow_mut();
        if same && !identified.iter().any(|(c, _)| *c == models.calibrate) {
            identified.push((models.calibrate, models.identified.clone()));
        }
    }

    /// Each fold's kriging hyperparameters, searched by likelihood on its training samples
    /// alone (a hybrid table's: on the residuals of the model `identified` from them), on
    /// at most [`FOLD_SEARCH_SAMPLES`] of them evenly strided; searched once, the folds
    /// side by side.
    fn fold_kriging(
        &self,
        calibrate: &CalibrateOptions,
        identified: &[Calibration],
    ) -> Result<Vec<Option<GivenChoices>>, TuneError> {
        let known = (self.kriging.borrow().iter())
            .find(|(c, _)| c == calibrate)
            .map(|(_, searched)| searched.clone());
        if let Some(known) = known {
            return Ok(known);
        }
        let samples = self.samples;
        let searched = (self.splits.par_iter().enumerate())
            .map(|(i, fold)| {
                let n = fold.train.len();
                let m = FOLD_SEARCH_SAMPLES.min(n);
                let picked: Vec<usize> = (0..m)
                    .map(|j| fold.train[(j as u128 * n as u128 / m as u128) as usize])
                    .collect();
                let model = identified.get(i).map(Calibration::prepared_model);
                adwi_compile::build::kriging_choices(&samples.subset(&picked), model.as_ref())
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(TuneError::Kriging)?;
        (self.kriging.borrow_mut()).push((*calibrate, searched.clone()));
        Ok(searched)
    }

    /// Chooses the identification's harmonic count (`--harmonics auto`) among `counts`,
    /// fewest terms first, on these folds, and identifies every later candidate's folds
    /// with the count chosen: the one of lowest held-out mean, or a count of fewer terms
    /// whose mean is within the noise of that one's (the standard error of the two means'
    /// difference, point by point: more terms must improve the figure by more than what a
    /// different draw of the points moves it). A count whose folds cannot be identified
    /// (more terms than a fold's samples determine) is no candidate.
    ///
    /// Each count is scored by its model alone (`kinematic`), not by the model with the
    /// residual field: the terms are part of the model, which is what every pose of use
    /// receives, inside the samples' volume and beyond it, while the residual field only
    /// reaches poses near the samples and its weight is learned afterwards on these same
    /// folds, with the count chosen ([`CrossValidation::residual_weight`]): a field scored
    /// here would reward a count for what the field, not the model, explains where the
    /// folds' samples are dense. It is also the cheap score: one identification per fold
    /// and count, and no table.
    ///
    /// # Errors
    ///
    /// The first count's identification or an evaluation failing; no count predicting a
    /// held-out point.
    pub fn choose_harmonics(&mut self, counts: &[u8]) -> Result<HarmonicsChoice, TuneError> {
        // Whole series held out judge the terms only where they answer within their
        // evidence: at the held-out poses whose joints lie within the angles the other
        // series span (beyond, a term is held at its range's end and the table flags the
        // answer `joints`). Where most poses lie beyond, as when the series cover
        // different turns of a joint, the count is chosen on spatial blocks of every
        // series' samples instead.
        let reach = self.series_reach();
        if let Some(reach) = reach.as_ref().filter(|r| !r.judges()) {
            let protocol = Protocol::Blocks {
                folds: AUTO_FOLDS,
                seed: 0,
            };
            let mut blocks =
                CrossValidation::held_out(self.samples, self.robot, self.calibrate, protocol)?;
            let choice = blocks.choose_harmonics(counts)?;
            self.calibrate.harmonics = choice.chosen;
            return Ok(HarmonicsChoice {
                series_reach: Some(reach.summary()),
                ..choice
            });
        }
        let n = self.samples.len();
        let model_alone = BuildOptions::default();
        let mut candidates = Vec::with_capacity(counts.len());
        let mut residuals = Vec::with_capacity(counts.len());
        for (i, &harmonics) in counts.iter().enumerate() {
            let calibrate = CalibrateOptions {
                harmonics,
                ..self.calibrate
            };
            let result = match self.results_with(&calibrate, &[Method::Kinematic], &model_alone) {
                Ok(mut results) => results.pop().flatten(),
                Err(TuneError::Identify(_)) if i > 0 => None,
                Err(e) => return Err(e),
            };
            // Each held-out point's position residual norm, mm (`None` where not
            // predicted, or not judged: beyond the terms' reach).
            let norms: Vec<Option<f64>> = match &result {
                Some(r) => (r.predictions.iter())
                    .zip(&self.samples.error_mm)
                    .enumerate()
                    .map(|(i, (p, e))| {
                        let p = p.as_ref()?;
                        if reach.as_ref().is_some_and(|r| !r.within[i]) {
                            return None;
                        }
                        let d = [0, 1, 2].map(|a| e[a] - p.position_error_mm[a]);
                        Some((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
                    })
                    .collect(),
                None => vec![None; n],
            };
            let cv_mean_mm = match (&result, &reach) {
                (Some(r), None) => r.position_mm.as_ref().map(|p| p.mean_norm),
                (Some(_), Some(_)) => mean_of(&norms),
                (None, _) => None,
            };
            candidates.push(HarmonicsCandidate {
                harmonics,
                cv_mean_mm,
                noise_mm: None,
                missed: result.map_or(n, |r| n - r.predicted()),
            });
            residuals.push(norms);
        }
        let lowest = best(candidates.iter().map(|c| (c.cv_mean_mm, c.missed)))
            .ok_or(TuneError::NothingPredicted)?;
        for (candidate, norms) in candidates.iter_mut().zip(&residuals) {
            if candidate.cv_mean_mm.is_some() {
                candidate.noise_mm = paired_standard_error(norms, &residuals[lowest]);
            }
        }
        let (best_mean, best_missed) = (candidates[lowest].cv_mean_mm, candidates[lowest].missed);
        let chosen = (0..lowest)
            .find(|&i| {
                let c = &candidates[i];
                match (c.cv_mean_mm, best_mean, c.noise_mm) {
                    (Some(mean), Some(best), Some(noise)) => {
                        c.missed <= best_missed && mean - best <= noise
                    }
                    _ => false,
                }
            })
            .unwrap_or(lowest);
        self.calibrate.harmonics = candidates[chosen].harmonics;
        Ok(HarmonicsChoice {
            folds: self.folds,
            held_out: self.held_out_by(),
            candidates,
            chosen: self.calibrate.harmonics,
            series_reach: reach.map(|r| r.summary()),
        })
    }

    /// With whole series held out and joint values given, which held-out poses lie within
    /// the joint-space terms' reach: every revolute joint within
    /// [`TERMS_MARGIN_RAD`] of the angles the other series span, around the circle
    /// ([`beyond_range`], as a table's query flags `joints`). `None` for other folds.
    fn series_reach(&self) -> Option<ReachOfSeries> {
        if !matches!(self.protocol, Protocol::Series(_)) {
            return None;
        }
        let robot = self.robot?;
        let joints = self.samples.joint_count()?;
        let revolute: Vec<usize> = (0..joints)
            .filter(|&j| robot.joint_kind(j) == JointKind::Revolute)
            .collect();
        let mut within = vec![false; self.samples.len()];
        for fold in &self.splits {
            let ranges: Vec<(usize, f64, f64)> = (revolute.iter())
                .map(|&j| {
                    let angles = fold.train.iter().filter_map(|&i| {
                        let q = self.samples.joints_rad(i)?;
                        q.get(j).copied()
                    });
                    let (lo, hi) = angles
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
                            (lo.min(q), hi.max(q))
                        });
                    (j, lo, hi)
                })
                .collect();
            for &i in &fold.test {
                let Some(q) = self.samples.joints_rad(i) else {
                    continue;
                };
                within[i] = ranges.iter().all(|&(j, lo, hi)| {
                    lo <= hi
                        && match beyond_range(q[j], lo, hi) {
                            None => true,
                            Some((_, by)) => by <= TERMS_MARGIN_RAD,
                        }
                });
            }
        }
        Some(ReachOfSeries { within })
    }

    /// The identification options every candidate's folds are identified with.
    pub fn calibrate(&self) -> &CalibrateOptions {
        &self.calibrate
    }

    /// The weight `s` in [0, 1] of a hybrid table's residual field that these folds'
    /// held-out points favour: the model identified on each fold's training samples plus
    /// `s` times the residual its served tier (`hybrid-trilinear`, as `options` build it)
    /// adds, at the lowest mean position residual over the points both predict. The mean
    /// norm is convex in `s`; the minimum is found by golden-section search and compared
    /// with both ends. `None` without a robot or a point both predict.
    ///
    /// # Errors
    ///
    /// The evaluation failing.
    pub fn residual_weight(
        &self,
        options: &BuildOptions,
    ) -> Result<Option<ResidualWeight>, TuneError> {
        if self.robot.is_none() {
            return Ok(None);
        }
        let mut results = self
            .results(&[Method::Kinematic, Method::HybridTrilinear], options)?
            .into_iter();
        let (Some(Some(model)), Some(Some(hybrid))) = (results.next(), results.next()) else {
            return Ok(None);
        };
        // Per point: what the model leaves, and what the residual field adds to it.
        let points: Vec<([f64; 3], [f64; 3])> = (model.predictions.iter())
            .zip(&hybrid.predictions)
            .zip(&self.samples.error_mm)
            .filter_map(|((m, h), e)| {
                let (m, h) = (m.as_ref()?, h.as_ref()?);
                let left = [0, 1, 2].map(|a| e[a] - m.position_error_mm[a]);
                let field = [0, 1, 2].map(|a| h.position_error_mm[a] - m.position_error_mm[a]);
                Some((left, field))
            })
            .collect();
        Ok(
            weight_minimising(&points).map(|(weight, weighted_mm)| ResidualWeight {
                weight,
                weighted_mm,
                model_mm: mean_left(&points, 0.0),
                full_mm: mean_left(&points, 1.0),
                points: points.len(),
                splits: self.folds,
                by_series: self.held_out_by() == HeldOut::Series,
            }),
        )
    }

    /// Chooses `k` and ε, the other options as in `base`; then, when `choose_field`, the
    /// served field with them ([`CrossValidation::served_field`]), and when
    /// `choose_posture` (a hybrid table), the posture term.
    ///
    /// # Errors
    ///
    /// [`TuneError`].
    pub fn tune(
        &self,
        base: &BuildOptions,
        choose_field: bool,
        choose_posture: bool,
    ) -> Result<TuneReport, TuneError> {
        let spacing = self.samples.spacing_mm().ok_or(TuneError::NoSpacing)?;
        let method = self.exact_method();
        let mut candidates = Vec::new();
        for &k in &K_CANDIDATES {
            for &spacings in &RADIUS_CANDIDATES_SPACINGS {
                let mut build = base.clone();
                build.method.max_neighbours = k;
                build.method.radius_mm = Some(spacings * spacing);
                let (cv_mean_mm, missed) = self.score(method, build)?;
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
            folds: self.folds as u32,
            cv_mean_mm: candidates[chosen].cv_mean_mm.unwrap_or(0.0),
            served_cv_mean_mm: None,
            posture_cv_mean_mm: None,
        });
        let served = if choose_field {
            let choice = self.served_field(&options)?;
            options.served_field = choice.field();
            if let Some(tuning) = &mut options.tuning {
                tuning.served_cv_mean_mm = choice.chosen_cv_mean_mm();
            }
            choice.candidates
        } else {
            Vec::new()
        };
        let posture = if choose_posture && self.robot.is_some() {
            // The chosen field's figure on these folds, scored above when it was chosen.
            let without_mm = match options.tuning.and_then(|t| t.served_cv_mean_mm) {
                Some(mean) => Some(mean),
                None => self
                    .choose_served_field(&[options.served_field], &options)?
                    .chosen_cv_mean_mm(),
            };
            let posture = self.posture(&options, without_mm)?;
            if posture.chosen {
                options.posture = Posture::Fit;
                if let Some(tuning) = &mut options.tuning {
                    tuning.served_cv_mean_mm = posture.without_mm;
                    tuning.posture_cv_mean_mm = posture.with_mm;
                }
            }
            Some(posture)
        } else {
            None
        };
        Ok(TuneReport {
            method,
            folds: self.folds,
            candidates,
            chosen,
            served,
            posture,
            options,
        })
    }

    /// What the served field's nodes should hold, scored on the served tier: the method's
    /// own answer against kriging with a nugget (which turns with the tool's axis where its
    /// likelihood says so: one kind), the other options as in `options`. A table with a
    /// joint screen has no served tier: no candidate, the method's.
    ///
    /// # Errors
    ///
    /// An evaluation failing.
    pub fn served_field(&self, options: &BuildOptions) -> Result<ServedChoice, TuneError> {
        if options.joint_radius_deg.is_some_and(|r| r > 0.0) {
            return Ok(ServedChoice::default());
        }
        self.choose_served_field(&[ServedField::Method, ServedField::Kriging], options)
    }

    /// [`CrossValidation::served_field`] among `fields`: each is tried in `options` in
    /// place of the field it holds.
    ///
    /// # Errors
    ///
    /// An evaluation failing.
    pub fn choose_served_field(
        &self,
        fields: &[ServedField],
        options: &BuildOptions,
    ) -> Result<ServedChoice, TuneError> {
        let method = self.served_method();
        let mut candidates = Vec::new();
        for &field in fields {
            let build = BuildOptions {
                served_field: field,
                ..options.clone()
            };
            let (cv_mean_mm, missed) = self.score(method, build)?;
            candidates.push(ServedCandidate {
                field,
                cv_mean_mm,
                missed,
            });
        }
        // The same cells are served either way; ties keep the method's own answer.
        let chosen = best(candidates.iter().map(|c| (c.cv_mean_mm, c.missed)));
        Ok(ServedChoice {
            folds: self.folds,
            held_out: self.held_out_by(),
            candidates,
            chosen,
        })
    }

    /// Whether a hybrid table's served tier (`hybrid-trilinear`, as `options` build it)
    /// gains from the posture term on these folds: `without_mm` is the figure of the field
    /// chosen on them, the term is fitted on each fold's training samples alone, and added
    /// when it lowers the mean by at least [`POSTURE_MIN_GAIN_FRACTION`] and
    /// [`POSTURE_MIN_GAIN_MM`].
    ///
    /// # Errors
    ///
    /// An evaluation failing (a position-only cross-validation has no hybrid table).
    pub fn posture(
        &self,
        options: &BuildOptions,
        without_mm: Option<f64>,
    ) -> Result<PostureChoice, TuneError> {
        let build = BuildOptions {
            posture: Posture::Fit,
            ..options.clone()
        };
        let (with_mm, _) = self.score(Method::HybridTrilinear, build)?;
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
}

/// How a cross-validation holds points out ([`CrossValidation::held_out_by`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum HeldOut {
    /// Random folds of the pooled samples.
    #[default]
    RandomFolds,
    /// Spatial blocks of the samples' nominal positions.
    Blocks,
    /// Whole series, each in turn.
    Series,
}

impl HeldOut {
    /// The splits in words, for `folds` of them.
    pub fn describe(self, folds: usize) -> String {
        match self {
            HeldOut::RandomFolds => format!("{folds}-fold cross-validation"),
            HeldOut::Blocks => format!("{folds} spatial blocks, each predicted from the others"),
            HeldOut::Series => format!("{folds} series, each predicted from the others"),
        }
    }
}

/// The served fields tried and the one chosen ([`CrossValidation::served_field`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ServedChoice {
    /// The folds.
    pub folds: usize,
    /// How the folds hold points out.
    pub held_out: HeldOut,
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

/// The residual weight held-out points favour ([`CrossValidation::residual_weight`]), and
/// the evidence.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ResidualWeight {
    /// The weight `s` of the residual field, in [0, 1].
    pub weight: f64,
    /// The held-out mean position residual with the weight, mm: what the build expects
    /// on new poses.
    pub weighted_mm: f64,
    /// The same with the model alone (`s` = 0), mm.
    pub model_mm: f64,
    /// The same with the whole residual field (`s` = 1), mm.
    pub full_mm: f64,
    /// The held-out points both predicted.
    pub points: usize,
    /// The splits they were held out by.
    pub splits: usize,
    /// Whether the splits are series (each left out in turn), not spatial blocks.
    pub by_series: bool,
}

/// The mean norm of `left − s · field` over `points`, mm.
fn mean_left(points: &[([f64; 3], [f64; 3])], s: f64) -> f64 {
    let sum: f64 = points
        .iter()
        .map(|(left, field)| {
            let r = [0, 1, 2].map(|a| left[a] - s * field[a]);
            (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt()
        })
        .sum();
    sum / points.len() as f64
}

/// The `s` in [0, 1] minimising [`mean_left`], and that mean; `None` for no point. Golden
/// section search on the convex mean, then the better of its minimum and either end (a
/// minimum at an end is then exact).
fn weight_minimising(points: &[([f64; 3], [f64; 3])]) -> Option<(f64, f64)> {
    if points.is_empty() {
        return None;
    }
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (0.0f64, 1.0f64);
    let mut c = b - ratio * (b - a);
    let mut d = a + ratio * (b - a);
    let (mut fc, mut fd) = (mean_left(points, c), mean_left(points, d));
    // 60 steps narrow [0, 1] to below 1e-12.
    for _ in 0..60 {
        if fc <= fd {
            b = d;
            d = c;
            fd = fc;
            c = b - ratio * (b - a);
            fc = mean_left(points, c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + ratio * (b - a);
            fd = mean_left(points, d);
        }
    }
    let middle = (a + b) / 2.0;
    [0.0, 1.0, middle]
        .into_iter()
        .map(|s| (s, mean_left(points, s)))
        .filter(|(_, mean)| mean.is_finite())
        .min_by(|x, y| x.1.total_cmp(&y.1))
}

/// The harmonic counts of the joint-space terms a build chooses among by default
/// (`--harmonics auto`, [`CrossValidation::choose_harmonics`]).
pub const HARMONICS_CANDIDATES: [u8; 3] = [0, 1, 2];

/// One harmonic count's cross-validated figures ([`CrossValidation::choose_harmonics`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct HarmonicsCandidate {
    /// The count: each revolute joint's terms up to this harmonic.
    pub harmonics: u8,
    /// Mean position residual of the model alone over the predicted held-out points, mm;
    /// `None` when the folds could not be identified with this count.
    pub cv_mean_mm: Option<f64>,
    /// The standard error of this count's mean less the lowest mean, the points paired,
    /// mm (0 for the lowest).
    pub noise_mm: Option<f64>,
    /// Held-out points not predicted.
    pub missed: usize,
}

/// The harmonic count chosen, and the evidence ([`CrossValidation::choose_harmonics`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct HarmonicsChoice {
    /// The splits.
    pub folds: usize,
    /// How they hold points out.
    pub held_out: HeldOut,
    /// Every count tried, fewest terms first.
    pub candidates: Vec<HarmonicsCandidate>,
    /// The count chosen.
    pub chosen: u8,
    /// With several series: how many held-out poses lay within the joint angles the other
    /// series span when each series was predicted from the others (the terms' reach). The
    /// counts are scored at those alone; where they are fewer than half, on spatial blocks
    /// of every series' samples instead (`held_out` says which).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub series_reach: Option<SeriesReach>,
}

/// The held-out poses of whole series within the joint angles the other series span: where
/// a model identified on those answers within its evidence, the joint-space terms
/// included ([`HarmonicsChoice::series_reach`], [`AutoServedField::series_reach`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SeriesReach {
    /// Held-out poses, every series' together.
    pub held_out_poses: usize,
    /// Of those, the poses whose every revolute joint lies within the angles the other
    /// series span (to [`TERMS_MARGIN_RAD`], around the circle).
    pub within_range: usize,
}

impl SeriesReach {
    /// Whether the series judge the counts: at least half their held-out poses within
    /// reach.
    pub fn judges(&self) -> bool {
        2 * self.within_range >= self.held_out_poses && self.within_range > 0
    }
}

/// Per sample, whether it lies within the joint angles of the other series, the reach of
/// the terms identified without its series ([`CrossValidation::series_reach`]). Each
/// sample is held out once, by its series, so every sample is a held-out pose.
struct ReachOfSeries {
    within: Vec<bool>,
}

impl ReachOfSeries {
    fn summary(&self) -> SeriesReach {
        SeriesReach {
            held_out_poses: self.within.len(),
            within_range: self.within.iter().filter(|&&w| w).count(),
        }
    }

    fn judges(&self) -> bool {
        self.summary().judges()
    }
}

/// The mean of the values given, `None` for none.
fn mean_of(values: &[Option<f64>]) -> Option<f64> {
    let given: Vec<f64> = values.iter().flatten().copied().collect();
    (!given.is_empty()).then(|| given.iter().sum::<f64>() / given.len() as f64)
}

/// Each fold's model as one cross-validation identified it, for another cross-validation
/// of the same samples on the same folds to take instead of identifying them again
/// ([`Ask::folds`]): an evaluation's split chooses its harmonic count on its training
/// samples, then its table's choices on the same samples and folds with the count chosen,
/// as a build makes both on one [`CrossValidation`].
#[derive(Clone, Debug)]
pub struct FoldModels {
    /// The identification's options the folds' models were identified with.
    calibrate: CalibrateOptions,
    /// Each fold's training samples (indices into the samples cross-validated).
    train: Vec<Vec<usize>>,
    /// The digests of the samples cross-validated and of the robot
    /// ([`CrossValidation::inputs_fingerprint`]): with `train`, what makes another
    /// cross-validation the same one.
    inputs: [u64; 2],
    /// Each fold's model.
    identified: Vec<Calibration>,
}

/// The standard error of the mean of `a − b` over the points both give, mm; `None` for
/// fewer than two such points.
fn paired_standard_error(a: &[Option<f64>], b: &[Option<f64>]) -> Option<f64> {
    let d: Vec<f64> = a
        .iter()
        .zip(b)
        .filter_map(|(a, b)| Some((*a)? - (*b)?))
        .collect();
    if d.len() < 2 {
        return None;
    }
    let m = d.len() as f64;
    let mean = d.iter().sum::<f64>() / m;
    let variance = d.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (m - 1.0);
    Some((variance / m).sqrt())
}

/// The most of a fold's training samples its kriging's hyperparameters are searched on
/// (evenly strided): the search is cubic in its samples, and a fold's, made on 400 instead
/// of up to 1,000 as the table's own, keeps a choice's five searches within a fifth of the
/// table's one. The field is then fitted to all of the fold's training samples.
pub const FOLD_SEARCH_SAMPLES: usize = 400;

/// The fewest samples the served field's choice by default cross-validates: with fewer,
/// the folds are too small to tell two fields apart, and the method's own answer is served.
pub const AUTO_MIN_SAMPLES: usize = 25;
/// The folds of the served field's choice by default ([`default_choices`]).
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
    /// The posture term's cross-validation, when it was asked for (a hybrid table).
    pub posture: Option<PostureChoice>,
    /// The residual field's weight learned from held-out series or regions, when it was
    /// asked for (a hybrid table).
    pub residual_weight: Option<ResidualWeight>,
    /// The identification's harmonic count chosen first, on the same folds, when it was
    /// asked for (a hybrid table): every other choice's folds are identified with it, and
    /// so is the table's model.
    pub harmonics: Option<HarmonicsChoice>,
    /// With several series and a robot: how many held-out poses lie within the joint angles
    /// the other series span. Where few do, the held-out figures above are the model's
    /// extrapolation to other angles, not what poses within the samples' angles see.
    pub series_reach: Option<SeriesReach>,
}

/// The posture term's cross-validation ([`CrossValidation::posture`]).
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

impl AutoServedField {
    /// Held-out points the chosen field answered, and the points held out (each sample
    /// cross-validated is held out once); none answered when no field was chosen.
    pub fn answered(&self) -> (usize, usize) {
        let held_out = self.samples;
        let missed = (self.choice.chosen).map_or(held_out, |i| self.choice.candidates[i].missed);
        (held_out.saturating_sub(missed), held_out)
    }

    /// `options` with the chosen field and the evidence recorded. A kriging field's
    /// hyperparameters are not among them: each fold searched its own on its training
    /// samples, and the table searches its own on all of them.
    pub fn apply(&self, options: &mut BuildOptions) {
        options.served_field = self.choice.field();
        options.tuning = self.tuning();
        if self.posture.is_some_and(|p| p.chosen) {
            options.posture = Posture::Fit;
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

/// What a table's served field holds (and whether a hybrid table has the posture term),
/// resolved before the table is encoded: chosen by the samples' cross-validation, with the
/// evidence, or fixed (given, or the method's own where nothing is chosen).
#[derive(Clone, Debug, PartialEq)]
pub enum ServedFieldDecision {
    /// Chosen by [`default_choices`].
    Chosen(Box<AutoServedField>),
    /// Not chosen: this field, no posture term beyond what the options say.
    Fixed(ServedField),
}

impl ServedFieldDecision {
    /// The field the table serves.
    pub fn field(&self) -> ServedField {
        match self {
            ServedFieldDecision::Chosen(auto) => auto.choice.field(),
            ServedFieldDecision::Fixed(field) => *field,
        }
    }

    /// The cross-validation that chose it, when one did.
    pub fn evidence(&self) -> Option<&AutoServedField> {
        match self {
            ServedFieldDecision::Chosen(auto) => Some(auto),
            ServedFieldDecision::Fixed(_) => None,
        }
    }

    /// The weight of a hybrid table's residual field: the one learned, else 1.
    pub fn residual_weight(&self) -> f64 {
        self.evidence()
            .and_then(|auto| auto.residual_weight)
            .map_or(1.0, |w| w.weight)
    }

    /// `options` with the decided field (and with the chosen one's evidence and the
    /// posture term).
    pub fn apply(&self, options: &mut BuildOptions) {
        match self {
            ServedFieldDecision::Chosen(auto) => auto.apply(options),
            ServedFieldDecision::Fixed(field) => options.served_field = *field,
        }
    }
}

/// What a build decides by default that it is not given ([`default_choices`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct Ask<'c> {
    /// Choose the served field (else only `options.served_field` is scored).
    pub field: bool,
    /// Decide a hybrid table's posture term.
    pub posture: bool,
    /// Learn a hybrid table's residual weight ([`CrossValidation::residual_weight`]).
    pub weight: bool,
    /// Choose the identification's harmonic count among [`HARMONICS_CANDIDATES`]
    /// ([`CrossValidation::choose_harmonics`]), before the other choices, which are then
    /// made with it (a hybrid table).
    pub harmonics: bool,
    /// The series of each sample (its index among the files read), when several: every
    /// choice is then made by leaving one series out at a time
    /// ([`CrossValidation::matching_use`]).
    pub series: Option<&'c [usize]>,
    /// The folds' models an earlier cross-validation of the same samples identified
    /// ([`harmonics_choice_and_folds`]), taken where they are the ones asked for.
    pub folds: Option<&'c FoldModels>,
}

/// The harmonic count alone, chosen as [`default_choices`] chooses it (`series` as
/// [`Ask::series`]); `None` where it cannot be chosen (too few samples, a failed
/// identification): the caller then keeps the count it was given. With it, the folds'
/// models of the count chosen: the choices made after it on the same samples
/// ([`default_choices`] with [`Ask::folds`]) take them instead of identifying the folds
/// again.
pub fn harmonics_choice_and_folds(
    samples: &SampleSet,
    robot: Option<&Robot>,
    options: &BuildOptions,
    calibrate: &CalibrateOptions,
    series: Option<&[usize]>,
) -> Option<(HarmonicsChoice, Option<FoldModels>)> {
    let ask = Ask {
        harmonics: true,
        series,
        ..Ask::default()
    };
    let (auto, folds) =
        choices_keeping_folds(samples, robot, options, calibrate, ask, true).ok()?;
    Some((auto.harmonics?, folds))
}

/// The choice a build makes by default, on at most [`AUTO_MAX_SAMPLES`] of the samples
/// (evenly strided), all on the same folds, those that match the table's use
/// ([`CrossValidation::matching_use`]: each series from the others, else each spatial
/// block from the others, else random folds for a position-only table): the exact tier
/// with `options`; the served field among the method's and kriging's when `ask.field`
/// (else `options.served_field` alone); when `ask.posture` and a robot is given, the
/// posture term; when `ask.weight` and a robot is given, the residual field's weight.
/// When `ask.harmonics` and a robot is given, the identification's harmonic count is
/// chosen first ([`CrossValidation::choose_harmonics`]) and the other choices' folds are
/// identified with it; asked for alone, no table is scored.
///
/// A kriging field's hyperparameters are searched by likelihood on each fold's training
/// samples alone, as the table's own are on all of them: no held-out point takes part in
/// the field it is predicted by. The posture term is fitted after the table it corrects,
/// on the same residuals, so its folds' fields reuse those searches.
///
/// # Errors
///
/// Too few samples, an identification or a kriging's fit failing, an evaluation failing.
pub fn default_choices(
    samples: &SampleSet,
    robot: Option<&Robot>,
    options: &BuildOptions,
    calibrate: &CalibrateOptions,
    ask: Ask<'_>,
) -> Result<AutoServedField, TuneError> {
    choices_keeping_folds(samples, robot, options, calibrate, ask, false).map(|(auto, _)| auto)
}

/// [`default_choices`], with the folds' models identified with the options the choices
/// ended with (the harmonic count chosen), when any were and `keep_folds` asks for them:
/// a caller that drops them does not pay for their copy and digests.
fn choices_keeping_folds(
    samples: &SampleSet,
    robot: Option<&Robot>,
    options: &BuildOptions,
    calibrate: &CalibrateOptions,
    ask: Ask<'_>,
    keep_folds: bool,
) -> Result<(AutoServedField, Option<FoldModels>), TuneError> {
    if samples.len() < AUTO_MIN_SAMPLES {
        return Err(TuneError::TooFewSamples(samples.len()));
    }
    let subset;
    let (samples, series) = if samples.len() > AUTO_MAX_SAMPLES {
        let stride = samples.len() as f64 / AUTO_MAX_SAMPLES as f64;
        let indices: Vec<usize> = (0..AUTO_MAX_SAMPLES)
            .map(|i| (i as f64 * stride) as usize)
            .collect();
        subset = samples.subset(&indices);
        let series = ask
            .series
            .map(|labels| indices.iter().map(|&i| labels[i]).collect::<Vec<_>>());
        (&subset, series)
    } else {
        (samples, ask.series.map(<[usize]>::to_vec))
    };
    let mut cv = CrossValidation::matching_use(samples, robot, *calibrate, series)?;
    if let Some(folds) = ask.folds {
        cv.adopt(folds);
    }
    let harmonics = if ask.harmonics && robot.is_some() {
        Some(cv.choose_harmonics(&HARMONICS_CANDIDATES)?)
    } else {
        None
    };
    // The harmonic count's choice found it already, on the same series and folds.
    let series_reach = match &harmonics {
        Some(h) => h.series_reach,
        None => cv.series_reach().map(|r| r.summary()),
    };
    if !(ask.field || ask.posture || ask.weight) {
        let auto = AutoServedField {
            choice: ServedChoice::default(),
            exact_cv_mean_mm: None,
            samples: samples.len(),
            posture: None,
            residual_weight: None,
            harmonics,
            series_reach,
        };
        return Ok((auto, keep_folds.then(|| cv.fold_models()).flatten()));
    }
    let given = [options.served_field];
    let fields: &[ServedField] = if ask.field {
        &[ServedField::Method, ServedField::Kriging]
    } else {
        &given
    };
    let method = BuildOptions {
        served_field: ServedField::Method,
        ..options.clone()
    };
    let (exact_cv_mean_mm, _) = cv.score(cv.exact_method(), method)?;
    let choice = cv.choose_served_field(fields, options)?;
    let chosen = BuildOptions {
        served_field: choice.field(),
        ..options.clone()
    };
    let posture = if ask.posture && robot.is_some() {
        Some(cv.posture(&chosen, choice.chosen_cv_mean_mm())?)
    } else {
        None
    };
    let residual_weight = if ask.weight && robot.is_some() {
        let chosen = BuildOptions {
            posture: if posture.is_some_and(|p| p.chosen) {
                Posture::Fit
            } else {
                chosen.posture
            },
            ..chosen
        };
        cv.residual_weight(&chosen)?
    } else {
        None
    };
    let auto = AutoServedField {
        choice,
        exact_cv_mean_mm,
        samples: samples.len(),
        posture,
        residual_weight,
        harmonics,
        series_reach,
    };
    Ok((auto, keep_folds.then(|| cv.fold_models()).flatten()))
}

/// `samples` with the residual `calibration` leaves of each error scaled by `weight`: the
/// error of the model plus `weight` times the rest (position and, when the samples carry
/// them, orientation). A hybrid table compiled from them holds the residual field scaled
/// by `weight` beside the same model, in the same format: how a learned weight is applied.
///
/// # Panics
///
/// When the samples carry no joint angles (a hybrid table's samples do).
pub fn weighted_residuals(
    samples: &SampleSet,
    calibration: &Calibration,
    weight: f64,
) -> SampleSet {
    let mut out = samples.clone();
    for i in 0..samples.len() {
        let joints = samples
            .joints_rad(i)
            .expect("a hybrid table's samples have joints");
        let (p, r) = calibration.predict_error(joints);
        let e = samples.error_mm[i];
        out.error_mm[i] = [0, 1, 2].map(|a| p[a] + weight * (e[a] - p[a]));
        if let Some(rotation) = &mut out.rotation_error_rad {
            let m = rotation[i];
            rotation[i] = [0, 1, 2].map(|a| r[a] + weight * (m[a] - r[a]));
        }
    }
    out
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

#[cfg(test)]
mod tests {
    use super::*;
    use adwi_samples::Joints;

    #[test]
    fn best_prefers_fewest_missed_then_lowest_mean_then_first() {
        let scores = [
            (Some(0.2), 1),
            (Some(0.3), 0),
            (Some(0.1), 2),
            (Some(0.3), 0),
        ];
        assert_eq!(best(scores.into_iter()), Some(1));
        assert_eq!(best([(None, 0), (Some(1.0), 3)].into_iter()), Some(1));
        assert_eq!(best([(None, 0)].into_iter()), None);
    }

    #[test]
    fn residual_weight_is_the_fraction_of_the_field_that_held_out_points_show() {
        let field = [[0.3, -0.1, 0.2], [0.0, 0.4, -0.2], [-0.5, 0.1, 0.1]];
        // What the model leaves is 40 % of what the field adds: the weight is 0.4.
        let points: Vec<_> = field.iter().map(|f| (f.map(|v| 0.4 * v), *f)).collect();
        let (weight, mean) = weight_minimising(&points).unwrap();
        assert!((weight - 0.4).abs() < 1e-6, "{weight}");
        assert!(mean < 1e-6);
        // A field that carries nothing gets weight 0, one that carries all of it 1.
        let none: Vec<_> = field.iter().map(|f| ([0.0; 3], *f)).collect();
        assert_eq!(weight_minimising(&none).unwrap().0, 0.0);
        let all: Vec<_> = field.iter().map(|f| (*f, *f)).collect();
        assert_eq!(weight_minimising(&all).unwrap().0, 1.0);
        // Against it: the weight stays in [0, 1].
        let against: Vec<_> = field.iter().map(|f| (f.map(|v| -v), *f)).collect();
        assert_eq!(weight_minimising(&against).unwrap().0, 0.0);
        assert!(weight_minimising(&[]).is_none());
    }

    /// Every third sample of the shipped KR150-2 lattice (243), and its robot.
    fn kr150_third() -> (SampleSet, Robot) {
        let robot_path = adwi_robot::model::shipped_robot_path("kr150-2");
        let samples = adwi_samples::read_samples(
            &robot_path.parent().unwrap().join("samples.csv"),
            &adwi_samples::ColumnMap::default(),
        )
        .unwrap();
        let every_third: Vec<usize> = (0..samples.len()).step_by(3).collect();
        (
            samples.subset(&every_third),
            Robot::load(&robot_path).unwrap(),
        )
    }

    #[test]
    fn choices_hold_out_series_else_regions_of_a_hybrid_table_else_random_folds() {
        let (samples, robot) = kr150_third();
        let calibrate = CalibrateOptions::default();
        let by = |robot: Option<&Robot>, series: Option<Vec<usize>>| {
            let cv = CrossValidation::matching_use(&samples, robot, calibrate, series).unwrap();
            (cv.held_out_by(), cv.folds())
        };
        let halves: Vec<usize> = (0..samples.len())
            .map(|i| usize::from(i % 2 == 1))
            .collect();
        assert_eq!(by(Some(&robot), Some(halves.clone())), (HeldOut::Series, 2));
        assert_eq!(by(None, Some(halves)), (HeldOut::Series, 2));
        // One series labelled is no series to hold out.
        let one = Some(vec![0; samples.len()]);
        assert_eq!(by(Some(&robot), one.clone()), (HeldOut::Blocks, AUTO_FOLDS));
        assert_eq!(by(Some(&robot), None), (HeldOut::Blocks, AUTO_FOLDS));
        assert_eq!(by(None, one), (HeldOut::RandomFolds, AUTO_FOLDS));
    }

    /// The kriging candidate's figure is the one its folds give when each searches the
    /// kriging's hyperparameters on its own training samples: no held-out point takes part
    /// in the field it is predicted by (hyperparameters searched on all the samples once
    /// and given to every fold gave another figure).
    #[test]
    fn a_kriging_candidate_is_fitted_on_each_folds_training_samples_alone() {
        let (samples, _) = kr150_third();
        let options = BuildOptions::default();
        let ask = Ask {
            field: true,
            ..Ask::default()
        };
        let auto =
            default_choices(&samples, None, &options, &CalibrateOptions::default(), ask).unwrap();
        let kriging = (auto.choice.candidates.iter())
            .find(|c| c.field == ServedField::Kriging)
            .unwrap();
        let each_fold_its_own = evaluate(
            &samples,
            &Protocol::KFold {
                folds: AUTO_FOLDS,
                seed: 0,
            },
            &EvalOptions {
                methods: Some(vec![Method::PaperTrilinear]),
                build: BuildOptions {
                    served_field: ServedField::Kriging,
                    kriging_choices: None,
                    ..options.clone()
                },
                ..EvalOptions::default()
            },
        )
        .unwrap();
        let expected = each_fold_its_own.method(Method::PaperTrilinear).unwrap();
        assert_eq!(
            kriging.cv_mean_mm,
            expected.position_mm.as_ref().map(|p| p.mean_norm)
        );
        assert_eq!(kriging.missed, samples.len() - expected.predicted());
        // Searched on all of them and given to every fold, the held-out points take part.
        let all = adwi_compile::build::kriging_choices(&samples, None).unwrap();
        let cv = CrossValidation::new(&samples, None, CalibrateOptions::default(), 5, 0).unwrap();
        let given = BuildOptions {
            kriging_choices: all,
            ..options
        };
        let (leaked, _) = cv
            .score(
                Method::PaperTrilinear,
                BuildOptions {
                    served_field: ServedField::Kriging,
                    ..given
                },
            )
            .unwrap();
        assert_ne!(kriging.cv_mean_mm, leaked);
    }

    /// The table choices made with the fold models of the harmonic choice on the same
    /// samples are the choices made identifying the folds again, to the bit; fold models
    /// of other samples are not taken.
    #[test]
    fn shared_fold_models_give_the_choices_identified_again() {
        let (samples, robot) = kr150_third();
        let options = BuildOptions::default();
        let calibrate = CalibrateOptions::default();
        let (harmonics, folds) =
            harmonics_choice_and_folds(&samples, Some(&robot), &options, &calibrate, None).unwrap();
        let folds = folds.unwrap();
        assert_eq!(folds.identified.len(), AUTO_FOLDS);
        assert_eq!(folds.calibrate.harmonics, harmonics.chosen);
        let calibrate = CalibrateOptions {
            harmonics: harmonics.chosen,
            ..calibrate
        };
        let ask = |folds| Ask {
            field: true,
            weight: true,
            folds,
            ..Ask::default()
        };
        let again = default_choices(&samples, Some(&robot), &options, &calibrate, ask(None));
        let shared = default_choices(
            &samples,
            Some(&robot),
            &options,
            &calibrate,
            ask(Some(&folds)),
        );
        assert_eq!(shared.unwrap(), again.unwrap());
        // Of other samples (the first 200): not the same folds, not adopted.
        let other = samples.subset(&(0..200).collect::<Vec<_>>());
        let cv = CrossValidation::matching_use(&other, Some(&robot), calibrate, None).unwrap();
        cv.adopt(&folds);
        assert!(cv.identified.borrow().is_empty());
        // The same position errors at other joint values: other samples.
        let mut moved = samples.clone();
        let joints = moved.joints.as_ref().expect("joint values");
        let mut rows = Joints::new(joints.row(0).len());
        for i in 0..joints.len() {
            let mut row = joints.row(i).to_vec();
            row[0] += if i == 0 { 1e-9 } else { 0.0 };
            rows.push(&row);
        }
        moved.joints = Some(rows);
        let cv = CrossValidation::matching_use(&moved, Some(&robot), calibrate, None).unwrap();
        cv.adopt(&folds);
        assert!(cv.identified.borrow().is_empty());
        // The same samples with another robot (its tool 1 mm longer).
        let mut tool = robot.tool();
        tool.translation_mm[2] += 1.0;
        let other_robot = robot
            .with_parts(
                robot.name.clone(),
                robot.base(),
                tool,
                robot.home().to_vec(),
            )
            .unwrap();
        let cv =
            CrossValidation::matching_use(&samples, Some(&other_robot), calibrate, None).unwrap();
        cv.adopt(&folds);
        assert!(cv.identified.borrow().is_empty());
        let cv = CrossValidation::matching_use(&samples, Some(&robot), calibrate, None).unwrap();
        cv.adopt(&folds);
        assert_eq!(cv.identified.borrow().len(), 1);
    }

    /// Series held out judge the harmonic count at their poses within the terms' reach;
    /// series that cover different angles of a joint cannot, and the count is chosen on
    /// spatial blocks of all of them, as for one series.
    #[test]
    fn series_beyond_each_others_angles_leave_the_count_to_blocks() {
        let (samples, robot) = kr150_third();
        let calibrate = CalibrateOptions::default();
        let q1 = |i: usize| samples.joints_rad(i).unwrap()[0];
        let mut sorted: Vec<f64> = (0..samples.len()).map(q1).collect();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        // The two halves of the first joint's angles: apart (but for those within the
        // margin of the other half).
        let apart: Vec<usize> = (0..samples.len())
            .map(|i| usize::from(q1(i) >= median))
            .collect();
        // Alternate samples: the same angles.
        let mixed: Vec<usize> = (0..samples.len()).map(|i| i % 2).collect();
        let reach = |series: &[usize]| {
            let cv = CrossValidation::matching_use(
                &samples,
                Some(&robot),
                calibrate,
                Some(series.to_vec()),
            )
            .unwrap();
            cv.series_reach().unwrap().summary()
        };
        let mixed_reach = reach(&mixed);
        assert_eq!(mixed_reach.held_out_poses, samples.len());
        assert!(mixed_reach.judges(), "{mixed_reach:?}");
        let apart_reach = reach(&apart);
        assert!(!apart_reach.judges(), "{apart_reach:?}");
        assert!(
            apart_reach.within_range < samples.len() / 4,
            "{apart_reach:?}"
        );
        // Not asked of blocks or random folds.
        let blocks = CrossValidation::matching_use(&samples, Some(&robot), calibrate, None);
        assert!(blocks.unwrap().series_reach().is_none());

        // Counts 0 and 1: the second harmonic adds time, not a case.
        let counts = [0, 1];
        let mut by_series =
            CrossValidation::matching_use(&samples, Some(&robot), calibrate, Some(apart)).unwrap();
        let choice = by_series.choose_harmonics(&counts).unwrap();
        let mut by_blocks =
            CrossValidation::matching_use(&samples, Some(&robot), calibrate, None).unwrap();
        let expected = by_blocks.choose_harmonics(&counts).unwrap();
        assert_eq!(choice.held_out, HeldOut::Blocks);
        assert_eq!(choice.series_reach, Some(apart_reach));
        assert_eq!(choice.candidates, expected.candidates);
        assert_eq!(choice.chosen, expected.chosen);
        assert_eq!(by_series.calibrate().harmonics, expected.chosen);
    }

    #[test]
    fn cross_validation_refuses_fewer_than_two_folds() {
        let samples = SampleSet::default();
        assert!(matches!(
            CrossValidation::new(&samples, None, CalibrateOptions::default(), 1, 0),
            Err(TuneError::Folds)
        ));
    }
}
