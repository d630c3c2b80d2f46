//! `tablec build`.

use std::path::PathBuf;
use std::time::Instant;

use adwi_compile::build::{compile_plan, BuildReport, ServedField};
use adwi_compile::hybrid;
use adwi_compile::write::write_atomically;
use adwi_robot::calibrate::{CalibrateOptions, Calibration};
use anyhow::{bail, Context};

use adwi_robot::measured::Registered;

#[derive(clap::Args)]
pub struct Args {
    /// The sample database (CSV: x,y,z and dx,dy,dz or mx,my,mz; see the README).
    samples: PathBuf,
    /// Where to write the table (written to a temporary file, then renamed).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    read: crate::read_options::ReadOptions,
    #[command(flatten)]
    table: crate::table_options::TableOptions,
    /// The robot file (TOML, or URDF by its .urdf extension), for --hybrid.
    #[arg(long, value_name = "ROBOT")]
    robot: Option<PathBuf>,
    #[command(flatten)]
    links: crate::RobotLinks,
    /// Build a hybrid table: identify the robot's kinematic deviations from the samples
    /// (which need j1..jn), then tabulate the residuals the calibrated model leaves. Query
    /// it with the target's joint angles.
    #[arg(long, requires = "robot")]
    hybrid: bool,
    /// Identify each revolute joint's gravity compliance (µrad/(N·m)) with the geometry:
    /// the arm deflected by the gravity torque of the links it carries. The robot file
    /// must give link masses (mass_kg, com_mm per joint).
    #[arg(long, requires = "hybrid")]
    compliance: bool,
    /// The frame the measured poses are in: `base` (the robot's), or `tracker` (a laser
    /// tracker's own frame: joints j1..jn and measured mx,my,mz, optionally a measured
    /// orientation; the tracker-to-base and flange-to-probe transforms are registered
    /// first and refined by the identification).
    #[arg(
        long,
        value_enum,
        value_name = "FRAME",
        default_value_t,
        requires = "hybrid"
    )]
    measured_in: crate::measured_in::MeasuredIn,
    /// Choose k and ε by k-fold cross-validation on these samples alone (k in 4, 8, 12; ε
    /// of 1.5, 2 or 3 sample spacings), scoring the method the table serves (the hybrid
    /// with --hybrid); then, with those, what the served field holds (--served-field
    /// method, kriging, or with --hybrid kriging-tool-axis), scoring the served tier. The
    /// choices and the cross-validated mean are recorded in the table (`tablec inspect`).
    /// The other options apply to every candidate.
    #[arg(long, conflicts_with_all = ["k", "radius"])]
    tune: bool,
    /// Folds of --tune's cross-validation.
    #[arg(long, default_value_t = 5, value_name = "K", requires = "tune")]
    tune_folds: usize,
    /// Worker threads [default: all cores]; the table is the same for any count.
    #[arg(long)]
    threads: Option<usize>,
    /// No progress bar or summary.
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let started = Instant::now();
    let mut inputs = vec![args.samples.as_path()];
    inputs.extend(args.robot.as_deref());
    crate::refuse_overwriting(&args.output, &inputs)?;
    let (columns, read) = args.read.resolve()?;
    let (registered, samples) = crate::measured_in::read_samples(
        args.measured_in,
        args.robot.as_deref(),
        &args.links,
        &args.samples,
        &columns,
        &read,
    )?;
    let mut options = args.table.build_options();
    let calibrate_options = CalibrateOptions {
        compliance: args.compliance,
        ..CalibrateOptions::default()
    };
    if args.tune {
        let robot = match (&registered, &args.robot, args.hybrid) {
            (Some(r), _, true) => Some(r.robot.clone()),
            (None, Some(path), true) => Some(args.links.load(path)?),
            _ => None,
        };
        let report = adwi_eval::tune::tune(
            &samples,
            robot.as_ref(),
            &options,
            &calibrate_options,
            args.tune_folds,
            0,
        )?;
        if !args.quiet {
            print_tuning(&report);
        }
        options = report.options;
    }
    let plan = adwi_compile::build::plan(&samples, &options)?;
    let cells = plan.cells();
    if plan.is_mostly_empty() {
        eprintln!(
            "warning: the grid's {cells} cells are mostly empty: at most {:.0} of them lie \
             within ε = {:.3} mm of a sample (samples along a line or a plane?); the table \
             will be about {} — give --bounds around the samples, or a larger --cell",
            plan.coverable_cells(),
            plan.params.radius_mm,
            adwi_compile::build::human_bytes(plan.estimated_table_bytes())
        );
    }
    let bar = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(cells as u64)
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} cells, {eta} left")
            .context("progress bar template")?
            .progress_chars("=> "),
    );
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = args.threads {
        pool = pool.num_threads(n);
    }
    let pool = pool.build().context("cannot start worker threads")?;
    let progress = |n| bar.inc(n);
    let mut calibration = None;
    let (bytes, report) = match (&args.robot, args.hybrid) {
        (Some(robot_path), true) => {
            let robot = match &registered {
                Some(r) => r.robot.clone(),
                None => args.links.load(robot_path)?,
            };
            bar.set_message("identifying");
            let identified = pool.install(|| {
                adwi_robot::calibrate::identify(&robot, &samples, &calibrate_options)
            })?;
            bar.set_message("compiling");
            let model = identified.prepared_model();
            let built = pool.install(|| hybrid::compile(&samples, &model, &plan, &progress))?;
            calibration = Some((identified, built.residual_position_rms_mm));
            (built.bytes, built.report)
        }
        (Some(_), false) => {
            bail!("--robot is only used by --hybrid: add --hybrid, or drop --robot")
        }
        _ => {
            bar.set_message("compiling");
            let hash = samples.source_hash();
            pool.install(|| compile_plan(&samples, &plan, None, hash, &progress))?
        }
    };
    bar.finish_and_clear();
    write_atomically(&args.output, &bytes)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    if !args.quiet {
        print_summary(
            &args,
            &report,
            &samples,
            calibration.as_ref(),
            registered.as_ref(),
            started,
        );
    }
    if let Some((c, _)) = &calibration {
        warn_unidentifiable(c);
    }
    Ok(())
}

