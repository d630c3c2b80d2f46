//! The jobs `tablec` and the `adwi` Python package run, written once.
//!
//! Each job has two stages, as ripgrep's `LowArgs` and `HiArgs` do:
//!
//! - `*Args` ([`BuildArgs`], [`EvalArgs`], [`CalibrateArgs`], [`SimulateArgs`]) are what a
//!   user asked for: every option, with its documentation and its default, defined once as
//!   a clap argument group (tablec flattens it) and as a serde struct (Python's keyword
//!   arguments deserialize into it);
//! - `*Job::new(args)` checks every option and every combination, opens and reads every
//!   input, sizes the work and checks every output (not an input, not two outputs in one
//!   file, not a FIFO or a device) — **before any work**, so that a bad request fails in
//!   milliseconds with one message — and `run` then does the work, writes its outputs all
//!   or nothing ([`adwi_output::OutputPlan`]) and returns typed results and typed
//!   [`Warning`]s.
//!
//! Front ends map their arguments onto `*Args` and print or convert the results; neither
//! calls a step of a pipeline itself.

pub mod args;
pub mod bench;
pub mod build;
pub mod calibrate;
pub mod compensate;
pub mod continuity;
pub mod eval;
mod inputs;
pub mod inspect;
pub mod iso9283;
pub mod plan;
pub mod query;
pub mod registration;
mod series;
pub mod simulate;
/// The table's choices by evidence, made beside evaluation.
pub use adwi_eval::choice;
/// What an identification found, as every front end gives it.
pub use adwi_eval::CalibrationSummary;

use std::fmt;
use std::path::{Path, PathBuf};

pub use args::{Frame, PostureChoice, Reading, RobotArgs, ServedFieldChoice, TableArgs};
pub use bench::{BenchArgs, BenchJob, Benched};
pub use build::{BuildArgs, BuildJob, Built};
pub use calibrate::{CalibrateArgs, CalibrateJob, Calibrated};
pub use compensate::{CompensateArgs, CompensateJob};
pub use continuity::{ContinuityArgs, ContinuityJob, ContinuityResult};
pub use eval::{EvalArgs, EvalJob, Evaluated};
pub use inputs::Source;
pub use inspect::{InspectArgs, InspectJob, Inspected};
pub use iso9283::{Iso9283Args, Iso9283Job, Iso9283Result};
pub use plan::{CriterionArg, PlanArgs, PlanJob, Planned};
pub use query::{QueryArgs, QueryJob, QueryResult};
pub use registration::RegistrationSummary;
pub use simulate::{SimulateArgs, SimulateJob, Simulated};

/// Why a job was refused or failed. Refusals of options come before any work.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// An option, or a combination of options, that cannot be honoured.
    #[error("{0}")]
    Options(String),
    /// A samples, validation or targets file that cannot be read (file, line, column).
    #[error(transparent)]
    Read(Box<adwi_samples::ReadError>),
    /// Tracker-frame measurements that cannot be registered to the robot.
    #[error(transparent)]
    Measured(Box<adwi_identify::measured::MeasuredError>),
    /// Series that cannot be trained together: one given twice, one in another unit.
    #[error(transparent)]
    Series(Box<adwi_samples::SeriesConflict>),
    /// Samples the robot file does not fit: its nominal forward kinematics does not put
    /// their joints near their positions (a unit, another robot, a column map).
    #[error(transparent)]
    Disagreement(Box<adwi_identify::agreement::Disagreement>),
    /// A robot file that cannot be loaded.
    #[error("cannot load the robot {}{hint}", path.display())]
    Robot {
        /// The robot file.
        path: PathBuf,
        /// What to give instead, when the file does not exist.
        hint: &'static str,
        /// Why.
        #[source]
        source: Box<adwi_robot::RobotError>,
    },
    /// A simulation that cannot run (its scenario, its plan).
    #[error(transparent)]
    Simulate(Box<adwi_simulate::SimulateError>),
    /// The table cannot be built from these samples and options.
    #[error(transparent)]
    Build(Box<adwi_compile::build::BuildError>),
    /// The kinematic identification failed.
    #[error(transparent)]
    Calibrate(Box<adwi_identify::calibrate::CalibrateError>),
    /// The evaluation failed.
    #[error(transparent)]
    Eval(Box<adwi_eval::EvalError>),
    /// The cross-validation that chooses the table's parameters failed.
    #[error(transparent)]
    Tune(Box<choice::TuneError>),
    /// A table that cannot be opened.
    #[error("cannot open table {}", path.display())]
    Table {
        /// The table file.
        path: PathBuf,
        /// Why.
        #[source]
        source: adwi_runtime::OpenError,
    },
    /// An output refused before any work, or that could not be written.
    #[error(transparent)]
    Output(Box<adwi_output::OutputError>),
    /// Worker threads could not be started.
    #[error("cannot start worker threads: {0}")]
    Threads(String),
    /// Measured cycles ISO 9283 cannot reduce, or a plan it cannot place.
    #[error(transparent)]
    Measure(Box<adwi_measure::iso9283::Iso9283Error>),
    /// A measurement plan that cannot be made.
    #[error(transparent)]
    Plan(Box<adwi_measure::plan::PlanError>),
    /// An identification that cannot be compared with a simulated robot's truth.
    #[error(transparent)]
    Truth(Box<adwi_measure::truth::TruthError>),
    /// A program that cannot be compensated: an input, a malformed program (file, line
    /// and column), an output, more work than allowed, or with `strict` a target left
    /// unchanged.
    #[error(transparent)]
    Program(Box<adwi_programs::Error>),
    /// A result came out non-finite and is not reported as one.
    #[error("{0}")]
    NonFinite(String),
    /// Continuity that cannot be measured on this table: a hybrid one, or a grid without
    /// a line of the length asked for.
    #[error(transparent)]
    Continuity(Box<adwi_eval::continuity::ContinuityError>),
    /// A benchmark without a workload.
    #[error("{0}")]
    Bench(String),
    /// A table whose bytes changed after it was validated (a file rewritten in place).
    #[error("table bytes changed after validation")]
    TableChanged,
}

