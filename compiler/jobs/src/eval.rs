//! The evaluation job: methods compared on held-out points, or a table built before
//! scored on a validation set (`tablec eval`, `adwi.evaluate`).

use std::path::{Path, PathBuf};

use adwi_compile::build::BuildOptions;
use adwi_compile::build::ServedField;
use adwi_eval::{EvalOptions, Evaluation, Method, Protocol, SplitRule};
use adwi_identify::agreement::{check_base_frame, check_registered};
use adwi_identify::calibrate::CalibrateOptions;
use adwi_identify::register::{Refined, Registration};
use adwi_output::{Content, OutputPlan};
use adwi_robot::Robot;
use adwi_samples::{ColumnMap, ReadOptions, SampleSet};
use serde::Deserialize;

use crate::args::{
    parsed, Frame, PostureChoice, Reading, ResidualWeightChoice, RobotArgs, ServedFieldChoice,
    TableArgs,
};
use crate::build::Harmonics;
use crate::inputs::{load_robot, Inputs, Source};
use crate::registration::RegistrationSummary;
use crate::series::Series;
use crate::{JobError, Warning};

/// Compare compensation methods on held-out points: every option of `tablec eval`.
#[derive(clap::Args, Deserialize, Debug, Clone)]
#[serde(default)]
pub struct EvalArgs {
    /// The sample database the methods are built from (CSV, as for `tablec build`; several
    /// series are trained together); not with --table.
    #[arg(value_name = "SAMPLES")]
    #[serde(skip)]
    pub samples: Vec<Source>,
    /// A validation set (CSV with errors, the samples' columns): build from all samples,
    /// evaluate at every validation point.
    #[arg(long, value_name = "FILE")]
    #[serde(skip)]
    pub validation: Option<Source>,
    /// Score this table, built before, at the validation points (--validation): its
    /// served field, queried with each point's joint angles when it is hybrid, as a
    /// controller queries it. No samples, methods or table options then.
    #[arg(long = "table", id = "table", value_name = "TABLE")]
    #[serde(rename = "table")]
    pub table_file: Option<PathBuf>,
    /// Use only the first N validation points.
    #[arg(long, value_name = "N")]
    pub limit: Option<usize>,
    /// k-fold cross-validation of the samples alone, with this many folds.
    #[arg(long, value_name = "K")]
    pub folds: Option<usize>,
    /// Seed of the k-fold split.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// With --folds: also hold out by region, as many spatial blocks of the samples'
    /// nominal positions as folds (several series: each series in turn), and report that
    /// figure after the random folds': what poses elsewhere, or the next series, see.
    #[arg(long)]
    pub by_region: bool,
    #[command(flatten)]
    #[serde(flatten)]
    pub reading: Reading,
    /// Methods to compare, comma-separated: paper, paper-trilinear, idw, grid, kriging,
    /// kinematic, hybrid, hybrid-trilinear [default: paper, paper-trilinear, idw, and with
    /// a robot kinematic, hybrid, hybrid-trilinear].
    #[arg(long, value_delimiter = ',', value_name = "LIST")]
    #[serde(deserialize_with = "parsed::list")]
    pub methods: Option<Vec<Method>>,
    /// The robot, for `kinematic` and `hybrid`.
    #[command(flatten)]
    #[serde(flatten)]
    pub robot: RobotArgs,
    /// The frame the measured poses are in, as for `tablec build`: `tracker` registers the
    /// samples (and the validation set, taken in the same tracker frame with the same
    /// probe) to the robot first.
    #[arg(long, value_enum, value_name = "FRAME", default_value_t)]
    pub measured_in: Frame,
    /// With `--measured-in tracker` and `--validation`: register the validation set on its
    /// own (a series measured after the tracker moved): the robot's frame in the new
    /// tracker frame is fitted to the TCP positions the samples' calibration predicts, the
    /// probe kept. Six rigid parameters come from the validation points this way; no
    /// method is trained on their errors.
    #[arg(long)]
    pub register_validation_apart: bool,
    /// Kinematic identification: relative pivot below which a parameter is unidentifiable.
    #[arg(long, default_value_t = CalibrateOptions::default().rank_tolerance)]
    pub rank_tol: f64,
    /// Kinematic identification: keep every parameter the pivoting keeps, even those whose
    /// estimates are implausible or within a few standard errors of zero (by default they
    /// are held at nominal, with the reason reported).
    #[arg(long)]
    pub keep_untrustworthy: bool,
    /// Kinematic identification (kinematic and hybrid methods): also identify each
    /// revolute joint's gravity compliance (µrad/(N·m)). The robot file must give link
    /// masses (mass_kg, com_mm per joint).
    #[arg(long)]
    pub compliance: bool,
    /// Kinematic identification: identify each revolute joint's joint-space terms up to
    /// this harmonic (0 none; 1 `sin q, cos q`; 2 also `sin 2q, cos 2q`), each kept only
    /// where the information criterion (BIC) supports it; `auto` (the default), chosen
    /// among 0, 1 and 2 as `tablec build` chooses it, on the training samples alone (each
    /// split's own in cross-validation).
    #[arg(long, value_name = "N", default_value_t = Harmonics::Auto)]
    #[serde(deserialize_with = "Harmonics::deserialize")]
    pub harmonics: Harmonics,
    #[command(flatten)]
    #[serde(flatten)]
    pub options: TableArgs,
    /// Write the figures as CSV.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Write the whole evaluation (figures, per-point predictions, identification) as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write an HTML report with plots to DIR/index.html.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
}

