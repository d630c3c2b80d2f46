//! The calibration job: a robot's kinematic deviations identified from samples, and the
//! calibrated robot written as a robot file and as URDF (`tablec calibrate`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use adwi_identify::calibrate::{identify, CalibrateOptions, Calibration};
use adwi_identify::register::{Refined, Registration};
use adwi_measure::truth::{self, TruthComparison};
use adwi_output::OutputPlan;
use adwi_robot::Robot;
use adwi_simulate::Scenario;
use serde::Deserialize;

use crate::args::{Frame, Reading, RobotArgs};
use crate::inputs::{load_robot, Inputs, Source};
use crate::registration::RegistrationSummary;
use crate::series::Series;
use crate::simulate::read_joint_rows;
use crate::{CalibrationSummary, JobError, Warning};

/// Identify a robot's kinematic deviations from samples: every option of `tablec
/// calibrate`.
#[derive(clap::Args, Deserialize, Debug, Clone)]
#[serde(default)]
pub struct CalibrateArgs {
    /// The sample database (CSV with joint values j1..jn), as for `tablec build`; several
    /// series are identified together.
    #[arg(required = true, value_name = "SAMPLES")]
    #[serde(skip)]
    pub samples: Vec<Source>,
    #[command(flatten)]
    #[serde(flatten)]
    pub reading: Reading,
    /// The robot to identify (required).
    #[command(flatten)]
    #[serde(flatten)]
    pub robot: RobotArgs,
    /// Write the calibrated robot as a robot file (TOML), loadable by every `--robot`.
    #[arg(short, long, value_name = "ROBOT.toml")]
    pub output: Option<PathBuf>,
    /// Write the calibrated robot as URDF (joint origins adjusted, the tool as a fixed
    /// joint to a `calibrated_tcp` link).
    #[arg(long, value_name = "ROBOT.urdf")]
    pub urdf: Option<PathBuf>,
    /// The frame the measured poses are in: `tracker` registers tracker-frame measurements
    /// (joints and measured probe poses) to the robot first (see `tablec build --help`).
    #[arg(long, value_enum, value_name = "FRAME", default_value_t)]
    pub measured_in: Frame,
    /// Relative pivot below which a parameter is unidentifiable.
    #[arg(long, default_value_t = CalibrateOptions::default().rank_tolerance)]
    pub rank_tol: f64,
    /// Identify each revolute joint's gravity compliance (µrad/(N·m)) with the geometry:
    /// the arm deflected by the gravity torque of the links it carries. The robot file
    /// must give link masses (mass_kg, com_mm per joint). The calibrated robot file
    /// carries them (compliance_urad_per_nm).
    #[arg(long)]
    pub compliance: bool,
    /// Kinematic identification: identify each revolute joint's joint-space terms up to
    /// this harmonic (0 none; 1 `sin q, cos q`; 2 also `sin 2q, cos 2q`), each kept only
    /// where the information criterion (BIC) supports it. None unless asked: the robot file
    /// and URDF written cannot hold them (a table can; `tablec build` chooses the count).
    #[arg(long, value_name = "N", default_value_t = CalibrateOptions::default().harmonics)]
    pub harmonics: u8,
    /// On a simulated robot: compare the identification with the truth of the scenario
    /// the samples were simulated with (TOML, as `tablec simulate --scenario`), at the
    /// poses of `--true-at`: the parameter error and the model's position error against
    /// the true robot (docs/measure.md, "Against the truth").
    #[arg(long, value_name = "SCENARIO.toml", requires = "true_at")]
    pub true_scenario: Option<PathBuf>,
    /// The workspace poses of `--true-scenario`'s comparison: a CSV with joint values
    /// j1..jn (degrees; mm for prismatic joints), such as held-out samples or a plan.
    #[arg(long, value_name = "POSES.csv", requires = "true_scenario")]
    pub true_at: Option<PathBuf>,
    /// Write the identification as JSON: its figures, every parameter as the report lists
    /// it, and with `--true-scenario` the comparison with the truth (`truth`, else null).
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
}

impl Default for CalibrateArgs {
    fn default() -> CalibrateArgs {
        CalibrateArgs {
            samples: Vec::new(),
            reading: Reading::default(),
            robot: RobotArgs::default(),
            output: None,
            urdf: None,
            measured_in: Frame::Base,
            rank_tol: CalibrateOptions::default().rank_tolerance,
            compliance: false,
            harmonics: CalibrateOptions::default().harmonics,
            true_scenario: None,
            true_at: None,
            json: None,
        }
    }
}

