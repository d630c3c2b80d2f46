//! The simulation job: a sample database for a robot, an error scenario and a sampling
//! plan (`tablec simulate`).

use std::path::PathBuf;

use adwi_output::OutputPlan;
use adwi_robot::{Configuration, Robot};
use adwi_simulate::{
    describe, position_error_stats_mm, simulate, write_csv, Positions, SamplingPlan, Scenario,
};
use serde::Deserialize;

use crate::args::{parse_triple, RobotArgs};
use crate::inputs::{load_robot, Inputs};
use crate::JobError;

/// Simulate measured samples: every option of `tablec simulate`.
#[derive(clap::Args, Deserialize, Debug, Clone)]
#[serde(default)]
pub struct SimulateArgs {
    /// The robot (required), e.g. tables/kr150-2/robot.toml.
    #[command(flatten)]
    #[serde(flatten)]
    pub robot: RobotArgs,
    /// Error scenario (TOML), e.g. tables/kr150-2/scenario.toml.
    #[arg(long)]
    pub scenario: PathBuf,
    /// Box corner x,y,z (mm, base frame).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true,
          required_unless_present = "poses")]
    pub min: Option<[f64; 3]>,
    /// Opposite box corner x,y,z (mm, base frame).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true,
          required_unless_present = "poses")]
    pub max: Option<[f64; 3]>,
    /// Measure these poses instead of a lattice or random ones: a CSV with joint values
    /// j1..jn (degrees; mm for prismatic joints), such as `tablec plan` writes; the nominal
    /// pose is the forward kinematics of each row's joints.
    #[arg(long, value_name = "POSES.csv", conflicts_with_all = ["min", "max", "step", "random"])]
    pub poses: Option<PathBuf>,
    /// Lattice spacing (mm): every min + k·step inside the box.
    #[arg(long)]
    pub step: Option<f64>,
    /// Number of poses drawn uniformly in the box.
    #[arg(long)]
    pub random: Option<usize>,
    /// Tool orientation A,B,C (KUKA degrees, R = Rz(A)·Ry(B)·Rx(C)).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true, default_value = "0,90,0")]
    pub abc: [f64; 3],
    /// Turn each orientation by a random angle up to this (degrees) about a random axis.
    #[arg(long, default_value_t = 0.0)]
    pub orientation_spread: f64,
    /// Use this configuration (0-7: bit 0 shoulder back, bit 1 elbow down, bit 2 wrist
    /// flip) instead of the solution closest to the robot's home posture.
    #[arg(long)]
    pub config: Option<u8>,
    /// Seed of every random draw: the same seed gives the same file byte for byte.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output CSV.
    #[arg(long, short)]
    pub output: PathBuf,
    /// Extra comment line written at the top of the file, after the description of the
    /// simulation (repeatable).
    #[arg(long)]
    pub comment: Vec<String>,
}

impl Default for SimulateArgs {
    fn default() -> SimulateArgs {
        SimulateArgs {
            robot: RobotArgs::default(),
            scenario: PathBuf::new(),
            min: None,
            max: None,
            poses: None,
            step: None,
            random: None,
            abc: [0.0, 90.0, 0.0],
            orientation_spread: 0.0,
            config: None,
            seed: 1,
            output: PathBuf::new(),
            comment: Vec::new(),
        }
    }
}

/// The joint values of every row of a poses file (rad; mm when prismatic).
pub(crate) fn read_joint_rows(
    path: &std::path::Path,
    robot: &Robot,
) -> Result<Vec<Vec<f64>>, JobError> {
    let (columns, options) = crate::args::Reading::default().resolve_for(Some(robot))?;
    // Joint values are what a pose to measure is: x,y,z may be in the file (a plan has
    // them) but are not needed.
    let rows = adwi_samples::read_poses(path, &columns, &options)?;
    rows.into_iter()
        .map(|q| {
            if q.len() == robot.joint_count() {
                return Ok(q);
            }
            Err(JobError::option(
                "poses",
                format!(
                    "{} gives {} joint values per row; the {} has {} joints",
                    path.display(),
                    q.len(),
                    robot.name,
                    robot.joint_count()
                ),
            ))
        })
        .collect()
}

