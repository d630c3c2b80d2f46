//! `compensate`: a robot program with every target replaced by the command that lands on
//! it, by a correction table.
//!
//! The dialects' readers and writers and the correction of a target are
//! [`adwi_programs`]' (the algorithm); this job maps the options onto it, refuses every bad
//! option before any file is read, and writes the outputs all or nothing.

use std::path::PathBuf;

use adwi_programs::gcode::{AbcConvention, GcodeOptions};
use adwi_programs::yaskawa::YaskawaOptions;
use adwi_programs::{fanuc::FanucOptions, CompensateOptions, Format};
use serde::Serialize;

use crate::JobError;

pub use adwi_programs::fanuc::parse_turn_axes;
pub use adwi_programs::gcode::DEFAULT_ARC_TOLERANCE_MM;
pub use adwi_programs::Error as ProgramError;
pub use adwi_programs::{
    escape_controls, Summary, TargetLine, TargetStatus, DEFAULT_MAX_CORRECTION_MM,
    DEFAULT_MAX_JOINT_CHANGE_DEG, DEFAULT_MAX_MEMORY_BYTES,
};

/// The default bound of the estimated work, seconds: a long program is refused before any
/// work rather than left running.
pub const DEFAULT_MAX_SECONDS: f64 = 300.0;

/// A frame: X, Y, Z (mm), A, B, C (KUKA degrees), or as the option says.
type Frame = [f64; 6];
/// Pulses per degree, per axis (an alias, so that the argument takes one value).
type Pulses = Vec<f64>;