impl Default for EvalArgs {
    fn default() -> EvalArgs {
        EvalArgs {
            samples: Vec::new(),
            validation: None,
            table_file: None,
            limit: None,
            folds: None,
            seed: 0,
            by_region: false,
            reading: Reading::default(),
            methods: None,
            robot: RobotArgs::default(),
            measured_in: Frame::Base,
            register_validation_apart: false,
            rank_tol: CalibrateOptions::default().rank_tolerance,
            keep_untrustworthy: false,
            compliance: false,
            harmonics: Harmonics::Auto,
            options: TableArgs::default(),
            csv: None,
            json: None,
            report: None,
        }
    }
}

/// What is evaluated: methods built from samples, or a table built before.
// One per job: the samples held inline cost nothing.
#[allow(clippy::large_enum_variant)]
enum Subject {
    Methods {
        series: Series,
        /// The validation set (read once checked, registered when the samples are), or
        /// the folds.
        held_out: HeldOut,
        columns: ColumnMap,
        read: ReadOptions,
        options: Box<EvalOptions>,
    },
    Table {
        table: adwi_runtime::Table<memmap2::Mmap>,
        path: PathBuf,
        points: SampleSet,
    },
}

/// The points an evaluation predicts.
enum HeldOut {
    /// A validation set: its first `limit` points; registered apart with `apart`.
    Validation {
        source: Source,
        limit: Option<usize>,
        apart: bool,
    },
    /// k-fold cross-validation of the samples, and by region when `by_region`.
    Folds {
        folds: usize,
        seed: u64,
        by_region: bool,
    },
}

/// An evaluation checked and loaded, ready to run.
pub struct EvalJob {
    subject: Subject,
    outputs: OutputPlan,
    csv: Option<PathBuf>,
    json: Option<PathBuf>,
    page: Option<PathBuf>,
}

/// What an evaluation found.
#[derive(Debug)]
pub struct Evaluated {
    /// Every method's figures, predictions and identification.
    pub evaluation: Evaluation,
    /// The same methods held out by region or by series (`by_region`).
    pub by_region: Option<Evaluation>,
    /// Tracker-frame samples' registration, and both transforms as an identification of
    /// all samples refined them.
    pub registration: Option<(Registration, Refined)>,
    /// Tracker-frame series after the first: each one's registration.
    pub series_registrations: Vec<Registration>,
    /// A validation set's own registration (registered apart).
    pub validation_registration: Option<Registration>,
    /// The report page written, when asked for.
    pub report_page: Option<PathBuf>,
    /// What the user should know.
    pub warnings: Vec<Warning>,
}

