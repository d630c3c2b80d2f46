//! The planning job: which poses to measure, written as a CSV the robot runs and
//! `tablec simulate --poses` measures (`tablec plan`).

use std::path::PathBuf;

use adwi_compile::nugget_kriging::ResidualGp;
use adwi_identify::calibrate::CalibrateOptions;
use adwi_measure::field::{FieldPrior, Kernel};
use adwi_measure::plan::{
    check, check_options, plan, write_csv, AllowedOrientations, Branches, ConfigLabel, Criterion,
    Plan, PlanError, PlanOptions, Prior, SetFigures, TrackerSight,
};
use adwi_output::OutputPlan;
use adwi_robot::{InverseKinematics, Robot};
use serde::Deserialize;

use crate::args::{parse_number_list, parse_triple, RobotArgs};
use crate::inputs::{load_robot, Inputs};
use crate::{JobError, Progress};

/// Plan the poses to measure: every option of `tablec plan`.
#[derive(clap::Args, Deserialize, Debug, Clone)]
#[serde(default)]
pub struct PlanArgs {
    /// The robot (required), e.g. tables/ur5/robot.toml.
    #[command(flatten)]
    #[serde(flatten)]
    pub robot: RobotArgs,
    /// Box corner x,y,z (mm, base frame) the TCP stays in (with --max).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true, requires = "max")]
    pub min: Option<[f64; 3]>,
    /// Opposite box corner x,y,z (mm, base frame).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true, requires = "min")]
    pub max: Option<[f64; 3]>,
    /// A further box, xmin,ymin,zmin,xmax,ymax,zmax (mm; repeatable): the TCP in any box.
    #[arg(id = "box", long = "box", value_name = "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX", allow_hyphen_values = true,
          value_parser = parse_six)]
    #[serde(rename = "box", deserialize_with = "boxes")]
    pub boxes: Vec<[f64; 6]>,
    /// Poses to plan.
    #[arg(long)]
    pub count: usize,
    /// Candidates to choose from [default: 10 × count, at least 1,000, at most 20,000].
    #[arg(long)]
    pub pool: Option<usize>,
    /// Seed of the candidates: the same seed gives the same file byte for byte.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// A laser tracker's position x,y,z (mm, base frame) that must see every pose.
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub tracker: Option<[f64; 3]>,
    /// The tracker's distance range MIN,MAX (mm).
    #[arg(long, value_name = "MIN,MAX", value_parser = parse_pair, requires = "tracker")]
    #[serde(deserialize_with = "pair")]
    pub tracker_range: Option<[f64; 2]>,
    /// The reflector's acceptance cone: the tool's z axis within this angle (degrees) of
    /// the line to the tracker.
    #[arg(long, requires = "tracker")]
    pub sight_cone_deg: Option<f64>,
    /// The tracker's maximum permissible error of a point coordinate, A + B·d: A (µm) and
    /// B (µm per m of distance to the tracker), as data sheets give it (ISO 10360-10). Each
    /// pose's information is weighed by 1/σ², σ = MPE/2, so that far poses count less and
    /// the variances are in mm².
    #[arg(long, value_name = "A,B", value_parser = parse_pair, requires = "tracker")]
    #[serde(deserialize_with = "pair")]
    pub tracker_mpe_um: Option<[f64; 2]>,
    /// An allowed tool orientation A,B,C (KUKA degrees; repeatable) [default: any].
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub abc: Vec<[f64; 3]>,
    /// How far the tool may turn from an allowed orientation, degrees.
    #[arg(long, default_value_t = 15.0)]
    pub orientation_tolerance: f64,
    /// Inverse-kinematics branches of a pose (with --abc): `home`, the one the robot works
    /// in (nearest the home posture); `all`, every branch within the limits (shoulder,
    /// elbow and wrist flips; another elbow angle of a redundant arm) as further
    /// candidates, the workspace staying the home branch's.
    #[arg(long, value_enum, default_value_t)]
    pub branches: BranchesArg,
    /// The selection's weight on coverage (maximin distance) against the criterion, 0 to 1.
    #[arg(long, default_value_t = 0.3)]
    pub coverage: f64,
    /// The design criterion: `i` (the mean prediction variance of the TCP position over
    /// the candidates, what a held-out error measures), `a` (the parameters' mean squared
    /// error, mm and mrad), `ia` (both, each relative to a spread design) or `d` (the
    /// log-determinant of the identification's information).
    #[arg(long, value_enum, default_value_t)]
    pub criterion: CriterionArg,
    /// Samples measured already (a sample file with j1..jn, as build reads; repeatable):
    /// the plan adds the poses they lack, and covers where they are not.
    #[arg(long)]
    pub measured: Vec<PathBuf>,
    /// A table built from the samples measured already: the poses go where its residual
    /// field's kriging variance is largest and most reducible (instead of the coverage).
    #[arg(long)]
    pub table: Option<PathBuf>,
    /// Exchange passes after the greedy selection: each pose in turn swapped for the
    /// candidate that improves the criterion most (0 to 20; a pass that swaps nothing
    /// ends them).
    #[arg(long, default_value_t = 2)]
    pub exchange_passes: usize,
    /// Relative pivot below which a parameter is unidentifiable (as calibrate's).
    #[arg(long, default_value_t = CalibrateOptions::default().rank_tolerance)]
    pub rank_tol: f64,
    /// Worker threads [default: all cores].
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output CSV.
    #[arg(long, short)]
    pub output: PathBuf,
}

