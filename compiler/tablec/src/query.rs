//! `tablec query`.

use std::io::Write;
use std::path::{Path, PathBuf};

use adwi_runtime::{Correction, Evidence, Status, Table, Target, Tier};
use adwi_samples::pose;
use anyhow::bail;

use crate::Answered;

/// The fixed-point compensation's tolerance, mm, and iteration bound.
const COMPENSATE_TOLERANCE_MM: f64 = 1e-6;
const COMPENSATE_ITERATIONS: u32 = 50;

#[derive(clap::Args)]
#[command(
    group(
        clap::ArgGroup::new("reading")
            .args(adwi_jobs::Reading::IDS)
            .multiple(true)
            .requires("targets")
    ),
    after_help = "Exit status: 0 when every target was answered (status ok) within the \
    table's evidence; 3 when the table gave no correction for the target, or for at least \
    one row of --targets, or answered beyond what its samples cover (an orientation they \
    never had, a TCP it cannot place: the `evidence` line or column says which; the rows \
    are all written, each with its status, and a count of the unanswered ones goes to \
    standard error); 1 on an error (unreadable table or targets file); 2 on a usage error."
)]
pub struct Args {
    /// The table.
    table: PathBuf,
    /// Target X Y Z (mm, base frame), optionally A B C (KUKA degrees).
    #[arg(allow_negative_numbers = true, num_args = 0..=6)]
    pose: Vec<f64>,
    /// Inverse-kinematics configuration of the target.
    #[arg(long)]
    config: Option<u8>,
    /// The joint values the controller will use for the target, degrees (mm for prismatic
    /// joints): J1,...,Jn, as many as the table's robot has.
    /// Needed by a hybrid table (built with --hybrid); applies a table's joint screen.
    #[arg(
        long,
        value_name = "DEG,...",
        allow_hyphen_values = true,
        value_parser = adwi_jobs::args::parse_number_list,
        conflicts_with = "targets"
    )]
    joints: Option<NumberList>,
    /// The TCP the target is for, X,Y,Z mm in the flange frame, when it is not the point
    /// the table's samples measured: a hybrid table answers the error at this TCP (its
    /// model turns the lever from the measured point); another table flags the answer
    /// (evidence `tcp`).
    #[arg(
        long,
        value_name = "X,Y,Z",
        allow_hyphen_values = true,
        value_parser = adwi_jobs::args::parse_number_list
    )]
    tcp: Option<NumberList>,
    /// A CSV of targets (columns x,y,z, optionally config and j1..jn) instead of one pose.
    #[arg(long, conflicts_with = "pose")]
    targets: Option<PathBuf>,
    /// How the targets CSV is read, as for `tablec build`.
    #[command(flatten)]
    read: adwi_jobs::Reading,
    /// Output CSV for --targets [default: standard output].
    #[arg(short, long, requires = "targets")]
    output: Option<PathBuf>,
    /// Answer from the exact tier (the paper's method to the digit) instead of the served
    /// continuous field.
    #[arg(long)]
    exact: bool,
}

type NumberList = Vec<f64>;

/// A refused argument: a usage error (exit status 2).
fn usage(message: String) -> anyhow::Error {
    adwi_jobs::JobError::Options(message).into()
}

/// Refuses a target or joint value that no robot takes, before the table answers: a
/// position beyond a kilometre, an angle beyond three turns. Such a value is a typing
/// error, and an answer to it (a command, `ok`) would be a number that means nothing. A
/// value that is not finite is the table's to refuse (status `invalid_input`).
fn check_pose(pose: &[f64]) -> anyhow::Result<()> {
    let names = ["X", "Y", "Z", "A", "B", "C"];
    for (i, (name, v)) in names.iter().zip(pose).enumerate() {
        if !v.is_finite() {
            continue;
        }
        let checked = if i < 3 {
            adwi_jobs::args::check_coordinate_mm(name, *v)
        } else {
            adwi_jobs::args::check_angle_deg(name, *v)
        };
        checked.map_err(usage)?;
    }
    Ok(())
}