/// The identification's options.
fn options(args: &CalibrateArgs) -> CalibrateOptions {
    CalibrateOptions {
        rank_tolerance: args.rank_tol,
        compliance: args.compliance,
        harmonics: args.harmonics,
        ..CalibrateOptions::default()
    }
}

/// A calibration checked and loaded, ready to run.
pub struct CalibrateJob {
    args: CalibrateArgs,
    series: Series,
    robot: Robot,
    outputs: OutputPlan,
    truth: Option<(Scenario, Vec<Vec<f64>>)>,
}

/// What a calibration found, and what it wrote.
#[derive(Debug)]
pub struct Calibrated {
    /// The identification.
    pub calibration: Calibration,
    /// The robot's name.
    pub robot_name: String,
    /// The samples files, as messages name them.
    pub sources: Vec<PathBuf>,
    /// Tracker-frame series after the first: each one's registration.
    pub series_registrations: Vec<Registration>,
    /// How many samples.
    pub samples: usize,
    /// Tracker-frame samples' registration, and both transforms as the identification
    /// refined them.
    pub registration: Option<(Registration, Refined)>,
    /// The files written, in the order written.
    pub written: Vec<PathBuf>,
    /// What the user should know.
    pub warnings: Vec<Warning>,
    /// The identification against the simulated robot's truth (`--true-scenario`).
    pub truth: Option<TruthComparison>,
}

impl CalibrateJob {
    /// Checks `args`, reads the samples and the robot, and checks the outputs.
    ///
    /// # Errors
    ///
    /// A refused option, an unreadable input, an output that is an input, or two outputs
    /// that are one file.
    pub fn new(args: CalibrateArgs) -> Result<CalibrateJob, JobError> {
        if args.robot.robot.is_none() {
            return Err(JobError::Options(
                "calibrate identifies a robot: give the robot file (--robot)".into(),
            ));
        }
        if !(args.rank_tol.is_finite() && args.rank_tol > 0.0 && args.rank_tol < 1.0) {
            return Err(JobError::option(
                "rank_tol",
                format!("{} is not a relative pivot between 0 and 1", args.rank_tol),
            ));
        }
        let mut inputs = Inputs::default();
        inputs.add_sources(&args.samples);
        let file_robot = load_robot(&args.robot, &mut inputs)?.expect("checked");
        let truth = match (&args.true_scenario, &args.true_at) {
            (Some(scenario), Some(poses)) => {
                if args.measured_in == Frame::Tracker {
                    return Err(JobError::option(
                        "true_scenario",
                        "a simulated robot's samples are in its base frame: leave out \
                         --measured-in tracker",
                    ));
                }
                inputs.add(scenario);
                inputs.add(poses);
                let s = Scenario::load(scenario)?;
                s.actual_robot(&file_robot)?;
                let q = read_joint_rows(poses, &file_robot)?;
                if q.is_empty() || q.len() > truth::MAX_POSES {
                    return Err(JobError::option(
                        "true_at",
                        format!(
                            "{} holds {} poses: give 1 to {}",
                            poses.display(),
                            q.len(),
                            truth::MAX_POSES
                        ),
                    ));
                }
                Some((s, q))
            }
            (None, None) => None,
            _ => {
                return Err(JobError::Options(
                    "--true-scenario and --true-at go together".into(),
                ))
            }
        };
        let outputs = OutputPlan::check(
            &[
                args.output.as_deref(),
                args.urdf.as_deref(),
                args.json.as_deref(),
            ]
            .into_iter()
            .flatten()
            .collect::<Vec<&Path>>(),
            &inputs.paths(),
        )?;
        let (columns, read) = args.reading.resolve_for(Some(&file_robot))?;
        let tracker = args.measured_in == Frame::Tracker;
        let series =
            crate::series::read(&args.samples, &columns, &read, Some(&file_robot), tracker)?;
        let robot = match &series.registered {
            Some(r) => r.robot.clone(),
            None => file_robot,
        };
        Ok(CalibrateJob {
            args,
            series,
            robot,
            outputs,
            truth,
        })
    }