impl Default for PlanArgs {
    fn default() -> PlanArgs {
        PlanArgs {
            robot: RobotArgs::default(),
            min: None,
            max: None,
            boxes: Vec::new(),
            count: 0,
            pool: None,
            seed: 1,
            tracker: None,
            tracker_range: None,
            sight_cone_deg: None,
            tracker_mpe_um: None,
            abc: Vec::new(),
            orientation_tolerance: 15.0,
            branches: BranchesArg::default(),
            coverage: 0.3,
            criterion: CriterionArg::default(),
            measured: Vec::new(),
            table: None,
            exchange_passes: 2,
            rank_tol: CalibrateOptions::default().rank_tolerance,
            threads: None,
            output: PathBuf::new(),
        }
    }
}

fn parse_six(text: &str) -> Result<[f64; 6], String> {
    six_of(parse_number_list(text)?)
}

fn six_of(values: Vec<f64>) -> Result<[f64; 6], String> {
    values.try_into().map_err(|v: Vec<f64>| {
        format!(
            "six numbers are needed, xmin,ymin,zmin,xmax,ymax,zmax; {} given",
            v.len()
        )
    })
}

fn parse_pair(text: &str) -> Result<[f64; 2], String> {
    pair_of(parse_number_list(text)?)
}

fn pair_of(values: Vec<f64>) -> Result<[f64; 2], String> {
    values
        .try_into()
        .map_err(|v: Vec<f64>| format!("two numbers are needed, MIN,MAX; {} given", v.len()))
}

/// Boxes from lists of six numbers (Python's `box=[[...], ...]`).
fn boxes<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<[f64; 6]>, D::Error> {
    let values: Vec<Vec<f64>> = Vec::deserialize(d)?;
    values
        .into_iter()
        .map(|v| six_of(v).map_err(serde::de::Error::custom))
        .collect()
}

/// A range from a list of two numbers (Python's `tracker_range=[...]`).
fn pair<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<[f64; 2]>, D::Error> {
    let values: Option<Vec<f64>> = Option::deserialize(d)?;
    values
        .map(|v| pair_of(v).map_err(serde::de::Error::custom))
        .transpose()
}

/// The design criterion, as the command line names it.
#[derive(clap::ValueEnum, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum CriterionArg {
    /// D-optimality.
    D,
    /// I-optimality.
    #[default]
    I,
    /// A-optimality on the parameters (mm, mrad).
    A,
    /// I- and A-optimality together.
    Ia,
}

/// The inverse-kinematics branches, as the command line names them.
#[derive(clap::ValueEnum, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum BranchesArg {
    /// The branch nearest the home posture.
    #[default]
    Home,
    /// Every branch within the limits.
    All,
}

/// The smallest distance between two poses as the plan's header and `tablec plan` say it.
pub fn smallest_distance(min_distance_mm: Option<f64>) -> String {
    match min_distance_mm {
        Some(d) => format!("smallest TCP distance {d:.1} mm"),
        None => "a single pose".into(),
    }
}

/// The default pool: ten candidates per pose, at least 1,000 and at most 20,000; at least
/// the count.
fn default_pool(count: usize) -> usize {
    count.saturating_mul(10).clamp(1_000, 20_000).max(count)
}

