//! `tablec simulate`: write a simulated sample database for a robot and an error scenario.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

use adwi_robot::simulate::{
    describe, position_error_stats_mm, simulate, write_csv, Positions, SamplingPlan, Scenario,
};
use adwi_robot::Configuration;
use anyhow::{bail, Context};

/// Simulate measured samples: nominal poses on a lattice or at random in a box, their exact
/// actual poses under an error scenario, measured with laser-tracker noise.
#[derive(clap::Args)]
pub struct Args {
    /// The robot file (TOML, or URDF by its .urdf extension), e.g.
    /// tables/kr150-2/robot.toml.
    #[arg(long, value_name = "ROBOT")]
    robot: PathBuf,
    #[command(flatten)]
    links: crate::RobotLinks,
    /// Error scenario (TOML), e.g. tables/kr150-2/scenario.toml.
    #[arg(long)]
    scenario: PathBuf,
    /// Box corner x,y,z (mm, base frame).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    min: [f64; 3],
    /// Opposite box corner x,y,z (mm, base frame).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    max: [f64; 3],
    /// Lattice spacing (mm): every min + k·step inside the box.
    #[arg(long, conflicts_with = "random", required_unless_present = "random")]
    step: Option<f64>,
    /// Number of poses drawn uniformly in the box.
    #[arg(long)]
    random: Option<usize>,
    /// Tool orientation A,B,C (KUKA degrees, R = Rz(A)·Ry(B)·Rx(C)).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true, default_value = "0,90,0")]
    abc: [f64; 3],
    /// Turn each orientation by a random angle up to this (degrees) about a random axis.
    #[arg(long, default_value_t = 0.0)]
    orientation_spread: f64,
    /// Use this configuration (0-7: bit 0 shoulder back, bit 1 elbow down, bit 2 wrist
    /// flip) instead of the solution closest to the robot's home posture.
    #[arg(long)]
    config: Option<u8>,
    /// Seed of every random draw: the same seed gives the same file byte for byte.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output CSV.
    #[arg(long, short)]
    output: PathBuf,
    /// Extra comment line written at the top of the file, after the description of the
    /// simulation (repeatable).
    #[arg(long)]
    comment: Vec<String>,
}

fn parse_triple(text: &str) -> Result<[f64; 3], String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("expected three comma-separated numbers: {e}"))?;
    values
        .try_into()
        .map_err(|v: Vec<f64>| format!("expected three comma-separated numbers, got {}", v.len()))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let robot = args.links.load(&args.robot)?;
    let scenario = Scenario::load(&args.scenario)?;
    let positions = match (args.step, args.random) {
        (Some(step_mm), None) => Positions::Lattice {
            min_mm: args.min,
            max_mm: args.max,
            step_mm,
        },
        (None, Some(count)) => Positions::Random {
            count,
            min_mm: args.min,
            max_mm: args.max,
        },
        _ => bail!("give exactly one of --step (lattice) and --random (count)"),
    };
    let config = args
        .config
        .map(|bits| {
            Configuration::from_bits(bits).with_context(|| format!("--config {bits} is not 0-7"))
        })
        .transpose()?;
    let plan = SamplingPlan {
        positions,
        abc_deg: args.abc,
        orientation_spread_deg: args.orientation_spread,
        config,
        seed: args.seed,
    };
    let samples = simulate(&robot, &scenario, &plan)?;

    crate::refuse_overwriting(&args.output, &[&args.robot, &args.scenario])?;
    let file = File::create(&args.output)
        .with_context(|| format!("cannot create {}", args.output.display()))?;
    let mut writer = BufWriter::new(file);
    let scenario_name = args.scenario.file_name().map_or_else(
        || args.scenario.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let mut comments = describe(&robot, &scenario_name, &plan);
    comments.extend(args.comment);
    write_csv(&samples, &comments, &mut writer)
        .and_then(|()| writer.flush())
        .with_context(|| format!("cannot write {}", args.output.display()))?;

    let (mean_mm, max_mm) = position_error_stats_mm(&samples);
    eprintln!(
        "{}: {} samples of {}; position error mean {mean_mm:.3} mm, max {max_mm:.3} mm",
        args.output.display(),
        samples.len(),
        robot.name
    );
    Ok(())
}
