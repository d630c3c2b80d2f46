//! The build job: samples into a table (`tablec build`, `adwi.build`).
//!
//! With a robot the table is hybrid: the robot's kinematic deviations are identified from
//! the samples (their joints j1..jn) and the table holds the calibrated model and the
//! residuals it leaves, so that it corrects every target the arm reaches. Without one it is
//! a position-only table of the measured errors.

use std::path::PathBuf;
use std::time::Instant;

use adwi_compile::build::{compile_plan, BuildReport, Plan, ServedField};
use adwi_eval::choice::{
    default_choices, Ask, CrossValidation, HarmonicsChoice, ServedFieldDecision, TuneReport,
    HARMONICS_CANDIDATES,
};
use adwi_identify::calibrate::{identify, CalibrateOptions, Calibration};
use adwi_identify::register::{Refined, Registration};
use adwi_output::OutputPlan;
use adwi_robot::Robot;
use adwi_samples::{RepeatReport, SampleSet};
use serde::Deserialize;

use crate::args::{Frame, Reading, RobotArgs, TableArgs};
use crate::args::{PostureChoice, ResidualWeightChoice, ServedFieldChoice};
use crate::inputs::{load_robot, Inputs, Source};
use crate::series::Series;
use crate::{JobError, Progress, Warning};

/// Compile a sample database into a correction table: every option of `tablec build`.
#[derive(clap::Args, Deserialize, Debug, Clone)]
#[serde(default)]
pub struct BuildArgs {
    /// The sample database (CSV: x,y,z and dx,dy,dz or mx,my,mz; see docs/samples.md);
    /// several series make one table (in a tracker's frame, each with its own
    /// tracker-to-base transform).
    #[arg(required = true, value_name = "SAMPLES")]
    #[serde(skip)]
    pub samples: Vec<Source>,
    /// Where to write the table (written complete beside it, then renamed into place).
    #[arg(short, long, value_name = "TABLE")]
    #[serde(skip)]
    pub output: PathBuf,
    #[command(flatten)]
    #[serde(flatten)]
    pub reading: Reading,
    #[command(flatten)]
    #[serde(flatten)]
    pub table: TableArgs,
    /// With a robot file (`--robot`), the table is hybrid: the robot's kinematic
    /// deviations are identified from the samples (which need j1..jn), and the table holds
    /// the calibrated model and the residuals it leaves. Query it with the target's joint
    /// angles.
    #[command(flatten)]
    #[serde(flatten)]
    pub robot: RobotArgs,
    /// Accepted for compatibility: a robot file makes the table hybrid.
    #[arg(long, hide = true)]
    pub hybrid: bool,
    /// Identify each revolute joint's gravity compliance (µrad/(N·m)) with the geometry:
    /// the arm deflected by the gravity torque of the links it carries. The robot file
    /// must give link masses (mass_kg, com_mm per joint).
    #[arg(long)]
    pub compliance: bool,
    /// Kinematic identification: identify each revolute joint's joint-space terms up to
    /// this harmonic (0 none; 1 `sin q, cos q`; 2 also `sin 2q, cos 2q`), each kept only
    /// where the information criterion (BIC) supports it; `auto` (the default), the count
    /// of 0, 1 or 2 whose model predicts held-out samples best (each series from the others
    /// when several are given, else each of 5 spatial blocks from the others), fewer terms
    /// unless more improve it by more than its noise.
    #[arg(long, value_name = "N", default_value_t = Harmonics::Auto)]
    #[serde(deserialize_with = "Harmonics::deserialize")]
    pub harmonics: Harmonics,
    /// The frame the measured poses are in: `base` (the robot's), or `tracker` (a laser
    /// tracker's own frame: joints j1..jn and measured mx,my,mz, optionally a measured
    /// orientation; the tracker-to-base and flange-to-probe transforms are registered
    /// first and refined by the identification). Needs the robot.
    #[arg(long, value_enum, value_name = "FRAME", default_value_t)]
    pub measured_in: Frame,
    /// Choose k and ε by k-fold cross-validation on these samples alone (k in 4, 8, 12; ε
    /// of 1.5, 2 or 3 sample spacings), scoring the method the table serves (the hybrid
    /// with a robot); then, with those, what the served field holds. The choices and the
    /// cross-validated mean are recorded in the table (`tablec inspect`). The other
    /// options apply to every candidate.
    #[arg(long)]
    pub tune: bool,
    /// Folds of --tune's cross-validation.
    #[arg(long, default_value_t = 5, value_name = "K")]
    pub tune_folds: usize,
    /// Worker threads [default: all cores]; the table is the same for any count.
    #[arg(long)]
    pub threads: Option<usize>,
}