/// What a compensation asks: every option, with its documentation and its default, once
/// (tablec flattens it; the Python package fills it in).
// The fields' doc comments are the options' help text, written for a terminal (KRL's
// `TOOL_DATA[n]` and the like), not for rustdoc's links.
#[allow(rustdoc::broken_intra_doc_links)]
#[derive(clap::Args, Clone, Debug)]
pub struct CompensateArgs {
    /// The correction table.
    pub table: PathBuf,
    /// The program: KUKA KRL (.src, .dat), ABB RAPID (.mod), URScript (.script), G-code
    /// (.nc, .ngc, .gcode, .tap), Yaskawa INFORM (.jbi), Fanuc TP (.ls), a Stäubli VAL3
    /// application (its .pjx, or its folder with --format val3: the output is its corrected
    /// .dtx) or a CSV of poses (.csv).
    pub program: PathBuf,
    /// The compensated program (never one of the inputs; written atomically).
    #[arg(short, long, required = true)]
    pub output: Option<PathBuf>,
    /// The program's format [default: by its extension].
    #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(Format::ALL.map(Format::name)))]
    pub format: Option<String>,
    /// A robot file (TOML, or URDF by its .urdf extension, with --base-link/--tip-link):
    /// for joint targets, and to check every command's posture (inverse kinematics in the
    /// target's configuration).
    #[command(flatten)]
    pub robot: crate::RobotArgs,
    /// The program's TCP in the flange frame, X,Y,Z,A,B,C (mm, KUKA degrees), where the
    /// program does not declare its tool [default: the table's point].
    #[arg(long, value_name = "X,Y,Z,A,B,C", allow_hyphen_values = true, value_parser = crate::args::parse_frame)]
    pub tool: Option<Frame>,
    /// The work object (base) in the robot's base frame, X,Y,Z,A,B,C, where the program
    /// does not declare it [default: the base frame].
    #[arg(long, value_name = "X,Y,Z,A,B,C", allow_hyphen_values = true, value_parser = crate::args::parse_frame)]
    pub base: Option<Frame>,
    /// A KUKA controller's $config.dat (or a file of its TOOL_DATA[n]={X ..,Y ..,Z ..,A ..,B
    /// ..,C ..} and BASE_DATA[n]={...} lines): the numbered tools and bases a KRL program
    /// selects ($TOOL = TOOL_DATA[n], an FDAT's TOOL_NO and BASE_NO, an inline form's
    /// Tool[n] Base[n]).
    #[arg(long, value_name = "PATH")]
    pub krl_config: Option<PathBuf>,
    /// The point the table's samples measured, in the flange frame, X,Y,Z,A,B,C [default: a
    /// hybrid table's own (the robot file's flange with --robot, else where the table
    /// records its point on the flange); else the robot file's tool; else the flange].
    #[arg(long, value_name = "X,Y,Z,A,B,C", allow_hyphen_values = true, value_parser = crate::args::parse_frame)]
    pub table_tool: Option<Frame>,
    /// G-code: how A, B, C (degrees) write the tool's orientation: kuka, R = Rz(A)·Ry(B)·Rx(C);
    /// xyz, fixed-axis rotations about x by A, then y by B, then z by C.
    #[arg(long, value_name = "CONVENTION", default_value = "kuka", value_parser = ["kuka", "xyz"])]
    pub gcode_abc: String,
    /// G-code: a work offset G54-G59 in the robot's base frame, G54=X,Y,Z[,A,B,C] (mm, KUKA
    /// degrees); repeat for each the program selects (a move in one not given is reported
    /// frame_unknown).
    #[arg(long, value_name = "G5n=X,Y,Z[,A,B,C]", allow_hyphen_values = true, value_parser = adwi_programs::gcode::parse_work_offset)]
    pub work_offset: Vec<(u8, [f64; 6])>,
    /// G-code: how far a corrected arc (G2/G3, its centre moved with its ends) may lie from
    /// the corrected path, mm; an arc beyond it is left unchanged (arc_tolerance).
    #[arg(long, default_value_t = DEFAULT_ARC_TOLERANCE_MM)]
    pub arc_tolerance_mm: f64,
    /// Yaskawa: a tool file, n=X,Y,Z,Rx,Ry,Rz (mm; degrees about the fixed x, y, z, as the
    /// pendant shows it); repeat for each ///TOOL n the job uses (a position with a tool not
    /// given is reported frame_unknown).
    #[arg(long, value_name = "n=X,Y,Z,Rx,Ry,Rz", allow_hyphen_values = true, value_parser = adwi_programs::yaskawa::parse_numbered_frame)]
    pub yaskawa_tool: Vec<(u16, [f64; 6])>,
    /// Yaskawa: a user frame in the robot's base frame, n=X,Y,Z,Rx,Ry,Rz; repeat for each
    /// ///USER n the job uses.
    #[arg(long, value_name = "n=X,Y,Z,Rx,Ry,Rz", allow_hyphen_values = true, value_parser = adwi_programs::yaskawa::parse_numbered_frame)]
    pub yaskawa_user: Vec<(u16, [f64; 6])>,
    /// Yaskawa: the encoder pulses per degree of each axis (S,L,U,R,B,T; negative for an
    /// axis counted against the robot file's joint), for PULSE positions; without it they
    /// are reported, not corrected.
    #[arg(long, value_name = "a,b,c,d,e,f", allow_hyphen_values = true, value_parser = adwi_programs::yaskawa::parse_pulses_per_deg)]
    pub yaskawa_pulses_per_deg: Option<Pulses>,
    /// Fanuc: a user frame in the world frame, n=X,Y,Z,W,P,R (mm; degrees about the fixed
    /// x, y, z, as the FRAME menu shows it); repeat for each UF n the positions use (user
    /// frame 0 is the world). A position in a frame not given is reported frame_unknown.
    #[arg(long, value_name = "n=X,Y,Z,W,P,R", allow_hyphen_values = true, value_parser = adwi_programs::fanuc::parse_frame)]
    pub fanuc_uframe: Vec<(u16, [f64; 6])>,
    /// Fanuc: a tool frame (the TCP in the faceplate frame), n=X,Y,Z,W,P,R; repeat for each
    /// UT n the positions use (tool frame 0 is the faceplate).
    #[arg(long, value_name = "n=X,Y,Z,W,P,R", allow_hyphen_values = true, value_parser = adwi_programs::fanuc::parse_frame)]
    pub fanuc_utool: Vec<(u16, [f64; 6])>,
    /// Fanuc: the controller's frame file (SYSFRAME.VA, its $MNUFRAME and $MNUTOOL), for the
    /// frames --fanuc-uframe and --fanuc-utool do not give; a file holding
    /// $SCR_GRP[1].$TURN_AXIS (SYMOTN.VA) gives the turn axes too.
    #[arg(long, value_name = "PATH")]
    pub fanuc_frames: Option<PathBuf>,
    /// Fanuc: the joints of a CONFIG's three turn numbers, J,J,J (1 for J1), as the
    /// controller's $SCR_GRP[1].$TURN_AXIS gives them: 1,4,6 on an R-2000iB or M-900iA,
    /// 4,5,6 on many LR Mates [default: the frame file's, else 4,5,6].
    #[arg(long, value_name = "J,J,J", value_parser = adwi_programs::fanuc::parse_turn_axes)]
    pub fanuc_turn_axes: Option<[u8; 3]>,
    /// Fanuc: how the pendant counts J3 in a joint position, J3 = the robot file's J3 + K·J2:
    /// 1 where it counts J3 from the horizontal (the J2/J3 interaction of most Fanuc arms)
    /// and the robot file from the upper arm (a ROS-Industrial URDF, any MD-H file), 0
    /// where both count alike [default: joint positions refused until it is given].
    #[arg(long, value_name = "K", allow_hyphen_values = true)]
    pub fanuc_j23: Option<f64>,
    /// Refuse (leave unchanged, report) a correction larger than this, mm.
    #[arg(long, default_value_t = DEFAULT_MAX_CORRECTION_MM)]
    pub max_correction_mm: f64,
    /// Refuse a command whose posture moves a joint more than this from the target's,
    /// degrees (mm for a prismatic joint).
    #[arg(long, default_value_t = DEFAULT_MAX_JOINT_CHANGE_DEG)]
    pub max_joint_change_deg: f64,
    /// Fail, writing nothing, when any target would be left unchanged.
    #[arg(long)]
    pub strict: bool,
    /// Correct targets a position-only table answers beyond what its samples cover (an
    /// orientation they never had) instead of refusing them (status beyond_evidence). A
    /// hybrid table's calibrated model answers there either way, and the report says so.
    #[arg(long)]
    pub beyond_evidence: bool,
    /// Write the per-target report as CSV too.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Refuse, before any work, a program estimated to take longer than this, seconds.
    #[arg(long, default_value_t = DEFAULT_MAX_SECONDS)]
    pub max_seconds: f64,
    /// Refuse, before any work, a program estimated to need more memory than this, MB
    /// (about 2 KB a target, and three times the program's size).
    #[arg(long, default_value_t = DEFAULT_MAX_MEMORY_BYTES / 1_000_000)]
    pub max_memory_mb: u64,
}