/// Refuses joint values beyond three turns (revolute joints, degrees) or a kilometre
/// (prismatic joints, mm). Without a model the joints' kinds are unknown: each is held to
/// the larger bound.
fn check_joints<D: AsRef<[u8]>>(table: &Table<D>, joints_deg: &[f64]) -> anyhow::Result<()> {
    use adwi_runtime::chain::JointKind;
    let kinds = table.model().map(|m| m.nominal().joints());
    for (i, v) in joints_deg.iter().enumerate() {
        let name = format!("--joints J{}", i + 1);
        let kind = kinds.and_then(|k| k.get(i)).map(|j| j.kind);
        let checked = match kind {
            Some(JointKind::Revolute) => adwi_jobs::args::check_angle_deg(&name, *v),
            _ => adwi_jobs::args::check_coordinate_mm(&name, *v),
        };
        checked.map_err(usage)?;
    }
    Ok(())
}

/// The `--tcp` option: three finite coordinates within the plausible range.
fn tcp_of(tcp: Option<&NumberList>) -> anyhow::Result<Option<[f64; 3]>> {
    let Some(tcp) = tcp else {
        return Ok(None);
    };
    let [x, y, z] = tcp.as_slice() else {
        return Err(usage(format!(
            "--tcp takes X,Y,Z (mm, flange frame); {} values given",
            tcp.len()
        )));
    };
    for (name, v) in ["--tcp X", "--tcp Y", "--tcp Z"].iter().zip([x, y, z]) {
        adwi_jobs::args::check_coordinate_mm(name, *v).map_err(usage)?;
    }
    Ok(Some([*x, *y, *z]))
}

pub fn run(args: Args) -> anyhow::Result<Answered> {
    check_pose(&args.pose)?;
    let tcp = tcp_of(args.tcp.as_ref())?;
    let table = crate::open_table(&args.table)?;
    if let Some(targets) = &args.targets {
        if let Some(output) = &args.output {
            adwi_compile::write::OutputPlan::check(&[output], &[&args.table, targets])?;
        }
        return run_batch(
            &table,
            targets,
            &args.read,
            args.output.as_deref(),
            args.exact,
            tcp,
        );
    }
    let (position, abc) = match args.pose.as_slice() {
        [x, y, z] => ([*x, *y, *z], None),
        [x, y, z, a, b, c] => ([*x, *y, *z], Some([*a, *b, *c])),
        _ => bail!("give a target as X Y Z or X Y Z A B C, or --targets FILE"),
    };
    // A non-finite orientation gives a non-finite rotation vector, which the table refuses
    // as it does a non-finite position (`invalid_input`): no command can be computed for it.
    let target = Target {
        position_mm: position,
        config: args.config,
        rotation_rad: abc.map(|abc| pose::rotation_vector(&pose::rotation_from_kuka_abc_deg(abc))),
        tcp_mm: tcp,
    };
    let joints_rad: Option<Vec<f64>> = args
        .joints
        .as_ref()
        .map(|q| q.iter().map(|v| v.to_radians()).collect());
    if let Some(q) = &args.joints {
        check_joints(&table, q)?;
    }
    if let (Some(q), Some(n)) = (&joints_rad, table.joint_count()) {
        if q.len() != n {
            bail!(
                "--joints takes the robot's {n} joint angles in degrees, J1,...,J{n}; {} given",
                q.len()
            );
        }
    }
    let c = table.answer(&target, joints_rad.as_deref(), tier(args.exact));
    println!(
        "target       {:.6} {:.6} {:.6} mm",
        position[0], position[1], position[2]
    );
    let tier = if args.exact || !table.has_served_field() {
        "exact"
    } else {
        "served"
    };
    let counted = if tier == "served" {
        "nodes"
    } else {
        "neighbours"
    };
    println!(
        "status       {} ({} {counted}, {tier} tier)",
        c.status.as_str(),
        c.neighbours
    );
    if c.status != Status::Ok {
        eprintln!("no correction: {}", c.status.as_str());
        if let (Status::JointsMismatch, Some(q)) = (c.status, &joints_rad) {
            explain_mismatch(&table, position, q);
        }
        return Ok(Answered::NotAll);
    }
    if table.is_hybrid() {
        println!("residual     {}", c.residual.as_str());
    }
    println!("evidence     {}", evidence_text(&table, c.evidence));
    let e = c.position_error_mm;
    println!("error        {:.9} {:.9} {:.9} mm", e[0], e[1], e[2]);
    if table.has_orientation() || table.is_hybrid() {
        let r = c.orientation_error_rad;
        println!("orientation  {:.9} {:.9} {:.9} rad", r[0], r[1], r[2]);
    }
    let command = command(&table, &target, joints_rad.as_deref(), &c, args.exact);
    let p = command.position_mm;
    println!(
        "command      {:.6} {:.6} {:.6} mm ({})",
        p[0], p[1], p[2], command.how
    );
    if let Some(abc) = abc {
        let target_rotation = pose::rotation_from_kuka_abc_deg(abc);
        let rotation = pose::rotation_from_vector(command.rotation_rad) * target_rotation;
        let [a, b, c] = pose::kuka_abc_deg_from_rotation(&rotation);
        println!("command abc  {a:.6} {b:.6} {c:.6} deg");
    }
    if !c.evidence.is_within() {
        eprintln!(
            "the answer lies beyond what the table's samples cover: {}",
            c.evidence.as_str()
        );
        return Ok(Answered::NotAll);
    }
    Ok(Answered::All)
}