impl Default for BuildArgs {
    fn default() -> BuildArgs {
        BuildArgs {
            samples: Vec::new(),
            output: PathBuf::new(),
            reading: Reading::default(),
            table: TableArgs::default(),
            robot: RobotArgs::default(),
            hybrid: false,
            compliance: false,
            harmonics: Harmonics::Auto,
            measured_in: Frame::Base,
            tune: false,
            tune_folds: 5,
            threads: None,
        }
    }
}

/// The identification's joint-space terms as asked for (`--harmonics`): a count, or
/// chosen by cross-validation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Harmonics {
    /// Chosen among 0, 1 and 2 on held-out samples that match use
    /// ([`adwi_eval::choice::CrossValidation::choose_harmonics`]).
    #[default]
    Auto,
    /// Each revolute joint's terms up to this harmonic (0, 1 or 2).
    Count(u8),
}

impl Harmonics {
    /// The count given, `None` for `auto`.
    pub fn fixed(self) -> Option<u8> {
        match self {
            Harmonics::Auto => None,
            Harmonics::Count(n) => Some(n),
        }
    }

    /// `auto`, or a count as a number or its text (the Python front end's `harmonics=2`).
    pub(crate) fn deserialize<'de, D: serde::Deserializer<'de>>(
        d: D,
    ) -> Result<Harmonics, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Given {
            Count(u8),
            Text(String),
        }
        match Given::deserialize(d)? {
            Given::Count(n) => n.to_string().parse(),
            Given::Text(text) => text.parse(),
        }
        .map_err(serde::de::Error::custom)
    }
}

impl std::str::FromStr for Harmonics {
    type Err = String;

    fn from_str(text: &str) -> Result<Harmonics, String> {
        match text {
            "auto" => Ok(Harmonics::Auto),
            "0" | "1" | "2" => Ok(Harmonics::Count(text.as_bytes()[0] - b'0')),
            _ => Err(format!("'{text}': choose auto, 0, 1 or 2")),
        }
    }
}

impl std::fmt::Display for Harmonics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Harmonics::Auto => f.write_str("auto"),
            Harmonics::Count(n) => write!(f, "{n}"),
        }
    }
}

/// A build checked and loaded, ready to run: every option valid, every input read, the
/// grid sized and the output checked.
pub struct BuildJob {
    args: BuildArgs,
    series: Series,
    robot: Option<Robot>,
    plan: Plan,
    outputs: OutputPlan,
    pool: rayon::ThreadPool,
    calibrate: CalibrateOptions,
    warnings: Vec<Warning>,
    started: Instant,
}

/// What a build made.
#[derive(Debug)]
pub struct Built {
    /// The table written.
    pub output: PathBuf,
    /// The samples files, as messages name them.
    pub sources: Vec<PathBuf>,
    /// How many samples (repeats averaged).
    pub samples: usize,
    /// The spread of repeated poses, when rows repeated a pose.
    pub repeats: Option<RepeatReport>,
    /// What the compiler made: the plan as resolved, candidate lists, served field.
    pub report: BuildReport,
    /// The cross-validation that chose the options (`tune`).
    pub tuning: Option<TuneReport>,
    /// The identification's harmonic count chosen by cross-validation (`--harmonics auto`,
    /// the default, with a robot), with the evidence.
    pub harmonics: Option<HarmonicsChoice>,
    /// The served field, resolved before the table was encoded, without `tune`: chosen by
    /// cross-validation (`served_field` or `posture` `auto`, the defaults) or fixed.
    pub served_field: Option<ServedFieldDecision>,
    /// A hybrid table's identification, and the RMS of the residuals its table holds, mm.
    pub calibration: Option<(Calibration, f64)>,
    /// Tracker-frame samples' registration, and both transforms as the identification
    /// refined them (of the first series, when several were given).
    pub registration: Option<(Registration, Refined)>,
    /// Tracker-frame series after the first: each one's registration to the robot
    /// identified from all of them (the probe the first one's).
    pub series_registrations: Vec<Registration>,
    /// What the user should know.
    pub warnings: Vec<Warning>,
    /// Wall time, s, from the job's creation.
    pub seconds: f64,
}