/// The large errors of the steps, boxed so that a job's `Result` stays small.
macro_rules! boxed_from {
    ($($variant:ident: $ty:ty),* $(,)?) => {
        $(impl From<$ty> for JobError {
            fn from(e: $ty) -> JobError {
                JobError::$variant(Box::new(e))
            }
        })*
    };
}

boxed_from!(
    Read: adwi_samples::ReadError,
    Measured: adwi_identify::measured::MeasuredError,
    Series: adwi_samples::SeriesConflict,
    Disagreement: adwi_identify::agreement::Disagreement,
    Simulate: adwi_simulate::SimulateError,
    Build: adwi_compile::build::BuildError,
    Calibrate: adwi_identify::calibrate::CalibrateError,
    Eval: adwi_eval::EvalError,
    Tune: choice::TuneError,
    Output: adwi_output::OutputError,
    Truth: adwi_measure::truth::TruthError,
);

impl JobError {
    /// A refused option, named as the command line names it.
    pub(crate) fn option(name: &str, why: impl fmt::Display) -> JobError {
        JobError::Options(format!("{}: {why}", flag(name)))
    }

    pub(crate) fn robot(path: &Path) -> impl FnOnce(adwi_robot::RobotError) -> JobError + '_ {
        move |source| JobError::Robot {
            path: path.to_path_buf(),
            hint: if is_not_found(&source) {
                ROBOT_NOT_FOUND_HINT
            } else {
                ""
            },
            source: Box::new(source),
        }
    }
}

/// What a missing robot file's message adds: what a robot file is, and the ones the
/// repository ships.
const ROBOT_NOT_FOUND_HINT: &str = ": no such file (a robot file is TOML or URDF, see \
    docs/cli.md; the repository ships tables/kr150-2/robot.toml, \
    tables/ur5/robot.toml, tables/ur10/robot.toml and tables/iiwa14/robot.toml)";

/// Whether a robot file could not be loaded because it does not exist.
fn is_not_found(e: &adwi_robot::RobotError) -> bool {
    matches!(e, adwi_robot::RobotError::Read { source, .. }
        if source.kind() == std::io::ErrorKind::NotFound)
}

/// An option's name as the command line spells it: `--tune-folds`. A job's messages name
/// options so; the Python package raises them with its keywords' spelling
/// ([`keyword_spelling`]), so that each front end names only its own.
pub(crate) fn flag(name: &str) -> String {
    format!("--{}", name.replace('_', "-"))
}