impl Evaluated {
    /// What `tablec eval` prints: the registrations of tracker-frame samples (the
    /// validation set's last), the figures, and those held out by region.
    pub fn text(&self) -> String {
        let mut out = crate::registration::registrations_text(
            self.registration.as_ref(),
            &self.series_registrations,
            true,
        );
        if let Some(v) = &self.validation_registration {
            out.push_str(&RegistrationSummary::of(v, None).validation_text());
        }
        out.push_str(&adwi_eval::output::terminal_table(&self.evaluation));
        if let Some(by_region) = &self.by_region {
            out.push_str(&adwi_eval::output::terminal_table(by_region));
        }
        out
    }

    /// The figures' rows as `tablec eval --csv` writes them, in full precision:
    /// `uncompensated`, then one per method.
    pub fn records(&self) -> Vec<adwi_eval::output::Record> {
        adwi_eval::output::records(&self.evaluation)
    }

    /// The rows of the evaluation held out by region (`by_region`), as [`Self::records`].
    pub fn by_region_records(&self) -> Option<Vec<adwi_eval::output::Record>> {
        self.by_region.as_ref().map(adwi_eval::output::records)
    }

    /// The registrations of tracker-frame samples as the front ends give them: the
    /// samples' (refined by an identification of all of them) and the validation set's
    /// own.
    pub fn registration_summaries(
        &self,
    ) -> (Option<RegistrationSummary>, Option<RegistrationSummary>) {
        (
            (self.registration.as_ref())
                .map(|(r, refined)| RegistrationSummary::of(r, Some(refined))),
            (self.validation_registration.as_ref()).map(|r| RegistrationSummary::of(r, None)),
        )
    }
}

impl EvalJob {
    /// Checks `args`, reads the samples, the validation set, the robot or the table, and
    /// checks the outputs, before any work.
    ///
    /// # Errors
    ///
    /// A refused option or combination, an unreadable input, an output that is an input.
    pub fn new(args: EvalArgs) -> Result<EvalJob, JobError> {
        check(&args)?;
        let mut inputs = Inputs::default();
        inputs.add_sources(&args.samples);
        inputs.add_sources(args.validation.as_ref());
        if let Some(t) = &args.table_file {
            inputs.add(t);
        }
        let file_robot = load_robot(&args.robot, &mut inputs)?;
        let page = args.report.as_ref().map(|dir| dir.join("index.html"));
        let mut outputs = OutputPlan::check(
            &[args.csv.as_deref(), args.json.as_deref()]
                .into_iter()
                .flatten()
                .collect::<Vec<_>>(),
            &inputs.paths(),
        )?;
        if let Some(page) = &page {
            outputs.check_in_new_directory(page, &inputs.paths())?;
        }
        let (columns, read) = args.reading.resolve_for(file_robot.as_ref())?;
        let subject = match &args.table_file {
            Some(path) => {
                // SAFETY: the mapping lives as long as the job; tablec and the Python
                // package replace tables by rename, never in place.
                let table = unsafe { adwi_runtime::Table::open(path) }.map_err(|source| {
                    JobError::Table {
                        path: path.clone(),
                        source,
                    }
                })?;
                let validation = args.validation.as_ref().expect("checked");
                // The table's robot says which joints slide: their columns are lengths.
                let read = adwi_samples::ReadOptions {
                    prismatic_joints: table.prismatic_joints(),
                    ..read
                };
                let mut points = validation.input().samples(&columns, &read)?;
                limit(&mut points, args.limit);
                Subject::Table {
                    table,
                    path: path.clone(),
                    points,
                }
            }
            None => {
                let tracker = args.measured_in == Frame::Tracker;
                let calibrate = CalibrateOptions {
                    rank_tolerance: args.rank_tol,
                    hold_untrustworthy: !args.keep_untrustworthy,
                    compliance: args.compliance,
                    harmonics: args.harmonics.fixed().unwrap_or(0),
                    ..CalibrateOptions::default()
                };
                let series = crate::series::read(
                    &args.samples,
                    &columns,
                    &read,
                    file_robot.as_ref(),
                    tracker,
                )?;
                let held_out = match (&args.validation, args.folds) {
                    (Some(v), None) => {
                        // Read once now, so that a bad file is refused before any work;
                        // registered in `run`, once the samples are. Held to the robot as
                        // the samples are: through the samples' registration when it is
                        // theirs (registered apart, it is registered in `run`).
                        if tracker {
                            let rows = v.input().measurements(&columns, &read)?;
                            if let (Some(r), false) =
                                (&series.registered, args.register_validation_apart)
                            {
                                let points = r.samples(v.input(), &columns, &read)?;
                                check_registered(&r.file_robot, &rows, &points, v.name())?;
                            }
                        } else {
                            let points = v.input().samples(&columns, &read)?;
                            if let Some(robot) = &file_robot {
                                check_base_frame(robot, &points, v.name())?;
                            }
                        }
                        HeldOut::Validation {
                            source: v.clone(),
                            limit: args.limit,
                            apart: args.register_validation_apart,
                        }
                    }
                    (None, Some(folds)) => {
                        // More folds than samples is refused before the tables are sized
                        // (which may merge a million samples), as the split would refuse it.
                        adwi_eval::baselines::stats::check_folds(series.samples.len(), folds)
                            .map_err(adwi_eval::EvalError::from)?;
                        HeldOut::Folds {
                            folds,
                            seed: args.seed,
                            by_region: args.by_region,
                        }
                    }
                    _ => unreachable!("checked"),
                };
                let robot: Option<Robot> = match &series.registered {
                    Some(r) => Some(r.robot.clone()),
                    None => file_robot,
                };
                // The methods' tables serve the field given; `auto` is chosen on each split's
                // training samples for the served-tier methods ([`split_rule`]), the exact
                // tier's serve none.
                let given = args.options.served_field.fixed();
                let build = args
                    .options
                    .build_options(given.unwrap_or(ServedField::Method));
                let split_rule = split_rule(&args.options, robot.is_some(), &build);
                let choose_harmonics = args.harmonics == Harmonics::Auto && robot.is_some();
                let options = EvalOptions {
                    methods: args.methods.clone(),
                    build,
                    robot,
                    calibrate,
                    split_rule,
                    choose_harmonics,
                    ..EvalOptions::default()
                };
                // The tables the methods build are sized now, from every sample: a grid
                // too large is refused before any fold is identified.
                adwi_compile::build::plan(&series.samples, &options.build)?;
                Subject::Methods {
                    series,
                    held_out,
                    columns,
                    read,
                    options: Box::new(options),
                }
            }
        };
        Ok(EvalJob {
            subject,
            outputs,
            csv: args.csv,
            json: args.json,
            page,
        })
    }