/// What was built: the plan as derived, the candidate lists, the method and the file.
fn print_summary(
    args: &Args,
    report: &BuildReport,
    samples: &adwi_samples::SampleSet,
    calibration: Option<&(Calibration, f64)>,
    registered: Option<&Registered>,
    started: Instant,
) {
    let plan = &report.plan;
    let derived = |yes| if yes { " (derived: default)" } else { "" };
    let spacing = plan
        .spacing_mm
        .map_or("n/a".to_string(), |s| format!("{s:.3} mm"));
    let g = plan.grid;
    let m = plan.params;
    println!(
        "samples        {} from {}",
        plan.samples,
        args.samples.display()
    );
    if let Some(r) = &samples.repeats {
        let orientation = match (r.orientation_max_mrad, r.orientation_rms_mrad) {
            (Some(max), Some(rms)) => format!("; orientation max {max:.4} mrad, RMS {rms:.4} mrad"),
            _ => String::new(),
        };
        println!(
            "repeats        {} poses on {} rows (at most {} of one pose), each averaged into one \
             sample; errors about their means: max {:.4} mm, RMS {:.4} mm{orientation}",
            r.poses, r.rows, r.max_rows_per_pose, r.position_max_mm, r.position_rms_mm
        );
    }
    println!("spacing        {spacing} (median nearest-neighbour distance)");
    println!(
        "radius ε       {:.3} mm{}",
        m.radius_mm,
        derived(plan.radius_derived)
    );
    println!(
        "cell           {:.3} mm{}",
        g.cell_mm,
        derived(plan.cell_derived)
    );
    println!(
        "grid           {} × {} × {} cells from ({:.3}, {:.3}, {:.3}) to ({:.3}, {:.3}, {:.3}) mm",
        g.dims[0],
        g.dims[1],
        g.dims[2],
        g.origin_mm[0],
        g.origin_mm[1],
        g.origin_mm[2],
        g.max_mm()[0],
        g.max_mm()[1],
        g.max_mm()[2]
    );
    println!(
        "candidates     {} distinct lists, {} of {} cells covered, mean {:.1}, max {} per cell",
        report.distinct_lists,
        report.cells_covered,
        plan.cells(),
        report.mean_list_len,
        report.max_list_len
    );
    if let Some(r) = registered {
        crate::measured_in::print_registration(r);
    }
    if let Some((c, residual_rms_mm)) = calibration {
        crate::calibrate::print_identification(c, Some(*residual_rms_mm));
        if let Some(r) = registered {
            crate::measured_in::print_refined(&r.registration.refined(c, samples));
        }
    }
    println!("method         {}", crate::describe_method(&m));
    println!(
        "joint screen   {}",
        crate::describe_joint_screen(plan.joint_radius_rad)
    );
    println!("served field   {}", describe_served_field(report));
    println!(
        "wrote          {} ({} bytes) in {:.2} s",
        args.output.display(),
        report.table_bytes,
        started.elapsed().as_secs_f64()
    );
}

