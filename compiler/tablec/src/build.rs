//! `tablec build`.

use std::path::PathBuf;
use std::time::Instant;

use adwi_compile::build::compile;
use adwi_compile::samples::{read_samples, ColumnMap};
use adwi_compile::write::write_atomically;
use adwi_robot::calibrate::{CalibrateOptions, Calibration};
use adwi_robot::Robot;
use anyhow::{bail, Context};

#[derive(clap::Args)]
pub struct Args {
    /// The sample database (CSV: x,y,z and dx,dy,dz or mx,my,mz; see the README).
    samples: PathBuf,
    /// Where to write the table (written to a temporary file, then renamed).
    #[arg(short, long)]
    output: PathBuf,
    /// Column mapping for files named otherwise: `x=x_t,y=y_t,dx=-x_dif,...`
    /// (`-` negates).
    #[arg(long, value_name = "MAP")]
    columns: Option<String>,
    #[command(flatten)]
    table: crate::table_options::TableOptions,
    /// The robot model (TOML), for --hybrid.
    #[arg(long, value_name = "ROBOT.toml")]
    robot: Option<PathBuf>,
    /// Build a hybrid table: identify the robot's kinematic deviations from the samples
    /// (which need j1..j6), then tabulate the residuals the calibrated model leaves. Query
    /// it with the target's joint angles.
    #[arg(long, requires = "robot")]
    hybrid: bool,
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
    let columns =
        ColumnMap::parse(args.columns.as_deref().unwrap_or("")).map_err(anyhow::Error::msg)?;
    let samples = read_samples(&args.samples, &columns)?;
    let (w1, w2) = args.table.weights();
    let options = args.table.build_options();
    let (_, _, plan) = adwi_compile::build::resolve(&samples, &options)?;
    let reachable =
        adwi_compile::build::max_covered_cells(plan.samples, plan.radius_mm, plan.cell_mm);
    if plan.cells > 100_000 && plan.cells as f64 > 10.0 * reachable {
        eprintln!(
            "warning: the grid's {} cells are mostly empty: at most {:.0} of them lie within ε = \
             {:.3} mm of a sample (samples along a line or a plane?); the table will be about \
             {} — give --bounds around the samples, or a larger --cell",
            plan.cells,
            reachable.min(plan.cells as f64),
            plan.radius_mm,
            adwi_compile::build::human_bytes(adwi_compile::build::estimated_table_bytes(
                plan.cells as u128,
                plan.samples,
                plan.radius_mm,
                plan.cell_mm,
                options.max_neighbours
            ))
        );
    }
    let bar = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(plan.cells as u64)
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} cells, {eta} left")
            .context("progress bar template")?
            .progress_chars("=> "),
    );
    bar.set_message("compiling");
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = args.threads {
        pool = pool.num_threads(n);
    }
    let pool = pool.build().context("cannot start worker threads")?;
    let mut calibration = None;
    let (bytes, report) = match (&args.robot, args.hybrid) {
        (Some(robot_path), true) => {
            let robot = Robot::load(robot_path)
                .with_context(|| format!("cannot load the robot {}", robot_path.display()))?;
            bar.set_message("identifying");
            let identified = pool.install(|| {
                adwi_robot::calibrate::identify(&robot, &samples, &CalibrateOptions::default())
            })?;
            bar.set_message("compiling");
            let built = pool.install(|| {
                adwi_compile::hybrid::compile(
                    &samples,
                    &identified.kinematic_model(),
                    &options,
                    &|n| bar.inc(n),
                )
            })?;
            calibration = Some((identified, built.residual_position_rms_mm));
            (built.bytes, built.report)
        }
        (Some(_), false) => {
            bail!("--robot is only used by --hybrid: add --hybrid, or drop --robot")
        }
        _ => pool.install(|| compile(&samples, &options, &|n| bar.inc(n)))?,
    };
    bar.finish_and_clear();
    write_atomically(&args.output, &bytes)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    if !args.quiet {
        let derived = |yes| if yes { " (derived: default)" } else { "" };
        let spacing = report
            .spacing_mm
            .map_or("n/a".to_string(), |s| format!("{s:.3} mm"));
        let g = report.grid;
        println!(
            "samples        {} from {}",
            report.samples,
            args.samples.display()
        );
        println!("spacing        {spacing} (median nearest-neighbour distance)");
        println!(
            "radius ε       {:.3} mm{}",
            report.radius_mm,
            derived(report.radius_derived)
        );
        println!(
            "cell           {:.3} mm{}",
            report.cell_mm,
            derived(report.cell_derived)
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
            report.cells,
            report.mean_list_len,
            report.max_list_len
        );
        if let Some((c, residual_rms_mm)) = &calibration {
            print_calibration(c, *residual_rms_mm);
        }
        println!(
            "method         k {}, w1 {}, w2 {}, r {}, [λ] {}, [ζ] {}, screen (40) {}",
            args.table.k,
            w1,
            w2,
            args.table.power,
            args.table.lambda_min,
            args.table.zeta_min,
            if args.table.no_consistency_screen {
                "off"
            } else {
                "on"
            }
        );
        match args.table.joint_radius.filter(|r| *r > 0.0) {
            Some(deg) => println!(
                "joint screen   every joint within {deg}° of the target's, when queried with joints"
            ),
            None => println!("joint screen   off"),
        }
        println!(
            "wrote          {} ({} bytes) in {:.2} s",
            args.output.display(),
            report.table_bytes,
            started.elapsed().as_secs_f64()
        );
    }
    if let Some((c, _)) = &calibration {
        warn_unidentifiable(c);
    }
    Ok(())
}

/// What identification found, as `tablec build --hybrid` reports it: the calibration's
/// quality and, above all, which parameters the data could not identify (they stay at
/// their nominal values).
fn print_calibration(c: &Calibration, residual_rms_mm: f64) {
    println!(
        "calibration    {} parameters identified, {} unidentifiable, condition number {:.1}, {} iterations{}",
        c.identified.len(),
        c.unidentifiable.len(),
        c.condition_number,
        c.iterations,
        if c.converged { "" } else { " (not converged)" }
    );
    println!(
        "position RMS   {:.4} mm before, {:.4} mm after calibration (table residuals {:.4} mm)",
        c.initial_position_rms_mm, c.position_rms_mm, residual_rms_mm
    );
    if let Some(r) = c.orientation_rms_rad {
        println!("orient. RMS    {:.4} mrad after calibration", r * 1e3);
    }
    let identified: Vec<String> = c
        .identified
        .iter()
        .map(|p| {
            let v = c.deviations[p.column()];
            if p.is_length() {
                format!("{p} {v:+.4} mm")
            } else {
                format!("{p} {:+.4} mrad", v * 1e3)
            }
        })
        .collect();
    println!("identified     {}", identified.join(", "));
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
