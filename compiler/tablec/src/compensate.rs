//! `tablec compensate`: a robot program with every target replaced by the command that
//! lands on it ([`adwi_programs::CompensateJob`]).

use std::path::PathBuf;

use adwi_programs::{escape_controls, CompensateJob, CompensateOptions, Format};

use crate::Answered;

#[derive(clap::Args)]
#[command(
    after_help = "Exit status: 0 when every target was corrected; 3 when some target \
    was left unchanged (the program is still written, each target's status in the report), \
    a position-only table's target beyond its samples' evidence among them; \
    with --strict, 3 and nothing written; 1 on an error (a malformed program, a program that \
    moves but holds no target, an unreadable input, a refused output: nothing is written); 2 on \
    a usage error."
)]
pub struct Args {
    /// The correction table.
    table: PathBuf,
    /// The program: KUKA KRL (.src, .dat), ABB RAPID (.mod), URScript (.script), G-code
    /// (.nc, .ngc, .gcode, .tap), Yaskawa INFORM (.jbi), Fanuc TP (.ls), a Stäubli VAL3
    /// application (its .pjx, or its folder with --format val3: the output is its corrected
    /// .dtx) or a CSV of poses (.csv).
    program: PathBuf,
    /// The compensated program (never one of the inputs; written atomically).
    #[arg(short, long)]
    output: PathBuf,
    /// The program's format [default: by its extension].
    #[arg(long, value_parser = ["krl", "rapid", "urscript", "csv", "gcode", "yaskawa", "fanuc", "val3"])]
    format: Option<String>,
    /// A robot file (TOML, or URDF by its .urdf extension, with --base-link/--tip-link):
    /// for joint targets, and to check every command's posture (inverse kinematics in the
    /// target's configuration).
    #[command(flatten)]
    robot: adwi_jobs::RobotArgs,
    /// The program's TCP in the flange frame, X,Y,Z,A,B,C (mm, KUKA degrees), where the
    /// program does not declare its tool [default: the table's point].
    #[arg(long, value_name = "X,Y,Z,A,B,C", allow_hyphen_values = true, value_parser = frame)]
    tool: Option<Frame>,
    /// The work object (base) in the robot's base frame, X,Y,Z,A,B,C, where the program
    /// does not declare it [default: the base frame].
    #[arg(long, value_name = "X,Y,Z,A,B,C", allow_hyphen_values = true, value_parser = frame)]
    base: Option<Frame>,
    /// A KUKA controller's $config.dat (or a file of its TOOL_DATA[n]={X ..,Y ..,Z ..,A ..,B
    /// ..,C ..} and BASE_DATA[n]={...} lines): the numbered tools and bases a KRL program
    /// selects ($TOOL = TOOL_DATA[n], an FDAT's TOOL_NO and BASE_NO, an inline form's
    /// Tool[n] Base[n]).
    #[arg(long, value_name = "PATH")]
    krl_config: Option<PathBuf>,
    /// The point the table's samples measured, in the flange frame, X,Y,Z,A,B,C [default: a
    /// hybrid table's own (with --robot); else the robot file's tool; else the flange].
    #[arg(long, value_name = "X,Y,Z,A,B,C", allow_hyphen_values = true, value_parser = frame)]
    table_tool: Option<Frame>,
    /// G-code: how A, B, C (degrees) write the tool's orientation: kuka, R = Rz(A)·Ry(B)·Rx(C);
    /// xyz, fixed-axis rotations about x by A, then y by B, then z by C.
    #[arg(long, value_name = "CONVENTION", default_value = "kuka", value_parser = ["kuka", "xyz"])]
    gcode_abc: String,
    /// G-code: a work offset G54-G59 in the robot's base frame, G54=X,Y,Z[,A,B,C] (mm, KUKA
    /// degrees); repeat for each the program selects (a move in one not given is reported
    /// frame_unknown).
    #[arg(long, value_name = "G5n=X,Y,Z[,A,B,C]", allow_hyphen_values = true, value_parser = adwi_programs::gcode::parse_work_offset)]
    work_offset: Vec<(u8, [f64; 6])>,
    /// G-code: how far a corrected arc (G2/G3, its centre moved with its ends) may lie from
    /// the corrected path, mm; an arc beyond it is left unchanged (arc_tolerance).
    #[arg(long, default_value_t = adwi_programs::gcode::DEFAULT_ARC_TOLERANCE_MM)]
    arc_tolerance_mm: f64,
    /// Yaskawa: a tool file, n=X,Y,Z,Rx,Ry,Rz (mm; degrees about the fixed x, y, z, as the
    /// pendant shows it); repeat for each ///TOOL n the job uses (a position with a tool not
    /// given is reported frame_unknown).
    #[arg(long, value_name = "n=X,Y,Z,Rx,Ry,Rz", allow_hyphen_values = true, value_parser = adwi_programs::yaskawa::parse_numbered_frame)]
    yaskawa_tool: Vec<(u16, [f64; 6])>,
    /// Yaskawa: a user frame in the robot's base frame, n=X,Y,Z,Rx,Ry,Rz; repeat for each
    /// ///USER n the job uses.
    #[arg(long, value_name = "n=X,Y,Z,Rx,Ry,Rz", allow_hyphen_values = true, value_parser = adwi_programs::yaskawa::parse_numbered_frame)]
    yaskawa_user: Vec<(u16, [f64; 6])>,
    /// Yaskawa: the encoder pulses per degree of each axis (S,L,U,R,B,T; negative for an
    /// axis counted against the robot file's joint), for PULSE positions; without it they
    /// are reported, not corrected.
    #[arg(long, value_name = "a,b,c,d,e,f", allow_hyphen_values = true, value_parser = adwi_programs::yaskawa::parse_pulses_per_deg)]
    yaskawa_pulses_per_deg: Option<Pulses>,
    /// Fanuc: a user frame in the world frame, n=X,Y,Z,W,P,R (mm; degrees about the fixed
    /// x, y, z, as the FRAME menu shows it); repeat for each UF n the positions use (user
    /// frame 0 is the world). A position in a frame not given is reported frame_unknown.
    #[arg(long, value_name = "n=X,Y,Z,W,P,R", allow_hyphen_values = true, value_parser = adwi_programs::fanuc::parse_frame)]
    fanuc_uframe: Vec<(u16, [f64; 6])>,
    /// Fanuc: a tool frame (the TCP in the faceplate frame), n=X,Y,Z,W,P,R; repeat for each
    /// UT n the positions use (tool frame 0 is the faceplate).
    #[arg(long, value_name = "n=X,Y,Z,W,P,R", allow_hyphen_values = true, value_parser = adwi_programs::fanuc::parse_frame)]
    fanuc_utool: Vec<(u16, [f64; 6])>,
    /// Fanuc: the controller's frame file (SYSFRAME.VA, its $MNUFRAME and $MNUTOOL), for the
    /// frames --fanuc-uframe and --fanuc-utool do not give.
    #[arg(long, value_name = "PATH")]
    fanuc_frames: Option<PathBuf>,
    /// Refuse (leave unchanged, report) a correction larger than this, mm.
    #[arg(long, default_value_t = adwi_programs::DEFAULT_MAX_CORRECTION_MM)]
    max_correction_mm: f64,
    /// Refuse a command whose posture moves a joint more than this from the target's,
    /// degrees (mm for a prismatic joint).
    #[arg(long, default_value_t = adwi_programs::DEFAULT_MAX_JOINT_CHANGE_DEG)]
    max_joint_change_deg: f64,
    /// Fail, writing nothing, when any target would be left unchanged.
    #[arg(long)]
    strict: bool,
    /// Correct targets a position-only table answers beyond what its samples cover (an
    /// orientation they never had) instead of refusing them (status beyond_evidence). A
    /// hybrid table's calibrated model answers there either way, and the report says so.
    #[arg(long)]
    beyond_evidence: bool,
    /// Write the per-target report as CSV too.
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
    /// Refuse, before any work, a program estimated to take longer than this, seconds.
    #[arg(long, default_value_t = 300.0)]
    max_seconds: f64,
    /// Refuse, before any work, a program estimated to need more memory than this, MB
    /// (about 2 KB a target, and three times the program's size).
    #[arg(long, default_value_t = adwi_programs::DEFAULT_MAX_MEMORY_BYTES / 1_000_000)]
    max_memory_mb: u64,
    /// Print only the targets left unchanged and the summary.
    #[arg(short, long)]
    quiet: bool,
}

