//! `tablec eval`.

use std::path::PathBuf;

use adwi_eval::{EvalOptions, Method, Protocol};
use adwi_robot::calibrate::CalibrateOptions;
use adwi_robot::measured::Input;
use anyhow::{bail, Context};

use crate::measured_in::MeasuredIn;

#[derive(clap::Args)]
pub struct Args {
    /// The sample database (CSV), as for `tablec build`.
    samples: PathBuf,
    /// A validation set (CSV with errors, same columns as the samples): build from all
    /// samples, evaluate at every validation point.
    #[arg(long, value_name = "FILE", conflicts_with = "folds")]
    validation: Option<PathBuf>,
    /// Use only the first N validation points.
    #[arg(long, value_name = "N", requires = "validation")]
    limit: Option<usize>,
    /// k-fold cross-validation of the samples alone, with this many folds.
    #[arg(long, value_name = "K")]
    folds: Option<usize>,
    /// Seed of the k-fold split.
    #[arg(long, default_value_t = 0, requires = "folds")]
    seed: u64,
    /// How the samples and the validation set are read, as for `tablec build`.
    #[command(flatten)]
    read: crate::read_options::ReadOptions,
    /// Methods to compare, comma-separated: paper, paper-joint, idw, grid, kriging,
    /// kinematic, hybrid [default: every one the data allow].
    #[arg(long, value_delimiter = ',', value_name = "LIST")]
    methods: Option<Vec<Method>>,
    /// The robot file (TOML, or URDF by its .urdf extension; e.g. tables/ur5/robot.toml),
    /// for `kinematic` and `hybrid`.
    #[arg(long, value_name = "ROBOT")]
    robot: Option<PathBuf>,
    #[command(flatten)]
    links: crate::RobotLinks,
    /// The frame the measured poses are in, as for `tablec build`: `tracker` registers the
    /// samples (and the validation set, taken in the same tracker frame with the same
    /// probe) to the robot first.
    #[arg(
        long,
        value_enum,
        value_name = "FRAME",
        default_value_t,
        requires = "robot"
    )]
    measured_in: MeasuredIn,
    /// With `--measured-in tracker` and `--validation`: register the validation set on its
    /// own (a series measured after the tracker moved): the robot's frame in the new
    /// tracker frame is fitted to the TCP positions the samples' calibration predicts, the
    /// probe kept. Six rigid parameters come from the validation points this way; no
    /// method is trained on their errors.
    #[arg(long, requires = "validation")]
    register_validation_apart: bool,
    /// Kinematic identification: relative pivot below which a parameter is unidentifiable.
    #[arg(long, default_value_t = CalibrateOptions::default().rank_tolerance)]
    rank_tol: f64,
    /// Kinematic identification: keep every parameter the pivoting keeps, even those whose
    /// estimates are implausible or within a few standard errors of zero (by default they
    /// are held at nominal, with the reason reported).
    #[arg(long)]
    keep_untrustworthy: bool,
    /// Kinematic identification (kinematic and hybrid methods): also identify each
    /// revolute joint's gravity compliance (µrad/(N·m)), the arm deflected by the gravity
    /// torque of the links it carries. The robot file must give link masses (mass_kg,
    /// com_mm per joint).
    #[arg(long, requires = "robot")]
    compliance: bool,
    #[command(flatten)]
    table: crate::table_options::TableOptions,
    /// Write the figures as CSV.
    #[arg(long, value_name = "FILE")]
    csv: Option<PathBuf>,
    /// Write the whole evaluation (figures, per-point predictions, identification) as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Write an HTML report with plots to DIR/index.html.
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
    /// Print nothing but errors and warnings.
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut inputs = vec![args.samples.as_path()];
    inputs.extend(args.validation.as_deref());
    inputs.extend(args.robot.as_deref());
    let page = args.report.as_ref().map(|dir| dir.join("index.html"));
    for output in [&args.csv, &args.json, &page].into_iter().flatten() {
        crate::refuse_overwriting(output, &inputs)?;
    }
    let (columns, read) = args.read.resolve()?;
    let (registered, samples) = crate::measured_in::read_samples(
        args.measured_in,
        args.robot.as_deref(),
        &args.links,
        &args.samples,
        &columns,
        &read,
    )?;
    if args.register_validation_apart && registered.is_none() {
        bail!("--register-validation-apart needs --measured-in tracker");
    }
    // The identification of all samples, made once: for registering a validation series
    // apart and for printing the refined transforms.
    let mut registered_apart = None;
    let calibrate_options = CalibrateOptions {
        rank_tolerance: args.rank_tol,
        hold_untrustworthy: !args.keep_untrustworthy,
        compliance: args.compliance,
        ..CalibrateOptions::default()
    };
    let protocol = match (&args.validation, args.folds) {
        (Some(path), None) => {
            // Registered apart, into the frame of the samples' calibration alone, as the
            // kinematic method makes it.
            let (mut validation, apart) = adwi_robot::measured::read_validation(
                Input::File(path),
                &columns,
                &read,
                registered.as_ref(),
                args.register_validation_apart
                    .then_some((&samples, &calibrate_options)),
            )?;
            registered_apart = apart;
            if let Some(n) = args.limit {
                if n == 0 {
                    bail!("--limit must be at least 1");
                }
                let n = n.min(validation.len());
                validation = adwi_eval::subset(&validation, &(0..n).collect::<Vec<_>>());
            }
            Protocol::Validation(validation)
        }
        (None, Some(folds)) => Protocol::KFold {
            folds,
            seed: args.seed,
        },
        _ => bail!("give a validation set (--validation FILE) or a fold count (--folds K)"),
    };
    let robot = match (&registered, &args.robot) {
        (Some(r), _) => Some(r.robot.clone()),
        (None, Some(path)) => Some(args.links.load(path)?),
        (None, None) => None,
    };
    let options = EvalOptions {
        methods: args.methods.clone(),
        build: args.table.build_options(),
        robot,
        calibrate: calibrate_options,
        ..EvalOptions::default()
    };
    let evaluation = adwi_eval::evaluate(&samples, &protocol, &options)?;

    for c in evaluation.calibrations.iter().take(1) {
        if !c.unidentifiable.is_empty() {
            let names: Vec<&str> = c.unidentifiable.iter().map(|(n, _)| n.as_str()).collect();
            eprintln!(
                "warning: {} kinematic parameters cannot be identified from these samples and \
                 stay at nominal: {}",
                names.len(),
                names.join(", ")
            );
        }
        if !c.converged {
            eprintln!(
                "warning: kinematic identification stopped after {} iterations without \
                 converging",
                c.iterations
            );
        }
    }
    if !args.quiet {
        if let Some(r) = &registered {
            crate::measured_in::print_registration(r);
            // The transforms refined by an identification of all samples.
            let identified = registered_apart.as_ref().map(|(_, c)| c);
            crate::measured_in::print_refined(&r.refined_by(
                &samples,
                &options.calibrate,
                identified,
            )?);
        }
        if let Some((v, _)) = &registered_apart {
            crate::measured_in::print_validation_registration(v);
        }
        print!("{}", adwi_eval::output::terminal_table(&evaluation));
    }
    if let Some(path) = &args.csv {
        std::fs::write(path, adwi_eval::output::csv(&evaluation))
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(path) = &args.json {
        let text = adwi_eval::output::json(&evaluation).context("cannot encode the evaluation")?;
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(dir) = &args.report {
        let command = std::env::args()
            .map(|a| if a.contains(' ') { format!("'{a}'") } else { a })
            .collect::<Vec<_>>()
            .join(" ");
        let page = adwi_eval::report::write(&evaluation, &command, dir)?;
        if !args.quiet {
            println!("report: {}", page.display());
        }
    }
    Ok(())
}