/// The poses measured already (`--measured`) and the table's residual field (`--table`);
/// `None` without either.
fn prior(args: &PlanArgs, robot: &Robot) -> Result<Option<Prior>, JobError> {
    if args.measured.is_empty() && args.table.is_none() {
        return Ok(None);
    }
    let mut prior = Prior::default();
    // As build reads them: the robot's prismatic joints' columns are lengths.
    let (columns, read) = crate::args::Reading::default().resolve_for(Some(robot))?;
    for path in &args.measured {
        let samples = adwi_samples::read_samples_with(path, &columns, &read)?;
        if samples.joints.is_none() {
            return Err(JobError::option(
                "measured",
                format!(
                    "{}: no joint columns (j1..j{}); the plan weighs measured poses by their joints",
                    path.display(),
                    robot.joint_count()
                ),
            ));
        }
        for i in 0..samples.len() {
            let q = samples.joints_rad(i).expect("checked").to_vec();
            prior.joints.push(q);
            let (n, e) = (samples.nominal_mm[i], samples.error_mm[i]);
            prior
                .positions_mm
                .push([n[0] + e[0], n[1] + e[1], n[2] + e[2]]);
        }
    }
    if let Some(path) = &args.table {
        prior.field = Some(table_field(path)?);
    }
    Ok(Some(prior))
}

/// A table's samples, their residuals, and the kernel the residual field's likelihood
/// chooses for them (as a kriging served field's build does).
fn table_field(path: &std::path::Path) -> Result<FieldPrior, JobError> {
    // SAFETY: the mapping lives for this function; tablec and the Python package replace
    // tables by rename, never in place.
    let table = unsafe { adwi_runtime::Table::open(path) }.map_err(|source| JobError::Table {
        path: path.to_path_buf(),
        source,
    })?;
    let unreadable = || {
        JobError::option(
            "table",
            format!(
                "{}: a version-1 table does not keep its samples' residuals apart; build it again",
                path.display()
            ),
        )
    };
    let Some(adwi_runtime::Payload::V2(data)) = table.payload() else {
        return Err(unreadable());
    };
    let native =
        |v: &adwi_runtime::format::v2::ArchivedQuerySample| v.actual_mm.map(|x| x.to_native());
    let positions_mm: Vec<[f64; 3]> = data.samples.iter().map(native).collect();
    let residuals_mm: Vec<[f64; 3]> = data
        .errors_mm
        .iter()
        .map(|e| e.map(|x| x.to_native()))
        .collect();
    let n = positions_mm.len();
    if !(3..=adwi_measure::field::MAX_FIELD_SAMPLES).contains(&n) {
        return Err(JobError::option(
            "table",
            format!(
                "{}: {n} samples; the residual field's variance needs 3 to {}",
                path.display(),
                adwi_measure::field::MAX_FIELD_SAMPLES
            ),
        ));
    }
    let inputs: Vec<Vec<f64>> = positions_mm.iter().map(|p| p.to_vec()).collect();
    let values: Vec<Vec<f64>> = residuals_mm.iter().map(|r| r.to_vec()).collect();
    let gp = ResidualGp::fit_cartesian(&inputs, &values).map_err(|e| {
        JobError::option(
            "table",
            format!(
                "{}: its residual field cannot be fitted: {e}",
                path.display()
            ),
        )
    })?;
    let choices = gp.choices();
    let kernel = |c: usize| Kernel {
        length_scale_mm: choices[c].length_scale,
        vertical_scale: choices[c].vertical_scale,
        relative_nugget: choices[c].relative_nugget,
    };
    Ok(FieldPrior {
        positions_mm,
        residuals_mm,
        kernels: [kernel(0), kernel(1), kernel(2)],
    })
}

/// The units of a plan's variances: per σ², or mm² (and mm², mrad² for the parameters)
/// when the tracker's MPE weighs the poses.
pub fn variance_units(plan: &Plan) -> (&'static str, &'static str) {
    if plan.tracker_sigma_mm.is_some() {
        ("mm²", "mm², mrad²")
    } else {
        ("σ²", "σ²")
    }
}