type Frame = [f64; 6];
/// Pulses per degree, per axis (an alias, so that the argument takes one value).
type Pulses = Vec<f64>;

fn frame(text: &str) -> Result<Frame, String> {
    adwi_jobs::args::parse_frame(text)
}

pub fn run(args: Args) -> anyhow::Result<Answered> {
    let mut options = CompensateOptions::new(&args.table, &args.program);
    options.output = Some(args.output);
    options.report = args.report;
    options.format = args.format.as_deref().and_then(Format::from_name);
    options.links = args.robot.links();
    options.robot = args.robot.robot;
    options.tool = args.tool;
    options.base = args.base;
    options.krl_config = args.krl_config;
    options.table_tool = args.table_tool;
    options.limits.max_correction_mm = args.max_correction_mm;
    options.limits.max_joint_change_deg = args.max_joint_change_deg;
    options.strict = args.strict;
    options.limits.beyond_evidence = args.beyond_evidence;
    options.max_seconds = args.max_seconds;
    options.max_memory_bytes = args.max_memory_mb.saturating_mul(1_000_000);
    options.gcode = adwi_programs::gcode::GcodeOptions {
        abc: adwi_programs::gcode::AbcConvention::from_name(&args.gcode_abc).unwrap_or_default(),
        work_offsets: args.work_offset,
        arc_tolerance_mm: args.arc_tolerance_mm,
    };
    options.yaskawa = adwi_programs::yaskawa::YaskawaOptions {
        tools: args.yaskawa_tool,
        users: args.yaskawa_user,
        pulses_per_deg: args.yaskawa_pulses_per_deg,
    };
    options.fanuc = adwi_programs::fanuc::FanucOptions {
        user_frames: args.fanuc_uframe,
        tool_frames: args.fanuc_utool,
        frames_file: args.fanuc_frames,
    };
    let job = CompensateJob::new(options)?;
    let done = match job.run() {
        // --strict: every target unaccounted or not corrected is the exit status 3 that
        // any target left unchanged gives, with nothing written.
        Err(e @ adwi_programs::Error::NotAllCorrected { .. }) => {
            eprintln!("error: {e}");
            return Ok(Answered::NotAll);
        }
        done => done?,
    };
    job.write(&done)?;
    for t in done
        .report
        .targets
        .iter()
        .filter(|t| !(args.quiet && t.status.corrected()))
    {
        let figure =
            |v: Option<f64>, unit: &str| v.map_or(String::new(), |v| format!(" {v:.4} {unit}"));
        println!(
            "{:<24} {}:{:<5} {:<10} {}{}{}{}",
            escape_controls(&t.name),
            t.line,
            t.column,
            t.kind,
            t.status.as_str(),
            figure(t.correction_mm, "mm"),
            figure(t.joint_change_deg, "° joint"),
            if t.detail.is_empty() {
                String::new()
            } else {
                format!(" ({})", escape_controls(&t.detail))
            },
        );
    }
    let summary = done.report.summary();
    println!("{}", escape_controls(&summary.to_string()));
    Ok(if summary.corrected == summary.total {
        Answered::All
    } else {
        Answered::NotAll
    })
}