impl BuildJob {
    /// Checks `args`, reads the samples and the robot, sizes the grid and checks the
    /// output, before any work.
    ///
    /// # Errors
    ///
    /// A refused option or combination, an unreadable input, a grid too large, an output
    /// that is an input.
    pub fn new(args: BuildArgs) -> Result<BuildJob, JobError> {
        let started = Instant::now();
        let pool = crate::thread_pool(args.threads)?;
        check(&args)?;
        let mut inputs = Inputs::default();
        inputs.add_sources(&args.samples);
        let file_robot = load_robot(&args.robot, &mut inputs)?;
        let outputs = OutputPlan::check(&[&args.output], &inputs.paths())?;
        let (columns, read) = args.reading.resolve_for(file_robot.as_ref())?;
        let tracker = args.measured_in == Frame::Tracker;
        // `auto` registers several series and starts its choice without terms.
        let calibrate = CalibrateOptions {
            compliance: args.compliance,
            harmonics: args.harmonics.fixed().unwrap_or(0),
            ..CalibrateOptions::default()
        };
        // Read and sized on the job's threads: a large file is read in chunks.
        let series = pool.install(|| {
            crate::series::read(&args.samples, &columns, &read, file_robot.as_ref(), tracker)
        })?;
        let robot = match &series.registered {
            Some(r) => Some(r.robot.clone()),
            None => file_robot,
        };
        // Sized with the field given, or the method's own where one is to be chosen: a
        // chosen kriging field is sized again once chosen.
        let sized = args.table.build_options(unchosen_field(&args));
        let plan = pool.install(|| adwi_compile::build::plan(&series.samples, &sized))?;
        let mut warnings = series.warnings();
        if plan.is_mostly_empty() {
            warnings.push(Warning::MostlyEmptyGrid {
                cells: plan.cells(),
                coverable: plan.coverable_cells(),
                radius_mm: plan.params.radius_mm,
                estimated_bytes: plan.estimated_table_bytes(),
            });
        }
        Ok(BuildJob {
            args,
            series,
            robot,
            plan,
            outputs,
            pool,
            calibrate,
            warnings,
            started,
        })
    }

    /// The plan the build follows (before tuning changes k and ε).
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// The samples read (registered to the robot when measured in a tracker's frame).
    pub fn samples(&self) -> &SampleSet {
        &self.series.samples
    }