/// The `evidence` line: `within`, or what lies beyond the samples and who answers there.
fn evidence_text<D: AsRef<[u8]>>(table: &Table<D>, evidence: Evidence) -> String {
    if evidence.is_within() {
        return "within".to_string();
    }
    let who = if table.is_hybrid() {
        "the calibrated model answers"
    } else {
        "no model carries the answer"
    };
    format!("beyond: {} ({who})", evidence.as_str())
}

/// Says how far the joints put the tool from the target, and the unit `--joints` takes.
fn explain_mismatch<D: AsRef<[u8]>>(table: &Table<D>, target_mm: [f64; 3], joints_rad: &[f64]) {
    let (Some(model), Some(tolerance_mm)) = (table.model(), table.joints_tolerance_mm()) else {
        return;
    };
    if let Some(at) = model.at(joints_rad) {
        let off_mm = adwi_runtime::method::distance_mm(at.nominal_tcp_mm, target_mm);
        eprintln!(
            "the joints' nominal forward kinematics puts the tool {off_mm:.1} mm from the \
             target (the table allows {tolerance_mm:.1} mm): --joints takes degrees"
        );
    }
}

/// The pose to command so that the robot lands on the target.
struct Command {
    position_mm: [f64; 3],
    /// Rotation vector to apply to the target orientation, rad, base frame.
    rotation_rad: [f64; 3],
    /// How it was found, for people and for the `command_status` column.
    how: String,
    /// `converged`, `not_converged` or `first_order`.
    status: &'static str,
}

/// The command for an answered target: the fixed point of `command + error(command) =
/// target` by [`Table::compensate`]; with joint angles, the first-order `target − error`,
/// since the moved command's joint angles are only known to the controller's inverse
/// kinematics.
fn command<D: AsRef<[u8]>>(
    table: &Table<D>,
    target: &Target,
    joints_rad: Option<&[f64]>,
    c: &Correction,
    exact: bool,
) -> Command {
    if joints_rad.is_some() {
        let e = c.position_error_mm;
        return Command {
            position_mm: [0, 1, 2].map(|a| target.position_mm[a] - e[a]),
            rotation_rad: c.orientation_error_rad.map(|v| -v),
            how: "first order: target − error".to_string(),
            status: "first_order",
        };
    }
    let comp = if exact {
        table
            .exact()
            .compensate(target, COMPENSATE_TOLERANCE_MM, COMPENSATE_ITERATIONS)
    } else {
        table.compensate(target, COMPENSATE_TOLERANCE_MM, COMPENSATE_ITERATIONS)
    };
    let status = if comp.converged {
        "converged"
    } else {
        "not_converged"
    };
    Command {
        position_mm: comp.command_position_mm,
        rotation_rad: comp.command_rotation_rad,
        how: format!(
            "{} after {} iterations, residual {:.2e} mm",
            status.replace('_', " "),
            comp.iterations,
            comp.residual_mm
        ),
        status,
    }
}