impl CompensateArgs {
    /// The defaults for `table` and `program`, as the command line gives them.
    pub fn new(table: impl Into<PathBuf>, program: impl Into<PathBuf>) -> CompensateArgs {
        CompensateArgs {
            table: table.into(),
            program: program.into(),
            output: None,
            format: None,
            robot: crate::RobotArgs::default(),
            tool: None,
            base: None,
            krl_config: None,
            table_tool: None,
            gcode_abc: AbcConvention::default().name().to_string(),
            work_offset: Vec::new(),
            arc_tolerance_mm: DEFAULT_ARC_TOLERANCE_MM,
            yaskawa_tool: Vec::new(),
            yaskawa_user: Vec::new(),
            yaskawa_pulses_per_deg: None,
            fanuc_uframe: Vec::new(),
            fanuc_utool: Vec::new(),
            fanuc_frames: None,
            fanuc_turn_axes: None,
            fanuc_j23: None,
            max_correction_mm: DEFAULT_MAX_CORRECTION_MM,
            max_joint_change_deg: DEFAULT_MAX_JOINT_CHANGE_DEG,
            strict: false,
            beyond_evidence: false,
            report: None,
            max_seconds: DEFAULT_MAX_SECONDS,
            max_memory_mb: DEFAULT_MAX_MEMORY_BYTES / 1_000_000,
        }
    }