/// A simulation checked and loaded, ready to run.
pub struct SimulateJob {
    args: SimulateArgs,
    robot: Robot,
    scenario: Scenario,
    plan: SamplingPlan,
    outputs: OutputPlan,
}

/// What a simulation wrote.
#[derive(Debug, Clone)]
pub struct Simulated {
    /// The file written.
    pub output: PathBuf,
    /// How many samples.
    pub samples: usize,
    /// The robot's name.
    pub robot_name: String,
    /// Mean and largest position error of the samples, mm.
    pub error_mean_max_mm: (f64, f64),
}

impl SimulateJob {
    /// Checks `args`, loads the robot and the scenario, and checks the output.
    ///
    /// # Errors
    ///
    /// A refused option, an unreadable robot or scenario, an output that is an input.
    pub fn new(args: SimulateArgs) -> Result<SimulateJob, JobError> {
        if args.robot.robot.is_none() {
            return Err(JobError::Options(
                "simulate needs the robot file (--robot)".into(),
            ));
        }
        let box_mm = match (args.min, args.max, &args.poses) {
            (Some(min), Some(max), None) => Some((min, max)),
            (None, None, Some(_)) => None,
            _ => {
                return Err(JobError::Options(
                    "give the box (--min and --max) with --step or --random, or the poses to \
                     measure (--poses) alone"
                        .into(),
                ))
            }
        };
        let positions = match (args.step, args.random, box_mm) {
            (Some(step_mm), None, Some((min_mm, max_mm))) => Positions::Lattice {
                min_mm,
                max_mm,
                step_mm,
            },
            (None, Some(count), Some((min_mm, max_mm))) => Positions::Random {
                count,
                min_mm,
                max_mm,
            },
            // Read below, once the poses file is known not to be the output.
            (None, None, None) => Positions::Joints(Vec::new()),
            _ => {
                return Err(JobError::Options(
                    "give exactly one of --step (a lattice), --random (a count) and --poses \
                     (a file)"
                        .into(),
                ))
            }
        };
        let config = args
            .config
            .map(|bits| {
                Configuration::from_bits(bits)
                    .ok_or_else(|| JobError::option("config", format!("{bits} is not 0-7")))
            })
            .transpose()?;
        let mut inputs = Inputs::default();
        inputs.add(&args.scenario);
        if let Some(poses) = &args.poses {
            inputs.add(poses);
        }
        let robot = load_robot(&args.robot, &mut inputs)?.expect("checked");
        let outputs = OutputPlan::check(&[&args.output], &inputs.paths())?;
        let positions = match &args.poses {
            Some(path) => Positions::Joints(read_joint_rows(path, &robot)?),
            None => positions,
        };
        let scenario = Scenario::load(&args.scenario)?;
        let plan = SamplingPlan {
            positions,
            abc_deg: args.abc,
            orientation_spread_deg: args.orientation_spread,
            config,
            seed: args.seed,
        };
        // Sized before anything is simulated: a plan too large is refused with its count.
        plan.sample_count()?;
        Ok(SimulateJob {
            args,
            robot,
            scenario,
            plan,
            outputs,
        })
    }

    /// Simulates the samples and writes them.
    ///
    /// # Errors
    ///
    /// The plan or the scenario refused by the simulation; the write failing (nothing is
    /// then replaced).
    pub fn run(self) -> Result<Simulated, JobError> {
        let SimulateJob {
            args,
            robot,
            scenario,
            plan,
            outputs,
        } = self;
        let samples = simulate(&robot, &scenario, &plan)?;
        let scenario_name = args.scenario.file_name().map_or_else(
            || args.scenario.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        let mut comments = describe(&robot, &scenario_name, &plan);
        comments.extend(args.comment);
        let mut bytes = Vec::new();
        write_csv(&samples, &comments, &mut bytes).map_err(|source| {
            JobError::from(adwi_output::OutputError::Write {
                path: args.output.clone(),
                source,
            })
        })?;
        outputs.write(&[(&args.output, &bytes)])?;
        Ok(Simulated {
            output: args.output,
            samples: samples.len(),
            robot_name: robot.name.clone(),
            error_mean_max_mm: position_error_stats_mm(&samples),
        })
    }
}