/// `message` with every option named as Python's keyword arguments name it: `--tune-folds`
/// becomes `tune_folds`. Only a flag that stands as a word of its own is renamed, not two
/// hyphens inside a path's name.
pub fn keyword_spelling(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    let mut previous: Option<char> = None;
    while let Some(at) = rest.find("--") {
        let (before, from) = rest.split_at(at);
        out.push_str(before);
        let previous_char = before.chars().next_back().or(previous);
        let name_len = from[2..]
            .find(|c: char| !(c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-'))
            .unwrap_or(from.len() - 2);
        let name = &from[2..2 + name_len];
        // A flag stands after the start, a space, an opening bracket or quote, a comma, or
        // the slash between alternatives (`--k/--radius`).
        let standalone = previous_char.is_none_or(|c| c.is_whitespace() || "([{'\"`,/".contains(c));
        if standalone && name.starts_with(|c: char| c.is_ascii_lowercase()) {
            out.push_str(&name.replace('-', "_"));
            rest = &from[2 + name_len..];
            previous = name.chars().next_back();
        } else {
            out.push_str("--");
            rest = &from[2..];
            previous = Some('-');
        }
    }
    out.push_str(rest);
    out
}

/// What a job warns about: the work was done, but the user should know.
#[derive(Debug, Clone, PartialEq)]
pub enum Warning {
    /// Most of the grid's cells are far from every sample (samples along a line or a
    /// plane): the table is large for what it holds.
    MostlyEmptyGrid {
        /// Cells in the grid.
        cells: usize,
        /// At most this many lie within ε of a sample.
        coverable: f64,
        /// ε, mm.
        radius_mm: f64,
        /// The table's estimated size, bytes.
        estimated_bytes: u128,
    },
    /// Kinematic parameters the samples cannot identify: they keep their nominal values
    /// and the table interpolates what they would have explained.
    Unidentifiable {
        /// Each parameter with its independent fraction (the pivot ratio).
        parameters: Vec<(String, f64)>,
    },
    /// The identification stopped without converging.
    NotConverged {
        /// Levenberg–Marquardt iterations made.
        iterations: u32,
    },
    /// What a URDF written from the calibrated robot does not carry (or carries only as
    /// the robot file gives it).
    UrdfOmits {
        /// The URDF written.
        path: PathBuf,
        /// What it leaves out.
        omissions: Vec<adwi_robot::urdf::UrdfOmission>,
    },
    /// Samples that look wrong for a robot measured in millimetres (a file in metres, say).
    Samples(adwi_samples::SampleWarning),
    /// A registration of tracker-frame measurements whose fit no robot's error explains.
    Registration(adwi_identify::register::RegisterWarning),
    /// Samples the robot file fits only with another tool or base frame than its own
    /// ([`adwi_identify::agreement`]): the identification takes it up.
    Agreement {
        /// The samples file.
        path: PathBuf,
        /// The tool or frame, and how well the samples fit with it.
        fitting: adwi_identify::agreement::Fitting,
    },
    /// The served field chosen answered fewer than half the points its cross-validation
    /// held out: most targets near the samples would go unanswered (ε small against the
    /// samples' spacing), and the choice rests on the few it answered.
    FewAnswered {
        /// Held-out points the chosen field answered.
        answered: usize,
        /// Points held out.
        held_out: usize,
        /// ε, mm.
        radius_mm: f64,
        /// The samples' spacing, mm, when derivable.
        spacing_mm: Option<f64>,
    },
    /// The served field could not be chosen by cross-validation (too few samples, or a
    /// fold that could not be evaluated): the table serves the method's own answer.
    ServedFieldNotChosen {
        /// Why.
        reason: String,
    },
    /// A hybrid table of samples that measured position alone: its model's rotation
    /// error is not determined by them, so the table serves none, and a TCP away from
    /// the measured point, whose lever that rotation would turn, is beyond their evidence
    /// (docs/runtime.md, "Another TCP").
    RotationUnmeasured,
}

impl Warning {
    /// Whether this is a note rather than a warning: what every identification of such
    /// samples reports (parameters no position measurement separates), not a sign that
    /// something went wrong.
    pub fn is_note(&self) -> bool {
        matches!(
            self,
            Warning::Unidentifiable { .. } | Warning::RotationUnmeasured
        )
    }
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Warning::FewAnswered {
                answered,
                held_out,
                radius_mm,
                spacing_mm,
            } => {
                write!(
                    f,
                    "the served field answered {answered} of the {held_out} samples its \
                     cross-validation held out: most targets will go unanswered, and the \
                     choice rests on those few; ε = {radius_mm:.3} mm"
                )?;
                if let Some(spacing_mm) = spacing_mm {
                    write!(f, " against a sample spacing of {spacing_mm:.3} mm")?;
                }
                write!(f, " (give a larger --radius, or leave it derived)")
            }
            Warning::ServedFieldNotChosen { reason } => write!(
                f,
                "the served field was not chosen by cross-validation ({reason}): it holds the \
                 method's own answer (--served-field kriging forces the other)"
            ),
            Warning::MostlyEmptyGrid {
                cells,
                coverable,
                radius_mm,
                estimated_bytes,
            } => write!(
                f,
                "the grid's {cells} cells are mostly empty: at most {coverable:.0} of them lie \
                 within ε = {radius_mm:.3} mm of a sample (samples along a line or a plane?); \
                 the table will be about {} — give bounds around the samples (--bounds), or a \
                 larger cell (--cell)",
                adwi_compile::build::human_bytes(*estimated_bytes)
            ),
            Warning::Unidentifiable { parameters } => {
                let names: Vec<String> = parameters
                    .iter()
                    .map(|(p, ratio)| format!("{p} ({ratio:.1e})"))
                    .collect();
                write!(
                    f,
                    "{} kinematic parameters are not observable in these samples and stay at \
                     nominal, as is usual (each is redundant with others, or needs what the \
                     samples lack, an orientation or another posture; independent fraction in \
                     brackets): {}",
                    names.len(),
                    names.join(", ")
                )
            }
            Warning::NotConverged { iterations } => write!(
                f,
                "kinematic identification stopped after {iterations} iterations without \
                 converging"
            ),
            Warning::UrdfOmits { path, omissions } => {
                let what: Vec<String> = omissions.iter().map(|o| o.to_string()).collect();
                write!(f, "{} does not carry: {}", path.display(), what.join("; "))
            }
            Warning::RotationUnmeasured => write!(
                f,
                "the samples measured position alone: the table corrects position and serves \
                 no orientation error (its model's, which positions do not determine, can be \
                 further from the robot's than none), and a TCP more than {} mm from their \
                 point is carried unturned and flagged `tcp` (tablec compensate refuses it \
                 without --beyond-evidence); samples with orientation (a 6-D tracker target) \
                 carry both",
                adwi_runtime::format::TCP_MARGIN_MM
            ),
            Warning::Samples(w) => write!(f, "{w}"),
            Warning::Registration(w) => write!(f, "{w}"),
            Warning::Agreement { path, fitting } => write!(
                f,
                "{}: the robot file's nominal forward kinematics puts the tool more than {} mm \
                 from the samples' commanded x,y,z, but they fit {fitting}: the identification \
                 takes it up; give it in the robot file for a model that describes the samples",
                path.display(),
                adwi_identify::agreement::MAX_NOMINAL_MISS_MM
            ),
        }
    }
}