    /// The algorithm's options, every option checked: the format's and the convention's
    /// names, the links' robot, the bounds, the frames.
    fn options(self) -> Result<CompensateOptions, JobError> {
        self.robot.check()?;
        let format = match self.format.as_deref() {
            None => None,
            Some(name) => Some(Format::from_name(name).ok_or_else(|| {
                JobError::Options(format!(
                    "format '{name}': one of {}",
                    Format::ALL.map(Format::name).join(", ")
                ))
            })?),
        };
        let abc = AbcConvention::from_name(&self.gcode_abc).ok_or_else(|| {
            JobError::option(
                "gcode_abc",
                format!("'{}': one of kuka, xyz", self.gcode_abc),
            )
        })?;
        let mut options = CompensateOptions::new(self.table, self.program);
        options.output = self.output;
        options.report = self.report;
        options.format = format;
        options.links = self.robot.links();
        options.robot = self.robot.robot;
        options.tool = self.tool;
        options.base = self.base;
        options.krl_config = self.krl_config;
        options.table_tool = self.table_tool;
        options.limits.max_correction_mm = self.max_correction_mm;
        options.limits.max_joint_change_deg = self.max_joint_change_deg;
        options.limits.beyond_evidence = self.beyond_evidence;
        options.strict = self.strict;
        options.max_seconds = self.max_seconds;
        options.max_memory_bytes = self.max_memory_mb.saturating_mul(1_000_000);
        options.gcode = GcodeOptions {
            abc,
            work_offsets: self.work_offset,
            arc_tolerance_mm: self.arc_tolerance_mm,
        };
        options.yaskawa = YaskawaOptions {
            tools: self.yaskawa_tool,
            users: self.yaskawa_user,
            pulses_per_deg: self.yaskawa_pulses_per_deg,
        };
        options.fanuc = FanucOptions {
            user_frames: self.fanuc_uframe,
            tool_frames: self.fanuc_utool,
            frames_file: self.fanuc_frames,
        };
        options.fanuc_turn_axes = self.fanuc_turn_axes;
        options.fanuc_j23 = self.fanuc_j23;
        options
            .check()
            .map_err(|e| JobError::Options(e.to_string()))?;
        Ok(options)
    }
}

/// A compensated program with its whole report ([`CompensateJob::run`]).
#[derive(Clone, Debug, Serialize)]
pub struct Compensated {
    /// The program with every corrected target's numbers replaced.
    #[serde(skip)]
    pub output: Vec<u8>,
    /// Per target, in the program's order, what was done.
    pub targets: Vec<TargetLine>,
    /// The report in figures.
    pub summary: Summary,
    /// The compensated program's xxh3-64 hash, as the report's rows name it.
    pub program_xxh3: u64,
}

/// A compensated program written, its report kept only in figures
/// ([`CompensateJob::run_and_write`]).
#[derive(Clone, Debug, Serialize)]
pub struct Written {
    /// The report in figures.
    pub summary: Summary,
    /// The compensated program's xxh3-64 hash.
    pub program_xxh3: u64,
}

/// A compensation whose options and inputs have all been checked.
pub struct CompensateJob {
    job: adwi_programs::CompensateJob,
}