    /// Identifies the robot and writes the calibrated robot files, all or none.
    ///
    /// # Errors
    ///
    /// The identification failing or coming out non-finite; a write failing (nothing is
    /// then replaced).
    pub fn run(self) -> Result<Calibrated, JobError> {
        let CalibrateJob {
            args,
            mut series,
            robot,
            outputs,
            truth,
        } = self;
        series.refine(&options(&args))?;
        let series_warnings = series.warnings();
        let Series {
            samples,
            registered,
            others,
            ..
        } = series;
        let c = identify(&robot, &samples, &options(&args))?;
        if !(c.position_rms_mm.is_finite() && c.initial_position_rms_mm.is_finite()) {
            return Err(JobError::NonFinite(format!(
                "the identification came out non-finite (position RMS {} mm): the robot file or \
                 the samples hold implausible values",
                c.position_rms_mm
            )));
        }
        let truth = truth
            .map(|(scenario, poses)| truth::compare(&robot, &scenario, &c, &poses, &options(&args)))
            .transpose()?;
        let sources: Vec<String> = args
            .samples
            .iter()
            .map(|s| s.name().display().to_string())
            .collect();
        let comment = [
            format!(
                "{} calibrated from {} ({} samples): position RMS {:.4} mm before, {:.4} mm after.",
                robot.name,
                sources.join(", "),
                samples.len(),
                c.initial_position_rms_mm,
                c.position_rms_mm
            ),
            "Written by tablec calibrate.".to_string(),
        ];
        let mut warnings = series_warnings;
        warnings.extend(crate::calibration_warnings(&c));
        let mut contents: Vec<(&Path, Vec<u8>)> = Vec::new();
        if let Some(path) = &args.output {
            let text = c.calibrated_robot().to_toml_string(&comment);
            contents.push((path, text.into_bytes()));
        }
        if let Some(path) = &args.urdf {
            let omissions = c.calibrated_robot().urdf_omissions();
            if !omissions.is_empty() {
                warnings.push(Warning::UrdfOmits {
                    path: path.clone(),
                    omissions,
                });
            }
            let text = c
                .calibrated_robot()
                .to_urdf_string(&comment)
                .map_err(JobError::robot(path))?;
            contents.push((path, text.into_bytes()));
        }
        if let Some(path) = &args.json {
            let text = serde_json::to_string_pretty(&report(
                &robot.name,
                samples.len(),
                &CalibrationSummary::of(&c),
                truth.as_ref(),
            ))
            .map_err(|e| JobError::NonFinite(e.to_string()))?;
            contents.push((path, text.into_bytes()));
        }
        let borrowed: Vec<(&Path, &[u8])> = contents.iter().map(|(p, b)| (*p, &b[..])).collect();
        outputs.write(&borrowed)?;
        let registration = registered.map(|r| {
            let refined = r.registration.refined(&c, &samples);
            (r.registration, refined)
        });
        Ok(Calibrated {
            robot_name: robot.name.clone(),
            sources: args
                .samples
                .iter()
                .map(|s| s.name().to_path_buf())
                .collect(),
            series_registrations: others,
            samples: samples.len(),
            registration,
            written: contents.iter().map(|(p, _)| p.to_path_buf()).collect(),
            warnings,
            calibration: c,
            truth,
        })
    }
}

impl Calibrated {
    /// What `--json` wrote ([`report`]).
    pub fn report(&self) -> serde_json::Value {
        report(
            &self.robot_name,
            self.samples,
            &self.summary(),
            self.truth.as_ref(),
        )
    }

    /// What the identification found, as every front end gives it.
    pub fn summary(&self) -> CalibrationSummary {
        CalibrationSummary::of(&self.calibration)
    }

    /// The registrations of tracker-frame series, each as the front ends give it: the
    /// samples' (refined by the identification), then each later series'.
    pub fn registration_summaries(
        &self,
    ) -> (Option<RegistrationSummary>, Vec<RegistrationSummary>) {
        (
            (self.registration.as_ref())
                .map(|(r, refined)| RegistrationSummary::of(r, Some(refined))),
            (self.series_registrations.iter())
                .map(|r| RegistrationSummary::of(r, None))
                .collect(),
        )
    }

    /// What `tablec calibrate` prints: the registrations, the identification's summary,
    /// the comparison with the truth, and the files written.
    pub fn text(&self) -> String {
        let mut out = crate::registration::registrations_text(
            self.registration.as_ref(),
            &self.series_registrations,
            true,
        );
        out.push_str(&self.summary().text(None));
        if let Some(t) = &self.truth {
            out.push_str(&truth_text(t));
        }
        for path in &self.written {
            let _ = writeln!(out, "wrote          {}", path.display());
        }
        out
    }
}