    /// Runs the build: the identification of a hybrid table's model, tuning when asked or
    /// the served field's choice (on that identification), the compilation, and the write.
    ///
    /// # Errors
    ///
    /// Tuning, identification or compilation failing; the write failing (nothing is then
    /// replaced).
    pub fn run(self, progress: &dyn Progress) -> Result<Built, JobError> {
        let BuildJob {
            args,
            mut series,
            robot,
            mut plan,
            outputs,
            pool,
            calibrate,
            mut warnings,
            started,
        } = self;
        let unchosen = unchosen_field(&args);
        let base = args.table.build_options(unchosen);
        if args.samples.len() > 1 {
            progress.stage("registering the series", None);
            pool.install(|| series.refine(&calibrate))?;
            plan = adwi_compile::build::plan(&series.samples, &base)?;
        }
        let mut calibrate = calibrate;
        let choose_harmonics = args.harmonics == Harmonics::Auto && robot.is_some();
        let choose_field = args.table.served_field == ServedFieldChoice::Auto;
        let choose_posture = args.table.posture == PostureChoice::Auto && robot.is_some();
        let choose_weight =
            args.table.residual_weight == ResidualWeightChoice::Auto && robot.is_some();
        let served_tier = plan.joint_radius_rad == 0.0;
        let mut harmonics = None;
        let (options, tuning, served_field) = if args.tune {
            progress.stage("tuning", None);
            let report = pool.install(|| {
                let mut cv = CrossValidation::new(
                    &series.samples,
                    robot.as_ref(),
                    calibrate,
                    args.tune_folds,
                    0,
                )?;
                if choose_harmonics {
                    harmonics = Some(cv.choose_harmonics(&HARMONICS_CANDIDATES)?);
                    calibrate = *cv.calibrate();
                }
                cv.tune(&base, choose_field, choose_posture && served_tier)
            })?;
            (report.options.clone(), Some(report), None)
        } else {
            let table_choices = (choose_field || choose_posture || choose_weight) && served_tier;
            let decision = if table_choices || choose_harmonics {
                // Never a reason for a build to fail that would succeed with the method's
                // own field and no terms: without the evidence, those.
                progress.stage("choosing the served field", None);
                let ask = Ask {
                    field: choose_field && table_choices,
                    posture: choose_posture && table_choices,
                    weight: choose_weight && table_choices,
                    harmonics: choose_harmonics,
                    series: series.labels.as_deref(),
                    folds: None,
                };
                let chosen = pool.install(|| {
                    default_choices(&series.samples, robot.as_ref(), &base, &calibrate, ask)
                });
                match chosen {
                    Ok(mut choice) => {
                        let (answered, held_out) = choice.answered();
                        if table_choices && 2 * answered < held_out {
                            warnings.push(Warning::FewAnswered {
                                answered,
                                held_out,
                                radius_mm: plan.params.radius_mm,
                                spacing_mm: plan.spacing_mm,
                            });
                        }
                        harmonics = choice.harmonics.take();
                        if let Some(h) = &harmonics {
                            calibrate.harmonics = h.chosen;
                        }
                        if table_choices {
                            ServedFieldDecision::Chosen(Box::new(choice))
                        } else {
                            ServedFieldDecision::Fixed(unchosen)
                        }
                    }
                    Err(e) => {
                        warnings.push(Warning::ServedFieldNotChosen {
                            reason: error_chain(&e),
                        });
                        ServedFieldDecision::Fixed(unchosen)
                    }
                }
            } else {
                ServedFieldDecision::Fixed(unchosen)
            };
            let mut options = args.table.build_options(decision.field());
            decision.apply(&mut options);
            (options, None, Some(decision))
        };
        // Several series were registered to the model without terms; with terms chosen,
        // again to the model with them, as `--harmonics N` registers them.
        if args.samples.len() > 1 && calibrate.harmonics > 0 && choose_harmonics {
            progress.stage("registering the series", None);
            pool.install(|| series.refine(&calibrate))?;
        }
        let Series {
            samples,
            registered,
            others,
            ..
        } = series;
        // Identified once, with the count chosen: the model the table holds.
        let identified = match &robot {
            Some(robot) => {
                progress.stage("identifying", None);
                Some(pool.install(|| identify(robot, &samples, &calibrate))?)
            }
            None => None,
        };
        let plan = adwi_compile::build::plan(&samples, &options)?;
        let advance = |n| progress.advance(n);
        let (bytes, report, calibration) = match robot.as_ref().zip(identified) {
            Some((robot, identified)) => {
                progress.stage("compiling", Some(plan.cells() as u64));
                // A learned residual weight scales the residuals the table holds.
                let weight = served_field.as_ref().map_or(1.0, |d| d.residual_weight());
                let built = pool.install(|| {
                    compile_hybrid(robot, &identified, &samples, plan, weight, &advance)
                })?;
                warnings.extend(crate::calibration_warnings(&identified));
                if samples.rotation_error_rad.is_none() {
                    warnings.push(Warning::RotationUnmeasured);
                }
                (
                    built.bytes,
                    built.report,
                    Some((identified, built.residual_position_rms_mm)),
                )
            }
            None => {
                progress.stage("compiling", Some(plan.cells() as u64));
                let hash = samples.source_hash();
                let (bytes, report) =
                    pool.install(|| compile_plan(&samples, &plan, None, hash, &advance))?;
                (bytes, report, None)
            }
        };
        outputs.write(&[(&args.output, &bytes)])?;
        let registration = registered.zip(calibration.as_ref()).map(|(r, (c, _))| {
            let refined = r.registration.refined(c, &samples);
            (r.registration, refined)
        });
        Ok(Built {
            output: args.output,
            sources: args
                .samples
                .iter()
                .map(|s| s.name().to_path_buf())
                .collect(),
            samples: samples.len(),
            repeats: samples.repeats,
            report,
            tuning,
            harmonics,
            served_field,
            calibration,
            registration,
            series_registrations: others,
            warnings,
            seconds: started.elapsed().as_secs_f64(),
        })
    }
}