impl CompensateJob {
    /// Checks every option (before any file is read: [`JobError::Options`]), then opens
    /// the table and the robot, reads the program and resolves every target's frames.
    ///
    /// # Errors
    ///
    /// [`JobError::Options`] for an option; [`JobError::Program`] for an input, a
    /// malformed program (file, line and column), an output that is an input, or more
    /// work than allowed.
    pub fn new(args: CompensateArgs) -> Result<CompensateJob, JobError> {
        let options = args.options()?;
        let job = adwi_programs::CompensateJob::new(options).map_err(program)?;
        Ok(CompensateJob { job })
    }

    /// The program as read.
    pub fn program(&self) -> &adwi_programs::Program {
        self.job.program()
    }

    /// The name of the program's partner file as read (a KRL `.dat`'s `.src` and back),
    /// where a report line `in_partner` is written.
    pub fn partner_name(&self) -> Option<&str> {
        self.job.partner_name()
    }

    /// The characters of the widest place (`line:column`) of a target written in the
    /// program itself ([`adwi_programs::CompensateJob::widest_place`]).
    pub fn widest_place(&self) -> usize {
        self.job.widest_place()
    }

    /// Corrects every target, keeping every target's report line; writes nothing.
    ///
    /// # Errors
    ///
    /// With `strict`, [`JobError::Program`] holding
    /// [`adwi_programs::Error::NotAllCorrected`] when a target was left unchanged.
    pub fn run(&self) -> Result<Compensated, JobError> {
        let done = self.job.run().map_err(program)?;
        Ok(Compensated {
            summary: done.report.summary(),
            program_xxh3: done.report.program_xxh3.unwrap_or_default(),
            output: done.output,
            targets: done.report.targets,
        })
    }

    /// Writes [`CompensateJob::run`]'s program and report where the arguments say, both
    /// or neither.
    ///
    /// # Errors
    ///
    /// [`JobError::Program`] when a file cannot be written (none is then replaced).
    pub fn write(&self, done: &Compensated) -> Result<(), JobError> {
        // The report's text only when it is written, from the lines as they are.
        let csv = self.job.options().report.as_ref().map(|_| {
            let mut rows = adwi_programs::CsvRows::with_capacity(done.targets.len());
            for t in &done.targets {
                rows.push(t);
            }
            rows.finish(Some(done.program_xxh3))
        });
        self.job
            .write_bytes(&done.output, csv.as_deref())
            .map_err(program)
    }

    /// Corrects every target and writes the outputs, handing each target's report line
    /// to `each` as it is made and keeping only the summary: what a long program needs.
    ///
    /// # Errors
    ///
    /// As [`CompensateJob::run`] and [`CompensateJob::write`]: nothing is then written.
    pub fn run_and_write(&self, each: impl FnMut(TargetLine)) -> Result<Written, JobError> {
        let done = self.job.run_and_write(each).map_err(program)?;
        Ok(Written {
            summary: done.summary,
            program_xxh3: done.program_xxh3,
        })
    }
}