    /// Runs the evaluation and writes its outputs, all or none. `command` is the command
    /// line the report quotes.
    ///
    /// # Errors
    ///
    /// The evaluation failing (a method's model cannot be built); an output failing
    /// (nothing is then replaced).
    pub fn run(self, command: &str) -> Result<Evaluated, JobError> {
        let EvalJob {
            subject,
            outputs,
            csv,
            json,
            page,
        } = self;
        let mut warnings = Vec::new();
        let mut series_registrations = Vec::new();
        let (evaluation, by_region, registration, validation_registration) = match subject {
            Subject::Table {
                table,
                path,
                points,
            } => {
                let description = format!(
                    "the table {} ({} samples), evaluated at {} validation points",
                    path.display(),
                    table.sample_count(),
                    points.len()
                );
                let evaluation = adwi_eval::evaluate_table(&table, &points, description)?;
                (evaluation, None, None, None)
            }
            Subject::Methods {
                mut series,
                held_out,
                columns,
                read,
                options,
            } => {
                series.refine(&options.calibrate)?;
                let mut options = options;
                let harmonics = match held_out {
                    HeldOut::Validation { .. } if options.choose_harmonics => {
                        harmonics_on_every_sample(&mut series, &mut options)?
                    }
                    _ => None,
                };
                warnings.extend(series.warnings());
                let Series {
                    samples,
                    labels,
                    registered,
                    others,
                    ..
                } = series;
                series_registrations = others;
                // Several series: a split's residual weight is learned by leaving one out.
                options.series = labels;
                let mut registered_apart = None;
                let mut regions = None;
                let protocol = match held_out {
                    HeldOut::Validation {
                        source,
                        limit: n,
                        apart,
                    } => {
                        // Registered apart, into the frame of the samples' calibration
                        // alone, as the kinematic method makes it.
                        let (mut points, made) = adwi_identify::measured::read_validation(
                            source.input(),
                            &columns,
                            &read,
                            registered.as_ref(),
                            apart.then_some((&samples, &options.calibrate)),
                        )?;
                        registered_apart = made;
                        limit(&mut points, n);
                        Protocol::Validation(points)
                    }
                    HeldOut::Folds {
                        folds,
                        seed,
                        by_region,
                    } => {
                        regions = by_region.then(|| match &options.series {
                            Some(series) => Protocol::Series(series.clone()),
                            None => Protocol::Blocks { folds, seed },
                        });
                        Protocol::KFold { folds, seed }
                    }
                };
                let mut evaluation = adwi_eval::evaluate(&samples, &protocol, &options)?;
                evaluation.harmonics_choices.extend(harmonics);
                let by_region = match &regions {
                    Some(regions) => Some(adwi_eval::evaluate(&samples, regions, &options)?),
                    None => None,
                };
                if let Some(c) = evaluation.identified.first() {
                    warnings.extend(crate::calibration_warnings(c));
                }
                // The transforms as an identification of all samples refines them: the one
                // registering the validation set apart, or that of the validation protocol
                // (its only split is every sample), or one made here for k-fold.
                let all_samples = match (&registered_apart, &protocol) {
                    (Some((_, c)), _) => Some(c),
                    (None, Protocol::Validation(_)) => evaluation.identified.first(),
                    (None, _) => None,
                };
                let registration = match registered {
                    Some(r) => {
                        let refined = r.refined_by(&samples, &options.calibrate, all_samples)?;
                        Some((r.registration, refined))
                    }
                    None => None,
                };
                (
                    evaluation,
                    by_region,
                    registration,
                    registered_apart.map(|(r, _)| r),
                )
            }
        };
        let mut contents: Vec<(&Path, Vec<u8>)> = Vec::new();
        if let Some(path) = &csv {
            contents.push((path, adwi_eval::output::csv(&evaluation).into_bytes()));
        }
        if let Some(path) = &page {
            let html = adwi_eval::report::html(&evaluation, command)
                .map_err(|e| JobError::NonFinite(format!("cannot draw the report: {e}")))?;
            contents.push((path, html.into_bytes()));
        }
        // The JSON holds every point's prediction (a gigabyte of text for a million
        // samples): written as it is encoded, never held beside the evaluation.
        let write_json = |w: &mut dyn std::io::Write| {
            adwi_eval::output::write_json(w, &evaluation).map_err(std::io::Error::other)
        };
        let mut borrowed: Vec<(&Path, Content<'_>)> = contents
            .iter()
            .map(|(p, b)| (*p, Content::Bytes(&b[..])))
            .collect();
        if let Some(path) = &json {
            borrowed.push((path, Content::Written(&write_json)));
        }
        outputs.write_contents(&borrowed)?;
        Ok(Evaluated {
            evaluation,
            by_region,
            registration,
            series_registrations,
            validation_registration,
            report_page: page,
            warnings,
        })
    }
}

/// With a validation set the one split is every sample: the harmonic count is chosen on
/// them here, before the validation set is registered to the model (with its terms, as
/// `--harmonics N` registers it); several series are registered again to the model with
/// the terms chosen. The splits then take the count as given.
fn harmonics_on_every_sample(
    series: &mut Series,
    options: &mut EvalOptions,
) -> Result<Option<adwi_eval::SplitHarmonics>, JobError> {
    options.choose_harmonics = false;
    let Some((choice, folds)) = adwi_eval::choice::harmonics_choice_and_folds(
        &series.samples,
        options.robot.as_ref(),
        &options.build,
        &options.calibrate,
        series.labels.as_deref(),
    ) else {
        return Ok(None);
    };
    options.calibrate.harmonics = choice.chosen;
    if choice.chosen > 0 {
        series.refine(&options.calibrate)?;
    }
    // The split's table choices are made on the same samples and folds, unless the series
    // were registered again (then their samples differ, and the folds are identified anew).
    options.split_fold_models = vec![folds];
    Ok(Some(adwi_eval::SplitHarmonics { split: 0, choice }))
}

/// What a split's served-tier table is decided on its training samples, as a build
/// decides what it is not given: the served field when `auto`, and a hybrid table's
/// posture term and residual weight when `auto` (without a joint screen, as a build). `None` when everything
/// is given.
fn split_rule(table: &TableArgs, robot: bool, build: &BuildOptions) -> Option<SplitRule> {
    let served_tier = build.joint_radius_deg.unwrap_or(0.0) == 0.0;
    let rule = SplitRule {
        choose_field: table.served_field == ServedFieldChoice::Auto,
        choose_posture: table.posture == PostureChoice::Auto && robot && served_tier,
        weigh_residual: table.residual_weight == ResidualWeightChoice::Auto && robot && served_tier,
    };
    (rule.choose_field || rule.choose_posture || rule.weigh_residual).then_some(rule)
}

/// The first `n` points, when limited.
fn limit(points: &mut SampleSet, n: Option<usize>) {
    if let Some(n) = n {
        let n = n.min(points.len());
        *points = points.subset(&(0..n).collect::<Vec<_>>());
    }
}

/// The combinations an evaluation refuses, before reading anything.
fn check(args: &EvalArgs) -> Result<(), JobError> {
    let refuse = |text: &str| Err(JobError::Options(text.into()));
    if args.table_file.is_some() {
        if args.validation.is_none() {
            return refuse("--table is scored at a validation set: give --validation");
        }
        if !args.samples.is_empty() || args.folds.is_some() {
            return refuse(
                "--table scores a table built before at --validation: give no samples \
                 file and no --folds",
            );
        }
        if args.methods.is_some()
            || args.robot.robot.is_some()
            || args.options != TableArgs::default()
        {
            return refuse(
                "--table scores the table as it was built: no --methods, --robot or \
                 table options",
            );
        }
        if args.measured_in != Frame::Base {
            return refuse(
                "--table reads the validation set in the robot's base frame (the \
                 table's)",
            );
        }
    } else {
        if args.samples.is_empty() {
            return refuse("give the samples file (or --table TABLE to score a table)");
        }
        match (&args.validation, args.folds) {
            (Some(_), Some(_)) => {
                return refuse(
                    "give a validation set (--validation) or a fold count (--folds), not both",
                )
            }
            (None, None) => {
                return refuse(
                    "give a validation set (--validation FILE) or a fold count (--folds K)",
                )
            }
            (None, Some(folds)) if folds < 2 => {
                return Err(JobError::option("folds", "give at least 2 folds"))
            }
            _ => {}
        }
    }
    if let Some(0) = args.limit {
        return Err(JobError::option("limit", "give at least 1 point"));
    }
    if args.by_region && args.folds.is_none() {
        return refuse("--by-region holds out regions as folds: give --folds K");
    }
    if args.limit.is_some() && args.validation.is_none() {
        return refuse("--limit keeps the first validation points: give --validation");
    }
    let robot = args.robot.robot.is_some();
    if args.measured_in == Frame::Tracker && !robot {
        return refuse(
            "--measured-in tracker needs the robot file the \
             measurements are registered to (--robot)",
        );
    }
    if args.register_validation_apart {
        if args.validation.is_none() {
            return refuse(
                "--register-validation-apart needs a validation \
                 set (--validation)",
            );
        }
        if args.measured_in != Frame::Tracker {
            return refuse(
                "--register-validation-apart needs --measured-in \
                 tracker",
            );
        }
    }
    if args.compliance && !robot {
        return refuse(
            "--compliance is identified with the robot's geometry: give the robot \
             file (--robot)",
        );
    }
    if !(args.rank_tol.is_finite() && args.rank_tol > 0.0 && args.rank_tol < 1.0) {
        return Err(JobError::option(
            "rank_tol",
            format!("{} is not a relative pivot between 0 and 1", args.rank_tol),
        ));
    }
    if let Some(methods) = &args.methods {
        if let Some(m) = methods.iter().find(|m| m.needs_robot()).filter(|_| !robot) {
            return Err(JobError::option(
                "methods",
                format!("{m} needs the robot file (--robot)"),
            ));
        }
    }
    Ok(())
}