/// What an identification warns about.
pub(crate) fn calibration_warnings(c: &adwi_identify::calibrate::Calibration) -> Vec<Warning> {
    let mut warnings = Vec::new();
    if !c.unidentifiable.is_empty() {
        warnings.push(Warning::Unidentifiable {
            parameters: c
                .unidentifiable
                .iter()
                .map(|(p, ratio)| (p.to_string(), *ratio))
                .collect(),
        });
    }
    if !c.converged {
        warnings.push(Warning::NotConverged {
            iterations: c.iterations,
        });
    }
    warnings
}

/// Where a long job reports how far it got. Every method has a default that does nothing,
/// so a front end without a progress bar passes [`Silent`].
pub trait Progress: Sync {
    /// A new stage begins (`identifying`, `compiling`), of `units` steps when known.
    fn stage(&self, _name: &str, _units: Option<u64>) {}
    /// `units` more steps of the current stage are done.
    fn advance(&self, _units: u64) {}
}

/// No progress reported.
pub struct Silent;

impl Progress for Silent {}

/// The worker threads of a job: all cores by default; a count is checked before any
/// work, since more threads than a few per core only add overhead.
pub(crate) fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, JobError> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        check_threads(n)?;
        pool = pool.num_threads(n);
    }
    pool.build().map_err(|e| JobError::Threads(e.to_string()))
}

/// The most worker threads a job takes: four per core (at least 64), beyond which threads
/// only contend for the cores.
pub fn max_threads() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    (4 * cores).max(64)
}