/// A program's error, as the job's: an option the inputs cannot take is an option's.
fn program(e: adwi_programs::Error) -> JobError {
    match e {
        adwi_programs::Error::OptionMisfit(message) => JobError::Options(message),
        e => JobError::Program(Box::new(e)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A job on files that do not exist, with `change` made to its arguments: the option
    /// must be refused as an option, before any file is read.
    fn refused(change: impl FnOnce(&mut CompensateArgs)) -> String {
        let mut args = CompensateArgs::new("missing.tbl", "missing.src");
        args.output = Some("out.src".into());
        change(&mut args);
        match CompensateJob::new(args) {
            Err(JobError::Options(message)) => message,
            Err(e) => panic!("not refused as an option: {e}"),
            Ok(_) => panic!("not refused"),
        }
    }

    #[test]
    fn every_option_is_refused_before_any_file_is_read() {
        type Change = Box<dyn FnOnce(&mut CompensateArgs)>;
        let cases: [(&str, Change); 10] = [
            ("max_correction_mm", Box::new(|a| a.max_correction_mm = 0.0)),
            (
                "max_joint_change_deg",
                Box::new(|a| a.max_joint_change_deg = f64::NAN),
            ),
            ("max_seconds", Box::new(|a| a.max_seconds = -1.0)),
            ("format 'vbs'", Box::new(|a| a.format = Some("vbs".into()))),
            ("gcode-abc", Box::new(|a| a.gcode_abc = "zyx".into())),
            (
                "robot file",
                Box::new(|a| a.robot.base_link = Some("base".into())),
            ),
            (
                "KRL programs",
                Box::new(|a| a.format = Some("rapid".into())),
            ),
            (
                "Fanuc programs",
                Box::new(|a| a.fanuc_frames = Some("f.va".into())),
            ),
            (
                "turn axes 4,4,6: three distinct joint numbers",
                Box::new(|a| a.fanuc_turn_axes = Some([4, 4, 6])),
            ),
            (
                "the Fanuc J2/J3 factor must be a number from -2 to 2",
                Box::new(|a| a.fanuc_j23 = Some(f64::NAN)),
            ),
        ];
        for (said, change) in cases {
            let message = refused(|a| {
                // A KRL configuration given to a RAPID program.
                a.krl_config = Some("config.dat".into());
                a.format = Some("krl".into());
                change(a)
            });
            assert!(message.contains(said), "{said}: {message}");
        }
    }

    #[test]
    fn a_program_whose_format_is_unknown_is_refused_as_an_option() {
        let message = refused(|a| a.program = "missing.txt".into());
        assert!(
            message.contains("cannot tell the program's format"),
            "{message}"
        );
    }

    #[test]
    fn a_run_written_whole_and_one_written_as_it_goes_write_the_same_files() {
        use adwi_compile::build::{compile, BuildOptions};
        use adwi_samples::{parse_samples, ColumnMap};
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let mut samples = String::from("x,y,z,dx,dy,dz\n");
        for i in 0..5 {
            for j in 0..5 {
                for k in 0..5 {
                    let p = [1300 + 200 * i, -100 + 200 * j, 700 + 200 * k];
                    samples += &format!("{},{},{},1,0,0\n", p[0], p[1], p[2]);
                }
            }
        }
        let samples =
            parse_samples("t.csv".as_ref(), samples.as_bytes(), &ColumnMap::default()).unwrap();
        let table = compile(&samples, &BuildOptions::default(), &|_| {})
            .unwrap()
            .0;
        std::fs::write(d.join("t.tbl"), table).unwrap();
        std::fs::write(
            d.join("p.csv"),
            "x,y,z\n1500,200,1200\n9000,0,0\n1600,300,1100\n",
        )
        .unwrap();
        let job = |name: &str| {
            let mut args = CompensateArgs::new(d.join("t.tbl"), d.join("p.csv"));
            args.output = Some(d.join(format!("{name}.csv")));
            args.report = Some(d.join(format!("{name}.rep")));
            CompensateJob::new(args).unwrap()
        };
        let whole = job("whole");
        let done = whole.run().unwrap();
        whole.write(&done).unwrap();
        let mut lines = Vec::new();
        let written = job("going").run_and_write(|l| lines.push(l)).unwrap();
        assert_eq!(lines, done.targets);
        assert_eq!(written.summary, done.summary);
        assert_eq!((done.summary.corrected, done.summary.total), (2, 3));
        for ext in ["csv", "rep"] {
            let read = |name: &str| std::fs::read(d.join(format!("{name}.{ext}"))).unwrap();
            assert_eq!(read("whole"), read("going"), "{ext}");
        }
    }

    #[test]
    fn the_defaults_are_the_command_lines() {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            args: CompensateArgs,
        }
        let parsed = Cli::parse_from(["tablec", "t.tbl", "p.src", "-o", "o.src"]).args;
        let mut made = CompensateArgs::new("t.tbl", "p.src");
        made.output = Some("o.src".into());
        assert_eq!(format!("{parsed:?}"), format!("{made:?}"));
    }
}