fn run_batch(
    table: &Table<memmap2::Mmap>,
    targets: &Path,
    read: &adwi_jobs::Reading,
    output: Option<&Path>,
    exact: bool,
    tcp: Option<[f64; 3]>,
) -> anyhow::Result<Answered> {
    let (columns, options) = read.resolve()?;
    let targets = adwi_samples::read_targets(targets, &columns, &options)?;
    // A file is written whole once every row is (atomically: never a partial file);
    // standard output row by row.
    let mut buffer = Vec::new();
    let stdout = std::io::stdout();
    let mut out: Box<dyn Write> = match output {
        Some(_) => Box::new(&mut buffer),
        None => Box::new(std::io::BufWriter::new(stdout.lock())),
    };
    writeln!(
        out,
        "x,y,z,pred_dx,pred_dy,pred_dz,pred_rx,pred_ry,pred_rz,neighbours,status,residual,\
         command_x,command_y,command_z,command_rx,command_ry,command_rz,command_status,evidence"
    )?;
    // A hybrid table's model predicts the orientation error whether or not the samples
    // measured one.
    let orientation = table.has_orientation() || table.is_hybrid();
    let mut beyond = 0usize;
    let mut unanswered: std::collections::BTreeMap<&str, usize> = Default::default();
    for row in &targets {
        // Rows with joint angles serve hybrid tables and the joint-space screen.
        let target = Target {
            tcp_mm: tcp,
            ..row.target
        };
        let c = table.answer(&target, row.joints_rad.as_deref(), tier(exact));
        let p = row.target.position_mm;
        write!(out, "{},{},{}", p[0], p[1], p[2])?;
        if c.status == Status::Ok {
            let e = c.position_error_mm;
            write!(out, ",{:.9},{:.9},{:.9}", e[0], e[1], e[2])?;
        } else {
            write!(out, ",,,")?;
        }
        if c.status == Status::Ok && orientation {
            let r = c.orientation_error_rad;
            write!(out, ",{:.12},{:.12},{:.12}", r[0], r[1], r[2])?;
        } else {
            write!(out, ",,,")?;
        }
        write!(out, ",{},{}", c.neighbours, c.status.as_str())?;
        if c.status == Status::Ok {
            write!(out, ",{}", c.residual.as_str())?;
            let command = command(table, &target, row.joints_rad.as_deref(), &c, exact);
            let p = command.position_mm;
            write!(out, ",{:.9},{:.9},{:.9}", p[0], p[1], p[2])?;
            if orientation {
                let r = command.rotation_rad;
                write!(out, ",{:.12},{:.12},{:.12}", r[0], r[1], r[2])?;
            } else {
                write!(out, ",,,")?;
            }
            writeln!(out, ",{},{}", command.status, c.evidence.as_str())?;
            beyond += usize::from(!c.evidence.is_within());
        } else {
            *unanswered.entry(c.status.as_str()).or_default() += 1;
            writeln!(out, ",,,,,,,,,")?;
        }
    }
    out.flush()?;
    drop(out);
    if let Some(path) = output {
        adwi_compile::write::write_atomically(path, &buffer)?;
    }
    if beyond > 0 {
        eprintln!(
            "{beyond} of {} targets answered beyond the table's evidence (column evidence)",
            targets.len()
        );
    }
    if unanswered.is_empty() {
        return Ok(if beyond == 0 {
            Answered::All
        } else {
            Answered::NotAll
        });
    }
    let count: usize = unanswered.values().sum();
    let by_status: Vec<String> = unanswered
        .iter()
        .map(|(status, n)| format!("{n} {status}"))
        .collect();
    eprintln!(
        "{count} of {} targets not answered: {}",
        targets.len(),
        by_status.join(", ")
    );
    Ok(Answered::NotAll)
}

/// The tier `--exact` asks for.
fn tier(exact: bool) -> Tier {
    if exact {
        Tier::Exact
    } else {
        Tier::Served
    }
}