/// The hybrid table of `samples` and their `identified` model, the residuals scaled by
/// `weight` (1: as measured), the point the samples measured on the flange recorded so
/// that a query may name another TCP, whose lever the model turns (within the samples'
/// evidence when they measured orientation, flagged otherwise: `Table::placed`).
fn compile_hybrid(
    robot: &Robot,
    identified: &Calibration,
    samples: &SampleSet,
    plan: Plan,
    weight: f64,
    advance: &(dyn Fn(u64) + Sync),
) -> Result<adwi_compile::hybrid::HybridBuild, adwi_compile::build::BuildError> {
    let model = identified.prepared_model();
    let weighted =
        (weight != 1.0).then(|| adwi_eval::choice::weighted_residuals(samples, identified, weight));
    let tool = robot.tool();
    let plan = Plan {
        point_in_flange: Some(adwi_runtime::format::PointInFlange::stored(
            tool.translation_mm,
            adwi_runtime::kinematics::rotation_vector(&tool.rotation),
        )),
        ..plan
    };
    adwi_compile::hybrid::compile(weighted.as_ref().unwrap_or(samples), &model, &plan, advance)
}

/// The field a table serves where none is chosen: the one given, else the method's own.
fn unchosen_field(args: &BuildArgs) -> ServedField {
    args.table
        .served_field
        .fixed()
        .unwrap_or(ServedField::Method)
}

/// An error and its sources, in one line.
fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        text.push_str(": ");
        text.push_str(&s.to_string());
        source = s.source();
    }
    text
}

/// The combinations a build refuses, before reading anything.
fn check(args: &BuildArgs) -> Result<(), JobError> {
    let robot = args.robot.robot.is_some();
    if args.hybrid && !robot {
        return Err(JobError::Options(
            "a hybrid table needs the robot file: --robot ROBOT (robot=PATH)".into(),
        ));
    }
    if args.compliance && !robot {
        return Err(JobError::Options(
            "--compliance is identified with the robot's geometry: give the robot \
             file (--robot)"
                .into(),
        ));
    }
    if args.table.posture == PostureChoice::On && !robot {
        return Err(JobError::Options(
            "--posture on (posture='on') is a hybrid table's term: give the robot file \
             (--robot)"
                .into(),
        ));
    }
    if args.measured_in == Frame::Tracker && !robot {
        return Err(JobError::Options(
            "--measured-in tracker needs the robot file the \
             measurements are registered to (--robot)"
                .into(),
        ));
    }
    if args.tune {
        if args.table.radius.is_some() || args.table.k.is_some() {
            return Err(JobError::Options(
                "--tune chooses k and the radius ε: give --tune, or --k/--radius, not \
                 both"
                    .into(),
            ));
        }
        if args.tune_folds < 2 {
            return Err(JobError::option("tune_folds", "give at least 2 folds"));
        }
    }
    if args.output.as_os_str().is_empty() {
        return Err(JobError::Options("give the table's path (-o TABLE)".into()));
    }
    // The table's options, before any file is read: a wrong k or w1 + w2 is a usage error
    // whatever the samples.
    adwi_compile::build::check_options(&args.table.build_options(unchosen_field(args)))
        .map_err(|e| JobError::Options(e.to_string()))
}