/// Every candidate of --tune with its cross-validated mean, the chosen one marked.
/// What the served field's nodes hold, with a kriging's hyperparameters per component.
fn describe_served_field(report: &BuildReport) -> String {
    if report.node_sets == 0 {
        return "none (the exact tier answers)".to_string();
    }
    let name = report.plan.served_field.name();
    if report.served_kriging.is_empty() {
        return name.to_string();
    }
    const COMPONENTS: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];
    let turning = report.plan.served_field == ServedField::KrigingToolAxis;
    let choices: Vec<String> = report
        .served_kriging
        .iter()
        .zip(COMPONENTS)
        .map(|(c, component)| {
            let weight = if turning {
                format!(", w {}", c.modulation)
            } else {
                String::new()
            };
            format!(
                "{component} ℓ {:.1} mm, vertical ×{}, λ {}{weight}",
                c.length_scale, c.vertical_scale, c.relative_nugget
            )
        })
        .collect();
    let legend = if turning {
        ", weight w of the part turning with the tool"
    } else {
        ""
    };
    format!(
        "{name}; by likelihood (length scale ℓ, vertical distances × a scale, nugget λ per sill{legend}): {}",
        choices.join("; ")
    )
}

fn print_tuning(report: &adwi_eval::tune::TuneReport) {
    println!(
        "tuning         {}-fold cross-validation of `{}` on the samples alone:",
        report.folds,
        report.method.name()
    );
    for (i, c) in report.candidates.iter().enumerate() {
        let mean = c
            .cv_mean_mm
            .map_or("—".to_string(), |m| format!("{m:.4} mm mean"));
        println!(
            "  {} k {:>2}, ε {:>9.3} mm: {mean}, {} missed",
            if i == report.chosen { "*" } else { " " },
            c.k,
            c.radius_mm,
            c.missed
        );
    }
    if let Some(chosen) = report.candidates.get(report.chosen) {
        for c in &report.served {
            let mean = c
                .cv_mean_mm
                .map_or("—".to_string(), |m| format!("{m:.4} mm mean"));
            println!(
                "  {} served field {:<17} (k {}, ε {:.3} mm): {mean}, {} missed",
                if c.field == report.options.served_field {
                    "*"
                } else {
                    " "
                },
                c.field.name(),
                chosen.k,
                chosen.radius_mm,
                c.missed
            );
        }
    }
}

/// Warns, on standard error and even with --quiet, about the parameters the data cannot
/// identify: the table is still built (they keep their nominal values, and the table
/// interpolates what they would have explained), but the user should know.
fn warn_unidentifiable(c: &Calibration) {
    if !c.unidentifiable.is_empty() {
        let dropped: Vec<String> = c
            .unidentifiable
            .iter()
            .map(|(p, ratio)| format!("{p} ({ratio:.1e})"))
            .collect();
        eprintln!(
            "warning: unidentifiable from these samples (kept nominal; independent fraction in brackets): {}",
            dropped.join(", ")
        );
    }
}