/// The figures of a set of poses of `plan`, one line.
pub fn figures_line(plan: &Plan, f: &SetFigures) -> String {
    let (unit, parameter_unit) = variance_units(plan);
    let o = match &f.observability {
        Some(o) => format!(
            "O1 {:.4} O2 {:.2e} O3 {:.4} O4 {:.2e} O5 {:.4}, noise amplification {:.3}",
            o.o1, o.o2, o.o3, o.o4, o.o5, o.noise_amplification
        ),
        None => "a parameter undetermined: no observability indices".into(),
    };
    format!(
        "{:>5} poses: mean prediction variance {} {unit}, parameter variance {} {parameter_unit}; {o}",
        f.poses,
        figure(plan, f.mean_variance),
        figure(plan, f.parameter_variance)
    )
}

/// A variance of `plan` as printed: four decimals per σ², three significant digits in mm²
/// (a few 10⁻⁴ mm² from a tracker).
pub fn figure(plan: &Plan, v: f64) -> String {
    if plan.tracker_sigma_mm.is_some() {
        format!("{v:.3e}")
    } else {
        format!("{v:.4}")
    }
}

/// A plan checked and sized, ready to run.
pub struct PlanJob {
    args: PlanArgs,
    robot: Robot,
    options: PlanOptions,
    threads: rayon::ThreadPool,
    outputs: OutputPlan,
}

/// What a plan chose, and where it wrote it.
#[derive(Debug, Clone)]
pub struct Planned {
    /// The plan.
    pub plan: Plan,
    /// The robot's name.
    pub robot_name: String,
    /// The file written.
    pub output: PathBuf,
}

impl PlanJob {
    /// Checks `args`, loads the robot, sizes the selection and checks the output.
    ///
    /// # Errors
    ///
    /// A refused option (with its figure), an unreadable robot, an output that is an input.
    pub fn new(args: PlanArgs) -> Result<PlanJob, JobError> {
        if args.robot.robot.is_none() {
            return Err(JobError::Options(
                "plan needs the robot file (--robot)".into(),
            ));
        }
        let mut boxes_mm: Vec<([f64; 3], [f64; 3])> = Vec::new();
        match (args.min, args.max) {
            (Some(min), Some(max)) => boxes_mm.push((min, max)),
            (None, None) => {}
            _ => {
                return Err(JobError::Options(
                    "--min and --max give one box together".into(),
                ))
            }
        }
        boxes_mm.extend(
            args.boxes
                .iter()
                .map(|b| ([b[0], b[1], b[2]], [b[3], b[4], b[5]])),
        );
        if args.tracker.is_none()
            && (args.tracker_range.is_some()
                || args.sight_cone_deg.is_some()
                || args.tracker_mpe_um.is_some())
        {
            return Err(JobError::option(
                "tracker",
                "--tracker-range, --sight-cone-deg and --tracker-mpe-um need the tracker's \
                 position",
            ));
        }
        let tracker = args.tracker.map(|position_mm| TrackerSight {
            position_mm,
            range_mm: args.tracker_range.unwrap_or([0.0, f64::MAX]),
            sight_cone_deg: args.sight_cone_deg,
            mpe_um: args.tracker_mpe_um,
        });
        let options = PlanOptions {
            boxes_mm,
            count: args.count,
            pool: args.pool.unwrap_or(0),
            seed: args.seed,
            tracker,
            orientations: (!args.abc.is_empty()).then(|| AllowedOrientations {
                abc_deg: args.abc.clone(),
                tolerance_deg: args.orientation_tolerance,
            }),
            coverage_weight: args.coverage,
            rank_tolerance: args.rank_tol,
            criterion: match args.criterion {
                CriterionArg::D => Criterion::D,
                CriterionArg::I => Criterion::I,
                CriterionArg::A => Criterion::A,
                CriterionArg::Ia => Criterion::Ia,
            },
            exchange_passes: args.exchange_passes,
            prior: None,
            branches: match args.branches {
                BranchesArg::Home => Branches::Home,
                BranchesArg::All => Branches::All,
            },
        };
        let mut options = options;
        if args.pool.is_none() {
            options.pool = default_pool(args.count);
        }
        let refused = |e: PlanError| match e {
            PlanError::Option { name, reason } => JobError::option(name, reason),
            e => JobError::Plan(Box::new(e)),
        };
        // Every option checked before any file is read.
        check_options(&options).map_err(refused)?;
        let threads = crate::thread_pool(args.threads)?;
        let mut inputs = Inputs::default();
        let robot = load_robot(&args.robot, &mut inputs)?.expect("checked");
        for path in args.measured.iter().chain(&args.table) {
            inputs.add(path);
        }
        let outputs = OutputPlan::check(&[&args.output], &inputs.paths())?;
        options.prior = prior(&args, &robot)?;
        // Sized before any work: the measured poses, the selection's arithmetic.
        check(&robot, &options).map_err(refused)?;
        Ok(PlanJob {
            args,
            robot,
            options,
            threads,
            outputs,
        })
    }