pub(crate) fn check_threads(n: usize) -> Result<(), JobError> {
    let max = max_threads();
    if n == 0 || n > max {
        return Err(JobError::option(
            "threads",
            format!(
                "{n} worker threads: give 1 to {max} (four per core of this machine's {}, at \
                 least 64); more only contend for the cores",
                std::thread::available_parallelism().map_or(1, |n| n.get())
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use clap::Parser;
    use serde::de::value::{Error, MapDeserializer};
    use serde::Deserialize;

    use super::*;

    /// Each job's arguments under a command, as tablec has them.
    #[derive(clap::Parser)]
    enum Cli {
        Build(BuildArgs),
        Eval(EvalArgs),
        Calibrate(CalibrateArgs),
        Simulate(SimulateArgs),
    }

    /// `T` from no keyword arguments at all, as Python's defaults are made.
    fn from_nothing<'de, T: Deserialize<'de>>() -> T {
        T::deserialize(MapDeserializer::<_, Error>::new(std::iter::empty::<(
            &str,
            &str,
        )>()))
        .unwrap()
    }

    /// The defaults clap gives when no flag is passed are the structs' `Default`s, which
    /// serde takes for every keyword a Python call leaves out: one definition, one set of
    /// defaults.
    #[test]
    fn the_command_line_and_python_have_the_same_defaults() {
        let Cli::Build(parsed) = Cli::parse_from(["tablec", "build", "s.csv", "-o", "t.tbl"])
        else {
            unreachable!()
        };
        let mut expected: BuildArgs = from_nothing();
        expected.samples = vec![Source::File("s.csv".into())];
        expected.output = "t.tbl".into();
        assert_eq!(format!("{parsed:?}"), format!("{expected:?}"));
        let default = BuildArgs {
            samples: vec![Source::File("s.csv".into())],
            output: "t.tbl".into(),
            ..BuildArgs::default()
        };
        assert_eq!(format!("{expected:?}"), format!("{default:?}"));

        let Cli::Eval(parsed) = Cli::parse_from(["tablec", "eval", "s.csv"]) else {
            unreachable!()
        };
        let mut expected: EvalArgs = from_nothing();
        expected.samples = vec![Source::File("s.csv".into())];
        assert_eq!(format!("{parsed:?}"), format!("{expected:?}"));

        let Cli::Calibrate(parsed) = Cli::parse_from(["tablec", "calibrate", "s.csv"]) else {
            unreachable!()
        };
        let mut expected: CalibrateArgs = from_nothing();
        expected.samples = vec![Source::File("s.csv".into())];
        assert_eq!(format!("{parsed:?}"), format!("{expected:?}"));

        let Cli::Simulate(parsed) = Cli::parse_from([
            "tablec",
            "simulate",
            "--scenario",
            "x.toml",
            "--min",
            "0,0,0",
            "--max",
            "1,1,1",
            "-o",
            "s.csv",
        ]) else {
            unreachable!()
        };
        let mut expected: SimulateArgs = from_nothing();
        expected.scenario = "x.toml".into();
        expected.min = Some([0.0; 3]);
        expected.max = Some([1.0; 3]);
        expected.output = "s.csv".into();
        assert_eq!(format!("{parsed:?}"), format!("{expected:?}"));
    }

    /// A refused combination is refused before anything is read: the samples file here
    /// does not exist.
    #[test]
    fn combinations_are_refused_before_any_input_is_read() {
        let mut args = BuildArgs {
            samples: vec![Source::File("/nonexistent/s.csv".into())],
            output: "/nonexistent/t.tbl".into(),
            tune: true,
            table: TableArgs {
                k: Some(4),
                ..TableArgs::default()
            },
            ..BuildArgs::default()
        };
        let e = BuildJob::new(args.clone()).err().unwrap();
        assert!(matches!(e, JobError::Options(_)), "{e}");
        args.tune = false;
        args.compliance = true;
        assert!(matches!(
            BuildJob::new(args.clone()),
            Err(JobError::Options(_))
        ));
        args.compliance = false;
        args.threads = Some(1_000_000);
        let e = BuildJob::new(args).err().unwrap();
        assert!(
            e.to_string()
                .starts_with("--threads: 1000000 worker threads"),
            "{e}"
        );
    }

    /// A refused option is named as the command line spells it, and as Python's keyword
    /// arguments spell it in the Python package's messages, never both.
    #[test]
    fn each_front_end_names_an_option_in_its_own_spelling() {
        let e = JobError::option("tune_folds", "give at least 2 folds, not --folds 1");
        assert_eq!(
            e.to_string(),
            "--tune-folds: give at least 2 folds, not --folds 1"
        );
        assert_eq!(
            keyword_spelling(&e.to_string()),
            "tune_folds: give at least 2 folds, not folds 1"
        );
        // A path's hyphens, a negative number and an em dash are not options.
        assert_eq!(
            keyword_spelling("cannot read /tmp/a--b.csv: -1 (--register-validation-apart)"),
            "cannot read /tmp/a--b.csv: -1 (register_validation_apart)"
        );
        assert_eq!(keyword_spelling("-- a --"), "-- a --");
        assert_eq!(
            keyword_spelling("give --tune, or --k/--radius"),
            "give tune, or k/radius"
        );
    }
}
