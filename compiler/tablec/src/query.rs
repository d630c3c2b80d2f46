//! `tablec query`: arguments onto [`adwi_jobs::QueryJob`], its answers printed.

use std::io::Write;
use std::path::PathBuf;

use adwi_jobs::query::{FileAnswers, PointAnswer};
use adwi_jobs::{QueryArgs, QueryJob, QueryResult};

use crate::Answered;

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
    /// Needed by a hybrid table (built with --robot); applies a table's joint screen.
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
    /// answer's rotation turns the lever from the measured point where the samples measured
    /// orientation; else unturned, and flagged); another table flags the answer (evidence
    /// `tcp`).
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

/// How close to B = ±90° (the A, B, C angles' singularity) the command's A and C are
/// explained, degrees.
const GIMBAL_NOTE_DEG: f64 = 1.0;

pub fn run(args: Args) -> anyhow::Result<Answered> {
    let job = QueryJob::new(QueryArgs {
        table: args.table,
        pose: args.pose,
        config: args.config,
        joints_deg: args.joints,
        tcp_mm: args.tcp,
        targets: args.targets,
        reading: args.read,
        output: args.output,
        exact: args.exact,
    })?;
    match job.run()? {
        QueryResult::One(answer) => Ok(print_one(&answer)),
        QueryResult::File(answers) => print_file(&answers),
    }
}

fn print_one(p: &PointAnswer) -> Answered {
    let a = &p.answer;
    let t = p.target_mm;
    println!("target       {:.6} {:.6} {:.6} mm", t[0], t[1], t[2]);
    let counted = if p.tier == "served" {
        "nodes"
    } else {
        "neighbours"
    };
    println!(
        "status       {} ({} {counted}, {} tier)",
        a.status, a.neighbours, p.tier
    );
    let (Some(e), Some(command)) = (a.error_mm, &p.command) else {
        eprintln!("no correction: {}", a.status);
        if let Some([lo, hi]) = p.grid_mm {
            eprintln!(
                "the table's grid spans x {:.1} to {:.1}, y {:.1} to {:.1}, z {:.1} to {:.1} mm \
                 (base frame)",
                lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]
            );
        }
        if let Some(off) = p.joints_off {
            let what = if off.tcp_placed {
                "the --tcp point"
            } else {
                "the tool"
            };
            eprintln!(
                "the joints' nominal forward kinematics puts {what} {:.1} mm from the \
                 target (the table allows {:.1} mm): --joints takes degrees",
                off.off_mm, off.tolerance_mm
            );
        }
        return Answered::NotAll;
    };
    if let (true, Some(residual)) = (a.hybrid, a.residual) {
        match &p.joint_beyond {
            Some(b) => println!(
                "residual     {residual}: joint {} at {:.1}° lies {:.1}° beyond the {:.1}° to \
                 {:.1}° the samples span (the residual fades to none {:.0}° past them)",
                b.joint,
                b.angle_deg,
                b.beyond_deg,
                b.range_deg[0],
                b.range_deg[1],
                adwi_runtime::joint_terms::RESIDUAL_FADE_RAD.to_degrees()
            ),
            None => println!("residual     {residual}"),
        }
    }
    println!("evidence     {}", a.evidence_text());
    println!("error        {:.9} {:.9} {:.9} mm", e[0], e[1], e[2]);
    if let Some(r) = a.orientation_error_rad {
        println!("orientation  {:.9} {:.9} {:.9} rad", r[0], r[1], r[2]);
    }
    let c = command.position_mm;
    println!(
        "command      {:.6} {:.6} {:.6} mm ({})",
        c[0],
        c[1],
        c[2],
        command.how()
    );
    if let Some([a, b, c]) = p.command_abc_deg {
        println!("command abc  {a:.6} {b:.6} {c:.6} deg");
        // Near B = ±90° the rotation depends on A − C (or A + C) alone: a command a
        // hundredth of a degree from the target can read as A and C each moved by degrees.
        if 90.0 - b.abs() < GIMBAL_NOTE_DEG {
            let turn = command
                .rotation_rad
                .iter()
                .map(|v| v * v)
                .sum::<f64>()
                .sqrt();
            println!(
                "note         B is within {GIMBAL_NOTE_DEG}° of ±90°, where A and C turn \
                 together: the command turns the target's orientation by {:.6}° in all",
                turn.to_degrees()
            );
        }
    }
    if !p.answered_within() {
        eprintln!(
            "the answer lies beyond what the table's samples cover: {}",
            a.evidence
        );
        return Answered::NotAll;
    }
    Answered::All
}

fn print_file(answers: &FileAnswers) -> anyhow::Result<Answered> {
    if answers.output.is_none() {
        let stdout = std::io::stdout();
        let mut out = std::io::BufWriter::new(stdout.lock());
        answers.write_csv(&mut out)?;
        out.flush()?;
    }
    let rows = answers.rows.len();
    let beyond = answers.beyond();
    if beyond > 0 {
        eprintln!(
            "{beyond} of {rows} targets answered beyond the table's evidence (column evidence)"
        );
    }
    let unanswered = answers.unanswered();
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
        "{count} of {rows} targets not answered: {}",
        by_status.join(", ")
    );
    Ok(Answered::NotAll)
}