    /// Plans the poses and writes them.
    ///
    /// # Errors
    ///
    /// Too few reachable candidates (with the figure), a Jacobian that cannot be formed,
    /// the write failing (nothing is then replaced).
    pub fn run(self, progress: &dyn Progress) -> Result<Planned, JobError> {
        let PlanJob {
            args,
            robot,
            options,
            threads,
            outputs,
        } = self;
        let planned = threads
            .install(|| {
                plan(
                    &robot,
                    &options,
                    &|name, units| progress.stage(name, Some(units)),
                    &|units| progress.advance(units),
                )
            })
            .map_err(|e| JobError::Plan(Box::new(e)))?;
        if !(planned.log_det.is_finite()
            && planned.mean_variance.is_finite()
            && planned.variance_bound.is_finite()
            && planned.min_distance_mm.is_none_or(f64::is_finite))
        {
            return Err(JobError::NonFinite(format!(
                "the plan's criterion came out non-finite (log det {}, mean prediction variance \
                 {}, its bound {}, smallest distance {:?} mm)",
                planned.log_det,
                planned.mean_variance,
                planned.variance_bound,
                planned.min_distance_mm
            )));
        }
        let closed_form = InverseKinematics::new(&robot).ok();
        let label = closed_form
            .as_ref()
            .map(|ik| move |q: &[f64]| ik.configuration(q.try_into().expect("six joints")).bits());
        let boxes: Vec<String> = options
            .boxes_mm
            .iter()
            .map(|(a, b)| format!("{a:?} to {b:?}"))
            .collect();
        let (unit, _) = variance_units(&planned);
        let mut comments = vec![
            format!(
                "{} poses of the {} planned by tablec plan, seed {}, from {} candidates ({} draws) in {} mm.",
                planned.poses.len(),
                robot.name,
                args.seed,
                planned.pool,
                planned.draws,
                boxes.join(", ")
            ),
            format!(
                "{} over {} identifiable parameters (log det {:.3}; mean prediction variance {} {unit}, no {} of the candidates below {} {unit}) blended with coverage (weight {}), {} exchange passes at most; {}; joint travel {:.2} rad.",
                match options.criterion {
                    Criterion::D => "D-optimality",
                    Criterion::I => "I-optimality (mean prediction variance over the candidates)",
                    Criterion::A => "A-optimality (parameters in mm and mrad)",
                    Criterion::Ia => "I- and A-optimality",
                },
                planned.parameters.len(),
                planned.log_det,
                figure(&planned, planned.mean_variance),
                planned.poses.len(),
                figure(&planned, planned.variance_bound),
                options.coverage_weight,
                options.exchange_passes,
                smallest_distance(planned.min_distance_mm),
                planned.path_travel
            ),
            "Columns: commanded j1..jn (deg; mm for prismatic joints); nominal x,y,z (mm) and a,b,c (KUKA deg) at them; config (IK branch) for closed-form robots.".into(),
        ];
        // Said only when used, so that a plan without them is written as before.
        let mut said = Vec::new();
        if let (Some([lo, hi]), Some([a, b])) = (
            planned.tracker_sigma_mm,
            options.tracker.as_ref().and_then(|t| t.mpe_um),
        ) {
            said.push(format!(
                "Weighed by the tracker's uncertainty: MPE {a} µm + {b} µm/m, σ = MPE/2 = {lo:.4} to {hi:.4} mm per coordinate over the candidates."
            ));
        }
        if options.branches == Branches::All {
            said.push(format!(
                "Every inverse-kinematics branch: {} of the candidates in the home branch (the workspace the variance is over), {} of the poses in another.",
                planned.workspace_candidates, planned.other_branches
            ));
        }
        comments.splice(2..2, said);
        let text = write_csv(
            &robot,
            &planned,
            &comments,
            label.as_ref().map(|l| l as &ConfigLabel),
        );
        outputs.write(&[(&args.output, text.as_bytes())])?;
        Ok(Planned {
            plan: planned,
            robot_name: robot.name.clone(),
            output: args.output,
        })
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;
    use serde::de::value::{Error, MapDeserializer};

    use super::*;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: PlanArgs,
    }