/// The identification against the simulated robot's truth: the parameter error (lengths
/// and angles apart) and the position error over the workspace poses.
fn truth_text(t: &TruthComparison) -> String {
    let rms =
        |v: Option<f64>, unit: &str| v.map_or("—".to_string(), |v| format!("{v:.4} {unit}"));
    let lengths = t
        .parameters
        .iter()
        .filter(|p| p.parameter.is_length())
        .count();
    format!(
        "truth params   identified − true RMS {} ({lengths} lengths), {} ({} angles); {} of \
         them not identified here (counted at 0), {} identified here only (not compared)\n\
         truth position |model − true robot| over {} poses: mean {:.4} mm, RMS {:.4} mm, max \
         {:.4} mm\n",
        rms(t.length_rms_mm, "mm"),
        rms(t.angle_rms_mrad, "mrad"),
        t.parameters.len() - lengths,
        t.missed,
        t.not_compared,
        t.poses,
        t.position_mean_mm,
        t.position_rms_mm,
        t.position_max_mm
    )
}

/// What `--json` writes, and the Python binding returns with its own keys added: the
/// identification's figures, its parameters as the reports list them, and the comparison
/// with the truth (null without one).
fn report(
    robot_name: &str,
    samples: usize,
    c: &CalibrationSummary,
    truth: Option<&TruthComparison>,
) -> serde_json::Value {
    serde_json::json!({
        "robot": robot_name,
        "samples": samples,
        "condition_number": c.condition_number,
        "iterations": c.iterations,
        "converged": c.converged,
        "initial_position_rms_mm": c.initial_position_rms_mm,
        "position_rms_mm": c.position_rms_mm,
        "orientation_rms_rad": c.orientation_rms_rad,
        "parameters": c.parameters,
        "truth": truth,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{SimulateArgs, SimulateJob};

    /// `--json` writes the identification and the comparison with the truth that the job
    /// returns, under the keys the Python binding takes from it.
    #[test]
    fn the_json_holds_the_truth_comparison_the_job_returns() {
        let dir = tempfile::tempdir().unwrap();
        let kr150 = adwi_robot::model::shipped_robot_path("kr150-2");
        let tables = kr150.parent().unwrap().to_path_buf();
        let scenario = tables.join("scenario_geometric.toml");
        let samples = dir.path().join("measured.csv");
        SimulateJob::new(SimulateArgs {
            robot: RobotArgs {
                robot: Some(kr150.clone()),
                ..RobotArgs::default()
            },
            scenario: scenario.clone(),
            min: Some([1350.0, 50.0, 850.0]),
            max: Some([2150.0, 850.0, 1650.0]),
            random: Some(30),
            abc: [0.0, 90.0, 0.0],
            seed: 1,
            output: samples.clone(),
            ..SimulateArgs::default()
        })
        .unwrap()
        .run()
        .unwrap();
        let json = dir.path().join("c.json");
        let calibrated = CalibrateJob::new(CalibrateArgs {
            samples: vec![Source::File(samples)],
            robot: RobotArgs {
                robot: Some(kr150),
                ..RobotArgs::default()
            },
            true_scenario: Some(scenario),
            true_at: Some(tables.join("validation.csv")),
            json: Some(json.clone()),
            ..CalibrateArgs::default()
        })
        .unwrap()
        .run()
        .unwrap();
        let text = std::fs::read_to_string(&json).unwrap();
        assert_eq!(
            text,
            serde_json::to_string_pretty(&calibrated.report()).unwrap()
        );
        let written: serde_json::Value = serde_json::from_str(&text).unwrap();
        let truth = calibrated.truth.unwrap();
        let t = &written["truth"];
        assert_eq!(t["poses"], 1000);
        let close = |v: &serde_json::Value, expected: f64| {
            (v.as_f64().unwrap() - expected).abs() <= 1e-12 * expected.abs()
        };
        assert!(close(&t["position_rms_mm"], truth.position_rms_mm));
        assert!(close(&t["length_rms_mm"], truth.length_rms_mm.unwrap()));
        assert_eq!(
            t["parameters"].as_array().unwrap().len(),
            truth.parameters.len()
        );
        assert_eq!(
            t["parameters"][0]["parameter"],
            truth.parameters[0].parameter.to_string()
        );
        assert_eq!(written["samples"], 30);
        assert_eq!(calibrated.written, vec![json]);
    }
}
