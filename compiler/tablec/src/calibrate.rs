//! `tablec calibrate`: kinematic identification alone, its parameters with their standard
//! errors, and the calibrated robot written as a robot file and as URDF.

use std::path::PathBuf;

use adwi_compile::write::write_atomically;
use adwi_robot::calibrate::{identify, CalibrateOptions, Calibration};
use adwi_robot::measured::{Input, Registered};
use adwi_samples::read_samples_with;
use anyhow::Context;

use crate::measured_in::MeasuredIn;

#[derive(clap::Args)]
pub struct Args {
    /// The sample database (CSV with joint values j1..jn), as for `tablec build`.
    samples: PathBuf,
    #[command(flatten)]
    read: crate::read_options::ReadOptions,
    /// The robot file (TOML, or URDF by its .urdf extension).
    #[arg(long, value_name = "ROBOT")]
    robot: PathBuf,
    #[command(flatten)]
    links: crate::RobotLinks,
    /// Write the calibrated robot as a robot file (TOML), loadable by every `--robot`.
    #[arg(short, long, value_name = "ROBOT.toml")]
    output: Option<PathBuf>,
    /// Write the calibrated robot as URDF (joint origins adjusted, the tool as a fixed
    /// joint to a `calibrated_tcp` link).
    #[arg(long, value_name = "ROBOT.urdf")]
    urdf: Option<PathBuf>,
    /// The frame the measured poses are in: `tracker` registers tracker-frame measurements
    /// (joints and measured probe poses) to the robot first (see `tablec build --help`).
    #[arg(long, value_enum, value_name = "FRAME", default_value_t)]
    measured_in: crate::measured_in::MeasuredIn,
    /// Relative pivot below which a parameter is unidentifiable.
    #[arg(long, default_value_t = CalibrateOptions::default().rank_tolerance)]
    rank_tol: f64,
    /// Identify each revolute joint's gravity compliance (µrad/(N·m)) with the geometry:
    /// the arm deflected by the gravity torque of the links it carries. The robot file
    /// must give link masses (mass_kg, com_mm per joint).
    /// The calibrated robot file carries them (compliance_urad_per_nm).
    #[arg(long)]
    compliance: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let inputs = [args.samples.as_path(), args.robot.as_path()];
    for output in [&args.output, &args.urdf].into_iter().flatten() {
        crate::refuse_overwriting(output, &inputs)?;
    }
    let (columns, read) = args.read.resolve()?;
    let file_robot = args.links.load(&args.robot)?;
    let (registered, samples, robot) = match args.measured_in {
        MeasuredIn::Tracker => {
            let (registered, samples) =
                Registered::read(Input::File(&args.samples), &columns, &read, file_robot)?;
            crate::measured_in::print_registration(&registered);
            let robot = registered.robot.clone();
            (Some(registered), samples, robot)
        }
        MeasuredIn::Base => (
            None,
            read_samples_with(&args.samples, &columns, &read)?,
            file_robot,
        ),
    };
    let options = CalibrateOptions {
        rank_tolerance: args.rank_tol,
        compliance: args.compliance,
        ..CalibrateOptions::default()
    };
    let c = identify(&robot, &samples, &options)?;
    if let Some(registered) = &registered {
        crate::measured_in::print_refined(&registered.registration.refined(&c, &samples));
    }
    print_identification(&c, None);
    let comment = [
        format!(
            "{} calibrated from {} ({} samples): position RMS {:.4} mm before, {:.4} mm after.",
            robot.name,
            args.samples.display(),
            samples.len(),
            c.initial_position_rms_mm,
            c.position_rms_mm
        ),
        "Written by tablec calibrate.".to_string(),
    ];
    if let Some(path) = &args.output {
        let text = c.calibrated_robot().to_toml_string(&comment);
        write_atomically(path, text.as_bytes())
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote          {}", path.display());
    }
    if let Some(path) = &args.urdf {
        if args.compliance {
            eprintln!(
                "warning: URDF has no place for the identified compliances: {} leaves them out \
                 (the robot file, -o, carries them)",
                path.display()
            );
        }
        let text = c.calibrated_robot().to_urdf_string(&comment)?;
        write_atomically(path, text.as_bytes())
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote          {}", path.display());
    }
    Ok(())
}

/// What identification found, as `build --hybrid` and `calibrate` report it: how many
/// parameters were identified, held at nominal for want of trust, or unidentifiable; the
/// residuals before and after (and, for a hybrid table, what its residual tier starts
/// from); then every parameter's value, standard error, strongest correlation, status and
/// reason.
pub fn print_identification(c: &Calibration, table_residual_rms_mm: Option<f64>) {
    println!(
        "calibration    {} parameters identified, {} held at nominal, {} unidentifiable, condition number {:.1}, {} iterations{}",
        c.identified.len(),
        c.held().len(),
        c.unidentifiable.len(),
        c.condition_number,
        c.iterations,
        if c.converged { "" } else { " (not converged)" }
    );
    let table =
        table_residual_rms_mm.map_or(String::new(), |r| format!(" (table residuals {r:.4} mm)"));
    println!(
        "position RMS   {:.4} mm before, {:.4} mm after; residual σ {:.4} mm per coordinate{table}",
        c.initial_position_rms_mm, c.position_rms_mm, c.residual_sigma_mm
    );
    if let Some(r) = c.orientation_rms_rad {
        println!("orient. RMS    {:.4} mrad after", r * 1e3);
    }
    print!(
        "{}",
        adwi_eval::output::parameter_table(&adwi_eval::ParameterRow::of(c))
    );
}