    #[test]
    fn the_command_line_and_python_have_the_same_defaults() {
        let parsed = Cli::parse_from(["plan", "--count", "5", "-o", "p.csv"]).args;
        let mut expected = PlanArgs::deserialize(MapDeserializer::<_, Error>::new(
            std::iter::empty::<(&str, &str)>(),
        ))
        .unwrap();
        expected.count = 5;
        expected.output = "p.csv".into();
        assert_eq!(format!("{parsed:?}"), format!("{expected:?}"));
        let default = PlanArgs {
            count: 5,
            output: "p.csv".into(),
            ..PlanArgs::default()
        };
        assert_eq!(format!("{parsed:?}"), format!("{default:?}"));
    }

    /// Refused with the figure when the job is made, before any candidate is drawn.
    #[test]
    fn a_plan_too_large_is_refused_before_any_work() {
        let args = PlanArgs {
            robot: RobotArgs {
                robot: Some(adwi_robot::model::shipped_robot_path("ur5")),
                ..RobotArgs::default()
            },
            min: Some([0.0; 3]),
            max: Some([1.0; 3]),
            count: 100_000,
            output: "/nonexistent/p.csv".into(),
            ..PlanArgs::default()
        };
        let e = PlanJob::new(args).err().unwrap();
        assert!(e.to_string().contains("100000 poses"), "{e}");
    }

    /// An option out of range is refused before any file is read: a robot file that does
    /// not exist is not what the refusal names.
    #[test]
    fn options_are_refused_before_any_file_is_read() {
        let args = PlanArgs {
            robot: RobotArgs {
                robot: Some("/nonexistent/robot.toml".into()),
                ..RobotArgs::default()
            },
            min: Some([0.0; 3]),
            max: Some([1.0; 3]),
            count: 5,
            coverage: 2.0,
            measured: vec!["/nonexistent/measured.csv".into()],
            table: Some("/nonexistent/t.tbl".into()),
            output: "/nonexistent/p.csv".into(),
            ..PlanArgs::default()
        };
        let e = PlanJob::new(args).err().unwrap();
        assert!(matches!(e, JobError::Options(_)), "{e}");
        assert!(e.to_string().contains("coverage"), "{e}");
    }

    /// A plan measured by `simulate --poses`: the samples are at the planned joints, in
    /// the plan's order.
    #[test]
    fn simulate_measures_the_planned_joints_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let robot = adwi_robot::model::shipped_robot_path("kr150-2");
        let planned = PlanJob::new(PlanArgs {
            robot: RobotArgs {
                robot: Some(robot.clone()),
                ..RobotArgs::default()
            },
            min: Some([1350.0, 50.0, 850.0]),
            max: Some([2150.0, 850.0, 1650.0]),
            abc: vec![[0.0, 90.0, 0.0]],
            count: 6,
            pool: Some(40),
            output: dir.path().join("plan.csv"),
            ..PlanArgs::default()
        })
        .unwrap()
        .run(&crate::Silent)
        .unwrap();
        let samples = dir.path().join("samples.csv");
        crate::SimulateJob::new(crate::SimulateArgs {
            robot: RobotArgs {
                robot: Some(robot),
                ..RobotArgs::default()
            },
            scenario: adwi_robot::model::shipped_file("kr150-2", "scenario.toml"),
            poses: Some(dir.path().join("plan.csv")),
            output: samples.clone(),
            ..crate::SimulateArgs::default()
        })
        .unwrap()
        .run()
        .unwrap();
        let read =
            adwi_samples::read_samples(&samples, &adwi_samples::ColumnMap::default()).unwrap();
        assert_eq!(read.len(), 6);
        for (i, pose) in planned.plan.poses.iter().enumerate() {
            let q = read.joints_rad(i).unwrap();
            for (a, b) in q.iter().zip(&pose.joints) {
                assert!((a - b).abs() < 1e-9, "{a} {b}");
            }
        }
    }
}
